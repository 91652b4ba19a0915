"""Whitened normal equations of the gyroscope stream, on the joint fit's parameters.

With a :class:`~wheelcal.model.effects.GyroReading` in the layout, every valid
gyro sample adds three residuals, ω_meas − (w ω(t) + b), to the
accelerometer's.  Their partial derivatives are

* spin coefficients and spin effects p:  w · ∂ω/∂p  (the rows of the
  kinematics, :func:`~wheelcal.model.forward.wheel_kinematics`);
* the reading's own parameters:  ∂/∂w_i = ω e_i,  ∂/∂b_i = e_i, and with the
  sensitivity to linear acceleration ∂/∂G_X = a_X e_i, ∂/∂G_Y = a_Y e_i;
* through G·a also the spin (∂a/∂p of eq. 1), the tilt and a fitted radius;

and nothing else (the gyro does not see R, gains or offsets — on a fixed
bench it measures the motion, and the force through G).  The gyro noise model (AR colour per
axis, from the gyro residual) whitens them as the accelerometer's model
whitens its residual; the two streams are independent, so their Fisher
informations add.  Accumulated in chunks like
:func:`~wheelcal.estimate.joint.normal_equations.accumulate`.
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.joint.gyro_rests import GyroRests
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.normal_equations import NormalEquations, add_gram, chunking, local_view
from wheelcal.model import (
    BenchForce,
    CalibrationParams,
    ParameterLayout,
    bench_force,
    wheel_kinematics,
)


def gyro_effect(layout: ParameterLayout):
    """The layout's gyro reading effect, or None."""
    return next((e for e in layout.effects if e.stage == "gyro"), None)


def gyro_prediction(
    params: CalibrationParams, t_s: np.ndarray, layout: ParameterLayout
) -> np.ndarray:
    """Predicted gyro samples (N, 3) at centred times ``t_s``."""
    effect = gyro_effect(layout)
    kin = wheel_kinematics(params, t_s, layout.effects)
    force = _force(params, kin).accel_mps2 if effect.g_sensitivity else None
    return effect.reading(params.effect(effect.name, effect.size), kin.omega_radps, force)


def _force(params: CalibrationParams, kin) -> BenchForce:
    bench = params.bench
    return bench_force(kin, bench.tilt_rad, bench.radius_m, params.gravity_mps2)


def _fed_blocks(
    layout: ParameterLayout, effect, through_force: bool
) -> tuple[dict[str, slice], np.ndarray]:
    """The blocks the gyro stream depends on, as slices of a compact Jacobian, and their rows.

    The spin and the spin effects (the kinematics' derivative rows, in their
    order), the tilt and a fitted radius (only through G·a), the reading's own.
    """
    blocks = layout.blocks
    names = ["spin"] + [f"effect:{e.name}" for e in layout.effects if e.stage == "spin"]
    if through_force:
        names += [name for name in ("tilt", "radius") if name in blocks]
    names.append(f"effect:{effect.name}")
    fed, rows, start = {}, [], 0
    for name in names:
        block = blocks[name]
        fed[name] = slice(start, start + block.stop - block.start)
        rows.append(np.arange(block.start, block.stop))
        start = fed[name].stop
    return fed, np.concatenate(rows)


def accumulate_gyro(
    params: CalibrationParams,
    t_s: np.ndarray,
    gyro_radps: np.ndarray,
    layout: ParameterLayout,
    noise: NoiseModel,
    jacobian: bool = True,
    chunk: int | None = None,
    rests: GyroRests | None = None,
) -> NormalEquations:
    """Cost, H and g of the whitened gyro residual (model − data) over ``layout``.

    ``t_s`` and ``gyro_radps`` hold the valid gyro samples only (rows left
    out — clipped, missing — are simply absent).  ``rests``: the gyro's static
    readings at the rests, three more rows each (:mod:`.gyro_rests`).
    """
    effect = gyro_effect(layout)
    n = t_s.size
    chunk, sparse = chunking(layout, t_s, chunk)
    p = noise.order
    cost, entries = 0.0, 0
    hess = np.zeros((layout.size, layout.size)) if jacobian else None
    grad = np.zeros(layout.size) if jacobian else None
    gyro_name = f"effect:{effect.name}"
    values = params.effect(effect.name, effect.size)
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        lo = max(0, start - p)
        t = t_s[lo:stop]
        view = local_view(params, layout, t[0], t[-1]) if sparse else None
        here, at = (view.layout, view.params) if view else (layout, params)
        kin = wheel_kinematics(at, t, here.effects, jacobian)
        force = _force(at, kin) if effect.g_sensitivity else None
        accel = None if force is None else force.accel_mps2
        residual = effect.reading(values, kin.omega_radps, accel) - gyro_radps[lo:stop]
        if not jacobian:
            rw, _ = noise.whiten(residual)
            cost += float(np.sum(rw * rw))
            entries += rw.size
            continue
        jac, rows = _gyro_jacobian(here, at, effect, kin, force, values)
        rw, jw = noise.whiten(residual, jac)
        jt = jw.reshape(jw.shape[0], -1)
        r_flat = rw.reshape(-1)
        add_gram(hess, grad, jt, r_flat, rows if view is None else view.index[rows])
        cost += float(r_flat @ r_flat)
        entries += r_flat.size
    prior = effect.g_prior_terms(values)
    if prior is not None:  # the sensor class's prior on G (GyroReading): once, not per chunk
        prior_cost, prior_grad, weight = prior
        cost += prior_cost
        if jacobian:
            g_rows = np.arange(layout.blocks[gyro_name].start + 6, layout.blocks[gyro_name].stop)
            hess[g_rows, g_rows] += weight
            grad[g_rows] += prior_grad
    if rests is not None:  # the rests' means: b + G·a_rest, three rows each
        rest_cost, rest_grad, rest_gram = rests.normal_terms(params, values, effect.g_sensitivity)
        cost += rest_cost
        entries += 3 * rests.count
        if jacobian:
            block = layout.blocks[gyro_name]
            rows = np.arange(block.start, block.stop)
            hess[np.ix_(rows, rows)] += rest_gram
            grad[rows] += rest_grad
    return NormalEquations(cost=cost, hessian=hess, gradient=grad, entries=entries)


