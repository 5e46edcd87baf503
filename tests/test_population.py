"""Population fit: truncation mass, importance-sampled unit likelihood, hierarchical posterior
against an exact normal-normal reference, the new-unit predictive, the command and the report."""

import json

import mpmath
import numpy as np
import pytest
from scipy import stats

from bayes_imu import NoiseModel, allan_variance, fit_allan, simulate_log
from bayes_imu.inference.archive import load_fit, save_fit
from bayes_imu.drift.bands import drift_bands
from bayes_imu.cli.main import main
from bayes_imu.errors import InputError
from bayes_imu.inference.population import (
    SPREAD_BOUNDS,
    UnitPosterior,
    _HyperPosterior,
    _sample_hyper,
    fit_population,
    log_box_mass,
    unit_log_likelihood,
)


def test_log_box_mass_matches_mpmath_in_both_tails():
    box = np.array([[-1.0, 2.0], [3.0, 3.5], [-40.0, -39.0]])
    mu = np.array([[0.0, 0.0, 0.0], [30.0, -30.0, 0.5]])
    sigma = np.array([[1.0, 0.1, 1.0], [1.0, 1.0, 0.05]])
    got = log_box_mass(box, mu, sigma)
    mpmath.mp.dps = 800  # enough digits for 1 - Phi(33) ~ 1e-237 to survive the subtraction
    for row in range(2):
        ref = mpmath.mpf(0)
        for d in range(3):
            a = (mpmath.mpf(box[d, 0]) - mu[row, d]) / sigma[row, d]
            b = (mpmath.mpf(box[d, 1]) - mu[row, d]) / sigma[row, d]
            ref += mpmath.log(mpmath.ncdf(b) - mpmath.ncdf(a))
        assert got[row] == pytest.approx(float(ref), rel=1e-10)


def test_unit_likelihood_is_the_gaussian_convolution():
    """Draws from N(m, s^2), population N(mu, sigma^2) on a huge box: mean density -> N(m; mu, s^2 +
    sigma^2)."""
    rng = np.random.default_rng(0)
    m, s = 0.3, 0.05
    phi = m + s * rng.standard_normal((200_000, 1))
    box = np.array([[-50.0, 50.0]])
    mu = np.array([[0.0], [0.4], [0.2]])
    sigma = np.array([[0.2], [0.1], [0.03]])
    got = unit_log_likelihood(phi, box, mu, sigma)
    ref = stats.norm.logpdf(m, mu[:, 0], np.sqrt(s**2 + sigma[:, 0] ** 2))
    np.testing.assert_allclose(got, ref, atol=0.01)  # Monte Carlo error of 2e5 draws, < 1%


def test_hyper_posterior_matches_exact_normal_normal_reference():
    """Gaussian unit posteriors: the marginal posterior of the spread is known on a grid (mu
    integrated out)."""
    rng = np.random.default_rng(1)
    m = np.array([0.10, -0.15, 0.32, 0.05, -0.02])
    s = 0.02
    phis = [mi + s * rng.standard_normal((1500, 1)) for mi in m]  # their means within s / 39 of m
    boxes = [np.array([[-20.0, 20.0]])] * len(m)
    target = _HyperPosterior(phis, boxes, spread_scale=1.0)
    _, spread, diag = _sample_hyper(target, rng, max_steps=40000)
    assert diag["converged"]
    # exact: m_u ~ N(mu, s^2 + sigma^2); flat mu integrates to a Gaussian marginal in sigma
    grid = np.geomspace(SPREAD_BOUNDS[0], 2.0, 4000)
    v = s**2 + grid**2
    n = m.size
    log_post = (-0.5 * (n - 1) * np.log(v) - 0.5 * np.log(n) - 0.5 * np.sum((m - m.mean()) ** 2) / v
                - 0.5 * grid**2 + np.log(grid))  # half-normal(1) prior in ln sigma (Jacobian sigma)
    w = np.exp(log_post - log_post.max()) * np.gradient(np.log(grid))
    cdf = np.cumsum(w) / w.sum()
    for q in (0.05, 0.5, 0.95):
        exact = np.interp(q, cdf, grid)
        sampled = np.quantile(spread[:, 0], q)
        # Monte Carlo error of ~1000 effective draws
        assert sampled == pytest.approx(exact, rel=0.08), q


