"""Repeatability report over sessions (the paper's Table II, made automatic).

For every group of sessions sharing ``sensor_id`` and ``mounting_id`` and every
calibrated parameter: mean, std (ddof = 1), the std *predicted* by the
per-session uncertainties (RMS of their σ) and the ratio std / predicted — the
comparison the paper makes by hand in IV-B (its offsets spread 3.5× the
expected value).

* **Is the spread larger than predicted?**  With honest σ,
  (n − 1)·ratio² follows χ²(n − 1); ``ratio_p_value`` is the upper tail.
* **Angles** (the mounting's Euler angles) are averaged as angles: unwrapped about
  their circular mean first (:mod:`wheelcal.calibration.angles`), so 179° and −179°
  average to 180°, not 0°.
* **Outliers**: each session against the others, t = (xᵢ − x̄₋ᵢ) / (s₋ᵢ √(1 + 1/(n−1))),
  Student t with n − 2 dof (externally studentised), Bonferroni-corrected over
  sessions × parameters; flagged when the corrected p < 0.01.

The systematic σ (radius, gravity, clock) is shared by every session of a bench,
so it cannot show in the spread; it is listed separately.

What matters is never only inside JSON: ``report.md`` opens with the sensor's
pooled calibration ("apply this": bias, matrix, σ and the export command), links
the PNG overview, and lists every session with a notes column (samples the
reader dropped or clipped, warnings, undetermined parameters, outliers, and why a
session failed or was refused); ``sessions.csv`` has a row per session, failed
ones included, with the same counts.
"""

from __future__ import annotations

import csv
import io
import math
import re
from collections import defaultdict
from collections.abc import Mapping, Sequence

import numpy as np
from scipy import special

from wheelcal.calibration import Calibration, as_angles, read_only_document
from wheelcal.model import AXES

REPORT_PARAMETERS = (
    "tilt_deg",
    "radius_m",
    "euler_1_deg",
    "euler_2_deg",
    "euler_3_deg",
    *(f"gain_{a}" for a in AXES),
    *(f"offset_{a}_mps2" for a in AXES),
)
OUTLIER_P = 0.01
_NOTES = (
    "std uses ddof = 1; predicted_std is the RMS of the per-session σ; ratio = std / predicted_std",
    "ratio_p_value: chance of a ratio this large if the per-session σ are honest (χ², n−1 dof)",
    "systematic_std is shared by all sessions of a bench and does not show in the spread",
)
_TABLE_HEAD = (
    "| parameter | mean | std | predicted std | ratio | p (ratio) | systematic σ (shared) |\n"
    "|---|---:|---:|---:|---:|---:|---:|"
)
_RATIO_NOTE = (
    "ratio = observed std / std predicted by the per-session uncertainties (≈ 1 when the model "
    "and the σ are right; the paper's IV-B found 3.5 for offsets). ⚠ marks p < 0.01."
)


def _finite(x) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else float(x)


def group_statistics(values: np.ndarray, stds: np.ndarray) -> dict:
    """mean, std (ddof=1), predicted_std (RMS σ), ratio and its χ² p-value.

    Over the sessions that determined the parameter (a null — undetermined — value
    is left out, and counted in ``undetermined``); None where nothing is left.
    """
    values = np.asarray(values, dtype=float)
    stds = np.asarray(stds, dtype=float)
    known = np.isfinite(values)
    undetermined = int(np.sum(~known))
    values, stds = values[known], stds[known]
    n = values.size
    if n == 0:
        return {
            "mean": None,
            "std": None,
            "predicted_std": None,
            "ratio": None,
            "ratio_p_value": None,
            "n": 0,
            "undetermined": undetermined,
        }
    mean = float(np.mean(values))
    std = float(np.std(values, ddof=1)) if n >= 2 else None
    predicted = float(np.sqrt(np.mean(stds**2))) if np.all(np.isfinite(stds)) else None
    ratio = std / predicted if std is not None and predicted else None
    p_value = None
    if ratio is not None:
        # stats.chi2.sf's own function (its numbers), without importing scipy.stats (≈ 0.5 s
        # of the batch's report, after the sessions)
        p_value = float(special.chdtrc(n - 1, (n - 1) * ratio**2))
    return {
        "mean": mean,
        "std": std,
        "predicted_std": predicted,
        "ratio": ratio,
        "ratio_p_value": p_value,
        "n": int(n),
        "undetermined": undetermined,
    }


