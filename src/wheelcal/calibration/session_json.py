"""``<stem>.calibration.json`` — the contract's per-session calibration file.

Written atomically.  Keys follow the contract (docs/guide/outputs.md); additions are
additive (``parameters``, ``geometry``, ``fit.noise_model``, ``fit.twin``,
``bench.radius_std_m``, ``wheelcal_version``, ``imu_noise``: Kalibr's noise terms,
:mod:`wheelcal.calibration.imu_noise`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from wheelcal import __version__
from wheelcal.calibration.allan_json import rests_allan
from wheelcal.calibration.imu_noise import imu_noise_block
from wheelcal.calibration.values import CalibrationDiagnosis, lean_block
from wheelcal.calibration.values import json_number as _num
from wheelcal.calibration.values import json_numbers as _vec
from wheelcal.estimate import residual_by_wheel_angle
from wheelcal.estimate.joint import CalibrationResult, SystematicBudget
from wheelcal.io import MARK_KEY, atomic_write_text, dumps_indented, origin_of, output_mark
from wheelcal.io import json_safe as _clean
from wheelcal.model import AXES, EULER_CONVENTION, SensorCorrection
from wheelcal.session import Assessment, SessionResult, fitted_stretches

FORMAT = "wheelcal.calibration/1"
#: A sensor's calibration pooled from its sessions (:mod:`wheelcal.calibration.sensor_json`):
#: same ``sensor``/``systematic``/``correction`` keys, so export and apply take either.
SENSOR_CALIBRATION_FORMAT = "wheelcal.sensor_calibration/1"
CORRECTION_FORMATS = (FORMAT, SENSOR_CALIBRATION_FORMAT)
_SYSTEMATIC_NOTE = (
    "shared by every recording of the same bench and clock: repeating does not average it away"
)


class CalibrationFileError(ValueError):
    """A calibration JSON that cannot be used, with the file named."""


def calibration_dict(session: SessionResult, provenance: dict | None = None) -> dict:
    """The contract dictionary for one calibrated session.

    ``provenance`` (input hash, run key) lets a batch re-run skip sessions whose
    output is up to date.  ``session.model`` is what was fitted (``fit.model``: the
    closed loop's final model, or ``"paper"``); its diagnosis (the closed loop's
    report) gives each added effect its evidence and lists what the screen could not
    test; ``fit.warnings`` are the fit's and then the gates'.
    """
    result, assessment = session.result, session.assessment
    undetermined = set(assessment.undetermined_names)
    std = dict(zip(result.names, result.std, strict=True))
    values = dict(zip(result.names, result.values, strict=True))
    for name in undetermined:  # never a usable-looking number
        std[name] = values[name] = float("nan")
    # what the document keeps of the closed loop's report: the one value
    # Calibration.diagnosis is, written by the same blocks
    diagnosis = CalibrationDiagnosis.from_loop(session.diagnosis, session.model)
    return {
        "format": FORMAT,
        "wheelcal_version": __version__,
        MARK_KEY: output_mark(origin_of([result.source]), [result.source]),
        "geometry": session.geometry,
        "provenance": provenance or {},
        "source": _source_block(session),
        "sensor": _sensor_block(values, std, assessment),
        "bench": _bench_block(session, std),
        "motion": _motion_block(result, std),
        "effects": effects_dict(result, diagnosis),
        "parameters": {
            n: {"value": _num(values[n]), "std": _num(std[n])} for n in _reported(result)
        },
        "fit": _fit_block(session, undetermined, diagnosis),
        "systematic": _systematic_block(result.systematic),
        **({"gyro": _clean(assessment.gyro.to_dict())} if assessment.gyro is not None else {}),
        **_imu_noise(session),
        "correction": _correction_block(result, undetermined),
    }


def _imu_noise(session: SessionResult) -> dict:
    """``imu_noise``: Kalibr's noise terms from the rests, else the residuals (imu_noise.py)."""
    result, assessment = session.result, session.assessment
    rests = assessment.noise.rests if assessment.noise is not None else ()
    gyro = assessment.gyro
    block = imu_noise_block(
        rests,
        _rate_hz(result.time_s),
        accel_residual_std=result.noise.marginal_std_mps2,
        accel_samples=int(result.time_s.size),
        gyro_residual_rms=None if gyro is None else gyro.residual_rms_radps,
        gyro_samples=int(result.time_s.size),
    )
    return {} if block is None else {"imu_noise": _clean(block)}


