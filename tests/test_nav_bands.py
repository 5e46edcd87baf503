"""Navigation bands (:mod:`bayes_imu.drift.nav_bands`): assembly over draws and terms, the
predictive bound against independent integrals, channels and errors."""

import numpy as np
import pytest
from scipy import integrate, optimize, stats

from bayes_imu.drift.nav_bands import navigation_bands, predictive_bound
from bayes_imu.drift.navigation import NavLoop
from bayes_imu.errors import InputError
from bayes_imu.inference.fit import FitResult
from bayes_imu.noise.avar_forms import NoiseModel
from bayes_imu.noise.model import REGISTRY


def fake_fit(terms, samples, dt=0.01):
    return FitResult(
        NoiseModel(terms, dt),
        np.asarray(samples, float),
        np.zeros(len(samples)),
        None,
        (),
        0,
        {},
        "test",
        None,
    )


def pair(rng, n=30, dt=0.01):
    gyro = fake_fit(
        ("white", "gauss_markov"),
        np.column_stack(
            [rng.uniform(0.5, 2.0, n) * 1e-5, rng.uniform(1e-9, 1e-8, n), rng.uniform(20, 200, n)]
        ),
        dt,
    )
    accel = fake_fit(
        ("white", "random_walk"),
        np.column_stack([rng.uniform(0.5, 2.0, n) * 1e-4, rng.uniform(1e-5, 1e-4, n)]),
        dt,
    )
    return gyro, accel


def per_draw(fit, loop, k, dt, **kw):
    """Independent assembly: one scalar nav_variance call per draw and term."""
    out = []
    for theta in fit.samples:
        params = fit.model.unpack(theta)
        out.append(sum(t.nav_variance(loop, k, params, dt, **kw) for t in fit.model.components))
    return np.array(out)


def test_bands_are_quantiles_of_per_draw_sums(rng):
    gyro, accel = pair(rng)
    t = np.array([0.5, 10.0, 60.0, 300.0])
    bands = navigation_bands(
        gyro, accel, t, calibration_s=30.0, max_draws=30, quantiles=(0.1, 0.5, 0.9)
    )
    k = t / 0.01
    var = per_draw(gyro, NavLoop("gyro"), k, 0.01, n_cal=3000) + per_draw(
        accel, NavLoop("accel"), k, 0.01, n_cal=3000
    )
    for i, name in enumerate(("tilt", "velocity", "position")):
        sd = np.sqrt(var[..., i])
        np.testing.assert_allclose(
            bands.quantities[name].sigma, np.quantile(sd, [0.1, 0.5, 0.9], axis=0), rtol=1e-12
        )
        mix = [
            optimize.brentq(
                lambda x: np.mean(2 * stats.norm.cdf(x / s) - 1) - 0.95, 0, 10 * s.max()
            )
            for s in sd.T
        ]
        np.testing.assert_allclose(bands.quantities[name].bound, mix, rtol=1e-9)
    assert bands.quantities["position"].term_probability == {
        "gyro:white": 1.0,
        "gyro:gauss_markov": 1.0,
        "accel:white": 1.0,
        "accel:random_walk": 1.0,
    }


def test_predictive_bound_of_one_normal_and_of_the_radius():
    s = np.array([[1.0, 3.0]])
    np.testing.assert_allclose(predictive_bound(s), stats.norm.ppf(0.975) * s[0], rtol=1e-12)
    # equal standard deviations: Rayleigh radius, sqrt(-2 ln 0.05) sigma
    np.testing.assert_allclose(
        predictive_bound(s, sigma2=s), np.sqrt(-2 * np.log(0.05)) * s[0], rtol=1e-12
    )
    # unequal: the CDF of the radius as a double integral of the 2-D normal density (scipy dblquad)
    a, b = 1.0, 0.2
    x = predictive_bound(np.array([[a]]), sigma2=np.array([[b]]))[0]

    def inside(r):
        return integrate.dblquad(
            lambda rho, th: (
                rho
                * np.exp(-0.5 * rho**2 * (np.cos(th) ** 2 / a**2 + np.sin(th) ** 2 / b**2))
                / (2 * np.pi * a * b)
            ),
            0,
            2 * np.pi,
            0,
            r,
            epsabs=1e-13,
        )[0]

    assert inside(x) == pytest.approx(0.95, abs=1e-9)


def test_three_axis_channels_radius_and_cross_track(rng):
    fits_g = [pair(rng)[0] for _ in range(3)]
    fits_a = [pair(rng)[1] for _ in range(3)]
    t = np.array([10.0, 120.0])
    three = navigation_bands(fits_g, fits_a, t, speed=20.0, max_draws=30)
    x = navigation_bands(
        fits_g[1], fits_a[0], t, max_draws=30
    )  # channel x: gyro y, accelerometer x
    y = navigation_bands(fits_g[0], fits_a[1], t, max_draws=30)
    np.testing.assert_allclose(
        three.quantities["position_x"].sigma, x.quantities["position"].sigma, rtol=1e-12
    )
    np.testing.assert_allclose(
        three.quantities["position_y"].sigma, y.quantities["position"].sigma, rtol=1e-12
    )
    heading = per_draw(fits_g[2], NavLoop("accel", schuler=False), t / 0.01, 0.01, n_cal=6000)[
        ..., 2
    ]
    np.testing.assert_allclose(
        three.quantities["cross_track"].sigma[1],
        np.median(20.0 * np.sqrt(heading), axis=0),
        rtol=1e-12,
    )
    rms = three.quantities["position"].sigma
    assert np.all(rms[1] >= x.quantities["position"].sigma[0])
    assert three.within("position", three.quantities["position"].bound[0] * 1.001) == 10.0


