"""The field model: a cambered wheel rolling on level ground, and the wheel angle from the gyro.

The oracle is the field simulator (``wheelcal.simulate.field_kinematics``): the
wheel's world-frame positions and attitudes, derived without wheelcal's model
code.  The model (``wheelcal.model.rolling`` with camber, ``wheelcal.model.gyro_angle``)
must reproduce its specific force on whole drives — cambered wheelchairs and cars,
in turns — and its Jacobian must match central differences.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wheelcal.model import (
    BenchParams,
    CalibrationParams,
    ParameterLayout,
    Rotation,
    SensorParams,
    SpinParams,
    evaluate,
    predict,
)
from wheelcal.model.gyro_angle import GyroAngle
from wheelcal.model.rolling import Rolling
from wheelcal.simulate.field import car_drive, robot_drive, simulate_field, wheelchair_coast


def _camber(truth) -> float:
    return float(truth.camber_rad)


def _truth(kind: str, seed: int, **options):
    """A drive's truth; a car's on a level road of one camber unless ``road`` is given."""
    make = {"car": car_drive, "robot": robot_drive, "wheelchair": wheelchair_coast}[kind]
    if kind == "car":
        options = {"road": False, **options}
    rng = np.random.default_rng(seed)
    return simulate_field(make(rng, **options), rng).truth


def _rolling(truth, across: bool) -> tuple[Rolling, dict]:
    """The rolling effect with the truth's yaw: ψ̇ itself, or its share across the axle."""
    m = truth.motion
    scale = np.cos(_camber(truth)) if across else 1.0  # y = ψ̇ cos γ
    effect = Rolling(
        truth.time_s,
        scale * m.yaw_rate_radps,
        scale * m.yaw_accel_radps2,
        yaw_scale_free=False,
        yaw_across_axle=across,
    )
    return effect, {effect.name: np.array([truth.rolling_radius_m])}


@pytest.mark.parametrize("across", [False, True])
@pytest.mark.parametrize(
    "kind, seed, options",
    [
        ("wheelchair", 3, {}),
        ("wheelchair", 4, {"side": -1}),
        ("car", 5, {"camber_deg": 8.0}),
        ("car", 6, {"camber_deg": 0.0}),
        ("robot", 7, {}),
    ],
)
def test_a_cambered_wheel_rolling_in_turns_is_the_rolling_model(kind, seed, options, across):
    truth = _truth(kind, seed, **options)
    assert np.abs(truth.motion.yaw_rate_radps).max() > 0.02, "the drive turns"
    effect, values = _rolling(truth, across)
    params = truth.params().with_changes(effects=values)
    model = evaluate(params, truth.time_s, effects=(effect,), kinematics=truth.kinematics())
    bare = evaluate(truth.params(), truth.time_s, kinematics=truth.kinematics())
    moving = np.abs(truth.clean_accel_mps2 - bare.predicted_mps2).max()
    assert moving > 0.05, "the rolling shows"
    assert np.abs(model.predicted_mps2 - truth.clean_accel_mps2).max() < 1e-6


def test_a_cambered_wheel_needs_the_camber_terms():
    # The vertical wheel's formulas at the cambered wheel's tilt are off by the turns'
    # camber terms: the test above would fail without them.
    truth = _truth("wheelchair", 3)
    effect, values = _rolling(truth, across=False)
    params = truth.params()
    vertical = params.with_changes(
        bench=dataclasses.replace(params.bench, tilt_rad=np.pi / 2), effects=values
    )
    kin = truth.kinematics()
    wrong = evaluate(vertical, truth.time_s, effects=(effect,), kinematics=kin).predicted_mps2
    # compare only the rolling share: both with their own eq. (1)
    bare_vertical = evaluate(vertical, truth.time_s, kinematics=kin).predicted_mps2
    bare = evaluate(params, truth.time_s, kinematics=kin).predicted_mps2
    error = (wrong - bare_vertical) - (truth.clean_accel_mps2 - bare)
    assert np.abs(error).max() > 1e-3


