"""Fleets: fit-batch on a small Dask LocalCluster equals serial runs byte for byte; failures
isolated."""

import json
from pathlib import Path

import numpy as np
import pytest

from bayes_imu.cli.main import main

pytest.importorskip(
    "distributed", reason="the fleet extra (pip install 'bayes_imu[fleet]') is not installed"
)


@pytest.fixture
def logs(tmp_path, rng):
    folder = tmp_path / "logs"
    folder.mkdir()
    paths = []
    for k, sigma in enumerate((0.01, 0.02, 0.05)):
        path = folder / f"unit{k:03d}.csv"
        path.write_text(
            "gx\n" + "\n".join(f"{v:.8f}" for v in sigma * rng.standard_normal(2**13)) + "\n"
        )
        paths.append(path)
    bad = folder / "unit_bad.csv"
    bad.write_text("gx\n0.1\n0.2\nnan\n0.3\n")
    return paths, bad


OPTIONS = ["--column", "gx", "--rate", "100", "--terms", "white", "--seed", "5", "--units", "deg/s"]


def _serial_summaries(tmp_path, paths):
    out = {}
    for path in paths:
        target = tmp_path / "serial" / path.stem
        assert main(["fit", str(path), *OPTIONS, "--out", str(target), "--quiet"]) == 0
        out[path.stem] = (target / "summary.json").read_bytes()
    return out


def test_local_cluster_matches_serial_and_isolates_failures(tmp_path, logs, capsys):
    paths, bad = logs
    out = tmp_path / "batch"
    status = main(
        [
            "fit-batch",
            *map(str, paths),
            str(bad),
            *OPTIONS,
            "--workers",
            "2",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert status == 2  # one log failed
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"bayes-imu: error: unit_bad: {bad}: line 4, column 'gx': got 'nan'; expected a finite "
        "number"
    ]
    batch = json.loads((out / "batch.json").read_text())
    assert [r["status"] for r in batch["logs"]] == [0, 0, 0, 2] and batch["n_failed"] == 1
    assert batch["scheduler"] == "LocalCluster" and batch["logs_per_minute"] > 0
    import os

    # every log ran in a worker process, not in this one
    assert all(r["worker"].rsplit(":", 1)[1] != str(os.getpid()) for r in batch["logs"])
    assert not (out / "unit_bad").exists()
    serial = _serial_summaries(tmp_path, paths)
    for path in paths:  # the same seed gives the same bytes, whichever process ran it
        assert (out / path.stem / "summary.json").read_bytes().replace(
            str(out / path.stem).encode(), b""
        ) == serial[path.stem].replace(str(tmp_path / "serial" / path.stem).encode(), b"")


@pytest.mark.slow  # ~8 s (a second Dask cluster): the nightly job; a local cluster: the test above
def test_existing_scheduler_and_serial_mode(tmp_path, logs, monkeypatch):
    """Run as a user runs it (no output-process setting): a Dask worker is a daemonic process, which
    may not start the fit's output process (it failed every log before); a serial batch writes
    in-process too (a new output process per log would import ArviZ and matplotlib again each
    time)."""
    from dask.distributed import LocalCluster

    import bayes_imu.report.runs as runs
    from bayes_imu.report.worker import WORKERS_ENV, OutputWriter

    monkeypatch.delenv(WORKERS_ENV, raising=False)
    chosen = []

    class Recording(OutputWriter):
        def __init__(self, background=None, warm=()):
            chosen.append(background)
            super().__init__(background, warm)

    monkeypatch.setattr(runs, "OutputWriter", Recording)  # the fit's run (report.runs)
    paths, _ = logs
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        assert (
            main(
                [
                    "fit-batch",
                    *map(str, paths[:2]),
                    *OPTIONS,
                    "--scheduler",
                    cluster.scheduler_address,
                    "--out",
                    str(tmp_path / "remote"),
                    "--quiet",
                ]
            )
            == 0
        )
    assert (
        main(
            [
                "fit-batch",
                *map(str, paths[:2]),
                *OPTIONS,
                "--serial",
                "--out",
                str(tmp_path / "local"),
                "--quiet",
            ]
        )
        == 0
    )
    for path in paths[:2]:
        remote = json.loads((tmp_path / "remote" / path.stem / "summary.json").read_text())
        local = json.loads((tmp_path / "local" / path.stem / "summary.json").read_text())
        assert remote["parameters"] == local["parameters"]
    assert json.loads((tmp_path / "local" / "batch.json").read_text())["scheduler"] == "serial"
    assert chosen == [False, False]  # the serial batch's two fits, in this process


def test_batch_refuses_busy_output_and_bad_scheduler(tmp_path, logs, capsys, monkeypatch):
    import bayes_imu.report.fleet

    # the refusal, without 10 s of retries
    monkeypatch.setattr(bayes_imu.report.fleet, "CONNECT_TIMEOUT", "1s")
    paths, _ = logs
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "x").write_text("x")
    assert main(["fit-batch", str(paths[0]), *OPTIONS, "--serial", "--out", str(busy)]) == 2
    assert "folder exists and is not empty ('x')" in capsys.readouterr().err
    assert (
        main(["fit-batch", str(paths[0]), *OPTIONS, "--serial", "--out", str(busy), "--force"]) == 2
    )
    assert "--force replaces only a previous bayes_imu result" in capsys.readouterr().err
    assert sorted(p.name for p in busy.iterdir()) == ["x"]
    assert main(["fit-batch", str(paths[0]), *OPTIONS, "--scheduler", "tcp://127.0.0.1:1",
                 "--out", str(tmp_path / "o")]) == 2
    assert "cannot connect" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # the claimed folder is removed with the failed run