def _source_block(session: SessionResult) -> dict:
    """``source``: the file, topic, samples, rate and window, the session's facts and notes."""
    result = session.result
    return {
        "file": result.source,
        "topic": result.topic,
        "samples": int(result.time_s.size),
        "rate_hz": _rate_hz(result.time_s),
        # sample times are whole nanoseconds: written at that precision (93.645, not
        # 93.64500000000001 from the ns → s conversion)
        "window_s": [round(t, 9) for t in result.window_s],
        "window_reason": session.window.reason,
        # additive: the stretches the fit used (several when pushes or a knock were cut)
        "fitted_stretches_s": [
            [round(a, 9), round(b, 9)]
            for a, b in fitted_stretches(result.time_s, _rate_hz(result.time_s) or 1.0)
        ],
        "sensor_id": result.info.sensor_id,
        "mounting_id": result.info.mounting_id,
        "notes": list(result.notes),
    }


def _sensor_block(values: dict, std: dict, assessment: Assessment) -> dict:
    """``sensor``: offsets and gains with their σ, and what the recording could not determine."""
    return {
        "offset_mps2": [_num(values[f"offset_{a}_mps2"]) for a in AXES],
        "gain": [_num(values[f"gain_{a}"]) for a in AXES],
        "offset_std_mps2": [_num(std[f"offset_{a}_mps2"]) for a in AXES],
        "gain_std": [_num(std[f"gain_{a}"]) for a in AXES],
        "undetermined": [{"parameter": n, "reason": r} for n, r in assessment.undetermined],
    }


def _bench_block(session: SessionResult, std: dict) -> dict:
    """``bench``: geometry (given or detected, why), radius (given or fitted), tilt, spin, R."""
    result = session.result
    params = result.params
    return {
        "geometry": session.geometry,
        "geometry_source": session.geometry_source,
        "geometry_reason": session.geometry_reason,
        "radius_m": _num(params.bench.radius_m),
        "radius_std_m": _num(std.get("radius_m", result.info.radius_std_m)),
        "radius_source": "fitted" if "radius_m" in result.names else "given",
        "tilt_deg": _num(params.bench.tilt_deg),
        "tilt_std_deg": _num(std.get("tilt_deg", 0.0)),
        "spin_sign": 1 if params.spin.omega_radps[0] >= 0 else -1,
        "misalignment_matrix": params.bench.misalignment.matrix.tolist(),
        "misalignment_euler_deg": _vec(params.bench.misalignment.euler_deg()),
        "misalignment_euler_std_deg": [_num(std[f"euler_{k}_deg"]) for k in (1, 2, 3)],
        "euler_convention": EULER_CONVENTION,
        **({"lean": lean_block(session.lean)} if session.lean is not None else {}),
    }


def _motion_block(result: CalibrationResult, std: dict) -> dict:
    """``motion``: the spin polynomial with its σ, and the wheel-angle spline when fitted."""
    params = result.params
    spin = params.spin
    spline = next((e for e in result.layout.effects if e.name == "spin_spline"), None)
    motion = {"model": f"polynomial{spin.degree}", "t0_unix_ns": int(result.t0_unix_ns)}
    if spline is not None:
        motion["model"] += "+spline"
        motion["spline"] = {
            **spline.settings(),
            "coefficients_rad": _vec(params.effect(spline.name, spline.size)),
            "description": spline.description,
        }
    for name, value in spin.to_dict().items():
        motion[name] = _num(value)
        motion[name.replace("_rad", "_std_rad", 1) if name == "theta0_rad" else _std_key(name)] = (
            _num(std[name])
        )
    return motion