def _gyro_angle_from_truth(truth, centre_s: float) -> tuple[GyroAngle, np.ndarray]:
    """A gyro angle from the truth's body rate as an ideal gyro (k = 1) reads it."""
    m = truth.motion
    gamma = _camber(truth) if truth.camber_rad is not None else 0.0
    t = truth.time_s - centre_s
    axle = m.omega_radps - m.yaw_rate_radps * np.sin(gamma)  # −Ω_z
    axle_dot = m.omega_dot_radps2 - m.yaw_accel_radps2 * np.sin(gamma)
    across = m.yaw_rate_radps * np.cos(gamma)
    across_dot = m.yaw_accel_radps2 * np.cos(gamma)
    return GyroAngle(t, axle, axle_dot, across, across_dot), t


@pytest.mark.parametrize("kind, seed", [("wheelchair", 3), ("car", 5), ("robot", 7)])
def test_the_gyro_angle_is_the_wheel_angle(kind, seed):
    truth = _truth(kind, seed, **({"camber_deg": 8.0} if kind == "car" else {}))
    centre = 0.5 * (truth.time_s[0] + truth.time_s[-1])
    angle, t = _gyro_angle_from_truth(truth, centre)
    theta0 = float(np.interp(centre, truth.time_s, truth.motion.theta_rad))
    params = truth.params().with_changes(
        spin=SpinParams(theta0, [0.0]), effects={angle.name: np.array([1.0])}
    )
    layout = ParameterLayout(spin_degree=0, fit_tilt=True, effects=(angle,))
    kin = evaluate(params, t, layout).kinematics
    # the trapezoid rule on the sampled rate: a few µrad over a drive
    assert np.abs(kin.theta_rad - truth.motion.theta_rad).max() < 1e-4
    assert np.abs(kin.omega_radps - truth.motion.omega_radps).max() < 1e-9
    # with the rolling effect, the whole specific force
    effect, values = _rolling(truth, across=True)
    yaw, yaw_dot = effect.yaw_rate_radps, effect.yaw_accel_radps2
    effect = Rolling(t, yaw, yaw_dot, yaw_scale_free=False, yaw_across_axle=True)
    full = params.with_changes(effects={**params.effects, **values})
    layout = ParameterLayout(spin_degree=0, fit_tilt=True, effects=(angle, effect))
    predicted = predict(full, t, layout)
    assert np.abs(predicted - truth.clean_accel_mps2).max() < 2e-3


def _fd_check(params, t, layout):
    analytic = evaluate(params, t, layout, jacobian=True).jacobian
    x = layout.pack(params)
    for k, name in enumerate(layout.names):
        h = 1e-6
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        fd = (
            predict(layout.unpack(xp, params), t, layout)
            - predict(layout.unpack(xm, params), t, layout)
        ).T / (2 * h)
        scale = np.abs(fd).max()
        assert np.abs(analytic[k] - fd).max() < 2e-5 * scale + 1e-9, name


def _series(t):
    rate = 9.0 + 3.0 * np.sin(0.3 * t) + 0.5 * np.cos(1.1 * t)
    rate_dot = 0.9 * np.cos(0.3 * t) - 0.55 * np.sin(1.1 * t)
    yaw = 0.25 * np.sin(0.4 * t) + 0.05
    yaw_dot = 0.1 * np.cos(0.4 * t)
    return rate, rate_dot, yaw, yaw_dot


def _field_params(tilt_deg: float, effects: dict) -> CalibrationParams:
    return CalibrationParams(
        spin=SpinParams(0.3, [0.02]),
        bench=BenchParams(np.deg2rad(tilt_deg), 0.05, Rotation.from_euler_deg(30.0, 20.0, 25.0)),
        sensor=SensorParams([0.2, -0.1, 0.3], [0.98, 1.01, 1.03]),
        effects=effects,
    )


@pytest.mark.parametrize("yaw_free", [False, True])
@pytest.mark.parametrize("tilt_deg", [72.0, 90.0])
def test_the_field_models_jacobian_is_exact(tilt_deg, yaw_free):
    t = np.linspace(-15.0, 15.0, 1201)
    rate, rate_dot, yaw, yaw_dot = _series(t)
    angle = GyroAngle(t, rate, rate_dot, yaw, yaw_dot)
    rolling = Rolling(t, yaw, yaw_dot, yaw_scale_free=yaw_free, yaw_across_axle=True)
    values = {angle.name: [1.013], rolling.name: [0.3, 0.97, 0.01] if yaw_free else [0.3]}
    params = _field_params(tilt_deg, values)
    # tilt and radius both free: the gyro angle's turns measure α
    layout = ParameterLayout(
        spin_degree=0, fit_tilt=True, fit_radius=True, effects=(angle, rolling)
    )
    _fd_check(params, t, layout)


