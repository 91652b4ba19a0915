"""A field scenario recorded: the sensor chain from exact kinematics to a Recording and its truth.

For each sample time t (recording seconds, the first sample at 0):

1. the motion gives ϑ, ω, ω̇, ψ, ψ̇, ψ̈, v, v̇ (:mod:`~wheelcal.simulate.field_motion`);
2. the rigid-body kinematics give the bench-frame specific force a and body
   rate Ω_B = Aᵀ Ω (:mod:`~wheelcal.simulate.field_kinematics`);
3. the hub's vibration x (:mod:`~wheelcal.simulate.road`), a world-frame
   translation, adds Aᵀ x to the force;
4. the accelerometer reads v = o + Γ R (a + Aᵀ x) + n, n its noise
   (:class:`~wheelcal.simulate.noise.NoiseSpec`), then optionally quantised
   and clipped (:class:`~wheelcal.simulate.noise.Quantiser`);
5. the gyro reads R Ω_B through its own errors
   (:meth:`~wheelcal.simulate.gyro.GyroSpec.output`, g-sensitive to R (a + Aᵀ x));
6. the logger's glitches (:mod:`~wheelcal.simulate.logger_glitches`).

Random draws, in order: accelerometer noise, vibration, gyro noise (and its bias's walk,
if it walks), the rim's vibration (if any), glitches; a road's own series come from its
seed (:mod:`~wheelcal.simulate.road_profile`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from wheelcal.model import (
    STANDARD_GRAVITY_MPS2,
    BenchParams,
    CalibrationParams,
    Kinematics,
    Rotation,
    SensorParams,
    SpinParams,
)
from wheelcal.recording import Recording, SessionInfo
from wheelcal.simulate.field_kinematics import Lean, wheel_kinematics
from wheelcal.simulate.field_motion import AxleSpin, MotionState, VehiclePath
from wheelcal.simulate.field_wheel import WheelGeometry
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.logger_glitches import (
    Glitches,
    GlitchRows,
    LoggedSamples,
    apply_glitches,
    glitch_rows,
    logged_samples,
)
from wheelcal.simulate.noise import NoiseSpec, Quantiser
from wheelcal.simulate.road import VibrationSpec
from wheelcal.simulate.road_profile import RoadProfile

#: Geometry labels (CONTRACT ``bench.geometry``).
GEOMETRIES = ("bench", "vertical", "rolling")
#: What the truth keeps of the scenario's specs, by the same names.
_SPECS = ("gyro", "noise", "vibration", "quantiser", "glitches", "free_spin", "road")


@dataclass(frozen=True, eq=False)
class FieldScenario:
    """Everything a field recording is drawn from (the profiles in :mod:`.field` build these).

    ``kind`` names the profile (``car``, ``robot``, ``wheelchair``, ``bench``,
    ``stand``); ``free_spin`` is a fixed axle's free spin-down as eq. (2) about
    its window's centre, when it has one.  The recording's session facts carry
    no radius unless ``include_radius`` (the estimator should find it).
    """

    kind: str
    wheel: WheelGeometry
    motion: VehiclePath | AxleSpin
    sensor: SensorParams
    mounting: Rotation
    duration_s: float
    rate_hz: float
    noise: NoiseSpec = field(default_factory=lambda: NoiseSpec(0.02))
    vibration: VibrationSpec | None = None
    gyro: GyroSpec | None = None
    quantiser: Quantiser | None = None
    glitches: Glitches = field(default_factory=Glitches)
    gravity_mps2: float = STANDARD_GRAVITY_MPS2
    include_radius: bool = False
    sensor_id: str = ""
    free_spin: SpinParams | None = None
    epoch_unix_ns: int = 1_700_000_000_000_000_000
    #: A rolling wheel's camber changes by this much per m/s² of lateral acceleration
    #: v ψ̇ (a car's body roll; :class:`~wheelcal.simulate.field_kinematics.Lean`).
    body_roll_deg_per_mps2: float = 0.0
    #: The road's camber along it and the carrier's angular shaking (rolling wheels).
    road: RoadProfile | None = None
    #: A second band of the hub's vibration (the rim's, e.g. 25–55 Hz along the axle),
    #: drawn after everything else.
    rim_vibration: VibrationSpec | None = None

    def __post_init__(self) -> None:
        if not (self.duration_s > 0 and self.rate_hz > 0):
            raise ValueError("duration_s and rate_hz must be positive")
        rolling = isinstance(self.motion, VehiclePath)
        if rolling != (self.wheel.rolling_radius_m is not None):
            raise ValueError("a vehicle path needs a rolling radius, a fixed axle none")
        if (
            self.vibration is not None
            and self.vibration.follows == "hands"
            and not isinstance(self.motion, AxleSpin)
        ):
            raise ValueError("vibration that follows the hands needs a fixed axle's spin")
        if self.include_radius and not self.wheel.radius_m > 0:
            raise ValueError("include_radius needs a sensor off the axle (radius_m > 0)")
        if self.body_roll_deg_per_mps2 and not rolling:
            raise ValueError("body roll needs a rolling wheel")
        if self.road is not None and not rolling:
            raise ValueError("a road profile needs a rolling wheel")

    @property
    def geometry(self) -> str:
        """``rolling`` (a vehicle's wheel), ``vertical`` (a fixed α = 90° axle) or ``bench``."""
        if isinstance(self.motion, VehiclePath):
            return "rolling"
        return "vertical" if np.isclose(self.wheel.tilt_rad, np.pi / 2, atol=1e-12) else "bench"

    def times_s(self) -> np.ndarray:
        """The sample grid, 0 to ``duration_s`` inclusive."""
        return np.arange(round(self.duration_s * self.rate_hz) + 1) / self.rate_hz

    def info(self) -> SessionInfo:
        """The session facts a logger would store (no radius unless ``include_radius``)."""
        standard = self.gravity_mps2 == STANDARD_GRAVITY_MPS2
        return SessionInfo(
            radius_m=self.wheel.radius_m if self.include_radius else None,
            sensor_id=self.sensor_id,
            gravity_mps2=None if standard else self.gravity_mps2,
            full_scale_g=None if self.quantiser is None else self.quantiser.full_scale_g,
            gyro_full_scale_dps=None if self.gyro is None else self.gyro.full_scale_dps,
        )


@dataclass(frozen=True, eq=False)
class FieldTruth:
    """The truth behind a field recording; per-sample arrays align with the recording's rows.

    Sensor and bench
        ``sensor`` (gain Γ, offset o), ``bench`` (tilt α — 90° − camber on a
        rolling wheel —, the sensor's radius r, R bench → sensor) as the
        estimator reports them; ``gravity_mps2``.
    Geometry (:mod:`~wheelcal.simulate.field_kinematics`)
        ``kind`` (profile), ``geometry`` (``bench``/``vertical``/``rolling``),
        ``rolling_radius_m`` ρ (hub to ground contact; ``None`` on a fixed
        axle), ``camber_rad`` γ (``None`` on a fixed axle), ``side`` σ (+1
        left, −1 right: the axle's upper end is outboard), ``axle_offset_m`` h.
    Motion, at ``time_s`` (recording seconds)
        ``motion`` (a :class:`~wheelcal.simulate.field_motion.MotionState`):
        ``theta_rad`` ϑ (the wheel's angle relative to its carrier, CONTRACT
        origin: X up the wheel plane at ϑ = 0), ``omega_radps`` ω = dϑ/dt,
        ``omega_dot_radps2``; ``heading_rad`` ψ, ``yaw_rate_radps`` ψ̇,
        ``yaw_accel_radps2`` ψ̈ (about the world vertical); ``speed_mps`` v ≥ 0
        and ``speed_dot_mps2`` v̇ of the hub, ``distance_m`` from t = 0.  On a
        rolling wheel ω = ψ̇ sin γ − σ v/ρ.
    Signals
        ``specific_force_mps2`` a (bench frame, exact, without vibration);
        ``body_rate_radps`` Ω_B = ψ̇ n − ω e_Z (bench frame, n the vertical in
        it; an ideal gyro reads R Ω_B); ``clean_accel_mps2`` o + Γ R a;
        ``vibration_mps2`` Γ R Aᵀ x, what the vibration added to the output;
        ``vibration_envelope`` e(t).
    Specs
        ``gyro`` (its errors), ``noise``, ``vibration``, ``quantiser``,
        ``glitches`` and where they fell (``glitch_rows``).
    Windows
        ``window_s``: a fixed axle's free spin, or a rolling wheel's first move
        to its last stop; ``free_spin`` the free spin as eq. (2) about its
        centre (fixed axle profiles), else ``None``.
    """

    kind: str
    geometry: str
    sensor: SensorParams
    bench: BenchParams
    rolling_radius_m: float | None
    camber_rad: float | None
    side: int
    axle_offset_m: float
    gravity_mps2: float
    time_s: np.ndarray
    motion: MotionState
    specific_force_mps2: np.ndarray
    body_rate_radps: np.ndarray
    clean_accel_mps2: np.ndarray
    vibration_mps2: np.ndarray
    vibration_envelope: np.ndarray
    gyro: GyroSpec | None
    noise: NoiseSpec
    vibration: VibrationSpec | None
    quantiser: Quantiser | None
    glitches: Glitches
    glitch_rows: GlitchRows
    window_s: tuple[float, float]
    free_spin: SpinParams | None = None
    #: The road's profile (camber, angular shaking), when it has one.
    road: RoadProfile | None = None
    #: γ(t) per sample where the camber changes during the drive (a lean), else None.
    camber_series_rad: np.ndarray | None = None

    @property
    def tilt_deg(self) -> float:
        """α in degrees (a leaning wheel's at rest: see :meth:`tilt_at_deg`)."""
        return self.bench.tilt_deg

    def tilt_at_deg(self, time_s: float) -> float:
        """α at ``time_s`` (recording seconds) as the CONTRACT reports it: in [0°, 90°].

        A leaning wheel's is 90° − γ(t).  Where the camber is negative there (the axle's
        outboard end, this simulator's Z, points down) the CONTRACT's Z is the other end,
        the one that points up: α = 90° − |γ| (the twin, R·diag(1, −1, −1), ϑ → −ϑ; the
        gains and offsets are the same in both).
        """
        if self.camber_series_rad is None:
            return self.tilt_deg
        gamma = float(np.interp(time_s, self.time_s, self.camber_series_rad))
        return 90.0 - abs(float(np.rad2deg(gamma)))

    @property
    def camber_deg(self) -> float | None:
        """γ in degrees (``None`` on a fixed axle)."""
        return None if self.camber_rad is None else float(np.rad2deg(self.camber_rad))

    @property
    def radius_m(self) -> float:
        """r, the sensor's distance from the axle."""
        return self.bench.radius_m

    @property
    def axle_twin_misalignment(self) -> Rotation:
        """R · diag(1, −1, −1): R of the same wheel described with Z reversed (ϑ, ω → −ϑ, −ω).

        At α = 90° (a vertical wheel, rolling or on a stand) neither end of the
        axle points up, and both descriptions fit the data exactly (CONTRACT's
        twin); this simulator takes Z outboard, an estimate may report the other.
        """
        return Rotation.composed(self.bench.misalignment.matrix @ np.diag([1.0, -1.0, -1.0]))

    def kinematics(self) -> Kinematics:
        """ϑ, ω, ω̇ at the samples, as the model's type."""
        m = self.motion
        return Kinematics(m.theta_rad, m.omega_radps, m.omega_dot_radps2)

    def params(self) -> CalibrationParams:
        """Bench, sensor and gravity as :class:`~wheelcal.model.CalibrationParams`.

        Its ``spin`` is only a placeholder (ϑ, ω at the first sample): the motion
        is :meth:`kinematics` (pass it to :func:`wheelcal.model.evaluate`).
        """
        spin = SpinParams(self.motion.theta_rad[0], (self.motion.omega_radps[0],))
        return CalibrationParams(spin, self.bench, self.sensor, self.gravity_mps2)


@dataclass(frozen=True, eq=False)
class FieldSimulation:
    """A simulated field recording: the Recording, its truth, and the logger's raw rows.

    ``logged`` is what the logger wrote (stamps in int ns), duplicate stamps
    included; write it with :func:`wheelcal.io.mcap_writer.write_accel_mcap`
    to test a reader.  ``recording`` holds each row once.
    """

    recording: Recording
    truth: FieldTruth
    logged: LoggedSamples
    scenario: FieldScenario


def _vibration(
    scenario: FieldScenario, state, kin, t: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """The hub's vibration in the bench frame (N, 3) and its envelope (N,)."""
    spec = scenario.vibration
    if spec is None:
        return np.zeros((t.size, 3)), np.zeros(t.size)
    if spec.follows == "speed":
        envelope = spec.envelope(state.speed_mps)
    else:
        envelope = scenario.motion.hand_envelope(t)
    return _shaken(spec, scenario, state, kin, t, rng, envelope), envelope


def _shaken(
    spec: VibrationSpec, scenario, state, kin, t, rng, envelope: np.ndarray | None = None
) -> np.ndarray:
    """One band of the hub's vibration in the bench frame (N, 3) (envelope: the speed's)."""
    if envelope is None:
        envelope = spec.envelope(state.speed_mps)
    local = spec.sample(t.size, scenario.rate_hz, rng) * envelope[:, None]
    c, s = np.cos(state.heading_rad), np.sin(state.heading_rad)
    world = np.column_stack([local[:, 0] * c - local[:, 1] * s, local[:, 0] * s + local[:, 1] * c])
    world = np.column_stack([world, local[:, 2]])  # (forward, left, up) → world
    return kin.to_bench(world)


def _window(scenario: FieldScenario, t: np.ndarray, speed: np.ndarray) -> tuple[float, float]:
    if isinstance(scenario.motion, AxleSpin):
        if scenario.motion.free_spin_s is not None:
            return scenario.motion.free_spin_s
        return float(t[0]), float(t[-1])
    moving = np.flatnonzero(speed > 1e-9)
    if moving.size == 0:
        return float(t[0]), float(t[0])
    return float(t[moving[0]]), float(t[moving[-1]])


def _leaning(
    state: MotionState,
    wheel: WheelGeometry,
    roll_rad_per_mps2: float,
    t: np.ndarray,
    road: RoadProfile | None = None,
) -> tuple[MotionState, Lean]:
    """γ(t) = γ₀ + k v ψ̇ (+ the road's), and ω = ψ̇ sin γ(t) − σ v/ρ with it (ϑ integrated)."""
    v, v_dot = state.speed_mps, state.speed_dot_mps2
    yaw, yaw_dot = state.yaw_rate_radps, state.yaw_accel_radps2
    gamma = wheel.camber_rad + roll_rad_per_mps2 * v * yaw
    gamma_dot = roll_rad_per_mps2 * (v_dot * yaw + v * yaw_dot)
    if road is not None:
        change = road.camber_change(state, wheel.side, t)
        gamma = gamma + change
        gamma_dot = gamma_dot + np.gradient(change, t)
    extra = (np.sin(gamma) - np.sin(wheel.camber_rad)) * yaw
    turned = np.concatenate([[0.0], np.cumsum(0.5 * (extra[1:] + extra[:-1]) * np.diff(t))])
    state = dataclasses.replace(
        state,
        theta_rad=state.theta_rad + turned - np.interp(0.0, t, turned),
        omega_radps=state.omega_radps + extra,
        omega_dot_radps2=state.omega_dot_radps2 + np.gradient(extra, t),
    )
    return state, Lean(gamma, gamma_dot, np.gradient(gamma_dot, t))


def simulate_field(scenario: FieldScenario, rng: np.random.Generator) -> FieldSimulation:
    """Record ``scenario`` (module docstring); ``rng`` is the only source of randomness."""
    t = scenario.times_s()
    wheel = scenario.wheel
    state = scenario.motion.state(t, wheel)
    lean = shake = None
    if scenario.body_roll_deg_per_mps2 or scenario.road is not None:
        roll = np.deg2rad(scenario.body_roll_deg_per_mps2)
        state, lean = _leaning(state, wheel, roll, t, scenario.road)
    if scenario.road is not None:
        shake = scenario.road.shake(state, scenario.rate_hz, t.size)
    kin = wheel_kinematics(state, wheel, lean, shake, scenario.rate_hz)
    force = kin.specific_force_bench(scenario.gravity_mps2)
    rot = scenario.mounting.matrix
    gain, offset = scenario.sensor.gain, scenario.sensor.offset_mps2
    clean = offset + gain * (force @ rot.T)
    accel_noise = scenario.noise.sample(t.size, scenario.rate_hz, rng)
    shake_bench, envelope = _vibration(scenario, state, kin, t, rng)
    shake_out = gain * (shake_bench @ rot.T)
    accel = clean + shake_out + accel_noise
    if scenario.quantiser is not None:
        accel = scenario.quantiser.apply(accel)
    body_rate = kin.rate_bench()
    gyro = None
    if scenario.gyro is not None:
        # GyroSpec reads R (−ω e_Z + extra): the extra is Ω_B's part besides the spin.
        extra = body_rate.copy()
        extra[:, 2] += state.omega_radps
        sensed = (force + shake_bench) @ rot.T
        gyro = scenario.gyro.output(state.omega_radps, sensed, rot, scenario.rate_hz, rng, extra)

    if scenario.rim_vibration is not None:
        rim = _shaken(scenario.rim_vibration, scenario, state, kin, t, rng)
        accel = accel + gain * (rim @ rot.T)
        shake_out = shake_out + gain * (rim @ rot.T)
    rows = glitch_rows(scenario.glitches, t, gyro is not None, rng)
    keep = rows.kept
    accel, gyro = apply_glitches(
        scenario.glitches, rows, accel[keep], None if gyro is None else gyro[keep], rng
    )
    time_s = t[keep]
    recording = Recording(
        time_s=time_s,
        accel_mps2=accel,
        info=scenario.info(),
        epoch_unix_ns=scenario.epoch_unix_ns,
        source=f"<field {scenario.kind}>",
        gyro_radps=gyro,
    )
    stamps = scenario.epoch_unix_ns + np.rint(time_s * 1e9).astype(np.int64)
    rolling = scenario.geometry == "rolling"
    truth = FieldTruth(
        kind=scenario.kind,
        geometry=scenario.geometry,
        sensor=scenario.sensor,
        bench=BenchParams(wheel.tilt_rad, wheel.radius_m, scenario.mounting),
        rolling_radius_m=wheel.rolling_radius_m,
        camber_rad=wheel.camber_rad if rolling else None,
        side=wheel.side,
        axle_offset_m=wheel.axle_offset_m,
        gravity_mps2=scenario.gravity_mps2,
        time_s=time_s,
        motion=state.take(keep),
        specific_force_mps2=force[keep],
        body_rate_radps=body_rate[keep],
        clean_accel_mps2=clean[keep],
        vibration_mps2=shake_out[keep],
        vibration_envelope=envelope[keep],
        glitch_rows=rows,
        window_s=_window(scenario, t, state.speed_mps),
        camber_series_rad=None if lean is None else lean.camber_rad[keep],
        **{name: getattr(scenario, name) for name in _SPECS},
    )
    return FieldSimulation(
        recording=recording,
        truth=truth,
        logged=logged_samples(stamps, accel, gyro, rows),
        scenario=scenario,
    )
