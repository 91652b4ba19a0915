"""Refusals, partial calibrations and option checks at the command line (issue 11).

* ``--accel-unit`` and a pipeline's ``[defaults]`` reach the reader (both were
  silently ignored before: these tests fail on that code);
* a refused session exits 1, names its gate and fix, leaves no calibration and
  renames an earlier one ``.stale``; the batch lists gate and fix in
  ``report.json``;
* an undetermined parameter is ``null`` with its reason, the correction keeps
  that axis unchanged, and ``export``/``apply`` refuse it without
  ``--allow-partial``;
* bad option values are usage errors (exit 2).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from wheelcal.cli.main import main
from wheelcal.io import write_recording
from wheelcal.io.mcap_writer import recording_stamps_ns, write_accel_mcap
from wheelcal.recording import SessionInfo
from wheelcal.simulate import hostile as H


@pytest.fixture(scope="module")
def session_file(tmp_path_factory):
    session = H.clean(np.random.default_rng(61))
    path = tmp_path_factory.mktemp("rec") / "spin.mcap"
    write_recording(session.recording, path)
    return session, path


def _gains(path):
    return np.array(json.loads(path.read_text())["sensor"]["gain"], dtype=float)


def test_accel_unit_overrides_a_wrong_unit_label(tmp_path, session_file, capsys):
    session, _ = session_file
    rec = session.recording
    path = tmp_path / "labelled_g.mcap"
    # Samples in m/s², but the channel says g: the reader refuses the file ...
    write_accel_mcap(
        path,
        recording_stamps_ns(rec),
        rec.accel_mps2,
        info=rec.info,
        encoding="json",
        unit="g",
        batch_size=20,
    )
    out = tmp_path / "out"
    assert main(["calibrate", str(path), "--out", str(out), "--quiet"]) == 1
    assert "--accel-unit" in capsys.readouterr().err
    # ... and --accel-unit states the truth.
    args = ["calibrate", str(path), "--out", str(out), "--accel-unit", "m/s^2", "--quiet"]
    assert main(args) == 0
    gains = _gains(out / "labelled_g.calibration.json")
    assert np.all(np.abs(gains - session.truth.sensor.gain) < 0.01), gains


def test_pipeline_defaults_supply_a_missing_radius(tmp_path, session_file):
    session, _ = session_file
    rec = session.recording
    path = tmp_path / "recordings" / "norad.mcap"
    path.parent.mkdir()
    write_recording(type(rec)(rec.time_s, rec.accel_mps2, info=SessionInfo()), path)  # no radius
    pipeline = tmp_path / "p.toml"
    pipeline.write_text(
        f'[pipeline]\nname = "d"\noutput = "{tmp_path / "out"}"\n'
        f'[inputs]\nglobs = ["{path.parent}/*.mcap"]\n'
        "[defaults]\nradius_m = 0.28\n[executor]\nworkers = 1\n"
    )
    assert main(["batch", str(pipeline)]) == 0
    gains = _gains(tmp_path / "out" / "norad.calibration.json")
    assert np.all(np.abs(gains - session.truth.sensor.gain) < 0.01), gains


def test_a_refused_session_names_its_gate_and_keeps_an_earlier_result_as_stale(
    tmp_path, session_file, capsys
):
    _, path = session_file
    out = tmp_path / "out"
    assert main(["calibrate", str(path), "--out", str(out), "--quiet"]) == 0
    good = json.loads((out / "spin.calibration.json").read_text())
    status = main(["calibrate", str(path), "--out", str(out), "--radius", "280"])
    err = capsys.readouterr().err
    assert status == 1
    assert "refused (gain_range)" in err and "0.28" in err and "--radius" in err
    assert "spin.calibration.stale.json" in err
    assert not (out / "spin.calibration.json").exists()
    assert json.loads((out / "spin.calibration.stale.json").read_text()) == good


def test_the_batch_lists_gate_and_fix_of_a_refused_session(tmp_path, session_file):
    _, path = session_file
    pipeline = tmp_path / "p.toml"
    pipeline.write_text(
        f'[pipeline]\nname = "r"\noutput = "{tmp_path / "out"}"\n'
        f'[inputs]\nglobs = ["{path}"]\n[overrides]\nradius_m = 0.028\n'
        "[executor]\nworkers = 1\n"
    )
    assert main(["batch", str(pipeline)]) == 1
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    (failed,) = report["failed"]
    assert failed["gate"] in ("gain_range", "unit")
    assert "radius" in failed["error"] and "measure the radius" in failed["fix"]
    assert "0.28" in failed["error"] and "0.28" not in failed["fix"]


def test_pipeline_gates_are_honoured(tmp_path, session_file):
    _, path = session_file
    pipeline = tmp_path / "p.toml"
    # A gain range that excludes the true gains (1.0095, 0.9942, 1.0275) must refuse.
    pipeline.write_text(
        f'[pipeline]\nname = "g"\noutput = "{tmp_path / "out"}"\n'
        f'[inputs]\nglobs = ["{path}"]\n[gates]\ngain_range = [0.995, 1.02]\n'
        "[executor]\nworkers = 1\n"
    )
    assert main(["batch", str(pipeline)]) == 1
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["failed"][0]["gate"] == "gain_range"


@pytest.fixture(scope="module")
def partial_calibration(tmp_path_factory):
    session = H.axis_near_wheel_axis(np.random.default_rng(11), 1.0)
    d = tmp_path_factory.mktemp("partial")
    path = d / "axis.mcap"
    write_recording(session.recording, path)
    assert main(["calibrate", str(path), "--out", str(d / "out"), "--quiet"]) == 0
    return path, d / "out" / "axis.calibration.json"


def test_undetermined_parameters_are_null_with_their_reason(partial_calibration):
    _, cal_path = partial_calibration
    cal = json.loads(cal_path.read_text())
    sensor = cal["sensor"]
    assert sensor["gain"][2] is None and sensor["gain_std"][2] is None
    assert sensor["offset_mps2"][2] is None and sensor["offset_std_mps2"][2] is None
    assert sensor["gain"][0] is not None and abs(sensor["gain"][0] - 1.00952) < 0.01
    reasons = {u["parameter"]: u["reason"] for u in sensor["undetermined"]}
    assert set(reasons) == {"gain_z", "offset_z_mps2"}
    assert "wheel axis" in reasons["gain_z"]
    assert cal["parameters"]["gain_z"]["value"] is None
    # the correction leaves z unchanged and says so
    assert cal["correction"]["matrix"][2] == [0.0, 0.0, 1.0]
    assert cal["correction"]["bias_mps2"][2] == 0.0
    assert cal["correction"]["identity_axes"] == ["z"]


def test_export_and_apply_refuse_a_partial_calibration_unless_allowed(
    tmp_path, partial_calibration, capsys
):
    recording, cal_path = partial_calibration
    assert main(["export", str(cal_path), "--format", "yaml"]) == 1
    assert "--allow-partial" in capsys.readouterr().err
    assert main(["export", str(cal_path), "--format", "yaml", "--allow-partial"]) == 0
    text = capsys.readouterr().out
    assert "PARTIAL: axis z is left unchanged" in text
    assert yaml.safe_load(text)["imu0"]["accelerometer"]["matrix"][2] == [0, 0, 1]
    out = tmp_path / "applied.mcap"
    assert main(["apply", str(cal_path), str(recording), str(out)]) == 1
    assert not out.exists()
    assert main(["apply", str(cal_path), str(recording), str(out), "--allow-partial"]) == 0
    assert out.exists()


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--radius-std", "-0.001"], "--radius-std"),
        (["--gravity", "9.5"], "--force-gravity"),
        (["--geometry", "tilt", "--tilt-deg", "95"], "--tilt-deg"),
        (["--tilt-std-deg", "-1"], "--tilt-std-deg"),
        (["--gain-range", "2", "0.5"], "gain_range"),
        (["--start-s", "10"], "--end-s"),
    ],
)
def test_bad_option_values_are_usage_errors(tmp_path, session_file, capsys, extra, message):
    _, path = session_file
    assert main(["calibrate", str(path), "--out", str(tmp_path / "o"), *extra]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_force_gravity_accepts_an_unusual_gravity(tmp_path, session_file):
    _, path = session_file
    args = ["calibrate", str(path), "--out", str(tmp_path / "o"), "--quiet"]
    assert main([*args, "--gravity", "9.5", "--force-gravity"]) == 0