def _outliers(files: list[str], name: str, values: np.ndarray, n_tests: int) -> list[dict]:
    """Each session against the others (leave-one-out t, Bonferroni over ``n_tests``).

    Sessions that left the parameter undetermined (null) take no part.
    """
    known = np.isfinite(values)
    files = [f for f, k in zip(files, known, strict=True) if k]
    values = values[known]
    n = values.size
    if n < 4:
        return []
    # Leave-one-out mean and std of the others, all at once, on centred values (no
    # cancellation: gains are ~1 with spreads of 1e-4).
    c = values - values.mean()
    others_mean = -c / (n - 1)
    others_var = (np.sum(c * c) - c * c - (n - 1) * others_mean**2) / (n - 2)
    others_std = np.sqrt(np.maximum(others_var, 0.0))
    scale = others_std * np.sqrt(1 + 1 / (n - 1))
    ok = others_std > 0
    t = np.zeros(n)
    t[ok] = (c[ok] - others_mean[ok]) / scale[ok]
    # stats.t.sf(|t|, n − 2), by its own function (see above)
    p = np.minimum(1.0, 2 * special.stdtr(n - 2, -np.abs(t)) * n_tests)
    return [
        {
            "file": files[i],
            "parameter": name,
            "value": float(values[i]),
            "t": float(t[i]),
            "p_corrected": float(p[i]),
        }
        for i in np.flatnonzero(ok & (p < OUTLIER_P))
    ]


def _stats_of(members: list[dict], names: list[str]) -> dict:
    """group_statistics for each name over member parameter tables ({name: {value, std}})."""
    out = {}
    for name in names:
        values = as_angles(
            name, [np.nan if m[name]["value"] is None else m[name]["value"] for m in members]
        )
        stds = np.array([np.nan if m[name]["std"] is None else m[name]["std"] for m in members])
        out[name] = group_statistics(values, stds)
    return out


def build_report(
    calibrations: list[dict],
    failed: list[dict],
    skipped: int = 0,
    diagnoses: list[dict] | None = None,
    per_session: Sequence[Mapping] | None = None,
) -> dict:
    """The ``report.json`` dictionary (CONTRACT keys plus additive extras).

    With ``diagnoses`` (closed loop on every session) each group also gets the
    same statistics for the paper's model (``parameters_paper_model``) and how
    often each effect was found (``effects_found``): the ratio before and after.

    ``per_session`` — one ``{"file", "stem", "status", "calibration", "error",
    "gate", "fix"}`` per session (status ``calibrated``, ``up to date`` or
    ``failed``) — becomes the additive ``per_session`` list: each session with
    its counts and notes (see :func:`session_entry`).  Without it the list is
    made from ``calibrations`` and ``failed``.
    """
    by_file = {d["source"]["file"]: d for d in diagnoses or []}
    calibrations = [c if isinstance(c, Calibration) else Calibration(c) for c in calibrations]
    groups: dict[tuple[str, str], list[Calibration]] = defaultdict(list)
    for cal in calibrations:
        groups[(cal.sensor_id, cal.mounting_id)].append(cal)
    out_groups = []
    outliers: list[dict] = []
    for (sensor_id, mounting_id), members in sorted(groups.items()):
        group, flagged = _group_entry(sensor_id, mounting_id, members, by_file)
        out_groups.append(group)
        outliers += flagged
    by_cal = {c.source_file: c for c in calibrations}
    if per_session is None:
        per_session = [
            {"file": f, "status": "calibrated", "calibration": None} for f in sorted(by_cal)
        ] + [{**f, "status": "failed"} for f in failed]
    entries = [session_entry(s, by_cal.get(s["file"]), outliers) for s in per_session]
    return {
        "format": "wheelcal.report/1",
        "sessions": len(calibrations) + len(failed),
        "calibrated": len(calibrations),
        "skipped_up_to_date": int(skipped),
        "failed": failed,
        "groups": out_groups,
        "outliers": outliers,
        "per_session": entries,
        "notes": list(_NOTES),
    }


