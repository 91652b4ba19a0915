"""The pooled sensor document's ``gyro`` block: the gyroscope's full matrix from its mountings.

Each session's calibration carries its gyro reading along the wheel axis
(``gyro.reading``: w, b, G_X, G_Y with their covariance), its mounting R
(``bench.misalignment_matrix``) and the covariance of R's Euler angles and the
tilt (``fit.covariance``).  :func:`gyro_block` turns those into
:class:`~wheelcal.closedloop.gyro_matrix.GyroMountingObservation` s, pools them
(:func:`~wheelcal.closedloop.gyro_matrix.pool_gyro`) and writes::

    "gyro": {
      "matrix": [[3],[3],[3]],  "matrix_std": [[3],[3],[3]],   # reading = matrix @ ω + bias
      "bias_radps": [3], "bias_std_radps": [3],
      "g_sensitivity_radps_per_mps2": [[3]×3], "g_sensitivity_std_radps_per_mps2": [[3]×3],
      "equation", "frame",
      "correction": {"matrix", "bias_radps", "equation"},      # only when complete
      "matrix_covariance": [[9]×9], "matrix_covariance_order",
      "mountings": [{"mounting_id", "sessions", "wheel_axis_in_sensor_frame",
                     "wheel_axis_spread_deg", "matrix_times_axis"}],
      "axes": {"independent", "singular_values", "least_seen_direction"},
      "undetermined": [{"parameter", "reason"}],
      "sessions_used", "skipped": [{"file", "reason"}],
      "spread": {"chi2_red", "dof", "scale"}, "priors", "warnings", "note"
    }

Entries the mountings cannot see are ``null`` (value and σ), named under
``undetermined`` with the reason.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from wheelcal.calibration.document import read_only_document
from wheelcal.closedloop import GyroMountingObservation, PooledGyro, geometry_covariance, pool_gyro
from wheelcal.model import STANDARD_GRAVITY_MPS2

_GEOMETRY_NAMES = ("euler_1_deg", "euler_2_deg", "euler_3_deg", "tilt_deg")
_NOTE = (
    "reading = matrix @ omega + bias_radps + g_sensitivity @ f, omega and f (specific force) in "
    "the accelerometer's orthonormal sensor frame (the frame of each session's "
    "bench.misalignment_matrix), rad/s; each mounting measures matrix @ (its wheel axis), the "
    "wheel axis known from the accelerometer's fit"
)


def _num(x) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _matrix(values) -> list:
    return [[_num(v) for v in row] for row in np.asarray(values, dtype=float).reshape(3, 3)]


def gyro_observation(calibration: Mapping) -> GyroMountingObservation:
    """One session's gyro reading and geometry; ValueError (naming the file) if it has none."""
    calibration = read_only_document(calibration)
    source = calibration.get("source", {})
    where = source.get("file", "?")
    reading = (calibration.get("gyro") or {}).get("reading")
    if not reading:
        raise ValueError(f"{where}: no gyro reading with its covariance (no gyroscope, or older)")
    names = list(reading.get("names", []))
    if len(names) != 12:
        raise ValueError(f"{where}: the gyro reading has no sensitivity to acceleration fitted")
    bench = calibration.get("bench", {})
    fit = calibration.get("fit", {})
    try:
        rotation = np.array(bench["misalignment_matrix"], dtype=float)
        tilt = math.radians(float(bench["tilt_deg"]))
        values = np.array(reading["values"], dtype=float)
        covariance = np.array(reading["covariance"], dtype=float)
        geometry = _geometry_covariance_deg2(fit)
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{where}: unusable gyro reading or bench ({exc!r})") from None
    prior = (calibration.get("gyro") or {}).get("g_sensitivity_prior_std_radps_per_mps2")
    return GyroMountingObservation(
        label=str(where),
        mounting_id=str(source.get("mounting_id") or ""),
        values=values,
        covariance=covariance,
        rotation=rotation,
        tilt_rad=tilt,
        gravity_mps2=float(reading.get("gravity_mps2") or STANDARD_GRAVITY_MPS2),
        geometry_covariance=geometry_covariance(rotation, geometry),
        g_prior_std=None if prior is None else float(prior),
    )


