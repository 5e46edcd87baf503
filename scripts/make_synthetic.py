"""Generate the synthetic static logs in data_synthetic/ with their true parameters.

Each log is drawn by ``bayes_imu.noise.simulate.simulate_log`` (exact discretisation) and written
as a gzipped CSV with a header row (``time_s`` plus one rate column, 9 significant digits);
``data_synthetic/truth.json`` records every log's model, parameters (bayes_imu names and
units), rate, length, column, unit and seed. Run from the project root:

    python scripts/make_synthetic.py [--only NAME,...]

The three ``population_unit*`` logs are units of one gyro model (parameters drawn around the
``POPULATION`` medians, recorded per unit) for ``bayes-imu fit-population``.
"""

import gzip
import json
from pathlib import Path

import numpy as np

from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.noise.simulate import simulate_log

OUT = Path(__file__).resolve().parent.parent / "data_synthetic"

#: name -> (column, unit, rate_hz, n_samples, offset, {parameter: value}); values in the column's
#: unit
LOGS = {
    # ADIS16405-like MEMS gyro: 0.05 deg/s/sqrt(Hz) white noise, 0.01 deg/s Gauss-Markov bias, T =
    # 100 s
    "gyro_lowgrade": (
        "gyro_x_dps",
        "deg/s",
        100.0,
        360_000,
        0.0,
        {"noise_variance": 0.05**2 * 100.0, "bias_variance": 0.01**2, "time_constant": 100.0},
    ),
    # tactical-grade gyro, white noise only (paper Fig 3): 0.002 deg/s/sqrt(Hz)
    "gyro_highgrade": (
        "gyro_x_dps",
        "deg/s",
        100.0,
        360_000,
        0.0,
        {"noise_variance": 0.002**2 * 100.0},
    ),
    # accelerometer axis reading gravity: VRW 0.2 m/s/sqrt(h) = 3.33e-3 m/s^2/sqrt(Hz), GM bias 2e-3
    # m/s^2, T = 10 s
    "accel_gravity": (
        "accel_z_mps2",
        "m/s^2",
        200.0,
        360_000,
        9.80665,
        {
            "noise_variance": (0.2 / 60.0) ** 2 * 200.0,
            "bias_variance": 2e-3**2,
            "time_constant": 10.0,
        },
    ),
    # gyro with white noise and rate random walk 2e-4 deg/s/sqrt(s)
    "gyro_rrw": (
        "gyro_x_dps",
        "deg/s",
        100.0,
        360_000,
        0.0,
        {"noise_variance": 0.01**2 * 100.0, "rate_random_walk": 2e-4},
    ),
    # the navigation walkthrough's accelerometers (x axis, 100 Hz like the gyros, 30 min):
    # a precise one, VRW 0.02 m/s/sqrt(h) = 3.33e-4 m/s^2/sqrt(Hz), white only ...
    "accel_precise": (
        "accel_x_mps2",
        "m/s^2",
        100.0,
        180_000,
        0.0,
        {"noise_variance": (0.02 / 60.0) ** 2 * 100.0},
    ),
    # ... and a budget one, VRW 0.2 m/s/sqrt(h), Gauss-Markov bias 2e-3 m/s^2 (204 ug), T = 100 s
    "accel_budget": (
        "accel_x_mps2",
        "m/s^2",
        100.0,
        180_000,
        0.0,
        {
            "noise_variance": (0.2 / 60.0) ** 2 * 100.0,
            "bias_variance": 2e-3**2,
            "time_constant": 100.0,
        },
    ),
}
#: seeds of logs added later (the others are numbered in name order, as they always were)
LATER_SEEDS = {"accel_precise": 101, "accel_budget": 102}
#: three units of one gyro model for the population fit: each unit's ln parameters drawn around
#: the medians below with a 15% spread (seeded), 20 minutes at 100 Hz each
POPULATION = {
    "median": {"noise_variance": 0.05**2 * 100.0, "bias_variance": 0.01**2, "time_constant": 100.0},
    "spread_ln": 0.15,
    "units": 3,
    "n_samples": 120_000,
    "seed": 20261123,
}
TERMS = {
    "noise_variance": "white",
    "bias_variance": "gauss_markov",
    "time_constant": "gauss_markov",
    "rate_random_walk": "random_walk",
}


def population_logs():
    """LOGS-style entries of the population units (parameters drawn from the population, seeded)."""
    rng = np.random.default_rng(POPULATION["seed"])
    names = list(POPULATION["median"])
    out = {}
    for i in range(1, POPULATION["units"] + 1):
        ln = np.log([POPULATION["median"][n] for n in names]) + POPULATION[
            "spread_ln"
        ] * rng.standard_normal(len(names))
        out[f"population_unit{i}"] = ("gyro_x_dps", "deg/s", 100.0, POPULATION["n_samples"], 0.0,
                                      dict(zip(names, np.exp(ln).round(12).tolist())))
    return out


def main(argv=None):
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--only", help="comma-separated log names to (re)write; truth.json keeps the others"
    )
    args = parser.parse_args(argv)
    OUT.mkdir(exist_ok=True)
    truth_path = OUT / "truth.json"
    truth = json.loads(truth_path.read_text()) if args.only and truth_path.exists() else {}
    logs = {**LOGS, **population_logs()}
    only = set(args.only.split(",")) if args.only else set(logs)
    first = sorted(n for n in logs if n not in LATER_SEEDS)  # the original logs keep their seeds
    seeds = {**{n: i for i, n in enumerate(first, start=1)}, **LATER_SEEDS}
    for name, (column, unit, rate, n, offset, params) in sorted(logs.items()):
        seed = seeds[name]
        if name not in only:
            continue
        terms = tuple(dict.fromkeys(TERMS[p] for p in params))
        model = NoiseModel(terms, 1.0 / rate)
        y = simulate_log(model, params, n, rng=seed, offset=offset)
        t = np.arange(n) / rate
        path = OUT / f"{name}.csv.gz"
        with gzip.open(path, "wt", encoding="utf-8", compresslevel=9) as handle:
            handle.write(f"time_s,{column}\n")
            np.savetxt(handle, np.column_stack([t, y]), fmt=["%.2f", "%.9g"], delimiter=",")
        truth[name] = {
            "file": path.name,
            "column": column,
            "unit": unit,
            "rate_hz": rate,
            "n_samples": n,
            "offset": offset,
            "model": list(model.terms),
            "parameters": params,
            "seed": seed,
        }
        print(f"wrote {path.name}: {n} samples, {model.terms}")
    truth["population"] = {
        **POPULATION,
        "logs": sorted(n for n in logs if n.startswith("population_")),
    }
    truth_path.write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
