"""Proper rotations: a validated value type, the exponential map, and Euler angles.

The misalignment R of eq. (4) maps a vector in the bench frame ⟨XYZ⟩ to the
same vector in the sensor frame ⟨xyz⟩: ``s = R a``.  Internally R is always a
3×3 rotation matrix; the optimiser moves it by a small rotation vector δ on the
right,

    R(δ) = R · exp([δ]×),

so there is no gimbal lock anywhere in the fit.  Euler angles exist only for
reporting, in the convention named by :data:`EULER_CONVENTION`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

EULER_CONVENTION = (
    "ZYX intrinsic (Tait-Bryan): R = Rz(euler_1) @ Ry(euler_2) @ Rx(euler_3); "
    "R maps bench -> sensor"
)


def hat(vector: np.ndarray) -> np.ndarray:
    """Skew matrix ``[v]×`` with ``[v]× w = v × w``; works on (..., 3) arrays."""
    v = np.asarray(vector, dtype=float)
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def exp_so3(rotvec: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues' formula)."""
    w = np.asarray(rotvec, dtype=float)
    angle = float(np.linalg.norm(w))
    k = hat(w)
    if angle < 1e-8:
        # Second-order Taylor expansion keeps the result orthogonal to ~1e-24.
        return np.eye(3) + k + 0.5 * (k @ k)
    return np.eye(3) + np.sin(angle) / angle * k + (1.0 - np.cos(angle)) / angle**2 * (k @ k)


