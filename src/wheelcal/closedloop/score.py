"""Score (Lagrange-multiplier) tests of candidate effects at a fitted model.

For effect parameters θ_e that are zero in the fitted model, the score test
needs only the fit itself: with whitened residual r̃ and Jacobian columns of
the free parameters (b) and of the effect (e),

    H = J̃ᵀJ̃ = [[H_bb, H_be], [H_eb, H_ee]],   g = J̃ᵀ r̃,
    C = H_ee − H_eb H_bb⁻¹ H_be            (information left after the fit),
    u = g_e − H_eb H_bb⁻¹ g_b,
    S = uᵀ C⁻¹ u  ~  χ²(k)  if the effect is absent.

The whitening is the fit's own noise model (AR colour, cross-axis
correlation), so coloured noise does not pose as an effect.  C⁻¹ is also the
Cramér–Rao bound of θ_e at the fit and −C⁻¹u the one-step estimate of its size.

An effect whose C is (nearly) singular — the fit's own parameters can mimic
it — cannot be identified from this recording: it is reported as such and
never tested or fitted into noise.  The fraction of its information left,
λ_min(D⁻½ C D⁻½) with D = diag(H_ee), measures that.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy import special

from wheelcal.closedloop.rest_stream import rest_normal, usable_rests
from wheelcal.estimate import RestSegment
from wheelcal.estimate.gyro import regress_gyro
from wheelcal.estimate.joint import (
    CHUNK_SAMPLES,
    CalibrationResult,
    GyroRests,
    NoiseModel,
    accumulate,
    accumulate_gyro,
    candidate_extra,
    gyro_effect,
    gyro_samples,
    lean_scores,
    quadrature_hessian,
    quadrature_rows,
    scaled_pinv,
    stride_for,
    whitened_back,
)
from wheelcal.model import (
    CalibrationParams,
    Effect,
    EvaluatedModel,
    GyroReading,
    ModelOutput,
    ParameterLayout,
    candidate_columns,
    evaluate,
    reverse_pass,
)
from wheelcal.recording import Recording

#: Below this fraction of its own information an effect counts as not identifiable.
IDENTIFIABLE_FRACTION = 1e-4
#: Rows per wheel turn of the screen's quadrature: a test's information needs ~1e-3, not
#: the 1e-5 of a reported σ (6 rows per turn move the statistics by < 0.2 % on Table I;
#: 3 rows by up to 7 %: ``tests/test_closed_loop_screen.py``).
SCREEN_ROWS_PER_TURN = 6.0


@dataclass(frozen=True, eq=False)
class ScoreTest:
    """The verdict on one candidate effect."""

    effect: Effect
    statistic: float
    dof: int
    p_value: float
    p_corrected: float
    identifiable: bool
    information_fraction: float
    estimate: np.ndarray  # one-step size of the effect parameters
    predicted_std: np.ndarray  # CRLB of the effect parameters at the fit
    #: What the test saw: "spin" (the accelerometer, and the gyro when there is one) or
    #: "spin+rests" (the rests around the window joined: :func:`screen`).
    streams: str = "spin"

    def as_dict(self) -> dict:
        """JSON-ready summary (non-finite numbers as None)."""

        def num(x):
            return float(x) if np.isfinite(x) else None

        names = self.effect.param_names
        return {
            "effect": self.effect.name,
            "label": self.effect.label(),
            "settings": self.effect.settings(),
            "statistic": num(self.statistic),
            "dof": self.dof,
            "p_value": num(self.p_value),
            "p_corrected": num(self.p_corrected),
            "identifiable": self.identifiable,
            "information_fraction": num(self.information_fraction),
            "estimate": dict(zip(names, map(num, self.estimate), strict=True)),
            "predicted_std": dict(zip(names, map(num, self.predicted_std), strict=True)),
            "streams": self.streams,
        }


def _candidate_columns(layout, candidates):
    """``extra`` callback: ∂v/∂θ_e of every candidate at the current parameters."""

    def extra(params: CalibrationParams, output: ModelOutput, t_s: np.ndarray) -> np.ndarray:
        return np.concatenate(
            [candidate_columns(params, t_s, layout, c, output) for c in candidates]
        )

    return extra


@dataclass(frozen=True, eq=False)
class ScoreContribution:
    """One recording's share of a score test: u (k,), C (k, k) and diag(H_ee) (k,)."""

    effect: Effect
    score: np.ndarray
    information: np.ndarray
    raw_information_diag: np.ndarray


