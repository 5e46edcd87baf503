"""R-hat and ESS (bayes_imu.inference.diagnostics) against ArviZ, the reference implementation of
Vehtari et al. (2021), on chains with autocorrelation, repeated values (rejected moves) and a
chain that has not mixed; and their behaviour on independent draws."""

import numpy as np
import pytest

from bayes_imu.inference import diagnostics
from bayes_imu.inference.fit import import_arviz


def _chains(rng, m, n, phi, shift=0.0, repeats=True):
    x = np.zeros((m, n))
    x[:, 0] = rng.standard_normal(m) / np.sqrt(1 - phi * phi)
    for t in range(1, n):
        x[:, t] = phi * x[:, t - 1] + rng.standard_normal(m)
    if repeats:
        x[:, 10:25] = x[:, 10:11]  # a run of rejected moves: ties in the ranks
    x[0] += shift
    return x


@pytest.mark.parametrize(
    "m, n, phi, shift",
    [
        (32, 40, 0.5, 0.0),
        (8, 301, 0.9, 0.0),
        (8, 300, 0.9, 3.0),
        (4, 1000, 0.99, 0.0),
        (32, 7, 0.0, 0.0),
    ],
)
def test_matches_arviz(rng, m, n, phi, shift):
    az = import_arviz()
    x = _chains(rng, m, n, phi, shift, repeats=n > 25)
    assert diagnostics.rhat(x) == pytest.approx(float(az.rhat(x)), rel=1e-10)
    assert diagnostics.ess_bulk(x) == pytest.approx(float(az.ess(x, method="bulk")), rel=1e-10)
    assert diagnostics.ess_tail(x) == pytest.approx(float(az.ess(x, method="tail")), rel=1e-10)


def test_independent_draws_and_a_stuck_chain(rng):
    """Independent normal draws: R-hat within 1% of 1, bulk ESS near the number of draws;
    one chain shifted by 3 sd: R-hat well above the 1.01 convergence bar."""
    x = rng.standard_normal((16, 500))
    assert abs(diagnostics.rhat(x) - 1.0) < 0.01
    assert 0.8 * x.size < diagnostics.ess_bulk(x) < 1.2 * x.size
    assert diagnostics.rhat(_chains(rng, 8, 300, 0.5, shift=3.0)) > 1.05
    chain = np.stack([x[:4].T, 2 * x[4:8].T], axis=2)  # emcee layout (draws, walkers, parameters)
    out = diagnostics.summary(chain)
    assert out["rhat_max"] == max(diagnostics.rhat(x[:4]), diagnostics.rhat(2 * x[4:8]))
    assert out["ess_bulk_min"] == min(diagnostics.ess_bulk(x[:4]), diagnostics.ess_bulk(2 * x[4:8]))