def _task(job):
    """A library task: succeed, fail as a user error, or fail internally, by the job's argument."""
    from bayes_imu.errors import InputError

    if job.request == ("user",):
        raise InputError("bad input in job")
    if job.request == ("bug",):
        raise ZeroDivisionError("division by zero")


def test_run_batch_maps_failures_to_statuses():
    """The library runs any task (it never calls the command line): 0 success, 2 user error, 1
    internal."""
    from bayes_imu.report.fleet import BatchJob, run_batch

    jobs = [BatchJob("ok", ("ok",)), BatchJob("user", ("user",)), BatchJob("bug", ("bug",))]
    results = run_batch(jobs, _task, scheduler="serial")
    assert [r.status for r in results] == [0, 2, 1]
    assert results[1].error == "bayes-imu: error: bad input in job"
    assert results[2].error == "bayes-imu: internal error: ZeroDivisionError: division by zero"
    assert [r.name for r in results] == ["ok", "user", "bug"]


def _subparser(name):
    from bayes_imu.cli.main import _build_parser

    parser = _build_parser()
    action = next(a for a in parser._actions if a.dest == "command")
    return action.choices[name]


#: options of a command that say where and how to write and print, not what to fit
_RUN_OPTIONS = {"help", "out", "force", "quiet"}
_BATCH_ONLY = {"logs", "scheduler", "workers", "serial"}


def _request_fields():
    import dataclasses

    from bayes_imu.allan.pipeline import LogSource
    from bayes_imu.report.writers import FitRequest

    return ({f.name for f in dataclasses.fields(LogSource)} - {"log", "label"}) | \
        ({f.name for f in dataclasses.fields(FitRequest)} - {"source"})


def test_every_fit_option_is_a_field_of_the_request_a_batch_hands_each_log():
    """The parser's options against the request's fields, both ways, so that a new ``fit`` option
    cannot be dropped on the way to a batch's logs (as a hand-kept list of forwarded options
    could)."""
    fit = {a.dest for a in _subparser("fit")._actions} - _RUN_OPTIONS - {"log"}
    batch = {a.dest for a in _subparser("fit-batch")._actions} - _RUN_OPTIONS - _BATCH_ONLY
    assert fit == _request_fields()
    assert batch == fit - {"allan_table", "samples"}  # a batch fits logs, not Allan tables


def _non_default(action):
    """A value of ``action`` other than its default, as argv words."""
    if action.nargs == 0:
        return [action.option_strings[0]]
    if action.choices:
        other = next(str(c) for c in action.choices if c != action.default)
        return [action.option_strings[0], other]
    # a number, or a file an option reads (the shipped datasheet of --datasheet)
    shipped = Path(__file__).resolve().parents[1] / "data_synthetic" / "gyro_datasheet.toml"
    for text in ("7", "0.5", str(shipped)):
        try:
            value = action.type(text) if action.type else text
        except Exception:  # noqa: BLE001 - an argparse type refuses with one of several errors
            continue
        if value != action.default:
            return [action.option_strings[0], text]
    raise AssertionError(f"no test value for {action.dest}")