def _units(n_units, spread, rng, n_samples=20_000):
    model = NoiseModel(("white",), 0.01)
    truth = np.exp(np.log(1e-4) + spread * rng.standard_normal(n_units))
    allans = [
        allan_variance(
            simulate_log(model, {"noise_variance": t}, n_samples, rng=rng), rate_hz=100.0
        )
        for t in truth
    ]
    return model, truth, allans


@pytest.fixture(scope="module")
def white_population():
    rng = np.random.default_rng(2)
    model, truth, allans = _units(4, 0.3, rng)
    return truth, allans, fit_population(allans, rng=3)


def test_population_of_white_units(white_population):
    truth, allans, pop = white_population
    assert pop.model.terms == ("white",)
    assert pop.diagnostics["converged"]
    # each unit alone is measured to ~1%: its pooled posterior stays at its own value (within 3.5
    # sd)
    for t, u in zip(truth, pop.units):
        ln = np.log(u.draws("noise_variance"))
        assert abs(np.log(t) - ln.mean()) < 3.5 * ln.std()
    # the spread of the four units' ln values is inside the population spread's 90% interval
    lo, hi = np.quantile(pop.spread[:, 0], [0.05, 0.95])
    assert lo < np.std(np.log(truth), ddof=1) < hi
    # a new unit's band is wider than any unit's own and covers every unit
    new = pop.new_unit.draws("noise_variance")
    q05, q95 = np.quantile(new, [0.05, 0.95])
    assert q05 < truth.min() and truth.max() < q95
    assert np.log(q95 / q05) > 5 * max(
        np.log(
            np.quantile(u.draws("noise_variance"), 0.95)
            / np.quantile(u.draws("noise_variance"), 0.05)
        )
        for u in pop.units
    )
    summary = pop.summary(unit="rad/s")
    json.dumps(summary, allow_nan=False)
    assert summary["model"] == ["white"] and len(summary["units"]) == 4
    assert set(summary["new_unit"]) == {"noise_variance", "noise_density"}


def test_new_unit_drift_bands_and_avar(white_population):
    truth, allans, pop = white_population
    bands = drift_bands(pop.new_unit, [1.0, 10.0], quantity="attitude", bias_start="zero")
    # white noise, zero bias start: sigma(t) = sqrt(q dt t) exactly, q from each draw
    q = pop.new_unit.draws("noise_variance")
    expected = np.quantile(np.sqrt(np.outer(q * 0.01, [1.0, 10.0])), [0.05, 0.5, 0.95], axis=0)
    np.testing.assert_allclose(bands.total, expected, rtol=1e-12)
    avar = pop.new_unit.predictive_avar(np.array([1, 100]), n_draws=20000, rng=0)
    np.testing.assert_allclose(
        np.median(avar, axis=0), np.median(q) / np.array([1, 100]), rtol=0.05
    )
    noisy = pop.new_unit.predictive_avar(
        np.array([1, 100]), edf=np.array([3.0, 3.0]), n_draws=20000, rng=0
    )
    assert np.quantile(noisy[:, 1], 0.95) / np.quantile(noisy[:, 1], 0.05) > 2 * np.quantile(
        avar[:, 1], 0.95
    ) / np.quantile(avar[:, 1], 0.05)


