"""``bayes-imu nav``: files and columns, agreement with the API, and one-line errors (exit 2)."""

import json

import numpy as np
import pytest

from bayes_imu.cli.main import main
from bayes_imu.drift.nav_bands import nav_times, navigation_bands
from bayes_imu.inference.archive import load_fit, save_fit
from bayes_imu.inference.fit import fit


def _folder(path, y, unit, rate=100.0, rng=0):
    path.mkdir()
    result = fit(y, rate_hz=rate, terms=("white", "gauss_markov"), rng=rng, progress=False)
    save_fit(result, path / "fit.npz")
    (path / "summary.json").write_text(json.dumps({"unit": unit, "column": path.name}))
    return path


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    rng = np.random.default_rng(7)
    root = tmp_path_factory.mktemp("nav")
    n = 20000
    gm = np.cumsum(rng.standard_normal(n)) * 1e-6
    gyro = _folder(root / "gyro", 3e-3 * rng.standard_normal(n) + gm, "rad/s")
    accel = _folder(root / "accel", 2e-2 * rng.standard_normal(n) + 10 * gm, "m/s^2")
    raw = _folder(root / "raw", 3e-3 * rng.standard_normal(n), "u")
    fast = _folder(root / "fast", 2e-2 * rng.standard_normal(n), "m/s^2", rate=200.0)
    return {"gyro": gyro, "accel": accel, "raw": raw, "fast": fast, "root": root}


