"""The plain-text report of ``wheelcal plan`` (returns strings; never prints)."""

from __future__ import annotations

import numpy as np

from wheelcal.plan.mounting import MountingChoice
from wheelcal.plan.planner import PlanReport

_MODE_TEXT = {
    "radius": "radius mode: r measured, tilt fitted",
    "tilt": "tilt mode: tilt measured, r fitted",
    "vertical": "vertical wheel: tilt 90° by spirit level, r fitted",
}


def render(report: PlanReport) -> str:
    """The whole report as a terminal table."""
    parts = [_header(report), _parameters(report), _sources(report)]
    if report.warnings:
        parts.append("Warnings\n" + "\n".join(f"  ! {w}" for w in report.warnings))
    if report.notes:
        parts.append("Notes\n" + "\n".join(f"  - {n}" for n in report.notes))
    if report.mounting is not None:
        parts.append(_mounting(report))
    if report.tradeoffs:
        parts.append(_tradeoffs(report))
    if report.gyro is not None:
        parts.append("Gyroscope\n" + "\n".join(f"  {line}" for line in report.gyro.lines()))
    return "\n\n".join(parts) + "\n"


def _header(report: PlanReport) -> str:
    s = report.setup
    euler = ", ".join(f"{e:.1f}°" for e in s.mounting_euler_deg)
    noise = (
        "white"
        if s.noise_bandwidth_hz is None
        else f"low-pass {s.noise_bandwidth_hz:g} Hz (coloured)"
    )
    tilt = f"tilt {s.tilt_deg:g}°" + (f" ± {s.tilt_std_deg:g}°" if s.geometry != "radius" else "")
    radius = f"r = {s.radius_m:g} m" + (
        f" ± {1e3 * s.radius_std_m:g} mm" if s.geometry == "radius" else ""
    )
    return "\n".join(
        [
            f"wheelcal plan — {_MODE_TEXT[s.geometry]}",
            f"  bench   {radius}, {tilt}, mounting ({euler}) [ZYX, bench → sensor]",
            f"  record  {s.duration_s:g} s at {s.rate_hz:g} Hz ({s.samples} samples), spin "
            f"{s.omega_start_radps:g} → {s.omega_end_radps:g} rad/s (≈ {s.turns:.0f} turns)",
            f"  noise   {s.noise_std_mps2:g} m/s² per sample, {noise}",
            f"  assumed gravity {s.gravity_mps2:g} ± {s.gravity_std_mps2:g} m/s², sample clock "
            f"± {s.clock_std_ppm:g} ppm",
        ]
    )


def _parameters(report: PlanReport) -> str:
    lines = [
        "Predicted 1σ — statistical: Cramér–Rao bound (the σ the joint fit will report);",
        "systematic: from r, tilt, g and clock errors (repeating does not reduce it)",
        f"  {'parameter':<16}{'planned':>11}{'statistical':>14}{'systematic':>13}",
    ]
    systematic = report.budget.total_std
    for name, value, std, sys in zip(
        report.names, report.values, report.std, systematic, strict=True
    ):
        lines.append(f"  {name:<16}{_num(value, 6):>11}{_num(std):>14}{_num(sys):>13}")
    return "\n".join(lines)


def _sources(report: PlanReport) -> str:
    names = report.names
    groups = [
        (label, [i for i, n in enumerate(names) if n.startswith(prefix)])
        for label, prefix in (("gains", "gain_"), ("offsets m/s²", "offset_"))
    ]
    geometry = [i for i, n in enumerate(names) if n in ("tilt_deg", "radius_m")]
    if geometry:
        groups.insert(0, (names[geometry[0]], geometry))
    header = "".join(f"{label:>26}" for label, _ in groups)
    lines = [
        "Systematic sources — worst shift at 1σ of each: first order / second order "
        "(exact null-space map, eq. 9–13)",
        f"  {'source':<22}{header}",
    ]
    for s in report.budget.sources:
        cells = []
        for _, idx in groups:
            first = float(np.max(np.abs(s.first_order[idx])))
            second = np.abs(s.second_order[idx])
            second_txt = (
                "n/a"
                if np.all(np.isnan(second))
                else _num(_above_round_off(float(np.nanmax(second)), first))
            )
            cells.append(f"{_num(first)} / {second_txt}")
        label = f"{s.name} ±{s.std:g} {s.unit}"
        lines.append(f"  {label:<22}" + "".join(f"{c:>26}" for c in cells))
    return "\n".join(lines)


