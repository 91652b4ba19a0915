"""The correction a calibration hands to firmware or a ROS node.

Eq. (5) says v = o + Γ s; inverting it gives the specific force in the sensor
frame from a raw sample,

    a = M (v − b),   b = o,   M = Γ⁻¹,

which is the contract's ``correction`` block ("a = matrix @ (v - bias)").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, eq=False)
class SensorCorrection:
    """Bias (m/s²) and 3×3 matrix that turn raw samples into specific force."""

    bias_mps2: np.ndarray
    matrix: np.ndarray

    def __post_init__(self) -> None:
        bias = np.array(self.bias_mps2, dtype=float).reshape(3)
        matrix = np.array(self.matrix, dtype=float).reshape(3, 3)
        if not (np.all(np.isfinite(bias)) and np.all(np.isfinite(matrix))):
            raise ValueError("correction bias and matrix must be finite")
        if abs(np.linalg.det(matrix)) < 1e-6:
            raise ValueError("correction matrix is singular")
        bias.setflags(write=False)
        matrix.setflags(write=False)
        object.__setattr__(self, "bias_mps2", bias)
        object.__setattr__(self, "matrix", matrix)

    @classmethod
    def from_offset_gain(cls, offset_mps2, gain) -> SensorCorrection:
        """Invert eq. (5): b = o, M = Γ⁻¹."""
        return cls(bias_mps2=np.asarray(offset_mps2), matrix=np.diag(1.0 / np.asarray(gain)))

    def apply(self, raw_mps2: np.ndarray) -> np.ndarray:
        """Corrected samples, (N, 3)."""
        # Mᵀ C-ordered: an (N, 3) @ F-ordered (3, 3) product takes numpy's slow path.
        return (np.asarray(raw_mps2, dtype=float) - self.bias_mps2) @ np.ascontiguousarray(
            self.matrix.T
        )
