"""One contract for every registered noise term (as emcee runs every move through one suite).

Each check is a plain function of a :class:`~bayes_imu.noise.Term` (``check_*``), run by a test
parametrised over :data:`~bayes_imu.noise.REGISTRY`, and run again on planted incomplete terms,
which must fail it: a term added to the registry is checked without editing this file, and a
term that misses a method or declares what the pipeline cannot serve is caught. A check for one
more method is one more ``check_*`` function and one more line in :data:`CHECKS`.

References (independent of the term's own closed forms):

* AVAR: the exact quadratic form ``w' G w / (2 m^2)`` over the ``2m`` rate samples of one
  second difference, with the rate autocovariance ``G(l) = (D(l+1) - 2 D(l) + D(l-1)) / 2``
  from the term's structure function (a sum over ``(2m)^2`` sample pairs, not the three-point
  form the terms use);
* structure function: Monte Carlo of the second differences of the term's simulator, within
  5 standard errors (relative standard error ``sqrt(2 / R)`` of a Gaussian mean square, ``R``
  draws);
* drift: the brute-force quadratic form ``w' G w`` of the calibrated Euler error (weights over
  ``y_{-N} .. y_{k-1}`` written out from the paper's sums; they annihilate constants, so the
  generalised covariance serves non-stationary terms too) and Monte Carlo of the same error on
  simulated records (5 standard errors), orders 1 and 2; for the start a simulated record
  realises (:attr:`Term.simulated_start`) the uncalibrated error as well;
* covariance tail: the declared tail, through the covariance kernel, against the exact sum over
  every lag of the record (:func:`bayes_imu.noise.avar_covariance.exact_pair_sums`).

Parameters come from each term's own prior box (its centre, on a fixed curve), so no table of
values is kept by hand here.
"""

import dataclasses

import numpy as np
import pytest

from bayes_imu.errors import InputError, ModelError
from bayes_imu.noise import (
    BIAS_STARTS,
    KALIBR_ROLES,
    REGISTRY,
    ROLES,
    SELECTION_ROLES,
    TAIL_KINDS,
    NoiseModel,
    Term,
)
from bayes_imu.noise._base import PriorScale
from bayes_imu.noise.avar_covariance import avar_covariance, exact_pair_sums, model_tails
from bayes_imu.noise.model import check_declarations

DT = 0.1
#: a curve with AVAR between 1e-2 and 1 over 0.1-10 s of a 200 s record
SCALE = PriorScale(
    log_lo=np.log(1e-2),
    log_hi=np.log(1.0),
    dt=DT,
    tau_min=DT,
    tau_max=10.0,
    m_min=1.0,
    record_s=200.0,
)
N_MC = 3000
#: how closely the covariance code's tail of each kind follows the exact sum over every lag on
#: 400 samples: exact, the Gauss-Markov midpoint rule (~1e-4), the flicker asymptote
#: ``-h a^2 b^2 / l_c^2`` (neglects ``O((b/l_c)^2)``, 4% off at m = 1 against m = 32 here)
TAIL_TOLERANCE = {"none": 1e-9, "gauss_markov": 1e-3, "flicker": 6e-2, "generic": 1e-9,
                  "deterministic": 0.0}
SIGMAS = 5.0


def params_of(term):
    """The centre of the term's prior box on :data:`SCALE` (scalars)."""
    box = np.asarray(term.bounds(SCALE), float)
    assert box.shape == (len(term.parameters), 2) and np.all(box[:, 0] < box[:, 1]), term.name
    return {name: float(np.exp(box[i].mean())) for i, name in enumerate(term.parameters)}


def rate_autocovariance(term, p, n):
    """``(n, n)`` generalised covariance of rate samples from the term's structure function."""
    lag = np.abs(np.arange(n)[:, None] - np.arange(n)[None, :]).astype(float)
    d = lambda k: term.structure(k, p, DT)  # noqa: E731
    return 0.5 * (d(lag + 1.0) - 2.0 * d(lag) + d(np.abs(lag - 1.0)))