def _fit_block(
    session: SessionResult, undetermined: set[str], diagnosis: CalibrationDiagnosis | None
) -> dict:
    """``fit``: model, screen, residual, covariance, warnings, noise model, goodness, gates."""
    result = session.result
    return {
        "model": session.model,
        **({} if diagnosis is None else {"effects_screen": diagnosis.screen_block()}),
        "residual_rms_mps2": _vec(result.residual_rms_mps2),
        "noise_std_mps2": _vec(result.noise.marginal_std_mps2),
        "converged": bool(result.converged),
        "iterations": int(result.iterations),
        "covariance": _covariance(result, undetermined),
        "covariance_names": list(_reported(result)),
        "warnings": list(session.warnings),
        "noise_model": result.noise.to_dict(),
        "twin": {
            "rejected_offset_mps2": _vec(result.twin.rejected.sensor.offset_mps2),
            "ambiguous": bool(result.twin.ambiguous),
        },
        "poorly_determined": list(result.identifiability.poorly_determined),
        "residual_by_wheel_angle": residual_by_wheel_angle(
            result.params.spin.theta_at(result.centred_time_s), result.residual_mps2
        ),
        "goodness": {
            "chi2": _num(result.chi2),
            "entries": int(result.entries),
            "free_parameters": int(result.layout.size),
            "chi2_reduced": _num(result.chi2_reduced),
            "aic": _num(result.aic),
            "bic": _num(result.bic),
        },
        **_assessment(session.assessment),
    }


#: What each systematic source assumes (``systematic.sources.<name>.assumes``).
_SOURCE_ASSUMES = {
    "sample_clock": (
        "the time stamps keep true seconds within ±{std:g} ppm (a crystal clock); a clock "
        "error ε acts as a radius error of −2ε. A stamped rate off its nominal rate, or a "
        "gyro that reads the wheel otherwise, is judged in fit.clock_check"
    ),
}


def _systematic_block(budget: SystematicBudget) -> dict:
    """``systematic``: the budget's total σ, and each unseen source's share."""
    sys_std = dict(zip(budget.names, budget.total_std, strict=True))
    return {
        "gain_std": [_num(sys_std[f"gain_{a}"]) for a in AXES],
        "offset_std_mps2": [_num(sys_std[f"offset_{a}_mps2"]) for a in AXES],
        "tilt_std_deg": _num(sys_std.get("tilt_deg", 0.0)),
        "sources": {
            s.name: {
                "std": _num(s.std),
                "unit": s.unit,
                "gain_std": [_num(v) for v in _pick(s.shift_std, budget.names, "gain")],
                "offset_std_mps2": [_num(v) for v in _pick(s.shift_std, budget.names, "offset")],
                "tilt_std_deg": _num(
                    dict(zip(budget.names, s.shift_std, strict=True)).get("tilt_deg", 0.0)
                ),
                **(
                    {"assumes": _SOURCE_ASSUMES[s.name].format(std=s.std)}
                    if s.name in _SOURCE_ASSUMES
                    else {}
                ),
            }
            for s in budget.sources
        },
        "note": _SYSTEMATIC_NOTE,
    }


def _correction_block(result: CalibrationResult, undetermined: set[str]) -> dict:
    """``correction``: a = matrix @ (v − bias), and the axes it leaves unchanged."""
    correction, identity_axes = _correction(result, undetermined)
    return {
        "bias_mps2": _vec(correction.bias_mps2),
        "matrix": correction.matrix.tolist(),
        "equation": "a = matrix @ (v - bias)",
        **(
            {
                "identity_axes": identity_axes,
                "note": "these axes are left unchanged (gain 1, offset 0): the recording "
                "cannot determine their gain or offset (see sensor.undetermined)",
            }
            if identity_axes
            else {}
        ),
    }