def _group_entry(
    sensor_id: str, mounting_id: str, members: list[Calibration], by_file: Mapping[str, dict]
) -> tuple[dict, list[dict]]:
    """One ``groups`` entry (one sensor on one mounting) and the outliers among its sessions."""
    files = [m.source_file for m in members]
    tables = [m.parameters for m in members]
    names = [p for p in REPORT_PARAMETERS if all(p in table for table in tables)]
    params = {}
    outliers: list[dict] = []
    for name in names:
        # angles averaged as angles: unwrapped about their circular mean (calibration/angles.py)
        values = as_angles(name, [table[name][0] for table in tables])
        stds = np.array([table[name][1] for table in tables], dtype=float)
        params[name] = group_statistics(values, stds)
        outliers += _outliers(files, name, values, len(names) * len(members))
    group = {
        "sensor_id": sensor_id,
        "mounting_id": mounting_id,
        "sessions": len(members),
        "files": files,
        "parameters": params,
        "systematic_std": _systematic_std(members[0]),
    }
    diags = [by_file[f] for f in files if f in by_file]
    if diags and len(diags) == len(files):
        group["parameters_paper_model"] = _stats_of([d["base"]["parameters"] for d in diags], names)
        found: dict[str, int] = defaultdict(int)
        for d in diags:
            for step in d["steps"]:
                found[step["effect"]] += 1
        group["effects_found"] = dict(sorted(found.items()))
    return group, outliers


def _systematic_std(calibration: Calibration) -> dict[str, float | None]:
    """A session's systematic σ by parameter (shared by its bench: one session says it)."""
    sys_block = calibration.get("systematic", {})
    systematic = {}
    for key in ("gain_std", "offset_std_mps2"):
        for axis, v in zip(AXES, sys_block.get(key, []), strict=False):
            prefix = "gain" if key == "gain_std" else "offset"
            suffix = "" if key == "gain_std" else "_mps2"
            systematic[f"{prefix}_{axis}{suffix}"] = _finite(v)
    systematic["tilt_deg"] = _finite(sys_block.get("tilt_std_deg"))
    return systematic


#: What the reader writes into ``source.notes`` when it drops samples (wheelcal.recording.samples).
_DROPPED = {
    "clipped": re.compile(r"dropped (\d+) clipped samples"),
    "nonfinite": re.compile(r"dropped (\d+) NaN/inf samples"),
    "duplicate": re.compile(r"(\d+) samples repeated a timestamp"),
}


_CLIPPED_SHARE = re.compile(r"dropped \d+ clipped samples \(([0-9.e+-]+) %\)")


def clipped_percent(notes: Sequence[str]) -> float:
    """The share of the recording's samples that clipped, in per cent (0: none)."""
    return float(sum(float(m.group(1)) for n in notes for m in _CLIPPED_SHARE.finditer(n)))


def dropped_counts(notes: Sequence[str]) -> dict[str, int]:
    """Samples the reader dropped, by cause, from a calibration's ``source.notes``."""
    counts = dict.fromkeys(_DROPPED, 0)
    for note in notes:
        for cause, pattern in _DROPPED.items():
            match = pattern.search(note)
            if match:
                counts[cause] += int(match.group(1))
    return counts


