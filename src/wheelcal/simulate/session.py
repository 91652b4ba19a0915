"""A realistic full session: rest, hand push, free spin, brake, rest.

Real recordings do not start and end with the free spin the model describes.
This simulator wraps the model's free spin in what a person does at the bench:

1. **rest** — the wheel stands still at some angle ϑ_r; the sensor reads
   gravity only: a = (g sin α cos ϑ_r, g sin α sin ϑ_r, g cos α);
2. **push** — a hand spins the wheel up from rest to ω_s = ω(−D/2), the rate
   at the start of the free-spin window, over ``push_s`` seconds, with a
   smooth-step profile ω = ω_s (3x² − 2x³), x = τ/P, so ω̇ = 6 ω_s x(1 − x)/P
   (strong tangential acceleration r ω̇) and the phase
   ϑ = ϑ_s − ω_s P (½ − x³ + x⁴/2) meets the free spin's ϑ(−D/2) exactly;
3. **free spin** — exactly the model, ``wheelcal.model.predict`` with the
   scenario's truth, whose time origin is the centre of this window;
4. **stop** — a brake takes ω from ω_e = ω(D/2) to 0 over ``stop_s`` with the
   mirrored smooth step; then **rest** at the final angle.

During push and stop the hand also shakes the wheel: band-limited (≈ 3 Hz)
random bench-frame accelerations of ``hand_jitter_mps2`` RMS, tapered to
zero at the ends of each phase, so the free spin stays exactly the model.
Sensor noise (the scenario's :class:`NoiseSpec`) covers the whole recording;
the quantiser, if any, is applied last.  The bench-frame force of eq. (1)
holds in every phase with the phase's own ϑ, ω, ω̇.

A scenario's gyro (if any) reads the wheel's rate in every phase — zero at
rest, the smooth step during push and stop — and the true specific force
(hand shake included) for its g-sensitivity; the hand's shake is a
translation, so the gyro sees no rotation from it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from wheelcal.model import CalibrationParams, Kinematics, ModelOutput, evaluate, spin_kinematics
from wheelcal.recording import Recording
from wheelcal.simulate.simulator import Scenario


@dataclass(frozen=True)
class SessionPlan:
    """Durations (s) of the phases around the free spin, and the hand's shake."""

    rest_before_s: float = 4.0
    push_s: float = 0.8
    stop_s: float = 1.5
    rest_after_s: float = 3.0
    hand_jitter_mps2: float = 0.8
    hand_band_hz: float = 3.0

    def __post_init__(self) -> None:
        for name in ("rest_before_s", "rest_after_s", "hand_jitter_mps2"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0")
        for name in ("push_s", "stop_s", "hand_band_hz"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")


@dataclass(frozen=True, eq=False)
class SimulatedFullSession:
    """A whole simulated session and its truth.

    ``window_s`` is the true free-spin window in recording time; the truth's
    motion parameters use t = 0 at its centre (CONTRACT).
    """

    recording: Recording
    truth: CalibrationParams
    window_s: tuple[float, float]
    clean_mps2: np.ndarray
    omega_radps: np.ndarray  # true ω(t) at every sample (signed)
    omega_dot_radps2: np.ndarray  # true ω̇(t) at every sample
    scenario: Scenario
    plan: SessionPlan = field(default_factory=SessionPlan)

    @property
    def centre_s(self) -> float:
        """Centre of the free-spin window (the truth's t = 0), recording time."""
        return 0.5 * (self.window_s[0] + self.window_s[1])


def _smooth_step(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """s(x) = 3x² − 2x³, its derivative 6x(1 − x), and its integral x³ − x⁴/2."""
    return 3 * x**2 - 2 * x**3, 6 * x * (1 - x), x**3 - x**4 / 2


def _hand_shake(n: int, rate_hz: float, plan: SessionPlan, rng: np.random.Generator) -> np.ndarray:
    """Band-limited random bench-frame acceleration, unit envelope, RMS ``hand_jitter_mps2``."""
    if n == 0 or plan.hand_jitter_mps2 == 0:
        return np.zeros((n, 3))
    sos = signal.butter(2, min(plan.hand_band_hz, 0.4 * rate_hz), fs=rate_hz, output="sos")
    burn = int(2 * rate_hz / plan.hand_band_hz) + 10
    raw = signal.sosfilt(sos, rng.standard_normal((n + burn, 3)), axis=0)[burn:]
    raw /= max(float(np.sqrt(np.mean(raw**2))), 1e-12)
    taper = np.sin(np.pi * (np.arange(n) + 0.5) / n) ** 2  # zero at both ends
    return plan.hand_jitter_mps2 * raw * taper[:, None]


def simulate_session(
    scenario: Scenario,
    rng: np.random.Generator,
    plan: SessionPlan | None = None,
    epoch_unix_ns: int = 1_700_000_000_000_000_000,
    source: str = "<simulated session>",
) -> SimulatedFullSession:
    """Simulate rest, push, the scenario's free spin, brake and rest as one recording.

    Parameters
    ----------
    scenario:
        Truth (free spin about its window centre), duration D of the free
        spin, sample rate, noise, optional quantiser, session facts.
    rng:
        The only source of randomness (noise and the hand's shake).
    plan:
        Durations of the other phases.
    epoch_unix_ns:
        Unix time of the first sample.
    source:
        Name recorded in the Recording.

    Returns
    -------
    SimulatedFullSession
        The recording (t = 0 at the first sample), the truth, the true
        free-spin window and the noise-free samples.
    """
    plan = plan or SessionPlan()
    rate = scenario.rate_hz
    duration = scenario.duration_s
    # Free-spin start on the sample grid, so its samples are the model's exactly.
    start = round((plan.rest_before_s + plan.push_s) * rate) / rate
    end = start + duration
    centre = start + duration / 2
    total = end + plan.stop_s + plan.rest_after_s
    t = np.arange(round(total * rate) + 1) / rate

    edges = _free_spin_edges(scenario)
    theta, omega, omega_dot, push, stop = _hand_phases(t, start, end, plan, edges)
    free = (t >= start) & (t <= end)
    # Phase 3 is exactly the model: its kinematics include the spin effects, if any.
    inside_out = scenario.clean_output(t[free] - centre)
    omega[free] = inside_out.kinematics.omega_radps
    omega_dot[free] = inside_out.kinematics.omega_dot_radps2
    shake = _hand_shakes(~free, (push, stop), rate, plan, rng)
    outside_kinematics = Kinematics(theta[~free], omega[~free], omega_dot[~free])
    clean, sensed = _session_output(
        scenario, t - centre, free, inside_out, outside_kinematics, shake
    )

    # Bearings and road vibrate in proportion to the speed, fully above 2 rad/s.
    envelope = np.minimum(1.0, np.abs(omega) / 2.0)
    recording = scenario.record(
        t, clean, rng, epoch_unix_ns, source, envelope, omega_radps=omega, sensed_mps2=sensed
    )
    return SimulatedFullSession(
        recording=recording,
        truth=scenario.truth,
        window_s=(float(start), float(end)),
        clean_mps2=clean,
        omega_radps=omega,
        omega_dot_radps2=omega_dot,
        scenario=scenario,
        plan=plan,
    )


def _free_spin_edges(scenario: Scenario) -> Kinematics:
    """The free spin's motion at its two ends (centred times ∓D/2).

    The motion is the truth's polynomial, or the scenario's physical motion.
    """
    ends = np.array([-scenario.duration_s / 2, scenario.duration_s / 2])
    if scenario.motion is not None:
        return scenario.motion.kinematics(ends)
    return spin_kinematics(scenario.truth.spin, ends)


def _hand_phases(
    t: np.ndarray, start: float, end: float, plan: SessionPlan, edges: Kinematics
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """ϑ, ω, ω̇ of the rests, the push and the brake, and the push's and the brake's samples.

    The free spin [start, end] is left at zero, for the model to fill; ``edges`` is
    the free spin's motion at its two ends (centred times ∓D/2).
    """
    omega_s, omega_e = (float(x) for x in edges.omega_radps)
    theta_s, theta_e = (float(x) for x in edges.theta_rad)
    theta = np.zeros_like(t)
    omega = np.zeros_like(t)
    omega_dot = np.zeros_like(t)
    push_from = start - plan.push_s
    # Phase 1: rest before.
    rest1 = t < push_from
    theta[rest1] = theta_s - omega_s * plan.push_s / 2
    # Phase 2: push.
    push = (t >= push_from) & (t < start)
    x = (t[push] - push_from) / plan.push_s
    s, ds, integral = _smooth_step(x)
    omega[push] = omega_s * s
    omega_dot[push] = omega_s * ds / plan.push_s
    theta[push] = theta_s - omega_s * plan.push_s * (0.5 - integral)
    # Phase 4: brake, then rest.
    stop = (t > end) & (t <= end + plan.stop_s)
    x = (t[stop] - end) / plan.stop_s
    s, ds, integral = _smooth_step(x)
    omega[stop] = omega_e * (1 - s)
    omega_dot[stop] = -omega_e * ds / plan.stop_s
    theta[stop] = theta_e + omega_e * plan.stop_s * (x - integral)
    rest2 = t > end + plan.stop_s
    theta[rest2] = theta_e + omega_e * plan.stop_s / 2
    return theta, omega, omega_dot, push, stop


def _hand_shakes(
    outside: np.ndarray,
    phases: tuple[np.ndarray, ...],
    rate_hz: float,
    plan: SessionPlan,
    rng: np.random.Generator,
) -> np.ndarray:
    """The hand's shake at the samples ``outside`` the free spin: one burst per phase, in order."""
    shake = np.zeros((int(outside.sum()), 3))
    for phase in phases:
        rows = np.flatnonzero(phase[outside])
        shake[rows] = _hand_shake(rows.size, rate_hz, plan, rng)
    return shake


def _session_output(
    scenario: Scenario,
    t_centred_s: np.ndarray,
    free: np.ndarray,
    inside_out: ModelOutput,
    outside_kinematics: Kinematics,
    shake: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free v(t) and the true specific force R a at every sample.

    Eq. (4)–(5) with the phase's own ϑ, ω, ω̇; the sensor's effects (a warm-up, a
    nonlinearity …) act in every phase, the spin's only in the free spin.  The
    hand's shake is a bench-frame force, sensed like any other.
    """
    truth = scenario.truth
    outside = ~free
    sensor_effects = tuple(e for e in scenario.effects if e.stage == "sensor")
    outside_out = evaluate(
        truth, t_centred_s[outside], effects=sensor_effects, kinematics=outside_kinematics
    )
    shake_sensed = shake @ truth.bench.misalignment.matrix.T
    clean = np.empty((free.size, 3))
    sensed = np.empty((free.size, 3))
    sensed[outside] = outside_out.sensed_mps2 + shake_sensed
    clean[outside] = outside_out.predicted_mps2 + truth.sensor.gain * shake_sensed
    sensed[free] = inside_out.sensed_mps2
    clean[free] = inside_out.predicted_mps2  # Phase 3: exactly the model
    return clean, sensed
