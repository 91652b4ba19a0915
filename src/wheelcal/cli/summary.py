"""Short human summaries of a calibration for the terminal."""

from __future__ import annotations

import numpy as np

from wheelcal.calibration import SessionOutcome
from wheelcal.model import AXES


def _pm(value: float, std: float, sys_std: float, digits: int) -> str:
    std_txt = "∞" if not np.isfinite(std) else f"{std:.{digits}f}"
    return f"{value:+.{digits}f} ± {std_txt} (sys {sys_std:.{digits}f})"


def session_summary(outcome: SessionOutcome) -> str:
    """A few lines: window, parameters ± σ (and systematic σ), residual vs noise, warnings."""
    if not outcome.ok:
        return f"FAILED  {outcome.error}"
    session = outcome.session
    r = session.result
    reason = session.window.reason
    sys = dict(zip(r.systematic.names, r.systematic.total_std, strict=True))
    w0, w1 = r.window_s
    omega = r.params.spin.omega_at(r.centred_time_s[[0, -1]])
    spin = f"ω {omega[0]:+.2f} → {omega[1]:+.2f} rad/s"
    gyro = session.window.recording.gyro_radps
    if session.model == "field" and gyro is not None:
        spin = f"ω from the gyroscope, up to {np.max(np.linalg.norm(gyro, axis=1)):.1f} rad/s"
    lines = [
        f"{outcome.source}  topic {r.topic or '-'}",
        f"  window {w0:.2f}–{w1:.2f} s, {r.time_s.size} samples, {spin}"
        + (f"  [{reason}]" if reason else ""),
    ]
    lines.append("  " + geometry_line(session))
    undetermined = set(session.undetermined)

    def show(name: str, digits: int) -> str:
        if name in undetermined:
            return "undetermined (null)"
        return _pm(r.value_of(name), r.std_of(name), sys[name], digits)

    for axis in AXES:
        g, o = f"gain_{axis}", f"offset_{axis}_mps2"
        lines.append(f"  {axis}: gain {show(g, 5)}   offset {show(o, 4)} m/s²")
    if "tilt_deg" in r.names:
        lines.append(
            f"  tilt {_pm(r.value_of('tilt_deg'), r.std_of('tilt_deg'), sys['tilt_deg'], 3)}°"
        )
    if "radius_m" in r.names:
        lines.append(
            f"  radius {r.value_of('radius_m'):.4f} ± {r.std_of('radius_m'):.4f} m (estimated)"
        )
    euler = [r.value_of(f"euler_{k}_deg") for k in (1, 2, 3)]
    euler_std = [r.std_of(f"euler_{k}_deg") for k in (1, 2, 3)]
    lines.append(
        "  misalignment (ZYX) "
        + ", ".join(f"{e:.3f} ± {s:.3f}°" for e, s in zip(euler, euler_std, strict=True))
    )
    noise = r.noise
    colour = "white" if noise.order == 0 else f"coloured, AR({noise.order})"
    lines.append(
        "  residual rms "
        + " ".join(f"{x:.4f}" for x in r.residual_rms_mps2)
        + " m/s² vs noise "
        + " ".join(f"{x:.4f}" for x in noise.marginal_std_mps2)
        + f" ({colour}, effective samples {100 * np.mean(noise.effective_sample_fraction):.0f} %)"
    )
    lines.append("  " + model_line(outcome))
    verdict = noise_verdict(session.assessment)
    if verdict:
        lines.append("  " + verdict)
    for warning in session.warnings:
        lines.append(f"  warning: {warning}")
    for note in r.notes:
        lines.append(f"  note: {note}")
    lines.append(
        f"  → {outcome.calibration_path}" + (f", {outcome.rrd_path}" if outcome.rrd_path else "")
    )
    return "\n".join(lines)


def geometry_line(session) -> str:
    """One line: the geometry fitted, whether it was given or read from the data, and why."""
    line = f"geometry {session.geometry} ({session.geometry_source})"
    return line + (f": {session.geometry_reason}" if session.geometry_reason else "")