@dataclass(frozen=True, eq=False)
class GyroStream:
    """The recording's gyroscope at a fit, for the score tests: a second, independent stream.

    ``layout`` is the fit's with the gyro's reading last and ``params`` its values
    (the fit's own when it fitted the gyro, else regressed on the fitted wheel rate
    with the prior on G: :func:`~wheelcal.estimate.gyro.block.regress_gyro`).
    """

    time_s: np.ndarray  # centred, usable samples only
    samples_radps: np.ndarray
    layout: ParameterLayout
    params: CalibrationParams
    noise: NoiseModel
    #: The gyro's readings at the rests, fitted or regressed on with the stream.
    rests: GyroRests | None = None


def gyro_stream(
    fit: CalibrationResult,
    recording: Recording,
    reading: GyroReading | None = None,
    rests: GyroRests | None = None,
) -> GyroStream | None:
    """The gyro stream of ``recording`` at ``fit``, or None (no usable gyroscope).

    ``reading``: the gyro's reading model (its prior on G) when the fit has none;
    ``rests``: the gyro's readings at the rests (the fit's own when it fitted them).
    """
    gyro = getattr(recording, "gyro_radps", None)
    if gyro is None or int(np.sum(np.all(np.isfinite(gyro), axis=1))) < 100:
        return None
    tc = recording.time_s - fit.centre_s
    gyro_t, samples = gyro_samples(recording, tc)
    if gyro_effect(fit.layout) is not None:
        return GyroStream(gyro_t, samples, fit.layout, fit.params, fit.gyro_noise, fit.gyro_rests)
    fitted = regress_gyro(fit, gyro_t, samples, reading=reading, rests=rests)
    return GyroStream(gyro_t, samples, fitted.layout, fitted.params, fitted.noise, rests)


def score_contributions(
    fit: CalibrationResult, recording: Recording, candidates: tuple[Effect, ...]
) -> list[ScoreContribution]:
    """The score u and information C of every candidate not yet in the fit's model.

    From the accelerometer's stream alone (:func:`_streams`); :func:`screen`, the
    closed loop's, adds the gyro's and the rests'.
    """
    candidates = _absent(fit, candidates)
    if not candidates:
        return []
    h, g, nuisance = _streams(fit, recording, candidates, None, None)
    return _schur(h, g, nuisance.size, candidates)


def _absent(fit: CalibrationResult, candidates: tuple[Effect, ...]) -> tuple[Effect, ...]:
    present = {e.name for e in fit.layout.effects}
    return tuple(c for c in candidates if c.name not in present)


def _unseen(fit: CalibrationResult, candidates: tuple[Effect, ...]) -> list[ScoreContribution]:
    """Candidates one recording cannot identify by construction, absent from the fit's model.

    Listed with no score and no information (a unit raw diagonal), never computed.
    """
    present = {e.name for e in fit.layout.effects}
    return [
        ScoreContribution(c, np.zeros(c.size), np.zeros((c.size, c.size)), np.ones(c.size))
        for c in candidates
        if not c.one_recording_identifies and c.name not in present
    ]


