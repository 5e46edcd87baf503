"""Memory and time of the commands on small hostile inputs, each run under an address-space limit.

Builds, in a temporary folder, the hostile inputs of issue 37 (a gzip bomb, a long comment
preamble, a one-megabyte field, a crafted ``fit.npz`` declaring a 6 GiB array, a FIFO and
``/dev/zero`` / ``/dev/urandom`` given as a scene or sensor file, a scene reaching outside its
folder) and a small valid log, then runs ``bayes-imu fit``, ``allan``, ``report``, ``drift`` and
``kalibr`` on each in a fresh process whose address space is limited (``ulimit -v``, i.e.
``RLIMIT_AS``, default 3 GiB) with a wall-time limit (default 120 s). Prints a table: command,
input, exit status, wall time (s) and peak resident memory (MiB, the child's ``ru_maxrss``).

Also a pipe that never ends (``yes 0.1 | bayes-imu allan -``, and a named pipe whose writer never
stops), a named pipe with no writer and ``/dev/zero`` given as a log.

Every hostile case must exit 2 (a user error) within the limits: never 1, never a
``MemoryError``, never killed by the time limit; the valid cases exit 0. The script exits 1 if a
case does not, or if a hostile case's peak resident memory passes ``--max-mib`` (the documented
bound, 256 MiB). ``--quick`` builds the large inputs 16x smaller (a test runs it).

    python scripts/bench_hostile.py [--limit-gib 3] [--timeout 120] [--max-mib 256] [--quick]
"""

