"""Drift of long outages: the order-2 calibrated contrast without a table of ``k + N`` samples.

A position bound searched up to 1e6 s at 100 Hz asks the contrast for outages of 1e8 samples;
a table of the structure function that long took minutes and gigabytes per call (issue 39).
References: the brute-force quadratic forms of ``tests/test_noise_drift.py`` (the covariance of
the rate samples from each term's definition), exact rational arithmetic for white noise at
1e8 samples, and mpmath's Hurwitz zeta derivative for the flicker sums.
"""

from fractions import Fraction

import mpmath
import numpy as np
import pytest

import bayes_imu.noise._base as base
from bayes_imu.noise import REGISTRY
from bayes_imu.noise.bias_instability import power_log_sum

from test_noise_drift import DT, PARAMS, error_weights, rate_covariance

CLOSED = ("white", "filtered_white", "random_walk", "quantization", "bias_instability")


def _contrast(term, k, n_cal, dt=DT):
    unit = {p: 1.0 for p in term.parameters}
    def structure(lag):
        return term.structure(lag, unit, dt) / term.amplitude2(unit)

    return base.calibrated_contrast(structure, 2, np.asarray(k, float), n_cal,
                                    sums=lambda n: term.structure_sums(n, dt))


@pytest.mark.parametrize("name", CLOSED)
def test_closed_form_sums_equal_brute_force_quadratic_form(name, monkeypatch):
    """The closed-form path (forced on short outages) gives the quadratic form ``w' S w`` of the
    error weights and the rate covariance from the term's definition, to 1e-9 relative."""
    monkeypatch.setattr(base, "TABLE_MAX", 0)
    term, p = REGISTRY[name], PARAMS[name]
    for k, n_cal in ((2, 5), (7, 3), (40, 40), (65, 17)):
        w = error_weights(2, k, n_cal)
        cov = rate_covariance(name, p, n_cal + k)
        ref = w @ cov @ w
        got = term.amplitude2(p) * DT**4 * _contrast(term, [k], float(n_cal))[0]
        np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-12 * abs(w) @ np.abs(cov) @ abs(w))


@pytest.mark.parametrize("name", CLOSED)
def test_closed_form_and_table_agree_at_the_switch_over(name, monkeypatch):
    """Just above :data:`TABLE_MAX` (closed forms) and with the whole table (limit raised): the same
    contrast to 3e-12 relative at outages of 2 to 1.1e6 samples (at 2 samples the flicker contrast
    cancels 12 digits: against mpmath the table is 1.1e-12 off there, the closed form 1.5e-13)."""
    term = REGISTRY[name]
    k = np.array([2.0, 3.0, 50.0, 1500.0, 2.0**20 - 6001.0, 1.1e6])
    fast = _contrast(term, k, 6000.0, dt=0.01)
    monkeypatch.setattr(base, "TABLE_MAX", 2**22)
    table = _contrast(term, k, 6000.0, dt=0.01)
    np.testing.assert_allclose(fast, table, rtol=3e-12)


def test_blocked_table_is_the_whole_table_bit_for_bit(monkeypatch):
    """Without closed forms a long table is summed in blocks: the same values as one ``cumsum``."""
    term = REGISTRY["bias_instability"]
    unit = {"bias_instability": 1.0}

    def structure(lag):
        return term.structure(lag, unit, DT)

    k = np.array([1.0, 2.0, 9.0, 300.0, 4000.0, 5000.0])
    whole = base.calibrated_contrast(structure, 2, k, 77.0)
    monkeypatch.setattr(base, "TABLE_MAX", 1000)
    blocked = base.calibrated_contrast(structure, 2, k, 77.0)
    np.testing.assert_array_equal(blocked, whole)


def test_white_position_at_1e8_samples_is_exact():
    """White noise, outage of 1e8 samples after a 6000-sample calibration: the exact variance
    ``sum_j (k-1-j)^2 + (k (k - 1) / 2)^2 / N`` (unit variance, unit dt), in rationals."""
    k, n = 10**8, 6000
    exact = Fraction((k - 1) * k * (2 * k - 1), 6) + Fraction((k * (k - 1) // 2) ** 2, n)
    got = _contrast(REGISTRY["white"], [float(k)], float(n), dt=1.0)[0]
    assert got == pytest.approx(float(exact), rel=1e-15)


@pytest.mark.parametrize("p", [2, 3])
def test_power_log_sum_against_mpmath(p):
    """``sum_{l<=n} l^p ln l``: direct below the switch-over, Euler-Maclaurin above; against mpmath
    (direct sums, and ``zeta'(-p, n + 1) - zeta'(-p)`` for large n) to 1e-18 relative."""
    mpmath.mp.dps = 40
    for n in (1, 2, 100, 4095, 4096, 4097, 5000, 10**6, 10**8, 10**11):
        if n <= 5000:
            ref = mpmath.fsum(mpmath.mpf(i) ** p * mpmath.log(i) for i in range(1, n + 1))
        else:
            ref = mpmath.zeta(-p, n + 1, derivative=1) - mpmath.zeta(-p, 1, derivative=1)
        got = power_log_sum(p, n)
        if n == 1:
            assert got == 0
            continue
        assert abs(mpmath.mpf(np.format_float_scientific(got, unique=True)) / ref - 1) < 1e-18


def test_unit_drift_is_remembered_read_only_and_unchanged():
    """The remembered unit drift is the computed one bit for bit, shared, read-only."""
    term = REGISTRY["white"]
    k = np.array([1.0, 10.0, 1000.0])
    fresh = term.unit_drift(2, k, DT, "calibrated", 60.0)
    first = term.cached_unit_drift(2, k, DT, "calibrated", 60.0)
    np.testing.assert_array_equal(first, fresh)
    assert term.cached_unit_drift(2, k.copy(), DT, "calibrated", 60.0) is first
    assert not first.flags.writeable
    other = term.cached_unit_drift(2, k, DT, "calibrated", 61.0)
    assert not np.array_equal(other, first)