def log_so3(matrix: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix (inverse of :func:`exp_so3`)."""
    m = np.asarray(matrix, dtype=float)
    cos_angle = np.clip((np.trace(m) - 1.0) / 2.0, -1.0, 1.0)
    angle = float(np.arccos(cos_angle))
    axis_term = np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    if angle < 1e-6:
        return 0.5 * axis_term
    if np.pi - angle < 1e-4:
        # Near 180°: sin(angle) vanishes, read the axis off the symmetric part.
        sym = (m + np.eye(3)) / 2.0
        axis = np.sqrt(np.clip(np.diag(sym), 0.0, None))
        pivot = int(np.argmax(axis))
        axis = sym[pivot] / axis[pivot]
        axis /= np.linalg.norm(axis)
        if axis @ axis_term < 0:
            axis = -axis
        return angle * axis
    return angle / (2.0 * np.sin(angle)) * axis_term


def _polar(m: np.ndarray) -> np.ndarray:
    """The nearest orthonormal matrix (polar decomposition), read-only: round-off never grows."""
    u, _, vt = np.linalg.svd(m)
    m = u @ vt
    m.setflags(write=False)
    return m


def _rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True, eq=False)
class Rotation:
    """A proper rotation (det = +1, RᵀR = I), validated at construction."""

    matrix: np.ndarray

    def __post_init__(self) -> None:
        m = np.array(self.matrix, dtype=float)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)):
            raise ValueError(f"a rotation is a finite 3x3 matrix, got shape {m.shape}")
        if not np.allclose(m.T @ m, np.eye(3), atol=1e-6) or np.linalg.det(m) < 0:
            raise ValueError("matrix is not a proper rotation (RᵀR ≠ I or det ≠ +1)")
        object.__setattr__(self, "matrix", _polar(m))

    @classmethod
    def composed(cls, matrix: np.ndarray) -> Rotation:
        """R from a product of rotations this code built (``R @ exp_so3(δ)``, ``R @ flip``, U Vᵀ).

        Re-orthonormalised as the constructor does (the same matrix, bit for bit),
        but not validated: a product of rotations is one.  The optimiser builds
        a dozen per calibration, where the validation's ``allclose`` and ``det``
        cost more than the rest.  Never for a matrix from outside (use the
        constructor).
        """
        rotation = object.__new__(cls)
        object.__setattr__(rotation, "matrix", _polar(np.array(matrix, dtype=float)))
        return rotation

    @classmethod
    def identity(cls) -> Rotation:
        """The identity rotation."""
        return cls(np.eye(3))

    @classmethod
    def from_euler_deg(cls, euler_1: float, euler_2: float, euler_3: float) -> Rotation:
        """Build R from the reporting Euler angles (see :data:`EULER_CONVENTION`)."""
        e1, e2, e3 = np.deg2rad([euler_1, euler_2, euler_3])
        return cls(_rot_z(e1) @ _rot_y(e2) @ _rot_x(e3))

    @classmethod
    def nearest(cls, matrix: np.ndarray) -> Rotation:
        """The proper rotation closest (Frobenius) to an arbitrary 3×3 matrix."""
        u, _, vt = np.linalg.svd(np.asarray(matrix, dtype=float))
        d = np.sign(np.linalg.det(u @ vt))
        return cls.composed(u @ np.diag([1.0, 1.0, d]) @ vt)  # a rotation by construction

    def euler_deg(self) -> np.ndarray:
        """Euler angles (deg) in :data:`EULER_CONVENTION`; unique for |euler_2| < 90°."""
        m = self.matrix
        e2 = np.arcsin(np.clip(-m[2, 0], -1.0, 1.0))
        if abs(np.cos(e2)) > 1e-9:
            e1 = np.arctan2(m[1, 0], m[0, 0])
            e3 = np.arctan2(m[2, 1], m[2, 2])
        else:  # gimbal lock in the *reporting* convention only
            e1 = np.arctan2(-m[0, 1], m[1, 1])
            e3 = 0.0
        return np.rad2deg(np.array([e1, e2, e3]))

    def euler_jacobian_deg(self) -> np.ndarray:
        """d(euler_deg)/dδ for the right perturbation R·exp([δ]×), a 3×3 matrix.

        Used only to carry covariances from the optimiser's δ to the reported
        angles.  With R = Rz(e₁) Ry(e₂) Rx(e₃), a change of the angles turns R by
        ω = E ė on the right, E = [[−s₂, 0, 1], [c₂s₃, c₃, 0], [c₂c₃, −s₃, 0]]
        (sᵢ = sin eᵢ, cᵢ = cos eᵢ), so dε/dδ = E⁻¹: rows (0, s₃/c₂, c₃/c₂),
        (0, c₃, −s₃), (1, s₂s₃/c₂, s₂c₃/c₂).  R's last row is (−s₂, c₂s₃, c₂c₃).
        Near gimbal lock (c₂ → 0, where E⁻¹ blows up) central differences of
        :meth:`euler_deg` instead.
        """
        _, m21, m22 = self.matrix[2].tolist()
        cos2_sq = m21 * m21 + m22 * m22
        if cos2_sq < 1e-6:
            return self._euler_jacobian_differences()
        cos2 = math.sqrt(cos2_sq)
        sin2 = -self.matrix[2, 0]
        sin3, cos3 = m21 / cos2, m22 / cos2
        inverse = [
            [0.0, sin3 / cos2, cos3 / cos2],
            [0.0, cos3, -sin3],
            [1.0, sin2 * sin3 / cos2, sin2 * cos3 / cos2],
        ]
        return np.rad2deg(np.array(inverse))

    def _euler_jacobian_differences(self) -> np.ndarray:
        step = 1e-6
        jac = np.empty((3, 3))
        for k in range(3):
            d = np.zeros(3)
            d[k] = step
            plus = self.perturbed(d).euler_deg()
            minus = self.perturbed(-d).euler_deg()
            diff = (plus - minus + 180.0) % 360.0 - 180.0
            jac[:, k] = diff / (2 * step)
        return jac

    def perturbed(self, delta_rad: np.ndarray) -> Rotation:
        """Right perturbation ``R · exp([δ]×)``."""
        return Rotation.composed(self.matrix @ exp_so3(delta_rad))

    def rotvec(self) -> np.ndarray:
        """Rotation vector (rad) of R."""
        return log_so3(self.matrix)

    def angle_to(self, other: Rotation) -> float:
        """Angle (rad) of the rotation taking this one to ``other``."""
        return float(np.linalg.norm(log_so3(self.matrix.T @ other.matrix)))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Rotation) and bool(np.array_equal(self.matrix, other.matrix))

    def __hash__(self) -> int:
        return hash(self.matrix.tobytes())
