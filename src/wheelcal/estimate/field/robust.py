"""σ that stay honest on a road: the sandwich, and the gyro's angle walk.

The joint fit's σ are the inverse Fisher information of its noise model —
stationary, coloured per axis.  A road's vibration is neither: it follows the
vehicle's speed, and it shakes along the world's vertical, which turns with the
wheel in the sensor's frame (its power on the in-plane axes swings at 2ϑ).  The
estimate stays consistent (the noise is zero-mean), but its spread is not what
the Fisher information says: on the simulated car drives the model's σ of the
offsets were 1.9× their spread.  Two parts make the reported covariance:

**The sandwich** ``C = H⁻¹ (M + Λ) H⁻¹``, ``H = J̃ᵀJ̃ + Λ``, with ``g_b = J̃_bᵀ r̃_b``
the whitened score summed over blocks b (longer than the noise's memory, at least
``MIN_BLOCKS`` of them) and ``M = Σ_b g_b g_bᵀ + Σ_{l=1..L} (1 − l/(L+1)) Σ_b (g_b
g_{b−l}ᵀ + g_{b−l} g_bᵀ)`` (Newey & West 1987: Bartlett weights, positive
semi-definite), the lags L spanning at least ``LAG_S`` and more where the blocks'
influences are correlated longer (Newey & West 1994's plug-in, :func:`influence_lags`):
it takes the spread from the residuals themselves (White 1982).  The plug-in is a
scalar's: each parameter's variance is the long-run variance of its own influence
f_b = (H⁻¹ g_b)_k at its own lags, the correlations those of the meat at the median
lags (:func:`own_lag_variances`).  On measured car drives the gains' and the radius's
block scores stay correlated for 5–20 s (on the simulator's, about 1 s): with one
second of lags the trial-to-trial z of the same sensors had an rms of 1.38, with the
median of the lags read from the data 1.27, with each parameter's own 1.24.  The lags matter
where the blocks are short (a 20 s wheelchair coast: 0.2 s, less than a turn): the
AR noise model cannot follow the road's peaked spectrum, and the whitened residual's neighbouring
blocks are anti-correlated at the wheel's turn — without them the wheelchair's σ
were 1.2–1.4× the spread of 100 drives.  Λ is the priors' information: a prior's
mean is off the truth by about its σ (a gyro's axes across the axle are 1 ± their
tolerance), so it adds to the meat as to the bread — without it the robot's gains
spread 2× their σ.

**Nuisances held.**  What the fit takes as measured but is known only to a prior —
the gyro's sensitivity to acceleration across the axle, which the yaw series
carries — is propagated: a shift Δ of the prediction (one σ of the nuisance, at
the fitted parameters) moves the fit by δp = H⁻¹ Σ_m J̃_mᵀ Δ̃_m, and δp δpᵀ joins
the covariance for each.  On wheelchair hubs (a slow wheel: the once-per-turn
rates it puts in the yaw pass its low-pass) the radius spread 1.3× its σ without.

**The gyro's angle walk.**  The wheel angle is the integrated gyro rate, taken as
measured; its white noise (density q) walks ϑ as a random walk, slow enough
that no residual block shows it.  Linearised, the fit answers an angle error
δϑ(t) with δp = H⁻¹ Σ_m J̃_mᵀ d̃_m δϑ(t_m) (d̃ the whitened ∂prediction/∂ϑ),
so with W(τ) = Σ_{t_m ≥ τ} w_m its covariance is q² Δt Σ_τ W(τ) W(τ)ᵀ.  On a
robot's wheel it is 1–2× the noise's σ of the camber and the axle axis's offset.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from wheelcal.estimate.joint import (
    CalibrationResult,
    covariance_from_fisher,
    effect_priors,
    report_transform,
    transform_covariance,
)
from wheelcal.model import CalibrationParams, ParameterLayout, evaluate

#: The score is summed over blocks of this many seconds …
BLOCK_S = 1.0
#: … shorter where the window would hold fewer blocks than this (a 20 s coast):
#: a meat of fewer blocks than parameters is rank-poor and its σ too small.
MIN_BLOCKS = 100
#: The meat's lags span at least this many seconds (a wheel's turn or two; Bartlett
#: weights), more where the blocks' own correlation says so (:func:`influence_lags`).
LAG_S = 1.0
#: The lags read from the data span at most this fraction of the blocks.
MAX_LAG_FRACTION = 0.2
#: Samples per evaluation (memory: P × 3 × this doubles).
_CHUNK = 20_000


@dataclasses.dataclass(frozen=True)
class _Pieces:
    """One pass over the window: H (priors in), the block scores, Λ and the angle's response.

    With an extended model (:class:`Extension`) also ``extended``: H, g and the meat over
    its parameters (priors in).
    """

    hess: np.ndarray
    prior_info: np.ndarray
    angle_score: np.ndarray  # (P, M): J̃_mᵀ d̃_m
    dt_s: float
    shift_score: np.ndarray  # (P, K): Σ_m J̃_mᵀ Δ̃_m of each nuisance's shift Δ
    block_scores: np.ndarray  # (P, B): g_b, in time order
    lags: np.ndarray  # (P,): each parameter's own lags (the meat's: their median)
    extended: WideNormal | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class WideNormal:
    """H, g and the sandwich's meat (priors in) of a wider model, in its parameters' order."""

    hess: np.ndarray
    grad: np.ndarray
    meat: np.ndarray


@dataclasses.dataclass(frozen=True, eq=False)
class Extension:
    """The fit's model with more parameters, all at zero (the result's prediction kept).

    ``index[k]`` is the extended vector's position of the fit's parameter k; the
    extension's own parameters are the rest, in order.
    """

    params: CalibrationParams
    layout: ParameterLayout
    index: np.ndarray

    @property
    def added(self) -> np.ndarray:
        """Positions of the extension's own parameters."""
        return np.setdiff1d(np.arange(self.layout.size), self.index)


