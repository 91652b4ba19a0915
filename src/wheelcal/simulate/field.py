"""Field recordings simulated exactly: car, robot and wheelchair wheels, a bench, a stand.

A wheel-mounted accelerometer (and gyro) on a vehicle's wheel rolling without
slip on level ground — speed changes, turns, stops, camber, rim or hub
mounting, road vibration, logger glitches — or on a fixed axle (the paper's
tilted bench, a vertical wheel on a stand), through one physical model:

    scenario = car_drive(rng)                  # the truth, drawn
    sim = simulate_field(scenario, rng)        # the recording, drawn
    sim.recording   # wheelcal.recording.Recording (no radius unless include_radius)
    sim.truth       # FieldTruth: sensor, bench (α, r, R), ρ, γ, ϑ(t), ω(t), ψ̇(t), …
    sim.logged      # the logger's raw rows (duplicate stamps only here)

Change anything with ``dataclasses.replace(scenario, glitches=Glitches(gyro_spikes=1))``.

Layers: :mod:`~wheelcal.simulate.field_motion` (motion laws, exact
piecewise cubics) → :mod:`~wheelcal.simulate.field_kinematics` (the geometry
— camber, side, ρ, the sensor's lever — and the rigid-body derivation) →
:mod:`~wheelcal.simulate.field_record` (sensor, vibration
(:mod:`~wheelcal.simulate.road`), gyro, glitches
(:mod:`~wheelcal.simulate.logger_glitches`), truth).  None of it uses the
estimator's model code; the tests cross-check both.

The profiles below draw every random quantity from the generator passed in.
Ranges follow the field recordings of issue 26: factory-calibrated sensors
(gains 1 ± 3 %, offsets < 0.4 m/s²) strapped ~0.15 m from a car's axle at
120 Hz; hub sensors ~5 cm from a wheelchair's axle at 18° camber, 400 Hz.
Mounting: ``"aligned"`` — one sensor axis within 2–5° of the axle, as a strap
or a hub mount leaves it (about the axle: within ±5° of radial on a rim,
anywhere on a hub); ``"random"`` — uniform over all rotations.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Literal

import numpy as np

from wheelcal.model import Rotation, SensorParams
from wheelcal.model.rotation import exp_so3
from wheelcal.simulate.field_kinematics import WheelGeometry, wheel_kinematics
from wheelcal.simulate.field_motion import AxleSpin, MotionState, SmoothLaw, VehiclePath
from wheelcal.simulate.field_record import (
    GEOMETRIES,
    FieldScenario,
    FieldSimulation,
    FieldTruth,
    simulate_field,
)
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.logger_glitches import Glitches, LoggedSamples
from wheelcal.simulate.noise import NoiseSpec
from wheelcal.simulate.presets import hand_spin, random_rotation
from wheelcal.simulate.road import VibrationSpec

__all__ = [
    "GEOMETRIES",
    "AxleSpin",
    "FieldScenario",
    "FieldSimulation",
    "FieldTruth",
    "Glitches",
    "LoggedSamples",
    "MotionState",
    "SmoothLaw",
    "VehiclePath",
    "VibrationSpec",
    "WheelGeometry",
    "bench_spin",
    "car_drive",
    "draw_mounting",
    "robot_drive",
    "simulate_field",
    "stand_spin",
    "wheel_kinematics",
    "wheelchair_coast",
]

Mounting = Literal["aligned", "random"]


def _square_rotations() -> list[np.ndarray]:
    """The 24 proper signed permutations: a sensor mounted square to the wheel."""
    out = []
    for order in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            matrix = np.diag(signs) @ np.eye(3)[list(order)]
            if np.linalg.det(matrix) > 0:
                out.append(matrix)
    return out


_SQUARE = _square_rotations()


def draw_mounting(
    rng: np.random.Generator,
    style: Mounting = "aligned",
    axle_tilt_deg: tuple[float, float] = (2.0, 5.0),
    about_axle_deg: tuple[float, float] | None = None,
) -> Rotation:
    """R (bench → sensor) of a sensor strapped or screwed on a wheel.

    ``"aligned"``: square to the wheel (a random signed permutation: some axis
    along ±Z), turned about the axle by ``about_axle_deg`` (``None``: anywhere),
    then its axle axis tilted by ``axle_tilt_deg`` in a random direction.
    ``"random"``: uniform over all rotations.
    """
    if style == "random":
        return random_rotation(rng)
    if style != "aligned":
        raise ValueError(f"mounting must be 'aligned' or 'random', got {style!r}")
    square = _SQUARE[int(rng.integers(len(_SQUARE)))]
    about = rng.uniform(-180.0, 180.0) if about_axle_deg is None else rng.uniform(*about_axle_deg)
    tilt = np.deg2rad(rng.uniform(*axle_tilt_deg))
    direction = rng.uniform(-np.pi, np.pi)
    turn = exp_so3(np.deg2rad(about) * np.array([0.0, 0.0, 1.0]))
    lean = exp_so3(tilt * np.array([np.cos(direction), np.sin(direction), 0.0]))
    return Rotation(square @ turn @ lean)


def _sensor(rng: np.random.Generator, gain_spread: float, offset_mps2: float) -> SensorParams:
    return SensorParams(
        offset_mps2=rng.uniform(-offset_mps2, offset_mps2, 3),
        gain=rng.uniform(1.0 - gain_spread, 1.0 + gain_spread, 3),
    )


def _gyro(rng: np.random.Generator, grade: Literal["factory", "mems"]) -> GyroSpec:
    """A gyro with drawn errors: a factory-calibrated IMU (Xsens DOT, NGIMU) or a bare MEMS part.

    The factory grade has no range limit here: a DOT's ±2000 °/s clips a car's
    wheel above ~10 m/s, which the drives would lose (pass a GyroSpec to model it).
    """
    if grade == "factory":
        bias, scale, misalign, density, g_sens, full_scale = 0.005, 0.003, 0.3, 0.007, 0.02, None
    else:
        bias, scale, misalign, density, g_sens, full_scale = 0.03, 0.02, 1.5, 0.01, 0.1, 2000.0
    return GyroSpec(
        noise_density_dps_rthz=density,
        bias_radps=tuple(rng.uniform(-bias, bias, 3)),
        scale_error=tuple(rng.uniform(-scale, scale, 3)),
        misalignment_deg=tuple(rng.uniform(-misalign, misalign, 3)),
        g_sensitivity_dps_per_g=g_sens,
        full_scale_dps=full_scale,
    )


def _side(rng: np.random.Generator, side: int | None) -> int:
    return int(rng.choice([1, -1])) if side is None else side


def _pick(rng: np.random.Generator, value: float | None, low: float, high: float) -> float:
    return float(rng.uniform(low, high)) if value is None else float(value)


@dataclass(frozen=True)
class DrivePlan:
    """How a vehicle is driven: ranges (low, high) that :func:`drive_path` draws from.

    Cruising speeds (m/s), accelerations and decelerations (m/s², peak of each
    ramp), cruise and stop durations (s), rests at the start and the end (s),
    stops every ``stop_every_s``; a turn in a cruise with ``turn_probability``,
    at a lateral acceleration v ψ̇ from ``lateral_mps2`` but |ψ̇| ≤ ``max_yaw_radps``.
    A cruise drifts in speed by up to ±``drift`` (so turns meet speed changes).
    """

    speed_mps: tuple[float, float]
    accel_mps2: tuple[float, float]
    brake_mps2: tuple[float, float]
    cruise_s: tuple[float, float]
    stop_s: tuple[float, float]
    rest_s: tuple[float, float]
    stop_every_s: tuple[float, float]
    lateral_mps2: tuple[float, float]
    max_yaw_radps: float
    turn_probability: float = 0.7
    drift: float = 0.1


CAR_PLAN = DrivePlan(
    speed_mps=(2.0, 15.0),
    accel_mps2=(0.8, 2.5),
    brake_mps2=(1.0, 3.0),
    cruise_s=(4.0, 14.0),
    stop_s=(2.0, 8.0),
    rest_s=(2.0, 5.0),
    stop_every_s=(25.0, 60.0),
    lateral_mps2=(0.5, 3.5),
    max_yaw_radps=0.6,
)
ROBOT_PLAN = DrivePlan(
    speed_mps=(0.2, 1.5),
    accel_mps2=(0.3, 1.0),
    brake_mps2=(0.4, 1.2),
    cruise_s=(2.5, 8.0),
    stop_s=(1.0, 4.0),
    rest_s=(1.0, 3.0),
    stop_every_s=(15.0, 40.0),
    lateral_mps2=(0.1, 0.8),
    max_yaw_radps=1.5,
)


def _ramp_s(change_mps: float, rate_mps2: float) -> float:
    """A PCHIP ramp between flat knots peaks at 1.5 × its mean slope."""
    return max(1.0, 1.5 * abs(change_mps) / rate_mps2)


def drive_path(rng: np.random.Generator, plan: DrivePlan, duration_s: float) -> VehiclePath:
    """A drive from rest to rest: speed changes, cruises (with turns) and full stops.

    Each leg ramps to a new cruising speed, cruises (drifting a little), and
    after ``stop_every_s`` brakes to a full stop; a leg that would not leave
    time to brake and rest before ``duration_s`` is drawn again (up to five
    times: slower legs fit better), else the drive ends.
    """
    times, speeds = [0.0, rng.uniform(*plan.rest_s)], [0.0, 0.0]
    end_rest = rng.uniform(*plan.rest_s)
    low, high = plan.speed_mps
    cruises: list[tuple[float, float, float]] = []
    t, v = times[-1], 0.0
    next_stop = t + rng.uniform(*plan.stop_every_s)
    tries = 0
    while tries < 5:
        target = rng.uniform(low, high)
        rate = rng.uniform(*(plan.accel_mps2 if target > v else plan.brake_mps2))
        ramp = _ramp_s(target - v, rate)
        cruise = rng.uniform(*plan.cruise_s)
        drifted = float(np.clip(target * (1 + rng.uniform(-plan.drift, plan.drift)), low, high))
        to_rest = _ramp_s(max(target, drifted), plan.brake_mps2[0]) + end_rest
        if t + ramp + cruise + to_rest > duration_s:
            tries += 1
            continue
        tries = 0
        times += [t + ramp, t + ramp + cruise]
        speeds += [target, drifted]
        cruises.append((t + ramp, t + ramp + cruise, max(target, drifted)))
        t, v = t + ramp + cruise, drifted
        stand = rng.uniform(*plan.stop_s)
        brake = _ramp_s(v, rng.uniform(*plan.brake_mps2))
        if t > next_stop and t + brake + stand + to_rest + plan.cruise_s[0] < duration_s:
            times += [t + brake, t + brake + stand]
            speeds += [0.0, 0.0]
            t, v = t + brake + stand, 0.0
            next_stop = t + rng.uniform(*plan.stop_every_s)
    if not cruises:
        raise ValueError(f"{duration_s:g} s is too short for a drive with this plan")
    t += _ramp_s(v, rng.uniform(*plan.brake_mps2))
    times += [t, max(t, duration_s) + 1.0]
    speeds += [0.0, 0.0]
    yaw = _turns(rng, plan, cruises, times[-1])
    return VehiclePath(
        speed=SmoothLaw.through(times, speeds),
        yaw_rate=yaw,
        theta0_rad=rng.uniform(-np.pi, np.pi),
        heading0_rad=rng.uniform(-np.pi, np.pi),
    )


def _turns(rng, plan: DrivePlan, cruises, end_s: float) -> SmoothLaw:
    """ψ̇(t): zero but for turns inside cruises (ramps of 0.6–1.5 s)."""
    times, rates = [0.0], [0.0]
    for start, stop, fastest in cruises:
        room = stop - start - 0.4
        if room < 2.0 or rng.uniform() > plan.turn_probability:
            continue
        length = rng.uniform(2.0, room)
        begin = start + 0.2 + rng.uniform(0.0, room - length)
        ramp = min(rng.uniform(0.6, 1.5), length / 3)
        rate = min(rng.uniform(*plan.lateral_mps2) / fastest, plan.max_yaw_radps)
        rate *= rng.choice([-1.0, 1.0])
        times += [begin, begin + ramp, begin + length - ramp, begin + length]
        rates += [0.0, rate, rate, 0.0]
    times.append(end_s)
    rates.append(0.0)
    return SmoothLaw.through(times, rates)


def car_drive(
    rng: np.random.Generator,
    *,
    duration_s: float = 120.0,
    rate_hz: float = 120.0,
    camber_deg: float | None = None,
    radius_m: float | None = None,
    rolling_radius_m: float | None = None,
    side: int | None = None,
    mounting: Mounting = "aligned",
    axle_offset_m: float = 0.0,
    vibration_mps2: float | None = None,
    gyro: bool = True,
    glitches: Glitches | None = None,
    include_radius: bool = False,
) -> FieldScenario:
    """A car's wheel: a 2-minute drive at 0–15 m/s with turns and stops.

    Drawn where not given: camber 0–2°, the sensor 0.12–0.18 m from the axle on
    the rim, ρ 0.28–0.33 m, either side, road vibration 0.3–1.5 m/s² rms
    (vertical; 5–30 Hz, full above 10 m/s, ∝ √v below), accelerometer noise
    0.008–0.02 m/s², a factory-calibrated gyro; mounting within ±5° of radial
    about the axle.
    """
    wheel = WheelGeometry.rolling(
        _pick(rng, camber_deg, 0.0, 2.0),
        _pick(rng, radius_m, 0.12, 0.18),
        _pick(rng, rolling_radius_m, 0.28, 0.33),
        _side(rng, side),
        axle_offset_m,
    )
    return FieldScenario(
        kind="car",
        wheel=wheel,
        motion=drive_path(rng, CAR_PLAN, duration_s),
        sensor=_sensor(rng, 0.03, 0.4),
        mounting=draw_mounting(rng, mounting, about_axle_deg=(-5.0, 5.0)),
        duration_s=duration_s,
        rate_hz=rate_hz,
        noise=NoiseSpec(rng.uniform(0.008, 0.02)),
        vibration=VibrationSpec(_pick(rng, vibration_mps2, 0.3, 1.5)),
        gyro=_gyro(rng, "factory") if gyro else None,
        glitches=glitches or Glitches(),
        include_radius=include_radius,
        sensor_id="car-wheel",
    )


def robot_drive(
    rng: np.random.Generator,
    *,
    duration_s: float = 90.0,
    rate_hz: float | None = None,
    mount: Literal["rim", "hub"] | None = None,
    radius_m: float | None = None,
    rolling_radius_m: float | None = None,
    side: int | None = None,
    mounting: Mounting | None = None,
    axle_offset_m: float = 0.0,
    vibration_mps2: float | None = None,
    gyro: bool = True,
    glitches: Glitches | None = None,
    include_radius: bool = False,
) -> FieldScenario:
    """A small robot's wheel: slow drives (0.2–1.5 m/s) with tight turns and stops.

    Drawn where not given: 100, 200 or 400 Hz; ρ 0.05–0.1 m; a sensor on the
    rim (r 0.5–0.85 ρ) or the hub (r 5–20 mm); camber 0; either mounting style;
    vibration 0.1–0.6 m/s² (10–60 Hz, full above 1 m/s); a bare MEMS IMU
    (noise 0.02–0.06 m/s², gains 1 ± 5 %, offsets < 0.5 m/s²).
    """
    rate = float(rng.choice([100.0, 200.0, 400.0])) if rate_hz is None else rate_hz
    rho = _pick(rng, rolling_radius_m, 0.05, 0.1)
    where = mount or ("rim" if rng.uniform() < 0.5 else "hub")
    low, high = (0.5 * rho, 0.85 * rho) if where == "rim" else (0.005, 0.02)
    wheel = WheelGeometry.rolling(
        0.0, _pick(rng, radius_m, low, high), rho, _side(rng, side), axle_offset_m
    )
    style = mounting or ("aligned" if rng.uniform() < 0.5 else "random")
    about = (-5.0, 5.0) if where == "rim" else None
    return FieldScenario(
        kind="robot",
        wheel=wheel,
        motion=drive_path(rng, ROBOT_PLAN, duration_s),
        sensor=_sensor(rng, 0.05, 0.5),
        mounting=draw_mounting(rng, style, about_axle_deg=about),
        duration_s=duration_s,
        rate_hz=rate,
        noise=NoiseSpec(rng.uniform(0.02, 0.06)),
        vibration=VibrationSpec(
            _pick(rng, vibration_mps2, 0.1, 0.6), band_hz=(10.0, 60.0), full_speed_mps=1.0
        ),
        gyro=_gyro(rng, "mems") if gyro else None,
        glitches=glitches or Glitches(),
        include_radius=include_radius,
        sensor_id="robot-wheel",
    )


def _coast(v0: float, resistance_mps2: float, drag_per_m: float, tau: np.ndarray) -> np.ndarray:
    """v(τ) of v̇ = −a − b v² from v0 (closed form), 0 once stopped."""
    k = np.sqrt(resistance_mps2 / drag_per_m)
    phase = np.arctan(v0 / k) - drag_per_m * k * tau
    return np.where(phase > 0, k * np.tan(np.maximum(phase, 0.0)), 0.0)


def wheelchair_coast(
    rng: np.random.Generator,
    *,
    rate_hz: float = 400.0,
    coast_s: float | None = None,
    camber_deg: float | None = None,
    radius_m: float | None = None,
    rolling_radius_m: float | None = None,
    side: int | None = None,
    axle_offset_m: float = 0.0,
    vibration_mps2: float | None = None,
    gyro: bool = True,
    glitches: Glitches | None = None,
    include_radius: bool = False,
) -> FieldScenario:
    """A manual wheelchair's hub sensor: rest, one push, ~20 s coasting, stop, rest.

    Drawn where not given: camber 16–20°, the sensor 4–6 cm from the axle, ρ
    0.28–0.32 m, either side; a push (0.6–1 s) to 1.2–2.2 m/s, then coasting
    by v̇ = −a − b v² (a 0.03–0.08 m/s², b 0.005–0.02 /m) for 18–22 s or to a
    stop, a hand's stop; the heading drifts gently (curvature ~0.01–0.03 /m
    wandering every 2 s, so ψ̇ = κ v vanishes at rest); vibration 0.05–0.3
    m/s² (5–40 Hz, full above 1.5 m/s); hub mounting (any angle about the axle,
    2–5° off it); a factory-calibrated IMU.
    """
    rest = rng.uniform(2.0, 4.0)
    push = rng.uniform(0.6, 1.0)
    v0 = rng.uniform(1.2, 2.2)
    coast = _pick(rng, coast_s, 18.0, 22.0)
    resistance, drag = rng.uniform(0.03, 0.08), rng.uniform(0.005, 0.02)
    start = rest + push
    tau = np.arange(0.0, coast + 1e-9, 0.25)
    speeds = _coast(v0, resistance, drag, tau)
    moving = int(np.count_nonzero(speeds > 0))  # the law is positive until it stops
    times, values = list(start + tau[:moving]), list(speeds[:moving])
    if moving < tau.size:  # stopped while coasting: at the first zero knot
        stop_at = start + tau[moving]
    else:  # still rolling: a hand on the rim stops it
        stop_at = times[-1] + _ramp_s(values[-1], rng.uniform(0.5, 1.0))
    end = stop_at + rng.uniform(2.0, 4.0)
    speed = SmoothLaw.through([0.0, rest, *times, stop_at, end + 1.0], [0, 0, *values, 0, 0])
    curvature = rng.uniform(-0.03, 0.03) + rng.normal(0.0, 0.01, len(times[::8]))
    yaw_times = [0.0, rest, *times[::8], stop_at, end + 1.0]
    yaw = [0.0, 0.0, *(curvature * np.asarray(values[::8])), 0.0, 0.0]
    wheel = WheelGeometry.rolling(
        _pick(rng, camber_deg, 16.0, 20.0),
        _pick(rng, radius_m, 0.04, 0.06),
        _pick(rng, rolling_radius_m, 0.28, 0.32),
        _side(rng, side),
        axle_offset_m,
    )
    path = VehiclePath(
        speed,
        SmoothLaw.through(yaw_times, yaw),
        rng.uniform(-np.pi, np.pi),
        rng.uniform(-np.pi, np.pi),
    )
    duration = np.floor(end * rate_hz) / rate_hz
    return FieldScenario(
        kind="wheelchair",
        wheel=wheel,
        motion=path,
        sensor=_sensor(rng, 0.03, 0.4),
        mounting=draw_mounting(rng, "aligned"),
        duration_s=duration,
        rate_hz=rate_hz,
        noise=NoiseSpec(rng.uniform(0.01, 0.03)),
        vibration=VibrationSpec(
            _pick(rng, vibration_mps2, 0.05, 0.3), band_hz=(5.0, 40.0), full_speed_mps=1.5
        ),
        gyro=_gyro(rng, "factory") if gyro else None,
        glitches=glitches or Glitches(),
        include_radius=include_radius,
        sensor_id="wheelchair-hub",
    )


def bench_spin(
    rng: np.random.Generator,
    *,
    tilt_deg: float | None = None,
    radius_m: float | None = None,
    free_spin_s: float | None = None,
    rate_hz: float = 200.0,
    mounting: Mounting = "random",
    axle_offset_m: float = 0.0,
    hand_shake_mps2: float = 0.8,
    gyro: bool = True,
    glitches: Glitches | None = None,
    include_radius: bool = False,
    kind: str = "bench",
) -> FieldScenario:
    """The paper's bench: a wheel on a fixed axle tilted by α, spun by hand, left to spin down.

    Rest 3–5 s, a push (0.6–1 s), a free spin-down of 60–90 s (quadratic drag
    as :func:`~wheelcal.simulate.presets.hand_spin`, 8–14 rad/s, either way),
    a brake (1–2 s), rest 2–4 s; push and brake are cubic Hermite pieces that
    meet the free spin's ω and ω̇, and the hand shakes the wheel meanwhile
    (``hand_shake_mps2`` rms, below 3 Hz).  Drawn where not given: α 10–85°,
    r 0.15–0.35 m; an MPU-9250-class sensor (noise 0.03–0.08 m/s², gains
    1 ± 5 %, offsets < 0.5 m/s², a bare MEMS gyro).
    """
    tilt = _pick(rng, tilt_deg, 10.0, 85.0)
    wheel = WheelGeometry(
        np.deg2rad(tilt), _pick(rng, radius_m, 0.15, 0.35), None, 1, axle_offset_m
    )
    free = _pick(rng, free_spin_s, 60.0, 90.0)
    spin = hand_spin(rng, free, start_radps=(8.0, 14.0))
    push_at = rng.uniform(3.0, 5.0)
    start = push_at + rng.uniform(0.6, 1.0)
    end = start + free
    brake_end = end + rng.uniform(1.0, 2.0)
    last = brake_end + rng.uniform(2.0, 4.0)
    accel = np.polynomial.polynomial.polyder(spin.omega_radps)
    edges = np.array([-free / 2, free / 2])
    w_start, w_end = spin.omega_at(edges)
    a_start, a_end = np.polynomial.polynomial.polyval(edges, accel)
    rate = SmoothLaw.hermite(
        [0.0, push_at, start, end, brake_end, last + 1.0],
        [0.0, 0.0, w_start, w_end, 0.0, 0.0],
        [0.0, 0.0, a_start, a_end, 0.0, 0.0],
    )
    check = np.linspace(0.0, last + 1.0, 20001)
    if np.any(np.sign(rate(check)[1]) == -np.sign(w_start)):
        raise ValueError("the push or the brake would turn the wheel backwards")
    centre = 0.5 * (start + end)
    theta0 = spin.theta0_rad - (rate(np.array([centre]))[0][0] - rate(np.zeros(1))[0][0])
    motion = AxleSpin(
        rate,
        theta0_rad=theta0,
        heading_rad=rng.uniform(-np.pi, np.pi),
        hand_phases_s=((push_at, start), (end, brake_end)),
        free_spin_s=(start, end),
    )
    shake = VibrationSpec(
        hand_shake_mps2, band_hz=(None, 3.0), axis_ratio=(1.0, 1.0, 1.0), follows="hands"
    )
    return FieldScenario(
        kind=kind,
        wheel=wheel,
        motion=motion,
        sensor=_sensor(rng, 0.05, 0.5),
        mounting=draw_mounting(rng, mounting, about_axle_deg=(-5.0, 5.0)),
        duration_s=np.floor(last * rate_hz) / rate_hz,
        rate_hz=rate_hz,
        noise=NoiseSpec(rng.uniform(0.03, 0.08)),
        vibration=shake,
        gyro=_gyro(rng, "mems") if gyro else None,
        glitches=glitches or Glitches(),
        include_radius=include_radius,
        sensor_id=f"{kind}-sensor",
        free_spin=spin,
    )


def stand_spin(rng: np.random.Generator, **options) -> FieldScenario:
    """A vertical wheel on a fixed stand (α = 90°: a bicycle in a stand, a car on a lift).

    :func:`bench_spin` with ``tilt_deg=90``; ``options`` as there.
    """
    return bench_spin(rng, tilt_deg=90.0, kind="stand", **options)
