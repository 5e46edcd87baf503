"""The paper's printed formulas against exact rational arithmetic (docs/errata.md).

Each printed form is evaluated with Fractions exactly as printed and compared with the
exact covariance propagation of ``tests/exact.py``; the corrected forms must agree
exactly, the printed ones (where they are wrong) must not.
"""

from fractions import Fraction

import pytest
from exact import fraction_variance

from bayes_imu import euler_variance

CASES = [(k, Fraction(p, q)) for k in (3, 4, 7, 12) for p, q in ((1, 3), (9, 10), (-1, 2))]


def eq11_printed(k):
    return Fraction(k * (k + 1) * (2 * k + 1), 6)


def eq11_corrected(k):
    return Fraction((k - 1) * k * (2 * k - 1), 6)


def eq16(k, A):
    return (A ** (2 * k) - 1) / (A**2 - 1)


def eq22(k, A):
    num = 1 + 2 * A - 2 * A**k - 2 * A ** (1 + k) + A ** (2 * k) - k + k * A**2
    return num / (-1 + 2 * A - 2 * A**3 + A**4)


def eq29_printed(k, A):
    """Eq 29 as printed, with dt = 1 and q = 1 (no denominator is printed)."""
    c1 = -2 - 4 * A + 2 * A**4 + 4 * A**3 + 2
    c2 = 9 - 12 * A - 6 * A**2 + 12 * A**3 - 3 * A**4
    c3 = -13 + 8 * A - 8 * A**3 + A**4
    c4 = 6 - 12 * A**2
    return (
        c1 * k**3
        + c2 * k**2
        + (c3 + 12 * A**k - 12 * A ** (2 + k)) * k
        + (c4 - 12 * A**k + 12 * A ** (2 + k) + 6 * A ** (2 * k))
    )


def eq29_corrected(k, A):
    """Corrected eq 29 (dt = 1, q = 1), in the paper's sign convention.

    Three fixes to the printed bracket: c1 = -2 + 4A - 4A**3 + 2A**4 (= 2 (A-1)**3 (A+1)),
    c3 gains the term +12 A**2, and the bracket is divided by 6 (A-1)**5 (A+1).
    """
    c1 = -2 + 4 * A - 4 * A**3 + 2 * A**4
    c2 = 9 - 12 * A - 6 * A**2 + 12 * A**3 - 3 * A**4
    c3 = -13 + 8 * A + 12 * A**2 - 8 * A**3 + A**4
    c4 = 6 - 12 * A**2
    bracket = (
        c1 * k**3
        + c2 * k**2
        + (c3 + 12 * A**k - 12 * A ** (2 + k)) * k
        + (c4 - 12 * A**k + 12 * A ** (2 + k) + 6 * A ** (2 * k))
    )
    return bracket / (6 * (A - 1) ** 5 * (A + 1))


@pytest.mark.parametrize("k", [2, 3, 5, 10, 31])
def test_eq11_printed_is_off_by_one_and_corrected_is_exact(k):
    exact = fraction_variance("white", 2, k)
    assert eq11_corrected(k) == exact
    assert eq11_printed(k) != exact
    assert eq11_printed(k - 1) == exact  # the printed sum runs to k instead of k - 1


@pytest.mark.parametrize("k, A", CASES)
def test_eq16_and_eq22_are_exact_as_printed(k, A):
    assert eq16(k, A) == fraction_variance("gauss_markov", 0, k, 1 - A)
    assert eq22(k, A) == fraction_variance("gauss_markov", 1, k, 1 - A)


@pytest.mark.parametrize("k, A", CASES)
def test_eq29_printed_is_wrong_and_corrected_is_exact(k, A):
    exact = fraction_variance("gauss_markov", 2, k, 1 - A)
    assert eq29_corrected(k, A) == exact
    assert eq29_printed(k, A) != exact
    # not merely the missing denominator (or its sign): the bracket itself is wrong
    assert eq29_printed(k, A) / (6 * (A - 1) ** 5 * (1 + A)) != exact


def test_eq28_time_step_power_is_six():
    """Eq 28/29 print dt**3: against the recursion propagated with dt written out (exact fractions,
    no scaling argument), the time step enters as dt**6; the printed dt**3 is off by dt**3."""
    from exact import fraction_variance_dt

    for dt in (0.5, 0.125):
        got = euler_variance(
            "gauss_markov", 2, 9, dt=dt, noise_variance=1.0, time_constant=4.0 * dt
        )
        exact = fraction_variance_dt(2, 9, dt=dt, tau=4.0 * dt)
        assert got == pytest.approx(float(exact), rel=1e-14)
        unit = float(fraction_variance_dt(2, 9, dt=1.0, tau=4.0))  # the same sum at dt = 1
        assert float(exact) / unit == pytest.approx(dt**6, rel=1e-14)
        assert abs(float(exact) / unit - dt**3) > 0.5 * dt**3  # the printed power


@pytest.mark.parametrize("k, A", CASES)
def test_eq19_inner_limit(k, A):
    """Eq 19's inner sum must stop at k-2-i (as eq 20 then correctly sums); k-1-i is wrong."""
    a = 1 - A
    coeff_eq20 = [sum(A**j for j in range(k - 1 - i)) for i in range(k - 1)]
    coeff_eq19 = [sum(A**j for j in range(k - i)) for i in range(k - 1)]
    exact = fraction_variance("gauss_markov", 1, k, a)
    assert sum(c * c for c in coeff_eq20) == exact
    assert sum(c * c for c in coeff_eq19) != exact