def second_difference_weights(m):
    """``d = x_{2m} - 2 x_m + x_0`` as weights on ``y_0 .. y_{2m-1}``."""
    return np.concatenate([-np.ones(m), np.ones(m)])


def drift_weights(order, k, n_cal, calibrated=True):
    """``e = w' y`` over ``y_{-N} .. y_{k-1}``: ``v_k = dt sum_{i<k} e_i``, ``p_k = dt sum_{j<k}
    v_j``, ``e_i = y_i - mean(y_{-N..-1})`` (or ``- 0`` uncalibrated)."""
    outage = DT * np.ones(k) if order == 1 else DT**2 * (k - 1 - np.arange(k, dtype=float))
    cal = -outage.sum() / n_cal * np.ones(n_cal) if calibrated else np.zeros(n_cal)
    return np.concatenate([cal, outage])


def simulate_many(term, p, n, rng, count=N_MC):
    return np.array([term.simulate(p, n, DT, rng) for _ in range(count)])


# --- the contract: each check raises (AssertionError, NotImplementedError, ModelError) on a bad
# term


def check_declarations_(term):
    """Roles, selection, Kalibr role and tail kind from their allowed sets; units of every
    parameter."""
    check_declarations(term, known=tuple(REGISTRY))
    assert (
        term.role in ROLES
        and set(term.selection) <= set(SELECTION_ROLES)
        and term.kalibr in KALIBR_ROLES
    )
    assert term.tail_kind in TAIL_KINDS


def check_avar(term):
    """AVAR equals the sample-level quadratic form of its structure function; broadcasts."""
    p = params_of(term)
    m = np.array([1.0, 2.0, 3.0, 5.0, 8.0, 21.0])
    got = term.avar(m, {k: np.asarray(v) for k, v in p.items()}, DT)
    ref = []
    for mi in m.astype(int):
        w = second_difference_weights(mi)
        ref.append(w @ rate_autocovariance(term, p, 2 * mi) @ w / (2.0 * mi * mi))
    # deterministic: no structure
    if np.all(np.asarray(term.structure(np.arange(50.0), p, DT)) == 0):
        assert np.all(got > 0)
    else:
        np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-14 * np.max(np.abs(got)))
    batch = {k: np.full((2, 3), v) for k, v in p.items()}
    out = term.avar(m, batch, DT)
    assert out.shape == (2, 3, m.size) and np.array_equal(out[1, 2], got)


def check_avar_many(term):
    """Evaluated with the other terms of its ``avar_group`` (a model's Gauss-Markov terms in one
    call), each term's Allan variance is the bits of its own ``avar``, scalars and batches."""
    group = [t for t in REGISTRY.values()
             if term.avar_group is not None and t.avar_group == term.avar_group and t is not term]
    m = np.array([1.0, 2.0, 3.0, 5.0, 8.0, 21.0, 4096.0])
    p = {}
    for t in (term, *group):
        p.update(params_of(t))
    for params in (p, {k: np.full((2, 3), v) * np.linspace(0.5, 2.0, 3) for k, v in p.items()}):
        got = term.avar_many(group, m, params, DT)
        assert len(got) == 1 + len(group)
        for t, value in zip((term, *group), got):
            assert np.array_equal(value, t.avar(m, params, DT)), t.name


