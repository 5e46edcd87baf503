"""Out-of-core Allan variance: identical (rel 1e-12) to the in-memory computation, one-line errors.

Reference: :func:`bayes_imu.allan.estimator.allan_variance` on the same samples loaded in memory
(itself checked against NBS14, Stable32 and an exact-integer computation in test_allan).
Small chunks (a few hundred samples) exercise every chunk boundary.
"""

import gzip
import json

import numpy as np
import pytest

from bayes_imu.allan.estimator import allan_variance
from bayes_imu.cli.main import main
from bayes_imu.errors import InputError
from bayes_imu.allan.outofcore import allan_variance_file


@pytest.fixture(scope="module")
def samples():
    """A gravity-offset accelerometer axis: white noise plus a random walk (varied noise types)."""
    rng = np.random.default_rng(8)
    n = 50_003
    return 9.80665 + 0.01 * rng.standard_normal(n) + 1e-4 * np.cumsum(rng.standard_normal(n))


def _files(tmp_path, y):
    np.save(tmp_path / "y.npy", y)
    y.astype("<f8").tofile(tmp_path / "y.f64")
    text = "acc\n" + "\n".join(repr(float(v)) for v in y) + "\n"
    (tmp_path / "y.csv").write_text(text)
    (tmp_path / "y.csv.gz").write_bytes(gzip.compress(text.encode()))
    return {
        "npy": (tmp_path / "y.npy", {}),
        "raw": (tmp_path / "y.f64", {}),
        "csv": (tmp_path / "y.csv", {"column": "acc"}),
        "csv.gz": (tmp_path / "y.csv.gz", {"column": 0}),
    }


@pytest.mark.parametrize("chunk", [512, 4096, 1 << 22])
def test_identical_to_in_memory(tmp_path, samples, chunk):
    reference = allan_variance(samples, rate_hz=200.0)
    for name, (path, kwargs) in _files(tmp_path, samples).items():
        result = allan_variance_file(path, rate_hz=200.0, chunk_samples=chunk, **kwargs)
        np.testing.assert_allclose(result.avar, reference.avar, rtol=1e-12, err_msg=name)
        np.testing.assert_array_equal(result.alpha, reference.alpha, err_msg=name)
        np.testing.assert_array_equal(result.edf, reference.edf, err_msg=name)
        np.testing.assert_allclose(result.avar_high, reference.avar_high, rtol=1e-12, err_msg=name)
        assert result.n_samples == samples.size and np.array_equal(result.m, reference.m)


def test_float32_all_grid_and_progress(tmp_path, samples, capsys):
    y32 = samples.astype("<f4")
    y32.tofile(tmp_path / "y.f32")
    reference = allan_variance(y32.astype(float), rate_hz=200.0, m="decade")
    result = allan_variance_file(
        tmp_path / "y.f32", rate_hz=200.0, m="decade", chunk_samples=1000, progress=True
    )
    np.testing.assert_allclose(result.avar, reference.avar, rtol=1e-12)
    assert "Allan variance of y.f32" in capsys.readouterr().err


@pytest.mark.parametrize(
    "make, kwargs, message",
    [
        (lambda p: None, {}, "no such file"),
        (
            lambda p: np.save(p.with_suffix(".npy"), np.zeros((10, 3))),
            {},
            "expected one column of samples",
        ),
        (
            lambda p: np.save(p.with_suffix(".npy"), np.arange(100)),
            {},
            "expected floating-point samples",
        ),
        (
            lambda p: p.with_suffix(".f64").write_bytes(b"\0" * 20),
            {},
            "not a whole number of float64 samples",
        ),
        (
            lambda p: np.array([1.0, np.nan, 2.0] * 20).tofile(p.with_suffix(".f64")),
            {},
            "sample 2 is nan",
        ),
        (lambda p: np.full(100, 3.0).tofile(p.with_suffix(".f64")), {}, "constant signal"),
        (
            lambda p: np.array([1e-300, 2e-300, 0.0] * 20).tofile(p.with_suffix(".f64")),
            {},
            "underflow the Allan variance",
        ),
        (
            lambda p: np.array([1.0, 2e150, 3.0] * 20).tofile(p.with_suffix(".f64")),
            {},
            r"sample 2 is 2e\+150; expected",
        ),
        (
            lambda p: np.array([1.0, 2.0, 3.0]).tofile(p.with_suffix(".f64")),
            {},
            "too few for an Allan variance",
        ),
        (lambda p: p.with_suffix(".csv").write_text("a\n1\n2\n3\n4\n5\n"), {}, "needs a column"),
        (
            lambda p: p.with_suffix(".csv").write_text("a\n1\nx\n3\n4\n5\n"),
            {"column": "a"},
            "line 3, column 'a': got 'x'",
        ),
    ],
)
def test_errors_are_one_line(tmp_path, make, kwargs, message):
    base = tmp_path / "log"
    make(base)
    written = [p for p in tmp_path.iterdir()]
    path = written[0] if written else base.with_suffix(".npy")
    with pytest.raises(InputError, match=message) as info:
        allan_variance_file(path, rate_hz=100.0, **kwargs)
    assert "\n" not in str(info.value)


