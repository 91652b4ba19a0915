"""A field wheel's geometry: where its axle points and where the sensor sits.

Shared by the motion (:mod:`wheelcal.simulate.field_motion`: the rolling radius
turns the wheel) and the kinematics (:mod:`wheelcal.simulate.field_kinematics`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class WheelGeometry:
    """Where the wheel's axle points and where the sensor sits (module docstring).

    Parameters
    ----------
    tilt_rad:
        α ∈ (0, π/2], the axle's angle from the vertical (CONTRACT); a rolling
        wheel's camber is γ = π/2 − α.
    radius_m:
        r ≥ 0, the sensor's distance from the axle.
    rolling_radius_m:
        ρ, a rolling wheel's radius (hub to ground contact); ``None`` on a fixed axle.
    side:
        σ = +1 (the vehicle's left) or −1 (right); the axle's upper end points outboard.
    axle_offset_m:
        h, the sensor's offset along Z from the wheel's mid-plane.
    """

    tilt_rad: float
    radius_m: float
    rolling_radius_m: float | None = None
    side: int = 1
    axle_offset_m: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 < self.tilt_rad <= np.pi / 2 + 1e-12:
            raise ValueError(f"tilt must be in (0°, 90°], got {np.rad2deg(self.tilt_rad)}°")
        if not (np.isfinite(self.radius_m) and self.radius_m >= 0):
            raise ValueError(f"radius_m must be finite and >= 0, got {self.radius_m}")
        rho = self.rolling_radius_m
        if rho is not None and not (np.isfinite(rho) and rho > 0):
            raise ValueError(f"rolling_radius_m must be positive, got {rho}")
        if self.side not in (1, -1):
            raise ValueError(f"side must be +1 (left) or -1 (right), got {self.side}")
        if not np.isfinite(self.axle_offset_m):
            raise ValueError("axle_offset_m must be finite")

    @classmethod
    def rolling(
        cls,
        *,
        camber_deg: float,
        radius_m: float,
        rolling_radius_m: float,
        axle_offset_m: float,
        side: int,
    ) -> WheelGeometry:
        """A vehicle's wheel with camber γ (0 ≤ γ < 90°), top inboard; every value named."""
        if not 0.0 <= camber_deg < 90.0:
            raise ValueError(f"camber must be in [0°, 90°), got {camber_deg}°")
        tilt = np.deg2rad(90.0 - camber_deg)
        return cls(tilt, radius_m, rolling_radius_m, side, axle_offset_m)

    @property
    def camber_rad(self) -> float:
        """γ = 90° − α."""
        return float(np.pi / 2 - self.tilt_rad)

    @property
    def lever_m(self) -> np.ndarray:
        """The sensor from the hub, p = (−r, 0, h), bench frame."""
        return np.array([-self.radius_m, 0.0, self.axle_offset_m])
