"""The library runs of the commands (:mod:`bayes_imu.report.runs`), used without the command line:
what they return is what they write, their callbacks come in order, their errors name parameters."""

import json
from pathlib import Path

import numpy as np
import pytest

from bayes_imu.allan.pipeline import LogSource
from bayes_imu.errors import InputError
from bayes_imu.report.runs import datasheet_summary, run_fit
from bayes_imu.report.writers import FitRequest


@pytest.mark.slow  # a whole fit with its figures (~7 s under load); the commands' tests run it too
def test_run_fit_returns_what_it_writes_and_says_each_stage_in_order(tmp_path, rng):
    log = tmp_path / "g.csv"
    y = 0.01 * rng.standard_normal((1024, 2))
    np.savetxt(log, y, header="gx,gy", delimiter=",", comments="", fmt="%.9g")
    source = LogSource(log=log, column="gx,gy", rate=100.0, units="rad/s")
    request = FitRequest(source=source, terms=("white",), sensor="gyro", horizon=1.0)
    said = []
    run = run_fit(request, tmp_path / "out", on_read=lambda read: said.append(read.columns),
                  on_axis=lambda axis: said.append(axis.column))
    assert said == [("gx", "gy"), "gx", "gy"]
    assert [a.folder for a in run.axes] == ["gx", "gy"] and run.unit == "rad/s"
    for axis in run.axes:
        written = json.loads((tmp_path / "out" / axis.folder / "summary.json").read_text())
        assert written == json.loads(json.dumps(axis.summary))
        assert axis.drift is not None and axis.drift.units == ("rad",)
    top = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert set(top["axes"]) == {"gx", "gy"} and "noise_variance" in top["worst_axis"]
    assert run.picture_failures == ()


def test_a_datasheet_of_another_kind_is_refused_naming_the_parameter():
    from bayes_imu.cli.main import as_flags

    request = FitRequest(source=LogSource(log=Path("a.csv")),
                         datasheet=(Path("sheet.json"), "gyro", {}))
    with pytest.raises(InputError, match=r"^datasheet=sheet.json: a gyro datasheet, but the log is "
                                         r"in 'm/s\^2'") as caught:
        datasheet_summary(request, None, "m/s^2")
    assert as_flags(str(caught.value)).startswith("--datasheet sheet.json: a gyro datasheet")
    assert datasheet_summary(FitRequest(source=request.source), None, "rad/s") is None