def _streams(
    fit: CalibrationResult,
    recording: Recording,
    candidates: tuple[Effect, ...],
    evaluated: EvaluatedModel | None,
    gyro: GyroStream | None,
) -> tuple[np.ndarray, np.ndarray, ParameterLayout]:
    """H and g of the accelerometer (and the gyro) over [nuisance | candidates], the nuisance.

    For the paper's model H comes by quadrature and g from every sample without a
    Jacobian (:func:`_normal_by_quadrature`); otherwise both are summed over every
    sample.  ``evaluated``: the model at the fit as its last pass left it.  With a
    ``gyro`` stream its information and score are added (:func:`_add_gyro`): the
    gyro's reading joins the fit's parameters, and a spin candidate (an imbalance's
    once-per-turn rate ripple) is seen by the gyro directly.
    """
    tc = recording.time_s - fit.centre_s
    stride = 1
    if not fit.layout.effects:
        stride = stride_for(
            tc, fit.params.spin, fit.noise.order, rows_per_turn=SCREEN_ROWS_PER_TURN
        )
    if stride > 1:
        h, g = _normal_by_quadrature(fit, recording, candidates, stride, evaluated)
    else:
        normal = accumulate(
            fit.params,
            tc,
            recording.accel_mps2,
            fit.layout,
            fit.noise,
            extra=_candidate_columns(fit.layout, candidates),
        )
        h, g = normal.hessian, normal.gradient
    if gyro is None:
        return h, g, fit.layout
    h, g = _embedded(h, g, fit.layout.size, gyro.layout.size)
    _add_gyro(fit, h, g, candidates, gyro)
    return h, g, gyro.layout


def _with_rests(fit, h, g, nuisance: ParameterLayout, rests, candidates):
    """H and g with the rests' stream: their angles join the nuisance parameters.

    The rests' static readings (:mod:`~wheelcal.closedloop.rest_stream`): a spin
    effect does not act at rest, so what it traded into the gains shows there.
    """
    size = nuisance.size
    h, g = _embedded(h, g, size, size + len(rests))
    h_rest, g_rest = rest_normal(fit, rests, candidates, nuisance)
    return h + h_rest, g + g_rest


def _schur(
    h: np.ndarray, g: np.ndarray, size: int, candidates: tuple[Effect, ...]
) -> list[ScoreContribution]:
    """Each candidate's score and information once the nuisance (the first ``size``) is fitted."""
    # The Schur complements of every candidate at once: A = H_eb H_bb⁻¹ (all rows), then
    # each candidate's own block of H_ee − A H_be and of g_e − A g_b.
    along = h[size:, :size] @ scaled_pinv(h[:size, :size])
    schur = h[size:, size:] - along @ h[:size, size:]
    score = g[size:] - along @ g[:size]
    out = []
    start = 0
    for cand in candidates:
        sl = slice(start, start + cand.size)
        start += cand.size
        own = np.diag(h[size:, size:][sl, sl]).copy()
        out.append(ScoreContribution(cand, score[sl], schur[sl, sl], own))
    return out


def screen(
    fit: CalibrationResult,
    recording: Recording,
    candidates: tuple[Effect, ...],
    evaluated: EvaluatedModel | None = None,
    gyro: GyroStream | None = None,
    rests: tuple[RestSegment, ...] = (),
) -> tuple[list[ScoreTest], list[ScoreTest]]:
    """The closed loop's two screens at ``fit``, Bonferroni-corrected over both together.

    1. The spin's streams (accelerometer, gyro): every candidate.
    2. The same with the rests joined (:mod:`~wheelcal.closedloop.rest_stream`), for the
       candidates that do not follow time — a rest lies outside the window where a
       warm-up's or a drift's law is known — and only while the model holds no such
       effect (the rests would then be judged by an extrapolated law).  Empty when
       there are no usable rests.

    The loop takes the first screen's best when it is significant, else the second's:
    a rest confirms what the spin cannot tell (an imbalance in the gains), it does not
    explain what the spin shows.
    """
    unseen = _unseen(fit, candidates)
    tested = _absent(fit, tuple(c for c in candidates if c.one_recording_identifies))
    if not tested:
        return finish_tests(unseen), []
    h, g, nuisance = _streams(fit, recording, tested, evaluated, gyro)
    plain = _schur(h, g, nuisance.size, tested)
    rests = usable_rests(fit, rests)
    static = [i for i, c in enumerate(tested) if not c.varies_in_time]
    if not rests or not static or any(e.varies_in_time for e in fit.layout.effects):
        return finish_tests(plain + unseen), []
    h2, g2 = _with_rests(fit, h, g, nuisance, rests, tested)
    at_rest = _schur(h2, g2, nuisance.size + len(rests), tested)
    both = finish_tests(plain + unseen + [at_rest[i] for i in static])
    first = len(plain) + len(unseen)
    return both[:first], [dataclasses.replace(t, streams="spin+rests") for t in both[first:]]


