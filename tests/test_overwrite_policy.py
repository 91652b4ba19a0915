"""Issue 40, item 5: one overwrite policy for every command that writes.

A re-run replaces what wheelcal wrote from the same input (and says so); a file
it did not write — a recording, a user's file — is replaced only with
``--force``; an input is never written over, even with ``--force`` and through
links; a device is never renamed over (before: ``simulate`` replaced a
recording, ``convert good.csv good.csv --force`` and ``export self.json --out
self.json --force`` destroyed their input, and as root ``export --out /dev/full
--force`` replaced the device node with a file).
"""

import hashlib
import json
import os
import stat

import numpy as np
import pytest

from batch_inputs import pipeline_file, simulated_recordings
from wheelcal.cli.main import main
from wheelcal.io import read_recording
from wheelcal.io.atomic import NotRegularFileError, atomic_write_text
from wheelcal.io.ownership import Output, OutputRefusedError, claim_outputs, examine, origin_of


def _digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def spin(tmp_path_factory):
    d = simulated_recordings(tmp_path_factory.mktemp("spin"), ["spin"], seed=5)
    out = d / "out"
    assert main(["calibrate", str(d / "spin.mcap"), "--out", str(out), "--quiet"]) == 0
    return d / "spin.mcap", out / "spin.calibration.json"


def _foreign_recording(path):
    """A recording wheelcal did not write (the mcap library's writer, another library name)."""
    from mcap.writer import Writer

    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start(profile="ros2", library="someone else's logger")
        writer.finish()


def test_simulate_keeps_a_recording_it_did_not_write(tmp_path, capsys):
    target = tmp_path / "real.mcap"
    _foreign_recording(target)
    before = _digest(target)
    assert main(["simulate", str(target), "--free-spin-only"]) == 2
    err = capsys.readouterr().err
    assert "is a recording wheelcal did not write" in err and "--force" in err
    assert _digest(target) == before
    assert main(["simulate", str(target), "--free-spin-only", "--force"]) == 0
    assert read_recording(target).samples > 0


def test_simulate_replaces_its_own_output_of_the_same_options_and_says_so(tmp_path, capsys):
    out, truth = tmp_path / "sim.mcap", tmp_path / "truth.json"
    args = ["simulate", str(out), "--seed", "3", "--free-spin-only", "--truth", str(truth)]
    assert main(args) == 0
    capsys.readouterr()
    assert main(args) == 0  # the same input (its options): replaced, and said
    err = capsys.readouterr().err
    assert f"note: replacing {out} (wheelcal wrote it from the same input)" in err
    assert f"note: replacing {truth}" in err
    other = ["simulate", str(out), "--seed", "4", "--free-spin-only"]
    assert main(other) == 2  # another seed is another recording: not without --force
    assert "wheelcal wrote it from another input" in capsys.readouterr().err
    user = tmp_path / "notes.json"
    user.write_text('{"mine": true}\n')
    assert main([*other, "--truth", str(user), "--force"]) == 0
    assert json.loads(user.read_text())["format"] == "wheelcal.truth/1"  # --force: replaced


def _csv(path):
    t = np.arange(400) / 200.0
    path.write_text("\n".join(["time,ax,ay,az"] + [f"{x:.3f},0.1,0.2,9.8" for x in t]) + "\n")


