"""ISO 8601 time stamps, the row filter (``--where``) and the added input units (issue 38)."""

import datetime
import json
import math

import numpy as np
import pytest

from bayes_imu.cli.main import main
from bayes_imu.errors import InputError
from bayes_imu.io.readers import UNITS, read_columns, to_si
from bayes_imu.io.rows import iso_seconds, looks_iso, parse_where


def _reference_seconds(stamps):
    """Seconds since the first stamp by Python's datetime (an independent parser, microseconds)."""
    parsed = [datetime.datetime.fromisoformat(s.replace("Z", "+00:00")) for s in stamps]
    parsed = [p if p.tzinfo else p.replace(tzinfo=datetime.timezone.utc) for p in parsed]
    return [(p - parsed[0]) / datetime.timedelta(microseconds=1) * 1e-6 for p in parsed]


def test_iso_stamps_with_zones_and_fractions_match_datetime():
    stamps = [
        "2026-11-25T12:00:00.123Z",
        "2026-11-25T14:00:00.133+02:00",
        "2026-11-25T07:00:00.143-05:00",
        "2026-11-25T12:00:00.153",
        "2026-11-25 12:00:00.163Z",
        "2026-11-26T01:30:00.173+1330",
        "2026-11-25T12:00:01Z",
        "2024-02-29T12:00:00.5Z",
    ]
    got = iso_seconds(stamps, list(range(1, 9)), "log")
    np.testing.assert_allclose(got, _reference_seconds(stamps), rtol=1e-15, atol=1e-12)
    assert got[1] == pytest.approx(0.010, abs=1e-15) and got[5] == pytest.approx(0.050, abs=1e-15)


def test_iso_stamps_keep_nanoseconds_over_days():
    """Integer nanoseconds: 3 days and 1 ns apart gives 259200.000000001 s to the float's spacing
    there (6e-11 s; a float of epoch seconds near 1.8e9, spacing 2.4e-7 s, would lose the ns)."""
    got = iso_seconds(
        ["2026-11-25T00:00:00.000000000Z", "2026-11-28T00:00:00.000000001Z"], [1, 2], "x"
    )
    assert got[1] - 259200.0 == pytest.approx(1e-9, rel=0.1)


@pytest.mark.parametrize(
    "bad",
    [
        "2026-13-01T00:00:00Z",
        "2026-02-30T00:00:00Z",
        "2026-11-25T24:00:00Z",
        "2026-11-25",
        "12:00:00",
        "2026-11-25T12:00:00.1.2Z",
        "1.5",
    ],
)
def test_a_bad_stamp_is_named_with_its_line(bad):
    with pytest.raises(InputError, match=r"log: line 7: time stamp .*ISO 8601"):
        iso_seconds(["2026-11-25T12:00:00Z", bad], [6, 7], "log")
    assert not looks_iso(bad) or bad[:7] in ("2026-13", "2026-02", "2026-11")  # shape only


def test_read_columns_reads_iso_stamps_and_filters_rows(tmp_path):
    path = tmp_path / "log.csv"
    rows = [
        (
            f"2026-11-25T12:00:{i // 100:02d}.{i % 100:02d}0Z",
            0.001 * ((i * 7919) % 13) - 0.006,
            i // 50,
            i % 3,
        )
        for i in range(200)
    ]
    path.write_text(
        "t,gx,period,status\n" + "".join(f"{t},{v:.6f},{p},{s}\n" for t, v, p, s in rows)
    )
    data = read_columns(path, columns=["gx"], time_column="t", where="period == 2 and status != 1")
    kept = [(i, r) for i, r in enumerate(rows) if r[2] == 2 and r[3] != 1]
    assert data.time_iso and data.values[:, 0].tolist() == [round(r[1], 6) for _, r in kept]
    np.testing.assert_allclose(data.time_s, [0.01 * i for i, _ in kept], rtol=0, atol=1e-12)
    assert data.lines.tolist() == [i + 2 for i, _ in kept]  # the header is line 1
    with pytest.raises(InputError, match="no row satisfies where='period > 9'"):
        read_columns(path, columns=["gx"], where="period > 9")
    with pytest.raises(InputError, match="no column 'phase'"):
        read_columns(path, columns=["gx"], where="phase == 1")


