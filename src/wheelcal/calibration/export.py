r"""Calibration exports: Kalibr's ``imu.yaml``, ``imu_calib``'s file, and a C header.

All carry the contract's correction, a = M (v − b) in the sensor frame, with
b in m/s² and M dimensionless (row-major).  A session's calibration
(``wheelcal.calibration/1``) and a sensor's pooled one
(``wheelcal.sensor_calibration/1``) export alike.

* ``yaml``: Kalibr's ``imu.yaml`` keys at the top level — the accelerometer's
  and the gyroscope's ``*_noise_density`` (the white noise's σ per sample /
  √rate, Kalibr's definition) and ``*_random_walk`` (the rests' Allan bound,
  marked as one), from ``imu_noise`` (:mod:`wheelcal.calibration.imu_noise`;
  a key that cannot be filled is left out and a comment says why),
  ``update_rate`` and ``rostopic`` — and wheelcal's ``imu0`` block
  (``accelerometer.bias_mps2``, ``matrix``, statistical and systematic σ, the
  per-axis Allan read-outs, ``noise``: the per-axis noise terms);
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

from wheelcal.calibration.imu_noise import ALLAN_VARIANCE_ROS_NAMES, KALIBR_KEYS, kalibr_values
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


def _update_rate(calibration: dict) -> float | None:
    """Kalibr's ``update_rate``: the recording's median sample rate (Hz)."""
    fit = calibration.get("fit", {})
    rate = (
        calibration.get("source", {}).get("rate_hz")
        or (calibration.get("imu_noise") or {}).get("rate_hz")
        or (fit.get("allan") or {}).get("rate_hz")
    )
    return _yaml_number(rate)


def kalibr_keys(calibration: dict) -> dict[str, tuple[float, str] | None]:
    """Kalibr's four noise keys (largest axis) with the note each carries, ``None`` if unknown.

    From the calibration's ``imu_noise`` (:mod:`wheelcal.calibration.imu_noise`: the
    white noise's σ per sample / √rate, the rests' Allan bound on the random walk).
    A file written before ``imu_noise`` existed gives the accelerometer's: its fit's σ
    per sample / √rate and ``fit.allan``'s bound.
    """
    keys = kalibr_values(calibration)
    if calibration.get("imu_noise"):
        return keys
    fit = calibration.get("fit", {})
    rate, noise = _update_rate(calibration), fit.get("noise_std_mps2")
    if rate and noise and all(v is not None for v in noise):
        keys["accelerometer_noise_density"] = (
            float(max(noise)) / float(np.sqrt(rate)),
            "sigma of the fit's noise model per sample / sqrt(rate)",
        )
    allan = fit.get("allan")
    if allan and all(v is not None for v in allan.get("random_walk_mps3_rthz", [None])):
        seen = all(allan.get("random_walk_seen", [False]))
        keys["accelerometer_random_walk"] = (
            float(max(allan["random_walk_mps3_rthz"])),
            "from the +1/2 slope of the rests' Allan deviation"
            if seen
            else "UPPER BOUND (min over tau of sigma(tau)*sqrt(3/tau) of the rests' Allan "
            "deviation): conservative",
        )
    return keys


#: Why a Kalibr key is missing, by its sensor (Kalibr's reader then names the field).
_MISSING = {
    "accelerometer": "the recording has no rest and no usable residual noise",
    "gyroscope": "this calibration has no gyroscope",
}
_WALK_MISSING = "no rest to read an Allan deviation from: record >= 10 s of rest"


def kalibr_lines(calibration: dict) -> tuple[list[str], list[str]]:
    """Kalibr's keys as ``key: value  # note`` lines, and comments for the keys left out.

    A key wheelcal cannot fill is left out rather than written ``null`` or 0 (Kalibr's
    reader refuses both — ``null`` cannot be compared, 0 is "invalid"): its reader then
    names the missing field, and the comment here says what to put in.
    """
    import yaml

    lines, missing = [], []
    for key, found in kalibr_keys(calibration).items():
        kind, what = KALIBR_KEYS[key]
        if found is None:
            why = _WALK_MISSING if what == "random_walk" and kind != "gyroscope" else _MISSING[kind]
            if what == "random_walk" and kind == "gyroscope" and calibration.get("gyro"):
                why = _WALK_MISSING
            missing.append(f"{key}: not written ({why}); put in your sensor's own value")
            continue
        value, note = found
        scalar = yaml.safe_dump(float(value), default_style=None).splitlines()[0]
        also = ALLAN_VARIANCE_ROS_NAMES[key]
        lines.append(f"{key}: {scalar}  # {_comment(note)} (allan_variance_ros: {also})")
    return lines, missing


def yaml_document(calibration: dict) -> dict:
    """The exported YAML's content: Kalibr's ``imu.yaml`` keys and wheelcal's ``imu0`` block."""
    corr = load_correction_from(calibration)
    src = calibration.get("source", {})
    sensor = calibration.get("sensor", {})
    systematic = calibration.get("systematic", {})
    fit = calibration.get("fit", {})
    noise = fit.get("noise_std_mps2", [None] * 3)
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
    imu0 = {
        "rostopic": topic,
        "sensor_id": str(src.get("sensor_id") or calibration.get("sensor_id") or ""),
        "accelerometer": accelerometer,
        "calibration_equation": "a = matrix @ (v - bias)",
        **_gyroscope_yaml(calibration),
    }
    noise_block = imu0_noise(calibration)
    if noise_block:
        imu0["noise"] = noise_block
    return {
        **{key: found[0] for key, found in kalibr_keys(calibration).items() if found},
        "rostopic": topic,
        "update_rate": _update_rate(calibration),
        **kalibr_scale_misalignment(calibration),
        "imu0": imu0,
    }


def imu0_noise(calibration: dict) -> dict:
    """``imu0.noise``: the ``imu_noise`` block per axis (white σ, densities, walks, sources)."""
    block = calibration.get("imu_noise") or {}
    out = {}
    for kind in ("accelerometer", "gyroscope"):
        sensor = block.get(kind)
        if sensor:
            out[kind] = {k: v for k, v in sensor.items() if k != "sessions"}
    return out


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

    lines, missing = kalibr_lines(calibration)
    header = [
        f"wheelcal calibration ({calibration['format']}) of {origin(calibration)}",
        "corrected specific force, sensor frame: a = matrix @ (v - bias)  [m/s^2]",
        *_partial_note(calibration),
        "Kalibr imu.yaml keys at the top level (ImuParameters: rostopic, update_rate, "
        "accelerometer_* and gyroscope_* noise_density [unit/sqrt(Hz)] and random_walk "
        "[unit/s/sqrt(Hz)]; m/s^2 and rad/s);",
        "noise density = the white noise's sigma per sample / sqrt(update_rate), Kalibr's "
        "definition; the Allan deviation at tau = 1 s is its check (imu0.noise);",
        "allan_variance_ros writes the same keys (its log's names in each key's comment)",
        *missing,
        *_gyro_yaml_notes(calibration),
    ]
    document = yaml_document(calibration)
    rest = {k: v for k, v in document.items() if k not in KALIBR_KEYS}
    body = yaml.safe_dump(
        rest,
        sort_keys=False,
        default_flow_style=None,  # [x, y, z] rows, nested maps in block style
        allow_unicode=False,
        width=1_000_000,
    )
    head = "".join(f"# {_comment(line)}\n" for line in header)
    return head + "".join(f"{line}\n" for line in lines) + body


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
