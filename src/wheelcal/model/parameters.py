"""Named, typed, immutable parameters of the wheel model (paper eq. 7).

``CalibrationParams`` bundles the three groups the paper names:

* the **spin** of the wheel, eq. (2): ϑ(t) = ϑ₀ + ω₀t + ω₁t²/2 + ω₂t³/3 + ω₃t⁴/4,
  with t = 0 at the *centre* of the fitted window (CONTRACT) — coefficient k has
  unit rad/s^(k+1); ω is signed (the wheel may turn either way);
* the **bench**: tilt α (eq. 1), radius r, misalignment R (eq. 4, bench → sensor);
* the **sensor**: offset o and gain Γ = diag(γ) (eq. 5),

plus gravity (a known constant, never fitted) and the parameters of optional
model extensions ("effects", zero = absent) keyed by effect name.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from wheelcal.model.rotation import Rotation

STANDARD_GRAVITY_MPS2 = 9.80665
AXES = ("x", "y", "z")


class FrozenMapping(dict):
    """A read-only dict that pickles (MappingProxyType does not)."""

    def _readonly(self, *args, **kwargs):
        raise TypeError("this mapping is read-only")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = _readonly  # type: ignore[assignment]
    __ior__ = _readonly  # type: ignore[assignment]

    def __reduce__(self):
        return (FrozenMapping, (dict(self),))

    def __hash__(self) -> int:  # type: ignore[override]
        return hash(tuple(sorted((k, np.asarray(v).tobytes()) for k, v in self.items())))


def _frozen_vector(values, length: int | None, name: str) -> np.ndarray:
    arr = np.array(values, dtype=float).reshape(-1)
    if length is not None and arr.shape != (length,):
        raise ValueError(f"{name} needs {length} values, got {arr.shape[0]}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr}")
    arr.setflags(write=False)
    return arr


def spin_coefficient_names(degree: int) -> tuple[str, ...]:
    """Names of ω₀…ω_degree with their units: omega0_radps, omega1_radps2, …."""
    return tuple(f"omega{k}_radps" + (str(k + 1) if k else "") for k in range(degree + 1))


@dataclass(frozen=True, eq=False)
class SpinParams:
    """Polynomial spin of eq. (2) about the window centre (t = 0)."""

    theta0_rad: float
    omega_radps: np.ndarray  # (ω₀, ω₁, …, ω_K); ω_k in rad/s^(k+1)

    def __post_init__(self) -> None:
        object.__setattr__(self, "theta0_rad", float(self.theta0_rad))
        object.__setattr__(self, "omega_radps", _frozen_vector(self.omega_radps, None, "omega"))
        if self.omega_radps.size < 1:
            raise ValueError("the spin polynomial needs at least ω₀")

    @property
    def degree(self) -> int:
        """Degree K of the ω(t) polynomial (3 in the paper)."""
        return self.omega_radps.size - 1

    def omega_at(self, t_s: np.ndarray) -> np.ndarray:
        """ω(t) in rad/s, eq. (2)."""
        return np.polynomial.polynomial.polyval(np.asarray(t_s, float), self.omega_radps)

    def theta_at(self, t_s: np.ndarray) -> np.ndarray:
        """ϑ(t) in rad, eq. (2)."""
        k = np.arange(1, self.omega_radps.size + 1)
        coeffs = np.concatenate([[self.theta0_rad], self.omega_radps / k])
        return np.polynomial.polynomial.polyval(np.asarray(t_s, float), coeffs)

    def shifted(self, dt_s: float) -> SpinParams:
        """The same motion described with the time origin moved by ``dt_s``.

        If this object describes ϑ(t), the result describes ϑ'(t') = ϑ(t' + dt_s),
        e.g. ``shifted(45.0)`` turns a start-origin 90 s profile into centre time.
        """
        coeffs = np.concatenate(
            [[self.theta0_rad], self.omega_radps / np.arange(1, self.degree + 2)]
        )
        # Taylor-shift the phase polynomial: p(t' + dt) expanded in t'.
        shifted = np.polynomial.Polynomial(coeffs)(np.polynomial.Polynomial([dt_s, 1.0])).coef
        shifted = np.pad(shifted, (0, coeffs.size - shifted.size))
        omega = shifted[1:] * np.arange(1, self.degree + 2)
        theta0 = (float(shifted[0]) + np.pi) % (2 * np.pi) - np.pi  # ϑ₀ is an angle
        return SpinParams(theta0_rad=theta0, omega_radps=omega)

    def to_dict(self) -> dict[str, float]:
        """Contract keys: theta0_rad, omega0_radps, omega1_radps2, …."""
        out = {"theta0_rad": self.theta0_rad}
        out.update(
            zip(spin_coefficient_names(self.degree), map(float, self.omega_radps), strict=True)
        )
        return out


@dataclass(frozen=True, eq=False)
class BenchParams:
    """Bench geometry: tilt α ∈ [0°, 90°] in canonical form, radius r, misalignment R."""

    tilt_rad: float
    radius_m: float
    misalignment: Rotation

    def __post_init__(self) -> None:
        object.__setattr__(self, "tilt_rad", float(self.tilt_rad))
        object.__setattr__(self, "radius_m", float(self.radius_m))
        if not np.isfinite(self.tilt_rad) or not np.isfinite(self.radius_m):
            raise ValueError("tilt and radius must be finite")
        if not isinstance(self.misalignment, Rotation):
            raise TypeError("misalignment must be a Rotation")

    @property
    def tilt_deg(self) -> float:
        """Tilt α in degrees."""
        return float(np.rad2deg(self.tilt_rad))


@dataclass(frozen=True, eq=False)
class SensorParams:
    """Six-parameter sensor of eq. (5): v = o + Γ s."""

    offset_mps2: np.ndarray
    gain: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "offset_mps2", _frozen_vector(self.offset_mps2, 3, "offset"))
        object.__setattr__(self, "gain", _frozen_vector(self.gain, 3, "gain"))
        if np.any(self.gain <= 0):
            raise ValueError(f"gains must be positive, got {self.gain}")


@dataclass(frozen=True, eq=False)
class CalibrationParams:
    """Everything the model of eq. (6)–(7) needs, plus optional effects."""

    spin: SpinParams
    bench: BenchParams
    sensor: SensorParams
    gravity_mps2: float = STANDARD_GRAVITY_MPS2
    effects: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        frozen = {
            name: _frozen_vector(values, None, f"effect {name}")
            for name, values in dict(self.effects).items()
        }
        object.__setattr__(self, "effects", FrozenMapping(frozen))
        object.__setattr__(self, "gravity_mps2", float(self.gravity_mps2))

    def with_changes(self, **changes) -> CalibrationParams:
        """A copy with some groups replaced (``spin=…``, ``bench=…``, …)."""
        return replace(self, **changes)

    def effect(self, name: str, size: int) -> np.ndarray:
        """Values of one effect; zeros (= absent) when it is not present."""
        values = self.effects.get(name)
        return np.zeros(size) if values is None else values

    def static_force_mps2(self, reading_mps2: np.ndarray) -> np.ndarray:
        """The force in the wheel frame that still readings show: a = Rᵀ Γ⁻¹ (v − o).

        ``reading_mps2``: (3,) or (k, 3) sensor readings (e.g. a rest's mean); the base
        sensor model only (effects are not inverted).
        """
        sensor = self.sensor
        relative = (np.asarray(reading_mps2, dtype=float) - sensor.offset_mps2) / sensor.gain
        return relative @ self.bench.misalignment.matrix  # rows: (Rᵀ x)ᵀ = xᵀ R