def _correction(result: CalibrationResult, undetermined: set[str]):
    """The correction, with gain 1 / offset 0 on every axis with an undetermined parameter."""
    gain = np.array(result.params.sensor.gain, dtype=float)
    offset = np.array(result.params.sensor.offset_mps2, dtype=float)
    identity = [
        a for a in AXES if f"gain_{a}" in undetermined or f"offset_{a}_mps2" in undetermined
    ]
    for a in identity:
        i = AXES.index(a)
        gain[i], offset[i] = 1.0, 0.0
    return SensorCorrection.from_offset_gain(offset, gain), identity


#: Nuisance parameters kept out of ``parameters`` and ``covariance`` (in ``motion.spline``).
_NUISANCE_PREFIXES = ("spin_spline.",)


def _reported(result: CalibrationResult) -> tuple[str, ...]:
    return tuple(n for n in result.names if not n.startswith(_NUISANCE_PREFIXES))


def _covariance(result: CalibrationResult, undetermined: set[str]) -> list:
    keep = [result.names.index(n) for n in _reported(result)]
    cov = np.array(result.covariance, dtype=float)[np.ix_(keep, keep)]
    names = _reported(result)
    for name in undetermined:
        i = names.index(name)
        cov[i, :] = cov[:, i] = np.nan
    return [[_num(c) for c in row] for row in cov]


def _rate_hz(time_s: np.ndarray) -> float | None:
    """The median sample rate, to 12 digits (``source.rate_hz``, additive: Kalibr's update_rate)."""
    if time_s.size < 2:
        return None
    return float(f"{1.0 / np.median(np.diff(time_s)):.12g}")


def _assessment(a: Assessment) -> dict:
    """``fit`` keys from the gates: noise floor, unexplained residual, rest checks, thresholds."""
    out = {}
    if a.noise is not None:
        out["noise_floor_mps2"] = _vec(a.noise.floor_mps2)
        out["unexplained_mps2"] = _vec(a.noise.unexplained_mps2)
        out["noise_reference"] = _clean(a.noise.to_dict())
        allan = rests_allan(a.noise.rests)
        if allan is not None:
            out["allan"] = allan
    if a.motion is not None:
        out["motion_check"] = _clean(a.motion.to_dict())
    out["rest_checks"] = [_clean(c.to_dict()) for c in a.rest_checks]
    if a.clock is not None:
        out["clock_check"] = _clean(a.clock.to_dict())
    out["gates"] = a.gates.to_dict()
    return out


def effects_dict(result: CalibrationResult, diagnosis: CalibrationDiagnosis | None = None) -> dict:
    """``effects`` block: per effect its parameters (value, std), settings and meaning.

    With the ``diagnosis`` (what the document keeps of the closed loop's report,
    :meth:`CalibrationDiagnosis.from_loop`), each effect it added carries its ``evidence``.
    """
    evidence = (
        {}
        if diagnosis is None
        else {step.name: diagnosis.evidence_block(step) for step in diagnosis.steps}
    )
    std = dict(zip(result.names, result.std, strict=True))
    out = {}
    for effect in result.layout.effects:
        if effect.stage == "gyro" or effect.name == "spin_spline":
            continue  # a measurement and a motion model: see ``gyro`` and ``motion``
        values = result.params.effect(effect.name, effect.size)
        entry = {
            p: {"value": _num(v), "std": _num(std.get(f"{effect.name}.{p}", float("nan")))}
            for p, v in zip(effect.param_names, values, strict=True)
        }
        entry["settings"] = effect.settings()
        entry["description"] = effect.description
        if effect.name in evidence:
            entry["evidence"] = evidence[effect.name]
        out[effect.name] = entry
    return out


def _std_key(name: str) -> str:
    """omega1_radps2 → omega1_std_radps2, theta0_rad → theta0_std_rad."""
    head, _, unit = name.partition("_")
    return f"{head}_std_{unit}"


