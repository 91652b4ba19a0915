"""A wheel rolling on the ground: a vehicle's drive with speed changes, stops and turns.

The wheel is vertical and rolls without slip on level ground
(:mod:`wheelcal.model.rolling`).  :class:`RollingMotion` gives the wheel's spin
ω(t) (a :class:`~wheelcal.simulate.motion.RateProfile`: speed / ρ) and the yaw
rate ψ̇(t) of its heading (shape-preserving cubic through knots, so ψ̈ is
continuous); :func:`drive` draws a drive — rests, accelerations, cruising at
several speeds, braking to a stop, turns left and right while moving — and
:func:`simulate_drive` records it: the accelerometer through the model with
the true :class:`~wheelcal.model.rolling.Rolling` effect (ρ and yaw scale 1),
road vibration in proportion to the speed, and a gyroscope that reads the
wheel's whole angular velocity Ω = −ω e_Z + ψ̇ u.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model import (
    BenchParams,
    CalibrationParams,
    Kinematics,
    Rolling,
    Rotation,
    SensorParams,
    SpinParams,
)
from wheelcal.recording import SessionInfo
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.motion import RateProfile
from wheelcal.simulate.noise import NoiseSpec
from wheelcal.simulate.presets import TABLE2_EULER_DEG, TABLE2_GAIN, TABLE2_OFFSET_MPS2
from wheelcal.simulate.simulator import Scenario, SimulatedSession


@dataclass(frozen=True)
class RollingMotion:
    """Spin ω(t) and heading yaw rate ψ̇(t) of a rolling wheel (centred times)."""

    speed: RateProfile  # ω(t) = v(t) / ρ, rad/s
    yaw_times_s: tuple[float, ...]
    yaw_rate_radps: tuple[float, ...]

    def __post_init__(self) -> None:
        t = np.asarray(self.yaw_times_s, float)
        if t.size < 2 or t.size != len(self.yaw_rate_radps) or not np.all(np.diff(t) > 0):
            raise ValueError("need increasing yaw knot times, one rate per time")

    def kinematics(self, t_s: np.ndarray) -> Kinematics:
        """ϑ, ω, ω̇ of the wheel at centred times."""
        return self.speed.kinematics(t_s)

    def yaw(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ψ̇ and ψ̈ at centred times (constant beyond the end knots)."""
        from scipy.interpolate import PchipInterpolator

        knots = np.asarray(self.yaw_times_s)
        pad = 1e6
        rates = np.asarray(self.yaw_rate_radps)
        law = PchipInterpolator(
            np.concatenate([[knots[0] - pad], knots, [knots[-1] + pad]]),
            np.concatenate([[rates[0]], rates, [rates[-1]]]),
        )
        t = np.asarray(t_s, float)
        return law(t), law.derivative()(t)


def drive(
    rng: np.random.Generator,
    duration_s: float = 90.0,
    rolling_radius_m: float = 0.30,
    max_speed_mps: float = 8.0,
    max_yaw_radps: float = 0.3,
) -> RollingMotion:
    """A random drive: start and end at rest, speed changes, a stop, turns while moving.

    Accelerate or brake at 0.8–1.5 m/s² (a car in town, a robot) to a new speed
    in [0.3, 1] × ``max_speed_mps`` and cruise for 4–7 s, with one full stop of
    3 s in the middle; a turn of ±(0.4–1) × ``max_yaw_radps`` (ramps of 1 s) in
    most cruising segments.
    """
    half = duration_s / 2
    times, speeds = [-half - 1.0, -half + 3.0], [0.0, 0.0]  # at rest for 3 s
    yaw_t, yaw_r = [-half - 1.0], [0.0]
    t = -half + 3.0
    stop_done = False

    def ramp_s(change_mps: float) -> float:
        return max(1.5, abs(change_mps) / rng.uniform(0.8, 1.5))

    while t < half - 16.0:
        if not stop_done and t > -5.0:  # brake to a stop, stand, drive off
            t += ramp_s(speeds[-1])
            times += [t, t + 3.0]
            speeds += [0.0, 0.0]
            t += 3.0
            stop_done = True
            continue
        v = max_speed_mps * rng.uniform(0.3, 1.0)
        t += ramp_s(v - speeds[-1])
        times.append(t)
        speeds.append(v)
        cruise = rng.uniform(4.0, 7.0)
        if rng.uniform() < 0.8:  # a turn while cruising
            yaw = max_yaw_radps * rng.uniform(0.4, 1.0) * rng.choice([-1.0, 1.0])
            a, b = t + 0.5, t + cruise - 0.5
            yaw_t += [a, a + 1.0, b - 1.0, b]
            yaw_r += [0.0, yaw, yaw, 0.0]
        t += cruise
        times.append(t)
        speeds.append(v)
    t += ramp_s(speeds[-1])  # brake to rest
    times += [t, max(half + 1.0, t + 1.0)]
    speeds += [0.0, 0.0]
    yaw_t.append(half + 1.0)
    yaw_r.append(0.0)
    omega = tuple(v / rolling_radius_m for v in speeds)
    speed = RateProfile(tuple(times), omega, float(rng.uniform(-np.pi, np.pi)))
    return RollingMotion(speed, tuple(yaw_t), tuple(yaw_r))