@pytest.mark.slow
def test_structure_chosen_by_summed_evidence():
    """A Gauss-Markov bias that short logs confuse with white noise or a random walk unit by unit:
    the units' summed evidence picks the true structure (found by a seed scan: units alone select
    white, white + random walk, ...)."""
    rng = np.random.default_rng(4)
    model = NoiseModel(("white", "gauss_markov"), 0.01)
    params = {"noise_variance": 1e-4, "bias_variance": 1.5e-7, "time_constant": 20.0}
    allans = [
        allan_variance(simulate_log(model, params, 60_000, rng=rng), rate_hz=100.0)
        for _ in range(5)
    ]
    fits = [fit_allan(a, rng=i) for i, a in enumerate(allans)]
    pop = fit_population(allans, unit_fits=fits, rng=5)
    chosen = pop.structures[pop.selected]
    assert pop.per_unit_evidence.shape == (len(pop.structures), 5)
    np.testing.assert_allclose(
        [s.log_evidence for s in pop.structures], pop.per_unit_evidence.sum(axis=1)
    )
    assert chosen.terms == ("white", "gauss_markov")
    assert sum("gauss_markov" in f.model.terms for f in fits) < 5


def test_population_input_errors():
    rng = np.random.default_rng(6)
    _, _, allans = _units(2, 0.1, rng, n_samples=2000)
    with pytest.raises(InputError, match="at least 2"):
        fit_population(allans[:1])
    other = allan_variance(rng.standard_normal(2000), rate_hz=50.0)
    with pytest.raises(InputError, match="one sample rate"):
        fit_population([allans[0], other])
    with pytest.raises(InputError, match="distinct labels"):
        fit_population(allans, labels=["a", "a"])


def test_archive_round_trip(tmp_path):
    rng = np.random.default_rng(7)
    model = NoiseModel(("white", "gauss_markov"), 0.01)
    y = simulate_log(
        model,
        {"noise_variance": 1e-4, "bias_variance": 1e-6, "time_constant": 10.0},
        40_000,
        rng=rng,
    )
    fit = fit_allan(allan_variance(y, rate_hz=100.0), rng=0)
    save_fit(fit, tmp_path / "fit.npz")
    back = load_fit(tmp_path)
    np.testing.assert_array_equal(back.samples, fit.samples)
    assert back.model == fit.model and back.widened == fit.widened and back.selected == fit.selected
    assert [c.terms for c in back.mixture] == [c.terms for c in fit.mixture]
    assert [(c.terms, c.log_evidence, c.method) for c in back.candidates] == \
        [(c.terms, c.log_evidence, c.method) for c in fit.candidates]
    assert {c.method for c in fit.candidates} == {"importance", "laplace"}  # both kinds round-trip
    a = drift_bands(fit, [1.0, 100.0], quantity="attitude", bias_start="calibrated", rng=0)
    b = drift_bands(back, [1.0, 100.0], quantity="attitude", bias_start="calibrated", rng=0)
    np.testing.assert_array_equal(a.total, b.total)
    assert back.summary(unit="rad/s")["adequacy"] == fit.summary(unit="rad/s")["adequacy"]
    with pytest.raises(InputError, match="no fit.npz"):
        load_fit(tmp_path / "missing")


def test_posterior_nc_is_the_file_arviz_writes(tmp_path):
    """write_netcdf (h5netcdf, no ArviZ) against ArviZ's own ``inference_data.to_netcdf``, both read
    back by ArviZ: the same groups, variables, dimensions, coordinates, dtypes and values (a widened
    fit: the discrepancy parameter too), the fit's attributes on the file, and every group readable
    by xarray."""
    import xarray

    from bayes_imu._version import __version__
    from bayes_imu.inference.archive import write_netcdf
    from bayes_imu.inference.fit import import_arviz

    model = NoiseModel(("white", "gauss_markov"), 0.01)
    y = simulate_log(
        model, {"noise_variance": 1e-4, "bias_variance": 1e-6, "time_constant": 10.0}, 20_000, rng=5
    )
    fit = fit_allan(
        allan_variance(y, rate_hz=100.0),
        terms=("white", "gauss_markov"),
        discrepancy="always",
        rng=0,
    )
    write_netcdf(fit, tmp_path / "ours.nc")
    fit.inference_data.to_netcdf(str(tmp_path / "arviz.nc"))
    az = import_arviz()
    ours, theirs = (
        az.from_netcdf(str(tmp_path / "ours.nc")),
        az.from_netcdf(str(tmp_path / "arviz.nc")),
    )
    assert (
        ours.groups()
        == theirs.groups()
        == ["posterior", "log_likelihood", "sample_stats", "observed_data"]
    )
    assert "log_model_discrepancy" in ours.posterior
    for group in theirs.groups():
        a, b = ours[group], theirs[group]
        assert list(a.variables) == list(b.variables) and dict(a.sizes) == dict(b.sizes)
        for name in b.variables:
            assert a[name].dims == b[name].dims and a[name].dtype == b[name].dtype, (group, name)
            np.testing.assert_array_equal(a[name].values, b[name].values)
        with xarray.open_dataset(tmp_path / "ours.nc", group=group, engine="h5netcdf") as ds:
            assert set(ds.variables) == set(b.variables)
    assert ours.attrs == {"terms": "white gauss_markov", "likelihood": "correlated",
                          "bayes_imu_version": __version__}
    save_fit(fit, tmp_path / "fit.npz")
    with pytest.raises(InputError, match="no chains"):  # a fit read back has no walkers to write
        write_netcdf(load_fit(tmp_path / "fit.npz"), tmp_path / "back.nc")