def _pieces(
    result: CalibrationResult,
    accel_mps2: np.ndarray,
    shifts: tuple[np.ndarray, ...] = (),
    extension: Extension | None = None,
) -> _Pieces:
    params, layout, noise = result.params, result.layout, result.noise
    t = result.centred_time_s
    p = noise.order
    dt = float(np.median(np.diff(t)))
    window_s = float(t[-1] - t[0])
    block = max(p + 1, round(min(BLOCK_S, window_s / MIN_BLOCKS) / dt))
    size = layout.size
    phase = layout.blocks["spin"].start  # ϑ₀: its column is ∂prediction/∂ϑ at each sample
    hess = np.zeros((size, size))
    wide = extension.layout.size if extension is not None else 0
    hess_ext, grad_ext = np.zeros((wide, wide)), np.zeros(wide)
    sums, sums_ext = [], []
    angle = []
    shift_score = np.zeros((size, len(shifts)))
    for start in range(0, t.size, _CHUNK):
        stop = min(t.size, start + _CHUNK + p)
        if extension is None:
            out = evaluate(params, t[start:stop], layout, jacobian=True)
        else:  # the extension's columns besides the fit's (its prediction is the fit's)
            out = evaluate(extension.params, t[start:stop], extension.layout, jacobian=True)
        residual = out.predicted_mps2 - accel_mps2[start:stop]
        rw, jw_all = noise.whiten(residual, out.jacobian)  # (3, M), (P, 3, M)
        flat_all = jw_all.reshape(jw_all.shape[0], -1)
        gram = flat_all @ flat_all.T
        score = np.einsum("pim,im->pm", jw_all, rw)  # per whitened sample
        edges = np.arange(0, score.shape[1], block)
        block_sums = np.add.reduceat(score, edges, axis=1)  # (P, blocks)
        # The angle's and the shifts' sums over every column, the fit's taken after (no
        # copy of the fit's columns of J̃).
        index = extension.index if extension is not None else slice(None)
        phase_all = extension.index[phase] if extension is not None else phase
        angle_all = np.einsum("pim,im->pm", jw_all, jw_all[phase_all])
        if extension is not None:
            hess_ext += gram
            grad_ext += score.sum(axis=1)
            sums_ext.append(block_sums)
            gram, block_sums = gram[np.ix_(index, index)], block_sums[index]
        hess += gram
        sums.append(block_sums)
        angle.append(angle_all[index])
        if shifts:  # each shift whitened as J is, then J̃ᵀ Δ̃ of all of them in one product
            moved = np.stack([np.asarray(shift[start:stop], dtype=float).T for shift in shifts])
            _, moved_w = noise.whiten(residual, moved)
            flat_shifts = moved_w.reshape(len(shifts), -1)
            shift_score += (flat_all @ flat_shifts.T)[index]
        if stop == t.size:
            break
    prior = effect_priors(params, layout)
    info = np.zeros(size) if prior is None else prior[2]
    hess[np.arange(size), np.arange(size)] += info
    block_scores = np.concatenate(sums, axis=1)
    each = influence_lags(block_scores, hess)
    floor = round(LAG_S / (block * dt))
    live = each >= 0
    lags = max(floor, int(np.median(each[live]))) if np.any(live) else floor
    own = np.where(live, np.maximum(floor, each), lags)  # their median: lags
    extended = None
    if extension is not None:
        meat_ext = block_meat(np.concatenate(sums_ext, axis=1), lags=lags)
        prior = effect_priors(extension.params, extension.layout)
        if prior is not None:
            hess_ext[np.arange(wide), np.arange(wide)] += prior[2]
            grad_ext += prior[1]
            meat_ext[np.arange(wide), np.arange(wide)] += prior[2]
        extended = WideNormal(hess_ext, grad_ext, meat_ext)
    return _Pieces(
        hess,
        info,
        np.concatenate(angle, axis=1),
        dt,
        shift_score,
        block_scores,
        own,
        extended,
    )


