"""Kalibr's ``imu.yaml`` that Kalibr's reader loads, with noise terms by Kalibr's definition.

* The export of a gyro recording passes every getter of Kalibr's ``ImuParameters``
  (mirrored in ``tests/kalibr_reader.py``, its source quoted there): every key, every
  type, every check — and an accelerometer-only export fails it by naming the one field
  wheelcal cannot fill, not by a ``None`` Kalibr cannot compare.
* The noise densities are the white noise's σ per sample / √rate: within 10 % of the
  simulator's truth on each of 6 seeds, accelerometer and gyroscope (the data give
  ±2 %); the Allan deviation at τ = 1 s, the check, lies within its own σ of them as
  often as a σ promises (≈ 68 %) and never beyond 3σ.
* The random walks are marked upper bounds in the line a Kalibr user reads.
"""

from __future__ import annotations

import dataclasses
import json
import math

import allantools
import numpy as np
import pytest
import yaml

import wheelcal
from kalibr_reader import ImuParameters
from wheelcal.calibration.export import to_yaml
from wheelcal.calibration.imu_noise import white_adev_edf
from wheelcal.calibration.sensor_json import sensor_calibration_dict, session_estimate
from wheelcal.cli.main import main
from wheelcal.closedloop.pooling import pool_sessions
from wheelcal.simulate import GyroSpec, preset
from wheelcal.simulate.session import simulate_session

SEEDS = (0, 1, 2, 3, 4, 5)


def _scenario(seed: int):
    """The ``wheelcal simulate --gyro`` session of this seed (table2, MPU-9250-class gyro)."""
    rng = np.random.default_rng(seed)
    scenario = preset("table2", rng=rng)
    info = scenario.info.merged(gyro_full_scale_dps=2000.0)
    scenario = dataclasses.replace(scenario, gyro=GyroSpec(full_scale_dps=2000.0), info=info)
    return scenario, simulate_session(scenario, rng).recording


@pytest.fixture(scope="module")
def calibrated():
    """(scenario, calibration document) per seed."""
    out = {}
    for seed in SEEDS:
        scenario, recording = _scenario(seed)
        out[seed] = scenario, wheelcal.calibrate(recording).to_dict()
    return out


def test_kalibrs_reader_loads_the_export_of_a_gyro_recording(tmp_path):
    rec, cal, yml = tmp_path / "g.mcap", tmp_path / "cal", tmp_path / "imu.yaml"
    assert main(["simulate", str(rec), "--gyro", "--seed", "11"]) == 0
    assert main(["calibrate", str(rec), "--out", str(cal), "--quiet"]) == 0
    assert (
        main(["export", str(cal / "g.calibration.json"), "--format", "yaml", "--out", str(yml)])
        == 0
    )
    imu = ImuParameters(yml)
    details = imu.print_details()
    assert details["rostopic"] == "/imu/data_raw"
    assert details["update_rate"] == pytest.approx(200.0)
    for sensor in ("accelerometer", "gyroscope"):
        discrete, walk, density = details[sensor]
        assert all(isinstance(v, float) for v in (discrete, walk, density))
        assert discrete == pytest.approx(density * math.sqrt(200.0))
    doc = json.loads((cal / "g.calibration.json").read_text())
    noise = doc["imu_noise"]
    # Kalibr's discrete σ is the per-sample σ wheelcal measured (the largest axis).
    assert details["accelerometer"][0] == pytest.approx(
        max(noise["accelerometer"]["white_std_mps2"])
    )
    assert details["gyroscope"][0] == pytest.approx(max(noise["gyroscope"]["white_std_radps"]))
    # the random walks: marked as bounds in the very line Kalibr reads
    lines = yml.read_text().splitlines()
    for key in ("accelerometer_random_walk", "gyroscope_random_walk"):
        (line,) = [ln for ln in lines if ln.startswith(key + ":")]
        assert "UPPER BOUND" in line