def _write_units(folder, n, rng):
    model = NoiseModel(("white",), 0.01)
    paths = []
    for i in range(n):
        y = simulate_log(
            model, {"noise_variance": 1e-4 * np.exp(0.2 * rng.standard_normal())}, 20_000, rng=rng
        )
        paths.append(folder / f"unit{i}.csv")
        np.savetxt(paths[-1], y[:, None], header="gx", comments="", fmt="%.8g")
    return paths


def test_fit_population_command(tmp_path, capsys):
    paths = _write_units(tmp_path, 3, np.random.default_rng(8))
    out = tmp_path / "pop"
    args = [str(p) for p in paths] + [
        "--column",
        "gx",
        "--rate",
        "100",
        "--units",
        "rad/s",
        "--out",
        str(out),
        "--times",
        "1,10",
        "--quiet",
        "--display-units",
        "deg",
    ]
    assert main(["fit-population", *args]) == 0
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "drift.csv", "drift.png", "population.npz", "population.png", "summary.json", "units"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["unit"] == "rad/s" and [u["label"] for u in summary["units"]] == [
        "unit0",
        "unit1",
        "unit2",
    ]
    assert set(summary["drift"]) == {"attitude"}
    # how much the units measured each spread, beside it (1: the prior's own width)
    assert all(0 < p["spread_ln"]["sd_over_prior_sd"] < 1.5 for p in summary["population"].values())
    # --display-units deg (issue 38): the new unit beside SI, a variance by (180/pi)^2
    for name, power in (("noise_variance", 2), ("noise_density", 1)):
        si, shown = summary["new_unit"][name], summary["new_unit_display"][name]
        assert shown["unit"] == si["unit"].replace("rad", "deg")
        for key in ("median", "q05", "q95"):
            assert shown[key] == pytest.approx(si[key] * (180 / np.pi) ** power, rel=1e-14)
    rows = (out / "drift.csv").read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["1", "10"]
    assert main(["fit-population", str(paths[0]), "--column", "gx", "--rate", "100", "--out",
                 str(tmp_path / "one")]) == 2
    assert "at least 2 units" in capsys.readouterr().err
    assert main(["fit-population", *map(str, paths), "--column", "gx,gx", "--rate", "100", "--out",
                 str(tmp_path / "two")]) == 2
    assert "one column" in capsys.readouterr().err
    assert not (tmp_path / "one").exists() and not (tmp_path / "two").exists()
    _report_reads_the_population_folder(tmp_path, out, summary)