def test_nav_writes_the_three_files_matching_the_api(folders, tmp_path, capsys):
    out = tmp_path / "nav"
    code = main(
        [
            "nav",
            "--gyro",
            str(folders["gyro"]),
            "--accel",
            str(folders["accel"]),
            "--times",
            "10,60,300",
            "--calibration",
            "60",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    # one channel is said to be one (not the horizontal radius, which three-axis folders give)
    assert (
        "position error along the accelerometer's axis (one horizontal channel) <="
        in capsys.readouterr().out
    )
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == [
        "nav.csv",
        "nav.png",
        "summary.json",
    ]
    lines = (out / "nav.csv").read_text().splitlines()
    assert lines[0].split(",")[:6] == ["t_s", "quantity", "q05", "q50", "q95", "unit"]
    rows = [line.split(",") for line in lines[1:]]
    assert [(float(r[0]), r[1], r[5]) for r in rows] == [
        (t, q, u)
        for t in (10.0, 60.0, 300.0)
        for q, u in (("tilt", "rad"), ("velocity", "m/s"), ("position", "m"))
    ]
    api = navigation_bands(
        load_fit(folders["gyro"]),
        load_fit(folders["accel"]),
        nav_times(0.01, (10, 60, 300)),
        calibration_s=60.0,
        rng=0,
    )
    for r in rows:
        q = api.quantities[r[1]]
        i = int(np.argmin(abs(api.t_s - float(r[0]))))
        np.testing.assert_allclose([float(v) for v in r[2:5]], q.sigma[:, i], rtol=1e-8)
        assert float(r[6]) == pytest.approx(q.bound[i], rel=1e-8)
        assert float(r[2]) <= float(r[3]) <= float(r[4]) < float(r[6])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["loop"]["schuler_period_s"] == pytest.approx(5064.0, abs=1.0)
    assert summary["bias_start"] == "calibrated" and summary["calibration_s"] == 60.0


@pytest.mark.parametrize(
    "swap, match",
    [
        (
            ("accel", "gyro"),
            "fitted in 'm/s^2'; expected a gyro fit in rad/s (it is an accelerometer fit; swap",
        ),
        (
            ("raw", "accel"),
            "fitted in 'u'; expected a gyro fit in rad/s (run bayes-imu fit with --units",
        ),
        (("gyro", "fast"), "mismatched sample rates (gyro 100 Hz, accelerometer 200 Hz)"),
        (("gyro", "missing"), "--accel"),
    ],
)
def test_bad_inputs_one_line_exit_2(folders, tmp_path, capsys, swap, match):
    gyro, accel = (str(folders["root"] / name) for name in swap)
    out = tmp_path / "nav"
    code = main(["nav", "--gyro", gyro, "--accel", accel, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert match in err and err.count("\n") == 1, err
    assert not out.exists()


@pytest.mark.parametrize("args", [["--times", "10,-5"], ["--calibration", "0"], ["--speed", "nan"]])
def test_bad_options_exit_2(folders, tmp_path, capsys, args):
    code = main(
        [
            "nav",
            "--gyro",
            str(folders["gyro"]),
            "--accel",
            str(folders["accel"]),
            "--out",
            str(tmp_path / "x"),
        ]
        + args
    )
    assert code == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_speed_needs_three_axes(folders, tmp_path, capsys):
    code = main(
        [
            "nav",
            "--gyro",
            str(folders["gyro"]),
            "--accel",
            str(folders["accel"]),
            "--speed",
            "10",
            "--out",
            str(tmp_path / "x"),
        ]
    )
    assert code == 2
    assert "three-axis gyro" in capsys.readouterr().err


def test_three_axis_folders_give_the_radius_channels_and_cross_track(folders, tmp_path):
    root = folders["root"]
    for kind, unit in (("gyro", "rad/s"), ("accel", "m/s^2")):
        three = root / f"{kind}3"
        if not three.exists():
            three.mkdir()
            axes = {a: {"folder": f"../{kind}", "unit": unit} for a in ("x", "y", "z")}
            (three / "summary.json").write_text(json.dumps({"axes": axes}))
    out = tmp_path / "nav3"
    code = main(
        [
            "nav",
            "--gyro",
            str(root / "gyro3"),
            "--accel",
            str(root / "accel3"),
            "--times",
            "10,60",
            "--speed",
            "15",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert code == 0
    rows = [line.split(",") for line in (out / "nav.csv").read_text().splitlines()[1:]]
    names = [r[1] for r in rows if r[0] == "10"]
    assert names == [
        "tilt",
        "tilt_x",
        "tilt_y",
        "velocity",
        "velocity_x",
        "velocity_y",
        "position",
        "position_x",
        "position_y",
        "cross_track",
    ]
    value = {r[1]: float(r[3]) for r in rows if r[0] == "60"}
    # identical axes: the rms radius is about sqrt(2) times one channel (draws picked apart)
    assert value["position"] == pytest.approx(np.sqrt(2.0) * value["position_x"], rel=0.05)
    main(
        [
            "nav",
            "--gyro",
            str(root / "gyro3"),
            "--accel",
            str(folders["accel"]),
            "--out",
            str(tmp_path / "mixed"),
        ]
    )
    assert not (tmp_path / "mixed").exists()


def test_max_position_requirement(folders, tmp_path, capsys):
    out = tmp_path / "req"
    code = main(
        [
            "nav",
            "--gyro",
            str(folders["gyro"]),
            "--accel",
            str(folders["accel"]),
            "--max-position",
            "5 m",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    req = json.loads((out / "summary.json").read_text())["requirement"]
    assert req["max_error_m"] == 5.0 and req["longest_outage_s"] > 0
    # a whole number of samples as people write it (it was 15.530000000000001), and one channel
    # called one channel (a one-axis pair gives no horizontal radius)
    assert len(repr(req["longest_outage_s"])) <= 14
    assert round(req["longest_outage_s"] * 100) == pytest.approx(req["longest_outage_s"] * 100,
                                                                 abs=1e-6)
    assert "one horizontal channel" in req["meaning"] and "radius" not in req["meaning"]
    assert f"within 5.00 m at 95 % for {req['longest_outage_s']:g} s" in capsys.readouterr().out
    code = main(
        [
            "nav",
            "--gyro",
            str(folders["gyro"]),
            "--accel",
            str(folders["accel"]),
            "--max-position",
            "5 parsecs",
            "--out",
            str(tmp_path / "bad"),
        ]
    )
    assert code == 2 and "--max-position" in capsys.readouterr().err


@pytest.mark.parametrize(
    "metres, text",
    [(17382.4, "17.4 km"), (156.2, "156 m"), (1.3, "1.30 m"), (0.197, "0.197 m"),
     (0.0042, "4.20 mm"), (999.6, "1.00 km"), (999.4, "999 m"), (1234567.0, "1,235 km"),
     (12.345, "12.3 m")],
)
def test_lengths_are_printed_for_people(metres, text):
    from bayes_imu.report.nav import format_length

    assert format_length(metres) == text


def test_nav_says_and_records_an_input_fit_whose_checks_failed(capsys):
    """A new user's finding: nav printed bounds from an accelerometer fit whose model did not
    describe its log (p = 0) and whose noise changed through the log, without a word. Each input
    fit's checks are recorded (summary.json ``inputs``) and a failed one is warned of."""
    from types import SimpleNamespace

    from bayes_imu.cli.nav import _warn_inputs
    from bayes_imu.report.nav import input_checks

    def fit(adequate, p, stationary):
        return SimpleNamespace(adequacy=SimpleNamespace(adequate=adequate, p_value=p),
                               stationarity=SimpleNamespace(stationary=stationary, p_value=1e-129))

    checks = input_checks([fit(True, 0.4, True)], [fit(False, 0.0, False)])
    assert checks == [
        {"sensor": "gyro", "axis": 0, "adequate": True, "p_value": 0.4, "stationary": True,
         "stationarity_p": 1e-129},
        {"sensor": "accel", "axis": 0, "adequate": False, "p_value": 0.0, "stationary": False,
         "stationarity_p": 1e-129},
    ]
    _warn_inputs(checks)
    err = capsys.readouterr().err.splitlines()
    assert err == [
        "bayes-imu: warning: --accel fit: the noise model does not describe its log (goodness of "
        "fit p < 1e-300): the bounds inherit its bands, too narrow where the model misses",
        "bayes-imu: warning: --accel fit: the noise changes during its log (p = 1e-129): a unit's "
        "noise on another day may differ",
    ]


def test_small_angle_limit_is_where_the_median_tilt_crosses_it():
    """``small_angle_valid_to_s`` and nav.png's hatch both start where the median tilt reaches
    0.1 rad, interpolated between band times (they differed: the last time below it in the
    summary, the first above it in the picture, 300 s against ~450 s on a coarse grid). A tilt
    growing as a power of time crosses exactly where the power law says: 0.002 t^1.5 = 0.1 at
    t = 50^(2/3) s."""
    from types import SimpleNamespace

    from bayes_imu.report.nav import SMALL_ANGLE_RAD, small_angle_limit

    t = np.array([1.0, 3.0, 10.0, 30.0, 100.0])

    def bands(tilt):
        return SimpleNamespace(t_s=t, quantities={"tilt": SimpleNamespace(
            sigma=np.vstack([0.5 * tilt, tilt, 2.0 * tilt]))})

    assert SMALL_ANGLE_RAD == 0.1
    assert small_angle_limit(bands(0.002 * t**1.5)) == pytest.approx(50.0 ** (2.0 / 3.0),
                                                                    rel=1e-12)
    assert small_angle_limit(bands(1e-4 * t)) is None
    assert small_angle_limit(bands(0.5 + 0 * t)) == 1.0  # above from the first time


def test_nav_png_labels_one_channel_with_one_pair_of_parentheses(folders, tmp_path, figures):
    """nav.png's y labels of a one-axis pair read "velocity error (one channel) (m/s)": two pairs
    of parentheses, the second the unit's. Now "velocity error, one channel (m/s)". Each term
    keeps one colour in every panel, and no two terms share one; each is named as the other figures
    name it (the term's plot label: "gyro Gauss-Markov bias", "accel acceleration random walk")."""
    from matplotlib.colors import to_hex

    from bayes_imu.noise import REGISTRY
    from bayes_imu.report.nav import plot_nav

    bands = navigation_bands(load_fit(folders["gyro"]), load_fit(folders["accel"]),
                             nav_times(0.01, (10, 60)), calibration_s=60.0, rng=0)
    plot_nav(bands, tmp_path / "nav.png")
    axes = [ax for ax in figures[-1].axes if ax.get_ylabel()]
    assert [ax.get_ylabel() for ax in axes] == [
        "tilt error (rad)", "velocity error, one channel (m/s)", "position error, one channel (m)"]
    colours = {}
    for ax in axes:
        for line in ax.get_lines():
            if line.get_label().startswith(("gyro ", "accel ")):
                colours.setdefault(line.get_label(), set()).add(to_hex(line.get_color()))
    assert colours and all(len(c) == 1 for c in colours.values()), colours
    assert len(set.union(*colours.values())) == len(colours), colours
    gyro = {f"gyro {t.plot_label}" for t in REGISTRY.values()}
    accel = {f"accel {t.plot_label.replace('rate ', 'acceleration ', 1)}"
             for t in REGISTRY.values()}
    assert any(k.startswith("accel ") for k in colours) and set(colours) <= gyro | accel, colours


def test_an_out_folder_that_would_be_refused_is_refused_before_the_bands(
    folders, tmp_path, capsys, monkeypatch
):
    """A non-empty --out that is not a bayes_imu result is refused (one line, exit 2, the folder's
    file kept) before any band is computed: the command does not make the user wait for the
    refusal (a new user's finding: the message came after the whole computation)."""
    import importlib

    module = importlib.import_module("bayes_imu.report.nav")

    def computed(*args, **kwargs):
        raise AssertionError("the bands were computed before the output folder was checked")

    monkeypatch.setattr(module, "navigation_bands", computed)
    out = tmp_path / "taken"
    out.mkdir()
    (out / "mine.txt").write_text("a user's file")
    code = main(["nav", "--gyro", str(folders["gyro"]), "--accel", str(folders["accel"]),
                 "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert str(out) in err
    assert (out / "mine.txt").read_text() == "a user's file"
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]


def _nav_args(folders, out):
    return ["nav", "--gyro", str(folders["gyro"]), "--accel", str(folders["accel"]), "--times",
            "10,60", "--quiet", "--out", str(out)]


def test_nav_png_from_the_output_process_is_the_same_file(folders, tmp_path, monkeypatch):
    """The executable draws nav.png in a second process (report.worker, as a fit's outputs): the
    three files are the same bytes as when everything is written here (the suite's default)."""
    from bayes_imu.report.worker import WORKERS_ENV

    made = {}
    for value in ("0", "1"):
        monkeypatch.setenv(WORKERS_ENV, value)
        out = tmp_path / f"nav{value}"
        assert main(_nav_args(folders, out)) == 0
        made[value] = {name: (out / name).read_bytes()
                       for name in ("nav.csv", "nav.png", "summary.json")}
    assert made["0"] == made["1"]
    assert made["1"]["nav.png"].startswith(b"\x89PNG")


def _broken_plot(*args, **kwargs):
    """A picture that cannot be drawn (module level: the output process imports it by name)."""
    raise ValueError("cannot draw")


def test_a_picture_failing_in_the_output_process_keeps_the_numbers(
    folders, tmp_path, monkeypatch, capsys
):
    """nav.png failing in the second process: one warning line, exit 3, nav.csv and summary.json
    written; a Python caller without ``failures`` gets the error itself."""
    import importlib

    from bayes_imu.report.nav import NavRequest, run_nav
    from bayes_imu.report.worker import WORKERS_ENV

    monkeypatch.setattr(importlib.import_module("bayes_imu.report.nav"), "plot_nav", _broken_plot)
    monkeypatch.setenv(WORKERS_ENV, "1")
    out = tmp_path / "nav"
    assert main(_nav_args(folders, out)) == 3
    assert capsys.readouterr().err == ("bayes-imu: warning: nav.png was not drawn (ValueError: "
                                       "cannot draw); the numbers were written\n")
    assert sorted(p.name for p in out.iterdir()) == [".bayes_imu.json", "nav.csv", "summary.json"]
    request = NavRequest(folders["gyro"], folders["accel"], tmp_path / "api", times=(10.0,))
    with pytest.raises(ValueError, match="cannot draw"):
        run_nav(request, background=True)
    assert not (tmp_path / "api").exists()
