"""One calibration per sensor, pooled from its sessions.

Each session of a sensor estimates the same six sensor parameters θ (three
gains, three offsets) with its own statistical σ and its own systematic σ.
Pooling gives the sensor's θ̂ with both, kept apart:

**Estimate.**  The joint sensor fit (:mod:`wheelcal.closedloop.sensor_fit`), when
there is one and it determines all six, is the maximum-likelihood θ̂ of all the
sessions' samples at once; otherwise the precision-weighted mean per
parameter k over the sessions i that determine it,

    θ̂_k = Σ_i w_ik x_ik / W_k,   w_ik = 1/(σ_ik² + τ_k²),   W_k = Σ_i w_ik,   σ_k = 1/√W_k.

τ_k² is the variance *between* sessions that their own σ do not contain
(DerSimonian–Laird: τ² = max(0, (Q − ν)/(W₀ − Σw₀²/W₀)) from the scatter Q of
the plain 1/σ² mean; 0 whenever the sessions agree within their σ, and then
this is the plain precision-weighted mean).  When something varies between
sessions, the sessions' own σ no longer rank how close each is to the sensor's
value: without τ², a session with a small σ would dominate a mean whose error
is mostly that variation, and the ±2σ coverage would fall to 84 % when the
sessions' σ differ by 2× (92–93 % with it).

**Statistical σ: checked against the spread.**  Per parameter,

    χ²_k = Σ_i w_ik (x_ik − x̄_k)²,   ν_k = n_k − 1,   s_k = max(1, √(χ²_k/ν_k)),

and the reported σ is s_k σ_k (the Birge ratio; for the weighted mean x̄ = θ̂).
Real sessions scatter more than their σ (the paper's offsets 3.5×: remounting,
temperature …), and this is where it shows.  For the joint fit, x̄ is the
1/σ² mean of the sessions of the same mounting and ν sums n_m − 1 over the
mountings: different mountings may differ for a reason the joint fit models
(cross-axis coupling), so only the scatter between sessions of one mounting is
unexplained.  With σ estimated from ν dof, θ̂_k ± 2 s_k σ_k covers the truth
like a Student t with ν dof: 92 % at ν = 9, 88 % at ν = 4 (``dof`` is
reported for that reason).

**Systematic σ: not averaged.**  Radius, gravity and sample-clock errors are
shared by the sessions of a bench, so they do not average away: the pooled
systematic σ is the weighted mean of the sessions' systematic σ (the
combination of fully correlated errors), never divided by √n.

**Undetermined parameters.**  A session that cannot determine a parameter
(value or σ null or infinite) is left out *for that parameter* and listed in
``skipped``; a parameter that no session determines is NaN with its reason in
``undetermined``, and the correction leaves that axis unchanged (gain 1,
offset 0).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import special

from wheelcal.model import GAIN_NAMES, OFFSET_NAMES, SensorCorrection

POOLED_PARAMETERS = (*GAIN_NAMES, *OFFSET_NAMES)
JOINT_FIT = "joint_sensor_fit"
WEIGHTED_MEAN = "precision_weighted_mean"
#: χ² upper-tail probability below which the scatter is called out in a warning.
SPREAD_WARNING_P = 0.01


def _frozen(values, shape) -> np.ndarray:
    out = np.array(values, dtype=float).reshape(shape)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class RecordingEstimate:
    """One recording's estimate of the sensor's parameters: the pooling's input.

    Parameters in the order :data:`POOLED_PARAMETERS`.

    NaN or ∞ in ``value`` or ``std`` marks a parameter the session cannot
    determine; ``reasons`` gives why, per parameter name, where known.
    """

    label: str
    value: np.ndarray
    std: np.ndarray
    systematic_std: np.ndarray
    mounting_id: str = ""
    covariance: np.ndarray | None = None
    reasons: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        n = len(POOLED_PARAMETERS)
        object.__setattr__(self, "value", _frozen(self.value, n))
        object.__setattr__(self, "std", _frozen(self.std, n))
        object.__setattr__(self, "systematic_std", _frozen(self.systematic_std, n))
        if self.covariance is not None:
            object.__setattr__(self, "covariance", _frozen(self.covariance, (n, n)))

    @property
    def determined(self) -> np.ndarray:
        """Per parameter: value and σ finite, σ > 0."""
        with np.errstate(invalid="ignore"):
            return np.isfinite(self.value) & np.isfinite(self.std) & (self.std > 0)


@dataclass(frozen=True, eq=False)
class JointEstimate:
    """The joint sensor fit's shared parameters (see :mod:`wheelcal.closedloop.sensor_fit`)."""

    value: np.ndarray
    std: np.ndarray
    converged: bool
    cross_axis_rad: np.ndarray | None = None  # (yx, zx, zy) when the mountings identify it
    effects: tuple[str, ...] = ()  # other shared effects it fitted (nonlinearity …)

    def __post_init__(self) -> None:
        n = len(POOLED_PARAMETERS)
        object.__setattr__(self, "value", _frozen(self.value, n))
        object.__setattr__(self, "std", _frozen(self.std, n))
        if self.cross_axis_rad is not None:
            object.__setattr__(self, "cross_axis_rad", _frozen(self.cross_axis_rad, 3))

    def unusable_because(self) -> str | None:
        """Why the pooled result cannot use this fit, or None when it can."""
        if not self.converged:
            return "the joint sensor fit did not converge"
        ok = np.isfinite(self.value) & np.isfinite(self.std) & (self.std > 0)
        if not np.all(ok):
            missing = [n for n, good in zip(POOLED_PARAMETERS, ok, strict=True) if not good]
            return f"the joint sensor fit does not determine {', '.join(missing)}"
        return None


