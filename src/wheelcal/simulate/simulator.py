"""Simulated recordings that speak the estimator's parameter types.

``simulate(scenario, rng)`` gives a :class:`~wheelcal.recording.Recording`
together with the truth as :class:`~wheelcal.model.CalibrationParams` about
the same window centre the estimator uses, so a round trip is one line::

    sim = simulate(preset("table1"), np.random.default_rng(1))
    result = JointFit().fit(sim.recording)
    result.params.sensor.gain - sim.truth.sensor.gain

A scenario may add a gyroscope (:class:`~wheelcal.simulate.gyro.GyroSpec`,
read as ``Recording.gyro_radps``) and a temperature channel
(:class:`~wheelcal.simulate.temperature.TemperatureSpec`, ``temperature_c``)
on the accelerometer's clock.  Their random draws come *after* the
accelerometer's, so a seed gives the same accelerometer samples with or
without them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from wheelcal.model import CalibrationParams, ModelOutput, evaluate
from wheelcal.recording import Recording, SessionInfo
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.noise import NoiseSpec, Quantiser
from wheelcal.simulate.temperature import TemperatureSpec


@dataclass(frozen=True)
class Scenario:
    """A bench, a sensor and a sampling plan: everything needed to simulate.

    ``truth`` is referenced to t = 0 at the centre of the recording (CONTRACT).
    """

    truth: CalibrationParams
    duration_s: float = 90.0
    rate_hz: float = 200.0
    noise: NoiseSpec = field(default_factory=NoiseSpec)
    info: SessionInfo = field(default_factory=SessionInfo)
    quantiser: Quantiser | None = None
    #: Effects present in the truth (their values in ``truth.effects``).
    effects: tuple = ()
    #: A physical motion (see :mod:`wheelcal.simulate.motion`) instead of ``truth.spin``.
    motion: object | None = None
    #: Vibration of the bench (bearings, road) while the wheel turns: broadband
    #: acceleration of this RMS (m/s², per axis), on top of the sensor noise.
    vibration: NoiseSpec | None = None
    #: A gyroscope on the same clock (``None``: the recording has no gyro).
    gyro: GyroSpec | None = None
    #: A temperature channel (``None``: the recording has none).
    temperature: TemperatureSpec | None = None

    def __post_init__(self) -> None:
        if not (self.duration_s > 0 and self.rate_hz > 0):
            raise ValueError("duration_s and rate_hz must be positive")
        if self.info.radius_m is None:
            object.__setattr__(self, "info", self.info.merged(radius_m=self.truth.bench.radius_m))

    def times_s(self) -> np.ndarray:
        """Sample times from 0 to ``duration_s`` inclusive."""
        n = round(self.duration_s * self.rate_hz) + 1
        return np.arange(n) / self.rate_hz

    def centred_times_s(self) -> np.ndarray:
        """Sample times about the centre of the recording."""
        t = self.times_s()
        return t - 0.5 * (t[0] + t[-1])

    def record(
        self,
        time_s: np.ndarray,
        clean_mps2: np.ndarray,
        rng: np.random.Generator,
        epoch_unix_ns: int,
        source: str,
        vibration_envelope: np.ndarray | None = None,
        omega_radps: np.ndarray | None = None,
        sensed_mps2: np.ndarray | None = None,
    ) -> Recording:
        """The sensor's output stage: noise, optional quantisation, a typed recording.

        ``vibration_envelope`` (0–1 per sample) scales the bench's vibration
        (``vibration``) with the wheel's speed; ``None`` means full throughout.
        With a ``gyro``, ``omega_radps`` (ω per sample) and ``sensed_mps2``
        (the true specific force R a per sample) drive it.  Draws, in order:
        accelerometer noise, vibration, then gyro noise and temperature noise.
        """
        noisy = clean_mps2 + self.noise.sample(time_s.size, self.rate_hz, rng)
        if self.vibration is not None:
            shake = self.vibration.sample(time_s.size, self.rate_hz, rng)
            if vibration_envelope is not None:
                shake *= np.asarray(vibration_envelope)[:, None]
            noisy += shake
        if self.quantiser is not None:
            noisy = self.quantiser.apply(noisy)
        gyro = None
        if self.gyro is not None:
            if omega_radps is None or sensed_mps2 is None:
                raise ValueError("a scenario with a gyro needs omega_radps and sensed_mps2")
            rotation = self.truth.bench.misalignment.matrix
            gyro = self.gyro.output(omega_radps, sensed_mps2, rotation, self.rate_hz, rng)
        temperature = None
        if self.temperature is not None:
            temperature = self.temperature.sample(time_s, rng)
        return Recording(
            time_s=time_s,
            accel_mps2=noisy,
            info=self.info,
            epoch_unix_ns=epoch_unix_ns,
            source=source,
            gyro_radps=gyro,
            temperature_c=temperature,
        )

    def clean_output(self, t_centred_s: np.ndarray) -> ModelOutput:
        """The noise-free model at centred times: v(t), and the kinematics and force behind it."""
        kin = None if self.motion is None else self.motion.kinematics(t_centred_s)
        return evaluate(self.truth, t_centred_s, effects=self.effects, kinematics=kin)

    def clean_signal(self, t_centred_s: np.ndarray) -> np.ndarray:
        """Noise-free v(t): the truth, its effects, and the physical motion if any."""
        return self.clean_output(t_centred_s).predicted_mps2


@dataclass(frozen=True, eq=False)
class SimulatedSession:
    """A simulated recording and the truth that generated it."""

    recording: Recording
    truth: CalibrationParams
    clean_mps2: np.ndarray  # noise-free v(t), for checks of applied calibrations
    scenario: Scenario


def simulate(
    scenario: Scenario,
    rng: np.random.Generator,
    epoch_unix_ns: int = 1_700_000_000_000_000_000,
    source: str = "<simulated>",
) -> SimulatedSession:
    """Draw one noisy recording of ``scenario`` (randomness from ``rng`` only)."""
    t = scenario.times_s()
    out = scenario.clean_output(scenario.centred_times_s())
    clean = out.predicted_mps2
    recording = scenario.record(
        t,
        clean,
        rng,
        epoch_unix_ns,
        source,
        omega_radps=out.kinematics.omega_radps,
        sensed_mps2=out.sensed_mps2,
    )
    return SimulatedSession(
        recording=recording, truth=scenario.truth, clean_mps2=clean, scenario=scenario
    )
