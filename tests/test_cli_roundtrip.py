"""CLI round trips: simulate → calibrate → apply → export, judged against the simulated truth."""

import json
import shutil
import subprocess

import numpy as np
import pytest
import yaml

from wheelcal.cli.main import main
from wheelcal.estimate.crlb import cramer_rao_bound
from wheelcal.estimate.noise_model import NoiseModel
from wheelcal.io import read_recording
from wheelcal.io.calibration_json import load_calibration, load_correction_from
from wheelcal.model import BenchParams, CalibrationParams, Rotation, SensorParams, SpinParams


def _truth(path) -> tuple[CalibrationParams, dict]:
    t = json.loads(path.read_text())
    motion = t["motion"]
    omegas = [motion[k] for k in sorted(k for k in motion if k.startswith("omega"))]
    params = CalibrationParams(
        spin=SpinParams(motion["theta0_rad"], omegas),
        bench=BenchParams(
            np.deg2rad(t["bench"]["tilt_deg"]),
            t["bench"]["radius_m"],
            Rotation.from_euler_deg(*t["bench"]["misalignment_euler_deg"]),
        ),
        sensor=SensorParams(t["sensor"]["offset_mps2"], t["sensor"]["gain"]),
    )
    return params, t


def _z_scores(cal: dict, truth: CalibrationParams, truth_json: dict, rate_hz: float) -> dict:
    """(estimate − truth)/σ_CRLB at the truth, over the window the calibration used."""
    w0, w1 = cal["source"]["window_s"]
    n = cal["source"]["samples"]
    t_fit = np.linspace(w0, w1, n)
    centre_true = 0.5 * sum(truth_json["window_s"])
    centre_fit = 0.5 * (w0 + w1)
    truth = truth.with_changes(spin=truth.spin.shifted(centre_fit - centre_true))
    bound = cramer_rao_bound(
        truth, t_fit - centre_fit, NoiseModel.white(truth_json["noise"]["std_mps2"])
    )
    z = {}
    for name, sigma, value in zip(bound.names, bound.std, bound.values, strict=True):
        est = cal["parameters"][name]["value"]
        d = est - value
        if name == "theta0_rad":
            d = (d + np.pi) % (2 * np.pi) - np.pi
        z[name] = d / sigma
    return z


@pytest.mark.parametrize(
    ("fmt", "reverse", "seed"), [("ros2", False, 21), ("json", True, 22), ("json", False, 23)]
)
def test_simulate_calibrate_round_trip_within_4_crlb(tmp_path, fmt, reverse, seed, capsys):
    mcap = tmp_path / "spin.mcap"
    truth_path = tmp_path / "truth.json"
    args = ["simulate", str(mcap), "--seed", str(seed), "--format", fmt, "--truth", str(truth_path)]
    assert main(args + (["--reverse"] if reverse else [])) == 0
    assert main(["calibrate", str(mcap), "--out", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out
    assert "gain" in printed and "spin.calibration.json" in printed
    cal = load_calibration(tmp_path / "out" / "spin.calibration.json")
    truth, truth_json = _truth(truth_path)
    z = _z_scores(cal, truth, truth_json, 200.0)
    assert max(abs(v) for v in z.values()) < 4.0, z
    assert cal["bench"]["spin_sign"] == (-1 if reverse else 1)
    # The automatic window lies inside the true free spin and covers most of it.
    (w0, w1), (t0, t1) = cal["source"]["window_s"], truth_json["window_s"]
    assert t0 - 0.05 <= w0 and w1 <= t1 + 0.05 and (w1 - w0) > 0.9 * (t1 - t0)


def test_apply_gives_the_true_specific_force_within_the_noise(tmp_path):
    mcap = tmp_path / "s.mcap"
    truth_path = tmp_path / "truth.json"
    assert (
        main(["simulate", str(mcap), "--seed", "5", "--free-spin-only", "--truth", str(truth_path)])
        == 0
    )
    assert main(["calibrate", str(mcap), "--out", str(tmp_path), "--quiet"]) == 0
    cal_path = tmp_path / "s.calibration.json"
    out = tmp_path / "s.cal.mcap"
    assert main(["apply", str(cal_path), str(mcap), str(out)]) == 0
    raw = read_recording(mcap)
    calibrated = read_recording(out, topic="/imu/data_raw/calibrated")
    assert calibrated.samples == raw.samples
    np.testing.assert_array_equal(calibrated.time_s, raw.time_s)
    truth, truth_json = _truth(truth_path)
    # True specific force in the sensor frame: s = R a(t) = Γ⁻¹ (v_clean − o).
    from wheelcal.model import predict

    t_c = raw.time_s - 0.5 * sum(truth_json["window_s"])
    clean = predict(truth, t_c)
    true_force = (clean - truth.sensor.offset_mps2) / truth.sensor.gain
    err = calibrated.accel_mps2 - true_force
    noise = 0.08
    # Within the noise: per-axis RMS ≈ σ_n/γ, and the mean error ≪ σ_n (bias well calibrated).
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) < 1.1 * noise)
    assert np.all(np.abs(err.mean(axis=0)) < 0.03)
    # The original channel is untouched and the calibration is stored as metadata.
    from mcap.reader import make_reader

    with open(out, "rb") as f:
        reader = make_reader(f)
        topics = {c.topic for c in reader.get_summary().channels.values()}
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert topics == {"/imu/data_raw", "/imu/data_raw/calibrated"}
    assert json.loads(meta["wheelcal.calibration"]["bias_mps2"]) == pytest.approx(
        load_calibration(cal_path)["correction"]["bias_mps2"]
    )
    assert "wheelcal.session" in meta