@pytest.mark.parametrize("left_out", ["--horizon", "--times"])
def test_every_fit_option_reaches_a_batch_job_as_fit_would_read_it(tmp_path, monkeypatch,
                                                                   left_out):
    """fit-batch with every option set away from its default: each job's request is, field for
    field, the request ``fit`` makes of the same log and options, and every option's value is in
    it (``--horizon`` and ``--times`` exclude each other: each is left out once)."""
    import dataclasses

    import bayes_imu.report.fleet as fleet
    from bayes_imu.cli.main import _fit_request
    from bayes_imu.report.fleet import JobResult

    actions = [a for a in _subparser("fit-batch")._actions
               if a.option_strings and a.dest not in _RUN_OPTIONS | _BATCH_ONLY
               and left_out not in a.option_strings]
    words = [w for a in actions for w in _non_default(a)]
    if "--input" in words:  # increments take increment units: keep the pair consistent
        words[words.index("--units") + 1] = "rad"
    jobs = []

    def run_batch(batch, task, **kwargs):
        jobs.extend(batch)
        return [JobResult(j.name, 2, "bayes-imu: error: not run", 0.0, "") for j in batch]

    monkeypatch.setattr(fleet, "run_batch", run_batch)
    logs = [tmp_path / "a.csv", tmp_path / "b.csv"]
    argv = ["fit-batch", *map(str, logs), *words, "--serial", "--out", str(tmp_path / "out")]
    assert main(argv + ["--quiet"]) == 2
    assert [j.request.source.log for j in jobs] == logs
    fit_args = _subparser("fit").parse_args([str(logs[0]), *words, "--out", str(tmp_path / "fit")])
    assert jobs[0].request == _fit_request(fit_args)
    defaults = _subparser("fit").parse_args([str(logs[0]), "--out", "x"])
    request = dataclasses.asdict(jobs[0].request)
    request.update(request.pop("source"))
    for action in actions:
        assert getattr(defaults, action.dest) != getattr(fit_args, action.dest), action.dest
        given = getattr(fit_args, action.dest)
        expected = tuple(given.split(",")) if action.dest == "terms" else given
        assert request[action.dest] == expected, action.dest


def test_logs_whose_names_look_like_options_are_fitted_as_logs(tmp_path, monkeypatch, rng):
    """``./-unit2.csv`` and ``./--terms=white.csv`` are logs: an argv rebuilt from their paths
    (``-unit2.csv``, ``--terms=white.csv``) read them as options, and both fits failed."""
    monkeypatch.chdir(tmp_path)
    names = ["-unit2.csv", "--terms=white.csv"]
    for name in names:
        values = 0.01 * rng.standard_normal(2048)
        (tmp_path / name).write_text("gx\n" + "".join(f"{v:.8f}\n" for v in values))
    status = main(["fit-batch", *(f"./{n}" for n in names), "--column", "gx", "--rate", "100",
                   "--terms", "random_walk,white", "--serial", "--out", "out", "--quiet"])
    batch = json.loads((tmp_path / "out" / "batch.json").read_text())
    assert status == 0, batch
    assert [r["status"] for r in batch["logs"]] == [0, 0]
    for row, name in zip(batch["logs"], names):
        summary = json.loads((tmp_path / "out" / row["name"] / "summary.json").read_text())
        assert summary["log"] == name and sorted(summary["model"]) == ["random_walk", "white"]


def test_a_batch_says_which_fits_flag_themselves(tmp_path, rng, capsys):
    """fit-batch printed only "2 of 2 logs fitted" where a fit alone warns (a new user's report):
    batch.json carries each axis's own checks (converged, adequate, stationary) and counts, and the
    command warns, one line a log, naming the log and what its summary.json flags."""
    folder = tmp_path / "logs"
    folder.mkdir()
    steady = 0.01 * rng.standard_normal(2**14)
    changing = steady * np.where(np.arange(steady.size) < steady.size // 2, 1.0, 3.0)
    for name, values in (("steady", steady), ("changing", changing)):
        (folder / f"{name}.csv").write_text("gx\n" + "\n".join(f"{v:.8f}" for v in values) + "\n")
    out = tmp_path / "batch"
    status = main(["fit-batch", str(folder / "steady.csv"), str(folder / "changing.csv"),
                   *OPTIONS, "--serial", "--out", str(out), "--quiet"])
    assert status == 0
    batch = json.loads((out / "batch.json").read_text())
    checks = {e["name"]: e["checks"]["gx"] for e in batch["logs"]}
    assert checks["steady"] == {"converged": True, "adequate": True, "stationary": True}
    assert checks["changing"]["stationary"] is False
    summary = json.loads((out / "changing" / "summary.json").read_text())
    assert checks["changing"]["adequate"] == summary["adequacy"]["adequate"]
    assert batch["n_unconverged"] == 0
    assert batch["n_inadequate"] == int(checks["changing"]["adequate"] is False)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bayes-imu: warning: changing: gx: ")
    assert "the noise changes during the log" in err[0]