def model_line(outcome: SessionOutcome) -> str:
    """One line: what the closed loop added (each with χ² and p), or that nothing was needed."""
    d = outcome.session.diagnosis
    if outcome.session.model == "field":
        return (
            "model: the field fit — the wheel's angle from the gyroscope, the hub's travel and "
            "the carrier's turns where it rolls (rolling model, camber from the turns)"
        )
    if d is None:
        return "model: the paper's (--model paper: no screen for effects it lacks)"
    tested = sum(t.identifiable for t in d.final_tests)
    if not d.steps:
        return (
            f"model: the paper's — the screen found none of {tested} candidate effects "
            f"(family-wise α = {d.alpha:g})"
        )
    found = ", ".join(
        f"{s.test.effect.label()} (χ² = {s.test.statistic:.0f}, {p_text(s.test.p_corrected)})"
        for s in d.steps
    )
    return f"model: the paper's + {found} (closed loop, family-wise α = {d.alpha:g})"


def p_text(p: float) -> str:
    """``p = 3e-05``, or ``p < 1e-300`` where it underflows."""
    return "p < 1e-300" if p <= 0 else f"p = {p:.1g}"


def noise_verdict(a) -> str:
    """One line: the residual against the independent noise floor (empty without one).

    ``a`` is the session's :class:`~wheelcal.session.gates.Assessment`.
    """
    if a.noise is None:
        return ""
    noise = a.noise
    where = "the rests" if noise.source == "rests" else "the spectrum between the wheel harmonics"
    floor = " ".join(f"{x:.4f}" for x in noise.floor_mps2)
    ratio = float(max(noise.ratio))
    if ratio <= a.gates.unexplained_ratio:
        return (
            f"verdict: the residual is at the sensor's noise floor ({floor} m/s², from {where}; "
            f"at most {ratio:.2f}×)"
        )
    unexplained = " ".join(f"{x:.4f}" for x in noise.unexplained_mps2)
    return (
        f"verdict: the residual is {ratio:.1f}× the sensor's noise floor ({floor} m/s², from "
        f"{where}): {unexplained} m/s² unexplained"
    )


def diagnosis_summary(outcome: SessionOutcome) -> str:
    """The closed loop in a few lines: each step, what was not identifiable, before/after.

    A wheel in the field is fitted by the field fit, which has no closed loop: its
    calibration is summarised, and the summary says the steps are for bench spins.
    """
    d = outcome.session.diagnosis
    if d is None:
        return "\n".join(
            [
                session_summary(outcome),
                f"  no step-by-step diagnosis: this recording was fitted as a wheel in the "
                f"field ({outcome.session.model} fit, geometry {outcome.session.geometry}); the "
                "closed loop's steps are for bench spins",
            ]
        )
    lines = [f"{outcome.source}: {len(d.steps)} effect(s) added (family-wise α = {d.alpha:g})"]
    for step in d.steps:
        t = step.test
        rms = " ".join(f"{x:.4f}" for x in step.result.residual_rms_mps2)
        lines.append(
            f"  + {t.effect.label():<32} χ²={t.statistic:9.1f} dof={t.dof}  "
            f"p={t.p_corrected:.2g} (corrected)  residual rms {rms} m/s²"
        )
    if d.not_identifiable:
        names = ", ".join(sorted({t.effect.name for t in d.not_identifiable}))
        lines.append(f"  not identifiable from this recording: {names}")
    bias = d.base_bias_sigma()
    if d.steps and bias:
        worst = sorted(bias.items(), key=lambda kv: -abs(kv[1]))[:4]
        lines.append(
            "  the paper's model was off by (σ): " + ", ".join(f"{k} {v:+.1f}" for k, v in worst)
        )
    base_rms = " ".join(f"{x:.4f}" for x in d.base.residual_rms_mps2)
    final_rms = " ".join(f"{x:.4f}" for x in d.final.residual_rms_mps2)
    lines.append(f"  residual rms: paper's model {base_rms} → final {final_rms} m/s²")
    lines.append(f"  → {outcome.diagnosis_path}, {outcome.calibration_path}")
    verdict = noise_verdict(outcome.session.assessment)
    if verdict:
        lines.append("  " + verdict)
    return "\n".join(lines)
