"""ROS bags: small ROS1 and ROS2 bags written here (rosbags' own writers) read back exactly.

Reference: the simulated samples and stamps the test writes; the fit through a bag equals
the fit of the same samples from a CSV (same seed, same numbers).
"""

import json

import numpy as np
import pytest

from bayes_imu.cli.main import main
from bayes_imu.errors import InputError

rosbags = pytest.importorskip(
    "rosbags", reason="the bags extra (pip install 'bayes_imu[bags]') is not installed"
)

RATE = 200.0


def _imu_messages(typestore, gyro, accel, stamps):
    Imu = typestore.types["sensor_msgs/msg/Imu"]
    Header = typestore.types["std_msgs/msg/Header"]
    Time = typestore.types["builtin_interfaces/msg/Time"]
    Vector3 = typestore.types["geometry_msgs/msg/Vector3"]
    Quaternion = typestore.types["geometry_msgs/msg/Quaternion"]
    zeros = np.zeros(9)
    has_seq = "seq" in Header.__dataclass_fields__  # ROS1 headers carry a sequence number
    for k, (g, a, t) in enumerate(zip(gyro, accel, stamps)):
        header = Header(
            stamp=Time(int(t // 10**9), int(t % 10**9)),
            frame_id="imu",
            **({"seq": k} if has_seq else {}),
        )
        yield Imu(
            header, Quaternion(0.0, 0.0, 0.0, 1.0), zeros, Vector3(*g), zeros, Vector3(*a), zeros
        )


def write_bag(path, version, gyro, accel, stamps, topic="/imu0"):
    from rosbags.typesys import Stores, get_typestore

    if version == 1:
        from rosbags.rosbag1 import Writer

        store = get_typestore(Stores.ROS1_NOETIC)
        writer, serialize = Writer(path), store.serialize_ros1
        msgtype = "sensor_msgs/msg/Imu"
    else:
        from rosbags.rosbag2 import Writer

        store = get_typestore(Stores.ROS2_HUMBLE)
        writer, serialize = Writer(path, version=9), store.serialize_cdr
        msgtype = "sensor_msgs/msg/Imu"
    with writer:
        conn = writer.add_connection(topic, msgtype, typestore=store)
        other = writer.add_connection("/status", "std_msgs/msg/String", typestore=store)
        String = store.types["std_msgs/msg/String"]
        for k, msg in enumerate(_imu_messages(store, gyro, accel, stamps)):
            writer.write(conn, int(stamps[k]), serialize(msg, msgtype))
            if k % 100 == 0:
                writer.write(other, int(stamps[k]), serialize(String("ok"), "std_msgs/msg/String"))


@pytest.fixture
def samples(rng):
    n = 4096
    gyro = 1e-3 * rng.standard_normal((n, 3))
    accel = np.array([0.0, 0.0, 9.81]) + 1e-2 * rng.standard_normal((n, 3))
    # integer ns, epoch time
    stamps = 1_700_000_000 * 10**9 + np.arange(n, dtype=np.int64) * int(1e9 / RATE)
    return gyro, accel, stamps


@pytest.mark.parametrize("version", [1, 2])
def test_bag_reads_back_exactly(tmp_path, samples, version):
    from bayes_imu.io.bags import read_imu_bag

    gyro, accel, stamps = samples
    path = tmp_path / ("imu.bag" if version == 1 else "imu_bag")
    write_bag(path, version, gyro, accel, stamps)
    data = read_imu_bag(path, topic="/imu0", columns=["gyro_z", "accel_z"])
    np.testing.assert_array_equal(data.values, np.column_stack([gyro[:, 2], accel[:, 2]]))
    np.testing.assert_allclose(data.time_s, (stamps - stamps[0]) * 1e-9, rtol=0, atol=1e-12)
    assert data.lines[0] == 1 and data.lines[-1] == len(stamps)


def test_fit_from_bag_equals_fit_from_csv(tmp_path, samples):
    """Rate from the header stamps; same samples, same seed: the same posterior as from a CSV."""
    gyro, accel, stamps = samples
    write_bag(tmp_path / "imu.bag", 1, gyro, accel, stamps)
    (tmp_path / "imu.csv").write_text(
        "t,gx\n"
        + "\n".join(
            f"{(t - stamps[0]) * 1e-9:.3f},{float(g)!r}" for t, g in zip(stamps, gyro[:, 0])
        )
    )
    common = ["--terms", "white", "--seed", "4", "--quiet"]
    assert (
        main(
            [
                "fit",
                str(tmp_path / "imu.bag"),
                "--topic",
                "/imu0",
                "--column",
                "gyro_x",
                "--out",
                str(tmp_path / "a"),
                *common,
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "fit",
                str(tmp_path / "imu.csv"),
                "--column",
                "gx",
                "--rate",
                "200",
                "--units",
                "rad/s",
                "--out",
                str(tmp_path / "b"),
                *common,
            ]
        )
        == 0
    )
    a = json.loads((tmp_path / "a" / "summary.json").read_text())
    b = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert (
        a["input"]["rate_source"] == "time column" and abs(a["input"]["rate_hz"] / 200.0 - 1) < 1e-9
    )
    assert a["unit"] == "rad/s" and a["input"]["input_units"] == "rad/s"
    for name in ("noise_variance", "noise_density"):
        assert a["parameters"][name]["median"] == pytest.approx(
            b["parameters"][name]["median"], rel=1e-8
        )


def test_bag_errors_are_one_line(tmp_path, samples, capsys):
    from bayes_imu.io.bags import read_imu_bag

    gyro, accel, stamps = samples
    gappy = stamps.copy()
    gappy[1000:] += 500_000_000  # 0.5 s
    write_bag(tmp_path / "gap.bag", 1, gyro, accel, gappy)
    out = tmp_path / "o"
    assert (
        main(
            [
                "allan",
                str(tmp_path / "gap.bag"),
                "--topic",
                "/imu0",
                "--column",
                "gyro_x",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "message 1001: gap from" in err and err.count("\n") == 1 and not out.exists()
    assert (
        main(
            [
                "allan",
                str(tmp_path / "gap.bag"),
                "--topic",
                "/imu0",
                "--column",
                "gyro_x",
                "--gaps",
                "longest",
                "--out",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
    with pytest.raises(
        InputError, match=r"no topic '/imu'; sensor_msgs/Imu topics in the bag: /imu0"
    ):
        read_imu_bag(tmp_path / "gap.bag", topic="/imu", columns=["gyro_x"])
    with pytest.raises(InputError, match="carries std_msgs/msg/String; expected sensor_msgs/Imu"):
        read_imu_bag(tmp_path / "gap.bag", topic="/status", columns=["gyro_x"])
    with pytest.raises(InputError, match="expected sensor_msgs/Imu fields"):
        read_imu_bag(tmp_path / "gap.bag", topic="/imu0", columns=["mag_x"])
    (tmp_path / "broken.bag").write_bytes(b"#ROSBAG V2.0\n" + bytes(100))
    with pytest.raises(InputError, match="cannot read as a ROS bag"):
        read_imu_bag(tmp_path / "broken.bag", topic="/imu0", columns=["gyro_x"])
    assert main(["allan", str(tmp_path / "gap.bag"), "--column", "gyro_x", "--out", str(out)]) == 2
    assert "needs --topic" in capsys.readouterr().err


def test_scene_reads_a_bag_as_fit_does(tmp_path, samples):
    """A scene sensor read from a ROS bag (``topic``, no ``rate_hz``: the header stamps give it)
    gets the bounds of the same samples from a CSV at the rate the stamps span ((n - 1) / (last -
    first), integer nanoseconds): the same numbers, bit for bit."""
    from bayes_imu.report.scene import build_report, read_scene

    gyro, accel, stamps = samples
    write_bag(tmp_path / "imu.bag", 1, gyro, accel, stamps)
    (tmp_path / "imu.csv").write_text("gz\n" + "".join(f"{float(g)!r}\n" for g in gyro[:, 2]))
    rate = (len(stamps) - 1) / (int(stamps[-1] - stamps[0]) * 1e-9)
    head = ('[scene]\nname = "s"\noutages_s = [1, 5]\ncredibility = 0.9\n'
            '[[sensor]]\nname = "imu"\nkind = "gyro"\n')
    bag = tmp_path / "bag.toml"
    bag.write_text(head + 'log = "imu.bag"\ntopic = "/imu0"\ncolumn = "gyro_z"\nunits = "rad/s"\n')
    csv = tmp_path / "csv.toml"
    csv.write_text(head + f'log = "imu.csv"\ncolumn = "gz"\nunits = "rad/s"\nrate_hz = {rate!r}\n')
    from_bag, from_csv = (build_report(read_scene(p), rng=2).sensors[0] for p in (bag, csv))
    assert from_bag.fit.allan.rate_hz == rate and from_bag.fit.allan.n_samples == len(stamps)
    assert [dict(b, axis="gz") for b in from_bag.bounds] == list(from_csv.bounds)