def check_avar_power(term):
    """A term that declares ``avar_power = k`` has one parameter ``p`` and its Allan variance is
    ``p**k`` times its value at ``p = 1``, for values of ``p`` across 40 decades; in a model with
    the white noise (itself such a term), the model's Allan variance (the terms' powers times their
    curves in one product, :class:`~bayes_imu.noise.model.AvarEvaluator`) is the sum of the terms'
    own ``avar`` to 1e-14, from an ``(..., n_par)`` array and from a dict."""
    if term.avar_power is None:
        return
    assert len(term.parameters) == 1 and term.avar_power in (1, 2, 3, 4)
    name = term.parameters[0]
    m = np.array([1.0, 2.0, 3.0, 5.0, 8.0, 21.0, 4096.0])
    unit = term.avar(m, {name: np.asarray(1.0)}, DT)
    for value in (1e-20, 3.7e-3, 1.0, 2.5e4, 1e20):
        got = term.avar(m, {name: np.asarray(value)}, DT)
        np.testing.assert_allclose(got, value**term.avar_power * unit, rtol=1e-14, atol=0)
    model = NoiseModel(tuple(dict.fromkeys(("white", term.name))), dt=DT)
    p = {**params_of(REGISTRY["white"]), **params_of(term)}
    scale = np.linspace(0.5, 2.0, 3)
    batch = {k: np.full((2, 3), v) * scale for k, v in p.items()}
    own = sum(REGISTRY[t].avar(m, batch, DT) for t in model.terms)
    theta = np.stack([batch[k] for k in model.parameter_names], axis=-1)
    for params in (theta, batch):
        np.testing.assert_allclose(model.avar(m, params), own, rtol=1e-14, atol=0)


def check_structure_vs_simulation(term, rng):
    """Mean square of the simulator's second differences equals ``2 m^2 AVAR(m)`` within 5 sigma."""
    p = params_of(term)
    m = np.array([1, 3, 8])
    y = simulate_many(term, p, 2 * int(m.max()), rng)
    assert y.shape == (N_MC, 2 * m.max()) and np.all(np.isfinite(y))
    x = np.concatenate([np.zeros((N_MC, 1)), np.cumsum(y, axis=1)], axis=1)
    expected = (
        2.0 * m * m * term.avar(m.astype(float), {k: np.asarray(v) for k, v in p.items()}, DT)
    )
    for mi, e in zip(m, expected):
        d = x[:, 2 * mi] - 2.0 * x[:, mi] + x[:, 0]
        assert abs(np.mean(d * d) / e - 1.0) < SIGMAS * np.sqrt(2.0 / N_MC), (term.name, mi)


def check_drift_brute_force(term):
    """Calibrated drift, orders 1 and 2, against ``w' G w`` (stochastic terms; a deterministic
    term is checked by Monte Carlo, which is exact for it)."""
    p = params_of(term)
    if np.all(np.asarray(term.structure(np.arange(50.0), p, DT)) == 0):
        return
    for order in (1, 2):
        for k, n_cal in ((1, 1), (2, 5), (9, 4), (30, 30)):
            w = drift_weights(order, k, n_cal)
            g = rate_autocovariance(term, p, n_cal + k)
            ref = w @ g @ w
            got = term.drift_variance(
                order,
                np.array([float(k)]),
                {n: np.asarray(v) for n, v in p.items()},
                DT,
                bias_start="calibrated",
                n_cal=float(n_cal),
            )
            np.testing.assert_allclose(
                got[0], ref, rtol=1e-8, atol=1e-12 * (np.abs(w) @ np.abs(g) @ np.abs(w))
            )


def check_drift_monte_carlo(term, rng):
    """Calibrated drift (orders 1, 2) and the start a simulated record realises, by Monte Carlo."""
    p = params_of(term)
    k, n_cal = 12, 8
    pp = {n: np.asarray(v) for n, v in p.items()}
    y = simulate_many(term, p, n_cal + k, rng)
    cases = [(order, "calibrated", y @ drift_weights(order, k, n_cal)) for order in (1, 2)]
    start = getattr(term, "simulated_start", None)
    assert start is None or start in BIAS_STARTS
    # the outage starts at the record's first sample
    if start is not None and start != "calibrated":
        cases += [
            (order, start, y[:, :k] @ drift_weights(order, k, 1, False)[1:]) for order in (1, 2)
        ]
    for order, bias_start, e in cases:
        got = term.drift_variance(
            order, np.array([float(k)]), pp, DT, bias_start=bias_start, n_cal=float(n_cal)
        )[0]
        assert abs(np.mean(e * e) / got - 1.0) < SIGMAS * np.sqrt(2.0 / N_MC), (
            term.name,
            order,
            bias_start,
        )


