"""allan.pipeline: a LogSource read into Allan variances, the one path every command and scene
report takes.

References: the Allan variance of the samples this test writes, computed from the numpy array itself
(``allan_variance``), and the SI factor written out here (pi / 180 for deg/s)."""

import dataclasses
import math

import numpy as np
import pytest

from bayes_imu.allan.estimator import allan_variance
from bayes_imu.allan.pipeline import LogSource, allan_from_source
from bayes_imu.errors import InputError


@pytest.fixture
def log(tmp_path, rng):
    y = 0.1 * rng.standard_normal((512, 2))
    path = tmp_path / "imu.csv"
    path.write_text(
        "t,gx,gy\n"
        + "".join(f"{k / 50:.2f},{float(a)!r},{float(b)!r}\n" for k, (a, b) in enumerate(y))
    )
    return path, y


def test_every_column_in_si_with_the_rate_of_the_stamps(log):
    path, y = log
    read = allan_from_source(LogSource(log=path, column="gx, gy", time_column="t", units="deg/s"))
    assert read.columns == ("gx", "gy") and read.unit == "rad/s"
    assert read.info["log"] == str(path) and read.info["rate_source"] == "time column"
    rate = 511 / 10.22  # (samples - 1) / (last stamp - first stamp)
    for j, result in enumerate(read.results):
        plain = allan_variance(y[:, j], rate_hz=rate)
        assert result.rate_hz == rate
        np.testing.assert_allclose(
            result.avar, plain.avar * (math.pi / 180) ** 2, rtol=1e-14, atol=0
        )


def test_a_label_names_the_log_in_what_was_read(log):
    path, _ = log
    read = allan_from_source(
        LogSource(log=path, column="gx", rate=50.0, label="from the pipe"), purpose="allan"
    )
    assert read.info["log"] == "from the pipe" and read.info["rate_source"] == "--rate"


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"rate": None}, r"no sample rate: give rate_hz or a time column"),
        ({"column": "gx,gy"}, r"^column='gx,gy': allan takes one column"),
        ({"units": "rad"}, r"^units=rad is an increment unit: add input='increments'"),
    ],
)
def test_errors_name_the_request_s_parameters(log, changes, message):
    path, _ = log
    source = LogSource(log=path, column="gx", rate=50.0)
    with pytest.raises(InputError, match=message):
        allan_from_source(dataclasses.replace(source, **changes), purpose="allan")
    with pytest.raises(InputError, match=r"purpose='plot': expected one of allan, fit"):
        allan_from_source(source, purpose="plot")
