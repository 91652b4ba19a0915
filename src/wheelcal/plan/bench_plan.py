"""A planned calibration setup: what the user will build, and the truth it implies.

The planner reasons about a bench *before* it is built, so the "truth" is the
plan itself: the radius and tilt the user intends, a sensor mounting R (eq. 4),
a nominal sensor (Γ = I, o = 0 unless given; eq. 5) and a spin-down.

The spin of a hand-pushed wheel is slowed mainly by air drag on the spokes,
proportional to ω² (paper II-B1), so

    ω̇ = −c ω²   ⇒   ω(t) = ω_s / (1 + c ω_s t),

with c chosen so that ω falls from ``omega_start_radps`` to ``omega_end_radps``
over the window.  Like :func:`wheelcal.simulate.hand_spin`, the planned motion
is this curve fitted by the cubic of eq. (2) about the window centre, so the
paper's model is exact for the planned truth.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from wheelcal.estimate.joint import (
    DEFAULT_CLOCK_STD_PPM,
    DEFAULT_GRAVITY_STD_MPS2,
    GEOMETRY_MODES,
    JointFit,
    NoiseModel,
)
from wheelcal.model import (
    STANDARD_GRAVITY_MPS2,
    BenchParams,
    CalibrationParams,
    ParameterLayout,
    Rotation,
    SensorParams,
    SpinParams,
)
from wheelcal.recording import SessionInfo
from wheelcal.simulate import NoiseSpec, Scenario

#: The paper's synthetic mounting (Table I, θ, φ, ψ read in EULER_CONVENTION).
PAPER_MOUNTING_EULER_DEG = (30.0, 20.0, 25.0)
VERTICAL_TILT_DEG = 90.0


def drag_spin(
    omega_start_radps: float,
    omega_end_radps: float,
    duration_s: float,
    degree: int = 3,
    theta0_rad: float = 0.0,
) -> SpinParams:
    """Quadratic-drag spin-down (module docstring) as the eq. (2) polynomial in centre time.

    Parameters
    ----------
    omega_start_radps, omega_end_radps:
        |ω| at the first and last sample, 0 < end ≤ start (the wheel turns the
        positive way).
    duration_s:
        Length of the window.
    degree:
        Degree K of the ω(t) polynomial of eq. (2).
    theta0_rad:
        Phase ϑ₀ at the window centre.
    """
    if not 0 < omega_end_radps <= omega_start_radps:
        raise ValueError(
            f"need 0 < omega_end <= omega_start, got {omega_start_radps} → {omega_end_radps} rad/s"
        )
    # ω(T) = ω_s / (1 + c ω_s T) = ω_e  ⇒  c = (ω_s/ω_e − 1) / (ω_s T)
    drag = (omega_start_radps / omega_end_radps - 1.0) / (omega_start_radps * duration_s)
    t = np.linspace(0.0, duration_s, 2001)
    omega = omega_start_radps / (1.0 + drag * omega_start_radps * t)
    coeffs = np.polynomial.polynomial.polyfit(t - duration_s / 2, omega, degree)
    return SpinParams(theta0_rad=theta0_rad, omega_radps=coeffs)


def _require(setup, names: tuple[str, ...], ok: Callable[[float], bool], words: str) -> None:
    """Refuse a field of ``setup`` that is not finite or not ``ok``, naming it (``words``)."""
    for name in names:
        value = getattr(setup, name)
        if not (np.isfinite(value) and ok(value)):
            raise ValueError(f"{name} {words}, got {value}")


@dataclass(frozen=True)
class PlannedSetup:
    """Everything the planner needs to know about a bench that is not built yet.

    Defaults are the paper's bench (Sec. IV): r = 0.28 m measured to ±1 mm, tilt
    45°, 90 s at 200 Hz, MPU-9250 noise 0.08 m/s² (white, as in Table I), a spin
    from 9 to 5.5 rad/s (≈ 100 turns, as in Sec. IV-B), mounting of Table I.

    Parameters
    ----------
    radius_m, radius_std_m:
        Sensor distance from the axle and the uncertainty of its measurement.
    tilt_deg, tilt_std_deg:
        Tilt α of the wheel axis from the vertical (eq. 1); its uncertainty
        matters only where the tilt is *assumed* (``tilt``/``vertical`` modes).
    mounting_euler_deg:
        R of eq. (4) in :data:`~wheelcal.model.EULER_CONVENTION`.
    duration_s, rate_hz:
        Length of the free-spin window and sampling rate.
    noise_std_mps2, noise_bandwidth_hz:
        Marginal noise σ per sample and the low-pass corner (``None``: white).
    omega_start_radps, omega_end_radps:
        Spin at the start and end of the window (quadratic drag in between).
    geometry:
        What is known (paper II-C): ``radius`` (r measured, α fitted),
        ``tilt`` (α measured, r fitted) or ``vertical`` (α = 90°, r fitted).
    gravity_mps2, gravity_std_mps2, clock_std_ppm:
        Local gravity assumed by the fit and its uncertainty; sample-clock
        scale uncertainty.
    gain, offset_mps2:
        Nominal sensor (eq. 5); the bound depends on them only weakly.
    spin_degree:
        Degree of the ω(t) polynomial the fit will use.
    full_scale_g:
        Sensor range, to warn about clipping (``None``: not checked).
    """

    radius_m: float = 0.28
    radius_std_m: float = 1e-3
    tilt_deg: float = 45.0
    tilt_std_deg: float = 0.5
    mounting_euler_deg: tuple[float, float, float] = PAPER_MOUNTING_EULER_DEG
    duration_s: float = 90.0
    rate_hz: float = 200.0
    noise_std_mps2: float = 0.08
    noise_bandwidth_hz: float | None = None
    omega_start_radps: float = 9.0
    omega_end_radps: float = 5.5
    geometry: str = "radius"
    gravity_mps2: float = STANDARD_GRAVITY_MPS2
    gravity_std_mps2: float = DEFAULT_GRAVITY_STD_MPS2
    clock_std_ppm: float = DEFAULT_CLOCK_STD_PPM
    gain: tuple[float, float, float] = (1.0, 1.0, 1.0)
    offset_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    spin_degree: int = 3
    full_scale_g: float | None = None

    def __post_init__(self) -> None:
        if self.geometry not in GEOMETRY_MODES:
            raise ValueError(f"geometry must be one of {GEOMETRY_MODES}, got {self.geometry!r}")
        positive = ("radius_m", "duration_s", "rate_hz", "noise_std_mps2")
        _require(self, positive, lambda v: v > 0, "must be a positive number")
        non_negative = ("radius_std_m", "tilt_std_deg", "gravity_std_mps2", "clock_std_ppm")
        _require(self, non_negative, lambda v: v >= 0, "must be >= 0")
        if not 0.0 < self.tilt_deg <= 90.0:
            raise ValueError(f"tilt_deg must lie in (0, 90], got {self.tilt_deg}")
        if self.geometry == "vertical" and self.tilt_deg != VERTICAL_TILT_DEG:
            raise ValueError(f"a vertical wheel has tilt 90°, got {self.tilt_deg}")
        if self.geometry != "vertical" and self.tilt_deg == VERTICAL_TILT_DEG:
            raise ValueError(
                "tilt 90° leaves the two discrete twins indistinguishable unless the fit "
                "knows it: plan it as geometry 'vertical'"
            )
        if self.rate_hz * self.duration_s < 100:
            raise ValueError("fewer than 100 samples: plan a longer or faster recording")
        # Validates ω_start ≥ ω_end > 0.
        drag_spin(self.omega_start_radps, self.omega_end_radps, self.duration_s, 1)
        object.__setattr__(
            self, "mounting_euler_deg", tuple(float(e) for e in self.mounting_euler_deg)
        )
        if len(self.mounting_euler_deg) != 3:
            raise ValueError("mounting_euler_deg needs three angles")

    # ---- derived quantities -------------------------------------------------------

    @property
    def mounting(self) -> Rotation:
        """R of eq. (4), bench → sensor."""
        return Rotation.from_euler_deg(*self.mounting_euler_deg)

    @property
    def samples(self) -> int:
        """Number of samples in the window (as the simulator draws them)."""
        return round(self.duration_s * self.rate_hz) + 1

    @property
    def turns(self) -> float:
        """Wheel turns in the window, ∫ω dt / 2π."""
        t = self.centred_times_s()
        return float(np.trapezoid(self.spin().omega_at(t), t) / (2 * np.pi))

    @property
    def peak_accel_mps2(self) -> float:
        """Largest |a| at the start of the spin: r ω_s² plus gravity."""
        return self.radius_m * self.omega_start_radps**2 + self.gravity_mps2

    def spin(self) -> SpinParams:
        """Planned ω(t), eq. (2), about the window centre."""
        return drag_spin(
            self.omega_start_radps, self.omega_end_radps, self.duration_s, self.spin_degree
        )

    def params(self) -> CalibrationParams:
        """The planned truth: bench, nominal sensor and spin (eq. 7)."""
        return CalibrationParams(
            spin=self.spin(),
            bench=BenchParams(
                tilt_rad=np.deg2rad(self.tilt_deg),
                radius_m=self.radius_m,
                misalignment=self.mounting,
            ),
            sensor=SensorParams(offset_mps2=self.offset_mps2, gain=self.gain),
            gravity_mps2=self.gravity_mps2,
        )

    def centred_times_s(self) -> np.ndarray:
        """Sample times about the window centre (the simulator's grid)."""
        t = np.arange(self.samples) / self.rate_hz
        return t - 0.5 * t[-1]

    def noise(self) -> NoiseSpec:
        """The planned sensor noise."""
        return NoiseSpec(self.noise_std_mps2, bandwidth_hz=self.noise_bandwidth_hz)

    def noise_model(self) -> NoiseModel:
        """Exact whitening model of the planned noise (AR(2) for band-limited noise)."""
        spec = self.noise()
        return NoiseModel.from_ar(
            spec.ar_polynomial(self.rate_hz), spec.innovation_std(self.rate_hz)
        )

    def layout(self) -> ParameterLayout:
        """Free parameters of the joint fit in this geometry mode."""
        return self.estimator().layout

    def estimator(self) -> JointFit:
        """The joint fit configured for this plan (geometry mode and budget inputs)."""
        return JointFit(
            spin_degree=self.spin_degree,
            geometry=self.geometry,
            known_tilt_deg=self.tilt_deg if self.geometry == "tilt" else None,
            tilt_std_deg=self.tilt_std_deg,
            clock_std_ppm=self.clock_std_ppm,
            gravity_std_mps2=self.gravity_std_mps2,
        )

    def scenario(self) -> Scenario:
        """A simulator scenario of this plan (for Monte Carlo checks of the prediction)."""
        gravity = None if self.gravity_mps2 == STANDARD_GRAVITY_MPS2 else self.gravity_mps2
        info = SessionInfo(
            radius_m=self.radius_m, radius_std_m=self.radius_std_m, gravity_mps2=gravity
        )
        return Scenario(
            truth=self.params(),
            duration_s=self.duration_s,
            rate_hz=self.rate_hz,
            noise=self.noise(),
            info=info,
        )

    def with_changes(self, **changes) -> PlannedSetup:
        """A copy with some fields replaced (validated again)."""
        return replace(self, **changes)

    def with_mounting(self, rotation: Rotation) -> PlannedSetup:
        """The same plan with another sensor mounting."""
        return replace(self, mounting_euler_deg=tuple(rotation.euler_deg()))

    def to_dict(self) -> dict:
        """The plan's inputs, with units in the keys."""
        return {
            "geometry": self.geometry,
            "radius_m": self.radius_m,
            "radius_std_m": self.radius_std_m,
            "tilt_deg": self.tilt_deg,
            "tilt_std_deg": self.tilt_std_deg,
            "mounting_euler_deg": list(self.mounting_euler_deg),
            "duration_s": self.duration_s,
            "rate_hz": self.rate_hz,
            "samples": self.samples,
            "noise_std_mps2": self.noise_std_mps2,
            "noise_bandwidth_hz": self.noise_bandwidth_hz,
            "omega_start_radps": self.omega_start_radps,
            "omega_end_radps": self.omega_end_radps,
            "turns": self.turns,
            "gravity_mps2": self.gravity_mps2,
            "gravity_std_mps2": self.gravity_std_mps2,
            "clock_std_ppm": self.clock_std_ppm,
            "spin_degree": self.spin_degree,
            "full_scale_g": self.full_scale_g,
        }
