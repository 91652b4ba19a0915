r"""Calibration exports: Kalibr's ``imu.yaml``, ``imu_calib``'s file, and a C header.

All carry the contract's correction, a = M (v − b) in the sensor frame, with
b in m/s² and M dimensionless (row-major).  A session's calibration
(``wheelcal.calibration/1``) and a sensor's pooled one
(``wheelcal.sensor_calibration/1``) export alike.

* ``yaml``: Kalibr's ``imu.yaml`` keys at the top level —
  ``accelerometer_noise_density`` and ``accelerometer_random_walk`` from the
  rests' Allan deviation (``fit.allan``; ``null`` when the recording has no
  rest), ``update_rate`` and ``rostopic`` — and wheelcal's ``imu0`` block
  (``accelerometer.bias_mps2``, ``matrix``, statistical and systematic σ, the
  per-axis Allan read-outs);
* ``imu_calib``: the ROS ``imu_calib`` package's ``SM`` (9, row-major) and
  ``bias``, for a = SM v − bias;
* ``c``: a C header with ``<prefix>_accel_correct()`` (and, with the gyro's
  full matrix, ``<prefix>_gyro_correct()``);
* ``imu_tk_acc``, ``imu_tk_gyro``: imu_tk's ``CalibratedTriad`` files
  (misalignment T, scale K, bias B: X' = T K (X − B)).

With a sensor's pooled calibration whose ``gyro`` block has the full matrix M
and bias b (:mod:`wheelcal.calibration.gyro_apply`), the YAML adds the gyro's
intrinsics in the form of Kalibr's ``scale-misalignment`` IMU model
(``--imu-models scale-misalignment``: ``model``, ``accelerometers.M``,
``gyroscopes.M``, ``gyroscopes.A``, ``gyroscopes.C_gyro_i``, the keys
``IccScaledMisalignedImu`` writes) and wheelcal's ``imu0.gyroscope`` block.

YAML is written by PyYAML (strings quoted and escaped as YAML requires, so a
sensor id like ``lab "A"`` or ``rig\new`` reads back unchanged); comment lines
are escaped so no name can end them.  Numbers are written at their shortest
faithful precision: the shortest decimal that reads back to the same double in
YAML (Python's ``repr``), and to the same ``float`` in C (the C constants are
single precision).
"""

from __future__ import annotations

import json

import numpy as np

from wheelcal.calibration.session_json import (
    SENSOR_CALIBRATION_FORMAT,
    load_correction_from,
    partial_axes,
)


def _c_float(value: float) -> str:
    """A C float literal, shortest that gives the same float (``0.0f``, never ``0f``)."""
    text = np.format_float_positional(np.float32(value), unique=True, trim="0")
    if len(text) > 12:  # tiny or huge: scientific is shorter
        text = np.format_float_scientific(np.float32(value), unique=True, trim="0")
    return text + "f"


def origin(calibration: dict) -> str:
    """Where a calibration comes from: the session's file, or the sensor and its sessions."""
    if calibration.get("format") == SENSOR_CALIBRATION_FORMAT:
        pooling = calibration.get("pooling", {})
        n = pooling.get("sessions", "?")
        method = str(pooling.get("method", "pooled")).replace("_", " ")
        return f"sensor {calibration.get('sensor_id', '?')}, pooled from {n} sessions ({method})"
    return str(calibration.get("source", {}).get("file", "?"))


def _partial_note(calibration: dict) -> list[str]:
    """Comment lines for axes left unchanged because a parameter was undetermined."""
    axes = partial_axes(calibration)
    if not axes:
        return []
    return [
        f"PARTIAL: axis {', '.join(axes)} is left unchanged (identity row: gain 1, offset 0);",
        "this recording could not determine its gain or offset (sensor.undetermined)",
    ]


def _comment(text: str) -> str:
    """``text`` made safe for one comment line (YAML ``#`` or C ``/* */``): escapes, no breaks."""
    line = json.dumps(str(text), ensure_ascii=True)[1:-1]  # \n, \u2028, quotes … escaped
    return line.replace("*/", "*\\/")


def _yaml_number(value) -> float | None:
    return None if value is None or not np.isfinite(value) else float(value)


