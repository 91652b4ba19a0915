"""Repeatability report over sessions (the paper's Table II, made automatic).

For every group of sessions sharing ``sensor_id`` and ``mounting_id`` and every
calibrated parameter: mean, std (ddof = 1), the std *predicted* by the
per-session uncertainties (RMS of their σ) and the ratio std / predicted — the
comparison the paper makes by hand in IV-B (its offsets spread 3.5× the
expected value).

* **Is the spread larger than predicted?**  With honest σ,
  (n − 1)·ratio² follows χ²(n − 1); ``ratio_p_value`` is the upper tail.
* **Outliers**: each session against the others, t = (xᵢ − x̄₋ᵢ) / (s₋ᵢ √(1 + 1/(n−1))),
  Student t with n − 2 dof (externally studentised), Bonferroni-corrected over
  sessions × parameters; flagged when the corrected p < 0.01.

The systematic σ (radius, gravity, clock) is shared by every session of a bench,
so it cannot show in the spread; it is listed separately.
"""

from __future__ import annotations

import csv
import io
import math
from collections import defaultdict

import numpy as np

from wheelcal.model.parameters import AXES

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
    """mean, std (ddof=1), predicted_std (RMS σ), ratio and its χ² p-value."""
    n = values.size
    mean = float(np.mean(values))
    std = float(np.std(values, ddof=1)) if n >= 2 else None
    predicted = float(np.sqrt(np.mean(stds**2))) if np.all(np.isfinite(stds)) else None
    ratio = std / predicted if std is not None and predicted else None
    p_value = None
    if ratio is not None:
        from scipy import stats

        p_value = float(stats.chi2.sf((n - 1) * ratio**2, n - 1))
    return {
        "mean": mean,
        "std": std,
        "predicted_std": predicted,
        "ratio": ratio,
        "ratio_p_value": p_value,
        "n": int(n),
    }


def _outliers(files: list[str], name: str, values: np.ndarray, n_tests: int) -> list[dict]:
    n = values.size
    if n < 4:
        return []
    from scipy import stats

    out = []
    for i in range(n):
        others = np.delete(values, i)
        s = np.std(others, ddof=1)
        if s == 0:
            continue
        t = (values[i] - others.mean()) / (s * np.sqrt(1 + 1 / (n - 1)))
        p = float(min(1.0, 2 * stats.t.sf(abs(t), n - 2) * n_tests))
        if p < OUTLIER_P:
            out.append(
                {
                    "file": files[i],
                    "parameter": name,
                    "value": float(values[i]),
                    "t": float(t),
                    "p_corrected": p,
                }
            )
    return out


def _stats_of(members: list[dict], names: list[str]) -> dict:
    """group_statistics for each name over member parameter tables ({name: {value, std}})."""
    out = {}
    for name in names:
        values = np.array([m[name]["value"] for m in members], dtype=float)
        stds = np.array([np.nan if m[name]["std"] is None else m[name]["std"] for m in members])
        out[name] = group_statistics(values, stds)
    return out


def build_report(
    calibrations: list[dict],
    failed: list[dict],
    skipped: int = 0,
    diagnoses: list[dict] | None = None,
) -> dict:
    """The ``report.json`` dictionary (CONTRACT keys plus additive extras).

    With ``diagnoses`` (closed loop on every session) each group also gets the
    same statistics for the paper's model (``parameters_paper_model``) and how
    often each effect was found (``effects_found``): the ratio before and after.
    """
    by_file = {d["source"]["file"]: d for d in diagnoses or []}
    groups: dict[tuple[str, str], list[dict]] = defaultdict(list)
    for cal in calibrations:
        src = cal.get("source", {})
        groups[(src.get("sensor_id", ""), src.get("mounting_id", ""))].append(cal)
    out_groups = []
    outliers: list[dict] = []
    for (sensor_id, mounting_id), members in sorted(groups.items()):
        files = [m["source"]["file"] for m in members]
        names = [p for p in REPORT_PARAMETERS if all(p in m.get("parameters", {}) for m in members)]
        params = {}
        systematic = {}
        for name in names:
            values = np.array([m["parameters"][name]["value"] for m in members], dtype=float)
            stds = np.array(
                [
                    np.nan if m["parameters"][name]["std"] is None else m["parameters"][name]["std"]
                    for m in members
                ],
                dtype=float,
            )
            params[name] = group_statistics(values, stds)
            outliers += _outliers(files, name, values, len(names) * len(members))
        for member in members[:1]:
            sys_block = member.get("systematic", {})
            for key in ("gain_std", "offset_std_mps2"):
                for axis, v in zip(AXES, sys_block.get(key, []), strict=False):
                    prefix = "gain" if key == "gain_std" else "offset"
                    suffix = "" if key == "gain_std" else "_mps2"
                    systematic[f"{prefix}_{axis}{suffix}"] = _finite(v)
            systematic["tilt_deg"] = _finite(sys_block.get("tilt_std_deg"))
        group = {
            "sensor_id": sensor_id,
            "mounting_id": mounting_id,
            "sessions": len(members),
            "files": files,
            "parameters": params,
            "systematic_std": systematic,
        }
        diags = [by_file[f] for f in files if f in by_file]
        if diags and len(diags) == len(files):
            group["parameters_paper_model"] = _stats_of(
                [d["base"]["parameters"] for d in diags], names
            )
            found: dict[str, int] = defaultdict(int)
            for d in diags:
                for step in d["steps"]:
                    found[step["effect"]] += 1
            group["effects_found"] = dict(sorted(found.items()))
        out_groups.append(group)
    return {
        "format": "wheelcal.report/1",
        "sessions": len(calibrations) + len(failed),
        "calibrated": len(calibrations),
        "skipped_up_to_date": int(skipped),
        "failed": failed,
        "groups": out_groups,
        "outliers": outliers,
        "notes": list(_NOTES),
    }


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
    """``report.md`` for people."""
    lines = [
        f"# {title}",
        "",
        f"{report['calibrated']} of {report['sessions']} sessions calibrated"
        + (
            f" ({report['skipped_up_to_date']} up to date, not recomputed)"
            if report["skipped_up_to_date"]
            else ""
        )
        + (f"; **{len(report['failed'])} failed**" if report["failed"] else "")
        + ".",
        "",
    ]
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
        lines += [f"- `{f['file']}`: {f['error']}" for f in report["failed"]]
        lines.append("")
    return "\n".join(lines)


def sessions_csv(calibrations: list[dict]) -> str:
    """One row per session: identifiers, window, every reported parameter (value, std)."""
    names = [
        p for p in REPORT_PARAMETERS if any(p in c.get("parameters", {}) for c in calibrations)
    ]
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    header = ["file", "sensor_id", "mounting_id", "window_start_s", "window_end_s", "samples"]
    for name in names:
        header += [name, f"{name}_std"]
    header += [f"residual_rms_{a}_mps2" for a in AXES] + ["warnings"]
    writer.writerow(header)
    for cal in calibrations:
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
            row += [p.get("value", ""), p.get("std", "")]
        row += [*cal["fit"]["residual_rms_mps2"], len(cal["fit"]["warnings"])]
        writer.writerow(row)
    return buf.getvalue()


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