def error_text(error: str, file: str) -> str:
    """An error without its leading file name, for lines that already name the file."""
    prefix = f"{file}: "
    return error[len(prefix) :] if error.startswith(prefix) else error


def session_notes(calibration: Mapping, outliers: Sequence[Mapping] = ()) -> list[str]:
    """What a person must know about one calibrated session, one short line each.

    The reader's repairs (clipped, dropped or merged samples, gaps), the fit's
    warnings, parameters the recording could not determine, a fit that did not
    converge, and the report's outlier flags.
    """
    calibration = read_only_document(calibration)
    src = calibration.get("source", {})
    fit = calibration.get("fit", {})
    notes = list(src.get("notes", []))
    if fit.get("converged") is False:
        notes.append("⚠ the fit did not converge")
    notes += [f"⚠ {w}" for w in fit.get("warnings", [])]
    for entry in calibration.get("sensor", {}).get("undetermined", []) or []:
        notes.append(f"undetermined: {entry.get('parameter')} ({entry.get('reason', '')})")
    for o in outliers:
        if o["file"] == src.get("file"):
            notes.append(
                f"outlier in {o['parameter']} (t = {o['t']:.1f}, p = {o['p_corrected']:.2g})"
            )
    return notes


def session_entry(
    session: Mapping, calibration: Mapping | None, outliers: Sequence[Mapping] = ()
) -> dict:
    """One ``per_session`` entry of ``report.json``: status, counts and notes."""
    calibration = None if calibration is None else read_only_document(calibration)
    file = session["file"]
    entry = {
        "file": file,
        "stem": session.get("stem"),
        "status": session["status"],
        "calibration": session.get("calibration"),
    }
    if calibration is None:
        gate = session.get("gate")
        reason = error_text(session.get("error") or "failed", file)
        entry.update(gate=gate, fix=session.get("fix"), error=reason)
        entry["notes"] = [f"{'refused' if gate else 'failed'}: {reason}"]
        return entry
    src = calibration["source"]
    fit = calibration.get("fit", {})
    counts = dropped_counts(src.get("notes", []))
    entry.update(
        window_s=src.get("window_s"),
        samples=src.get("samples"),
        residual_rms_mps2=fit.get("residual_rms_mps2"),
        clipped_samples=counts["clipped"],
        clipped_percent=clipped_percent(src.get("notes", [])),
        dropped_samples=sum(counts.values()),
        warnings=len(fit.get("warnings", [])),
        model=fit.get("model", "paper"),
        effects_found=effects_found(calibration),
        notes=session_notes(calibration, outliers),
    )
    return entry


def effects_found(calibration: Mapping) -> list[dict]:
    """What the closed loop added to the paper's model, each with its evidence."""
    out = []
    for name, entry in calibration.get("effects", {}).items():
        evidence = entry.get("evidence", {})
        out.append(
            {
                "effect": name,
                "statistic": evidence.get("statistic"),
                "dof": evidence.get("dof"),
                "p_corrected": evidence.get("p_corrected"),
            }
        )
    return out


def _effects_cell(entry: Mapping) -> str:
    """report.md's "effects found" cell: each effect with χ² and p, or what was fitted."""
    if entry.get("status") == "failed" or "model" not in entry:
        return "–"
    if entry["model"] == "paper":
        return "not screened (paper's model)"
    found = entry.get("effects_found") or []
    if not found:
        return "none"
    return "<br>".join(
        f"{e['effect']} (χ² = {_fmt(e['statistic'], 3)}, p = {_fmt(e['p_corrected'], 2)})"
        for e in found
    )


def counts_sentence(report: Mapping) -> str:
    """The one sentence on how many sessions did what (report.md and the CLI say the same)."""
    total = report["sessions"]
    calibrated = report["calibrated"]
    fresh = report["skipped_up_to_date"]
    failed = len(report["failed"])
    text = f"{total} session{'s' if total != 1 else ''}: {calibrated} calibrated"
    if fresh:
        text += f" ({calibrated - fresh} now, {fresh} up to date)"
    return text + f", {failed} failed"