def _pick(values: np.ndarray, names: tuple[str, ...], prefix: str) -> list[float]:
    picked = [float(v) for n, v in zip(names, values, strict=True) if n.startswith(prefix + "_")]
    return picked or [0.0]


def write_calibration(
    path: str | os.PathLike,
    session: SessionResult,
    provenance: dict | None = None,
    durable: bool = True,
    document: dict | None = None,
) -> Path:
    """Write the calibration JSON atomically; returns the path (``durable``: see atomic).

    ``document``: ``calibration_dict(session, provenance)`` when the caller made it
    already (the session's view reads the same one).
    """
    doc = calibration_dict(session, provenance) if document is None else document
    text = dumps_indented(doc)  # json.dumps(doc, indent=2, allow_nan=False), faster
    atomic_write_text(path, text + "\n", durable=durable)
    return Path(path)


def load_calibration(path: str | os.PathLike, allow_partial: bool = False) -> dict:
    """Read and check a calibration JSON (format tag, correction block).

    Accepts a session's calibration and a sensor's pooled one (:data:`CORRECTION_FORMATS`).
    A calibration with undetermined parameters (``sensor.undetermined``) is
    refused unless ``allow_partial``: its correction leaves those axes
    unchanged, which a user must choose knowingly.
    """
    from wheelcal.io import read_bounded
    from wheelcal.recording import InputError

    try:
        data = json.loads(read_bounded(path, "calibration").decode("utf-8"))
    except FileNotFoundError:
        raise CalibrationFileError(f"{path}: no such calibration file") from None
    except InputError as exc:  # a FIFO, a device, a folder, a file of gigabytes
        raise CalibrationFileError(str(exc)) from None
    except OSError as exc:
        raise CalibrationFileError(f"{path}: cannot be read ({exc.strerror or exc})") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CalibrationFileError(f"{path}: not a calibration JSON ({exc})") from None
    except RecursionError:
        raise CalibrationFileError(f"{path}: not a calibration JSON (nested too deeply)") from None
    return check_calibration(data, path, allow_partial)


def check_calibration(data, path: str | os.PathLike, allow_partial: bool = False) -> dict:
    """The checks of :func:`load_calibration` on a document already read from ``path``.

    The ``format`` tag is the document's type and format version (``<type>/<version>``):
    a known type at another version (a newer wheelcal's) is refused as such.
    """
    tag = data.get("format") if isinstance(data, dict) else None
    if tag not in CORRECTION_FORMATS:
        kind, _, version = str(tag).rpartition("/")
        known = {f.rpartition("/")[0]: f.rpartition("/")[2] for f in CORRECTION_FORMATS}
        if isinstance(tag, str) and kind in known:
            raise CalibrationFileError(
                f"{path}: {kind} format version {version!r}; this wheelcal ({__version__}) "
                f"reads version {known[kind]} ({kind}/{known[kind]}) — was it written by "
                "a newer wheelcal?"
            )
        raise CalibrationFileError(
            f"{path}: not a {' or '.join(CORRECTION_FORMATS)} file "
            "(format tag missing or different)"
        )
    try:
        load_correction_from(data)
    except (KeyError, TypeError, ValueError) as exc:
        raise CalibrationFileError(f"{path}: unusable correction block ({exc})") from None
    missing = [u.get("parameter", "?") for u in data.get("sensor", {}).get("undetermined", [])]
    if missing and not allow_partial:
        raise CalibrationFileError(
            f"{path}: the recording could not determine {', '.join(missing)}; the correction "
            "leaves those axes unchanged (gain 1, offset 0). Use --allow-partial to export or "
            "apply it anyway"
        )
    return data


def partial_axes(data: dict) -> list[str]:
    """Axes the correction leaves unchanged because a parameter was undetermined."""
    return list(data.get("correction", {}).get("identity_axes", []))


def load_correction_from(data: dict) -> SensorCorrection:
    """The correction of a loaded calibration dictionary."""
    block = data["correction"]
    return SensorCorrection(bias_mps2=block["bias_mps2"], matrix=block["matrix"])
