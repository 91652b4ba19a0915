"""The simulated gyroscope: sign convention against an independent oracle, error model, seeds.

The sign test rebuilds the CONTRACT's bench frame in a world frame from its
definitions alone (X from the sensor toward the axle, Y = Z × X the direction
of increasing ϑ, gravity terms of eq. 1) and differentiates it numerically —
finite rotations and finite differences, no wheelcal.model code — then
compares with what the simulator writes.
"""

import dataclasses
import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation as SciRotation

from wheelcal.cli.main import main
from wheelcal.io import read_recording
from wheelcal.model import SpinParams
from wheelcal.simulate import (
    GyroSpec,
    NoiseSpec,
    TemperatureSpec,
    simulate,
    simulate_session,
    table1,
    table2,
)
from wheelcal.simulate.motion import ImbalancedSpin, RateProfile

G0 = 9.80665


def _theta(spin: SpinParams, t: np.ndarray) -> np.ndarray:
    """ϑ(t) = ϑ₀ + Σ ω_k t^(k+1)/(k+1), straight from the coefficients."""
    coeffs = np.asarray(spin.omega_radps, float)
    integral = np.concatenate([[spin.theta0_rad], coeffs / np.arange(1, coeffs.size + 1)])
    return np.polynomial.polynomial.polyval(t, integral)


