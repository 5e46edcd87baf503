"""Run the README walkthrough as written and regenerate its pictures and numbers.

Runs every ``bayes-imu`` line of the README's ``sh`` block (in a fresh folder ``walk/`` beside
``data_synthetic/``: the commands use those relative paths), copies the pictures the README
shows into ``docs/walkthrough/``, and prints the numbers the README quotes, with each
command's wall time. Run from the project root: ``python scripts/make_walkthrough.py``.
"""

import json
import re
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PICTURES = {"walk/gyro/allan_fit.png": "allan_fit.png", "walk/gyro/corner.png": "corner.png",
            "walk/gyro/drift.png": "drift.png", "walk/population/population.png": "population.png",
            "walk/report/comparison.png": "comparison.png",
            "walk/nav_report/comparison.png": "nav_comparison.png"}


def main():
    text = (ROOT / "README.md").read_text()
    commands = [
        line
        for block in re.findall(r"```sh\n(.*?)```", text, re.S)
        for line in block.splitlines()
        if line.startswith("bayes-imu ")
    ]
    shutil.rmtree(ROOT / "walk", ignore_errors=True)
    for line in commands:
        start = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "bayes_imu.cli", *shlex.split(line)[1:], "--quiet"]
            if not line.startswith("bayes-imu kalibr") and not line.startswith("bayes-imu report")
            else [sys.executable, "-m", "bayes_imu.cli", *shlex.split(line)[1:]],
            cwd=ROOT,
            check=True,
            capture_output=True,
        )
        print(f"{time.perf_counter() - start:6.1f} s  {line}")
    out = ROOT / "docs" / "walkthrough"
    out.mkdir(parents=True, exist_ok=True)
    for src, name in PICTURES.items():
        shutil.copyfile(ROOT / src, out / name)
    gyro = json.loads((ROOT / "walk/gyro/summary.json").read_text())
    print("gyro model:", " + ".join(gyro["model"]), "| adequate:", gyro["adequacy"]["adequate"],
          f"p = {gyro['adequacy']['p_value']:.2g}")
    for name, p in gyro["datasheet"].items():
        print(f"  {name}: {p['median']:.4g} [{p['q05']:.4g}, {p['q95']:.4g}] {p['unit']}")
    print("  model probabilities:", ", ".join(f"{'+'.join(c['model'])} {c['probability']:.2f}"
                                               for c in gyro["model_averaging"]))
    d = gyro["drift"]["attitude"]
    print(
        f"  attitude drift at {d['t_s']:g} s: {d['q50']:.3g} [{d['q05']:.3g}, {d['q95']:.3g}] "
        f"{d['unit']}"
    )
    pop = json.loads((ROOT / "walk/population/summary.json").read_text())
    print("population model:", " + ".join(pop["model"]))
    for name, p in pop["new_unit_datasheet"].items():
        print(f"  new unit {name}: {p['median']:.4g} [{p['q05']:.4g}, {p['q95']:.4g}] {p['unit']}")
    for u in pop["units"]:
        a = u["alone"]["noise_density"]
        print(
            f"  {u['label']} alone: noise density {a['median']:.4g} [{a['q05']:.4g}, "
            f"{a['q95']:.4g}]"
        )
    report = json.loads((ROOT / "walk/report/report.json").read_text())
    for s in report["sensors"]:
        print(
            f"report {s['name']}: longest outage within {report['requirement']['given']}: "
            f"{s['max_outage_s']:.4g} s; 95% bounds "
            + ", ".join(f"{b['outage_s']:g} s {b['bound']:.3g} rad" for b in s["bounds"])
        )
    print("ranking:", report["ranking"])
    nav = json.loads((ROOT / "walk/nav_report/report.json").read_text())
    for s in nav["sensors"]:
        if s["max_outage_s"] is not None:
            print(f"nav scene, {s['name']} alone: {s['max_outage_s']:.4g} s within the requirement")
    for imu in nav["navigation"]["imus"]:
        print(f"nav scene, {imu['name']}: {imu['longest_outage_s']:.4g} s within "
              f"{nav['navigation']['requirement_text']}; meets: {imu['meets_requirement']}; "
              f"unit-to-unit: {imu['unit_to_unit']}")
    print("IMU ranking:", nav["navigation"]["ranking"])
    print((ROOT / "walk/imu.yaml").read_text())


if __name__ == "__main__":
    main()