def _report_reads_the_population_folder(tmp_path, out, summary):
    """Issue 38: the population folder read back gives the summary it was written with, and a
    report given it reads it: with every fit and the population sampler made to fail, it still
    bounds the new unit of the 3 units."""
    import bayes_imu.inference.population as population
    import bayes_imu.report.scene as scene_module
    from bayes_imu.inference.population_archive import load_population
    from bayes_imu.report.scene import build_report, read_scene

    back = load_population(out).summary(unit="rad/s")
    for key in ("new_unit", "population", "units", "model"):
        assert back[key] == summary[key], key

    def refit(*args, **kwargs):
        raise AssertionError("fitted again")

    (tmp_path / "scene.toml").write_text('[scene]\noutages_s = [1, 10]\n[[sensor]]\nname = "pop"\n'
                                         'kind = "gyro"\nfit = "pop"\n')
    with pytest.MonkeyPatch.context() as patch:
        for module, name in ((population, "fit_population"), (population, "fit_allan"),
                             (scene_module, "fit_allan")):
            patch.setattr(module, name, refit)
        report = build_report(read_scene(tmp_path / "scene.toml"), rng=0)
    (sensor,) = report.sensors
    assert sensor.fit is None and sensor.posterior is sensor.axes[0].population.new_unit
    entry = report.to_json()["sensors"][0]
    assert "3 units" in entry["unit_to_unit"] and entry["parameters"] == summary["new_unit"]
    # export from the folder: the new unit's white-noise density, sqrt(variance dt) (white only)
    assert main(["export", "--gyro", str(out), "--format", "kalibr", "--out",
                 str(tmp_path / "k.yaml"), "--quiet"]) == 0
    written = dict(line.split(":", 1) for line in (tmp_path / "k.yaml").read_text().splitlines()
                   if line.startswith("gyroscope_noise_density"))
    variance = load_population(out).new_unit.draws("noise_variance")
    assert float(written["gyroscope_noise_density"]) == pytest.approx(
        float(np.median(np.sqrt(variance * 0.01))), rel=1e-9)
    assert main(["export", "--gyro", str(out), "--format", "openvins", "--overbound", "--t-max",
                 "10", "--out", str(tmp_path / "o.yaml"), "--quiet"]) == 0


@pytest.mark.slow  # ~15 s (two fits, a population, a report): the nightly job; the report of a
# population folder alone is test_fit_population_command's
def test_report_population_and_fit_folders(tmp_path):
    from bayes_imu.report.scene import build_report, read_scene

    rng = np.random.default_rng(9)
    paths = _write_units(tmp_path, 3, rng)
    assert (
        main(
            [
                "fit",
                str(paths[0]),
                "--column",
                "gx",
                "--rate",
                "100",
                "--units",
                "rad/s",
                "--out",
                str(tmp_path / "fit0"),
                "--terms",
                "white",
                "--quiet",
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "fit",
                str(paths[1]),
                "--column",
                "gx",
                "--rate",
                "100",
                "--out",
                str(tmp_path / "fit_u"),
                "--terms",
                "white",
                "--quiet",
            ]
        )
        == 0
    )
    scene = tmp_path / "scene.toml"
    scene.write_text("""[scene]
outages_s = [1, 10]
credibility = 0.9
[[sensor]]
name = "population"
kind = "gyro"
logs = ["unit0.csv", "unit1.csv", "unit2.csv"]
column = "gx"
rate_hz = 100
units = "rad/s"
[[sensor]]
name = "folder"
kind = "gyro"
fit = "fit0"
""")
    report = build_report(read_scene(scene), rng=0)
    pop, folder = report.sensors
    assert pop.fit is None and pop.axes[0].population is not None
    assert "NEW unit" in report.to_json()["sensors"][0]["unit_to_unit"]
    assert "NOT included" in report.to_json()["sensors"][1]["unit_to_unit"]
    # the folder's bounds come from the saved draws, not a refit
    saved = load_fit(tmp_path / "fit0")
    np.testing.assert_array_equal(folder.fit.samples, saved.samples)
    # unit-to-unit spread included: the new unit's bound sits further above its median than any
    # unit's own
    ratio = pop.bounds[1]["bound"] / pop.bounds[1]["median"]
    for f in pop.axes[0].population.unit_fits:
        own = np.sqrt(f.draws("noise_variance") * 0.01 * 10.0)
        assert ratio > np.quantile(own, 0.9) / np.median(own)
    # fit folders of several units: a population without refitting any unit
    assert (
        main(
            [
                "fit",
                str(paths[2]),
                "--column",
                "gx",
                "--rate",
                "100",
                "--units",
                "rad/s",
                "--out",
                str(tmp_path / "fit2"),
                "--terms",
                "white",
                "--quiet",
            ]
        )
        == 0
    )
    folders = tmp_path / "folders.toml"
    folders.write_text(scene.read_text().replace('fit = "fit0"', 'fits = ["fit0", "fit2"]'))
    both_units = build_report(read_scene(folders), rng=0).sensors[1]
    assert both_units.fit is None and both_units.axes[0].population.labels == ("1: fit0", "2: fit2")
    np.testing.assert_array_equal(both_units.axes[0].population.unit_fits[0].samples, saved.samples)
    bad = tmp_path / "bad.toml"
    bad.write_text(scene.read_text().replace('fit = "fit0"', 'fit = "fit_u"'))
    with pytest.raises(InputError, match="fitted in 'u'"):
        build_report(read_scene(bad))
    both = tmp_path / "both.toml"
    both.write_text(scene.read_text().replace('fit = "fit0"', 'fit = "fit0"\nlog = "unit0.csv"'))
    with pytest.raises(InputError, match="exactly one of log, logs"):
        read_scene(both)
    column = tmp_path / "column.toml"
    column.write_text(scene.read_text().replace('fit = "fit0"', 'fit = "fit0"\ncolumn = "gx"'))
    with pytest.raises(InputError, match="taken from the fit folder"):
        read_scene(column)


