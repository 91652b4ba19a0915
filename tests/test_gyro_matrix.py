"""The gyroscope's full matrix from several mountings (issue 38): oracle, truth, batch, apply.

* **Oracle** (no wheelcal model code): the bench frame placed in a world frame and
  turned (tests/physics_oracle.py), its body rate from finite rotations and its
  specific force from finite differences; a gyro with a full non-orthogonal M,
  a bias and a sensitivity G reads M R Ω + G R f + b.  Each mounting's session
  reading (w, b_s, G_X, G_Y) is the plain least-squares regression of that
  reading on [ω, 1, a_X, a_Y]; pooled over three mountings they must give M, b
  and G exactly, and the correction must give back R Ω.
* **Truth** (the simulator, default options): one IMU in three mountings (the
  wheel axis near the sensor's x, y and z), three spins each, through
  ``wheelcal batch``: every entry of M within 4 σ with σ ≤ 0.002, the bias within
  4 σ; the accelerometer's pooled answer is the accelerometer-only one.
  ``wheelcal apply`` with the sensor's file then gives a gyro rate equal to
  ω d from the accelerometer's own fit within the gyro's noise.  The ``slow``
  Monte Carlo checks reported σ against the spread.
* What fewer mountings cannot see is null, with the reason.
"""

from __future__ import annotations

import json
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from physics_oracle import (
    body_rate_bench,
    euler_zyx_matrix,
    polynomial_theta,
    specific_force_bench,
)
from wheelcal.calibration.gyro_apply import GyroCorrection
from wheelcal.closedloop.gyro_matrix import GyroMountingObservation, geometry_covariance, pool_gyro
from wheelcal.model import Rotation
from wheelcal.model.rotation import log_so3
from wheelcal.simulate.gyro import GyroSpec

G0 = 9.80665
#: The accelerometer's correction matrix of the export test (diagonal).
ACC_MATRIX = (1.01, 0.99, 1.02)
#: Three mountings (scipy's ZYX Euler angles, not wheelcal's): R e_Z near the sensor's x, y, z.
ORACLE_EULER_DEG = {"x": (0.0, 70.0, 0.0), "y": (0.0, 0.0, -70.0), "z": (30.0, 20.0, 25.0)}


def _oracle_gyro() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A full M (scales, misalignment, non-orthogonality), a bias and G, written out."""
    m = np.array([[1.012, 0.018, -0.011], [-0.006, 0.991, 0.024], [0.015, -0.021, 1.004]])
    bias = np.array([0.013, -0.022, 0.007])
    g = np.array([[2.1, -0.4, 0.7], [0.3, -1.5, 0.9], [-0.8, 0.6, 1.2]]) * 1e-4
    return m, bias, g


def _oracle_session(axis: str, m, bias, g, tilt_deg: float = 40.0):
    """One mounting: the oracle's reading regressed on [ω, 1, a_X, a_Y], exact geometry."""
    rotation = euler_zyx_matrix(ORACLE_EULER_DEG[axis])
    tilt = np.deg2rad(tilt_deg)
    theta = polynomial_theta(0.4, (10.0, -0.05, 2e-4))
    t = np.linspace(-20.0, 20.0, 801)
    body = body_rate_bench(theta, t, tilt)  # bench axes
    force = specific_force_bench(theta, t, tilt, 0.28, G0)
    reading = (body @ rotation.T) @ m.T + (force @ rotation.T) @ g.T + bias
    h = 1e-5
    omega = (theta(t + h) - theta(t - h)) / (2 * h)  # signed dϑ/dt by differences
    design = np.column_stack([omega, np.ones_like(t), force[:, 0], force[:, 1]])
    coef, *_ = np.linalg.lstsq(design, reading, rcond=None)  # rows: w, b_s, G_X, G_Y
    residual = reading - design @ coef
    assert np.max(np.abs(residual)) < 1e-8, "the reading is not w ω + b + G_X a_X + G_Y a_Y"
    obs = GyroMountingObservation(
        label=f"near {axis}",
        mounting_id=axis,
        values=coef.reshape(-1),
        covariance=np.eye(12) * 1e-16,
        rotation=rotation,
        tilt_rad=tilt,
        gravity_mps2=G0,
        geometry_covariance=np.eye(4) * 1e-18,
    )
    return obs, body @ rotation.T, force @ rotation.T, reading


