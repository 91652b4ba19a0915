"""From the optimiser's vector to the reported parameters (contract names).

The optimiser moves R by a local rotation vector δ; people read Euler angles
(:data:`~wheelcal.model.EULER_CONVENTION`) and degrees.  :func:`report_transform`
gives the reported names and values and the Jacobian G = ∂(reported)/∂x, so a
covariance C in optimiser coordinates becomes G C Gᵀ.
"""

from __future__ import annotations

import numpy as np

from wheelcal.model import AXES, CalibrationParams, ParameterLayout, spin_coefficient_names

EULER_NAMES = tuple(f"euler_{k}_deg" for k in (1, 2, 3))
GAIN_NAMES = tuple(f"gain_{a}" for a in AXES)
OFFSET_NAMES = tuple(f"offset_{a}_mps2" for a in AXES)


def report_transform(
    params: CalibrationParams, layout: ParameterLayout
) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """Reported names, their values, and G = ∂(reported)/∂(optimiser vector)."""
    names: list[str] = ["theta0_rad", *spin_coefficient_names(layout.spin_degree)]
    values: list[float] = [params.spin.theta0_rad, *params.spin.omega_radps]
    size = layout.size
    g = np.zeros((size, size))
    b = layout.blocks
    g[b["spin"], b["spin"]] = np.eye(layout.spin_degree + 2)
    row = layout.spin_degree + 2
    if layout.fit_tilt:
        names.append("tilt_deg")
        values.append(np.rad2deg(params.bench.tilt_rad))
        g[row, b["tilt"]] = np.rad2deg(1.0)
        row += 1
    if layout.fit_radius:
        names.append("radius_m")
        values.append(params.bench.radius_m)
        g[row, b["radius"]] = 1.0
        row += 1
    names += EULER_NAMES
    values += list(params.bench.misalignment.euler_deg())
    g[row : row + 3, b["rotation"]] = params.bench.misalignment.euler_jacobian_deg()
    row += 3
    names += GAIN_NAMES
    values += list(params.sensor.gain)
    g[row : row + 3, b["gain"]] = np.eye(3)
    row += 3
    names += OFFSET_NAMES
    values += list(params.sensor.offset_mps2)
    g[row : row + 3, b["offset"]] = np.eye(3)
    row += 3
    for effect in layout.effects:
        k = len(effect.param_names)
        names += [f"{effect.name}.{p}" for p in effect.param_names]
        values += list(params.effect(effect.name, k))
        g[row : row + k, b[f"effect:{effect.name}"]] = np.eye(k)
        row += k
    return tuple(names), np.array(values, dtype=float), g


def transform_covariance(g: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """G C Gᵀ that keeps ∞ variance (unidentifiable parameters) as ∞, never NaN."""
    bad = ~np.isfinite(np.diag(cov))
    clean = np.where(np.isfinite(cov), cov, 0.0)
    out = g @ clean @ g.T
    if np.any(bad):
        affected = np.any(np.abs(g[:, bad]) > 0, axis=1)
        out[affected, :] = np.nan
        out[:, affected] = np.nan
        out[affected, affected] = np.inf
    return out