def chosen_lags(sums: np.ndarray, hess: np.ndarray) -> int:
    """The meat's lags: the median over the parameters of :func:`influence_lags`."""
    each = influence_lags(sums, hess)
    return int(np.median(each[each >= 0])) if np.any(each >= 0) else 0


def influence_lags(sums: np.ndarray, hess: np.ndarray) -> np.ndarray:
    """Each parameter's lags, read from its blocks' own autocorrelation (Newey & West 1994).

    For each parameter, its blocks' influence f_b = (H⁻¹ g_b)_k: with its autocovariances
    σ_j up to the pilot lag n = ⌊4 (B/100)^(2/9)⌋, s₀ = σ₀ + 2 Σ σ_j and s₁ = 2 Σ j σ_j,
    its lags are ⌈1.1447 (s₁/s₀)^(2/3) B^(1/3)⌉, at most ``MAX_LAG_FRACTION`` of the
    blocks (−1 for a parameter the data do not determine; 0 for all under 8 blocks).  A
    white series gives few; a slow one — the score of the gains and the radius on
    measured car drives stays correlated for 5–20 s, about 1 s on the simulator's — more.
    """
    blocks = sums.shape[1]
    bread = covariance_from_fisher(hess)
    live = np.isfinite(np.diag(bread))
    if blocks < 8 or not np.any(live):
        return np.zeros(sums.shape[0], dtype=int)
    out = np.full(sums.shape[0], -1, dtype=int)
    f = np.where(np.isfinite(bread), bread, 0.0)[np.ix_(live, live)] @ sums[live]
    f = f - f.mean(axis=1, keepdims=True)
    pilot = int(4.0 * (blocks / 100.0) ** (2.0 / 9.0))
    cov = np.stack([np.sum(f[:, j:] * f[:, : blocks - j], axis=1) for j in range(pilot + 1)])
    s0 = cov[0] + 2.0 * cov[1:].sum(axis=0)
    s1 = 2.0 * np.sum(np.arange(1, pilot + 1)[:, None] * cov[1:], axis=0)
    ratio = np.where((s0 > 0) & (s1 > 0), s1 / np.where(s0 > 0, s0, 1.0), 0.0)
    each = np.ceil(1.1447 * ratio ** (2.0 / 3.0) * blocks ** (1.0 / 3.0))
    out[live] = np.minimum(each, int(MAX_LAG_FRACTION * blocks))
    return out


def own_lag_variances(influence: np.ndarray, lags: np.ndarray) -> np.ndarray:
    """Each row's long-run variance Σ_b f_b² + 2 Σ_{l=1..L} (1 − l/(L+1)) Σ_b f_b f_{b−l}.

    ``influence`` (P, B): each parameter's block influence f_b = (H⁻¹ g_b)_k; ``lags``
    (P,): its own L — the diagonal of H⁻¹ M H⁻¹ with each parameter's meat at its lags.
    """
    out = np.einsum("pb,pb->p", influence, influence)
    blocks = influence.shape[1]
    for lag in range(1, min(int(lags.max(initial=0)), blocks - 1) + 1):
        weight = np.where(lags >= lag, 1.0 - lag / (lags + 1.0), 0.0)
        out += 2.0 * weight * np.einsum("pb,pb->p", influence[:, lag:], influence[:, :-lag])
    return out


def block_meat(sums: np.ndarray, lags: int) -> np.ndarray:
    """Σ_b g_b g_bᵀ plus the Bartlett-weighted lags 1…``lags`` (module docstring).

    ``sums`` (P, B): the score summed over each block, in time order.
    """
    meat = sums @ sums.T
    for lag in range(1, min(lags, sums.shape[1] - 1) + 1):
        cross = sums[:, lag:] @ sums[:, :-lag].T
        meat += (1.0 - lag / (lags + 1.0)) * (cross + cross.T)
    return meat


def _in_reported(result: CalibrationResult, cov: np.ndarray) -> np.ndarray:
    _, _, g = report_transform(result.params, result.layout)
    return transform_covariance(g, cov)


def _bread(pieces: _Pieces) -> tuple[np.ndarray, np.ndarray]:
    bread = covariance_from_fisher(pieces.hess)
    finite = np.isfinite(np.diag(bread))
    return np.where(np.isfinite(bread), bread, 0.0), finite


