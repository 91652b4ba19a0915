"""``sensors/<sensor_id>.calibration.json`` — one calibration per sensor, pooled from its sessions.

Format ``wheelcal.sensor_calibration/1``.  A pooled result has no single
source file, bench or motion; it keeps the keys a session's calibration uses
for the sensor, so ``export`` and ``apply`` read it the same way::

    {
      "format": "wheelcal.sensor_calibration/1",
      "sensor_id": "...",
      "source":  {"sensor_id", "topic", "mounting_ids": [...], "files": [...]},
      "sensor":  {"offset_mps2": [3], "gain": [3], "offset_std_mps2": [3], "gain_std": [3],
                  "undetermined": [{"parameter", "reason"}]},     # statistical σ
      "systematic": {"gain_std": [3], "offset_std_mps2": [3], "note"},  # shared, not ÷√n
      "correction": {"bias_mps2": [3], "matrix": [[3],[3],[3]], "equation",
                     "identity_axes": [...], "note"},   # only when an axis is undetermined
      "pooling": {"method", "description", "sessions", "spread": {name: {"chi2_red", "dof",
                  "between_session_std", "scale", "sessions_used"}}},
      "sessions": [{"file", "mounting_id", "calibration", "skipped": [{"parameter", "reason"}]}],
      "parameters": {name: {"value", "std", "systematic_std", "std_unscaled"}},
      "fit": {"noise_std_mps2": [3], "covariance", "covariance_names", "warnings",
              "allan": {...}},  # the sessions' rests pooled (wheelcal.calibration.allan_json)
      "imu_noise": {...}   # Kalibr's noise terms pooled (wheelcal.calibration.imu_noise)
      "gyro": {"matrix", "matrix_std", "bias_radps", "bias_std_radps", "mountings", ...}
                                # with a gyroscope (wheelcal.calibration.gyro_json)
    }

Values a session cannot determine are JSON ``null`` in its file; they are
skipped for that parameter here (and listed under ``sessions[].skipped``).
Written atomically.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from wheelcal import __version__
from wheelcal.calibration.allan_json import pooled_allan
from wheelcal.calibration.document import read_only_document
from wheelcal.calibration.gyro_json import gyro_block
from wheelcal.calibration.imu_noise import pooled_imu_noise
from wheelcal.calibration.session_json import SENSOR_CALIBRATION_FORMAT as FORMAT
from wheelcal.closedloop import (
    JOINT_FIT,
    POOLED_PARAMETERS,
    JointEstimate,
    PooledSensor,
    RecordingEstimate,
)
from wheelcal.io import atomic_write_text
from wheelcal.model import AXES

_DESCRIPTION = {
    JOINT_FIT: (
        "joint sensor fit over every session's samples (shared offsets and gains, each session "
        "its own bench and spin); σ scaled by max(1, √χ²_red) of the sessions' scatter within "
        "each mounting"
    ),
    "precision_weighted_mean": (
        "precision-weighted mean of the sessions, weights 1/(σ² + τ²) with τ the scatter between "
        "sessions beyond their σ (DerSimonian–Laird; 0 when they agree); σ = 1/√Σw scaled by "
        "max(1, √χ²_red) of the sessions' scatter about the mean"
    ),
}
_SYSTEMATIC_NOTE = (
    "shared by the sessions (radius, gravity, sample clock): the weighted mean of their "
    "systematic σ, not divided by √n — repeating does not average it away"
)
_GAINS, _OFFSETS = slice(0, 3), slice(3, 6)  # of POOLED_PARAMETERS: gains, then offsets
#: JSON key → PooledSensor field, per parameter: ``pooling.spread`` and ``parameters``.
_SPREAD_FIELDS = {
    **{name: name for name in ("chi2_red", "dof", "between_session_std", "scale")},
    "sessions_used": "used",
}
_PARAMETER_FIELDS = {name: name for name in ("value", "std", "systematic_std", "std_unscaled")}
_STATISTICAL_NOTE = (
    "sensor.*_std are statistical one-sigma σ after the spread check; add the systematic σ "
    "in quadrature for the total"
)


def _num(x) -> float | None:
    """A JSON number, or null for NaN/∞/None."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _float(x) -> float:
    """A JSON number (null → NaN)."""
    return math.nan if x is None else float(x)


def _list(values) -> list:
    return [_num(v) for v in np.asarray(values, dtype=float).reshape(-1)]


