"""Issue 28: ``convert``, ``apply`` and ``export`` never overwrite a user's file unless --force.

The refusal comes before any work (exit 2, naming the file and --force); the
install itself is atomic and no-clobber (a file created meanwhile is kept too).
"""

import hashlib

import numpy as np
import pytest

import wheelcal
from batch_inputs import simulated_recordings
from wheelcal.cli.main import main
from wheelcal.io import read_recording
from wheelcal.io.atomic import OutputExistsError, atomic_output, atomic_write_text


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def spin(tmp_path_factory):
    d = simulated_recordings(tmp_path_factory.mktemp("spin"), ["spin"], seed=5)
    rec = d / "spin.mcap"
    wheelcal.calibrate(rec).to_json(d / "spin.calibration.json")
    return rec, d / "spin.calibration.json"


def _csv(path):
    t = np.arange(400) / 200.0
    rows = ["time,ax,ay,az"] + [f"{x:.3f},0.1,0.2,9.8" for x in t]
    path.write_text("\n".join(rows) + "\n")


def test_convert_keeps_an_existing_recording(tmp_path, spin, capsys):
    rec, _ = spin
    target = tmp_path / "my.mcap"
    target.write_bytes(rec.read_bytes())  # a real recording, with its radius and sensor id
    before = _digest(target)
    _csv(tmp_path / "log.csv")
    args = ["convert", str(tmp_path / "log.csv"), str(target), "--accel-unit", "m/s^2"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert str(target) in err and "--force" in err
    assert _digest(target) == before
    assert read_recording(target).info.radius_m is not None
    assert main([*args, "--force"]) == 0
    assert _digest(target) != before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_apply_keeps_an_existing_output(tmp_path, spin, capsys):
    rec, cal = spin
    target = tmp_path / "out.mcap"
    target.write_bytes(b"precious")
    args = ["apply", str(cal), str(rec), str(target)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert str(target) in err and "--force" in err
    assert target.read_bytes() == b"precious"
    assert main([*args, "--force"]) == 0
    assert read_recording(target, topic="/imu/data_raw/calibrated").samples > 0


def test_export_keeps_an_existing_output(tmp_path, spin, capsys):
    _, cal = spin
    target = tmp_path / "imu.yaml"
    target.write_text("mine\n")
    args = ["export", str(cal), "--format", "yaml", "--out", str(target)]
    assert main(args) == 2
    assert "--force" in capsys.readouterr().err
    assert target.read_text() == "mine\n"
    assert main([*args, "--force"]) == 0
    assert "imu0:" in target.read_text()


def test_a_file_created_while_writing_is_not_replaced(tmp_path):
    target = tmp_path / "late.txt"
    with pytest.raises(OutputExistsError, match=r"late\.txt: exists"):
        with atomic_output(target, binary=False, replace=False) as stream:
            stream.write("ours")
            target.write_text("theirs")  # another process got there first
    assert target.read_text() == "theirs"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["late.txt"]  # no temporary left
    atomic_write_text(target, "replaced")  # the default still replaces
    assert target.read_text() == "replaced"
