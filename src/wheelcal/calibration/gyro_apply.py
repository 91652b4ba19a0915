"""The gyroscope's correction from a sensor's pooled calibration (its ``gyro`` block).

The pooled fit (:mod:`wheelcal.closedloop.gyro_matrix`) gives the gyro's reading
as g = M ω + b + G f, ω and f (the specific force) in the accelerometer's
orthonormal sensor frame.  Inverted, per sample,

    ω = M⁻¹ (g − b − G f),    f = the calibrated accelerometer, a = matrix @ (v − bias),

which is what ``wheelcal apply`` writes as the calibrated topic's angular
velocity, and what the exports hand to Kalibr, imu_tk and firmware.  A
session's own calibration sees the gyro along one wheel axis only, so it
carries no correction: only a sensor's file pooled over mountings that
determine M and b does (``gyro.correction``).  G is applied when the mountings
determine it, else left out (and said so).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class GyroCorrection:
    """ω = matrix @ (g − bias − G f): the pooled gyro's correction (rad/s)."""

    matrix: np.ndarray  # M⁻¹
    bias_radps: np.ndarray
    response: np.ndarray  # M
    g_sensitivity: np.ndarray | None  # G, rad/s per m/s² (None: not determined)

    def __post_init__(self) -> None:
        for name, shape in (("matrix", (3, 3)), ("bias_radps", (3,)), ("response", (3, 3))):
            value = np.array(getattr(self, name), dtype=float).reshape(shape)
            if not np.all(np.isfinite(value)):
                raise ValueError(f"the gyro correction's {name} is not finite")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if self.g_sensitivity is not None:
            g = np.array(self.g_sensitivity, dtype=float).reshape(3, 3)
            g.setflags(write=False)
            object.__setattr__(self, "g_sensitivity", g if np.all(np.isfinite(g)) else None)

    def apply(self, gyro_radps: np.ndarray, accel_mps2: np.ndarray | None = None) -> np.ndarray:
        """Corrected rates (N, 3); ``accel_mps2`` the calibrated specific force (for G)."""
        g = np.asarray(gyro_radps, dtype=float) - self.bias_radps
        if self.g_sensitivity is not None and accel_mps2 is not None:
            g = g - np.asarray(accel_mps2, dtype=float) @ self.g_sensitivity.T
        return g @ np.ascontiguousarray(self.matrix.T)

    def describe(self) -> str:
        """One line for the user: what the gyro's correction does."""
        g = (
            ", less its sensitivity to acceleration G f (f the calibrated accelerometer)"
            if self.g_sensitivity is not None
            else " (G not determined by the mountings: not applied)"
        )
        return f"gyro corrected with the sensor's matrix and bias: ω = M⁻¹ (g − b){g}"


def gyro_correction_from(calibration: Mapping) -> GyroCorrection | None:
    """The gyro correction of a calibration document, or None when it has none."""
    block = calibration.get("gyro") or {}
    correction = block.get("correction")
    if not isinstance(correction, Mapping):
        return None
    try:
        g = block.get("g_sensitivity_radps_per_mps2")
        g_matrix = None
        if g is not None and all(v is not None for row in g for v in row):
            g_matrix = np.array(g, dtype=float)
        return GyroCorrection(
            matrix=np.array(correction["matrix"], dtype=float),
            bias_radps=np.array(correction["bias_radps"], dtype=float),
            response=np.array(block["matrix"], dtype=float),
            g_sensitivity=g_matrix,
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"the calibration's gyro correction is unusable ({exc})") from None


def why_no_gyro_correction(calibration: Mapping) -> str:
    """Why a calibration has no gyro correction (for the messages of apply and export)."""
    block = calibration.get("gyro")
    if not block:
        return "the calibration has no gyroscope"
    if "scale" in block:  # a session's block: one wheel axis
        return (
            "a session's calibration sees the gyro along its wheel axis only: the full matrix "
            "comes from a sensor's file pooled over three mountings (wheelcal batch)"
        )
    if block.get("matrix") is None:
        return "the pooled gyro fit has no matrix" + (
            f" ({'; '.join(block.get('warnings', []))})" if block.get("warnings") else ""
        )
    undetermined = block.get("undetermined") or []
    if undetermined:
        return f"{len(undetermined)} entries of the gyro's matrix are undetermined: " + str(
            undetermined[0].get("reason", "")
        )
    return "the gyro's bias is not determined"