def _fmt(x, digits=5) -> str:
    if x is None:
        return "–"
    if isinstance(x, float) and (abs(x) >= 1e4 or (0 < abs(x) < 1e-3)):
        return f"{x:.3e}"
    return f"{x:.{digits}g}"


def _with_before_column() -> str:
    return (
        "| parameter | mean | std | predicted std | ratio | p (ratio) | ratio, paper's model "
        "| systematic σ (shared) |\n|---|---:|---:|---:|---:|---:|---:|---:|"
    )


def report_markdown(report: dict, title: str = "Repeatability report") -> str:
    """``report.md`` for people: what to apply first, then the evidence."""
    lines = [f"# {title}", "", counts_sentence(report) + ".", ""]
    lines += apply_this_markdown(report.get("sensors", []))
    lines += allan_markdown(report.get("sensors", []))
    lines += overview_markdown(report.get("overview"))
    lines += sessions_markdown(report.get("per_session", []))
    for g in report["groups"]:
        who = f"sensor `{g['sensor_id'] or '-'}`, mounting `{g['mounting_id'] or '-'}`"
        lines += [f"## {who} ({g['sessions']} sessions)", "", _TABLE_HEAD]
        before = g.get("parameters_paper_model")
        if before:
            lines[-1] = _with_before_column()
        for name, st in g["parameters"].items():
            flag = " ⚠" if st["ratio_p_value"] is not None and st["ratio_p_value"] < 0.01 else ""
            cells = [
                f"`{name}`",
                _fmt(st["mean"], 7),
                _fmt(st["std"], 3),
                _fmt(st["predicted_std"], 3),
                _fmt(st["ratio"], 3) + flag,
                _fmt(st["ratio_p_value"], 2),
                _fmt(g["systematic_std"].get(name), 3),
            ]
            if before:
                cells.insert(6, _fmt(before[name]["ratio"], 3))
            lines.append("| " + " | ".join(cells) + " |")
        if g.get("effects_found"):
            found = ", ".join(f"`{k}` in {v}" for k, v in g["effects_found"].items())
            lines += ["", f"Closed loop: effects found — {found} of {g['sessions']} sessions."]
        lines.append("")
    if report["groups"]:
        lines += [_RATIO_NOTE, ""]
    lines += closure_markdown(report.get("closure"))
    if report["outliers"]:
        lines += [
            "## Outlier sessions",
            "",
            "| file | parameter | value | t | p (Bonferroni) |",
            "|---|---|---:|---:|---:|",
        ]
        for o in report["outliers"]:
            cells = [o["file"], f"`{o['parameter']}`", _fmt(o["value"], 7), f"{o['t']:.1f}"]
            lines.append("| " + " | ".join([*cells, _fmt(o["p_corrected"], 2)]) + " |")
        lines.append("")
    if report["failed"]:
        lines += ["## Failed sessions", ""]
        for f in report["failed"]:
            line = f"- `{f['file']}`: {error_text(f['error'], f['file'])}"
            if f.get("gate") and f.get("fix") and f["fix"] not in f["error"]:
                line += f" — fix: {f['fix']}"
            lines.append(line)
        lines.append("")
    return "\n".join(lines)


def _decimals(sigma) -> int:
    """Decimals that show a value to the second significant digit of its σ."""
    if sigma is None or not math.isfinite(sigma) or sigma <= 0:
        return 6
    return int(min(12, max(0, 1 - math.floor(math.log10(sigma)))))


def _value(x, sigma) -> str:
    if x is None:
        return "null"
    return "0" if x == 0 else f"{x:.{_decimals(sigma)}f}"


def _sigma(x) -> str:
    return "–" if x is None else f"{x:.2g}"