import argparse
import gzip
import io
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def build(folder, scale=1):
    """The inputs: ``{name: path}`` (``scale``: the large ones divided by it)."""
    rng = np.random.default_rng(37)
    x = 0.05 * rng.standard_normal(2000)
    good = folder / "good.csv"
    good.write_text("gx\n" + "".join(f"{v:.6f}\n" for v in x))
    bomb = folder / "bomb.csv.gz"
    with gzip.open(bomb, "wb", compresslevel=9) as f:
        f.write(b"gx\n")
        for _ in range(64 // scale):
            f.write(b"0.1\n" * (1 << 22))  # 1 GiB of text in a file of about 1 MB
    preamble = folder / "preamble.csv"
    with open(preamble, "w") as f:
        for _ in range(40 // scale + 1):
            f.write("#" * (1 << 20))
        f.write("\ngx\n1\n2\n")
    field = folder / "field.csv"
    field.write_text("gx\n" + "1\n" * 100 + "9" * (100 // scale * 2**20) + "x\n")
    fifo = folder / "fifo.toml"
    os.mkfifo(fifo)
    fifo_log = folder / "fifo.csv"
    os.mkfifo(fifo_log)
    endless = folder / "endless.csv"
    os.mkfifo(endless)
    outside = folder / "scenes" / "outside.toml"
    outside.parent.mkdir()
    outside.write_text(
        '[scene]\noutages_s = [10]\n[[sensor]]\nname = "s"\nkind = "gyro"\nlog = "/etc/passwd"\n'
        'column = "0"\nrate_hz = 100\nunits = "deg/s"\n'
    )
    sensor = folder / "sensor.json"
    sensor.write_text(json.dumps({"kind": "gyro", "rate_hz": 100, "noise_density": 1e-3}))
    return {
        "good.csv": good,
        "bomb.csv.gz (1 GiB in 1 MB)": bomb,
        "preamble.csv (40 MiB comment)": preamble,
        "field.csv (100 MiB field)": field,
        "fifo.toml (no writer)": fifo,
        "fifo.csv (no writer)": fifo_log,
        "endless.csv (FIFO, endless writer)": endless,
        "- (yes 0.1 |, never ends)": Path("-"),
        "outside.toml": outside,
        "sensor.json": sensor,
        "/dev/zero": Path("/dev/zero"),
        "/dev/urandom": Path("/dev/urandom"),
    }


def crafted_fit(folder, fit):
    """A copy of the fit folder ``fit`` whose fit.npz also holds an array header declaring 6 GiB."""
    crafted = folder / "crafted_fit"
    crafted.mkdir()
    (crafted / "summary.json").write_bytes((fit / "summary.json").read_bytes())
    (crafted / "fit.npz").write_bytes((fit / "fit.npz").read_bytes())
    header = np.lib.format.header_data_from_array_1_0(np.zeros(1))
    header["shape"] = (6 * 2**30 // 8,)
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, header)
    with zipfile.ZipFile(crafted / "fit.npz", "a") as z:
        z.writestr("huge.npy", buffer.getvalue() + b"\0" * 4096)
    return crafted


def run(argv, limit, timeout, feeder=None):
    """``(status, seconds, peak MiB, last stderr line)`` of ``bayes-imu argv`` in a fresh, limited
    process (``feeder``: a command whose output is its standard input, or that writes a FIFO)."""

    def limited():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    env = dict(os.environ, PYTHONPATH=str(ROOT), BAYES_IMU_OUTPUT_PROCESS="0")
    feed = None
    if feeder is not None:
        feed = subprocess.Popen(feeder, stdout=subprocess.PIPE if "-" in argv else None)
    start = time.perf_counter()
    with tempfile.TemporaryFile("w+") as err:
        stdin = feed.stdout if feed is not None and "-" in argv else subprocess.DEVNULL
        child = subprocess.Popen([sys.executable, "-m", "bayes_imu.cli", *argv], env=env,
                                 preexec_fn=limited, stdin=stdin, stdout=subprocess.DEVNULL,
                                 stderr=err, text=True)
        if feed is not None and feed.stdout is not None:
            feed.stdout.close()  # the child holds the pipe now
        deadline = start + timeout
        while True:  # this child's own resource usage (wait4), polled until it ends or times out
            pid, status, usage = os.wait4(child.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                child.kill()
                pid, status, usage = os.wait4(child.pid, 0)
                status = None
                break
            time.sleep(0.02)
        child.returncode = 0  # reaped here: keep Popen from waiting again
        if feed is not None:
            feed.kill()  # the feeder this function started
            feed.wait()
        err.seek(0)
        lines = err.read().strip().splitlines()
    seconds = time.perf_counter() - start
    code = "timeout" if status is None else os.waitstatus_to_exitcode(status)
    return code, seconds, usage.ru_maxrss / 1024.0, (lines[-1][:110] if lines else "")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--limit-gib", type=float, default=3.0)
    parser.add_argument("--timeout", type=float, default=120.0)
    parser.add_argument("--max-mib", type=float, default=256.0,
                        help="documented bound on a hostile case's peak resident memory (MiB)")
    parser.add_argument("--quick", action="store_true", help="the large inputs 16x smaller")
    args = parser.parse_args()
    limit = int(args.limit_gib * 2**30)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        inputs = build(folder, scale=16 if args.quick else 1)
        out = folder / "out"
        cases = [
            (
                "fit",
                inputs["good.csv"],
                [
                    "--column",
                    "gx",
                    "--rate",
                    "100",
                    "--units",
                    "deg/s",
                    "--terms",
                    "white",
                    "--out",
                    str(folder / "fit"),
                ],
                0,
            ),
            (
                "allan",
                inputs["bomb.csv.gz (1 GiB in 1 MB)"],
                ["--column", "gx", "--rate", "100"],
                2,
            ),
            ("fit", inputs["bomb.csv.gz (1 GiB in 1 MB)"], ["--column", "gx", "--rate", "100"], 2),
            (
                "allan",
                inputs["preamble.csv (40 MiB comment)"],
                ["--column", "gx", "--rate", "100"],
                2,
            ),
            ("allan", inputs["field.csv (100 MiB field)"], ["--column", "gx", "--rate", "100"], 2),
            ("report", inputs["fifo.toml (no writer)"], [], 2),
            ("report", inputs["/dev/urandom"], [], 2),
            ("report", inputs["/dev/zero"], [], 2),
            ("report", inputs["outside.toml"], [], 2),
            ("drift", inputs["/dev/zero"], [], 2),
            ("drift", inputs["fifo.toml (no writer)"], [], 2),
            ("drift", inputs["sensor.json"], [], 0),
            ("fit", inputs["/dev/zero"], ["--column", "0", "--rate", "100"], 2),
            ("fit", inputs["fifo.csv (no writer)"], ["--column", "0", "--rate", "100"], 2),
            ("allan", inputs["- (yes 0.1 |, never ends)"], ["--column", "0", "--rate", "100"], 2),
            ("fit", inputs["endless.csv (FIFO, endless writer)"],
             ["--column", "0", "--rate", "100"], 2),
        ]
        feeders = {
            inputs["- (yes 0.1 |, never ends)"]: ["yes", "0.1"],
            inputs["endless.csv (FIFO, endless writer)"]: [
                "sh", "-c", f"exec yes 0.1 > '{inputs['endless.csv (FIFO, endless writer)']}'"],
        }
        print(f"address-space limit {args.limit_gib:g} GiB, time limit {args.timeout:g} s")
        print(
            f"{'command':8s} {'input':32s} {'status':>7s} {'want':>5s} {'wall s':>7s} "
            f"{'peak MiB':>9s}  message"
        )
        rows = []
        for command, path, extra, want in cases:
            argv = [command, str(path), *extra]
            if "--out" not in argv:
                argv += ["--out", str(out), "--force"]
            rows.append((command, path, *run(argv, limit, args.timeout, feeders.get(path)), want))
            if command == "fit" and want == 0:
                crafted = crafted_fit(folder, folder / "fit")
        rows.append(
            (
                "kalibr",
                Path("crafted_fit (6 GiB header)"),
                *run(
                    ["kalibr", "--gyro", str(crafted), "--out", str(folder / "imu.yaml")],
                    limit,
                    args.timeout,
                ),
                2,
            )
        )
        for command, path, status, seconds, peak, message, want in rows:
            name = next((k for k, v in inputs.items() if v == path), path.name)
            print(
                f"{command:8s} {name:32s} {status!s:>7s} {want:>5d} {seconds:7.2f} "
                f"{peak:9.0f}  {message}"
            )
        bad = [r for r in rows if r[2] != r[-1]]
        heavy = [r for r in rows if r[-1] == 2 and r[4] > args.max_mib]
        hostile = [r for r in rows if r[-1] == 2]
        print(f"hostile cases: at most {max(r[4] for r in hostile):.0f} MiB resident (bound "
              f"{args.max_mib:g}), at most {max(r[3] for r in hostile):.1f} s (limit "
              f"{args.timeout:g})")
        print("all as expected" if not bad and not heavy else
              f"{len(bad)} case(s) not as expected, {len(heavy)} above {args.max_mib:g} MiB")
        return 1 if bad or heavy else 0


if __name__ == "__main__":
    sys.exit(main())