def _choice(label: str, choice: MountingChoice) -> str:
    euler = ", ".join(f"{e:6.1f}°" for e in choice.euler_deg)
    return (
        f"  {label:<24}({euler}) tilt {choice.tilt_deg:5.1f}°   worst offset σ "
        f"{choice.objective:.2g} m/s²   gain σ ≤ {np.max(choice.gain_std):.2g}"
    )


def _mounting(report: PlanReport) -> str:
    m = report.mounting
    what = "statistical" if m.objective == "statistical" else "statistical ⊕ systematic"
    lines = [
        f"Best mounting — minimises the worst-axis offset σ ({what}); Euler angles ZYX",
        _choice("your mounting", m.reference),
        _choice("best at your tilt", m.best_at_plan_tilt)
        + f"   → offset σ {m.improvement_at_plan_tilt:.1f}× smaller",
    ]
    if m.best is not None:
        lines.append(
            _choice("best, tilt free", m.best) + f"   → offset σ {m.improvement:.1f}× smaller"
        )
    lines.append(
        f"  (a mounting chosen at random: worst offset σ ≈ {m.random_median:.2g} m/s², median; "
        f"{m.evaluations} candidates evaluated)"
    )
    return "\n".join(lines)


def _tradeoffs(report: PlanReport) -> str:
    s = report.setup
    lines = [
        "Geometry modes — worst axis, this mounting and these uncertainties "
        f"(radius ±{1e3 * s.radius_std_m:g} mm, tilt ±{s.tilt_std_deg:g}°, "
        f"g ±{s.gravity_std_mps2:g} m/s²)",
        f"  {'mode':<10}{'tilt':>6}{'offset σ':>11}{'offset sys':>12}"
        f"{'gain σ':>10}{'gain sys':>10}{'gain 2nd':>10}",
    ]
    for row in report.tradeoffs:
        mark = " ◀ plan" if (row.geometry, row.tilt_deg) == (s.geometry, s.tilt_deg) else ""
        second = _above_round_off(row.gain_second_order, row.gain_systematic)
        lines.append(
            f"  {row.geometry:<10}{row.tilt_deg:>5g}°{_num(row.offset_std_mps2):>11}"
            f"{_num(row.offset_systematic_mps2):>12}{_num(row.gain_std):>10}"
            f"{_num(row.gain_systematic):>10}{_num(second):>10}{mark}"
        )
    lines += [
        "  radius mode: offset σ and radius-error shifts grow like tan α toward vertical",
        "  tilt mode: a levelling error δ moves gains by cot α·δ, offsets by g δ/sin α",
        "  vertical: offsets move by g δ (0.17 m/s² per degree), gains only by −δ²/2",
    ]
    return "\n".join(lines)


#: A second-order shift is the exact map minus the first order: below this fraction of
#: the first order (or of 1, whichever is larger) it is the subtraction's round-off.
ROUND_OFF = 1e-9


def _above_round_off(value: float, scale: float) -> float:
    """``value``, or 0 where it is round-off of a difference of numbers of size ``scale``."""
    return 0.0 if abs(value) < ROUND_OFF * max(abs(scale), 1.0) else value


def _num(value: float, digits: int = 2) -> str:
    if not np.isfinite(value):
        return "∞"
    if value == 0:
        return "0"
    if 1e-3 <= abs(value) < 1e4:
        return f"{value:.{digits}g}" if abs(value) < 1 else f"{value:.{max(digits, 4)}g}"
    return f"{value:.{digits}g}"