def test_schuler_off_reproduces_the_uncoupled_growth(rng):
    gyro = fake_fit(("white",), np.full((4, 1), 1e-6))
    accel = fake_fit(("white",), np.full((4, 1), 1e-30))
    t = np.array([100.0])
    on = (
        navigation_bands(gyro, accel, t, bias_start="zero", max_draws=4)
        .quantities["position"]
        .sigma[1]
    )
    off = (
        navigation_bands(gyro, accel, t, bias_start="zero", schuler=False, max_draws=4)
        .quantities["position"]
        .sigma[1]
    )
    # g N sqrt(t^5/20), N^2 = q dt
    assert off[0] == pytest.approx(9.80665 * np.sqrt(1e-6 * 0.01 * 100.0**5 / 20.0), rel=1e-6)
    assert on[0] < off[0]  # the Schuler loop pulls the tilt's gravity error back


def test_input_errors(rng):
    gyro, accel = pair(rng)
    with pytest.raises(InputError, match="mismatched sample rates"):
        navigation_bands(gyro, pair(rng, dt=0.005)[1], [10.0])
    with pytest.raises(InputError, match="bias_start"):
        navigation_bands(gyro, accel, [10.0], bias_start="warm")
    with pytest.raises(InputError, match="speed"):
        navigation_bands(gyro, accel, [10.0], speed=10.0)
    with pytest.raises(InputError, match="three"):
        navigation_bands([gyro, gyro], [accel, accel], [10.0])
    with pytest.raises(InputError, match="calibration"):
        navigation_bands(gyro, accel, [10.0], calibration_s=0.001)
    with pytest.raises(InputError, match="t:"):
        navigation_bands(gyro, accel, [-1.0])


def test_longest_outage_is_where_the_bound_crosses(rng):
    from bayes_imu.drift.nav_bands import longest_outage

    gyro, accel = pair(rng)
    limit = 50.0
    t = longest_outage(gyro, accel, limit, max_draws=30, rng=0)
    # independent check: the bound just at and just beyond that time (same draws: same rng)
    at = navigation_bands(gyro, accel, [t, t + 2.0], max_draws=30, rng=0).quantities["position"]
    assert at.bound[0] <= limit < at.bound[1]
    assert longest_outage(gyro, accel, 1e-9, max_draws=30, rng=0) == 0.0
    with pytest.raises(InputError, match="max_error"):
        longest_outage(gyro, accel, -1.0)


@pytest.fixture(scope="module")
def measured_gyro():
    """A gyro fitted on 400 s of white + random walk, whose record then shows twice the drift
    the model predicts (its contrasts scaled: mean square x 4)."""
    from dataclasses import replace

    from bayes_imu.inference.fit import fit

    rng = np.random.default_rng(11)
    n = 40000
    y = 1e-3 * rng.standard_normal(n) + np.cumsum(rng.standard_normal(n)) * 3e-6
    result = fit(y, rate_hz=100.0, terms=("white", "random_walk"), rng=1, progress=False)
    doubled = replace(result.allan, contrasts=result.allan.contrasts.scaled(2.0))
    return result, replace(result, allan=doubled)


@pytest.mark.slow
def test_bands_contain_the_records_own_interval(measured_gyro):
    """Schuler off, no accelerometer noise to speak of: the tilt is the gyro's order-1 drift, so
    the navigation band must contain the honest drift band (the record's interval), at every
    measured outage, and be the model's band where nothing is widened."""
    from bayes_imu.drift.bands import drift_bands

    plain, doubled = measured_gyro
    quiet = fake_fit(("white",), [[1e-30]] * plain.samples.shape[0])
    t = np.array([1.0, 5.0, 20.0, 60.0, 150.0])
    opts = {"calibration_s": 60.0, "schuler": False, "max_draws": plain.samples.shape[0]}
    model = navigation_bands(plain, quiet, t, honest=False, rng=0, **opts)
    for fit in (plain, doubled):
        nav = navigation_bands(fit, quiet, t, rng=0, **opts).quantities["tilt"]
        drift = drift_bands(fit, t, quantity="attitude", calibration_s=60.0, rng=0)
        inside = t <= drift.measured_s
        assert inside[:3].all()
        band = model.quantities["tilt"].sigma
        assert np.all(nav.sigma[0] <= band[0] * (1 + 1e-12))
        assert np.all(nav.sigma[-1] >= band[-1] * (1 - 1e-12))
        assert np.all(nav.sigma[-1][inside] >= drift.total[-1][inside] * 0.97)
    # twice the drift on the record: the upper band reaches past twice the model's median
    assert np.all(nav.sigma[-1][inside] >= 1.5 * band[1][inside])
    assert np.all(nav.bound >= model.quantities["tilt"].bound * (1 - 1e-12))