@pytest.mark.parametrize(
    "text, conditions",
    [
        ("period == 0", [("period", "==", 0.0)]),
        ("period==2 and status != 1", [("period", "==", 2.0), ("status", "!=", 1.0)]),
        (
            "temp_C >= -5.5e0, temp_C < 40 && 3 <= 2",
            [("temp_C", ">=", -5.5), ("temp_C", "<", 40.0), ("3", "<=", 2.0)],
        ),
        ('"my col" > .5', [("my col", ">", 0.5)]),
    ],
)
def test_where_grammar(text, conditions):
    assert list(parse_where(text).conditions) == conditions


@pytest.mark.parametrize(
    "text",
    [
        "__import__('os').system('true')",
        "period = 0",
        "period == zero",
        "period == 0 or period == 1",
        "",
        "period ==",
        "== 0",
        "period == 1e999",
    ],
)
def test_where_refuses_anything_else_in_one_line(text):
    with pytest.raises(InputError) as info:
        parse_where(text)
    assert "\n" not in str(info.value) and "where" in str(info.value)


def test_added_units_convert_by_their_definitions():
    """mrad/s = 1e-3 rad/s; ug = 1e-6 g with standard gravity 9.80665 m/s^2 (CGPM 1901)."""
    assert to_si([2.0], "mrad/s")[0] == 2e-3 and UNITS["mrad/s"][0] == "gyro"
    assert (
        to_si([3.0], "ug")[0] == pytest.approx(3 * 9.80665e-6, rel=1e-15)
        and UNITS["ug"][0] == "accel"
    )
    assert to_si([1.0], "deg/h")[0] == pytest.approx(math.pi / 180 / 3600, rel=1e-15)


@pytest.mark.slow
def test_fit_with_where_and_iso_stamps_on_the_command_line(tmp_path, capsys):
    """A two-period log with ISO stamps (+02:00) fitted on its second period only, in mrad/s."""
    rng = np.random.default_rng(8)
    start = datetime.datetime(
        2026, 11, 25, 23, 59, tzinfo=datetime.timezone(datetime.timedelta(hours=2))
    )
    lines = ["time,gx,period"] + [
        f"{(start + datetime.timedelta(milliseconds=10 * i)).isoformat(timespec='milliseconds')},"
        f"{(5.0 if i < 1000 else 1.0) * rng.standard_normal():.6f},{i // 1000}"
        for i in range(2000)
    ]
    (tmp_path / "log.csv").write_text("\n".join(lines) + "\n")
    argv = [
        "fit",
        str(tmp_path / "log.csv"),
        "--column",
        "gx",
        "--time-column",
        "time",
        "--units",
        "mrad/s",
        "--terms",
        "white",
        "--out",
        str(tmp_path / "f"),
        "--quiet",
    ]
    assert main(argv + ["--where", "period == 1"]) == 0
    summary = json.loads((tmp_path / "f" / "summary.json").read_text())
    assert (
        summary["input"]["where"] == "period == 1" and summary["input"]["time_stamps"] == "ISO 8601"
    )
    assert summary["input"]["rate_hz"] == pytest.approx(100.0, rel=1e-9)
    assert summary["n_samples"] == 1000
    # the second period's white noise, 1 mrad/s per sample: variance 1e-6 (rad/s)^2 within 15%
    assert summary["parameters"]["noise_variance"]["median"] == pytest.approx(1e-6, rel=0.15)
    argv[argv.index("--out") + 1] = str(tmp_path / "g")
    assert main(argv + ["--where", "period = 1"]) == 2
    assert "is not a condition" in capsys.readouterr().err and not (tmp_path / "g").exists()


def test_a_scene_sensor_takes_where(tmp_path):
    from bayes_imu.report.scene import read_scene

    (tmp_path / "log.csv").write_text("gx,period\n0.1,0\n0.2,1\n")
    head = '[scene]\noutages_s = [10]\n[[sensor]]\nname = "s"\nkind = "gyro"\nlog = "log.csv"\n'
    body = 'column = "gx"\nrate_hz = 100\nunits = "mrad/s"\n'
    (tmp_path / "a.toml").write_text(head + body + 'where = "period == 1"\n')
    assert read_scene(tmp_path / "a.toml").sensors[0].reading.where == "period == 1"
    (tmp_path / "b.toml").write_text(head + body + 'where = "period := 1"\n')
    with pytest.raises(InputError, match="is not a condition"):
        read_scene(tmp_path / "b.toml")