def test_the_pooled_gyro_model_is_the_physics():
    m, bias, g = _oracle_gyro()
    sessions = [_oracle_session(axis, m, bias, g) for axis in "xyz"]
    pooled = pool_gyro([s[0] for s in sessions])
    np.testing.assert_allclose(pooled.matrix, m, atol=1e-7)
    np.testing.assert_allclose(pooled.bias_radps, bias, atol=1e-8)
    np.testing.assert_allclose(pooled.g_sensitivity, g, atol=1e-8)
    # The correction turns the reading back into the body rate in the sensor frame.
    inverse, b = pooled.correction()
    correction = GyroCorrection(inverse, b, pooled.matrix, pooled.g_sensitivity)
    for _, rate, force, reading in sessions:
        np.testing.assert_allclose(correction.apply(reading, force), rate, atol=1e-7)
    # Each mounting measures M times its wheel axis −R e_Z.
    for obs, *_ in sessions:
        np.testing.assert_allclose(obs.values[:3], m @ -obs.rotation[:, 2], atol=1e-8)


def test_fewer_mountings_leave_the_unseen_entries_null_with_the_reason():
    m, bias, g = _oracle_gyro()
    for axes, independent in (("z", "one wheel axis"), ("xz", "2 independent wheel axes")):
        pooled = pool_gyro([_oracle_session(a, m, bias, g)[0] for a in axes])
        assert not pooled.complete
        assert np.all(np.isnan(pooled.matrix)), pooled.matrix
        reasons = dict(pooled.undetermined)
        assert len(reasons) == 9
        assert all(independent in r for r in reasons.values()), reasons
        # What the mountings do see is kept as evidence: M along each wheel axis.
        for evidence in pooled.mountings:
            np.testing.assert_allclose(evidence.measured, m @ evidence.axis, atol=1e-8)
        with pytest.raises(ValueError, match="not determined"):
            pooled.correction()


def test_the_geometry_covariance_is_the_euler_angles_carried_to_the_perturbation():
    """(δ, α) from (ε, α): δ = log(Rᵀ R(ε)) by finite differences of the Euler angles."""
    rotation = Rotation.from_euler_deg(24.76, 7.311, 31.974)
    h = 1e-5
    to_delta = np.zeros((4, 4))
    for k in range(3):
        step = np.zeros(3)
        step[k] = h
        turned = Rotation.from_euler_deg(*(rotation.euler_deg() + step))
        to_delta[:3, k] = log_so3(rotation.matrix.T @ turned.matrix) / h
    to_delta[3, 3] = np.pi / 180
    cov_deg2 = np.diag([0.02, 0.01, 0.03, 0.015]) ** 2
    cov_deg2[0, 2] = cov_deg2[2, 0] = 0.5 * 0.02 * 0.03
    np.testing.assert_allclose(
        geometry_covariance(rotation.matrix, cov_deg2),
        to_delta @ cov_deg2 @ to_delta.T,
        rtol=1e-4,
        atol=1e-16,
    )


# ---- the simulator's truth through the default batch ----------------------------------------


def _sessions(seed: int, spins: int = 3):
    from wheelcal.simulate.mountings import imu_sessions

    gyro = GyroSpec.device(np.random.default_rng([seed, 0]))
    return gyro, imu_sessions(np.random.default_rng([seed, 1]), gyro, spins=spins)