def _embedded(
    h: np.ndarray, g: np.ndarray, size: int, new_size: int
) -> tuple[np.ndarray, np.ndarray]:
    """H, g over [nuisance (``size``) | candidates] with zero rows inserted before the candidates.

    The nuisance block grows to ``new_size`` (another stream's own parameters).
    """
    total = new_size + (h.shape[0] - size)
    hh, gg = np.zeros((total, total)), np.zeros(total)
    rows = np.r_[0:size, new_size:total]
    hh[np.ix_(rows, rows)] = h
    gg[rows] = g
    return hh, gg


def _add_gyro(
    fit: CalibrationResult,
    hh: np.ndarray,
    gg: np.ndarray,
    candidates: tuple[Effect, ...],
    gyro: GyroStream,
) -> None:
    """Add the gyro stream's H and g to [the gyro layout's parameters | the candidates].

    The gyro layout is the fit's with the reading last.  The gyro stream's normal
    equations are accumulated over it with the spin candidates inserted before the
    reading (:func:`~wheelcal.estimate.joint.gyro_equations.accumulate_gyro`: a spin
    effect moves ω, which the gyro reads); sensor candidates do not act on it.
    The score is taken where the fit left the accelerometer's parameters and the
    regression the gyro's: Neyman's C(α) form u = g_e − H_eb H_bb⁻¹ g_b holds there.
    """
    nuisance = gyro.layout
    size = nuisance.size
    spin = [c for c in candidates if c.stage == "spin"]
    reading = gyro_effect(nuisance)
    others = tuple(e for e in nuisance.effects if e is not reading)
    layout = dataclasses.replace(nuisance, effects=(*others, *spin, reading))
    values = {**gyro.params.effects, **{c.name: np.zeros(c.size) for c in spin}}
    params = gyro.params.with_changes(effects=values)
    normal = accumulate_gyro(
        params, gyro.time_s, gyro.samples_radps, layout, gyro.noise, rests=gyro.rests
    )
    offsets, row = {}, size
    for cand in candidates:
        offsets[cand.name] = row
        row += cand.size
    position = {name: i for i, name in enumerate(nuisance.names)}
    index = []
    for name in layout.names:
        if name in position:
            index.append(position[name])
        else:  # a spin candidate's parameter: its place among the candidates
            effect, _, param = name.partition(".")
            cand = next(c for c in spin if c.name == effect)
            index.append(offsets[effect] + cand.param_names.index(param))
    index = np.array(index)
    hh[np.ix_(index, index)] += normal.hessian
    gg[index] += normal.gradient