def apply_this_markdown(sensors: Sequence[Mapping]) -> list[str]:
    """One "apply this" table per sensor: bias, matrix, σ, and the command that exports it."""
    lines = []
    for s in sensors:
        sensor, systematic, correction = s["sensor"], s["systematic"], s["correction"]
        method = (
            "the joint sensor fit"
            if s["method"] == "joint_sensor_fit"
            else "the precision-weighted mean"
        )
        lines += [
            f"## Apply this — sensor `{s['sensor_id'] or '-'}`",
            "",
            f"Pooled from {s['sessions']} session{'s' if s['sessions'] != 1 else ''} by {method}"
            " (σ scaled by max(1, √χ²_red) of their scatter). Corrected specific force in the "
            "sensor frame: **a = M (v − b)**, m/s². σ stat is this calibration's statistical σ; "
            "σ sys is shared by the sessions (radius, gravity, clock) and does not average away.",
            "",
            "| axis | bias b (m/s²) | σ stat | σ sys | matrix M (row) | gain | σ stat | σ sys |",
            "|---|---:|---:|---:|---|---:|---:|---:|",
        ]
        for k, axis in enumerate(AXES):
            g_std = sensor["gain_std"][k]
            row = ", ".join(_value(m, g_std) for m in correction["matrix"][k])
            lines.append(
                _row(
                    axis,
                    _value(correction["bias_mps2"][k], sensor["offset_std_mps2"][k]),
                    _sigma(sensor["offset_std_mps2"][k]),
                    _sigma(systematic["offset_std_mps2"][k]),
                    f"[{row}]",
                    _value(sensor["gain"][k], g_std),
                    _sigma(g_std),
                    _sigma(systematic["gain_std"][k]),
                )
            )
        lines += [
            "",
            f"File: `{s['file']}`. Export it: `wheelcal export {s['file']} --format yaml` "
            f"(ROS/Kalibr) or `--format c` (firmware header); "
            f"apply it: `wheelcal apply {s['file']} IN.mcap OUT.mcap`.",
        ]
        for entry in sensor.get("undetermined", []):
            lines.append(
                f"- undetermined: `{entry['parameter']}` ({entry['reason']}); "
                "the correction leaves that axis unchanged"
            )
        lines += [f"- ⚠ {w}" for w in s.get("warnings", [])]
        lines.append("")
    return lines


def allan_markdown(sensors: Sequence[Mapping]) -> list[str]:
    """Per sensor: the rests' overlapping Allan deviation and its read-outs (``fit.allan``)."""
    lines = []
    for s in sensors:
        allan = s.get("allan")
        if not allan:
            continue
        read = "read at τ = 1 s" if allan["white_noise_read_at_1s"] else "extrapolated (−½ slope)"
        intro = (
            f"Overlapping Allan deviation of {allan['rests_s']:.3g} s of rests (the sensor still "
            f"before the push and after the stop) at {allan['rate_hz']:.6g} Hz, pooled over the "
            "sessions. White-noise density N = σ(1 s)·√1 s (Kalibr's "
            "`accelerometer_noise_density`); bias instability B = σ_min / 0.664; random walk "
            "K ≤ min σ(τ)·√(3/τ) (Kalibr's `accelerometer_random_walk`). *bound*: the rests are "
            "too short to show a floor or a rise, so the value is an upper bound."
        )
        title = f"## Noise at rest — sensor `{s['sensor_id'] or '-'}` (Allan deviation)"
        head = ("axis", "N (m/s²/√Hz)", "B (m/s²)", "at τ (s)", "K (m/s³/√Hz)")
        lines += [title, "", intro, "", _row(*head), _row("---", *["---:"] * 4)]
        for k, axis in enumerate(AXES):
            floor = allan["bias_instability_is_floor"][k]
            seen = allan["random_walk_seen"][k]
            lines.append(
                _row(
                    axis,
                    f"{allan['white_noise_density_mps2_rthz'][k]:.3g} ({read})",
                    f"{allan['bias_instability_mps2'][k]:.3g}" + ("" if floor else " (bound)"),
                    f"{allan['bias_instability_tau_s'][k]:.3g}",
                    f"{allan['random_walk_mps3_rthz'][k]:.3g}" + ("" if seen else " (bound)"),
                )
            )
        lines += ["", _row("τ (s)", *(f"σ_{a} (m/s²)" for a in AXES)), _row(*["---:"] * 4)]
        for tau, adev in zip(allan["tau_s"], allan["adev_mps2"], strict=True):
            lines.append(_row(f"{tau:.3g}", *(f"{v:.3g}" for v in adev)))
        lines.append("")
    return lines


