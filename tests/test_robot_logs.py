"""Issue 28: rosbag2 ``.db3``, ROS 1 ``.bag`` and ROS 1-encoded MCAP are read.

Files written by the tools' own writers (:mod:`robot_logs`); every sample,
stamp and gyro reading read back equals what was written, through the same
decoders and checks as the MCAP path, and ``wheelcal calibrate`` gives the
same calibration as for the contract MCAP of the same samples.
"""

import json

import numpy as np
import pytest

from robot_logs import imu_messages, write_bag, write_db3, write_ros1_mcap
from wheelcal.cli.main import main
from wheelcal.io import read_recording, write_recording
from wheelcal.io.errors import CorruptFileError, TopicError
from wheelcal.simulate import table2
from wheelcal.simulate.session import simulate_session


@pytest.fixture(scope="module")
def short():
    """2,400 samples (12 s at 200 Hz) with a gyro."""
    rng = np.random.default_rng(3)
    time_ns = 1_700_000_000_000_000_000 + np.arange(2400) * 5_000_000
    accel = rng.normal([0.1, -0.2, 9.8], 0.05, size=(2400, 3))
    gyro = rng.normal(0.0, 0.3, size=(2400, 3))
    return time_ns, accel, gyro


def _check(recording, time_ns, accel, gyro):
    np.testing.assert_array_equal(recording.accel_mps2, accel)
    np.testing.assert_array_equal(
        recording.epoch_unix_ns + np.rint(recording.time_s * 1e9).astype(np.int64), time_ns
    )
    np.testing.assert_array_equal(recording.gyro_radps, gyro)
    assert recording.topic == "/imu/data_raw"


def test_rosbag2_db3_file_and_folder(tmp_path, short):
    time_ns, accel, gyro = short
    db3 = write_db3(tmp_path / "bag", time_ns, imu_messages(time_ns, accel, gyro))
    _check(read_recording(db3), time_ns, accel, gyro)
    _check(read_recording(tmp_path / "bag"), time_ns, accel, gyro)


def test_rosbag2_with_zstd_compressed_messages(tmp_path, short):
    time_ns, accel, gyro = short
    messages = imu_messages(time_ns, accel, gyro)
    write_db3(tmp_path / "bag", time_ns, messages, zstd_messages=True)
    _check(read_recording(tmp_path / "bag"), time_ns, accel, gyro)


@pytest.mark.parametrize("compression", ["none", "bz2", "lz4"])
def test_ros1_bag(tmp_path, short, compression):
    time_ns, accel, gyro = short
    messages = imu_messages(time_ns, accel, gyro, ros1=True)
    bag = write_bag(tmp_path / "imu.bag", time_ns, messages, compression=compression)
    _check(read_recording(bag), time_ns, accel, gyro)


def test_ros1_encoded_mcap(tmp_path, short):
    time_ns, accel, gyro = short
    messages = imu_messages(time_ns, accel, gyro, ros1=True)
    path = write_ros1_mcap(tmp_path / "converted.mcap", time_ns, messages)
    _check(read_recording(path), time_ns, accel, gyro)


def test_damaged_and_foreign_bags_are_named_errors(tmp_path, short):
    time_ns, accel, _ = short
    bag = write_bag(tmp_path / "cut.bag", time_ns, imu_messages(time_ns, accel, ros1=True))
    data = bag.read_bytes()
    bag.write_bytes(data[: len(data) // 2])  # a recording cut off: no index at the end
    with pytest.raises(CorruptFileError, match=r"cut\.bag: .*rosbag reindex"):
        read_recording(bag)
    db3 = write_db3(tmp_path / "other", time_ns, imu_messages(time_ns, accel), topic="/x")
    with pytest.raises(TopicError, match=r"no topic '/imu'.*/x \[sensor_msgs/msg/Imu"):
        read_recording(db3, topic="/imu")


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    d = tmp_path_factory.mktemp("robot")
    rec = simulate_session(table2(rng=np.random.default_rng(8)), np.random.default_rng(9)).recording
    write_recording(rec, d / "spin.mcap")
    time_ns = rec.epoch_unix_ns + np.rint(rec.time_s * 1e9).astype(np.int64)
    write_db3(d / "spin_bag", time_ns, imu_messages(time_ns, rec.accel_mps2))
    write_bag(d / "spin_ros1.bag", time_ns, imu_messages(time_ns, rec.accel_mps2, ros1=True))
    return d


def test_calibrate_reads_db3_and_bag_like_the_mcap(session):
    out = session / "out"
    files = [session / "spin.mcap", *session.glob("spin_bag/*.db3"), session / "spin_ros1.bag"]
    args = ["calibrate", *map(str, files), "--out", str(out), "--radius", "0.28", "--quiet"]
    assert main(args) == 0
    docs = [json.loads((out / f"{f.stem}.calibration.json").read_text()) for f in files]
    assert [d["source"]["file"] for d in docs] == [str(f) for f in files]
    for doc in docs[1:]:
        for key in ("gain", "offset_mps2", "gain_std"):
            np.testing.assert_allclose(doc["sensor"][key], docs[0]["sensor"][key], rtol=1e-9)
