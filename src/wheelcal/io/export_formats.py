"""Calibration exports: ROS/Kalibr-style YAML and a C header for firmware.

Both carry the contract's correction, a = M (v − b) in the sensor frame,
with b in m/s² and M dimensionless (row-major), plus the statistical and
systematic σ of offsets and gains as comments/fields.  A session's calibration
(``wheelcal.calibration/1``) and a sensor's pooled one
(``wheelcal.sensor_calibration/1``) export alike.

Numbers are written at their shortest faithful precision: the shortest decimal
that reads back to the same double in YAML (Python's ``repr``), and to the same
``float`` in C (the C constants are single precision).
"""

from __future__ import annotations

import numpy as np

from wheelcal.io.calibration_json import (
    SENSOR_CALIBRATION_FORMAT,
    load_correction_from,
    partial_axes,
)


def _shortest(value: float) -> str:
    """The shortest decimal that reads back as the same double (``1`` for 1.0, as before)."""
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") else text


def _floats(values) -> str:
    return ", ".join(_shortest(v) for v in np.asarray(values, dtype=float).reshape(-1))


def _c_float(value: float) -> str:
    """A C float literal, shortest that gives the same float (``0.0f``, never ``0f``)."""
    text = np.format_float_positional(np.float32(value), unique=True, trim="0")
    if len(text) > 12:  # tiny or huge: scientific is shorter
        text = np.format_float_scientific(np.float32(value), unique=True, trim="0")
    return text + "f"


def _stds(values) -> str:
    return ", ".join("null" if v is None else _shortest(v) for v in values)


def origin(calibration: dict) -> str:
    """Where a calibration comes from: the session's file, or the sensor and its sessions."""
    if calibration.get("format") == SENSOR_CALIBRATION_FORMAT:
        pooling = calibration.get("pooling", {})
        n = pooling.get("sessions", "?")
        method = str(pooling.get("method", "pooled")).replace("_", " ")
        return f"sensor {calibration.get('sensor_id', '?')}, pooled from {n} sessions ({method})"
    return str(calibration.get("source", {}).get("file", "?"))


def _values(values) -> str:
    return ", ".join("null" if v is None else _shortest(v) for v in values)


def _partial_note(calibration: dict) -> list[str]:
    """Comment lines for axes left unchanged because a parameter was undetermined."""
    axes = partial_axes(calibration)
    if not axes:
        return []
    return [
        f"PARTIAL: axis {', '.join(axes)} is left unchanged (identity row: gain 1, offset 0);",
        "this recording could not determine its gain or offset (sensor.undetermined)",
    ]


def to_yaml(calibration: dict) -> str:
    """ROS/Kalibr-style YAML of a loaded calibration dictionary."""
    corr = load_correction_from(calibration)
    src = calibration.get("source", {})
    sensor = calibration.get("sensor", {})
    systematic = calibration.get("systematic", {})
    noise = calibration.get("fit", {}).get("noise_std_mps2", [None] * 3)
    lines = [
        f"# wheelcal calibration ({calibration['format']}) of {origin(calibration)}",
        "# corrected specific force, sensor frame: a = matrix @ (v - bias)  [m/s^2]",
        *[f"# {line}" for line in _partial_note(calibration)],
        "imu0:",
        f"  rostopic: {src.get('topic') or '/imu/data_raw'}",
        f'  sensor_id: "{src.get("sensor_id", "")}"',
        "  accelerometer:",
        f"    bias_mps2: [{_floats(corr.bias_mps2)}]",
        "    matrix:",
        *[f"      - [{_floats(row)}]" for row in corr.matrix],
        f"    offset_mps2: [{_values(sensor.get('offset_mps2', corr.bias_mps2))}]",
        f"    offset_std_mps2: [{_stds(sensor.get('offset_std_mps2', [None] * 3))}]",
        f"    gain: [{_values(sensor.get('gain', 1 / np.diag(corr.matrix)))}]",
        f"    gain_std: [{_stds(sensor.get('gain_std', [None] * 3))}]",
        f"    systematic_offset_std_mps2: [{_stds(systematic.get('offset_std_mps2', [None] * 3))}]",
        f"    systematic_gain_std: [{_stds(systematic.get('gain_std', [None] * 3))}]",
        f"    noise_std_mps2: [{_stds(noise)}]",
        '  calibration_equation: "a = matrix @ (v - bias)"',
    ]
    return "\n".join(lines) + "\n"


def to_c_header(calibration: dict, prefix: str = "WHEELCAL") -> str:
    """A C header with the bias, the matrix and an inline correction function."""
    if not prefix.isidentifier():
        raise ValueError(f"C prefix must be an identifier, got {prefix!r}")
    corr = load_correction_from(calibration)
    src = calibration.get("source", {})
    guard = f"{prefix}_ACCEL_CALIBRATION_H"
    rows = ",\n".join("    {" + ", ".join(map(_c_float, row)) + "}" for row in corr.matrix)
    bias = ", ".join(map(_c_float, corr.bias_mps2))
    where = "  ".join(
        [
            origin(calibration),
            f"topic: {src.get('topic', '?')}",
            f"sensor: {src.get('sensor_id', '')}",
        ]
    )
    fn = prefix.lower()
    partial = "".join(f"\n * {line}" for line in _partial_note(calibration))
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

#endif /* {guard} */
"""
