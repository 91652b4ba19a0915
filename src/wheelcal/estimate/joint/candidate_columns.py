"""The columns ∂v/∂θ of candidate effects at θ = 0, leanly: for the closed loop's screen.

At zero a candidate changes nothing else, so only its own columns are needed
(:func:`~wheelcal.model.forward.candidate_columns`).  Most sensor effects act on
one axis per parameter (:meth:`~wheelcal.model.effects.Effect.axis_columns`): a
row per parameter instead of (3, N) mostly zeros.  The joint fit appends these
columns to its Fisher information's quadrature (``JointFit.screen``), and the
screen takes their score from every sample.
"""

from __future__ import annotations

import numpy as np

from wheelcal.model import (
    CalibrationParams,
    Effect,
    ModelOutput,
    OffsetWarmup,
    candidate_columns,
    spin_columns,
)


def candidate_extra(candidates: tuple[Effect, ...], layout):
    """The candidates' columns as an ``extra`` callback of the normal equations.

    It ``fills`` a buffer given as ``into`` (k, 3, N), e.g. the rows of a Jacobian's
    buffer after the free parameters' (no copy), or returns new columns.
    """

    def extra(
        params: CalibrationParams,
        output: ModelOutput,
        t_s: np.ndarray,
        into: np.ndarray | None = None,
    ) -> np.ndarray:
        if into is None:
            cols = np.zeros((extra.size, 3, t_s.size))
        else:
            cols = into
            cols[...] = 0.0
        row = 0
        table = lean_columns(candidates, params, output, t_s)
        force = output.force
        for cand, lean in zip(candidates, table, strict=True):
            here = cols[row : row + cand.size]
            if lean is None and cand.stage == "spin":  # written in place
                rows = cand.own_rows(t_s, output.kinematics, force.sin_theta, force.cos_theta)
                spin_columns(params, t_s, layout, rows, output, here)
            elif lean is None:
                here[...] = candidate_columns(params, t_s, layout, cand, output)
            else:
                values, axes = lean
                for k, axis in enumerate(axes):
                    cols[row + k, axis] = values[k]
            row += cand.size
        return cols

    extra.size = sum(c.size for c in candidates)
    extra.fills = True
    return extra


def lean_columns(
    candidates: tuple[Effect, ...], params: CalibrationParams, output: ModelOutput, t_s
) -> list:
    """Each candidate's lean per-axis columns (``axis_columns``), or None where it has none.

    A grid of warm-ups shares its exponentials (:func:`_warmup_decays`).
    """
    decays = _warmup_decays(candidates, t_s)
    out = []
    for cand in candidates:
        if type(cand) is OffsetWarmup:
            out.append((np.broadcast_to(1.0 - decays[cand.tau_s], (3, t_s.size)), (0, 1, 2)))
        else:
            lean = getattr(cand, "axis_columns", None)
            out.append(None if lean is None else lean(t_s, output.sensed_mps2, params.sensor.gain))
    return out


def lean_scores(
    candidates: tuple[Effect, ...],
    params: CalibrationParams,
    output: ModelOutput,
    t_s: np.ndarray,
    weights: np.ndarray,
) -> list:
    """Σ_n (lean column k at sample n) · w_n of each candidate (its ``axis_scores``), or None.

    The score's sums of :func:`lean_columns`'s columns for weights w (3, N), without
    forming them where an effect sums directly; a grid of warm-ups shares its
    exponentials as there.
    """
    decays = _warmup_decays(candidates, t_s)
    warm = {}
    if decays:  # Σ (1 − e^{−t/τ}) w of every τ in one product
        taus = list(decays)
        rises = np.empty((len(taus), t_s.size))
        for row, tau in enumerate(taus):
            np.subtract(1.0, decays[tau], out=rises[row])
        sums = weights @ rises.T  # (3, τs)
        warm = {tau: sums[:, j] for j, tau in enumerate(taus)}
    out = []
    for cand in candidates:
        if type(cand) is OffsetWarmup:
            out.append(warm[cand.tau_s])
        else:
            scores = getattr(cand, "axis_scores", None)
            sensed, gain = output.sensed_mps2, params.sensor.gain
            out.append(None if scores is None else scores(t_s, sensed, gain, weights))
    return out


def _warmup_decays(candidates: tuple[Effect, ...], t_s: np.ndarray) -> dict[float, np.ndarray]:
    """e^{−t/τ} of each warm-up's τ: for the longest τ, then squared down where τ halves.

    The default grid takes one exponential, not four.
    """
    warm = {c.tau_s for c in candidates if type(c) is OffsetWarmup}
    decays: dict[float, np.ndarray] = {}
    previous = None
    for tau in sorted(warm, reverse=True):
        if previous is not None and previous[0] == 2 * tau:
            decays[tau] = previous[1] * previous[1]
        else:
            decays[tau] = np.exp(-t_s / tau)
        previous = (tau, decays[tau])
    return decays
