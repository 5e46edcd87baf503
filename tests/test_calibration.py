"""Calibration (slow): 90% intervals of the correlated likelihood cover the truth ~90% of the time.

The full study (210+ logs, three scenarios, SBC ranks) is ``scripts/bench_calibration.py``;
this is its smaller check: 40 white + Gauss-Markov logs of 2**15 samples, truth drawn
log-uniformly within +-0.5 decade. With n = 40 and p = 0.9 the binomial standard error
is 0.047, so each coverage must lie in [0.76, 1.0] (3 sigma).
"""

import warnings

import numpy as np
import pytest

from bayes_imu.allan import allan_variance
from bayes_imu.errors import ConvergenceWarning
from bayes_imu.fit import fit_allan
from bayes_imu.models import NoiseModel
from bayes_imu.simulate import simulate_log

BASE = {"noise_variance": 1e-2, "bias_variance": 1e-5, "time_constant": 10.0}


@pytest.mark.slow
def test_coverage_white_gauss_markov(rng):
    model = NoiseModel(("white", "gauss_markov"), 0.01)
    hits = {k: [] for k in BASE}
    for _ in range(40):
        truth = {k: v * 10 ** rng.uniform(-0.5, 0.5) for k, v in BASE.items()}
        allan = allan_variance(simulate_log(model, truth, 2**15, rng=rng), rate_hz=100.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            result = fit_allan(allan, terms=model.terms, rng=rng)
        for k in BASE:
            lo, hi = np.quantile(result.draws(k), [0.05, 0.95])
            hits[k].append(lo <= truth[k] <= hi)
    coverage = {k: np.mean(v) for k, v in hits.items()}
    assert all(0.76 <= c <= 1.0 for c in coverage.values()), coverage