def _geometry_covariance_deg2(fit: Mapping) -> np.ndarray:
    """The (euler_1..3, tilt) block of a session's covariance, deg²; 0 where not fitted."""
    names = list(fit.get("covariance_names") or [])
    matrix = fit.get("covariance") or []
    out = np.zeros((4, 4))
    index = [(k, names.index(n)) for k, n in enumerate(_GEOMETRY_NAMES) if n in names]
    for a, i in index:
        for b, j in index:
            value = matrix[i][j]
            out[a, b] = np.nan if value is None else float(value)
    if not np.all(np.isfinite(out)):
        raise ValueError("the mounting's covariance is not finite (an undetermined angle)")
    return out


def gyro_block(calibrations: Sequence[Mapping]) -> dict:
    """``{"gyro": …}`` for the pooled sensor document, or ``{}`` when no session has a gyro."""
    observations, skipped = [], []
    for calibration in calibrations:
        calibration = read_only_document(calibration)
        if not calibration.get("gyro"):
            continue
        try:
            observations.append(gyro_observation(calibration))
        except ValueError as exc:
            skipped.append({"file": calibration.get("source", {}).get("file"), "reason": str(exc)})
    if not observations:
        if not skipped:
            return {}
        return {"gyro": _empty(skipped, [])}
    try:
        pooled = pool_gyro(observations)
    except (ValueError, np.linalg.LinAlgError) as exc:  # the accelerometer's file still counts
        return {"gyro": _empty(skipped, [f"the pooled gyro fit failed: {exc}"])}
    return {"gyro": pooled_gyro_dict(pooled, skipped)}


def _empty(skipped: Sequence[Mapping], warnings: Sequence[str]) -> dict:
    """The block when no session's gyro reading could be pooled: nulls, and why."""
    return {
        "matrix": None,
        "matrix_std": None,
        "bias_radps": None,
        "bias_std_radps": None,
        "mountings": [],
        "undetermined": [{"parameter": "matrix", "reason": "no session has a usable gyro reading"}],
        "sessions_used": 0,
        "skipped": list(skipped),
        "warnings": list(warnings),
        "note": _NOTE,
    }


def pooled_gyro_dict(pooled: PooledGyro, skipped: Sequence[Mapping] = ()) -> dict:
    """The ``gyro`` block of a :class:`~wheelcal.closedloop.gyro_matrix.PooledGyro`."""
    block = {
        "matrix": _matrix(pooled.matrix),
        "matrix_std": _matrix(pooled.matrix_std),
        "bias_radps": [_num(v) for v in pooled.bias_radps],
        "bias_std_radps": [_num(v) for v in pooled.bias_std_radps],
        "g_sensitivity_radps_per_mps2": _matrix(pooled.g_sensitivity),
        "g_sensitivity_std_radps_per_mps2": _matrix(pooled.g_sensitivity_std),
        "equation": "reading = matrix @ omega + bias_radps + g_sensitivity_radps_per_mps2 @ f",
        "frame": "the accelerometer's orthonormal sensor frame (bench.misalignment_matrix's)",
    }
    if pooled.complete:
        inverse, bias = pooled.correction()
        block["correction"] = {
            "matrix": _matrix(inverse),
            "bias_radps": [_num(v) for v in bias],
            "equation": "omega = matrix @ (reading - bias_radps)",
        }
    block.update(
        {
            "matrix_covariance": [[_num(v) for v in row] for row in pooled.matrix_covariance],
            "matrix_covariance_order": "row-major: matrix[0][0], matrix[0][1], … matrix[2][2]",
            "mountings": [m.to_dict() for m in pooled.mountings],
            "axes": {
                "independent": pooled.independent_axes,
                "singular_values": [_num(v) for v in pooled.axes_singular_values],
                "least_seen_direction": [_num(v) for v in pooled.least_seen_axis],
                "note": "singular values of the mountings' unit wheel axes ÷ √(mountings): "
                "0.577 each for three orthogonal axes, 0 for a direction no mounting sees",
            },
            "undetermined": [{"parameter": p, "reason": r} for p, r in pooled.undetermined],
            "sessions_used": len(pooled.sessions),
            "skipped": list(skipped),
            "spread": {
                "chi2_red": _num(pooled.chi2_red),
                "dof": pooled.dof,
                "scale": _num(pooled.scale),
            },
            "priors": {
                "g_sensitivity_prior_std_radps_per_mps2": _num(pooled.g_prior_std),
                "sessions_prior_taken_out": pooled.priors_taken_out,
                "note": "each session's prior on G is taken out and G's prior applied once",
            },
            "warnings": list(pooled.warnings),
            "note": _NOTE,
        }
    )
    return block