def _z(pooled_block: dict, gyro: GyroSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    m = np.array(pooled_block["matrix"], dtype=float)
    m_std = np.array(pooled_block["matrix_std"], dtype=float)
    b = np.array(pooled_block["bias_radps"], dtype=float)
    b_std = np.array(pooled_block["bias_std_radps"], dtype=float)
    return (m - gyro.response_matrix) / m_std, (b - np.asarray(gyro.bias_radps)) / b_std, m_std


def test_one_imu_in_three_mountings_through_the_default_batch(tmp_path):
    from wheelcal.calibration.sensor_json import session_estimate
    from wheelcal.cli.main import main
    from wheelcal.closedloop.pooling import pool_sessions
    from wheelcal.io import read_recording, write_recording
    from wheelcal.session.compute import SessionOptions, compute_recording

    gyro, sessions = _sessions(7)
    inputs = tmp_path / "in"
    inputs.mkdir()
    for i, s in enumerate(sessions):
        write_recording(s.recording, inputs / f"s{i}.mcap")
    pipeline = tmp_path / "p.toml"
    pipeline.write_text(
        f'[pipeline]\nname = "imu"\noutput = "{tmp_path / "out"}"\n'
        f'[inputs]\nglobs = ["{inputs}/*.mcap"]\n[executor]\nworkers = 2\n'
    )
    assert main(["batch", str(pipeline)]) == 0
    sensor_file = tmp_path / "out" / "sensors" / "imu.calibration.json"
    doc = json.loads(sensor_file.read_text())
    block = doc["gyro"]
    z_matrix, z_bias, m_std = _z(block, gyro)
    assert np.all(np.abs(z_matrix) < 4.0), z_matrix
    assert np.all(m_std <= 0.002), m_std
    assert np.all(np.abs(z_bias) < 4.0), z_bias
    assert block["undetermined"] == [] and block["axes"]["independent"] == 3
    assert sorted(m["mounting_id"] for m in block["mountings"]) == [
        f"wheel-axis-near-{a}" for a in "xyz"
    ]
    assert all(m["sessions"] == 3 for m in block["mountings"])
    np.testing.assert_allclose(
        np.array(block["correction"]["matrix"]) @ np.array(block["matrix"]), np.eye(3), atol=1e-12
    )
    # Every session kept the free spin (the accelerometer's own answer), so the pooled
    # gains and offsets are those of the accelerometer alone (--gyro off).
    off = [
        compute_recording(read_recording(inputs / f"s{i}.mcap"), SessionOptions(gyro="off"))
        for i in range(len(sessions))
    ]
    from wheelcal.calibration.session_json import calibration_dict

    alone = pool_sessions([session_estimate(calibration_dict(s)) for s in off])
    values = [*doc["sensor"]["gain"], *doc["sensor"]["offset_mps2"]]
    assert np.all(np.abs(np.array(values) - alone.value) <= 0.1 * alone.std), (values, alone)

    # apply: a fourth spin of the same IMU, its gyro corrected by the sensor's file, against
    # the rate the accelerometer's own fit gives, ω d (d the wheel axis in the sensor frame).
    from wheelcal.calibration.gyro_json import gyro_observation
    from wheelcal.simulate.mountings import imu_sessions

    extra = imu_sessions(np.random.default_rng([7, 2]), gyro, axes=("z",), spins=1)[0]
    write_recording(extra.recording, tmp_path / "extra.mcap")
    out = tmp_path / "c.mcap"
    assert main(["apply", str(sensor_file), str(tmp_path / "extra.mcap"), str(out)]) == 0
    calibrated = read_recording(out, topic="/imu/data_raw/calibrated")
    fit = compute_recording(read_recording(tmp_path / "extra.mcap"), SessionOptions())
    assert fit.window.reason.startswith("free spin")  # the accelerometer's own answer
    result = fit.result
    lo, hi = result.time_s[[0, -1]]
    inside = (calibrated.time_s >= lo) & (calibrated.time_s <= hi)
    omega = result.params.spin.omega_at(calibrated.time_s[inside] - result.centre_s)
    axis = -result.params.bench.misalignment.matrix[:, 2]
    rate = calibrated.gyro_radps[inside]
    noise = gyro.noise_std_radps(200.0)
    # Along the wheel axis the corrected gyro is the accelerometer's ω, within the gyro's noise.
    along = rate @ axis - omega
    assert np.sqrt(np.mean(along**2)) < 1.05 * noise, (np.sqrt(np.mean(along**2)), noise)
    assert abs(along.mean()) < 4 * noise / np.sqrt(along.size) + 4 * result.std_of("omega0_radps")
    # Across it, within the noise and the fit's own σ of the wheel axis (its R: 0.01–0.03°).
    geometry = gyro_observation(calibration_dict(fit))
    turn = geometry.rotation @ np.array([[0, -1, 0], [1, 0, 0], [0, 0, 0]], dtype=float)
    axis_cov = turn @ geometry.geometry_covariance[:3, :3] @ turn.T  # of d = −R e_Z
    across = rate - np.outer(rate @ axis, axis)
    expected = np.mean(omega) ** 2 * axis_cov + np.eye(3) * noise**2 / along.size
    mean = across.mean(axis=0)
    assert mean @ np.linalg.pinv(expected, rcond=1e-9) @ mean < 4.0**2, mean
    assert np.all(np.sqrt(np.mean((across - mean) ** 2, axis=0)) < 1.05 * noise)


def test_the_exports_carry_the_gyro_intrinsics(tmp_path):
    import yaml

    from wheelcal.calibration.export import lower_times_rotation, to_c_header, to_imu_tk, to_yaml
    from wheelcal.calibration.gyro_json import pooled_gyro_dict

    m, bias, g = _oracle_gyro()
    pooled = pool_gyro([_oracle_session(a, m, bias, g)[0] for a in "xyz"])
    calibration = {
        "format": "wheelcal.sensor_calibration/1",
        "sensor_id": "imu",
        "source": {"topic": "/imu"},
        "sensor": {"gain": [1.0, 1.0, 1.0], "offset_mps2": [0.0, 0.0, 0.0]},
        "correction": {
            "bias_mps2": [0.1, 0.2, 0.3],
            "matrix": np.diag([1.01, 0.99, 1.02]).tolist(),
        },
        "gyro": json.loads(json.dumps(pooled_gyro_dict(pooled), allow_nan=False)),
    }
    doc = yaml.safe_load(to_yaml(calibration))
    assert doc["model"] == "scale-misalignment"
    lower = np.array(doc["gyroscopes"]["M"])
    rotation = np.array(doc["gyroscopes"]["C_gyro_i"])
    assert np.all(np.triu(lower, 1) == 0) and np.all(np.diag(lower) > 0)
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rotation) > 0
    np.testing.assert_allclose(lower @ rotation, m, atol=1e-7)  # Kalibr: M_gyro C_gyro_i = M
    np.testing.assert_allclose(np.array(doc["gyroscopes"]["A"]) @ rotation, g, atol=1e-9)
    np.testing.assert_allclose(
        np.array(doc["accelerometers"]["M"]), np.diag(1 / np.array(ACC_MATRIX))
    )
    np.testing.assert_allclose(doc["imu0"]["gyroscope"]["bias_radps"], bias, atol=1e-8)
    # imu_tk: T (unit diagonal) K (diagonal) = M⁻¹, B = b, as CalibratedTriad::load reads it.
    numbers = np.array(to_imu_tk(calibration, "gyro").split(), dtype=float)
    assert numbers.size == 21
    t_mat, k_mat, b_vec = numbers[:9].reshape(3, 3), numbers[9:18].reshape(3, 3), numbers[18:]
    np.testing.assert_allclose(np.diag(t_mat), 1.0)
    np.testing.assert_allclose(k_mat, np.diag(np.diag(k_mat)))
    np.testing.assert_allclose(t_mat @ k_mat, np.linalg.inv(m), atol=1e-7)
    np.testing.assert_allclose(b_vec, bias, atol=1e-8)
    acc = np.array(to_imu_tk(calibration, "acc").split(), dtype=float)
    np.testing.assert_allclose(
        acc[:9].reshape(3, 3) @ acc[9:18].reshape(3, 3), np.diag([1.01, 0.99, 1.02])
    )
    header = to_c_header(calibration)
    assert "wheelcal_gyro_correct(const float g[3], const float a[3], float w[3])" in header
    assert "WHEELCAL_GYRO_MATRIX[3][3]" in header
    # The LQ form of a matrix with det ≤ 0 does not exist: said, not invented.
    with pytest.raises(ValueError, match="det"):
        lower_times_rotation(np.diag([1.0, 1.0, -1.0]))
    # A session's file has no full matrix: the gyro export says why.
    session = {**calibration, "format": "wheelcal.calibration/1", "gyro": {"scale": 1.0}}
    with pytest.raises(ValueError, match="wheel axis only"):
        to_imu_tk(session, "gyro")
    assert "model" not in yaml.safe_load(to_yaml(session))