def _with_undetermined(cov: np.ndarray, finite: np.ndarray) -> np.ndarray:
    cov[~finite, :] = np.nan
    cov[:, ~finite] = np.nan
    cov[~finite, ~finite] = np.inf
    return cov


def _sandwich(pieces: _Pieces, bread: np.ndarray) -> np.ndarray:
    """C = H⁻¹ (M + Λ) H⁻¹ (module docstring), in the fit's own parameters."""
    return sandwich_covariance(bread, pieces.block_scores, pieces.lags, pieces.prior_info)


def sandwich_covariance(
    bread: np.ndarray, block_scores: np.ndarray, own_lags: np.ndarray, prior_info: np.ndarray
) -> np.ndarray:
    """H⁻¹ (M + Λ) H⁻¹: each parameter's variance at its own lags, the correlations at theirs.

    ``bread`` (P, P) H⁻¹ (undetermined rows zero), ``block_scores`` (P, B) g_b in time
    order, ``own_lags`` (P,) each parameter's lags (the meat M takes their median),
    ``prior_info`` (P,) Λ's diagonal.
    """
    lags = int(np.median(own_lags))
    prior = bread @ np.diag(prior_info) @ bread
    cov = bread @ block_meat(block_scores, lags=lags) @ bread + prior
    own = own_lag_variances(bread @ block_scores, own_lags) + np.diag(prior)
    diag = np.diag(cov)
    ratio = np.clip(own, 0.0, None) / np.where(diag > 0, diag, 1.0)
    scale = np.where(diag > 0, np.sqrt(ratio), 1.0)
    return scale[:, None] * cov * scale[None, :]


def _angle_walk(pieces: _Pieces, bread: np.ndarray, density: float) -> np.ndarray:
    """q² Δt Σ_τ W(τ) W(τ)ᵀ, W(τ) = Σ_{t_m ≥ τ} H⁻¹ J̃_mᵀ d̃_m (module docstring)."""
    tail = np.cumsum((bread @ pieces.angle_score)[:, ::-1], axis=1)
    return density**2 * pieces.dt_s * (tail @ tail.T)


def angle_walk_covariance(
    result: CalibrationResult, accel_mps2: np.ndarray, gyro_density: float
) -> np.ndarray:
    """The gyro's angle walk alone, q² Δt Σ_τ W(τ) W(τ)ᵀ, in the reported parameters."""
    pieces = _pieces(result, accel_mps2)
    bread, finite = _bread(pieces)
    walk = _angle_walk(pieces, bread, gyro_density)
    return _in_reported(result, _with_undetermined(walk, finite))


def robust_result(
    result: CalibrationResult,
    accel_mps2: np.ndarray,
    gyro_density: float | None = None,
    shifts: tuple[np.ndarray, ...] = (),
) -> CalibrationResult:
    """``result`` with the sandwich's covariance plus the gyro's angle walk (module docstring).

    ``gyro_density`` q (rad/s/√Hz) of the rate the angle integrates; None: no walk.
    ``shifts``: each (N, 3), what a nuisance the fit holds (one σ of it) changes in the
    prediction at the fitted parameters — its covariance joins (module docstring).
    """
    return robust_result_with(result, accel_mps2, gyro_density, shifts).result


@dataclasses.dataclass(frozen=True, eq=False)
class RobustPass:
    """:func:`robust_result_with`'s answer: the result with its covariance, and what it used.

    ``shift_covariance``: the held nuisances' share (Σ δp δpᵀ of the shifts given), in the
    reported parameters (None without shifts); ``extended``: the wider model's normal
    equations (None without an extension).
    """

    result: CalibrationResult
    extended: WideNormal | None
    shift_covariance: np.ndarray | None


def robust_result_with(
    result: CalibrationResult,
    accel_mps2: np.ndarray,
    gyro_density: float | None = None,
    shifts: tuple[np.ndarray, ...] = (),
    extension: Extension | None = None,
) -> RobustPass:
    """:func:`robust_result`, the shifts' share of it, and H and g of a wider model.

    ``extension``: the wider model (its :class:`WideNormal`; None without one), for a
    Hausman check of what it would move.
    """
    pieces = _pieces(result, accel_mps2, shifts, extension)
    bread, finite = _bread(pieces)
    cov = _sandwich(pieces, bread)
    if gyro_density is not None and gyro_density > 0:
        cov = cov + _angle_walk(pieces, bread, gyro_density)
    shifted = None
    if shifts:
        response = bread @ pieces.shift_score  # (P, K): the fit's answer to each shift
        shifted = response @ response.T
        cov = cov + shifted
        shifted = _in_reported(result, _with_undetermined(shifted, finite))
    covariance = _in_reported(result, _with_undetermined(cov, finite))
    robust = dataclasses.replace(result, covariance=covariance)
    return RobustPass(robust, pieces.extended, shifted)
