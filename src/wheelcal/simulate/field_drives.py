"""Vehicle paths for the field profiles: drives with speed changes, turns and stops; a coast.

Every path is a :class:`~wheelcal.simulate.field_motion.VehiclePath` whose speed
and yaw rate are shape-preserving cubics through knots, so a rest is exactly at
rest (v = ψ̇ = 0) and the speed never dips below zero between knots.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.simulate.field_motion import SmoothLaw, VehiclePath


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


# The two vehicles side by side: (car, robot).
_PLANS = {
    "speed_mps": ((2.0, 15.0), (0.2, 1.5)),
    "accel_mps2": ((0.8, 2.5), (0.3, 1.0)),
    "brake_mps2": ((1.0, 3.0), (0.4, 1.2)),
    "cruise_s": ((4.0, 14.0), (2.5, 8.0)),
    "stop_s": ((2.0, 8.0), (1.0, 4.0)),
    "rest_s": ((2.0, 5.0), (1.0, 3.0)),
    "stop_every_s": ((25.0, 60.0), (15.0, 40.0)),
    "lateral_mps2": ((0.5, 3.5), (0.1, 0.8)),
    "max_yaw_radps": (0.6, 1.5),
}
CAR_PLAN = DrivePlan(**{name: pair[0] for name, pair in _PLANS.items()})
ROBOT_PLAN = DrivePlan(**{name: pair[1] for name, pair in _PLANS.items()})


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


def _coast(v0: float, resistance_mps2: float, drag_per_m: float, tau: np.ndarray) -> np.ndarray:
    """v(τ) of v̇ = −a − b v² from v0 (closed form), 0 once stopped."""
    k = np.sqrt(resistance_mps2 / drag_per_m)
    phase = np.arctan(v0 / k) - drag_per_m * k * tau
    return np.where(phase > 0, k * np.tan(np.maximum(phase, 0.0)), 0.0)


def coast_path(rng: np.random.Generator, coast_s: float) -> tuple[VehiclePath, float]:
    """A manual wheelchair's path: rest, one push, coasting, a stop; and the time to stop recording.

    Rest 2–4 s; a push (0.6–1 s) to 1.2–2.2 m/s; coasting by v̇ = −a − b v²
    (a 0.03–0.08 m/s², b 0.005–0.02 /m: rolling resistance and air) for
    ``coast_s`` or until it stops; a hand on the rim stops a wheel still rolling;
    rest 2–4 s.  The heading drifts gently: ψ̇ = κ v with the curvature κ a
    bias of ±0.03 /m plus a wander of 0.01 /m every 2 s (so ψ̇ vanishes at rest).
    """
    rest = rng.uniform(2.0, 4.0)
    start = rest + rng.uniform(0.6, 1.0)
    v0 = rng.uniform(1.2, 2.2)
    resistance, drag = rng.uniform(0.03, 0.08), rng.uniform(0.005, 0.02)
    tau = np.arange(0.0, coast_s + 1e-9, 0.25)
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
    path = VehiclePath(
        speed,
        SmoothLaw.through(yaw_times, yaw),
        rng.uniform(-np.pi, np.pi),
        rng.uniform(-np.pi, np.pi),
    )
    return path, float(end)