def check_drift_orders_and_starts(term):
    """Every bias start at orders 1 and 2 is finite, non-negative and zero at ``k = 0``; other
    orders raise ModelError; an unknown start raises InputError."""
    pp = {n: np.full(3, v) for n, v in params_of(term).items()}
    k = np.array([0.0, 1.0, 2.0, 17.0, 400.0])
    for order in (1, 2):
        for start in BIAS_STARTS:
            v = term.drift_variance(order, k, pp, DT, bias_start=start, n_cal=50.0)
            assert v.shape == (3, k.size) and np.all(np.isfinite(v)) and np.all(v >= 0), (
                order,
                start,
            )
            assert np.all(v[:, 0] == 0)
    for order in (0, 3, 1.5, True, -1):
        with pytest.raises(ModelError, match="integration order"):
            term.drift_variance(order, k, pp, DT)
    with pytest.raises(InputError, match="bias_start"):
        term.drift_variance(1, k, pp, DT, bias_start="warm")


def check_covariance_tail(term):
    """The declared tail through the covariance code equals the exact sum over every lag (a term
    correlating beyond the overlap window under a ``"none"`` declaration would fail here)."""
    p = params_of(term)
    model = NoiseModel(tuple(dict.fromkeys(("white",) + term.requires + (term.name,))), DT)
    full = dict(p)
    for other in model.components:
        if other is not term:
            full.update(params_of(other))
    tails = model_tails(model, full)
    assert [t.kind for t in tails] == [t.tail_kind for t in model.components]
    m = np.array([1, 2, 4, 8, 16, 32])
    n = 400
    cov = avar_covariance(model, full, m, n)
    table = np.asarray(model.structure_function(np.arange(n + 4 * m.max() + 1), full), float)
    mf = m.astype(float)
    norm = 2.0 * np.outer(mf * mf * (n - 2 * mf + 1), mf * mf * (n - 2 * mf + 1))
    exact = exact_pair_sums(table, m, n) / norm
    assert np.all(np.diag(cov) > 0) and np.array_equal(cov, cov.T)
    if any(t.kind == "deterministic" for t in tails):
        # a fixed-amplitude signal spreads the estimates less than a Gaussian process of its
        # covariance (its own fourth moments left out, a sum of squares); Monte Carlo in its tests
        assert np.all(np.diag(cov) <= np.diag(exact) * (1 + 1e-9))
        return
    rtol = max(TAIL_TOLERANCE[t.kind] for t in tails)
    np.testing.assert_allclose(cov, exact, rtol=rtol, atol=1e-3 * rtol * np.max(np.abs(exact)))


def check_selection_and_start(term):
    """A selection role, and a starting guess for every parameter, finite and positive."""
    assert term.selection and set(term.selection) <= set(SELECTION_ROLES)
    tau = DT * 2.0 ** np.arange(8)
    avar = 0.5 / (tau / DT) + 0.01
    guess = term.starting_guess(tau, avar, tau / DT, DT)
    assert set(guess) == set(term.parameters)
    assert all(np.isfinite(v) and v > 0 for v in guess.values())


def check_datasheet_and_kalibr(term):
    """Datasheet rows for both sensors, drawn from its parameters (or the noise density); a
    Kalibr random-walk term gives a non-negative density per draw."""
    names = set(term.parameters) | {"noise_density"}
    p = params_of(term)
    for sensor in ("gyro", "accel"):
        rows = term.datasheet_rows(sensor)
        assert isinstance(rows, dict)
        for name, (source, convert, unit, what) in rows.items():
            assert source in names and unit and what, name
            if source in p:
                assert np.isfinite(convert(np.array([p[source]]))).all()
    if term.kalibr == "random_walk":
        draws = {n: np.full(4, v) for n, v in p.items()}
        rw2 = term.kalibr_random_walk2(draws, 10.0)
        assert rw2.shape == (4,) and np.all(rw2 >= 0)
    if term.kalibr == "noise_density":
        assert term.role == "short_term"