def _world_frame(theta: float, tilt_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Bench axes [X Y Z] as world columns, and the world's "up", from the definitions.

    World "up" is +z.  Z (the wheel axis, upward side) is tilted by α from up;
    e1 is the in-plane direction of "up", e2 = Z × e1.  Eq. (1)'s gravity terms
    need up·X = sinα cosϑ and up·Y = sinα sinϑ, so X = cosϑ e1 + s sinϑ e2
    with the sign s that makes Y = Z × X satisfy the second one.
    """
    up = np.array([0.0, 0.0, 1.0])
    z_axis = np.array([np.sin(tilt_rad), 0.0, np.cos(tilt_rad)])
    e1 = (up - np.cos(tilt_rad) * z_axis) / np.sin(tilt_rad)
    e2 = np.cross(z_axis, e1)
    for s in (1.0, -1.0):
        x_axis = np.cos(theta) * e1 + s * np.sin(theta) * e2
        y_axis = np.cross(z_axis, x_axis)
        if np.isclose(up @ y_axis, np.sin(tilt_rad) * np.sin(theta)):
            return np.column_stack([x_axis, y_axis, z_axis]), up
    raise AssertionError("no frame fits eq. (1)")


@pytest.mark.parametrize("direction", [1, -1])
def test_ideal_gyro_sign_by_finite_rotation_of_the_bench_frame(direction):
    base = table1()
    spin = base.truth.spin
    spin = SpinParams(direction * spin.theta0_rad, tuple(direction * w for w in spin.omega_radps))
    scenario = dataclasses.replace(
        base,
        truth=base.truth.with_changes(spin=spin),
        gyro=GyroSpec.ideal(),
        noise=NoiseSpec(0.0),
    )
    sim = simulate(scenario, np.random.default_rng(0))
    tilt = scenario.truth.bench.tilt_rad
    r_m = scenario.truth.bench.radius_m
    rot = scenario.truth.bench.misalignment.matrix  # bench -> sensor (a number, not model code)
    sensor = scenario.truth.sensor
    tc = scenario.centred_times_s()
    h = 1e-4
    for i in np.random.default_rng(1).choice(tc.size, 25, replace=False):
        frames = [_world_frame(_theta(spin, np.array([tc[i] + d]))[0], tilt) for d in (-h, 0, h)]
        (c_before, _), (c_now, up), (c_after, _) = frames
        # The contract's "Y is the direction of increasing ϑ": dP/dϑ ∥ +Y for P = −r X.
        p = [-r_m * c[:, 0] for c, _ in frames]
        velocity = (p[2] - p[0]) / (2 * h)
        omega = (_theta(spin, np.array([tc[i] + h])) - _theta(spin, np.array([tc[i] - h])))[0] / (
            2 * h
        )
        np.testing.assert_allclose(velocity, r_m * omega * c_now[:, 1], atol=1e-6)
        # Specific force by finite differences = what the simulator's accelerometer sensed.
        accel_world = (p[2] - 2 * p[1] + p[0]) / h**2 + G0 * up
        sensed = rot @ (c_now.T @ accel_world)
        truth_sensed = (sim.clean_mps2[i] - sensor.offset_mps2) / sensor.gain
        np.testing.assert_allclose(sensed, truth_sensed, atol=2e-5)
        # Body rate from the finite rotation of the bench frame over [t − h, t + h].
        body = SciRotation.from_matrix(c_before.T @ c_after).as_rotvec() / (2 * h)
        np.testing.assert_allclose(rot @ body, sim.recording.gyro_radps[i], rtol=1e-7, atol=1e-9)
        # ... which is −ω R e_Z: the convention documented in the README.
        np.testing.assert_allclose(body, [0.0, 0.0, -omega], atol=1e-8)


def test_gyro_error_model_against_its_formula():
    spec = GyroSpec(
        noise_density_dps_rthz=0.0,
        bias_radps=(0.01, -0.02, 0.03),
        scale_error=(0.01, -0.02, 0.03),
        misalignment_deg=(0.5, -1.0, 0.8),
        g_sensitivity_dps_per_g=[[0.1, 0.02, 0.0], [0.0, 0.1, 0.0], [-0.03, 0.0, 0.1]],
        full_scale_dps=None,
    )
    scenario = dataclasses.replace(table1(), gyro=spec, duration_s=5.0)
    sim = simulate(scenario, np.random.default_rng(2))
    rot = scenario.truth.bench.misalignment.matrix
    sensor = scenario.truth.sensor
    sensed = (sim.clean_mps2 - sensor.offset_mps2) / sensor.gain
    omega = np.gradient(_theta(scenario.truth.spin, scenario.centred_times_s()), 1 / 200)
    mis = SciRotation.from_rotvec(np.deg2rad([0.5, -1.0, 0.8])).as_matrix()
    response = np.diag([1.01, 0.98, 1.03]) @ mis
    g_matrix = np.array(spec.g_sensitivity_dps_per_g) * np.pi / 180 / G0
    expected = (
        (-omega[:, None] * rot[:, 2]) @ response.T
        + sensed @ g_matrix.T
        + np.array([0.01, -0.02, 0.03])
    )
    got = sim.recording.gyro_radps
    np.testing.assert_allclose(got[2:-2], expected[2:-2], atol=2e-6)  # gradient's O(h²)
    # The wheel-axis response (k_w, u) is the part proportional to ω.
    scale, axis = spec.wheel_axis_response(rot)
    np.testing.assert_allclose(scale * axis, response @ (-rot[:, 2]), atol=1e-15)
    assert abs(np.linalg.norm(axis) - 1) < 1e-15 and 0.95 < scale < 1.05
    assert np.degrees(np.arccos(axis @ -rot[:, 2])) > 0.5  # the errors tilt u off −R e_Z


def test_noise_density_quantisation_and_clipping():
    spec = GyroSpec(
        noise_density_dps_rthz=0.01,
        bias_radps=0.0,
        scale_error=0.0,
        misalignment_deg=0.0,
        g_sensitivity_dps_per_g=0.0,
        full_scale_dps=250.0,
        bits=16,
    )
    n = 200_000
    rest = spec.output(np.zeros(n), np.zeros((n, 3)), np.eye(3), 200.0, np.random.default_rng(3))
    sigma = 0.01 * np.pi / 180 * np.sqrt(100.0)  # density · √(f_s/2)
    assert spec.noise_std_radps(200.0) == pytest.approx(sigma, rel=1e-12)
    assert np.std(rest) == pytest.approx(sigma, rel=0.01)  # 0.13 % expected scatter
    lsb = 500 * np.pi / 180 / 2**16
    np.testing.assert_allclose(rest / lsb, np.round(rest / lsb), atol=1e-9)  # whole counts
    # A 9 rad/s spin about the sensor's z axis saturates the ±250 °/s range at the rails.
    spin = spec.output(
        np.full(10, 9.0), np.zeros((10, 3)), np.eye(3), 200.0, np.random.default_rng(4)
    )
    lo, hi = spec.limits_radps
    assert hi == pytest.approx(250 * np.pi / 180 - lsb) and lo == pytest.approx(-250 * np.pi / 180)
    np.testing.assert_array_equal(spin[:, 2], np.full(10, lo))  # −ω R e_Z = −9 rad/s < −4.36


def test_no_gyro_draws_reproduce_existing_seeds_and_a_gyro_leaves_the_accelerometer_alone():
    # Values written by the simulator before the gyro existed (commit dc66ebd).
    rec = simulate(table1(), np.random.default_rng(11)).recording
    np.testing.assert_allclose(
        rec.accel_mps2[[0, 9000, -1]],
        [
            [23.990499991827086, 14.073567236768149, -1.694261388433925],
            [14.746011427019003, -2.581781923834372, 0.08783972644531082],
            [8.140018503060483, -1.7992008139658087, 4.8842496243864195],
        ],
        rtol=1e-12,
    )
    rng = np.random.default_rng(5)
    full = simulate_session(table2(rng=rng), rng).recording
    assert full.samples == 19861 and full.gyro_radps is None and full.temperature_c is None
    np.testing.assert_allclose(
        full.accel_mps2[[0, 1000, 12000, -1]],
        [
            [8.778628102719564, -0.19959140460352975, 4.420673077789257],
            [41.807715966936016, 20.541390563714817, 2.812385557052619],
            [25.755825948620977, 13.376005317506518, 5.133624067410573],
            [-4.057948362499792, -1.6697845468123222, 8.696611031586224],
        ],
        rtol=1e-12,
    )
    rng = np.random.default_rng(5)
    scenario = dataclasses.replace(table2(rng=rng), gyro=GyroSpec(), temperature=TemperatureSpec())
    with_gyro = simulate_session(scenario, rng).recording
    np.testing.assert_array_equal(with_gyro.accel_mps2, full.accel_mps2)
    assert with_gyro.gyro_radps.shape == (19861, 3) and with_gyro.temperature_c.shape == (19861,)


@pytest.mark.parametrize("motion", ["imbalance", "profile"])
def test_session_gyro_follows_every_phase_and_physical_motions(motion):
    base = table2(rng=np.random.default_rng(6))
    if motion == "imbalance":
        moving = ImbalancedSpin(base.truth.spin, 0.3, -0.2)
    else:
        moving = RateProfile(
            (-30.0, -10.0, -9.6, 10.0, 10.4, 30.0), (10.0, 10.0, 11.0, 11.0, 9.0, 9.0)
        )
    scenario = dataclasses.replace(
        base, duration_s=60.0, motion=moving, gyro=GyroSpec.ideal(), noise=NoiseSpec(0.0)
    )
    sim = simulate_session(scenario, np.random.default_rng(7))
    rot = scenario.truth.bench.misalignment.matrix
    np.testing.assert_allclose(
        sim.recording.gyro_radps, -sim.omega_radps[:, None] * rot[:, 2], atol=1e-12
    )
    start, end = sim.window_s
    free = (sim.recording.time_s >= start) & (sim.recording.time_s <= end)
    truth = moving.kinematics(sim.recording.time_s[free] - sim.centre_s).omega_radps
    np.testing.assert_allclose(sim.omega_radps[free], truth, atol=1e-12)
    rest = sim.recording.time_s < 1.0
    assert np.all(sim.recording.gyro_radps[rest] == 0.0)  # at rest the wheel does not turn
    push = (sim.recording.time_s > start - 0.5) & (sim.recording.time_s < start)
    assert np.all(np.abs(sim.recording.gyro_radps[push] @ rot[:, 2]) > 0.5)


@pytest.mark.parametrize("encoding", ["ros2", "json"])
def test_cli_simulate_writes_gyro_and_temperature(tmp_path, encoding, capsys):
    out = tmp_path / "g.mcap"
    truth = tmp_path / "t.json"
    args = ["simulate", str(out), "--gyro", "--temperature", "--format", encoding]
    assert main([*args, "--seed", "3", "--truth", str(truth)]) == 0
    assert "with gyro and temperature" in capsys.readouterr().out
    rec = read_recording(out)
    gyro = json.loads(truth.read_text())["gyro"]
    assert rec.info.gyro_full_scale_dps == 2000.0 and rec.notes == ()
    assert rec.gyro_valid.all()
    # At rest (first 3 s) the gyro reads its bias plus the g-sensitivity to gravity.
    rest = rec.time_s < 3.0
    std = gyro["noise_std_radps"]
    bias_plus_g = rec.gyro_radps[rest].mean(axis=0)
    assert np.all(np.abs(bias_plus_g - gyro["bias_radps"]) < 0.1 * np.pi / 180 + 5 * std)
    # Spinning, it reads k_w u ω along its wheel-axis response.
    spinning = np.abs(rec.gyro_radps @ gyro["axis"]) > 5.0
    assert spinning.sum() > 10_000
    # Temperature warms up by the spec's 3 °C over the 99 s session (τ = 60 s).
    assert 23.8 < rec.temperature_c[0] < 24.2 and 26.0 < rec.temperature_c[-1] < 26.8
    # other options are another recording: replacing it takes --force (issue 40)
    assert main([*args, "--seed", "3", "--gyro-full-scale-dps", "250", "--force"]) == 0
    clipped = read_recording(out)
    assert any("clipped at the gyro range ±250 °/s" in n for n in clipped.notes)
    assert 0.05 < clipped.gyro_valid.mean() < 0.2  # rests, push start and stop only
