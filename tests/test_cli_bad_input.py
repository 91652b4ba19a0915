"""Bad input at the command line: clear messages naming the file, exit status, no partial output."""

import dataclasses

import numpy as np
import pytest

from wheelcal.cli.main import main
from wheelcal.io import write_recording
from wheelcal.recording import Recording, SessionInfo
from wheelcal.simulate import simulate, table1


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    d = tmp_path_factory.mktemp("good")
    path = d / "good.mcap"
    assert main(["simulate", str(path), "--seed", "3", "--free-spin-only"]) == 0
    return path


def _outputs(directory):
    return sorted(p.name for p in directory.iterdir()) if directory.exists() else []


def test_one_corrupt_file_does_not_stop_the_others(tmp_path, good, capsys):
    bad = tmp_path / "broken.mcap"
    data = bytearray(good.read_bytes())
    data[len(data) // 2 : len(data) // 2 + 64] = b"\x00" * 64  # damage a chunk
    bad.write_bytes(bytes(data))
    out = tmp_path / "out"
    status = main(["calibrate", str(bad), str(good), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert status == 1
    assert "broken.mcap" in err and ("CRC" in err or "corrupt" in err.lower())
    assert "1 of 2 recording(s) failed" in err
    assert _outputs(out) == ["good.calibration.json"]  # nothing half-written for the bad one


def test_truncated_file_is_named_and_refused(tmp_path, good, capsys):
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(good.read_bytes()[: good.stat().st_size // 3])
    assert main(["calibrate", str(cut), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "cut.mcap" in err and "truncated" in err.lower()
    assert _outputs(tmp_path / "o") == []


def test_not_an_mcap_file(tmp_path, capsys):
    text = tmp_path / "log.txt"  # no table (a CSV is read: tests/test_csv_direct.py)
    text.write_text("spin of monday\nno samples here\n")
    assert main(["calibrate", str(text), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "log.txt" in err and "not an MCAP file" in err


def test_missing_radius_then_given_on_the_command_line(tmp_path, capsys):
    path = tmp_path / "norad.mcap"
    assert main(["simulate", str(path), "--seed", "4", "--free-spin-only", "--no-radius"]) == 0
    assert main(["calibrate", str(path), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "norad.mcap" in err and "radius" in err
    assert _outputs(tmp_path / "o") == []
    assert (
        main(["calibrate", str(path), "--out", str(tmp_path / "o"), "--radius", "0.28", "--quiet"])
        == 0
    )
    assert _outputs(tmp_path / "o") == ["norad.calibration.json"]


def test_a_wheel_that_did_not_spin(tmp_path, capsys):
    rng = np.random.default_rng(0)
    t = np.arange(12000) / 200.0
    rest = np.array([1.0, 2.0, 9.5]) + 0.08 * rng.standard_normal((t.size, 3))
    path = tmp_path / "rest.mcap"
    write_recording(Recording(t, rest, SessionInfo(radius_m=0.28)), path)
    assert main(["calibrate", str(path), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert "rest.mcap" in err and "free spin" in err


def test_too_few_turns_in_a_given_window(tmp_path, good, capsys):
    # A 3 s window holds ~4 turns: refused with the count, not fitted into noise.
    status = main(
        ["calibrate", str(good), "--out", str(tmp_path / "o"), "--start-s", "10", "--end-s", "13"]
    )
    err = capsys.readouterr().err
    assert status == 1
    assert "good.mcap" in err and ("turned only" in err or "too short" in err)


def test_recording_too_short(tmp_path, capsys):
    scenario = dataclasses.replace(table1(), duration_s=3.0)
    path = tmp_path / "short.mcap"
    write_recording(simulate(scenario, np.random.default_rng(1)).recording, path)
    assert main(["calibrate", str(path), "--out", str(tmp_path / "o")]) == 1
    assert "short.mcap" in capsys.readouterr().err


@pytest.mark.parametrize(
    "extra",
    [["--start-s", "5"], ["--radius", "-1"], ["--geometry", "tilt"], ["--radius", "abc"]],
)
def test_bad_usage_exits_2(tmp_path, good, extra, capsys):
    with pytest.raises(SystemExit) as exc:  # argparse errors exit directly
        status = main(["calibrate", str(good), "--out", str(tmp_path / "o"), *extra])
        raise SystemExit(status)
    assert exc.value.code == 2
    assert "error" in capsys.readouterr().err


def test_unknown_preset_is_bad_usage(tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "x.mcap"), "--preset", "table9"]) == 2
    assert "unknown preset" in capsys.readouterr().err
    assert not (tmp_path / "x.mcap").exists()
