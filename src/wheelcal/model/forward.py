"""The observation model v(t) = o + Γ R a(t) (eq. 6) and its analytic Jacobian.

For a free-parameter layout (see :mod:`wheelcal.model.layout`) the Jacobian
is stored *transposed*, ``jacobian[p, i, n] = ∂v_i(t_n)/∂x_p`` with shape
(P, 3, N): every row is contiguous, which keeps filtering and JᵀJ fast.
With W = Γ R and a(t) from eq. (1):

* spin coefficient p:   W[:,0]·(−g sinα sinϑ ∂ϑ/∂p + 2rω ∂ω/∂p)
                       + W[:,1]·( g sinα cosϑ ∂ϑ/∂p + r ∂ω̇/∂p)
* tilt α:               W ∂a/∂α
* radius r:             W ∂a/∂r
* rotation δ_k:         Γ R (e_k × a)          (right perturbation R·exp([δ]×))
* gain γ_i:             e_i s_i,   s = R a
* offset o_i:           e_i

Effects of stage ``force`` (:class:`~wheelcal.model.rolling.Rolling`) add Δa
to the bench-frame force before R; their partials w.r.t. ϑ, ω, ω̇ chain into
the spin rows, and R, Γ then act on the total a.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from wheelcal.model.bench import (
    BenchForce,
    bench_force,
    d_force_d_gravity,
    d_force_d_radius,
    d_force_d_tilt,
)
from wheelcal.model.kinematics import Kinematics, spin_kinematics, spin_partials
from wheelcal.model.layout import ParameterLayout
from wheelcal.model.parameters import CalibrationParams


@dataclass(frozen=True, eq=False)
class ModelOutput:
    """Predicted samples (N, 3) in m/s² and, if asked for, ∂v/∂x as (P, 3, N)."""

    predicted_mps2: np.ndarray
    jacobian: np.ndarray | None
    kinematics: Kinematics
    force: BenchForce
    sensed_mps2: np.ndarray
    #: ∂Δa/∂r (N, 3) of the force-stage effects (with a Jacobian), for the radius' budget.
    force_by_radius: np.ndarray | None = None
    #: The effects' share of ∂v/∂α (3, N) (with a Jacobian; tilt-aware effects only),
    #: for the tilt's budget when α is held.
    effects_by_tilt: np.ndarray | None = None


def output_at_samples(output: ModelOutput, index: np.ndarray) -> ModelOutput:
    """The paper's model evaluated (no Jacobian) at some of ``output``'s samples.

    Every quantity is per sample (ϑ, ω, ω̇, the bench force, s, v), so taking them
    gives what :func:`evaluate` computes there, for :func:`evaluate`'s ``output``.
    """
    if output.jacobian is not None or output.force_by_radius is not None:
        raise ValueError("output_at_samples takes the paper's model without a Jacobian")
    kin, force = output.kinematics, output.force
    return ModelOutput(
        output.predicted_mps2[index],
        None,
        Kinematics(kin.theta_rad[index], kin.omega_radps[index], kin.omega_dot_radps2[index]),
        BenchForce(
            force.accel_mps2[index],
            force.sin_theta[index],
            force.cos_theta[index],
            force.g_sin_tilt,
            force.g_cos_tilt,
        ),
        output.sensed_mps2[index],
    )


@dataclass(frozen=True, eq=False)
class EvaluatedModel:
    """The model (no Jacobian) at ``params`` and times ``t_s``, kept for a later pass there.

    A fit's last pass evaluates the model at its result; a check at that very
    point (the motion check) then forms the Jacobian from its ϑ, ω, ω̇ and bench
    force (:func:`evaluate` with ``output``) instead of evaluating them again.
    Keyed by the parameter object itself and the times' values: any other point
    gets nothing.  Its callers keep it for windows of one chunk only (memory).
    """

    params: CalibrationParams
    t_s: np.ndarray
    output: ModelOutput
    #: The reverse mode the last pass took there (a gradient pass), when it took one.
    reverse: ReverseAt | None = None

    def output_at(self, params: CalibrationParams, t_s: np.ndarray) -> ModelOutput | None:
        """The kept output if it was evaluated at ``params`` itself and these times, else None."""
        if params is not self.params or t_s.shape != self.t_s.shape:
            return None
        return self.output if np.array_equal(t_s, self.t_s) else None

    def reverse_for(self, *made_of: object) -> ReverseAt | None:
        """The kept reverse pass if its weights were made of ``made_of`` themselves, else None.

        E.g. ``(noise model, samples)``: the very objects, not equal ones.
        """
        reverse = self.reverse
        if reverse is None or len(made_of) != len(reverse.made_of):
            return None
        same = all(a is b for a, b in zip(made_of, reverse.made_of, strict=True))
        return reverse if same else None


@dataclass(frozen=True, eq=False)
class ReverseAt:
    """:func:`reverse_pass` at an :class:`EvaluatedModel`, with the weights it took.

    A fit's gradient pass at its result (weights u = Wᵀ W r: the residual whitened
    back) is what a score test there needs again: the fit's parameters' sums, the
    wheel angle's adjoint rows and u itself (a sensor effect's score is Σ column · u).
    ``made_of`` holds what made the weights (the fit's noise model and samples): a
    reuser checks that they are its own (:meth:`EvaluatedModel.reverse_for`).
    """

    weights: np.ndarray  # (3, N)
    gradient: np.ndarray  # (P,) Σ_n ∂v_n/∂x · w_n
    adjoint: np.ndarray  # (3, N) :func:`spin_adjoint` rows
    made_of: tuple[object, ...]


def _apply_spin_effect(
    effect, values: np.ndarray, t: np.ndarray, kin: Kinematics, jacobian: bool, tilt_rad: float
) -> Kinematics:
    """Add a spin effect to ϑ, ω, ω̇; chain its partials into the existing rows, append its own.

    An effect that depends on the tilt (``uses_tilt``) gets it, and its ∂/∂α rows
    add to the kinematics' ``d_tilt``.
    """
    if getattr(effect, "uses_tilt", False):
        d = effect.spin_delta(values, t, kin, jacobian, tilt_rad=tilt_rad)
    else:
        d = effect.spin_delta(values, t, kin, jacobian)
    theta = kin.theta_rad + d.theta
    omega = kin.omega_radps + d.omega
    omega_dot = kin.omega_dot_radps2 + d.omega_dot
    if not jacobian:
        return Kinematics(theta, omega, omega_dot)
    rows = [kin.d_theta.copy(), kin.d_omega.copy(), kin.d_omega_dot.copy()]
    d_tilt = None if kin.d_tilt is None else kin.d_tilt.copy()
    for partials, base in ((d.by_theta, kin.d_theta), (d.by_omega, kin.d_omega)):
        if partials is not None:
            for k in range(3):
                rows[k] += partials[k] * base
    for partials, k_base in ((d.by_theta, 0), (d.by_omega, 1)):
        if partials is not None and d_tilt is not None:
            base_row = kin.d_tilt[k_base].copy()
            for k in range(3):
                d_tilt[k] += partials[k] * base_row
    by_tilt = getattr(d, "by_tilt", None)
    if by_tilt is not None:
        d_tilt = np.array(by_tilt) if d_tilt is None else d_tilt + np.array(by_tilt)
    own = (d.d_own_theta, d.d_own_omega, d.d_own_omega_dot)
    rows = [np.vstack([r, o]) for r, o in zip(rows, own, strict=True)]
    return Kinematics(theta, omega, omega_dot, *rows, d_tilt=d_tilt)


def _sensor_w(gain: np.ndarray, rot: np.ndarray, terms: list) -> np.ndarray:
    """W = ∂v/∂s · R as (3, 3, 1) for the paper's sensor, (3, 3, N) with sensor effects."""
    extra_ds = [term.d_sensed for term in terms if term.d_sensed is not None]
    if not extra_ds:
        return (gain[:, None] * rot)[:, :, None]
    dv_ds = np.diag(gain)[None] + sum(extra_ds)
    return np.einsum("nij,jk->ikn", dv_ds, rot)


def _spin_rows_to_v(
    w3: np.ndarray, force: BenchForce, kin_rows, omega, radius_m, out: np.ndarray | None = None
) -> np.ndarray:
    """dv/dp (rows, 3, N) of parameters acting through (∂ϑ, ∂ω, ∂ω̇)/∂p rows.

    ∂a_X/∂p = −g sinα sinϑ ∂ϑ/∂p + 2rω ∂ω/∂p and ∂a_Y/∂p = g sinα cosϑ ∂ϑ/∂p + r ∂ω̇/∂p,
    then dv/dp = W[:,0] ∂a_X/∂p + W[:,1] ∂a_Y/∂p (written into ``out`` when given).
    """
    d_theta, d_omega, d_omega_dot = kin_rows
    # (∂a_X, ∂a_Y) of each row side by side, so that W[:, :2] maps them to the three
    # axes in one batched product (one pass, not three scaled copies and adds).
    partials = np.empty((d_theta.shape[0], 2, d_theta.shape[1]))
    dax, day = partials[:, 0, :], partials[:, 1, :]
    np.multiply(d_theta, -force.g_sin_tilt * force.sin_theta, out=dax)
    dax += d_omega * ((2 * radius_m) * omega)
    np.multiply(d_theta, force.g_sin_tilt * force.cos_theta, out=day)
    day += radius_m * d_omega_dot
    if out is None:
        out = np.empty((d_theta.shape[0], 3, d_theta.shape[1]))
    if w3.shape[2] == 1:
        return np.matmul(w3[:, :2, 0], partials, out=out)
    for i in range(3):  # W per sample (sensor effects)
        row = out[:, i, :]
        np.multiply(dax, w3[i, 0], out=row)
        row += w3[i, 1] * day
    return out


def candidate_columns(
    params: CalibrationParams,
    t_s: np.ndarray,
    layout: ParameterLayout,
    candidate,
    output: ModelOutput | None = None,
) -> np.ndarray:
    """∂v/∂θ (k, 3, N) of a candidate effect *not* in ``layout``, at its zero values.

    Cheaper than a full Jacobian: at zero the candidate changes nothing else,
    so only its own columns are computed (for the closed loop's score tests).
    ``output`` (an :func:`evaluate` result at the same point) saves re-evaluating.
    """
    t = np.asarray(t_s, dtype=float)
    out = output if output is not None else evaluate(params, t, layout)
    gain = params.sensor.gain
    if candidate.stage == "sensor":
        term = candidate.sensor_delta(np.zeros(candidate.size), t, out.sensed_mps2, gain, True)
        return term.d_own
    if candidate.stage == "force":
        w3 = _layout_w(params, t, layout, out)
        r = params.bench.radius_m
        tilt = params.bench.tilt_rad
        d = candidate.force_delta(
            np.zeros(candidate.size), t, out.kinematics, r, True, tilt, params.gravity_mps2
        )
        return np.stack([_through_w(w3, column) for column in d.d_own])
    force = out.force
    rows = candidate.own_rows(t, out.kinematics, force.sin_theta, force.cos_theta)
    return spin_columns(params, t, layout, rows, out)


def spin_columns(
    params: CalibrationParams,
    t_s: np.ndarray,
    layout: ParameterLayout,
    rows: tuple[np.ndarray, np.ndarray, np.ndarray],
    output: ModelOutput,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """∂v/∂q (k, 3, N) of quantities q not in ``layout`` that act on the wheel angle alone.

    ``rows`` = (∂ϑ/∂q, ∂ω/∂q, ∂ω̇/∂q), each (k, N), at the samples of ``output``
    (an :func:`evaluate` result of ``layout`` at ``params`` and ``t_s``), as a
    spin candidate at zero contributes them (see :func:`candidate_columns`);
    written into ``out`` (k, 3, N) when given.
    """
    w3 = _layout_w(params, np.asarray(t_s, dtype=float), layout, output)
    omega = output.kinematics.omega_radps
    return _spin_rows_to_v(w3, output.force, rows, omega, params.bench.radius_m, out=out)


def _layout_w(
    params: CalibrationParams, t: np.ndarray, layout: ParameterLayout, out: ModelOutput
) -> np.ndarray:
    """W = ∂v/∂s · R of ``layout``'s sensor (its sensor effects at their values)."""
    gain = params.sensor.gain
    terms = [
        e.sensor_delta(params.effect(e.name, e.size), t, out.sensed_mps2, gain, True)
        for e in layout.effects
        if e.stage == "sensor"
    ]
    return _sensor_w(gain, params.bench.misalignment.matrix, terms)


def blocks_needing_zeros(layout: ParameterLayout) -> np.ndarray:
    """Rows of the Jacobian that evaluate() fills only partly or not at all.

    Gain, offset and sensor effects are filled per axis; a measurement of
    another stream (the gyro) does not act on the accelerometer at all.
    """
    b = layout.blocks
    rows = list(range(b["gain"].start, b["offset"].stop))
    for effect in layout.effects:
        if effect.stage in ("sensor", "gyro"):
            block = b[f"effect:{effect.name}"]
            rows += list(range(block.start, block.stop))
    return np.array(rows, dtype=int)


def _through_w(w3: np.ndarray, da: np.ndarray) -> np.ndarray:
    """W·a for bench-frame vectors da (N, 3) → (3, N); W constant (3,3,1) or per sample (3,3,N)."""
    if w3.shape[2] == 1:
        return w3[:, :, 0] @ da.T
    return np.einsum("ijn,nj->in", w3, da)


def _add_force_rows(jac, layout, w3, kin, force_terms, spin_effects) -> None:
    """Force effects' share of dv/dp, and their own columns.

    Spin rows p: W·(∂Δa/∂ϑ ∂ϑ/∂p + ∂Δa/∂ω ∂ω/∂p + ∂Δa/∂ω̇ ∂ω̇/∂p); own: W·∂Δa/∂θ.
    W·∂Δa/∂ϑ (and for ω, ω̇) is formed once per sample (3, N) and scaled by each row's
    ∂ϑ/∂p: three products per row instead of a (rows, N, 3) product and its contraction.
    """
    blocks = layout.blocks
    through = [
        _through_w(w3, sum(getattr(term, k) for _, term in force_terms))
        for k in ("by_theta", "by_omega", "by_omega_dot")
    ]
    kin_rows = (kin.d_theta, kin.d_omega, kin.d_omega_dot)
    targets = [blocks["spin"]] + [blocks[f"effect:{e.name}"] for e in spin_effects]
    row = 0
    for target in targets:
        size = target.stop - target.start
        part = jac[target]  # a view: the rows are added in place
        for d, by in zip(kin_rows, through, strict=True):
            part += d[row : row + size, None, :] * by[None]
        row += size
    for effect, term in force_terms:
        _own_through_w(w3, np.asarray(term.d_own), jac[blocks[f"effect:{effect.name}"]])


def _own_through_w(w3: np.ndarray, d_own: np.ndarray, out: np.ndarray) -> None:
    """W·∂Δa/∂θ_k (k, 3, N) into ``out`` for bench-frame columns ``d_own`` (k, N, 3)."""
    if w3.shape[2] == 1:
        np.matmul(w3[:, :, 0], d_own.transpose(0, 2, 1), out=out)
        return
    for i in range(3):  # W per sample (sensor effects)
        row = out[:, i, :]
        np.multiply(d_own[:, :, 0], w3[i, 0], out=row)
        row += d_own[:, :, 1] * w3[i, 1]
        row += d_own[:, :, 2] * w3[i, 2]


def wheel_kinematics(
    params: CalibrationParams,
    t_s: np.ndarray,
    effects: tuple = (),
    jacobian: bool = False,
    kinematics: Kinematics | None = None,
) -> Kinematics:
    """ϑ, ω, ω̇ of the spin (eq. 2, or a given motion) with its spin-stage effects.

    With ``jacobian`` the derivative rows are the spin coefficients, then each
    spin effect's parameters in the order of ``effects``.
    """
    t = np.asarray(t_s, dtype=float)
    kin = kinematics if kinematics is not None else spin_kinematics(params.spin, t, jacobian)
    for effect in effects:
        if effect.stage == "spin":
            values = params.effect(effect.name, effect.size)
            kin = _apply_spin_effect(effect, values, t, kin, jacobian, params.bench.tilt_rad)
    return kin


def evaluate(
    params: CalibrationParams,
    t_s: np.ndarray,
    layout: ParameterLayout | None = None,
    jacobian: bool = False,
    effects: tuple = (),
    kinematics: Kinematics | None = None,
    out: np.ndarray | None = None,
    output: ModelOutput | None = None,
) -> ModelOutput:
    """Evaluate eq. (6) at times ``t_s`` (s from the window centre).

    ``layout`` chooses the free parameters and the effects in the model
    (``effects`` gives them when there is no layout); with ``jacobian=True``
    the layout is required and ∂v/∂x is returned in its order, shape (P, 3, N).
    ``kinematics`` replaces the polynomial spin of eq. (2) by a given motion
    (the simulator's physical spin-down laws); no Jacobian then.
    ``out`` is an optional (P, 3, N) buffer for the Jacobian (its contents are
    overwritten), so callers can stack extra columns after it without a copy.
    ``output`` (the paper's model, with ``jacobian``): an evaluation without a
    Jacobian at the same ``params`` and ``t_s``, whose ϑ, ω, ω̇, bench force and
    prediction serve; only ∂ϑ/∂p, ∂ω/∂p, ∂ω̇/∂p and the Jacobian are formed.
    """
    if jacobian and (layout is None or kinematics is not None):
        raise ValueError("a Jacobian needs a ParameterLayout and the model's own spin")
    if output is not None:
        if not jacobian or layout.effects or output.predicted_mps2.shape[0] != np.size(t_s):
            raise ValueError("output serves a Jacobian of the paper's model at its own samples")
        return _jacobian_from(params, np.asarray(t_s, dtype=float), layout, output, out)
    effects = layout.effects if layout is not None else tuple(effects)
    t = np.asarray(t_s, dtype=float)
    kin = wheel_kinematics(params, t, effects, jacobian, kinematics)
    force = bench_force(kin, params.bench.tilt_rad, params.bench.radius_m, params.gravity_mps2)
    force_terms = []
    for effect in effects:
        if effect.stage == "force":  # Δa of the bench frame (e.g. a rolling wheel's hub)
            values = params.effect(effect.name, effect.size)
            term = effect.force_delta(
                values,
                t,
                kin,
                params.bench.radius_m,
                jacobian,
                params.bench.tilt_rad,
                params.gravity_mps2,
            )
            force_terms.append((effect, term))
    if force_terms:
        total = force.accel_mps2 + sum(term.delta for _, term in force_terms)
        force = dataclasses.replace(force, accel_mps2=total)
    rot = params.bench.misalignment.matrix
    gain = params.sensor.gain
    # Eq. (4): s = R a.  (Rᵀ made C-contiguous: an (N, 3) @ F-ordered (3, 3) product takes
    # numpy's slow path, ~3.5× the time for the same numbers.)
    sensed = force.accel_mps2 @ np.ascontiguousarray(rot.T)
    # Eq. (5): v = o + Γ s, a column at a time (broadcasting (3,) over (N, 3) rows of
    # three is ~3× slower; the same products and sums).
    predicted = np.empty_like(sensed)
    for i in range(3):
        np.multiply(sensed[:, i], gain[i], out=predicted[:, i])
        predicted[:, i] += params.sensor.offset_mps2[i]
    sensor_terms = []
    for effect in effects:
        if effect.stage == "sensor":
            values = params.effect(effect.name, effect.size)
            term = effect.sensor_delta(values, t, sensed, gain, jacobian)
            predicted = predicted + term.delta
            sensor_terms.append((effect, term))
    if not jacobian:
        return ModelOutput(predicted, None, kin, force, sensed)
    return _with_jacobian(
        params,
        t,
        layout,
        ModelOutput(predicted, None, kin, force, sensed),
        out,
        force_terms,
        sensor_terms,
    )


def _jacobian_from(
    params: CalibrationParams,
    t: np.ndarray,
    layout: ParameterLayout,
    output: ModelOutput,
    out: np.ndarray | None,
) -> ModelOutput:
    """:func:`evaluate` with a Jacobian, from an evaluation without one (the paper's model)."""
    base = output.kinematics
    kin = Kinematics(
        base.theta_rad, base.omega_radps, base.omega_dot_radps2, *spin_partials(params.spin, t)
    )
    done = ModelOutput(output.predicted_mps2, None, kin, output.force, output.sensed_mps2)
    return _with_jacobian(params, t, layout, done, out, [], [])


def _with_jacobian(
    params: CalibrationParams,
    t: np.ndarray,
    layout: ParameterLayout,
    model: ModelOutput,
    out: np.ndarray | None,
    force_terms: list,
    sensor_terms: list,
) -> ModelOutput:
    """``model`` (kinematics with their partials) with ∂v/∂x (P, 3, N), into ``out`` when given."""
    kin, force, sensed, predicted = (
        model.kinematics,
        model.force,
        model.sensed_mps2,
        model.predicted_mps2,
    )
    effects = layout.effects
    rot = params.bench.misalignment.matrix
    gain = params.sensor.gain
    if out is None:
        jac = np.zeros((layout.size, 3, t.size))
    else:
        if out.shape != (layout.size, 3, t.size):
            raise ValueError(f"out must have shape {(layout.size, 3, t.size)}, got {out.shape}")
        jac = out
        jac[blocks_needing_zeros(layout)] = 0.0
    blocks = layout.blocks
    w3 = _sensor_w(gain, rot, [term for _, term in sensor_terms])
    # Spin coefficients (and spin-effect parameters) act through ϑ, ω, ω̇ on a_X, a_Y:
    # dv/dp = W[:,0]·∂a_X/∂p + W[:,1]·∂a_Y/∂p (outer products, no 3×3 per sample).
    r = params.bench.radius_m
    kin_rows = (kin.d_theta, kin.d_omega, kin.d_omega_dot)
    spin = blocks["spin"]
    spin_effects = [e for e in effects if e.stage == "spin"]
    # Straight into the Jacobian, block by block (no copy): the spin's, then each spin
    # effect's rows, as the kinematics hold them.
    row = 0
    for target in [spin] + [blocks[f"effect:{e.name}"] for e in spin_effects]:
        size = target.stop - target.start
        rows = tuple(k[row : row + size] for k in kin_rows)
        _spin_rows_to_v(w3, force, rows, kin.omega_radps, r, out=jac[target])
        row += size
    if force_terms:
        _add_force_rows(jac, layout, w3, kin, force_terms, spin_effects)
    by_tilt = _effects_by_tilt(w3, force, kin, r, force_terms)
    if layout.fit_tilt:
        jac[blocks["tilt"].start] = _through_w(w3, d_force_d_tilt(force))
        if by_tilt is not None:
            jac[blocks["tilt"].start] += by_tilt
    if layout.fit_radius:
        da_dr = d_force_d_radius(kin)
        for _, term in force_terms:
            da_dr = da_dr + term.by_radius
        jac[blocks["radius"].start] = _through_w(w3, da_dr)
    # Rotation: ∂(R exp([δ]×) a)/∂δ_k = R (e_k × a), so dv/dδ_k = W (e_k × a):
    # e_x × a = (0, −a_Z, a_Y), e_y × a = (a_Z, 0, −a_X), e_z × a = (−a_Y, a_X, 0).
    a = force.accel_mps2
    rot0 = blocks["rotation"].start
    a_x, a_y = a[:, 0], a[:, 1]
    a_z = a[:, 2] if force_terms else force.g_cos_tilt  # a_Z is a constant in eq. (1)
    w_x, w_y, w_z = w3[:, 0], w3[:, 1], w3[:, 2]
    jac[rot0] = w_z * a_y - w_y * a_z
    jac[rot0 + 1] = w_x * a_z - w_z * a_x
    jac[rot0 + 2] = w_y * a_x - w_x * a_y
    for i in range(3):
        jac[blocks["gain"].start + i, i, :] = sensed[:, i]
        jac[blocks["offset"].start + i, i, :] = 1.0
    for effect, term in sensor_terms:
        jac[blocks[f"effect:{effect.name}"]] = term.d_own
        if term.d_gain is not None:
            jac[blocks["gain"]] += term.d_gain
    by_radius = sum(term.by_radius for _, term in force_terms) if force_terms else None
    return ModelOutput(predicted, jac, kin, force, sensed, by_radius, by_tilt)


def _effects_by_tilt(w3, force, kin: Kinematics, radius_m: float, force_terms) -> np.ndarray | None:
    """The effects' share of ∂v/∂α (3, N): force effects' ∂Δa/∂α, and the wheel angle's.

    A tilt-aware spin effect moves ϑ, ω, ω̇ with α (``kin.d_tilt``): that acts
    through eq. (1) and through the force effects' ∂Δa/∂(ϑ, ω, ω̇).
    """
    tilted = [term.by_tilt for _, term in force_terms if term.by_tilt is not None]
    if not tilted and kin.d_tilt is None:
        return None
    da = sum(tilted) if tilted else np.zeros_like(force.accel_mps2)
    if kin.d_tilt is not None:
        d_theta, d_omega, d_omega_dot = kin.d_tilt
        for _, term in force_terms:
            da = da + term.by_theta * d_theta[:, None]
            da = da + term.by_omega * d_omega[:, None] + term.by_omega_dot * d_omega_dot[:, None]
    out = _through_w(w3, da)
    if kin.d_tilt is not None:
        rows = tuple(row[None] for row in kin.d_tilt)
        out = out + _spin_rows_to_v(w3, force, rows, kin.omega_radps, radius_m)[0]
    return out


def jacobian_transpose_times(
    params: CalibrationParams,
    t_s: np.ndarray,
    layout: ParameterLayout,
    weights: np.ndarray,
    output: ModelOutput,
) -> np.ndarray:
    """Σ_n ∂v(t_n)/∂x · w_n, shape (P,), for weights w (3, N) — without forming ∂v/∂x.

    Reverse mode through eq. (6) for a layout without effects: with W = Γ R and
    u_n = Wᵀ w_n (the weights seen in the bench frame), every parameter acting
    through a(t) contributes Σ_n ∂a_n/∂x · u_n; the spin coefficients through
    ϑ, ω, ω̇ (see the module doc), the rotation Σ_n a_n × u_n, gain i
    Σ_n s_{n,i} w_{n,i} and offset i Σ_n w_{n,i}.  ``output`` is an
    :func:`evaluate` result at ``params`` and ``t_s`` (no Jacobian needed).
    """
    return reverse_pass(params, t_s, layout, weights, output)[0]


def reverse_pass(
    params: CalibrationParams,
    t_s: np.ndarray,
    layout: ParameterLayout,
    weights: np.ndarray,
    output: ModelOutput,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`jacobian_transpose_times` and the :func:`spin_adjoint` rows it passes through.

    The spin coefficients' sums run through the wheel angle's adjoint rows
    (∂v/∂ϑ · w, ∂v/∂ω · w, ∂v/∂ω̇ · w per sample), which a quantity acting on the
    wheel angle alone (a candidate effect) then needs too: one pass gives both.
    """
    if layout.effects:
        raise ValueError("jacobian_transpose_times covers the paper's model (no effects)")
    t = np.asarray(t_s, dtype=float)
    force = output.force
    u = _bench_weights(params, weights)
    blocks = layout.blocks
    out = np.empty(layout.size)
    adjoint = _adjoint_rows(params, u, output)
    # The spin rows through the powers t^j, without forming ∂ϑ/∂p, ∂ω/∂p, ∂ω̇/∂p
    # (see kinematics: ∂ϑ/∂ω_k = t^(k+1)/(k+1), ∂ω/∂ω_k = t^k, ∂ω̇/∂ω_k = k t^(k−1)).
    degree = params.spin.degree
    powers = np.empty((degree + 2, t.size))
    powers[0] = 1.0
    for j in range(1, degree + 2):
        powers[j] = powers[j - 1] * t
    k = np.arange(degree + 1)
    through_theta = powers @ adjoint[0]
    spin = np.empty(degree + 2)
    spin[0] = through_theta[0]
    spin[1:] = through_theta[1:] / (k + 1) + powers[:-1] @ adjoint[1]
    spin[2:] += k[1:] * (powers[:degree] @ adjoint[2])
    out[blocks["spin"]] = spin
    if layout.fit_tilt:
        out[blocks["tilt"].start] = force.g_cos_tilt * (
            force.cos_theta @ u[0] + force.sin_theta @ u[1]
        ) - force.g_sin_tilt * np.sum(u[2])
    if layout.fit_radius:
        kin = output.kinematics
        out[blocks["radius"].start] = kin.omega_radps**2 @ u[0] + kin.omega_dot_radps2 @ u[1]
    a = force.accel_mps2
    rot0 = blocks["rotation"].start
    out[rot0] = a[:, 1] @ u[2] - a[:, 2] @ u[1]
    out[rot0 + 1] = a[:, 2] @ u[0] - a[:, 0] @ u[2]
    out[rot0 + 2] = a[:, 0] @ u[1] - a[:, 1] @ u[0]
    sensed = output.sensed_mps2
    for i in range(3):
        out[blocks["gain"].start + i] = sensed[:, i] @ weights[i]
        out[blocks["offset"].start + i] = np.sum(weights[i])
    return out, adjoint


def _bench_weights(params: CalibrationParams, weights: np.ndarray) -> np.ndarray:
    """u_n = Wᵀ w_n (3, N): weights on the three axes seen in the bench frame (W = Γ R)."""
    w_mat = params.sensor.gain[:, None] * params.bench.misalignment.matrix
    return w_mat.T @ weights


def _by_theta(force: BenchForce, u: np.ndarray) -> np.ndarray:
    """∂a/∂ϑ · u per sample: g sinα (cosϑ u_Y − sinϑ u_X)."""
    return force.g_sin_tilt * (force.cos_theta * u[1] - force.sin_theta * u[0])


def spin_adjoint(params: CalibrationParams, weights: np.ndarray, output: ModelOutput) -> np.ndarray:
    """(3, N): ∂v_n/∂ϑ · w_n, ∂v_n/∂ω · w_n, ∂v_n/∂ω̇ · w_n — the reverse of :func:`spin_columns`.

    A quantity q acting on the wheel angle alone then has
    Σ_n ∂v_n/∂q · w_n = Σ_n (row₀ ∂ϑ/∂q + row₁ ∂ω/∂q + row₂ ∂ω̇/∂q) at sample n
    (∂a_X = −g sinα sinϑ ∂ϑ + 2rω ∂ω, ∂a_Y = g sinα cosϑ ∂ϑ + r ∂ω̇).  The
    paper's model (no effects); ``output`` an :func:`evaluate` result there.
    """
    return _adjoint_rows(params, _bench_weights(params, weights), output)


def _adjoint_rows(params: CalibrationParams, u: np.ndarray, output: ModelOutput) -> np.ndarray:
    """:func:`spin_adjoint` from the weights seen in the bench frame (u = Wᵀ w)."""
    r = params.bench.radius_m
    rows = np.empty((3, u.shape[1]))
    rows[0] = _by_theta(output.force, u)
    np.multiply(output.kinematics.omega_radps, u[0], out=rows[1])
    rows[1] *= 2 * r
    np.multiply(u[1], r, out=rows[2])
    return rows


def predict(
    params: CalibrationParams,
    t_s: np.ndarray,
    layout: ParameterLayout | None = None,
    effects: tuple = (),
) -> np.ndarray:
    """v(t) of eq. (6), shape (N, 3), in m/s² (with ``effects`` when there is no layout)."""
    return evaluate(params, t_s, layout, effects=effects).predicted_mps2


def nuisance_sensitivity(
    params: CalibrationParams, t_s: np.ndarray, nuisance: str, output: ModelOutput | None = None
) -> np.ndarray:
    """∂v/∂q (N, 3) for a quantity the fit holds fixed: ``radius_m`` or ``gravity_mps2``.

    A sample-clock scale error ε is equivalent to a relative radius error of
    −2ε (ω and ω̇ are read in the wrong seconds while r ω² is not), so it needs
    no entry of its own.  ``output`` (an :func:`evaluate` result at the same
    parameters and times) saves evaluating the model again.
    """
    out = output if output is not None else evaluate(params, t_s)
    w_mat = params.sensor.gain[:, None] * params.bench.misalignment.matrix
    if nuisance == "radius_m":
        da = d_force_d_radius(out.kinematics)
        if out.force_by_radius is not None:  # a rolling wheel's r ψ̇², r ψ̈, 2 r ω ψ̇ terms
            da = da + out.force_by_radius
    elif nuisance == "gravity_mps2":
        da = d_force_d_gravity(out.force, params.bench.tilt_rad)
    elif nuisance == "tilt_rad":
        da = d_force_d_tilt(out.force)
        if out.effects_by_tilt is not None:  # a cambered rolling wheel's, a gyro angle's
            return da @ np.ascontiguousarray(w_mat.T) + out.effects_by_tilt.T
    else:
        raise ValueError(f"unknown nuisance quantity {nuisance!r}")
    return da @ np.ascontiguousarray(w_mat.T)  # (C-ordered: see evaluate)
