"""The axle and the gyro's bias across it, from the gyro alone, against a synthetic truth.

The samples are built here (not by the simulator): g(t) = ω(t) ŵ + ψ̇(t) u(ϑ) + b + noise,
with ŵ, b, the speed profile and a yaw turning with the wheel chosen by the test.
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.field.gyro_axle import gyro_axle, refined_axle


def _drive(rng: np.random.Generator, axis: np.ndarray, bias: np.ndarray, yaw_radps: float = 0.3):
    t = np.arange(0.0, 120.0, 1.0 / 200.0)
    # speed changes and two stops: the rate the bias must be told from
    omega = 12.0 * np.clip(np.sin(2 * np.pi * t / 60.0) ** 2 + 0.3 * np.sin(t / 7.0), 0.0, None)
    theta = np.cumsum(omega) / 200.0
    e1 = np.cross(axis, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    up = np.outer(np.cos(theta), e1) + np.outer(np.sin(theta), e2)  # turns with the wheel
    yaw = yaw_radps * np.sin(2 * np.pi * t / 9.0) * (omega > 1.0)
    noise = 0.003 * rng.standard_normal((t.size, 3))
    gyro = np.outer(omega, axis) + yaw[:, None] * up + bias + noise
    return t, gyro, theta, np.column_stack([e1, e2, axis])


def test_the_axle_and_the_bias_across_it_are_found_when_the_speed_changes():
    rng = np.random.default_rng(4)
    axis = np.array([0.05, -0.998, 0.03])
    axis /= np.linalg.norm(axis)
    bias = np.array([-0.026, -0.015, 0.011])
    t, gyro, _, _ = _drive(rng, axis, bias)
    found = gyro_axle(t, gyro)
    across_truth = bias - (bias @ axis) * axis
    sign = np.sign(found.axis @ axis)
    # the principal direction alone leans toward b⊥ by |b⊥| / ω: 0.165° here
    assert np.rad2deg(np.arccos(min(1.0, sign * found.axis @ axis))) < 0.03
    # |b⊥| = 0.029 rad/s; what is left is the yaw's turning share that does not average
    # out over this drive (0.0035 rad/s, the same for every noise seed)
    np.testing.assert_allclose(found.across_bias_radps, across_truth, atol=4e-3)
    assert abs(found.across_bias_radps @ found.axis) < 1e-12  # along the axle: the fit's ω₀
    # the samples across the axle, less the bias, are the yaw and the noise only
    across = found.across(gyro)
    still = np.linalg.norm(gyro, axis=1) < 0.1  # the stops: the bias only
    assert np.linalg.norm(np.mean(across[still], axis=0)) < 4e-3


def test_a_steady_spin_keeps_the_principal_axis_and_no_bias():
    """A constant rate cannot tell a tilted axle from a bias: no bias is claimed."""
    t = np.arange(0.0, 30.0, 0.005)
    axis = np.array([0.0, 0.0, 1.0])
    gyro = np.outer(np.full(t.size, 10.0), axis) + np.array([0.02, 0.0, 0.0])
    found = gyro_axle(t, gyro)
    np.testing.assert_array_equal(found.across_bias_radps, np.zeros(3))


def test_the_bias_across_the_axle_once_the_wheel_angle_is_known():
    """A robot's turns (1.5 rad/s of yaw) leak into the regression's b⊥; across the axle and
    ⊥ the yaw's direction (known with ϑ) the gyro reads the bias alone."""
    rng = np.random.default_rng(5)
    axis = np.array([0.03, -0.998, -0.05])
    axis /= np.linalg.norm(axis)
    bias = np.array([-0.026, 0.004, 0.011])
    t, gyro, theta, rotation = _drive(rng, axis, bias, yaw_radps=1.5)
    first = gyro_axle(t, gyro)
    refined = refined_axle(gyro, first, theta, rotation)
    across_truth = bias - (bias @ axis) * axis
    sign = np.sign(refined.axis @ axis)
    assert np.linalg.norm(first.across_bias_radps - across_truth) > 5e-3  # what it fixes
    np.testing.assert_allclose(refined.across_bias_radps, across_truth, atol=5e-4)
    assert np.rad2deg(np.arccos(min(1.0, sign * refined.axis @ axis))) < 0.01
    np.testing.assert_array_equal(refined.rate_radps, first.rate_radps)
