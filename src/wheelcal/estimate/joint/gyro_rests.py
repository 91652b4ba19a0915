"""The gyroscope at rest: static readings of its bias and its sensitivity to the force.

Before the push and after the stop the wheel stands still.  There the gyro
reads ω = b + G_X a_X + G_Y a_Y (:class:`~wheelcal.model.effects.GyroReading`
with ω = 0), where a = Rᵀ Γ⁻¹ (v̄ − o) is the force in the wheel frame that the
accelerometer's rest mean v̄ shows.  Each rest's gyro mean is then one more
observation of the reading's b and G, three rows that join the gyro stream's
normal equations (:func:`~wheelcal.estimate.joint.gyro_equations.accumulate_gyro`).

Why it matters: on an unbalanced wheel the imbalance ripples the rate once per
turn, and so does G·a (a's in-plane part turns with the wheel); only the
imbalance's 1/ω law tells them apart, and G's prior (0.1 °/s/g) leaves them
trading.  A rest pins b + G·a_rest to a few thousandths of a °/s.  Both rests
of an unbalanced wheel sit at about the same angle (heavy side down), so they
pin one direction of G in the wheel plane, not both: on the 46° bench the
bound of gain_z with an imbalance falls from 2.3× to 1.75× the clean bound.

The σ of each mean is the gyro's noise over the rest / √n with a floor,
:data:`REST_FLOOR_DPS`, for what moves the bias between a rest and the spin
(warm-up; the Earth's rate, ≤ 0.004 °/s, which the spin averages out of the
wheel plane).  a is formed with the sensor's base model (an offset warm-up of
0.1 m/s² moves G·a by ~0.001 °/s, under the floor) and held fixed in the
Jacobian: its derivatives through R, Γ and o carry ~10⁻⁶ of the
accelerometer's information on them.  Rests that disagree with each other
beyond their σ (and G's prior over their different forces) are not used: the
bias moved between them.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wheelcal.model import CalibrationParams

#: Floor on the σ of a rest's gyro mean (°/s): the bias may move between a rest and the spin.
REST_FLOOR_DPS = 0.02
#: Two rests whose gyro means differ by more than this many σ are not used.
DISAGREE_SIGMA = 4.0


@dataclass(frozen=True, eq=False)
class GyroRests:
    """The rests' means, accelerometer (m/s²) and gyro (rad/s), and each gyro mean's σ."""

    accel_mps2: np.ndarray  # (k, 3)
    gyro_radps: np.ndarray  # (k, 3)
    std_radps: np.ndarray  # (k, 3)

    @classmethod
    def of(
        cls, rests: Sequence, g_prior_std_radps_per_mps2: float | None = None
    ) -> GyroRests | None:
        """The rests with a gyro mean, or None (none, or they disagree: see :func:`agree`)."""
        usable = [r for r in rests if getattr(r, "gyro_mean_radps", None) is not None]
        if not usable:
            return None
        floor = np.deg2rad(REST_FLOOR_DPS)
        out = cls(
            accel_mps2=np.array([r.mean_mps2 for r in usable], dtype=float),
            gyro_radps=np.array([r.gyro_mean_radps for r in usable], dtype=float),
            std_radps=np.array(
                [np.hypot(r.gyro_mean_std_radps, floor) for r in usable], dtype=float
            ),
        )
        return out if out.agree(g_prior_std_radps_per_mps2) else None

    @property
    def count(self) -> int:
        """How many rests."""
        return int(self.gyro_radps.shape[0])

    def agree(self, g_prior_std_radps_per_mps2: float | None = None) -> bool:
        """Every two rests' gyro means within :data:`DISAGREE_SIGMA` σ of each other.

        σ of a difference: both means' σ and, with a prior on G, σ_G times the
        difference of their forces (G·a differs between rests at other angles).
        """
        g_std = g_prior_std_radps_per_mps2 or 0.0
        for i, j in itertools.combinations(range(self.count), 2):
            force = float(np.linalg.norm(self.accel_mps2[i] - self.accel_mps2[j]))
            std = np.sqrt(self.std_radps[i] ** 2 + self.std_radps[j] ** 2 + (g_std * force) ** 2)
            if np.any(np.abs(self.gyro_radps[i] - self.gyro_radps[j]) > DISAGREE_SIGMA * std):
                return False
        return True

    def forces_mps2(self, params: CalibrationParams) -> np.ndarray:
        """The force a = Rᵀ Γ⁻¹ (v̄ − o) of each rest in the wheel frame, (k, 3), at ``params``."""
        return params.static_force_mps2(self.accel_mps2)

    def normal_terms(
        self, params: CalibrationParams, values: np.ndarray, g_sensitivity: bool
    ) -> tuple[float, np.ndarray, np.ndarray]:
        """Cost, gradient and Gram of the whitened rest rows over the reading's ``values``.

        ``values``: the reading's parameters (w, b, and G_X, G_Y with
        ``g_sensitivity``); the gradient and Gram are over all of them (w's
        entries stay zero: a wheel at rest shows no scale).
        """
        values = np.asarray(values, dtype=float)
        force = self.forces_mps2(params)
        predicted = np.broadcast_to(values[3:6], self.gyro_radps.shape).copy()
        if g_sensitivity:
            predicted += np.outer(force[:, 0], values[6:9]) + np.outer(force[:, 1], values[9:12])
        weight = 1.0 / self.std_radps**2  # (k, 3)
        residual = predicted - self.gyro_radps
        cost = float(np.sum(weight * residual**2))
        size = values.size
        grad = np.zeros(size)
        gram = np.zeros((size, size))
        # Axis i's rows depend on b_i, G_X,i and G_Y,i only, with partials (1, a_X, a_Y).
        partials = np.column_stack([np.ones(self.count), force[:, 0], force[:, 1]])
        blocks = 3 if g_sensitivity else 1
        for i in range(3):
            rows = np.array([3 + i, 6 + i, 9 + i])[:blocks]
            d = partials[:, :blocks]
            grad[rows] += d.T @ (weight[:, i] * residual[:, i])
            gram[np.ix_(rows, rows)] += d.T @ (weight[:, i, None] * d)
        return cost, grad, gram