def session_estimate(calibration: Mapping) -> RecordingEstimate:
    """The pooling input of one session's calibration dictionary (nulls become NaN)."""
    calibration = read_only_document(calibration)
    source = calibration.get("source", {})
    where = source.get("file", "?")
    try:
        sensor = calibration["sensor"]
        value = [*map(_float, sensor["gain"]), *map(_float, sensor["offset_mps2"])]
        std = [*map(_float, sensor["gain_std"]), *map(_float, sensor["offset_std_mps2"])]
        sys_block = calibration.get("systematic", {})
        systematic = [
            *map(_float, sys_block.get("gain_std", [None] * 3)),
            *map(_float, sys_block.get("offset_std_mps2", [None] * 3)),
        ]
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{where}: calibration has no usable sensor block ({exc!r})") from None
    reasons = {}
    for entry in sensor.get("undetermined", []) or []:
        if isinstance(entry, Mapping) and "parameter" in entry:
            reasons[str(entry["parameter"])] = str(entry.get("reason", "undetermined"))
    return RecordingEstimate(
        label=where,
        value=value,
        std=std,
        systematic_std=systematic,
        mounting_id=str(source.get("mounting_id") or ""),
        covariance=_covariance(calibration.get("fit", {})),
        reasons=tuple(sorted(reasons.items())),
    )


def _covariance(fit: Mapping) -> np.ndarray | None:
    """The six sensor parameters' block of a session's covariance, if it carries one."""
    names = fit.get("covariance_names")
    matrix = fit.get("covariance")
    if not names or not matrix or not all(n in names for n in POOLED_PARAMETERS):
        return None
    index = [names.index(n) for n in POOLED_PARAMETERS]
    try:
        full = np.array([[_float(c) for c in row] for row in matrix], dtype=float)
        return full[np.ix_(index, index)]
    except (TypeError, ValueError, IndexError):
        return None


def joint_estimate(sensor_fit: Mapping) -> JointEstimate:
    """The pooling input of a joint sensor fit (``SensorFitResult.as_dict()``)."""
    params = sensor_fit.get("parameters", {})

    def entry(name: str, key: str) -> float:
        return _float(params.get(name, {}).get(key))

    cross = None
    names = ("cross_axis.yx_rad", "cross_axis.zx_rad", "cross_axis.zy_rad")
    if all(n in params for n in names) and all(np.isfinite([entry(n, "std") for n in names])):
        cross = [entry(n, "value") for n in names]
    effects = tuple(sorted({n.split(".", 1)[0] for n in params if "." in n}))
    return JointEstimate(
        value=[entry(n, "value") for n in POOLED_PARAMETERS],
        std=[entry(n, "std") for n in POOLED_PARAMETERS],
        converged=bool(sensor_fit.get("converged", False)),
        cross_axis_rad=cross,
        effects=effects,
    )


def sensor_calibration_dict(
    sensor_id: str,
    pooled: PooledSensor,
    calibrations: Sequence[Mapping],
    calibration_paths: Mapping[str, str] | None = None,
) -> dict:
    """The ``wheelcal.sensor_calibration/1`` dictionary (see the module docstring).

    ``calibrations`` are the pooled sessions' dictionaries, in the order of
    ``pooled.sessions``; ``calibration_paths`` maps a session's file to its
    calibration JSON.
    """
    calibrations = [read_only_document(c) for c in calibrations]  # read only: no copies
    correction = pooled.correction()
    sources = [c.get("source", {}) for c in calibrations]
    topics = {s.get("topic") for s in sources if s.get("topic")}
    return {
        "format": FORMAT,
        "wheelcal_version": __version__,
        "sensor_id": sensor_id,
        "source": {
            "sensor_id": sensor_id,
            "topic": topics.pop() if len(topics) == 1 else None,
            "mounting_ids": sorted({str(s.get("mounting_id") or "") for s in sources}),
            "rate_hz": _common_rate(sources),
            "files": [s.get("file") for s in sources],
        },
        "sensor": _sensor_block(pooled),
        "systematic": {
            "gain_std": _list(pooled.systematic_std[_GAINS]),
            "offset_std_mps2": _list(pooled.systematic_std[_OFFSETS]),
            "note": _SYSTEMATIC_NOTE,
        },
        "correction": {
            "bias_mps2": _list(correction.bias_mps2),
            "matrix": [_list(row) for row in correction.matrix],
            "equation": "a = matrix @ (v - bias)",
            **_identity_axes(pooled),
        },
        "pooling": {
            "method": pooled.method,
            "description": _DESCRIPTION[pooled.method],
            "sessions": len(pooled.sessions),
            "note": _STATISTICAL_NOTE,
            "spread": _by_parameter(pooled, _SPREAD_FIELDS),
        },
        "sessions": _sessions(pooled, sources, calibration_paths or {}),
        "parameters": _by_parameter(pooled, _PARAMETER_FIELDS),
        "fit": {
            "noise_std_mps2": _list(_noise_rms(calibrations)),
            "covariance": [_list(row) for row in pooled.covariance],
            "covariance_names": list(pooled.names),
            "warnings": list(pooled.warnings),
            **_pooled_allan(calibrations),
        },
        **_pooled_noise(calibrations),
        # The gyroscope's full matrix from the mountings (calibration/gyro_json.py).
        **gyro_block(calibrations),
    }


