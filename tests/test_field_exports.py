"""Issue 28: exports the field's tools read, written so that any name survives.

* ``--format yaml``: Kalibr's ``imu.yaml`` keys (noise density and random walk
  from the rests' Allan deviation, update rate, topic) at the top level, the
  ``imu0`` block as before; a hostile sensor id or topic reads back unchanged;
* ``--format imu_calib``: ``SM`` and ``bias`` that correct like wheelcal;
* ``apply``: every calibrated Imu carries the noise covariance M diag(σ²) Mᵀ;
* ``fit.allan`` is the overlapping Allan deviation of the rests' own samples.
"""

import json

import numpy as np
import pytest
import yaml

from wheelcal.calibration.session_json import load_calibration, load_correction_from
from wheelcal.cli.main import main
from wheelcal.estimate.allan import AllanSums
from wheelcal.io import read_recording

HOSTILE = [
    'lab "A"',
    "rig\\new",
    "two\nlines",
    "tab\there",
    "# not a comment",
    "'quoted'",
    "colon: value",
    "emoji \U0001f6b2",
    "nel\x85 and ls\u2028",
    "*/ end of comment",
]


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    d = tmp_path_factory.mktemp("field")
    rec = d / "spin.mcap"
    assert main(["simulate", str(rec), "--seed", "11"]) == 0  # rest, push, spin, stop, rest
    assert main(["calibrate", str(rec), "--out", str(d), "--quiet"]) == 0
    return rec, d / "spin.calibration.json"


def test_fit_allan_is_the_overlapping_adev_of_the_rest_samples(session):
    rec, cal = session
    doc = json.loads(cal.read_text())
    block = doc["fit"]["allan"]
    recording = read_recording(rec, info_overrides={"radius_m": 0.28})
    t, v = recording.time_s, recording.accel_mps2
    parts = []
    for start, end in doc["fit"]["noise_reference"]["rests_s"]:
        inside = (t >= start - 1e-9) & (t <= end + 1e-9)
        parts.append(AllanSums.of(v[inside], recording.rate_hz))
    curve = AllanSums.combined(parts).deviation()
    np.testing.assert_allclose(block["tau_s"], curve.tau_s, rtol=1e-9)
    np.testing.assert_allclose(block["adev_mps2"], curve.adev, rtol=1e-9)
    assert block["counts"] == curve.counts.tolist()
    density, _ = curve.white_noise_density()
    np.testing.assert_allclose(block["white_noise_density_mps2_rthz"], density, rtol=1e-9)


def test_kalibr_keys_come_from_the_rests(session, tmp_path):
    _, cal = session
    out = tmp_path / "imu.yaml"
    assert main(["export", str(cal), "--format", "yaml", "--out", str(out)]) == 0
    doc = yaml.safe_load(out.read_text())
    calibration = json.loads(cal.read_text())
    allan = calibration["fit"]["allan"]
    noise = calibration["imu_noise"]["accelerometer"]
    # Kalibr's density: the rests' σ per sample / √rate (the Allan deviation is the check)
    rests = calibration["fit"]["noise_floor_mps2"]
    assert doc["accelerometer_noise_density"] == pytest.approx(max(rests) / np.sqrt(200.0))
    assert doc["accelerometer_noise_density"] == max(noise["noise_density_mps2_rthz"])
    assert doc["accelerometer_random_walk"] == max(allan["random_walk_mps3_rthz"])
    assert doc["update_rate"] == pytest.approx(200.0, rel=1e-9)
    assert doc["rostopic"] == "/imu/data_raw" == doc["imu0"]["rostopic"]
    corr = load_correction_from(load_calibration(cal))
    np.testing.assert_array_equal(doc["imu0"]["accelerometer"]["bias_mps2"], corr.bias_mps2)


@pytest.mark.parametrize("name", HOSTILE)
def test_hostile_names_read_back_unchanged(session, tmp_path, name):
    _, cal = session
    doc = json.loads(cal.read_text())
    doc["source"]["sensor_id"] = name
    doc["source"]["topic"] = "/" + name
    doc["source"]["file"] = name + ".mcap"
    hostile = tmp_path / "hostile.calibration.json"
    hostile.write_text(json.dumps(doc))
    out = tmp_path / "imu.yaml"
    assert main(["export", str(hostile), "--format", "yaml", "--out", str(out)]) == 0
    back = yaml.safe_load(out.read_text())
    assert back["imu0"]["sensor_id"] == name
    assert back["rostopic"] == back["imu0"]["rostopic"] == "/" + name
    calib = tmp_path / "imu_calib.yaml"
    assert main(["export", str(hostile), "--format", "imu_calib", "--out", str(calib)]) == 0
    assert set(yaml.safe_load(calib.read_text())) == {"SM", "bias"}
    header = tmp_path / "cal.h"
    assert main(["export", str(hostile), "--format", "c", "--out", str(header)]) == 0
    text = header.read_text()
    # the opening comment ends where it should: no name closes it early
    assert text[text.index("*/") + 2 :].lstrip().startswith("#ifndef")


def test_imu_calib_corrects_like_wheelcal(session, tmp_path):
    _, cal = session
    out = tmp_path / "imu_calib.yaml"
    assert main(["export", str(cal), "--format", "imu_calib", "--out", str(out)]) == 0
    doc = yaml.safe_load(out.read_text())
    sm = np.array(doc["SM"]).reshape(3, 3)  # row-major, as imu_calib reads it
    bias = np.array(doc["bias"])
    v = np.random.default_rng(1).normal(0, 9.8, size=(50, 3))
    expected = load_correction_from(load_calibration(cal)).apply(v)
    np.testing.assert_allclose(v @ sm.T - bias, expected, rtol=1e-12, atol=1e-12)


def test_apply_writes_the_noise_covariance(session, tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    rec, cal = session
    out = tmp_path / "calibrated.mcap"
    assert main(["apply", str(cal), str(rec), str(out)]) == 0
    doc = load_calibration(cal)
    m = np.array(doc["correction"]["matrix"])
    sigma = np.array(doc["fit"]["noise_floor_mps2"])
    expected = m @ np.diag(sigma**2) @ m.T
    seen = 0
    with open(out, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, _, _, msg in reader.iter_decoded_messages(topics=["/imu/data_raw/calibrated"]):
            cov = np.array(msg.linear_acceleration_covariance).reshape(3, 3)
            np.testing.assert_allclose(cov, expected, rtol=1e-15)
            seen += 1
            if seen == 100:
                break
    assert seen == 100 and np.all(np.diag(expected) > 0)
