"""CLI round trips: simulate → calibrate → apply → export, judged against the simulated truth."""

import json
import re
import shutil
import subprocess

import numpy as np
import pytest
import yaml

from wheelcal.calibration.session_json import load_calibration, load_correction_from
from wheelcal.cli.main import main
from wheelcal.estimate.joint.crlb import cramer_rao_bound
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.io import read_recording
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
    noise = np.asarray(truth_json["noise"]["std_mps2"], float)  # per axis
    # To first order err_i = n_i/γ_i − (δo_i + δγ_i s_i)/γ_i: the noise through the correction
    # plus the calibration's error, whose covariance is the CRLB at the truth over the window.
    cal = load_calibration(cal_path)
    w0, w1 = cal["source"]["window_s"]
    t_fit = np.linspace(w0, w1, cal["source"]["samples"]) - 0.5 * (w0 + w1)
    shifted = truth.with_changes(
        spin=truth.spin.shifted(0.5 * (w0 + w1 - sum(truth_json["window_s"])))
    )
    bound = cramer_rao_bound(shifted, t_fit, NoiseModel.white(noise))
    gain = truth.sensor.gain
    n = err.shape[0]
    se = 1 / np.sqrt(2 * n)  # relative SE of an RMS of n Gaussian samples
    for i, a in enumerate("xyz"):
        idx = [bound.names.index(f"offset_{a}_mps2"), bound.names.index(f"gain_{a}")]
        cov = bound.covariance[np.ix_(idx, idx)]
        jac = -np.stack([np.ones(n), true_force[:, i]], axis=1) / gain[i]  # ∂err_i/∂(o_i, γ_i)
        cal_var = np.einsum("tj,jk,tk->t", jac, cov, jac)  # calibration error's variance at t
        noise_i = noise[i] / gain[i]
        # Mean error: the calibration error at the mean force, plus the noise's mean.
        jm = jac.mean(axis=0)
        sigma_mean = np.sqrt(jm @ cov @ jm + noise_i**2 / n)
        assert abs(err[:, i].mean()) < 4 * sigma_mean, (a, err[:, i].mean(), sigma_mean)
        # RMS error: the noise's σ_n/γ_i, plus at most (4 σ)² of calibration error.
        rms = np.sqrt(np.mean(err[:, i] ** 2))
        lo = noise_i * (1 - 4 * se)
        hi = np.sqrt(noise_i**2 + 16 * cal_var.mean()) * (1 + 4 * se)
        assert lo < rms < hi, (a, rms, lo, hi)
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


def _c_array(text: str, name: str) -> np.ndarray:
    """Every number of the C initialiser of ``name`` in the header, in order."""
    body = re.search(rf"{name}(?:\[3\])+ = (\{{.*?\}});", text, re.S)
    assert body, name
    return np.array([float(x) for x in re.findall(r"(-?[\d.]+(?:e[-+]?\d+)?)f", body.group(1))])


def test_export_c_header_compiles_and_corrects_like_python(calibration_file, tmp_path):
    header = tmp_path / "wheelcal_cal.h"
    assert main(["export", str(calibration_file), "--format", "c", "--out", str(header)]) == 0
    text = header.read_text()
    corr = load_correction_from(load_calibration(calibration_file))
    # Every number of the header against the calibration JSON: 3 biases, 9 matrix entries.
    bias = _c_array(text, "WHEELCAL_ACCEL_BIAS_MPS2")
    matrix = _c_array(text, "WHEELCAL_ACCEL_MATRIX")
    assert bias.shape == (3,) and matrix.shape == (9,)
    np.testing.assert_allclose(bias, corr.bias_mps2, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(matrix.reshape(3, 3), corr.matrix, rtol=1e-6, atol=1e-9)
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler: the header's numbers are checked, its code is not compiled")
    # Compile the header as firmware would and correct samples probing every matrix column.
    samples = np.array([[1.0, -2.0, 9.0], [10.0, 0.0, 0.0], [0.0, -10.0, 0.0], [0.0, 0.0, 10.0]])
    rows = ",".join("{" + ",".join(f"{x:.1f}f" for x in v) + "}" for v in samples)
    prog = tmp_path / "t.c"
    prog.write_text(
        '#include <stdio.h>\n#include "wheelcal_cal.h"\n'
        f"static const float V[{len(samples)}][3] = {{{rows}}};\n"
        f"int main(void){{for(int k=0;k<{len(samples)};++k){{float a[3];"
        "wheelcal_accel_correct(V[k],a);"
        'printf("%.9g %.9g %.9g\\n",a[0],a[1],a[2]);}return 0;}\n'
    )
    exe = tmp_path / "t"
    subprocess.run(
        [cc, "-std=c99", "-Wall", "-Werror", "-o", str(exe), str(prog)], check=True, cwd=tmp_path
    )
    out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout
    got = np.array(out.split(), float).reshape(-1, 3)
    np.testing.assert_allclose(got, corr.apply(samples), rtol=1e-5, atol=1e-5)


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