def test_tilt_and_radius_are_free_together_only_with_an_effect_that_measures_the_tilt():
    with pytest.raises(ValueError, match="null space"):
        ParameterLayout(fit_tilt=True, fit_radius=True)
    t = np.linspace(-1.0, 1.0, 11)
    vertical = Rolling(t, np.zeros_like(t))
    with pytest.raises(ValueError, match="null space"):
        ParameterLayout(fit_tilt=True, fit_radius=True, effects=(vertical,))


def test_gravity_through_the_gyros_g_sensitivity_is_no_lean():
    # A wheel that stops at three angles: the gyro's cross terms across the axle read
    # gravity as g·(c0 + c1 cos 2ϑ + c2 sin 2ϑ) along the direction of travel; no lean.
    from wheelcal.estimate.field.gyro_axle import _lowpass, lean_change_rad, lean_in_turns

    rate_hz = 100.0
    t = np.arange(0.0, 90.0, 1.0 / rate_hz)
    omega = np.where((t % 30.0) < 22.0, 20.0, 0.0)  # 22 s at 20 rad/s, then 8 s stopped
    theta = np.cumsum(omega) / rate_hz + 0.4
    g_rate = np.deg2rad(0.15)  # 0.15 °/s/g at 1 g
    raw = g_rate * (0.8 + 0.5 * np.cos(2 * theta) - 0.7 * np.sin(2 * theta))
    lean_rate = _lowpass(raw, rate_hz, 1.0)
    yaw = np.zeros_like(t)
    assert np.rad2deg(lean_change_rad(t, lean_rate, theta, yaw)) < 0.01
    turns = lean_in_turns(t, lean_rate, theta, yaw, np.sin(0.3 * t))
    assert turns.range_rad < np.deg2rad(0.01)


def test_every_pass_of_the_fit_carries_the_priors():
    # A gyro's G under its prior, at 2 σ of it: the stage-2 start (accumulate_fitting_noise),
    # the Jacobian pass (accumulate), the gradient pass and the cost-only pass must give one
    # cost, gradient and Hessian.  The start had none of the prior: its step went 10³ σ along
    # G and its cost sat Σ (x/σ)² below every later pass ("stalled" wheelchair hubs).
    from wheelcal.estimate.joint.fit import _LastResidual, _residual_fn
    from wheelcal.estimate.joint.noise_model import NoiseModel
    from wheelcal.estimate.joint.normal_equations import (
        accumulate,
        accumulate_fitting_noise,
        gradient_pass,
    )
    from wheelcal.model import evaluate

    t = np.linspace(-15.0, 15.0, 1201)
    rate, rate_dot, _, _ = _series(t)
    force = np.column_stack([np.sin(t), np.cos(0.7 * t), 9.0 + 0.0 * t])
    angle = GyroAngle(t, rate, rate_dot, accel_mps2=force, g_prior_std=1e-3)
    params = _field_params(72.0, {angle.name: [1.01, 2e-3, -1e-3, 5e-4]})
    layout = ParameterLayout(spin_degree=0, fit_tilt=True, fit_radius=True, effects=(angle,))
    rng = np.random.default_rng(0)
    data = evaluate(params, t, layout).predicted_mps2 + rng.normal(0.0, 0.02, (t.size, 3))
    noise = NoiseModel.white(np.full(3, 0.02))
    start, _ = accumulate_fitting_noise(params, t, data, layout, lambda r: noise)
    full = accumulate(params, t, data, layout, noise, jacobian=True)
    grad = gradient_pass(params, t, data, layout, noise)
    cost_only = _LastResidual(_residual_fn(t, data, layout, noise), t, data, layout, noise)
    residual = data - evaluate(params, t, layout).predicted_mps2
    prior = 2.0**2 + 1.0**2 + 0.5**2  # G at (2, −1, 0.5) σ
    assert full.cost - np.sum((residual / 0.02) ** 2) == pytest.approx(prior, rel=1e-6)
    for other in (start, grad, cost_only(params, False)):
        assert other.cost == pytest.approx(full.cost, rel=1e-12)
    for other in (start, grad):
        np.testing.assert_allclose(other.gradient[: layout.size], full.gradient[: layout.size])
    np.testing.assert_allclose(start.hessian, full.hessian, rtol=1e-10, atol=1e-12)