def check_start_variants(term):
    """Further starts of the mode search (pilot or not): at least one, each a few of its own
    parameters at finite positive values."""
    tau = DT * 2.0 ** np.arange(8)
    avar = 0.5 / (tau / DT) + 0.01
    for pilot in (True, False):
        variants = term.start_variants(tau, avar, pilot=pilot)
        assert len(variants) >= 1
        for variant in variants:
            assert set(variant) <= set(term.parameters), variant
            assert all(np.isfinite(v) and v > 0 for v in variant.values()), variant


def check_worst_axis(term):
    """A worst-axis parameter is an amplitude: doubling it never lowers the Allan variance at
    any cluster size (1 to 2^12) and raises it somewhere; the derived noise density is a
    short-term density term's."""
    p = params_of(term)
    m = 2.0 ** np.arange(13)
    base = term.avar(m, p, DT)
    for name in term.worst_axis:
        if name not in term.parameters:
            assert term.kalibr == "noise_density" and term.role == "short_term", name
            continue
        more = term.avar(m, dict(p, **{name: 2.0 * p[name]}), DT)
        assert np.all(more >= base * (1.0 - 1e-12)) and np.any(more > base * (1.0 + 1e-6)), name


def check_exchangeable(term):
    """Terms of one exchangeable group are one process: the same prior box and the same Allan
    variance at the same (variance, time constant), as every other registered member."""
    if not term.exchangeable:
        return
    p = params_of(term)
    values = [p[n] for n in term.parameters]
    m = 2.0 ** np.arange(10)
    others = [t for t in REGISTRY.values() if t.exchangeable == term.exchangeable and t is not term]
    assert others, f"no other term of group {term.exchangeable!r}"
    for other in others:
        np.testing.assert_array_equal(np.asarray(other.bounds(SCALE)),
                                      np.asarray(term.bounds(SCALE)))
        mapped = dict(zip(other.parameters, values))
        np.testing.assert_allclose(other.avar(m, mapped, DT), term.avar(m, p, DT), rtol=1e-14)


CHECKS = (
    check_declarations_,
    check_avar,
    check_structure_vs_simulation,
    check_drift_brute_force,
    check_drift_monte_carlo,
    check_drift_orders_and_starts,
    check_covariance_tail,
    check_avar_many,
    check_avar_power,
    check_selection_and_start,
    check_datasheet_and_kalibr,
    check_start_variants,
    check_worst_axis,
    check_exchangeable,
)
_NEEDS_RNG = {check_structure_vs_simulation, check_drift_monte_carlo}


def run_check(check, term, rng):
    return check(term, rng) if check in _NEEDS_RNG else check(term)


@pytest.mark.parametrize("name", list(REGISTRY))
@pytest.mark.parametrize("check", CHECKS, ids=lambda c: c.__name__)
def test_every_term_meets_the_contract(check, name, rng):
    run_check(check, REGISTRY[name], rng)


# --- planted incomplete terms fail the contract


class _HalfWhite(Term):
    """White noise with its AVAR and simulator only: no structure, guess, rows or drift."""

    tail_kind = "none"

    def avar(self, mf, params, dt):
        return np.asarray(params["noise_variance"], float)[..., None] / mf

    def simulate(self, params, n, dt, rng):
        return np.sqrt(params["noise_variance"]) * rng.standard_normal(n)

    def bounds(self, scale):
        return [scale.amplitude(0.0, 1.0)]


class _PeriodicTail(_HalfWhite):
    """Complete but for a covariance tail of a kind the covariance code does not serve."""

    tail_kind = "periodic"

    def structure(self, k, params, dt):
        return params["noise_variance"] * np.asarray(k, float)


class _WrongAvar(_PeriodicTail):
    """A declared tail, but an AVAR twice its structure function's."""

    tail_kind = "none"

    def avar(self, mf, params, dt):
        return 2.0 * super().avar(mf, params, dt)