@dataclass(frozen=True, eq=False)
class PooledSensor:
    """The sensor's pooled parameters, statistical and systematic σ apart.

    Arrays follow :data:`POOLED_PARAMETERS`.  ``std`` is the statistical σ
    after the spread check (``std_unscaled`` · ``scale``); ``covariance`` is
    its statistical covariance.  ``dof`` is the spread check's ν (0: nothing
    to check against).
    """

    method: str
    value: np.ndarray
    std: np.ndarray
    std_unscaled: np.ndarray
    systematic_std: np.ndarray
    covariance: np.ndarray
    chi2_red: np.ndarray
    between_session_std: np.ndarray  # τ: the scatter between sessions beyond their σ
    dof: np.ndarray
    scale: np.ndarray
    used: np.ndarray
    sessions: tuple[str, ...]
    skipped: tuple[tuple[str, str, str], ...] = ()  # (session, parameter, reason)
    undetermined: tuple[tuple[str, str], ...] = ()  # (parameter, reason)
    cross_axis_rad: np.ndarray | None = None
    warnings: tuple[str, ...] = ()
    names: tuple[str, ...] = field(default=POOLED_PARAMETERS)

    @property
    def total_std(self) -> np.ndarray:
        """√(statistical² + systematic²) per parameter."""
        return np.hypot(self.std, np.nan_to_num(self.systematic_std))

    def value_of(self, name: str) -> float:
        """Pooled value of one parameter (NaN when undetermined)."""
        return float(self.value[self.names.index(name)])

    def std_of(self, name: str) -> float:
        """Statistical σ of one parameter (after the spread check)."""
        return float(self.std[self.names.index(name)])

    def correction(self) -> SensorCorrection:
        """The correction a = M (v − b): b = o, M = (Γ (I + L))⁻¹; undetermined axes unchanged."""
        gain = np.where(np.isfinite(self.value[:3]), self.value[:3], 1.0)
        offset = np.where(np.isfinite(self.value[3:]), self.value[3:], 0.0)
        coupling = np.eye(3)
        if self.cross_axis_rad is not None:
            for value, (i, j) in zip(self.cross_axis_rad, ((1, 0), (2, 0), (2, 1)), strict=True):
                coupling[i, j] = value
        return SensorCorrection(bias_mps2=offset, matrix=np.linalg.inv(np.diag(gain) @ coupling))