@pytest.fixture(scope="module")
def calibration_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("export")
    mcap = d / "e.mcap"
    assert main(["simulate", str(mcap), "--seed", "8", "--free-spin-only"]) == 0
    assert main(["calibrate", str(mcap), "--out", str(d), "--quiet"]) == 0
    return d / "e.calibration.json"


def test_export_yaml_parses_to_the_same_correction(calibration_file, tmp_path):
    out = tmp_path / "cal.yaml"
    assert main(["export", str(calibration_file), "--format", "yaml", "--out", str(out)]) == 0
    doc = yaml.safe_load(out.read_text())
    corr = load_correction_from(load_calibration(calibration_file))
    acc = doc["imu0"]["accelerometer"]
    np.testing.assert_allclose(acc["bias_mps2"], corr.bias_mps2, rtol=1e-8)
    np.testing.assert_allclose(acc["matrix"], corr.matrix, rtol=1e-8)


def test_export_c_header_compiles_and_corrects_like_python(calibration_file, tmp_path):
    header = tmp_path / "wheelcal_cal.h"
    assert main(["export", str(calibration_file), "--format", "c", "--out", str(header)]) == 0
    text = header.read_text()
    corr = load_correction_from(load_calibration(calibration_file))
    v = np.array([1.0, -2.0, 9.0])
    expected = corr.apply(v[None])[0]
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:  # still check the numbers in the text
        import re

        numbers = [float(x) for x in re.findall(r"(-?[\d.]+(?:e-?\d+)?)f", text)]
        np.testing.assert_allclose(numbers[:3], corr.bias_mps2, rtol=1e-6)
        return
    prog = tmp_path / "t.c"
    prog.write_text(
        '#include <stdio.h>\n#include "wheelcal_cal.h"\n'
        "int main(void){float v[3]={1.0f,-2.0f,9.0f},a[3];wheelcal_accel_correct(v,a);"
        'printf("%.7g %.7g %.7g\\n",a[0],a[1],a[2]);return 0;}\n'
    )
    exe = tmp_path / "t"
    subprocess.run(
        [cc, "-std=c99", "-Wall", "-Werror", "-o", str(exe), str(prog)], check=True, cwd=tmp_path
    )
    got = np.array(
        subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout.split(), float
    )
    np.testing.assert_allclose(got, expected, rtol=1e-5)


def test_convert_csv_in_g_and_ms_calibrates_like_the_original(tmp_path, calibration_file):
    mcap = calibration_file.with_name("e.mcap")
    rec = read_recording(mcap)
    csv = tmp_path / "log.csv"
    rows = ["time_ms;ax;ay;az"] + [
        f"{1e3 * t:.3f};{a[0] / 9.80665:.8f};{a[1] / 9.80665:.8f};{a[2] / 9.80665:.8f}"
        for t, a in zip(rec.time_s, rec.accel_mps2, strict=True)
    ]
    csv.write_text("\n".join(rows) + "\n")
    out = tmp_path / "log.mcap"
    args = ["convert", str(csv), str(out), "--time-column", "time_ms", "--time-unit", "ms"]
    assert main([*args, "--accel-unit", "g", "--radius", "0.28"]) == 0
    assert main(["calibrate", str(out), "--out", str(tmp_path), "--quiet"]) == 0
    a = load_calibration(tmp_path / "log.calibration.json")["sensor"]
    b = load_calibration(calibration_file)["sensor"]
    np.testing.assert_allclose(a["gain"], b["gain"], atol=1e-6)
    np.testing.assert_allclose(a["offset_mps2"], b["offset_mps2"], atol=1e-4)
    # A column that is not there is named in the error.
    bad = ["--accel-columns", "ax", "ay", "a_z"]
    assert main(["convert", str(csv), str(tmp_path / "x.mcap"), "--accel-unit", "g", *bad]) == 1
    assert not (tmp_path / "x.mcap").exists()
