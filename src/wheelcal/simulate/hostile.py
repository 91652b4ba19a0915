"""Well-formed but physically hostile recordings, with their truth.

Real sessions break the paper's assumptions in ways a file check cannot see:
a driven or re-pushed wheel, a spin sampled too slowly or recorded for an
hour, a saturated axis, a vibrating bench, a sensor axis that the wheel's
motion cannot excite.  Each builder here returns a whole session (rest, push,
motion, stop, rest; :func:`~wheelcal.simulate.session.simulate_session`) on the
paper's Table II bench unless it says otherwise, so the estimator, the gates
and the command line can be tested against known truth.

Every builder takes ``rng`` (the only source of randomness) and returns a
:class:`~wheelcal.simulate.session.SimulatedFullSession`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from wheelcal.model import BenchParams, CalibrationParams, Rotation, SensorParams, SpinParams
from wheelcal.recording import Recording
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.motion import (
    DragSpin,
    RateProfile,
    pushes_profile,
    steps_profile,
    wandering_profile,
)
from wheelcal.simulate.noise import NoiseSpec, Quantiser
from wheelcal.simulate.presets import (
    TABLE2_EULER_DEG,
    TABLE2_GAIN,
    TABLE2_OFFSET_MPS2,
    TABLE2_RADIUS_M,
    TABLE2_TILT_DEG,
    hand_spin,
)
from wheelcal.simulate.session import SimulatedFullSession, simulate_session
from wheelcal.simulate.simulator import Scenario


def table2_truth(spin: SpinParams, rotation: Rotation | None = None) -> CalibrationParams:
    """Table II's bench and sensor with a given spin (and optionally another mounting)."""
    return CalibrationParams(
        spin=spin,
        bench=BenchParams(
            tilt_rad=np.deg2rad(TABLE2_TILT_DEG),
            radius_m=TABLE2_RADIUS_M,
            misalignment=rotation or Rotation.from_euler_deg(*TABLE2_EULER_DEG),
        ),
        sensor=SensorParams(offset_mps2=TABLE2_OFFSET_MPS2, gain=TABLE2_GAIN),
    )


def _session(
    scenario: Scenario, rng: np.random.Generator, name: str, gyro: GyroSpec | None = None
) -> SimulatedFullSession:
    if gyro is not None:
        scenario = replace(scenario, gyro=gyro)
    return simulate_session(scenario, rng, source=f"<{name}>")


def clean(
    rng: np.random.Generator,
    duration_s: float = 90.0,
    rate_hz: float = 200.0,
    gyro: GyroSpec | None = None,
):
    """The reference: a clean Table II hand spin (nothing hostile)."""
    truth = table2_truth(hand_spin(rng, duration_s, direction=1))
    scenario = Scenario(truth=truth, duration_s=duration_s, rate_hz=rate_hz, noise=NoiseSpec(0.08))
    return _session(scenario, rng, "clean", gyro)


def sampled_at(rng: np.random.Generator, rate_hz: float, omega_radps: float = 10.0):
    """A 90 s spin from ``omega_radps`` sampled at ``rate_hz`` (1 Hz cannot see a 1.6 Hz turn)."""
    spin = hand_spin(rng, 90.0, start_radps=(omega_radps, omega_radps), direction=1)
    scenario = Scenario(
        truth=table2_truth(spin), duration_s=90.0, rate_hz=rate_hz, noise=NoiseSpec(0.08)
    )
    return _session(scenario, rng, f"{rate_hz:g} Hz")


def long_spin(
    rng: np.random.Generator,
    duration_s: float,
    omega_start_radps: float = 12.0,
    omega_end_radps: float = 3.0,
    rate_hz: float = 200.0,
):
    """A free spin of ``duration_s`` by pure quadratic drag (no cubic describes an hour)."""
    motion = DragSpin(
        omega_start_radps, omega_end_radps, duration_s, theta0_rad=rng.uniform(-np.pi, np.pi)
    )
    spin = SpinParams(theta0_rad=0.0, omega_radps=(omega_start_radps,))  # placeholder: see motion
    scenario = Scenario(
        truth=table2_truth(spin),
        duration_s=duration_s,
        rate_hz=rate_hz,
        noise=NoiseSpec(0.08),
        motion=motion,
    )
    return _session(scenario, rng, f"{duration_s:g} s spin")


def driven(
    rng: np.random.Generator,
    profile: RateProfile,
    name: str,
    duration_s: float = 90.0,
    gyro: GyroSpec | None = None,
):
    """A wheel moved along ``profile`` (centred times) for ``duration_s``."""
    spin = SpinParams(theta0_rad=0.0, omega_radps=(profile.knot_omega_radps[0],))
    scenario = Scenario(
        truth=table2_truth(spin),
        duration_s=duration_s,
        rate_hz=200.0,
        noise=NoiseSpec(0.08),
        motion=profile,
    )
    return _session(scenario, rng, name, gyro)