class _BadStarts(_WrongAvar):
    """Starts a parameter it does not have."""

    def start_variants(self, tau, avar, *, pilot):
        return ({"time_constant": 1.0},)


class _WrongPower(_WrongAvar):
    """Declares its Allan variance the square of its parameter's multiple; it is the multiple."""

    avar_power = 2


_UNITS = {"noise_variance": "({u})^2"}
PLANTED = {
    "wrong_power": _WrongPower("wrong_power", ("noise_variance",), _UNITS, "wrong power",
                               "short_term", selection=("extension",), kalibr="none"),
    "bad_starts": _BadStarts(
        "bad_starts",
        ("noise_variance",),
        _UNITS,
        "bad starts",
        "short_term",
        selection=("extension",),
        kalibr="none",
    ),
    # a Gauss-Markov bias that calls its time constant an amplitude (no worse direction)
    "worst_time": dataclasses.replace(
        REGISTRY["gauss_markov"], name="worst_time", worst_axis=("time_constant",), exchangeable=""
    ),
    # the fast correlated term declared exchangeable with the Gauss-Markov biases (another box)
    "fast_exchangeable": dataclasses.replace(
        REGISTRY["hf_correlated"], name="fast_exchangeable", exchangeable="gauss_markov"
    ),
    "worst_unknown": dataclasses.replace(
        REGISTRY["white"], name="worst_unknown", worst_axis=("noise_level",)
    ),
    "half": _HalfWhite(
        "half",
        ("noise_variance",),
        _UNITS,
        "half white",
        "short_term",
        selection=("extension",),
        kalibr="noise_density",
    ),
    "periodic": _PeriodicTail(
        "periodic",
        ("noise_variance",),
        _UNITS,
        "periodic",
        "short_term",
        selection=("extension",),
        kalibr="none",
    ),
    "wrong_avar": _WrongAvar(
        "wrong_avar",
        ("noise_variance",),
        _UNITS,
        "wrong",
        "short_term",
        selection=("extension",),
        kalibr="none",
    ),
    "no_role": _WrongAvar("no_role", ("noise_variance",), _UNITS, "no role", "short_term"),
}
#: (planted term, the checks it must fail)
FAILURES = [
    ("half", check_avar),
    ("half", check_drift_brute_force),
    ("half", check_selection_and_start),
    ("half", check_datasheet_and_kalibr),
    ("half", check_drift_orders_and_starts),
    ("periodic", check_declarations_),
    ("wrong_avar", check_avar),
    ("wrong_avar", check_structure_vs_simulation),
    ("no_role", check_declarations_),
    ("no_role", check_selection_and_start),
    ("bad_starts", check_start_variants),
    ("worst_time", check_worst_axis),
    ("fast_exchangeable", check_exchangeable),
    ("worst_unknown", check_declarations_),
    ("wrong_power", check_avar_power),
]


@pytest.mark.parametrize("planted, check", FAILURES, ids=[f"{p}-{c.__name__}" for p, c in FAILURES])
def test_planted_incomplete_term_fails_the_contract(planted, check, rng):
    with pytest.raises((AssertionError, NotImplementedError, ModelError)):
        run_check(check, PLANTED[planted], rng)


def test_undeclared_tail_kind_is_refused_by_the_covariance_code(monkeypatch):
    """A model holding a term of an unknown tail kind raises ModelError rather than dropping its
    correlation (the registry itself refuses such a term, :func:`check_declarations`)."""
    import bayes_imu.noise.model as model_module

    monkeypatch.setitem(model_module.REGISTRY, "periodic", PLANTED["periodic"])
    monkeypatch.setattr(model_module, "TERMS", model_module.TERMS + ("periodic",))
    model = NoiseModel(("white", "periodic"), DT)
    with pytest.raises(ModelError, match="periodic"):
        avar_covariance(model, {"noise_variance": 1.0}, np.array([1, 2]), 100)
    with pytest.raises(ModelError, match="covariance tail kind"):
        check_declarations(PLANTED["periodic"])