def test_unit_posterior_rejects_unknown_parameter():
    post = UnitPosterior(NoiseModel(("white",), 0.01), np.ones((3, 1)), 10.0)
    with pytest.raises(InputError, match="noise_variance"):
        post.draws("bias_variance")


def test_fixed_terms_write_valid_json_and_a_failing_unit_is_named(tmp_path, monkeypatch):
    """``--terms white`` scores no evidence: summary.json has null there, not NaN (which made the
    command fail after the fit); and a unit whose fit fails is named in the one-line error."""
    rng = np.random.default_rng(4)
    logs = []
    for i in range(3):
        logs.append(tmp_path / f"unit{i}.csv")
        logs[-1].write_text(
            "gx\n" + "".join(f"{v:.8f}\n" for v in 0.01 * rng.standard_normal(20000))
        )
    out = tmp_path / "pop"
    assert (
        main(
            [
                "fit-population",
                *map(str, logs),
                "--column",
                "gx",
                "--rate",
                "100",
                "--terms",
                "white",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    structures = json.loads((out / "summary.json").read_text())["structures"]
    assert structures[0]["log_evidence"] is None and structures[0]["per_unit"] == [None] * 3

    import bayes_imu.inference.population as population
    from bayes_imu.errors import ModelError

    real = population.fit_allan

    def fails_on_the_second(allan, **options):
        if allan.n_samples == 20000 and fails_on_the_second.calls == 1:
            raise ModelError("no model converged")
        fails_on_the_second.calls += 1
        return real(allan, **options)

    fails_on_the_second.calls = 0
    monkeypatch.setattr(population, "fit_allan", fails_on_the_second)
    with pytest.raises(ModelError, match=r"^unit 'unit 2': no model converged$"):
        population.fit_population(
            [allan_variance(np.loadtxt(p, skiprows=1), rate_hz=100.0) for p in logs],
            terms=("white",),
            rng=0,
        )


def test_unconverged_population_is_a_loud_failure(tmp_path, monkeypatch, capsys):
    """A population sampler that does not converge: a ConvergenceWarning, ``converged: false`` with
    its R-hat and effective draws in summary.json, and exit status 4 after the numbers are
    written."""
    import bayes_imu.inference.population as population
    from bayes_imu.cli.main import NOT_CONVERGED_STATUS
    from bayes_imu.errors import ConvergenceWarning

    rng = np.random.default_rng(5)
    logs = []
    for i in range(2):
        logs.append(tmp_path / f"unit{i}.csv")
        logs[-1].write_text(
            "gx\n" + "".join(f"{v:.8f}\n" for v in 0.01 * rng.standard_normal(5000))
        )
    # an effective-draw goal no chain of 100 iterations reaches
    real = population.sample_hmc
    monkeypatch.setattr(
        population,
        "sample_hmc",
        lambda *args, **options: real(*args, **{**options, "max_steps": 100, "ess_min": 1e9}),
    )
    with pytest.warns(ConvergenceWarning, match="population sampler not converged"):
        pop = population.fit_population(
            [allan_variance(np.loadtxt(p, skiprows=1), rate_hz=100.0) for p in logs],
            terms=("white",),
            rng=0,
        )
    assert pop.diagnostics["converged"] is False and pop.diagnostics["n_steps"] == 100
    out = tmp_path / "pop"
    status = main(
        [
            "fit-population",
            *map(str, logs),
            "--column",
            "gx",
            "--rate",
            "100",
            "--terms",
            "white",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert status == NOT_CONVERGED_STATUS == 4
    diagnostics = json.loads((out / "summary.json").read_text())["diagnostics"]
    assert diagnostics["converged"] is False and diagnostics["ess_hyper_min"] < 1e9
    assert diagnostics["rhat_max"] is None or diagnostics["rhat_max"] > 0
    assert "population sampler did not converge" in capsys.readouterr().err


def test_spread_prior_sd_is_the_truncated_half_normal_s():
    """The spread prior's standard deviation: the untruncated half-normal's s sqrt(1 - 2/pi) where
    the bounds do not bite, and a quadrature of the truncated density where they do (scale 5 on
    (1e-3, 5))."""
    from scipy import integrate

    from bayes_imu.inference.population import SPREAD_BOUNDS, spread_prior_sd

    assert spread_prior_sd(1.0, (0.0, 60.0)) == pytest.approx(np.sqrt(1 - 2 / np.pi), rel=1e-12)
    for scale in (0.3, 1.0, 5.0):
        lo, hi = SPREAD_BOUNDS
        moments = [integrate.quad(lambda x, k=k: x**k * np.exp(-0.5 * (x / scale) ** 2), lo, hi,
                                  epsabs=0, epsrel=1e-12)[0] for k in (0, 1, 2)]
        mean, second = moments[1] / moments[0], moments[2] / moments[0]
        assert spread_prior_sd(scale) == pytest.approx(np.sqrt(second - mean**2), rel=1e-9)


def test_a_spread_the_units_barely_measure_is_named():
    """Spread draws from the prior itself give a share near 1 and are named (a user saw a new
    unit's wide interval from two units with no word on why); draws the data narrowed are not."""
    from types import SimpleNamespace

    from bayes_imu.inference.population import (
        SPREAD_BOUNDS, SPREAD_PRIOR_SHARE, PopulationResult, spread_prior_sd)
    from bayes_imu.report.text import spread_prior_note

    rng = np.random.default_rng(3)
    prior = np.abs(rng.standard_normal(200_000))
    prior = prior[(prior > SPREAD_BOUNDS[0]) & (prior < SPREAD_BOUNDS[1])]
    narrow = rng.normal(0.2, 0.02, prior.size)
    pop = SimpleNamespace(spread=np.column_stack([prior, narrow]), spread_scale=1.0,
                          parameter_names=("noise_variance", "time_constant"), labels=("a", "b"))
    share = PopulationResult.spread_prior_share(pop)
    assert share["noise_variance"] == pytest.approx(1.0, abs=0.01)
    assert share["time_constant"] == pytest.approx(0.02 / spread_prior_sd(1.0), rel=0.02)
    assert share["time_constant"] < SPREAD_PRIOR_SHARE <= share["noise_variance"]
    pop.spread_prior_share = lambda: share
    note = spread_prior_note(pop)
    assert note.startswith("2 units barely measure the unit-to-unit spread of noise_variance "
                           "(posterior standard deviation 1.00 of the prior's)")
    assert "time_constant" not in note and "half-normal, scale 1" in note
    pop.spread_prior_share = lambda: {"time_constant": share["time_constant"]}
    assert spread_prior_note(pop) is None