def pool_sessions(
    sessions: Sequence[RecordingEstimate], joint: JointEstimate | None = None
) -> PooledSensor:
    """Pool the sessions of one sensor (see the module docstring)."""
    if not sessions:
        raise ValueError("pooling needs at least one session")
    n_par = len(POOLED_PARAMETERS)
    values = np.array([s.value for s in sessions])
    stds = np.array([s.std for s in sessions])
    determined = np.array([s.determined for s in sessions])
    variances = np.where(determined, stds, 1.0) ** 2
    plain = np.where(determined, 1.0 / variances, 0.0)
    used = determined.sum(axis=0)
    tau2 = _between_session_variance(values, plain, determined)
    weights = np.where(determined, 1.0 / (variances + tau2), 0.0)
    total = weights.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(used > 0, (weights * np.nan_to_num(values)).sum(axis=0) / total, np.nan)
        std = np.where(used > 0, 1.0 / np.sqrt(total), np.nan)
    warnings: list[str] = []
    method = WEIGHTED_MEAN
    cross_axis = None
    if joint is not None:
        why = joint.unusable_because()
        if why is None:
            method = JOINT_FIT
            mean, std = np.array(joint.value), np.array(joint.std)
            tau2 = np.zeros_like(tau2)
            weights, total = plain, plain.sum(axis=0)
            cross_axis = joint.cross_axis_rad
            left_out = [e for e in joint.effects if e != "cross_axis"]
            if left_out:
                warnings.append(
                    f"the joint sensor fit found {', '.join(left_out)}: the linear correction "
                    "(bias and matrix) cannot express it; see the sensor's .sensor.json"
                )
        else:
            warnings.append(f"{why}: pooled by the precision-weighted mean instead")
    groups = _spread_groups(sessions, method)
    chi2, dof = _spread(values, weights, determined, groups)
    with np.errstate(invalid="ignore", divide="ignore"):
        chi2_red = np.where(dof > 0, chi2 / np.maximum(dof, 1), np.nan)
    scale = np.where(dof > 0, np.sqrt(np.maximum(1.0, np.nan_to_num(chi2_red, nan=1.0))), 1.0)
    covariance = _weighted_covariance(sessions, weights, total, determined, tau2)
    if method == JOINT_FIT:
        covariance = np.diag(std**2)
    covariance = covariance * np.outer(scale, scale)
    systematic = _shared_systematic(sessions, weights)
    skipped, undetermined = _left_out(sessions, determined, used)
    if len(sessions) == 1:
        warnings.append(
            "one session: its σ cannot be checked against a spread over sessions; "
            "calibrate the sensor again to pool"
        )
    warnings += _spread_warnings(chi2_red, dof, scale)
    return PooledSensor(
        method=method,
        value=_frozen(np.where(used > 0, mean, np.nan), n_par),
        std=_frozen(np.where(used > 0, std * scale, np.nan), n_par),
        std_unscaled=_frozen(np.where(used > 0, std, np.nan), n_par),
        systematic_std=_frozen(systematic, n_par),
        covariance=_frozen(covariance, (n_par, n_par)),
        chi2_red=_frozen(chi2_red, n_par),
        between_session_std=_frozen(np.sqrt(tau2), n_par),
        dof=_frozen(dof, n_par).astype(int),
        scale=_frozen(scale, n_par),
        used=_frozen(used, n_par).astype(int),
        sessions=tuple(s.label for s in sessions),
        skipped=skipped,
        undetermined=undetermined,
        cross_axis_rad=cross_axis,
        warnings=tuple(warnings),
    )


def _spread_groups(sessions: Sequence[RecordingEstimate], method: str) -> list[list[int]]:
    """Sessions whose scatter σ must explain: all of them, or each mounting (joint fit)."""
    if method != JOINT_FIT:
        return [list(range(len(sessions)))]
    by_mounting: dict[str, list[int]] = defaultdict(list)
    for i, s in enumerate(sessions):
        by_mounting[s.mounting_id].append(i)
    return list(by_mounting.values())


