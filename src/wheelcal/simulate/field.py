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

A profile draws what its keywords (:class:`FieldOptions`) leave open —
``car_drive(rng, camber_deg=0.0, glitches=Glitches(gyro_spikes=1))`` — and any
scenario can be changed afterwards with ``dataclasses.replace``.

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

import dataclasses
import itertools
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from wheelcal.model import Rotation, SensorParams, SpinParams, exp_so3
from wheelcal.simulate.field_drives import CAR_PLAN, ROBOT_PLAN, DrivePlan, coast_path, drive_path
from wheelcal.simulate.field_kinematics import wheel_kinematics
from wheelcal.simulate.field_motion import AxleSpin, MotionState, SmoothLaw, VehiclePath
from wheelcal.simulate.field_record import (
    GEOMETRIES,
    FieldScenario,
    FieldSimulation,
    FieldTruth,
    simulate_field,
)
from wheelcal.simulate.field_wheel import WheelGeometry
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.logger_glitches import Glitches, LoggedSamples
from wheelcal.simulate.noise import NoiseSpec
from wheelcal.simulate.presets import hand_spin, random_rotation
from wheelcal.simulate.road import VibrationSpec
from wheelcal.simulate.road_profile import RoadProfile

__all__ = [
    "GEOMETRIES",
    "AxleSpin",
    "DrivePlan",
    "FieldOptions",
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


@dataclass(frozen=True)
class FieldOptions:
    """What a profile fixes instead of drawing (``None``: drawn), and what it records.

    Every profile takes these as keywords; an unknown keyword is a TypeError, one
    that does not apply to the profile a ValueError.

    Parameters
    ----------
    radius_m:
        r, the sensor's distance from the axle.
    rolling_radius_m, camber_deg, side:
        ρ, γ and σ of a rolling wheel (:class:`WheelGeometry`).
    tilt_deg:
        α of a fixed axle.
    axle_offset_m:
        h, the sensor's offset along the axle from the wheel's mid-plane (0 by default).
    mounting:
        ``"aligned"`` or ``"random"`` (module docstring); ``None``: the profile's habit.
    vibration_mps2:
        The road's vertical rms at full speed (rolling wheels).
    rate_hz:
        Sample rate; ``None``: the profile's.
    gyro:
        Record a gyroscope (its errors drawn for the profile's sensor class).
    glitches:
        The logger's glitches (:class:`Glitches`).
    include_radius:
        Put r into the recording's session facts (off: the estimator must find it).
    """

    radius_m: float | None = None
    rolling_radius_m: float | None = None
    camber_deg: float | None = None
    side: int | None = None
    tilt_deg: float | None = None
    axle_offset_m: float = 0.0
    mounting: Mounting | None = None
    vibration_mps2: float | None = None
    rate_hz: float | None = None
    gyro: bool = True
    glitches: Glitches = field(default_factory=Glitches)
    include_radius: bool = False
    #: A car's road (:class:`~wheelcal.simulate.road_profile.RoadProfile`, drawn as the
    #: measured drives show it) and its gyro's bias walking and warming up; ``False``: a
    #: level road of one camber, a carrier that shakes only in translation, a steady bias.
    road: bool = True


_ROLLING_ONLY = ("rolling_radius_m", "camber_deg", "side", "vibration_mps2", "road")


def _options(given: dict, rolling: bool) -> FieldOptions:
    options = FieldOptions(**given)
    wrong = [n for n in (_ROLLING_ONLY if not rolling else ("tilt_deg",)) if n in given]
    if wrong:
        where = "a fixed axle" if not rolling else "a rolling wheel (give camber_deg)"
        raise ValueError(f"{', '.join(wrong)} does not apply to {where}")
    return options


@dataclass(frozen=True)
class _Device:
    """A sensor class: the ranges its gains, offsets and noise are drawn from, its gyro."""

    gain_spread: float
    offset_mps2: float
    noise_mps2: tuple[float, float]
    gyro_grade: Literal["factory", "mems"]


#: Xsens-DOT / NGIMU class (factory-calibrated) and a bare MPU-9250-class part.
FACTORY_IMU = _Device(0.03, 0.4, (0.008, 0.02), "factory")
HUB_IMU = _Device(0.03, 0.4, (0.01, 0.03), "factory")
MEMS_IMU = _Device(0.05, 0.5, (0.02, 0.06), "mems")
BENCH_IMU = _Device(0.05, 0.5, (0.03, 0.08), "mems")


#: σ of each entry of a drawn gyro's g-sensitivity matrix, °/s/g.
G_SENSITIVITY_CLASS_DPS_PER_G = 0.1


def _gyro(rng: np.random.Generator, grade: Literal["factory", "mems"]) -> GyroSpec:
    """A gyro with drawn errors: a factory-calibrated IMU (Xsens DOT, NGIMU) or a bare MEMS part.

    The factory grade has no range limit here: a DOT's ±2000 °/s clips a car's
    wheel above ~10 m/s, which the drives would lose (pass a GyroSpec to model it).
    The sensitivity to linear acceleration is drawn per device, every entry of the
    3×3 matrix normal with σ :data:`G_SENSITIVITY_CLASS_DPS_PER_G` for both grades:
    a factory calibration leaves it (the MEMS parts inside, e.g. a BMI160, state
    0.1 °/s/g), and it is the class the fit's default prior describes.
    """
    if grade == "factory":
        bias, scale, misalign, density, full_scale = 0.005, 0.003, 0.3, 0.007, None
    else:
        bias, scale, misalign, density, full_scale = 0.03, 0.02, 1.5, 0.01, 2000.0
    return GyroSpec(
        noise_density_dps_rthz=density,
        bias_radps=tuple(rng.uniform(-bias, bias, 3)),
        scale_error=tuple(rng.uniform(-scale, scale, 3)),
        misalignment_deg=tuple(rng.uniform(-misalign, misalign, 3)),
        g_sensitivity_dps_per_g=tuple(
            map(tuple, rng.normal(0.0, G_SENSITIVITY_CLASS_DPS_PER_G, (3, 3)))
        ),
        full_scale_dps=full_scale,
    )


def _pick(rng: np.random.Generator, value: float | None, low: float, high: float) -> float:
    return float(rng.uniform(low, high)) if value is None else float(value)


def _rolling_wheel(
    rng: np.random.Generator,
    options: FieldOptions,
    camber_deg: tuple[float, float],
    radius_m: tuple[float, float],
    rolling_radius_m: tuple[float, float],
) -> WheelGeometry:
    """A rolling wheel drawn from these ranges where ``options`` leave it open; either side."""
    return WheelGeometry.rolling(
        camber_deg=_pick(rng, options.camber_deg, *camber_deg),
        radius_m=_pick(rng, options.radius_m, *radius_m),
        rolling_radius_m=_pick(rng, options.rolling_radius_m, *rolling_radius_m),
        axle_offset_m=options.axle_offset_m,
        side=int(rng.choice([1, -1])) if options.side is None else options.side,
    )


def _scenario(
    rng: np.random.Generator,
    kind: str,
    wheel: WheelGeometry,
    motion: VehiclePath | AxleSpin,
    device: _Device,
    mounting: Rotation,
    vibration: VibrationSpec,
    options: FieldOptions,
    duration_s: float,
    rate_hz: float,
    free_spin: SpinParams | None = None,
) -> FieldScenario:
    """The scenario, with the sensor, its noise and its gyro drawn for ``device``."""
    spread, offset = device.gain_spread, device.offset_mps2
    return FieldScenario(
        kind=kind,
        wheel=wheel,
        motion=motion,
        sensor=SensorParams(
            rng.uniform(-offset, offset, 3), rng.uniform(1 - spread, 1 + spread, 3)
        ),
        mounting=mounting,
        duration_s=duration_s,
        rate_hz=rate_hz,
        noise=NoiseSpec(rng.uniform(*device.noise_mps2)),
        vibration=vibration,
        gyro=_gyro(rng, device.gyro_grade) if options.gyro else None,
        glitches=options.glitches,
        include_radius=options.include_radius,
        sensor_id=f"{kind}-sensor",
        free_spin=free_spin,
    )


def car_drive(rng: np.random.Generator, *, duration_s: float = 120.0, **options) -> FieldScenario:
    """A car's wheel: a 2-minute drive at 0–15 m/s with turns and stops, 120 Hz.

    Drawn where ``options`` (:class:`FieldOptions`) leave it open: camber 0–2°,
    the sensor 0.12–0.18 m from the axle on the rim, ρ 0.28–0.33 m, either
    side, road vibration 0.3–1.5 m/s² rms (vertical; 5–30 Hz, full above
    10 m/s, ∝ √v below); a factory-calibrated IMU (noise 0.008–0.02 m/s²,
    gains 1 ± 3 %, offsets < 0.4 m/s²) strapped within ±5° of radial about the
    axle; the drive itself (:data:`~wheelcal.simulate.field_drives.CAR_PLAN`).
    """
    opts = _options(options, rolling=True)
    wheel = _rolling_wheel(rng, opts, (0.0, 2.0), (0.12, 0.18), (0.28, 0.33))
    path = drive_path(rng, CAR_PLAN, duration_s)
    vibration = VibrationSpec(_pick(rng, opts.vibration_mps2, 0.3, 1.5))
    mounting = draw_mounting(rng, opts.mounting or "aligned", about_axle_deg=(-5.0, 5.0))
    rate = opts.rate_hz or 120.0
    scenario = _scenario(
        rng, "car", wheel, path, FACTORY_IMU, mounting, vibration, opts, duration_s, rate
    )
    if not opts.road:
        return scenario
    return _on_a_road(rng, scenario)


def _on_a_road(rng: np.random.Generator, scenario: FieldScenario) -> FieldScenario:
    """A car's scenario on a measured drive's road (drawn after everything else).

    The road's camber and the carrier's angular shaking
    (:meth:`~wheelcal.simulate.road_profile.RoadProfile.car`), the rim's vibration in a
    second band along the axle (25–55 Hz, 0.4–1.2 m/s² at full speed: the measured
    residual's along-axle share), and the factory gyro's bias walking
    (0.002–0.005 °/s/√s) and warming up (±0.05 °/s, τ 60–300 s).
    """
    road = RoadProfile.car(rng)
    gyro = scenario.gyro
    if gyro is not None:
        gyro = dataclasses.replace(
            gyro,
            bias_walk_dps_per_sqrt_s=float(rng.uniform(0.002, 0.005)),
            bias_warmup_dps=tuple(float(x) for x in rng.uniform(-0.05, 0.05, 3)),
            bias_warmup_tau_s=float(rng.uniform(60.0, 300.0)),
        )
    rim = VibrationSpec(
        float(rng.uniform(0.4, 1.2)), band_hz=(25.0, 55.0), axis_ratio=(0.3, 1.0, 0.3)
    )
    return dataclasses.replace(scenario, road=road, gyro=gyro, rim_vibration=rim)


def robot_drive(
    rng: np.random.Generator,
    *,
    duration_s: float = 90.0,
    mount: Literal["rim", "hub"] | None = None,
    **options,
) -> FieldScenario:
    """A small robot's wheel: slow drives (0.2–1.5 m/s) with tight turns and stops.

    Drawn where not given: 100, 200 or 400 Hz; ρ 0.05–0.1 m; a sensor on the
    rim (r 0.5–0.85 ρ, within ±5° of radial) or the hub (r 5–20 mm, any angle
    about the axle), ``mount``; camber 0; either mounting style; vibration
    0.1–0.6 m/s² (10–60 Hz, full above 1 m/s); a bare MEMS IMU (noise
    0.02–0.06 m/s², gains 1 ± 5 %, offsets < 0.5 m/s²).
    """
    opts = _options(options, rolling=True)
    rate = opts.rate_hz or float(rng.choice([100.0, 200.0, 400.0]))
    rho = _pick(rng, opts.rolling_radius_m, 0.05, 0.1)
    where = mount or ("rim" if rng.uniform() < 0.5 else "hub")
    radius = (0.5 * rho, 0.85 * rho) if where == "rim" else (0.005, 0.02)
    camber = (opts.camber_deg or 0.0,) * 2
    wheel = _rolling_wheel(rng, opts, camber, radius, (rho, rho))
    path = drive_path(rng, ROBOT_PLAN, duration_s)
    level = _pick(rng, opts.vibration_mps2, 0.1, 0.6)
    vibration = VibrationSpec(level, band_hz=(10.0, 60.0), full_speed_mps=1.0)
    style = opts.mounting or ("aligned" if rng.uniform() < 0.5 else "random")
    mounting = draw_mounting(rng, style, about_axle_deg=(-5.0, 5.0) if where == "rim" else None)
    return _scenario(
        rng, "robot", wheel, path, MEMS_IMU, mounting, vibration, opts, duration_s, rate
    )


def wheelchair_coast(
    rng: np.random.Generator, *, coast_s: float | None = None, **options
) -> FieldScenario:
    """A manual wheelchair's hub sensor at 400 Hz: rest, one push, ~20 s coasting, stop, rest.

    The path: :func:`~wheelcal.simulate.field_drives.coast_path` (``coast_s``
    drawn 18–22 s).  Drawn where not given: camber 16–20°, the sensor 4–6 cm
    from the axle, ρ 0.28–0.32 m, either side; vibration 0.05–0.3 m/s² (5–40 Hz,
    full above 1.5 m/s); a factory-calibrated IMU on the hub (any angle about
    the axle, 2–5° off it).
    """
    opts = _options(options, rolling=True)
    path, end_s = coast_path(rng, _pick(rng, coast_s, 18.0, 22.0))
    wheel = _rolling_wheel(rng, opts, (16.0, 20.0), (0.04, 0.06), (0.28, 0.32))
    level = _pick(rng, opts.vibration_mps2, 0.05, 0.3)
    vibration = VibrationSpec(level, band_hz=(5.0, 40.0), full_speed_mps=1.5)
    mounting = draw_mounting(rng, opts.mounting or "aligned")
    rate = opts.rate_hz or 400.0
    duration = np.floor(end_s * rate) / rate
    return _scenario(
        rng, "wheelchair", wheel, path, HUB_IMU, mounting, vibration, opts, duration, rate
    )


def _hand_spin_law(rng: np.random.Generator, free_s: float) -> tuple[AxleSpin, SpinParams, float]:
    """Rest, push, the free spin (eq. 2's cubic), brake, rest: the law, the cubic, the end time."""
    spin = hand_spin(rng, free_s, start_radps=(8.0, 14.0))
    push_at = rng.uniform(3.0, 5.0)
    start = push_at + rng.uniform(0.6, 1.0)
    end = start + free_s
    brake_end = end + rng.uniform(1.0, 2.0)
    last = brake_end + rng.uniform(2.0, 4.0)
    edges = np.array([-free_s / 2, free_s / 2])
    w_start, w_end = spin.omega_at(edges)
    slope = np.polynomial.polynomial.polyder(spin.omega_radps)
    a_start, a_end = np.polynomial.polynomial.polyval(edges, slope)
    rate = SmoothLaw.hermite(
        [0.0, push_at, start, end, brake_end, last + 1.0],
        [0.0, 0.0, w_start, w_end, 0.0, 0.0],
        [0.0, 0.0, a_start, a_end, 0.0, 0.0],
    )
    if np.any(np.sign(rate(np.linspace(0.0, last + 1.0, 20001))[1]) == -np.sign(w_start)):
        raise ValueError("the push or the brake would turn the wheel backwards")
    centre = 0.5 * (start + end)
    theta0 = spin.theta0_rad - (rate(np.array([centre]))[0][0] - rate(np.zeros(1))[0][0])
    law = AxleSpin(
        rate,
        theta0_rad=theta0,
        heading_rad=rng.uniform(-np.pi, np.pi),
        hand_phases_s=((push_at, start), (end, brake_end)),
        free_spin_s=(start, end),
    )
    return law, spin, last


def bench_spin(
    rng: np.random.Generator,
    *,
    free_spin_s: float | None = None,
    hand_shake_mps2: float = 0.8,
    kind: str = "bench",
    **options,
) -> FieldScenario:
    """The paper's bench: a wheel on a fixed axle tilted by α, spun by hand, left to spin down.

    Rest 3–5 s, a push (0.6–1 s), a free spin-down of ``free_spin_s`` (drawn
    60–90 s; quadratic drag as :func:`~wheelcal.simulate.presets.hand_spin`,
    8–14 rad/s, either way), a brake (1–2 s), rest 2–4 s; push and brake are
    cubic Hermite pieces that meet the free spin's ω and ω̇, and the hand
    shakes the wheel meanwhile (``hand_shake_mps2`` rms, below 3 Hz).  Drawn
    where not given: α 10–85°, r 0.15–0.35 m, 200 Hz; an MPU-9250-class sensor
    (noise 0.03–0.08 m/s², gains 1 ± 5 %, offsets < 0.5 m/s², a bare MEMS
    gyro) mounted anywhere.
    """
    opts = _options(options, rolling=False)
    tilt = np.deg2rad(_pick(rng, opts.tilt_deg, 10.0, 85.0))
    wheel = WheelGeometry(tilt, _pick(rng, opts.radius_m, 0.15, 0.35), None, 1, opts.axle_offset_m)
    law, spin, last = _hand_spin_law(rng, _pick(rng, free_spin_s, 60.0, 90.0))
    shake = VibrationSpec(hand_shake_mps2, (None, 3.0), (1.0, 1.0, 1.0), follows="hands")
    mounting = draw_mounting(rng, opts.mounting or "random", about_axle_deg=(-5.0, 5.0))
    rate = opts.rate_hz or 200.0
    duration = np.floor(last * rate) / rate
    return _scenario(rng, kind, wheel, law, BENCH_IMU, mounting, shake, opts, duration, rate, spin)


def stand_spin(rng: np.random.Generator, **options) -> FieldScenario:
    """A vertical wheel on a fixed stand (α = 90°: a bicycle in a stand, a car on a lift).

    :func:`bench_spin` with ``tilt_deg=90`` and ``kind="stand"``; ``options`` as there.
    """
    if "tilt_deg" in options:
        raise ValueError("a stand's wheel is vertical: tilt_deg does not apply (see bench_spin)")
    return bench_spin(rng, kind="stand", tilt_deg=90.0, **options)