def rising(rng: np.random.Generator):
    """A driven wheel whose rate rises smoothly 19.7 → 24.6 rad/s over 16 s (the cubic fits)."""
    t = np.linspace(-8.0, 8.0, 9)
    x = (t + 8.0) / 16.0
    rates = 19.7 + (24.6 - 19.7) * x * x * (3 - 2 * x)
    return driven(
        rng, RateProfile(tuple(t), tuple(rates), rng.uniform(-np.pi, np.pi)), "rising", 16.0
    )


def motor_steps(rng: np.random.Generator, gyro: GyroSpec | None = None):
    """A motor holding 10 rad/s with ±10 % steps every 15 s."""
    return driven(rng, steps_profile(rng, 90.0, 10.0), "motor steps", gyro=gyro)


def three_pushes(rng: np.random.Generator, gyro: GyroSpec | None = None):
    """A hand-spun wheel pushed again twice: three spin-downs in one recording."""
    return driven(rng, pushes_profile(rng, 90.0, pushes=3), "three pushes", gyro=gyro)


def wandering(rng: np.random.Generator, gyro: GyroSpec | None = None):
    """A motor-driven wheel whose speed wanders smoothly by ±5 % around 10 rad/s."""
    return driven(rng, wandering_profile(rng, 90.0), "wandering motor", gyro=gyro)


def vibrating(rng: np.random.Generator, vibration_mps2: float = 0.5, gyro: GyroSpec | None = None):
    """A clean spin on a bench that vibrates with broadband ``vibration_mps2`` RMS."""
    truth = table2_truth(hand_spin(rng, 90.0, direction=1))
    scenario = Scenario(
        truth=truth,
        duration_s=90.0,
        rate_hz=200.0,
        noise=NoiseSpec(0.08),
        vibration=NoiseSpec(vibration_mps2, bandwidth_hz=40.0),
    )
    return _session(scenario, rng, "vibration", gyro)


def saturated(rng: np.random.Generator, full_scale_g: float = 2.0, jitter_lsb: float = 1.0):
    """An MPU-9250 at ±``full_scale_g`` g whose radial axis saturates, the rail jittering.

    The sensor's x axis is nearly radial, so r ω² + g sinα reaches past full
    scale at the start of the spin; a real ADC does not repeat its rail value
    exactly but toggles by about ``jitter_lsb`` counts.
    """
    rotation = Rotation.from_euler_deg(5.0, 4.0, 30.0)
    spin = hand_spin(rng, 90.0, start_radps=(8.0, 8.0), direction=1)
    quantiser = Quantiser(full_scale_g=full_scale_g, bits=16)
    scenario = Scenario(
        truth=table2_truth(spin, rotation),
        duration_s=90.0,
        rate_hz=200.0,
        noise=NoiseSpec(0.08),
        quantiser=quantiser,
    )
    session = _session(scenario, rng, "saturated")
    lo, hi = quantiser.limits_mps2
    v = np.array(session.recording.accel_mps2)
    lsb = quantiser.lsb_mps2
    at_rail = (v >= hi - 0.5 * lsb) | (v <= lo + 0.5 * lsb)
    toggle = rng.integers(0, 2, size=v.shape) * jitter_lsb * lsb
    v = np.where(v >= hi - 0.5 * lsb, v - toggle, v)
    v = np.where(v <= lo + 0.5 * lsb, v + toggle, v)
    assert np.any(at_rail), "the scenario must saturate"
    return replace(session, recording=replace(session.recording, accel_mps2=v))


def axis_near_wheel_axis(rng: np.random.Generator, angle_deg: float = 1.0):
    """The sensor's z axis within ``angle_deg`` of the wheel axis (its gain is undetermined)."""
    rotation = Rotation.from_euler_deg(35.0, 0.0, angle_deg)
    truth = table2_truth(hand_spin(rng, 90.0, direction=1), rotation)
    scenario = Scenario(truth=truth, duration_s=90.0, rate_hz=200.0, noise=NoiseSpec(0.08))
    return _session(scenario, rng, "axis along the wheel axis")


def axis_exactly_radial(rng: np.random.Generator, roll_deg: float = 30.0):
    """The sensor's x axis exactly radial: a rotation about it trades gain_y with gain_z."""
    rotation = Rotation.from_euler_deg(0.0, 0.0, roll_deg)
    truth = table2_truth(hand_spin(rng, 90.0, direction=1), rotation)
    scenario = Scenario(truth=truth, duration_s=90.0, rate_hz=200.0, noise=NoiseSpec(0.08))
    return _session(scenario, rng, "axis exactly radial")


def rescaled(session: SimulatedFullSession, factor: float, name: str) -> Recording:
    """The session's recording with every sample × ``factor`` (a unit stated wrongly)."""
    rec = session.recording
    return replace(rec, accel_mps2=rec.accel_mps2 * factor, source=f"<{name}>")


def clock_scaled(session: SimulatedFullSession, factor: float, name: str) -> Recording:
    """The session's recording with every time stamp × ``factor`` (a slow or fast clock).

    ``factor`` 0.98: the clock that stamped the samples runs 2 % slow, so the
    samples of a 200 Hz sensor read as 204.08 Hz.
    """
    rec = session.recording
    return replace(rec, time_s=rec.time_s * factor, source=f"<{name}>")