def _normal_by_quadrature(
    fit: CalibrationResult,
    recording: Recording,
    candidates: tuple[Effect, ...],
    stride: int,
    evaluated: EvaluatedModel | None,
) -> tuple[np.ndarray, np.ndarray]:
    """H over [the fit's parameters | the candidates] by quadrature, g over every sample.

    H sums smooth functions of time (:mod:`~wheelcal.estimate.joint.fisher_quadrature`):
    the candidates' columns are formed at the quadrature's clusters only
    (:func:`~wheelcal.estimate.joint.candidate_columns.candidate_extra`).
    g = J̃ᵀr̃ is a sum of noise, taken over every sample without a Jacobian: the
    residual whitened back (u = WᵀW r), the fit's parameters by the model's reverse
    mode (both from the fit's own last gradient pass when it took one there:
    :func:`_reverse_at`), a sensor candidate as Σ (its column on its axis) · u
    (:func:`~wheelcal.estimate.joint.candidate_columns.lean_scores`), a spin candidate
    through the wheel angle's adjoint rows (:func:`~wheelcal.model.forward.spin_adjoint`).
    """
    params, layout, noise = fit.params, fit.layout, fit.noise
    tc = recording.time_s - fit.centre_s
    size = layout.size
    width = sum(c.size for c in candidates)
    grad = np.zeros(size + width)
    p = noise.order
    whole = None  # the model over the whole window (one chunk), for the clusters too
    for start in range(0, tc.size, CHUNK_SAMPLES):
        stop = min(tc.size, start + CHUNK_SAMPLES)
        lo = max(0, start - p)
        t = tc[lo:stop]
        output = evaluated.output_at(params, t) if evaluated is not None else None
        if output is None:
            output = evaluate(params, t, layout)
            data = recording.accel_mps2[lo:stop]
            u, base, adjoint = _reverse(params, t, layout, noise, data, output)
        else:  # the whole window
            data = recording.accel_mps2
            u, base, adjoint = _reverse_at(evaluated, params, t, layout, noise, data)
        if lo == 0 and stop == tc.size:
            whole = output
        grad[:size] += base
        scores = lean_scores(candidates, params, output, t, u)
        force = output.force
        row = size
        for cand, score in zip(candidates, scores, strict=True):
            if score is not None:
                grad[row : row + cand.size] += score
            elif cand.stage == "spin":
                rows = cand.own_rows(t, output.kinematics, force.sin_theta, force.cos_theta)
                grad[row : row + cand.size] += sum(
                    r @ a for r, a in zip(rows, adjoint, strict=True)
                )
            else:
                cols = candidate_columns(params, t, layout, cand, output)
                grad[row : row + cand.size] += cols.reshape(cand.size, -1) @ u.reshape(-1)
            row += cand.size
    rows = quadrature_rows(tc.size, noise.order, stride)
    extra = candidate_extra(candidates, layout)
    hess = quadrature_hessian(params, tc, layout, noise, rows, extra, whole)
    return hess, grad


def _reverse(params, t_s, layout, noise, accel_mps2, output):
    """The residual whitened back (u = Wᵀ W r), the fit's parameters' sums Jᵀu, ϑ's rows."""
    _, u = whitened_back(output.predicted_mps2 - accel_mps2, noise)
    return u, *reverse_pass(params, t_s, layout, u, output)


def _reverse_at(evaluated: EvaluatedModel, params, t_s, layout, noise, accel_mps2):
    """:func:`_reverse` over the whole window, from the fit's own gradient pass if it took one.

    The joint fit's last gradient pass at its result (its noise model, these samples)
    computed the very same sums (:class:`~wheelcal.model.forward.ReverseAt`).
    """
    kept = evaluated.reverse_for(noise, accel_mps2)
    if kept is None:
        return _reverse(params, t_s, layout, noise, accel_mps2, evaluated.output)
    return kept.weights, kept.gradient, kept.adjoint


