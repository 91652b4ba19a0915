"""Whether the fitted spin law describes the wheel's motion, asked turn by turn.

Eq. (2) holds for a free spin: ω(t) is smooth and slowly decaying.  A driven
wheel (a motor's speed changes, a second push, a very long spin) is followed
by no cubic, and then the joint fit trades the misfit into the sensor
parameters — a confident wrong answer.

The residual tells: around the fit, a phase error δϑ changes the data by
δϑ·∂v/∂ϑ, with ∂v/∂ϑ = g sinα·W(−sinϑ, cosϑ, 0) (W = ΓR).  Projecting the
residual on that direction over each whole turn gives one phase error per
turn, δϑ_j, with the once-per-turn terms (imbalance) averaged out.  Noise
makes them independent from turn to turn; a motion the spin law cannot
follow makes them *drift* slowly.  The von Neumann ratio

    η = Σ (δϑ_{j+1} − δϑ_j)² / Σ (δϑ_j − δϑ̄)²

is ≈ 2 for independent errors (standard deviation 2/√J over J turns) and
→ 0 for a slow drift, whatever the noise level — so the test needs no noise
model.  Its size is judged too: the slow part, √(var δϑ − ½ var Δδϑ), times
g sinα is the misfit in m/s² it leaves in the data, to be compared with the
sensor's noise floor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model import CalibrationParams, ParameterLayout, evaluate


@dataclass(frozen=True)
class MotionCheck:
    """Turn-by-turn phase errors of a fit, and whether they drift."""

    turns: int
    z_drift: float  # (2 − η)/(2/√J): ≫ 1 when the phase error drifts
    slow_phase_rms_rad: float
    slow_misfit_mps2: float  # g sinα × slow phase RMS

    def drifts(self, z_limit: float, floor_mps2: float, size_fraction: float) -> bool:
        """True when the drift is significant and not small against the noise floor."""
        return self.z_drift > z_limit and self.slow_misfit_mps2 > size_fraction * floor_mps2


def phase_errors(
    params: CalibrationParams,
    layout: ParameterLayout,
    t_centred_s: np.ndarray,
    residual_mps2: np.ndarray,
    weights: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """δϑ per whole turn (rad) and its σ from ``weights`` (1/σ² per axis)."""
    out = evaluate(params, t_centred_s, layout)
    theta = out.kinematics.theta_rad
    w_mat = params.sensor.gain[:, None] * params.bench.misalignment.matrix
    g_sin = out.force.g_sin_tilt
    d = g_sin * (
        -np.outer(np.sin(theta), w_mat[:, 0]) + np.outer(np.cos(theta), w_mat[:, 1])
    )  # ∂v/∂ϑ, (N, 3)
    turn = np.floor(np.abs(theta - theta[0]) / (2 * np.pi)).astype(int)
    full = turn < turn[-1]  # the last, partial turn is left out
    num = np.bincount(turn[full], weights=(residual_mps2[full] * d[full]) @ weights)
    den = np.bincount(turn[full], weights=(d[full] ** 2) @ weights)
    ok = den > 0
    return num[ok] / den[ok], 1.0 / np.sqrt(den[ok])


def check_motion(
    params: CalibrationParams,
    layout: ParameterLayout,
    t_centred_s: np.ndarray,
    residual_mps2: np.ndarray,
    floor_mps2: np.ndarray,
) -> MotionCheck:
    """Phase errors per turn of a fit and their drift statistics."""
    weights = 1.0 / np.maximum(np.asarray(floor_mps2, dtype=float), 1e-9) ** 2
    dtheta, _ = phase_errors(params, layout, t_centred_s, residual_mps2, weights)
    turns = dtheta.size
    if turns < 8:
        return MotionCheck(turns, 0.0, 0.0, 0.0)
    var = float(np.var(dtheta))
    diff_var = float(np.mean(np.diff(dtheta) ** 2))
    eta = diff_var / max(var, 1e-300)
    z = (2.0 - eta) / (2.0 / np.sqrt(turns))
    slow = float(np.sqrt(max(var - diff_var / 2, 0.0)))
    g_sin = params.gravity_mps2 * np.sin(params.bench.tilt_rad)
    return MotionCheck(turns, float(z), slow, float(g_sin * slow))