def _kalibr_noise(calibration: dict) -> tuple[dict, list[str]]:
    """Kalibr's accelerometer keys, and comment lines saying where each comes from."""
    fit = calibration.get("fit", {})
    allan = fit.get("allan")
    rate = calibration.get("source", {}).get("rate_hz") or (allan or {}).get("rate_hz")
    keys = {
        "accelerometer_noise_density": None,
        "accelerometer_random_walk": None,
        "update_rate": _yaml_number(rate),
    }
    if not allan:
        notes = [
            "accelerometer_noise_density, accelerometer_random_walk: null — the recording has "
            "no rest (the sensor still before the push or after the stop) to read an Allan "
            "deviation from; record ≥ 10 s of rest, or fill them in from your sensor's own",
        ]
        return keys, notes
    density = max(allan["white_noise_density_mps2_rthz"])
    walk = max(allan["random_walk_mps3_rthz"])
    keys["accelerometer_noise_density"] = _yaml_number(density)
    keys["accelerometer_random_walk"] = _yaml_number(walk)
    read = (
        "read at tau = 1 s"
        if allan["white_noise_read_at_1s"]
        else ("extrapolated along the -1/2 slope: the rests do not reach tau = 1 s")
    )
    seen = all(allan["random_walk_seen"])
    notes = [
        f"from the overlapping Allan deviation of {allan['rests_s']:.3g} s of rests at "
        f"{allan['rate_hz']:.6g} Hz (largest axis; per axis under imu0.accelerometer.allan):",
        f"  accelerometer_noise_density [m/s^2/sqrt(Hz)]: white noise, {read}",
        "  accelerometer_random_walk [m/s^3/sqrt(Hz)]: "
        + (
            "from the +1/2 slope at the longest tau"
            if seen
            else "an UPPER BOUND, min over tau of sigma(tau)*sqrt(3/tau): the rests are too "
            "short to show the random walk"
        ),
    ]
    return keys, notes


def yaml_document(calibration: dict) -> dict:
    """The exported YAML's content: Kalibr's ``imu.yaml`` keys and wheelcal's ``imu0`` block."""
    corr = load_correction_from(calibration)
    src = calibration.get("source", {})
    sensor = calibration.get("sensor", {})
    systematic = calibration.get("systematic", {})
    fit = calibration.get("fit", {})
    noise = fit.get("noise_std_mps2", [None] * 3)
    kalibr, _ = _kalibr_noise(calibration)
    accelerometer = {
        "bias_mps2": [float(v) for v in corr.bias_mps2],
        "matrix": [[float(v) for v in row] for row in corr.matrix],
        "offset_mps2": _list(sensor.get("offset_mps2", corr.bias_mps2)),
        "offset_std_mps2": _list(sensor.get("offset_std_mps2", [None] * 3)),
        "gain": _list(sensor.get("gain", 1 / np.diag(corr.matrix))),
        "gain_std": _list(sensor.get("gain_std", [None] * 3)),
        "systematic_offset_std_mps2": _list(systematic.get("offset_std_mps2", [None] * 3)),
        "systematic_gain_std": _list(systematic.get("gain_std", [None] * 3)),
        "noise_std_mps2": _list(noise),
    }
    allan = fit.get("allan")
    if allan:
        accelerometer["allan"] = {
            key: allan[key]
            for key in (
                "rests_s",
                "white_noise_density_mps2_rthz",
                "white_noise_read_at_1s",
                "bias_instability_mps2",
                "bias_instability_is_floor",
                "random_walk_mps3_rthz",
                "random_walk_seen",
            )
        }
    topic = src.get("topic") or "/imu/data_raw"
    return {
        **{k: v for k, v in kalibr.items() if k != "update_rate"},
        "rostopic": topic,
        "update_rate": kalibr["update_rate"],
        **kalibr_scale_misalignment(calibration),
        "imu0": {
            "rostopic": topic,
            "sensor_id": str(src.get("sensor_id") or calibration.get("sensor_id") or ""),
            "accelerometer": accelerometer,
            "calibration_equation": "a = matrix @ (v - bias)",
            **_gyroscope_yaml(calibration),
        },
    }