def overview_markdown(overview: Mapping | None) -> list[str]:
    """The PNG overview's link, or why there is none."""
    if not overview:
        return []
    if overview.get("file"):
        return [
            f"![Overview: each parameter per session with ±σ and the group mean; residual "
            f"against wheel angle]({overview['file']})",
            "",
        ]
    return [f"Overview PNG not drawn: {overview.get('note', 'unavailable')}.", ""]


def sessions_markdown(entries: Sequence[Mapping]) -> list[str]:
    """Every session in one table, with a notes column (nothing important left in JSON)."""
    if not entries:
        return []
    lines = [
        "## Sessions",
        "",
        "| # | file | status | window (s) | samples | residual rms x / y / z (m/s²) "
        "| effects found | notes |",
        "|---:|---|---|---|---:|---|---|---|",
    ]
    for i, e in enumerate(entries, start=1):
        window = e.get("window_s")
        rms = e.get("residual_rms_mps2")
        notes = "<br>".join(n.replace("|", "\\|") for n in e.get("notes", [])) or "–"
        lines.append(
            _row(
                i,
                f"`{e['file']}`",
                e["status"] if not e.get("gate") else f"refused ({e['gate']})",
                "–" if not window else f"{window[0]:.2f}–{window[1]:.2f}",
                e.get("samples", "–"),
                "–" if not rms else " / ".join(_fmt(x, 3) for x in rms),
                _effects_cell(e),
                notes,
            )
        )
    lines.append("")
    return lines


def sessions_csv(calibrations: list[dict], per_session: Sequence[Mapping] | None = None) -> str:
    """One row per session: identifiers, window, every reported parameter (value, std), counts.

    With ``per_session`` (``report.json``'s list) failed sessions get a row too,
    and the appended columns carry the status, the reader's dropped and clipped
    sample counts, the number of notes and their text.
    """
    calibrations = [read_only_document(c) for c in calibrations]
    names = [
        p for p in REPORT_PARAMETERS if any(p in c.get("parameters", {}) for c in calibrations)
    ]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    header = ["file", "sensor_id", "mounting_id", "window_start_s", "window_end_s", "samples"]
    for name in names:
        header += [name, f"{name}_std"]
    header += [f"residual_rms_{a}_mps2" for a in AXES] + ["warnings"]
    header += ["status", "stem", "gate", "clipped_samples", "dropped_samples", "notes", "details"]
    writer.writerow(header)
    by_file = {c["source"]["file"]: c for c in calibrations}
    if per_session is None:
        per_session = [{"file": f, "status": "calibrated"} for f in by_file]
    for entry in per_session:
        cal = by_file.get(entry["file"])
        notes = list(entry.get("notes", []))
        tail = [entry["status"], entry.get("stem") or "", entry.get("gate") or ""]
        if cal is None:
            row = [entry["file"], "", "", "", "", ""] + [""] * (2 * len(names) + 4)
            writer.writerow([*row, *tail, "", "", len(notes), " | ".join(notes)])
            continue
        src = cal["source"]
        row = [
            src["file"],
            src.get("sensor_id", ""),
            src.get("mounting_id", ""),
            *src["window_s"],
            src["samples"],
        ]
        for name in names:
            p = cal["parameters"].get(name, {})
            row += [_csv_number(p.get("value")), _csv_number(p.get("std"))]
        row += [*map(_csv_number, cal["fit"]["residual_rms_mps2"]), len(cal["fit"]["warnings"])]
        counts = dropped_counts(src.get("notes", []))
        row += [*tail, counts["clipped"], sum(counts.values()), len(notes), " | ".join(notes)]
        writer.writerow(row)
    return buf.getvalue()