@pytest.mark.parametrize("how", ["same name", "symbolic link", "hard link"])
def test_convert_never_writes_onto_its_input_even_with_force(tmp_path, capsys, how):
    source = tmp_path / "good.csv"
    _csv(source)
    before = _digest(source)
    target = {"same name": source, "symbolic link": tmp_path / "link.mcap"}.get(how)
    if how == "symbolic link":
        target.symlink_to(source)
    elif how == "hard link":
        target = tmp_path / "hard.mcap"
        os.link(source, target)
    args = ["convert", str(source), str(target), "--accel-unit", "m/s^2", "--force"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "is an input of this command" in err and "even with --force" in err
    assert _digest(source) == before


def test_export_never_writes_onto_its_calibration_even_with_force(tmp_path, spin, capsys):
    _, cal = spin
    own = tmp_path / "self.json"
    own.write_bytes(cal.read_bytes())
    before = _digest(own)
    assert main(["export", str(own), "--format", "yaml", "--out", str(own), "--force"]) == 2
    assert "is an input of this command" in capsys.readouterr().err
    assert _digest(own) == before


def test_export_replaces_its_own_output_and_refuses_a_users_file(tmp_path, spin, capsys):
    _, cal = spin
    out = tmp_path / "imu.yaml"
    args = ["export", str(cal), "--format", "yaml", "--out", str(out)]
    assert main(args) == 0
    assert main([*args[:3], "imu_calib", *args[4:]]) == 0  # same CAL.json: replaced, said
    assert "note: replacing" in capsys.readouterr().err
    out.write_text("mine\n")
    assert main(args) == 2 and out.read_text() == "mine\n"
    assert "wheelcal did not write it" in capsys.readouterr().err


@pytest.mark.skipif(os.geteuid() != 0, reason="making a device node needs root")
def test_a_device_is_never_renamed_over_even_as_root_with_force(tmp_path, spin, capsys):
    _, cal = spin
    device = tmp_path / "full"
    os.mknod(device, stat.S_IFCHR | 0o666, os.makedev(1, 7))  # the node of /dev/full
    args = ["export", str(cal), "--format", "c", "--out", str(device), "--force"]
    assert main(args) == 2
    assert "is a device, not a regular file" in capsys.readouterr().err
    assert stat.S_ISCHR(os.lstat(device).st_mode)
    with pytest.raises(NotRegularFileError, match="is a device"):  # the writer itself refuses
        atomic_write_text(device, "x")
    assert stat.S_ISCHR(os.lstat(device).st_mode)
    assert [p.name for p in tmp_path.iterdir()] == ["full"]  # no temporary left


def test_a_fifo_is_never_replaced_even_if_it_appears_while_writing(tmp_path):
    from wheelcal.io.atomic import atomic_output

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(NotRegularFileError, match="is a FIFO"):
        atomic_write_text(fifo, "x")
    late = tmp_path / "late"
    with pytest.raises(NotRegularFileError, match="is a FIFO"):
        with atomic_output(late, binary=False) as stream:
            stream.write("ours")
            os.mkfifo(late)  # made by someone else meanwhile: the install checks again
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode) and stat.S_ISFIFO(os.lstat(late).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["late", "pipe"]  # no temporary


def test_calibrate_keeps_a_users_file_and_replaces_its_own(tmp_path, spin, capsys):
    rec, _ = spin
    out = tmp_path / "out"
    out.mkdir()
    user = out / "spin.calibration.json"
    user.write_text('{"my": "notes"}\n')
    args = ["calibrate", str(rec), "--out", str(out), "--quiet"]
    assert main(args) == 2
    assert "wheelcal did not write it" in capsys.readouterr().err
    assert json.loads(user.read_text()) == {"my": "notes"}
    assert main([*args, "--force"]) == 0
    capsys.readouterr()
    assert main(args) == 0  # the same recording: replaced, and said
    assert "note: replacing" in capsys.readouterr().err


def test_apply_replaces_its_own_copy_of_the_same_inputs(tmp_path, spin, capsys):
    rec, cal = spin
    out = tmp_path / "calibrated.mcap"
    args = ["apply", str(cal), str(rec), str(out)]
    assert main(args) == 0
    assert main(args) == 0
    assert "note: replacing" in capsys.readouterr().err
    # the copy's mark is its own, not the source's
    assert examine(out, origin_of([cal, rec]), (cal, rec)).state == "ours"


def test_batch_keeps_a_users_report_in_its_output_folder(tmp_path, spin, capsys):
    rec, _ = spin
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.md").write_text("# my own report\n")
    path = pipeline_file(tmp_path / "p.toml", out, str(rec))
    assert main(["batch", str(path)]) == 2
    assert "report.md exists and wheelcal did not write it" in capsys.readouterr().err
    assert not (out / "spin.calibration.json").exists()  # refused before any work
    assert main(["batch", str(path), "--force"]) == 0
    assert "Repeatability report" in (out / "report.md").read_text()
    other = pipeline_file(tmp_path / "other.toml", out, str(rec), extra="[run]\nrerun = false\n")
    capsys.readouterr()
    assert main(["batch", str(other)]) == 2  # another pipeline's report: not without --force
    assert "wheelcal wrote it from another input" in capsys.readouterr().err


def test_an_unmarked_output_follows_the_marked_ones_written_with_it(tmp_path):
    md, csv = tmp_path / "report.md", tmp_path / "sessions.csv"
    origin = origin_of([tmp_path / "p.toml"])
    md.write_text(f"# r\n<!-- wheelcal-output: origin={origin} -->\n")
    csv.write_text("a,b\n1,2\n")
    outputs = [Output(md, origin), Output(csv, origin, follows=True)]
    assert len(claim_outputs(outputs)) == 2
    md.write_text("# someone else's\n")
    with pytest.raises(OutputRefusedError, match=r"sessions\.csv exists and wheelcal did not"):
        claim_outputs(outputs)


def test_a_calibration_written_before_marks_counts_by_its_source(tmp_path, spin):
    rec, cal = spin
    doc = json.loads(cal.read_text())
    doc.pop("wheelcal_output")
    old = tmp_path / "old.calibration.json"
    old.write_text(json.dumps(doc))
    assert examine(old, origin_of([rec]), (str(rec),)).state == "ours"
    assert examine(old, origin_of([tmp_path / "x.mcap"]), (str(tmp_path / "x.mcap"),)).state == (
        "other"
    )