def lower_times_rotation(matrix) -> tuple[np.ndarray, np.ndarray]:
    """M = L Q: L lower triangular with a positive diagonal, Q a proper rotation.

    Kalibr's ``scale-misalignment`` gyro reads ``M_gyro C_gyro_i ω + A C_gyro_i a + b``
    with ``M_gyro`` lower triangular and ``C_gyro_i`` a rotation: the QR
    decomposition of Mᵀ (Mᵀ = Q' R', so M = R'ᵀ Q'ᵀ), signs fixed so that L's
    diagonal is positive.  Raises ValueError when det M ≤ 0 (not a rotation's).
    """
    m = np.asarray(matrix, dtype=float).reshape(3, 3)
    if not np.linalg.det(m) > 0:
        raise ValueError("the gyro's matrix has det ≤ 0: no lower-triangular × rotation form")
    q, r = np.linalg.qr(m.T)
    signs = np.sign(np.diag(r))
    lower = np.tril((signs[:, None] * r).T) + 0.0  # exact zeros above the diagonal
    rotation = (q * signs).T
    return lower, rotation


def kalibr_scale_misalignment(calibration: dict) -> dict:
    """Kalibr's ``scale-misalignment`` IMU model keys, or ``{}`` without the gyro's matrix.

    ``accelerometers.M`` = the accelerometer's response (v = M a + b: the inverse of
    the correction matrix, lower triangular as Kalibr's); ``gyroscopes.M`` and
    ``C_gyro_i`` from M = M_gyro C_gyro_i (:func:`lower_times_rotation`); ``A`` =
    G C_gyro_iᵀ (zeros when G is not determined).  The biases are Kalibr's own
    states (estimated online): wheelcal's are in ``imu0``.
    """
    from wheelcal.calibration.gyro_apply import gyro_correction_from

    gyro = gyro_correction_from(calibration)
    if gyro is None:
        return {}
    corr = load_correction_from(calibration)
    lower, rotation = lower_times_rotation(gyro.response)
    g = gyro.g_sensitivity if gyro.g_sensitivity is not None else np.zeros((3, 3))
    return {
        "model": "scale-misalignment",
        "accelerometers": {"M": _rows(np.linalg.inv(corr.matrix))},
        "gyroscopes": {
            "M": _rows(lower),
            "A": _rows(g @ rotation.T),
            "C_gyro_i": _rows(rotation),
        },
    }


def _rows(matrix) -> list:
    return [[float(v) for v in row] for row in np.asarray(matrix, dtype=float)]


def _gyroscope_yaml(calibration: dict) -> dict:
    """``imu0.gyroscope``: the pooled gyro's M, b, G and correction (``{}`` without them)."""
    from wheelcal.calibration.gyro_apply import gyro_correction_from

    gyro = gyro_correction_from(calibration)
    if gyro is None:
        return {}
    block = calibration["gyro"]
    return {
        "gyroscope": {
            "bias_radps": [float(v) for v in gyro.bias_radps],
            "matrix": _rows(gyro.matrix),
            "response_matrix": _rows(gyro.response),
            "response_matrix_std": [[_yaml_number(v) for v in row] for row in block["matrix_std"]],
            "bias_std_radps": _list(block.get("bias_std_radps", [None] * 3)),
            "g_sensitivity_radps_per_mps2": None
            if gyro.g_sensitivity is None
            else _rows(gyro.g_sensitivity),
            "calibration_equation": "omega = matrix @ (g - bias - g_sensitivity @ a)",
            "reading_equation": "g = response_matrix @ omega + bias + g_sensitivity @ a",
        }
    }


def _list(values) -> list:
    return [_yaml_number(v) for v in values]


def to_yaml(calibration: dict) -> str:
    """Kalibr ``imu.yaml`` keys plus wheelcal's ``imu0`` block, written by PyYAML.

    Every string (topic, sensor id, file names in the comments) goes through
    the YAML library or is escaped, so hostile names read back unchanged.
    """
    import yaml

    _, notes = _kalibr_noise(calibration)
    header = [
        f"wheelcal calibration ({calibration['format']}) of {origin(calibration)}",
        "corrected specific force, sensor frame: a = matrix @ (v - bias)  [m/s^2]",
        *_partial_note(calibration),
        "Kalibr imu.yaml keys at the top level (gyroscope_* are not measured by wheelcal);",
        *notes,
        *_gyro_yaml_notes(calibration),
    ]
    body = yaml.safe_dump(
        yaml_document(calibration),
        sort_keys=False,
        default_flow_style=None,  # [x, y, z] rows, nested maps in block style
        allow_unicode=False,
        width=1_000_000,
    )
    return "".join(f"# {_comment(line)}\n" for line in header) + body