def test_an_accelerometer_only_export_names_the_missing_gyro_field(tmp_path):
    rec, cal, yml = tmp_path / "a.mcap", tmp_path / "cal", tmp_path / "imu.yaml"
    assert main(["simulate", str(rec), "--seed", "11"]) == 0
    assert main(["calibrate", str(rec), "--out", str(cal), "--quiet"]) == 0
    assert (
        main(["export", str(cal / "a.calibration.json"), "--format", "yaml", "--out", str(yml)])
        == 0
    )
    imu = ImuParameters(yml)
    assert imu.get_accelerometer_statistics()[2] > 0
    with pytest.raises(RuntimeError, match="Field 'gyroscope_noise_density' missing"):
        imu.get_gyro_statistics()
    assert "gyroscope_noise_density: not written (this calibration has no gyroscope)" in (
        yml.read_text()
    )


def _truth(scenario):
    rate = scenario.rate_hz
    accel = scenario.noise.std / math.sqrt(rate)
    gyro = scenario.gyro.noise_std_radps(rate) / math.sqrt(rate)
    return {"accelerometer": accel, "gyroscope": np.full(3, gyro)}


def test_noise_densities_are_the_truth_within_10_percent_on_six_seeds(calibrated):
    worst, within_sigma, z_all = 0.0, 0, []
    for seed, (scenario, doc) in calibrated.items():
        truth = _truth(scenario)
        noise = doc["imu_noise"]
        for kind, unit in (("accelerometer", "mps2"), ("gyroscope", "radps")):
            block = noise[kind]
            assert block["source"] == "rests"
            density = np.asarray(block[f"noise_density_{unit}_rthz"])
            error = density / truth[kind] - 1
            assert np.all(np.abs(error) < 0.10), (seed, kind, error)
            # … and within 4 of its own σ (±1/√(2(n−1)), ≈ 2 %): the σ is honest
            assert np.all(np.abs(error) < 4 * block["white_std_rel_std"]), (seed, kind, error)
            worst = max(worst, float(np.max(np.abs(error))))
            z = np.asarray(block["allan_z"])
            np.testing.assert_allclose(
                z,
                (np.asarray(block[f"allan_density_{unit}_rthz"]) - density)
                / (density * block["allan_rel_std"]),
            )
            z_all += z.tolist()
            within_sigma += int(np.sum(np.abs(z) <= 1))
    z_all = np.abs(z_all)
    assert worst < 0.06, worst
    assert np.all(z_all < 3), z_all
    # 36 comparisons: a 1σ band holds ≈ 68 % (binomial ± 8 %)
    assert within_sigma / z_all.size > 0.5, within_sigma


def test_the_allan_sigma_is_nists_edf():
    # NIST SP 1065's white-FM edf, as allantools computes it (edf_simple, alpha = 0)
    for n, m in ((760, 200), (540, 200), (1300, 64), (3000, 1)):
        assert white_adev_edf([n], m) == pytest.approx(allantools.edf_simple(n + 1, m, 0))
    assert white_adev_edf([760, 540], 200) == pytest.approx(
        white_adev_edf([760], 200) + white_adev_edf([540], 200)
    )


def test_a_sensors_pooled_file_exports_the_pooled_noise(calibrated, tmp_path):
    docs = [doc for _, doc in calibrated.values()][:3]
    pooling = pool_sessions([session_estimate(d) for d in docs])
    pooled = sensor_calibration_dict("sim-sensor", pooling, docs)
    path = tmp_path / "imu.yaml"
    path.write_text(to_yaml(pooled))
    details = ImuParameters(path).print_details()
    weights = np.array([d["imu_noise"]["accelerometer"]["samples"] - 1 for d in docs], float)
    var = np.array(
        [np.asarray(d["imu_noise"]["accelerometer"]["white_std_mps2"]) ** 2 for d in docs]
    )
    expected = np.sqrt(weights @ var / weights.sum()) / math.sqrt(200.0)
    assert details["accelerometer"][2] == pytest.approx(float(expected.max()))
    assert yaml.safe_load(path.read_text())["imu0"]["noise"]["gyroscope"]["samples"] > 0