def test_an_effect_with_another_yaw_is_the_effect_built_with_it():
    # with_yaw (the field fit's propagation of the gyro's G across the axle) against
    # the effects built from scratch with the new yaw: the same prediction and Jacobian,
    # and the effect it came from unchanged.
    t = np.linspace(-15.0, 15.0, 1201)
    rate, rate_dot, yaw, yaw_dot = _series(t)
    other, other_dot = 0.8 * yaw + 0.02 * np.cos(2.1 * t), 0.8 * yaw_dot - 0.042 * np.sin(2.1 * t)
    theta = 9.0 * t

    def cross(y):
        return np.vstack([y * np.cos(theta), y * np.sin(theta)])

    force = np.column_stack([np.sin(t), np.cos(0.7 * t), 9.0 + 0.0 * t])

    def built(y, y_dot):
        angle = GyroAngle(t, rate, rate_dot, y, y_dot, cross(y), force, g_prior_std=1e-3)
        return angle, Rolling(t, y, y_dot, yaw_across_axle=True, yaw_scale_prior_std=0.01)

    angle, rolling = built(yaw, yaw_dot)
    values = [1.01, 2e-3, -1e-3, 1e-3, -2e-3, 5e-4]
    params = _field_params(72.0, {angle.name: values, rolling.name: [0.3, 1.02, 1e-3]})

    def evaluated(effects):
        layout = ParameterLayout(spin_degree=0, fit_tilt=True, fit_radius=True, effects=effects)
        return evaluate(params, t, layout, jacobian=True)

    before = evaluated((angle, rolling))
    moved = evaluated(
        (angle.with_yaw(other, other_dot, cross(other)), rolling.with_yaw(other, other_dot))
    )
    fresh = evaluated(built(other, other_dot))
    np.testing.assert_allclose(moved.predicted_mps2, fresh.predicted_mps2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(moved.jacobian, fresh.jacobian, rtol=0, atol=1e-10)
    assert np.abs(moved.predicted_mps2 - before.predicted_mps2).max() > 1e-3  # the yaw matters
    again = evaluated((angle, rolling))  # the originals keep their own yaw
    np.testing.assert_array_equal(again.predicted_mps2, before.predicted_mps2)
    with pytest.raises(ValueError, match="cross"):
        angle.with_yaw(other, other_dot)


def _track_series(t):
    """A camber's change (rad) and two basis series, smooth and zero at t = 0."""
    track = 0.06 * np.sin(0.2 * t) + 0.02 * (1 - np.cos(0.5 * t))
    basis = {"drift_radps": t.copy(), "heading": 0.1 * np.sin(0.4 * t)}
    return track, basis


@pytest.mark.parametrize("yaw_free", [False, True])
@pytest.mark.parametrize("tilt_deg", [72.0, 88.0])
def test_the_camber_tracks_jacobian_is_exact(tilt_deg, yaw_free):
    # The rolling wheel with a camber track (gravity turned by Δγ(t), the turns at Γ(t))
    # and the gyro angle's ψ̇ sin γ(t): every column against central differences.
    t = np.linspace(-15.0, 15.0, 1201)
    rate, rate_dot, yaw, yaw_dot = _series(t)
    track, basis = _track_series(t)
    angle = GyroAngle(t, rate, rate_dot, yaw, yaw_dot, camber_track_rad=track)
    rolling = Rolling(
        t,
        yaw,
        yaw_dot,
        yaw_scale_free=yaw_free,
        yaw_across_axle=True,
        camber_track_rad=track,
        camber_basis=basis,
    )
    assert rolling.camber_names == ("camber_drift_radps", "camber_heading")
    values = [0.3, 0.97, 0.01] if yaw_free else [0.3]
    params = _field_params(tilt_deg, {angle.name: [1.013], rolling.name: [*values, 2e-3, 0.05]})
    layout = ParameterLayout(
        spin_degree=0, fit_tilt=True, fit_radius=True, effects=(angle, rolling)
    )
    _fd_check(params, t, layout)


def test_a_camber_track_of_zeros_is_one_camber():
    t = np.linspace(-15.0, 15.0, 601)
    _, _, yaw, yaw_dot = _series(t)
    flat = Rolling(t, yaw, yaw_dot, yaw_across_axle=True)
    zero = Rolling(
        t,
        yaw,
        yaw_dot,
        yaw_across_axle=True,
        camber_track_rad=np.zeros_like(t),
        camber_basis={"drift_radps": t.copy()},
    )
    params = _field_params(80.0, {"rolling": [0.3, 0.99, 0.002]})
    with_track = params.with_changes(effects={"rolling": [0.3, 0.99, 0.002, 0.0]})
    a = predict(params, t, ParameterLayout(spin_degree=0, effects=(flat,)))
    b = predict(with_track, t, ParameterLayout(spin_degree=0, effects=(zero,)))
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    # a drift of 1 mrad/s turns the camber by 15 mrad at the window's ends: g·0.015 on a_Z
    drifting = with_track.with_changes(effects={"rolling": [0.3, 0.99, 0.002, 1e-3]})
    c = predict(drifting, t, ParameterLayout(spin_degree=0, effects=(zero,)))
    assert np.abs(c - b).max() > 0.1


@pytest.mark.parametrize("roll", [0.4, 0.8])
def test_a_camber_that_changes_is_the_rolling_model_with_its_track(roll):
    # The oracle (the simulator's world-frame kinematics) with a camber that follows the
    # turns (a body's roll, γ(t) = γ₀ + k·v ψ̇): the model with the true track l(t) = γ(t) −
    # γ(0) reproduces the specific force (to the finite differences of the sampled track
    # that give its rate λ and λ̇: ≤ 5 mm/s²; without the roll's own terms, 2 r ω λ, it was
    # 0.21 m/s² off); one camber misses it by g·Δγ on a_Z.
    make_car = car_drive
    rng = np.random.default_rng(21)
    scenario = dataclasses.replace(
        make_car(rng, camber_deg=2.0, road=False), body_roll_deg_per_mps2=roll
    )
    truth = simulate_field(scenario, rng).truth
    m = truth.motion
    t = truth.time_s
    camber = _true_camber(truth, scenario)
    centre = int(np.argmin(np.abs(t - 0.5 * (t[0] + t[-1]))))
    track = camber - camber[centre]
    assert np.ptp(np.rad2deg(track)) > 1.0, "the camber changes"
    across = m.yaw_rate_radps * np.cos(camber)  # y = ψ̇ cos γ(t), what the gyro reads
    across_dot = np.gradient(across, t)
    rolling = Rolling(
        t,
        across,
        across_dot,
        yaw_scale_free=False,
        yaw_across_axle=True,
        camber_track_rad=track,
        camber_basis={},
    )
    bench = dataclasses.replace(truth.bench, tilt_rad=np.pi / 2 - camber[centre])
    params = truth.params().with_changes(
        bench=bench, effects={rolling.name: np.array([truth.rolling_radius_m])}
    )
    kin = truth.kinematics()
    model = evaluate(params, t, effects=(rolling,), kinematics=kin).predicted_mps2
    assert np.abs(model - truth.clean_accel_mps2).max() < 1e-2
    flat = Rolling(t, across, across_dot, yaw_scale_free=False, yaw_across_axle=True)
    one = evaluate(params, t, effects=(flat,), kinematics=kin).predicted_mps2
    assert np.abs(one - truth.clean_accel_mps2).max() > 0.1


def _true_camber(truth, scenario) -> np.ndarray:
    """γ(t) of a simulated drive whose carrier rolls with its lateral acceleration."""
    from wheelcal.simulate.field_record import _leaning

    m = truth.motion
    wheel = scenario.wheel
    _, lean = _leaning(m, wheel, np.deg2rad(scenario.body_roll_deg_per_mps2), truth.time_s)
    return lean.camber_rad