def rolling_truth(radius_m: float = 0.12, rotation: Rotation | None = None) -> CalibrationParams:
    """Table II's sensor on a vertical wheel, ``radius_m`` from the axle."""
    return CalibrationParams(
        spin=SpinParams(theta0_rad=0.0, omega_radps=(0.0,)),  # placeholder: see the motion
        bench=BenchParams(
            tilt_rad=np.pi / 2,
            radius_m=radius_m,
            misalignment=rotation or Rotation.from_euler_deg(*TABLE2_EULER_DEG),
        ),
        sensor=SensorParams(offset_mps2=TABLE2_OFFSET_MPS2, gain=TABLE2_GAIN),
    )


def rolling_scenario(
    rng: np.random.Generator,
    duration_s: float = 90.0,
    rolling_radius_m: float = 0.30,
    radius_m: float = 0.12,
    vibration_mps2: float = 0.5,
    gyro: GyroSpec | None = None,
    max_yaw_radps: float = 0.3,
) -> Scenario:
    """A drive (:func:`drive`) as a scenario: truth, true rolling effect, vibration, gyro."""
    motion = drive(rng, duration_s, rolling_radius_m, max_yaw_radps=max_yaw_radps)
    rate_hz = 200.0
    t = np.arange(round(duration_s * rate_hz) + 1) / rate_hz
    tc = t - 0.5 * (t[0] + t[-1])
    yaw_rate, yaw_accel = motion.yaw(tc)
    effect = Rolling(tc, yaw_rate, yaw_accel)
    truth = rolling_truth(radius_m).with_changes(
        effects={effect.name: np.array([rolling_radius_m, 1.0, 0.0])}
    )
    return Scenario(
        truth=truth,
        duration_s=duration_s,
        rate_hz=rate_hz,
        noise=NoiseSpec(0.08),
        info=SessionInfo(radius_m=radius_m),
        effects=(effect,),
        motion=motion,
        vibration=None if vibration_mps2 == 0 else NoiseSpec(vibration_mps2, bandwidth_hz=40.0),
        gyro=gyro if gyro is not None else GyroSpec(),
    )


def simulate_drive(
    scenario: Scenario,
    rng: np.random.Generator,
    epoch_unix_ns: int = 1_700_000_000_000_000_000,
    source: str = "<rolling drive>",
) -> SimulatedSession:
    """Record a rolling scenario: the model with its true rolling, vibration and the gyro.

    The gyro reads Ω = −ω e_Z + ψ̇ u (u = (cos ϑ, sin ϑ, 0), the upward direction
    in the bench frame); the road's vibration scales with the speed (full above
    2 rad/s), as on the bench.
    """
    t = scenario.times_s()
    tc = scenario.centred_times_s()
    out = scenario.clean_output(tc)
    kin = out.kinematics
    yaw_rate, _ = scenario.motion.yaw(tc)
    up = np.column_stack([np.cos(kin.theta_rad), np.sin(kin.theta_rad), np.zeros(tc.size)])
    recording = scenario.record(
        t,
        out.predicted_mps2,
        rng,
        epoch_unix_ns,
        source,
        vibration_envelope=np.minimum(1.0, np.abs(kin.omega_radps) / 2.0),
        omega_radps=kin.omega_radps,
        sensed_mps2=out.sensed_mps2,
        gyro_extra_rate_radps=yaw_rate[:, None] * up,
    )
    return SimulatedSession(
        recording=recording,
        truth=scenario.truth,
        clean_mps2=out.predicted_mps2,
        scenario=scenario,
    )