def _monte_carlo_run(seed: int):
    from threadpoolctl import threadpool_limits

    from wheelcal.calibration.gyro_json import gyro_block
    from wheelcal.calibration.session_json import calibration_dict
    from wheelcal.session.compute import SessionOptions, compute_recording

    with threadpool_limits(1):
        gyro, sessions = _sessions(seed)
        docs = [
            calibration_dict(compute_recording(s.recording, SessionOptions())) for s in sessions
        ]
        block = gyro_block(docs)["gyro"]
    z_matrix, z_bias, m_std = _z(block, gyro)
    return z_matrix.ravel(), z_bias, float(np.max(m_std))


@pytest.mark.slow
def test_the_pooled_gyro_sigma_matches_its_spread_monte_carlo():
    runs = 100
    with ProcessPoolExecutor(2) as pool:
        out = list(pool.map(_monte_carlo_run, range(100, 100 + runs)))
    z_matrix, z_bias, worst_std = (np.array(x) for x in zip(*out, strict=True))
    assert np.all(np.abs(z_matrix) < 4.0), np.abs(z_matrix).max()
    assert np.all(np.abs(z_bias) < 4.0), np.abs(z_bias).max()
    assert np.all(worst_std <= 0.002), worst_std.max()
    # reported σ / observed spread = 1 / std(z): each group in 0.8–1.25, each entry within
    # 4 standard errors (1/√(2·99) = 7 %) of 1.
    honest_matrix = 1.0 / np.std(z_matrix, axis=0, ddof=1)
    honest_bias = 1.0 / np.std(z_bias, axis=0, ddof=1)
    print("reported/spread M", honest_matrix.round(3), "b", honest_bias.round(3))
    assert 0.8 <= np.mean(honest_matrix) <= 1.25, honest_matrix
    assert 0.8 <= np.mean(honest_bias) <= 1.25, honest_bias
    assert np.all((honest_matrix > 0.72) & (honest_matrix < 1.4)), honest_matrix
    assert np.all((honest_bias > 0.72) & (honest_bias < 1.4)), honest_bias


def test_monte_carlo_harness_short():
    """One run of the slow Monte Carlo's harness (the same code path, CI-sized)."""
    for seed in (1,):
        z_matrix, z_bias, worst = _monte_carlo_run(seed)
        assert np.all(np.abs(z_matrix) < 4.0) and np.all(np.abs(z_bias) < 4.0)
        assert worst <= 0.002
