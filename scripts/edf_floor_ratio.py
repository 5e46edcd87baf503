"""How far below the exact EDF the record's model-free floor lies (issue 35; docs/reference.md,
"The record's interval without the model's EDF").

For each noise below, the exact EDF of the direct calibrated-outage estimate (Isserlis,
``noise.contrast_covariance.contrast_edf``, strided starts as the package averages them) divided by
``drift.direct.record_edf_floor`` (``floor(n / (k + N))``), for windows ``N`` of 100, 1000 and
10000 samples and outages ``k`` from 1 to 50000 samples in a 2^18-sample record at 100 Hz. A
ratio of at least 1 everywhere is what makes the floor a safe cap; how large it gets is what the
cap costs.

    python scripts/edf_floor_ratio.py
"""

import numpy as np

from bayes_imu.allan.contrast import contrast_stride, phase_contrasts
from bayes_imu.drift.direct import record_edf_floor
from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.noise.contrast_covariance import contrast_edf

DT, N_SAMPLES = 0.01, 2**18
CASES = [
    ("white", ("white",), {"noise_variance": 1.0}),
    ("random walk of the rate", ("random_walk",), {"rate_random_walk": 1e-3}),
    ("flicker", ("bias_instability",), {"bias_instability": 0.05}),
    ("quantization + white", ("white", "quantization"),
     {"noise_variance": 1.0, "quantization": 0.1}),
    ("Gauss-Markov 0.5 s", ("white", "gauss_markov"),
     {"noise_variance": 1e-4, "bias_variance": 1.0, "time_constant": 0.5}),
    ("Gauss-Markov 30 s", ("white", "gauss_markov"),
     {"noise_variance": 1e-4, "bias_variance": 1.0, "time_constant": 30.0}),
    ("Gauss-Markov 300 s", ("white", "gauss_markov"),
     {"noise_variance": 1e-4, "bias_variance": 1.0, "time_constant": 300.0}),
]


def main():
    print("| noise | window N | k = 1 | 10 | 100 | 1000 | 10000 | 50000 |")
    print("|---|---|---|---|---|---|---|---|")
    low, high = np.inf, 0.0
    for name, terms, params in CASES:
        model = NoiseModel(terms, DT)
        for n_cal in (100, 1000, 10000):
            ks = np.array([1, 10, 100, 1000, 10000, 50000])
            ks = ks[ks + n_cal <= N_SAMPLES // 2]
            exact = contrast_edf(model, params, ks, n_cal, N_SAMPLES, contrast_stride(ks, n_cal))
            grid = phase_contrasts(np.zeros(N_SAMPLES), rate_hz=1 / DT, calibration_s=n_cal * DT,
                                   k=ks)
            ratio = exact / record_edf_floor(grid, ks * DT)
            low, high = min(low, ratio.min()), max(high, ratio.max())
            cells = [f"{r:.2f}" for r in ratio] + ["-"] * (6 - ratio.size)
            print(f"| {name} | {n_cal} | " + " | ".join(cells) + " |")
    print(f"\nexact EDF / floor: {low:.2f} to {high:.2f}")


if __name__ == "__main__":
    main()