def _sensor_block(pooled: PooledSensor) -> dict:
    """``sensor``: the pooled offsets and gains with their statistical σ."""
    sensor = {
        "offset_mps2": _list(pooled.value[_OFFSETS]),
        "gain": _list(pooled.value[_GAINS]),
        "offset_std_mps2": _list(pooled.std[_OFFSETS]),
        "gain_std": _list(pooled.std[_GAINS]),
        "undetermined": [{"parameter": p, "reason": r} for p, r in pooled.undetermined],
    }
    if pooled.cross_axis_rad is not None:
        sensor["cross_axis_rad"] = dict(
            zip(("yx_rad", "zx_rad", "zy_rad"), _list(pooled.cross_axis_rad), strict=True)
        )
    return sensor


def _by_parameter(pooled: PooledSensor, fields: Mapping[str, str]) -> dict:
    """``{name: {key: value}}`` per pooled parameter, from ``fields``: key → PooledSensor field."""
    columns = {key: getattr(pooled, name) for key, name in fields.items()}
    return {
        name: {key: _json_number(column[k]) for key, column in columns.items()}
        for k, name in enumerate(pooled.names)
    }


def _json_number(x) -> int | float | None:
    """An integer stays one; a float is a JSON number, or null for NaN/∞."""
    return int(x) if isinstance(x, np.integer) else _num(x)


def _sessions(
    pooled: PooledSensor, sources: Sequence[Mapping], paths: Mapping[str, str]
) -> list[dict]:
    """``sessions``: each session's file, mounting, calibration JSON and skipped parameters."""
    skipped: dict[str, list[dict]] = {}
    for label, parameter, reason in pooled.skipped:
        skipped.setdefault(label, []).append({"parameter": parameter, "reason": reason})
    return [
        {
            "file": s.get("file"),
            "mounting_id": str(s.get("mounting_id") or ""),
            "calibration": paths.get(s.get("file")),
            "skipped": skipped.get(s.get("file"), []),
        }
        for s in sources
    ]


def _noise_rms(calibrations: Sequence[Mapping]) -> np.ndarray | list[None]:
    """The sessions' noise σ per axis, RMS over the sessions that state it."""
    noise = np.array(
        [
            [_float(v) for v in c.get("fit", {}).get("noise_std_mps2", [None] * 3)]
            for c in calibrations
        ]
    )
    return np.sqrt(np.nanmean(noise**2, axis=0)) if np.isfinite(noise).any() else [None] * 3


def _pooled_allan(calibrations: Sequence[Mapping]) -> dict:
    """``fit.allan`` pooled over the sessions' rests (additive; absent without rests)."""
    block = pooled_allan([c.get("fit", {}).get("allan") for c in calibrations])
    return {} if block is None else {"allan": block}


def _pooled_noise(calibrations: Sequence[Mapping]) -> dict:
    """``imu_noise`` pooled over the sessions (:mod:`wheelcal.calibration.imu_noise`)."""
    block = pooled_imu_noise([c.get("imu_noise") for c in calibrations])
    return {} if block is None else {"imu_noise": block}


def _common_rate(sources: Sequence[Mapping]) -> float | None:
    """The sessions' sample rate when they share one (within 0.1 %), else None."""
    rates = [r for r in (s.get("rate_hz") for s in sources) if isinstance(r, int | float)]
    if not rates or max(rates) > 1.001 * min(rates):
        return None
    return float(np.median(rates))


def _identity_axes(pooled: PooledSensor) -> dict:
    """``identity_axes`` and a note when an undetermined parameter leaves an axis unchanged."""
    names = {p for p, _ in pooled.undetermined}
    axes = [a for a in AXES if f"gain_{a}" in names or f"offset_{a}_mps2" in names]
    if not axes:
        return {}
    return {
        "identity_axes": axes,
        "note": "these axes are left unchanged (gain 1, offset 0): no session of this sensor "
        "determines their gain or offset (see sensor.undetermined)",
    }


def sensor_calibration_text(doc: Mapping) -> str:
    """A sensor calibration dictionary as the file's text."""
    return json.dumps(doc, indent=2, allow_nan=False) + "\n"


def write_sensor_calibration(path: str | os.PathLike, doc: Mapping, durable: bool = True) -> Path:
    """Write a sensor calibration dictionary atomically; returns the path."""
    atomic_write_text(path, sensor_calibration_text(doc), durable=durable)
    return Path(path)