def _spread(values, weights, determined, groups) -> tuple[np.ndarray, np.ndarray]:
    """χ² of the sessions about their group's weighted mean, and its dof, per parameter."""
    chi2 = np.zeros(values.shape[1])
    dof = np.zeros(values.shape[1])
    for group in groups:
        w = weights[group]
        x = np.nan_to_num(values[group])
        n = determined[group].sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            centre = (w * x).sum(axis=0) / w.sum(axis=0)
        chi2 += np.where(n > 1, (w * (x - np.nan_to_num(centre)) ** 2).sum(axis=0), 0.0)
        dof += np.maximum(n - 1, 0)
    return chi2, dof


def _between_session_variance(values, plain, determined) -> np.ndarray:
    """τ² per parameter (DerSimonian–Laird, method of moments; 0 when the sessions agree)."""
    w = plain
    x = np.nan_to_num(values)
    n = determined.sum(axis=0)
    total = w.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (w * x).sum(axis=0) / total
        q = (w * (x - np.nan_to_num(mean)) ** 2).sum(axis=0)
        denominator = total - (w**2).sum(axis=0) / total
        tau2 = (q - (n - 1)) / denominator
    return np.where((n > 1) & (denominator > 0) & np.isfinite(tau2), np.maximum(tau2, 0.0), 0.0)


def _weighted_covariance(sessions, weights, total, determined, tau2) -> np.ndarray:
    """Cov(θ̂_k, θ̂_l) = Σ_i w_ik w_il (C_i + diag τ²)[k, l] / (W_k W_l) (independent sessions)."""
    n_par = weights.shape[1]
    cov = np.zeros((n_par, n_par))
    for s, w, ok in zip(sessions, weights, determined, strict=True):
        c = s.covariance if s.covariance is not None else np.diag(np.where(ok, s.std, 0.0) ** 2)
        c = c + np.diag(tau2)
        both = np.outer(ok, ok)
        cov += np.where(both, np.outer(w, w) * np.nan_to_num(c, posinf=0.0, neginf=0.0), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return cov / np.outer(total, total)


def _shared_systematic(sessions, weights) -> np.ndarray:
    """Weighted mean of the sessions' systematic σ (fully correlated: not divided by √n)."""
    sys = np.array([s.systematic_std for s in sessions])
    known = np.isfinite(sys) & (weights > 0)
    w = np.where(known, weights, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(
            w.sum(axis=0) > 0, (w * np.nan_to_num(sys)).sum(axis=0) / w.sum(axis=0), np.nan
        )


def _left_out(sessions, determined, used):
    skipped, undetermined = [], []
    for k, name in enumerate(POOLED_PARAMETERS):
        reasons = []
        for s, ok in zip(sessions, determined[:, k], strict=True):
            if not ok:
                reason = dict(s.reasons).get(name, "value or σ null or infinite")
                skipped.append((s.label, name, reason))
                reasons.append(reason)
        if used[k] == 0:
            undetermined.append(
                (name, "no session determines it: " + "; ".join(dict.fromkeys(reasons)))
            )
    return tuple(skipped), tuple(undetermined)


def _spread_warnings(chi2_red, dof, scale) -> list[str]:
    out = []
    for name, c, nu, s in zip(POOLED_PARAMETERS, chi2_red, dof, scale, strict=True):
        if nu > 0 and np.isfinite(c) and c > 1 and special.chdtrc(nu, c * nu) < SPREAD_WARNING_P:
            out.append(
                f"{name}: the sessions scatter {s:.2g}× more than their σ (χ²_red {c:.3g}, "
                f"{int(nu)} dof): σ scaled by {s:.2g}; something varies between sessions that "
                "one recording cannot see (remounting, temperature, an unmodelled effect)"
            )
    return out