def finish_tests(contributions: list[ScoreContribution]) -> list[ScoreTest]:
    """Statistics, p-values and Bonferroni correction from (summed) contributions.

    The small matrices of every candidate are handled as one stack, each padded to
    the largest size with an identity block (which leaves its λ_min ≤ 1, inverse,
    uᵀC⁻¹u and −C⁻¹u as they are): a dozen candidates cost a few numpy calls, not
    a few dozen.
    """
    if not contributions:
        return []
    c, u, d, sizes = _padded(contributions)
    # λ_min of D⁻½ C D⁻½ (information_fraction), all at once.
    fractions = np.maximum(np.linalg.eigvalsh(c / (d[:, :, None] * d[:, None, :]))[:, 0], 0.0)
    ok = fractions > IDENTIFIABLE_FRACTION
    tested = int(np.count_nonzero(ok))
    if tested:
        # The identifiable ones' inverses, statistics uᵀC⁻¹u and one-step sizes −C⁻¹u.
        c_inv = np.linalg.inv(c[ok])
        along = np.matmul(c_inv, u[ok][:, :, None])[:, :, 0]  # C⁻¹u
        stats = np.einsum("nk,nk->n", u[ok], along)
        predicted = np.sqrt(np.diagonal(c_inv, axis1=1, axis2=2))
        # The χ² survival function (what stats.chi2.sf returns, without its ~40 µs of checks).
        p_values = special.chdtrc(sizes[ok], stats)
    results = []
    j = 0
    for part, frac, identifiable in zip(contributions, fractions.tolist(), ok, strict=True):
        k = part.effect.size
        if not identifiable:
            nan, inf = np.full(k, np.nan), np.full(k, np.inf)
            results.append(ScoreTest(part.effect, np.nan, k, np.nan, np.nan, False, frac, nan, inf))
            continue
        stat, p = float(stats[j]), float(p_values[j])
        estimate, std = -along[j, :k], predicted[j, :k]
        j += 1
        results.append(
            ScoreTest(part.effect, stat, k, p, min(1.0, p * tested), True, frac, estimate, std)
        )
    return results


def _padded(contributions: list[ScoreContribution]):
    """C (n, K, K), u (n, K), √diag(H_ee) (n, K) padded to the largest size K; the sizes (n,)."""
    sizes = np.array([part.effect.size for part in contributions])
    n, width = sizes.size, int(sizes.max())
    c = np.zeros((n, width, width))
    c[:, range(width), range(width)] = 1.0
    u = np.zeros((n, width))
    d = np.ones((n, width))
    for i, part in enumerate(contributions):
        k = sizes[i]
        c[i, :k, :k] = part.information
        u[i, :k] = part.score
        d[i, :k] = np.sqrt(np.maximum(part.raw_information_diag, 1e-300))
    return c, u, d, sizes


def score_tests(
    fit: CalibrationResult, recording: Recording, candidates: tuple[Effect, ...]
) -> list[ScoreTest]:
    """Score-test every candidate (not already in the fit's model) at the fit.

    On the accelerometer's stream (:func:`score_contributions`).  What one recording
    cannot identify by construction (cross-axis coupling: the rotation spans it on one
    mounting) is listed with no information, not computed.
    """
    tested = tuple(c for c in candidates if c.one_recording_identifies)
    return finish_tests(score_contributions(fit, recording, tested) + _unseen(fit, candidates))


def pooled_score_tests(
    fits: list[CalibrationResult], recordings: list[Recording], candidates: tuple[Effect, ...]
) -> list[ScoreTest]:
    """One test per candidate of a parameter *shared* by all recordings.

    Under H₀ the per-recording scores are independent with covariances C_k, so
    S = (Σu_k)ᵀ (Σ C_k)⁻¹ (Σu_k) ~ χ²(k) — the candidate's own degrees of
    freedom, not their sum.  Each recording keeps its own bench, spin, offset
    and gain here (the conservative choice: nothing is assumed shared but the
    effect), so the test is valid whatever the other parameters do.
    """
    pooled: dict[str, ScoreContribution] = {}
    order: list[str] = []
    for fit, recording in zip(fits, recordings, strict=True):
        for part in score_contributions(fit, recording, candidates):
            key = part.effect.label()
            if key not in pooled:
                pooled[key] = part
                order.append(key)
            else:
                prev = pooled[key]
                pooled[key] = ScoreContribution(
                    part.effect,
                    prev.score + part.score,
                    prev.information + part.information,
                    prev.raw_information_diag + part.raw_information_diag,
                )
    return finish_tests([pooled[k] for k in order])