def _csv_number(x) -> str | float:
    """A float at its shortest round-trip precision (repr); empty for null."""
    return "" if x is None else float(x)


def _row(*cells) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def closure_markdown(closure: dict | None) -> list[str]:
    """Sensor-level closure: pooled tests, the sensor model, and the spread before/after."""
    if not closure or not closure.get("sensors"):
        return []
    lines = []
    for sensor in closure["sensors"]:
        lines += [
            f"## Closure: sensor `{sensor['sensor_id'] or '-'}` ({sensor['sessions']} sessions)",
            "",
        ]
        lines += [
            "Pooled tests of sensor-intrinsic effects (one test per shared parameter, "
            f"Bonferroni-corrected, α = {sensor['alpha']:g}):",
            "",
            "| effect | χ² | dof | p (corrected) | verdict |",
            "|---|---:|---:|---:|---|",
        ]
        for t in sensor["pooled_tests"]:
            if not t["identifiable"]:
                lines.append(_row(f"`{t['label']}`", "–", t["dof"], "–", "not identifiable here"))
                continue
            verdict = "**present**" if t["p_corrected"] < sensor["alpha"] else "not shown"
            stat = f"{t['statistic']:.1f}"
            lines.append(
                _row(f"`{t['label']}`", stat, t["dof"], _fmt(t["p_corrected"], 2), verdict)
            )
        fit = sensor.get("sensor_fit")
        if fit:
            lines += ["", "Joint sensor fit (shared offset, gain and the effects found):", ""]
            lines += [
                "| parameter | value | σ | σ best single | pooling gain |",
                "|---|---:|---:|---:|---:|",
            ]
            for name, p in fit["parameters"].items():
                best = _fmt(fit["best_single_std"].get(name), 3)
                gain = _fmt(fit["pooling_gain"].get(name), 3)
                lines.append(_row(f"`{name}`", _fmt(p["value"], 7), _fmt(p["std"], 3), best, gain))
            lines += [f"- {w}" for w in fit["warnings"]]
        inflated = [s for s in sensor["spread"] if s["inflated_before"] or s["inflated_after"]]
        lines += [
            "",
            f"Spread over sessions vs the per-session σ ({sensor['spread_correction']}); "
            "offsets that warm up or drift are compared at the start of each recording:",
            "",
            _row(
                "parameter",
                "mounting",
                "ratio, paper's model",
                "p",
                "ratio, with effects",
                "p",
                "verdict",
            ),
            "|---|---|---:|---:|---:|---:|---|",
        ]
        for s in sensor["spread"]:
            if s["inflated_after"]:
                verdict = "**still inflated**: an effect not among the candidates"
            elif s["inflated_before"]:
                verdict = "inflated, explained by the effects"
            else:
                verdict = "consistent"
            if s in inflated or s["parameter"].startswith(("offset", "gain")):
                lines.append(
                    f"| `{s['parameter']}` | {s['mounting_id'] or '-'} | {s['ratio_before']:.2f} "
                    f"| {_fmt(s['p_before_corrected'], 2)} | {s['ratio_after']:.2f} "
                    f"| {_fmt(s['p_after_corrected'], 2)} | {verdict} |"
                )
        lines += [
            "",
            "Candidate causes tested: " + ", ".join(f"`{c}`" for c in sensor["candidates_tested"]),
            "",
        ]
    return lines