def test_not_enough_disk_is_refused_before_writing(tmp_path, samples, monkeypatch):
    import bayes_imu.allan.outofcore as outofcore

    np.save(tmp_path / "y.npy", samples)
    monkeypatch.setattr(outofcore, "_available_disk", lambda folder=None: 1000)
    with pytest.raises(InputError, match="the temporary phase file needs 0.0004 GB; 1e-06 GB free"):
        allan_variance_file(tmp_path / "y.npy", rate_hz=100.0)


def test_cli_reads_npy_with_units(tmp_path, samples):
    """bayes-imu allan on a .npy log in g (held in memory, as it is small): the same allan.csv as
    the CSV read in memory."""
    np.save(tmp_path / "y.npy", samples)
    (tmp_path / "y.csv").write_text("acc\n" + "\n".join(repr(float(v)) for v in samples) + "\n")
    assert (
        main(
            [
                "allan",
                str(tmp_path / "y.npy"),
                "--rate",
                "200",
                "--units",
                "g",
                "--out",
                str(tmp_path / "a"),
                "--quiet",
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "allan",
                str(tmp_path / "y.csv"),
                "--column",
                "acc",
                "--rate",
                "200",
                "--units",
                "g",
                "--out",
                str(tmp_path / "b"),
                "--quiet",
            ]
        )
        == 0
    )
    a = [r.split(",") for r in (tmp_path / "a" / "allan.csv").read_text().splitlines()[1:]]
    b = [r.split(",") for r in (tmp_path / "b" / "allan.csv").read_text().splitlines()[1:]]
    np.testing.assert_allclose(
        np.array(a)[:, 2:6].astype(float), np.array(b)[:, 2:6].astype(float), rtol=1e-8
    )
    assert a[0][6] == "m/s^2"
    assert (
        main(
            [
                "fit",
                str(tmp_path / "y.csv"),
                "--column",
                "acc",
                "--rate",
                "200",
                "--stream",
                "--terms",
                "white,random_walk",
                "--out",
                str(tmp_path / "c"),
                "--quiet",
            ]
        )
        == 0
    )
    assert (
        json.loads((tmp_path / "c" / "summary.json").read_text())["input"]["read"] == "out of core"
    )


def test_cli_binary_log_rejects_column_and_time(tmp_path, samples, capsys):
    np.save(tmp_path / "y.npy", samples)
    assert (
        main(
            [
                "allan",
                str(tmp_path / "y.npy"),
                "--rate",
                "200",
                "--column",
                "x",
                "--out",
                str(tmp_path / "o"),
            ]
        )
        == 2
    )
    assert "leave out --column" in capsys.readouterr().err
    assert (
        main(["allan", str(tmp_path / "y.npy"), "--time-column", "t", "--out", str(tmp_path / "o")])
        == 2
    )
    # a small .npy is read in memory, a large one streamed: no time column either way
    err = capsys.readouterr().err
    assert (
        "a binary log has no time column; give --rate HZ" in err and not (tmp_path / "o").exists()
    )
    assert main(["allan", str(tmp_path / "y.npy"), "--time-column", "t", "--stream", "--out",
                 str(tmp_path / "o")]) == 2
    assert "not available out of core" in capsys.readouterr().err and not (tmp_path / "o").exists()