def _gyro_jacobian(
    layout: ParameterLayout,
    params: CalibrationParams,
    effect,
    kin,
    force: BenchForce | None,
    values: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """∂(gyro prediction)/∂p over the rows the gyro depends on, (rows, 3, N), and those rows.

    Only the rows the gyro depends on (not R, the gains, the offsets …): a
    compact Jacobian, its Gram added to those rows of H.  ``force`` is the
    bench's specific force when the reading senses it (G), else None.
    """
    w = values[:3]
    gx, gy = (values[6:9], values[9:12]) if force is not None else (None, None)
    gyro_name = f"effect:{effect.name}"
    fed, rows = _fed_blocks(layout, effect, force is not None)
    jac = np.zeros((rows.size, 3, kin.omega_radps.size))
    row = 0
    for name in ("spin", *(n for n in fed if n.startswith("effect:") and n != gyro_name)):
        target = fed[name]
        size = target.stop - target.start
        d_omega = kin.d_omega[row : row + size]  # (size, N)
        jac[target] = d_omega[:, None, :] * w[None, :, None]
        if force is not None:  # G_X ∂a_X/∂p + G_Y ∂a_Y/∂p (eq. 1)
            d_theta = kin.d_theta[row : row + size]
            dax = d_theta * (-force.g_sin_tilt * force.sin_theta)
            dax += d_omega * (2 * params.bench.radius_m * kin.omega_radps)
            day = d_theta * (force.g_sin_tilt * force.cos_theta)
            day += params.bench.radius_m * kin.d_omega_dot[row : row + size]
            jac[target] += dax[:, None, :] * gx[None, :, None]
            jac[target] += day[:, None, :] * gy[None, :, None]
        row += size
    if force is not None:
        if "tilt" in fed:  # ∂a/∂α = g cosα (cosϑ, sinϑ, ·)
            tilt = fed["tilt"].start
            jac[tilt] += np.outer(gx, force.g_cos_tilt * force.cos_theta)
            jac[tilt] += np.outer(gy, force.g_cos_tilt * force.sin_theta)
        if "radius" in fed:  # ∂a/∂r = (ω², ω̇, 0)
            radius = fed["radius"].start
            jac[radius] += np.outer(gx, kin.omega_radps**2)
            jac[radius] += np.outer(gy, kin.omega_dot_radps2)
    gyro_block = fed[gyro_name]
    for i in range(3):
        jac[gyro_block.start + i, i] = kin.omega_radps
        jac[gyro_block.start + 3 + i, i] = 1.0
        if force is not None:
            jac[gyro_block.start + 6 + i, i] = force.accel_mps2[:, 0]
            jac[gyro_block.start + 9 + i, i] = force.accel_mps2[:, 1]
    return jac, rows


def combined(a: NormalEquations, b: NormalEquations, a_free: int | None = None) -> NormalEquations:
    """The normal equations of two independent streams over the same parameters.

    ``b`` covers the free parameters only.  ``a`` covers the first ``a_free``
    of them (default: all; the rest — the gyro's reading, last in the layout —
    do not act on its stream) and may carry extra columns after them (the
    systematic budget's), which stay last.
    """
    if a.hessian is None or b.hessian is None:
        return NormalEquations(a.cost + b.cost, None, None, a.entries + b.entries)
    size = b.hessian.shape[0]
    a_free = size if a_free is None else a_free
    extra = a.hessian.shape[0] - a_free
    order = np.r_[0:a_free, size : size + extra]  # a's rows in the combined matrix
    hess = np.zeros((size + extra, size + extra))
    grad = np.zeros(size + extra)
    hess[np.ix_(order, order)] = a.hessian
    grad[order] = a.gradient
    hess[:size, :size] += b.hessian
    grad[:size] += b.gradient
    return NormalEquations(a.cost + b.cost, hess, grad, a.entries + b.entries)