def _gyro_yaml_notes(calibration: dict) -> list[str]:
    """Comment lines: the gyro's intrinsics exported, or why not."""
    from wheelcal.calibration.gyro_apply import gyro_correction_from, why_no_gyro_correction

    if gyro_correction_from(calibration) is not None:
        return [
            "gyro intrinsics (pooled over the mountings): model, accelerometers, gyroscopes "
            "in Kalibr's scale-misalignment form (g = M_gyro C_gyro_i w + A C_gyro_i a + b); "
            "wheelcal's imu0.gyroscope: w = matrix @ (g - bias - g_sensitivity @ a) [rad/s]",
        ]
    if calibration.get("gyro"):
        return [f"no gyro intrinsics: {why_no_gyro_correction(calibration)}"]
    return []


def _imu_tk_triad(correction, bias) -> str:
    """imu_tk's ``CalibratedTriad`` file: T (unit diagonal), K (diagonal), B; X' = T K (X − B).

    ``CalibratedTriad_::load`` reads 9 + 9 + 3 numbers (row-major), whitespace
    between; no comments (they would be read as numbers).  T K = ``correction``:
    K = its diagonal, T = correction K⁻¹.
    """
    c = np.asarray(correction, dtype=float)
    scale = np.diag(np.diag(c))
    misalignment = c @ np.linalg.inv(scale)

    def rows(m) -> str:
        return "\n".join(" ".join(repr(float(v)) for v in row) for row in np.atleast_2d(m))

    bias_rows = "\n".join(repr(float(v)) for v in np.asarray(bias, dtype=float))
    return f"{rows(misalignment)}\n\n{rows(scale)}\n\n{bias_rows}\n\n"


def to_imu_tk(calibration: dict, sensor: str) -> str:
    """imu_tk's calibration file of the accelerometer (``"acc"``) or the gyro (``"gyro"``)."""
    from wheelcal.calibration.gyro_apply import gyro_correction_from, why_no_gyro_correction

    if sensor == "acc":
        corr = load_correction_from(calibration)
        return _imu_tk_triad(corr.matrix, corr.bias_mps2)
    if sensor != "gyro":
        raise ValueError(f"imu_tk exports 'acc' or 'gyro', got {sensor!r}")
    gyro = gyro_correction_from(calibration)
    if gyro is None:
        raise ValueError(f"no gyro intrinsics to export: {why_no_gyro_correction(calibration)}")
    return _imu_tk_triad(gyro.matrix, gyro.bias_radps)


def to_imu_calib(calibration: dict) -> str:
    """The ``imu_calib`` ROS package's calibration file (``SM``, ``bias``), by PyYAML.

    ``imu_calib`` corrects ``a = SM · v − bias`` (``apply_calib``); the
    contract's ``a = M (v − b)`` is the same with ``SM = M`` (row-major, 9
    values) and ``bias = M b``.
    """
    import yaml

    corr = load_correction_from(calibration)
    matrix = np.asarray(corr.matrix, dtype=float)
    doc = {
        "SM": [float(v) for v in matrix.reshape(-1)],
        "bias": [float(v) for v in matrix @ np.asarray(corr.bias_mps2, dtype=float)],
    }
    header = [
        f"wheelcal calibration ({calibration['format']}) of {origin(calibration)}",
        "imu_calib layout: a = SM * v - bias  (SM row-major; bias = SM * wheelcal's bias_mps2)",
        *_partial_note(calibration),
    ]
    body = yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=1_000_000)
    return "".join(f"# {_comment(line)}\n" for line in header) + body


def to_c_header(calibration: dict, prefix: str = "WHEELCAL") -> str:
    """A C header with the bias, the matrix and an inline correction function."""
    if not prefix.isidentifier():
        raise ValueError(f"C prefix must be an identifier, got {prefix!r}")
    corr = load_correction_from(calibration)
    src = calibration.get("source", {})
    guard = f"{prefix}_ACCEL_CALIBRATION_H"
    rows = ",\n".join("    {" + ", ".join(map(_c_float, row)) + "}" for row in corr.matrix)
    bias = ", ".join(map(_c_float, corr.bias_mps2))
    where = _comment(
        "  ".join(
            [
                origin(calibration),
                f"topic: {src.get('topic', '?')}",
                f"sensor: {src.get('sensor_id', '')}",
            ]
        )
    )
    fn = prefix.lower()
    partial = "".join(f"\n * {_comment(line)}" for line in _partial_note(calibration))
    return f"""/* Accelerometer calibration generated by wheelcal ({calibration["format"]}).
 * Source: {where}
 * a = M (v - b): v raw sample [m/s^2], a corrected specific force [m/s^2], sensor frame.{partial}
 */
#ifndef {guard}
#define {guard}

static const float {prefix}_ACCEL_BIAS_MPS2[3] = {{{bias}}};

static const float {prefix}_ACCEL_MATRIX[3][3] = {{
{rows}
}};

/* Correct one raw sample v (m/s^2) into a (m/s^2). */
static inline void {fn}_accel_correct(const float v[3], float a[3])
{{
    const float d0 = v[0] - {prefix}_ACCEL_BIAS_MPS2[0];
    const float d1 = v[1] - {prefix}_ACCEL_BIAS_MPS2[1];
    const float d2 = v[2] - {prefix}_ACCEL_BIAS_MPS2[2];
    for (int i = 0; i < 3; ++i) {{
        a[i] = {prefix}_ACCEL_MATRIX[i][0] * d0 + {prefix}_ACCEL_MATRIX[i][1] * d1
             + {prefix}_ACCEL_MATRIX[i][2] * d2;
    }}
}}
{_c_gyro_section(calibration, prefix)}
#endif /* {guard} */
"""


def _c_gyro_section(calibration: dict, prefix: str) -> str:
    """The gyro's bias, matrices and ``<prefix>_gyro_correct()`` (empty without them)."""
    from wheelcal.calibration.gyro_apply import gyro_correction_from, why_no_gyro_correction

    gyro = gyro_correction_from(calibration)
    if gyro is None:
        if not calibration.get("gyro"):
            return ""
        return f"\n/* No gyro correction: {_comment(why_no_gyro_correction(calibration))} */\n"
    g = gyro.g_sensitivity if gyro.g_sensitivity is not None else np.zeros((3, 3))

    def matrix(m) -> str:
        return ",\n".join("    {" + ", ".join(map(_c_float, row)) + "}" for row in m)

    bias = ", ".join(map(_c_float, gyro.bias_radps))
    fn = prefix.lower()
    return f"""
/* Gyroscope (pooled over the mountings): w = M (g - b - G a), g raw rate [rad/s], a the
 * corrected specific force [m/s^2] of {fn}_accel_correct(), w [rad/s], sensor frame. */
static const float {prefix}_GYRO_BIAS_RADPS[3] = {{{bias}}};

static const float {prefix}_GYRO_MATRIX[3][3] = {{
{matrix(gyro.matrix)}
}};

static const float {prefix}_GYRO_G_SENSITIVITY[3][3] = {{
{matrix(g)}
}};

/* Correct one raw rate g (rad/s) into w (rad/s), a the corrected specific force. */
static inline void {fn}_gyro_correct(const float g[3], const float a[3], float w[3])
{{
    float d[3];
    for (int i = 0; i < 3; ++i) {{
        d[i] = g[i] - {prefix}_GYRO_BIAS_RADPS[i] - ({prefix}_GYRO_G_SENSITIVITY[i][0] * a[0]
             + {prefix}_GYRO_G_SENSITIVITY[i][1] * a[1] + {prefix}_GYRO_G_SENSITIVITY[i][2] * a[2]);
    }}
    for (int i = 0; i < 3; ++i) {{
        w[i] = {prefix}_GYRO_MATRIX[i][0] * d[0] + {prefix}_GYRO_MATRIX[i][1] * d[1]
             + {prefix}_GYRO_MATRIX[i][2] * d[2];
    }}
}}
"""
