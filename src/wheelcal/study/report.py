"""The study's numbers as JSON, CSV tables and a Markdown summary (no files written here).

Ratios of spreads (per parameter, per σ_n):

* ``paper_over_joint`` = σ_paper-method / σ_joint — what the joint fit gains;
* ``joint_over_crlb`` = σ_joint / σ_CRLB — 1 when the joint fit is efficient;
* ``paper_over_crlb`` = σ_paper-method / σ_CRLB.

Their sampling error: a std of n runs has relative standard error
1/√(2(n − 1)), so a ratio of two independent ones ≈ √(1/(2(n₁−1)) + 1/(2(n₂−1)))
(the paired runs make it smaller still).  Group values average the parameters.
"""

from __future__ import annotations

import math

import numpy as np

from wheelcal import __version__
from wheelcal.study.duration import SENSOR_NAMES, loglog_slope
from wheelcal.study.montecarlo import PARAMETER_GROUPS, group_of
from wheelcal.study.noise_sweep import LevelStats, proportionality_slope
from wheelcal.study.paper_table1 import TABLE1_ROWS
from wheelcal.study.runner import StudyResult

FORMAT = "wheelcal.study/1"
#: The paper's claim of Fig. 7: unbiased up to this noise level.
UNBIASED_UP_TO_MPS2 = 0.2
_SENSOR_GROUPS = ("offset", "gain")


def clean(value):
    """JSON-safe copy: numpy → Python, NaN/∞ → None."""
    if isinstance(value, dict):
        return {str(k): clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return clean(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _level_dict(s: LevelStats) -> dict:
    per = {
        q: getattr(s, q)
        for q in (
            "truth",
            "mean",
            "std",
            "robust_std",
            "bias",
            "bias_se",
            "crlb_std",
            "std_over_crlb",
            "normalised_deviation_pct",
            "normalised_std",
            "crlb_normalised_std",
        )
    }
    return {
        "sigma_mps2": s.sigma_mps2,
        "runs": s.runs,
        "failures": s.failures,
        "parameters": {
            n: {"group": group_of(n), **{q: float(v[i]) for q, v in per.items()}}
            for i, n in enumerate(s.names)
        },
        "groups": {
            g: {
                q: s.group_mean(per[q])[g]
                for q in (
                    "normalised_deviation_pct",
                    "normalised_std",
                    "crlb_normalised_std",
                    "std_over_crlb",
                )
            }
            for g in PARAMETER_GROUPS
        },
    }


def ratios(result: StudyResult) -> list[dict]:
    """Per σ_n: paper/joint, joint/CRLB and paper/CRLB spreads, per parameter and group."""
    out = []
    for joint in result.sweep.get("joint", ()):
        paper = _maybe_level(result, "paper", joint.sigma_mps2)
        per = {
            "joint_over_crlb": joint.std / joint.crlb_std,
            "paper_over_joint": paper.std / joint.std
            if paper
            else np.full(len(joint.names), np.nan),
            "paper_over_crlb": paper.std / paper.crlb_std
            if paper
            else np.full(len(joint.names), np.nan),
        }
        se_joint = 1 / np.sqrt(2 * (joint.runs - 1))
        se_paper = 1 / np.sqrt(2 * (paper.runs - 1)) if paper else float("nan")
        out.append(
            {
                "sigma_mps2": joint.sigma_mps2,
                "runs": {"joint": joint.runs, "paper": paper.runs if paper else 0},
                "relative_se": {
                    "joint_over_crlb": se_joint,
                    "paper_over_joint": float(np.hypot(se_joint, se_paper)),
                    "paper_over_crlb": se_paper,
                },
                "parameters": {
                    n: {q: float(v[i]) for q, v in per.items()} for i, n in enumerate(joint.names)
                },
                "groups": {
                    g: {q: joint.group_mean(v)[g] for q, v in per.items()} for g in PARAMETER_GROUPS
                },
            }
        )
    return out


def _maybe_level(result: StudyResult, estimator: str, sigma: float) -> LevelStats | None:
    try:
        return result.level(estimator, sigma)
    except KeyError:
        return None


def table1_rows(result: StudyResult) -> dict[str, list[dict]]:
    """Table I at its two noise levels: paper, our paper-method, our joint fit, CRLB (SI units)."""
    out = {}
    for sigma in result.config.noise_sweep.table_levels_mps2:
        joint = result.level("joint", sigma)
        paper = _maybe_level(result, "paper", sigma)
        rows = []
        for row in TABLE1_ROWS:
            i = joint.names.index(row.parameter)
            published = row.at_sigma.get(sigma)
            rows.append(
                {
                    "parameter": row.parameter,
                    "symbol": row.symbol,
                    "display_unit": row.display_unit,
                    "display_scale": row.display_scale,
                    "truth": float(joint.truth[i]),
                    "paper": {"mean": published[0], "std": published[1]} if published else None,
                    "paper_method": (
                        {"mean": float(paper.mean[i]), "std": float(paper.std[i])}
                        if paper
                        else None
                    ),
                    "joint": {"mean": float(joint.mean[i]), "std": float(joint.std[i])},
                    "crlb_std": float(joint.crlb_std[i]),
                }
            )
        out[f"{sigma:g}"] = rows
    return out


def static_comparison(result: StudyResult) -> list[dict]:
    """Six still poses against the wheel's joint fit, same sensor, noise and 90 s."""
    out = []
    for c in result.static:
        mc = c.static
        per = {
            n: {
                "static_std": float(mc.std[i]),
                "static_bound_std": float(mc.bound_std[i]),
                "wheel_joint_std": float(c.wheel_joint_std[i]),
                "wheel_crlb_std": float(c.wheel_crlb_std[i]),
                "wheel_over_static": float(c.wheel_joint_std[i] / mc.std[i]),
            }
            for i, n in enumerate(SENSOR_NAMES)
        }
        groups = {
            g: {
                q: float(np.mean([v[q] for n, v in per.items() if group_of(n) == g]))
                for q in next(iter(per.values()))
            }
            for g in _SENSOR_GROUPS
        }
        plan = mc.plan
        out.append(
            {
                "sigma_mps2": c.sigma_mps2,
                "runs": mc.errors.shape[0],
                "failures": mc.failures,
                "plan": {
                    "total_s": plan.total_s,
                    "rate_hz": plan.rate_hz,
                    "poses": plan.poses,
                    "settle_s": plan.settle_s,
                    "usable_per_pose_s": plan.usable_per_pose_s,
                    "samples_per_pose": plan.samples_per_pose,
                    "pose_error_deg": plan.pose_error_deg,
                },
                "parameters": per,
                "groups": groups,
            }
        )
    return out


def _precision_points(points, axis: str) -> dict:
    rows = []
    for p in points:
        rows.append(
            {
                "duration_s": p.duration_s,
                "rate_hz": p.rate_hz,
                "parameters": {
                    n: {
                        "wheel_crlb_std": float(p.wheel_std[i]),
                        "static_std": float(p.static_std[i]),
                        "static_no_settle_std": float(p.static_no_settle_std[i]),
                    }
                    for i, n in enumerate(SENSOR_NAMES)
                },
            }
        )
    x = np.array([getattr(p, axis) for p in points])
    slopes = {}
    for g in _SENSOR_GROUPS:
        idx = [i for i, n in enumerate(SENSOR_NAMES) if group_of(n) == g]
        slopes[g] = {
            "wheel": loglog_slope(x, [np.mean(p.wheel_std[idx]) for p in points]),
            "static": loglog_slope(x, [np.mean(p.static_std[idx]) for p in points]),
        }
    return {"axis": axis, "points": rows, "loglog_slopes": slopes}


def checks(result: StudyResult) -> list[dict]:
    """Monte Carlo checks of the CRLB prediction (joint fit) and of the static bound."""
    out = []
    for c in result.checks:
        per = {}
        for i, n in enumerate(SENSOR_NAMES):
            per[n] = {
                "joint_std": float(c.joint_std[i]),
                "crlb_std": float(c.crlb_std[i]),
                "joint_over_crlb": float(c.joint_std[i] / c.crlb_std[i]),
                "static_std": float(c.static.std[i]) if c.static else None,
                "static_bound_std": float(c.static.bound_std[i]) if c.static else None,
            }
        out.append(
            {
                "duration_s": c.duration_s,
                "rate_hz": c.rate_hz,
                "runs": c.runs,
                "failures": c.failures,
                "static_runs": c.static.errors.shape[0] if c.static else 0,
                "parameters": per,
            }
        )
    return out


def findings(result: StudyResult) -> dict:
    """The paper's qualitative claims, measured (Sec. IV-A, Fig. 7–8)."""
    out = {}
    for estimator, levels in result.sweep.items():
        low = [s for s in levels if s.sigma_mps2 <= UNBIASED_UP_TO_MPS2 + 1e-12]
        z = np.array([np.abs(s.bias / s.bias_se) for s in low]) if low else np.zeros((0, 0))
        out[estimator] = {
            "unbiased_up_to_mps2": UNBIASED_UP_TO_MPS2,
            "max_abs_bias_over_se": (
                {n: float(z[:, i].max()) for i, n in enumerate(levels[0].names)} if low else {}
            ),
            "max_abs_group_deviation_pct": {
                g: max(abs(s.group_mean(s.normalised_deviation_pct)[g]) for s in low)
                for g in PARAMETER_GROUPS
            }
            if low
            else {},
            "std_vs_sigma_loglog_slope": (
                {g: proportionality_slope(list(levels), g) for g in PARAMETER_GROUPS}
                if len(levels) > 1
                else {}
            ),
            "weakest_group": {
                f"{s.sigma_mps2:g}": max(
                    PARAMETER_GROUPS, key=lambda g, s=s: s.group_mean(s.normalised_std)[g]
                )
                for s in levels
            },
            "offset_over_gain_std": {
                f"{s.sigma_mps2:g}": s.group_mean(s.std)["offset"] / s.group_mean(s.std)["gain"]
                for s in levels
            },
        }
    return out


def to_json(result: StudyResult, command: str | None = None) -> dict:
    """The whole study as one JSON-ready dict (``study.json``)."""
    sc = result.scenario
    joint0 = result.sweep["joint"][0]
    return clean(
        {
            "format": FORMAT,
            "wheelcal_version": __version__,
            "command": command,
            "config": result.config.to_dict(),
            "scenario": {
                "preset": "table1",
                "duration_s": sc.duration_s,
                "rate_hz": sc.rate_hz,
                "radius_m": sc.truth.bench.radius_m,
                "noise": "white Gaussian, independent per axis, σ_n per sample",
                "truth": dict(zip(joint0.names, joint0.truth.tolist(), strict=True)),
            },
            "motion_time_origin": "first_sample",
            "run": {"wall_s": result.wall_s, "fits": result.fits, "workers": result.workers},
            "noise_sweep": {
                "sigma_mps2": list(result.sigma_levels_mps2),
                **{e: [_level_dict(s) for s in lv] for e, lv in result.sweep.items()},
            },
            "ratios": ratios(result),
            "table1": table1_rows(result),
            "static": static_comparison(result),
            "duration": _precision_points(result.durations, "duration_s"),
            "rate": _precision_points(result.rates, "rate_hz"),
            "checks": checks(result),
            "systematic": result.systematic,
            "findings": findings(result),
        }
    )


# ---------------------------------------------------------------------------
# CSV tables


def csv_tables(result: StudyResult) -> dict[str, list[dict]]:
    """File name → rows (dicts with the same keys), for the CSV outputs."""
    doc = to_json(result)
    tables: dict[str, list[dict]] = {}
    tables["noise_sweep.csv"] = [
        {"estimator": e, "sigma_mps2": lv["sigma_mps2"], "parameter": n, **p,
         "runs": lv["runs"], "failures": lv["failures"]}
        for e in result.sweep
        for lv in doc["noise_sweep"][e]
        for n, p in lv["parameters"].items()
    ]  # fmt: skip
    tables["groups.csv"] = [
        {"estimator": e, "sigma_mps2": lv["sigma_mps2"], "group": g, **v}
        for e in result.sweep
        for lv in doc["noise_sweep"][e]
        for g, v in lv["groups"].items()
    ]
    tables["ratios.csv"] = [
        {"sigma_mps2": r["sigma_mps2"], "parameter": n, "group": group_of(n), **v}
        for r in doc["ratios"]
        for n, v in r["parameters"].items()
    ]
    tables["table1.csv"] = [
        {
            "sigma_mps2": float(sigma),
            "parameter": row["parameter"],
            "symbol": row["symbol"],
            "display_unit": row["display_unit"],
            **_display(row),
        }
        for sigma, rows in doc["table1"].items()
        for row in rows
    ]
    tables["static.csv"] = [
        {"sigma_mps2": c["sigma_mps2"], "parameter": n, **v}
        for c in doc["static"]
        for n, v in c["parameters"].items()
    ]
    tables["duration.csv"] = [
        {"sweep": sweep, "duration_s": p["duration_s"], "rate_hz": p["rate_hz"],
         "parameter": n, **v}
        for sweep in ("duration", "rate")
        for p in doc[sweep]["points"]
        for n, v in p["parameters"].items()
    ]  # fmt: skip
    tables["checks.csv"] = [
        {"duration_s": c["duration_s"], "rate_hz": c["rate_hz"], "runs": c["runs"],
         "parameter": n, **v}
        for c in doc["checks"]
        for n, v in c["parameters"].items()
    ]  # fmt: skip
    tables["runs.csv"] = [
        {"estimator": e, "sigma_mps2": s.sigma_mps2, "run": k,
         **{f"error_{n}": float(v) for n, v in zip(s.names, row, strict=True)}}
        for e, levels in result.sweep.items()
        for s in levels
        for k, row in enumerate(s.errors)
    ]  # fmt: skip
    return tables


def _display(row: dict) -> dict:
    """Table I row in the paper's display units (µrad/s⁴, °, …)."""
    k = row["display_scale"]

    def scaled(entry, key):
        return None if entry is None or entry.get(key) is None else entry[key] * k

    return {
        "truth": row["truth"] * k,
        "paper_mean": scaled(row["paper"], "mean"),
        "paper_std": scaled(row["paper"], "std"),
        "paper_method_mean": scaled(row["paper_method"], "mean"),
        "paper_method_std": scaled(row["paper_method"], "std"),
        "joint_mean": scaled(row["joint"], "mean"),
        "joint_std": scaled(row["joint"], "std"),
        "crlb_std": row["crlb_std"] * k,
    }


# ---------------------------------------------------------------------------
# Markdown


def _g(x, digits: int = 3) -> str:
    return (
        "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.{digits}g}"
    )


def _pm(mean, std) -> str:
    if mean is None:
        return "–"
    return f"{mean:.6g} ± {std:.2g}"


def summary_markdown(result: StudyResult, command: str | None = None) -> str:
    """A readable summary of the study (``summary.md``)."""
    doc = to_json(result, command)
    lines = ["# wheelcal accuracy study — paper Sec. IV-A (Table I, Fig. 7–8)", ""]
    if command:
        lines += ["Regenerate with:", "", "```", command, "```", ""]
    run = doc["run"]
    lines += [
        f"{run['fits']} fits on {run['workers']} workers in {run['wall_s']:.0f} s. "
        "Motion parameters use the paper's time origin (first sample). "
        "Paper = the published Table I; paper method = our implementation of its four steps; "
        "joint = wheelcal's joint ML fit; CRLB = Cramér–Rao bound at the truth.",
        "",
    ]
    lines += _table1_markdown(result, doc)
    lines += _ratios_markdown(doc)
    lines += _static_markdown(doc)
    d = result.config.duration
    lines += _precision_markdown(
        f"Recording length (σ_n = {d.sigma_mps2:g} m/s², {d.base_rate_hz:g} Hz; mean over axes)",
        "T (s)",
        "duration_s",
        doc["duration"]["points"],
    )
    lines += [""]
    lines += _precision_markdown(
        f"Sampling rate ({d.base_duration_s:g} s)", "rate (Hz)", "rate_hz", doc["rate"]["points"]
    )
    if doc["checks"]:
        lines += [
            "",
            "## Monte Carlo checks of the CRLB prediction (joint σ / CRLB, mean over axes)",
            "",
            "| T (s) | rate (Hz) | runs | offsets | gains |",
            "|---|---|---|---|---|",
        ]
        for c in doc["checks"]:
            r = {
                g: np.mean(_group_values(c["parameters"], g, "joint_over_crlb"))
                for g in _SENSOR_GROUPS
            }
            lines.append(
                f"| {c['duration_s']:g} | {c['rate_hz']:g} | {c['runs']} "
                f"| {r['offset']:.2f} | {r['gain']:.2f} |"
            )
    lines += _findings_markdown(doc)
    return "\n".join(lines)


def _table1_markdown(result: StudyResult, doc: dict) -> list[str]:
    """One Table I per noise level: truth, paper, paper method, joint fit, CRLB."""
    lines = []
    for sigma, rows in doc["table1"].items():
        runs = {e: result.level(e, float(sigma)).runs for e in result.sweep}
        lines += [
            f"## Table I at σ_n = {sigma} m/s² "
            f"({', '.join(f'{e}: {n} runs' for e, n in runs.items())})",
            "",
            "| parameter | unit | truth | paper | paper method | joint | CRLB σ |",
            "|---|---|---|---|---|---|---|",
        ]
        for row in rows:
            d = _display(row)
            lines.append(
                f"| {row['symbol']} | {row['display_unit']} | {d['truth']:.6g} "
                f"| {_pm(d['paper_mean'], d['paper_std'])} "
                f"| {_pm(d['paper_method_mean'], d['paper_method_std'])} "
                f"| {_pm(d['joint_mean'], d['joint_std'])} | {d['crlb_std']:.2g} |"
            )
        lines.append("")
    return lines


def _ratios_markdown(doc: dict) -> list[str]:
    """The spread ratios per parameter group, averaged over the noise levels."""
    lines = [
        "## Spread ratios per group (mean over σ_n levels)",
        "",
        "| group | paper method σ / joint σ | joint σ / CRLB | paper method σ / CRLB |",
        "|---|---|---|---|",
    ]
    for g in PARAMETER_GROUPS:
        vals = {
            q: np.nanmean([r["groups"][g][q] for r in doc["ratios"]])
            if doc["ratios"]
            else float("nan")
            for q in ("paper_over_joint", "joint_over_crlb", "paper_over_crlb")
        }
        lines.append(
            f"| {g} | {_g(vals['paper_over_joint'])} | {_g(vals['joint_over_crlb'])} "
            f"| {_g(vals['paper_over_crlb'])} |"
        )
    return lines


def _static_markdown(doc: dict) -> list[str]:
    """Six still poses against the wheel, one table per Table I noise level."""
    lines = ["", "## Six still poses against the wheel (same sensor, noise, total time)", ""]
    for c in doc["static"]:
        plan = c["plan"]
        lines += [
            f"σ_n = {c['sigma_mps2']:g} m/s²: {plan['poses']} poses in {plan['total_s']:g} s, "
            f"{plan['settle_s']:g} s settling each → {plan['usable_per_pose_s']:g} s "
            f"({plan['samples_per_pose']} samples) per pose.",
            "",
            "| parameter | static σ | static bound | wheel joint σ | wheel CRLB | wheel / static |",
            "|---|---|---|---|---|---|",
        ]
        for n, v in c["parameters"].items():
            lines.append(
                f"| {n} | {_g(v['static_std'])} | {_g(v['static_bound_std'])} "
                f"| {_g(v['wheel_joint_std'])} | {_g(v['wheel_crlb_std'])} "
                f"| {_g(v['wheel_over_static'])} |"
            )
        lines.append("")
    return lines


def _precision_markdown(title: str, column: str, key: str, points: list[dict]) -> list[str]:
    """Wheel and static σ of offsets and gains against one plan quantity (``key``)."""
    lines = [
        f"## {title}",
        "",
        f"| {column} | wheel offset σ (m/s²) | static offset σ | wheel gain σ | static gain σ |",
        "|---|---|---|---|---|",
    ]
    for p in points:
        lines.append(f"| {p[key]:g} | " + " | ".join(_group_means(p)) + " |")
    return lines


def _findings_markdown(doc: dict) -> list[str]:
    """The paper's claims, measured, per estimator; ends the summary."""
    lines = ["", "## Findings (paper's claims, measured)", ""]
    for e, f in doc["findings"].items():
        if f["max_abs_group_deviation_pct"]:
            dev = ", ".join(f"{g} {v:.3g} %" for g, v in f["max_abs_group_deviation_pct"].items())
            lines.append(f"- **{e}**: largest |normalised deviation| up to 0.2 m/s²: {dev}.")
            worst = max(f["max_abs_bias_over_se"].items(), key=lambda kv: kv[1])
            lines.append(
                f"  Largest |bias| / standard error up to 0.2 m/s²: {worst[0]} {worst[1]:.1f}."
            )
        if f["std_vs_sigma_loglog_slope"]:
            sl = ", ".join(f"{g} {v:.2f}" for g, v in f["std_vs_sigma_loglog_slope"].items())
            lines.append(f"  Slope of log σ against log σ_n (1 = proportional): {sl}.")
        weakest = sorted(set(f["weakest_group"].values()))
        lines.append(f"  Largest normalised σ (weakest group): {', '.join(weakest)}.")
    lines.append("")
    return lines


def _group_means(point: dict) -> list[str]:
    out = []
    for g in _SENSOR_GROUPS:
        for q in ("wheel_crlb_std", "static_std"):
            vals = _group_values(point["parameters"], g, q)
            out.append(_g(None if any(v is None for v in vals) else float(np.mean(vals))))
    return out


def _group_values(parameters: dict, group: str, key: str) -> list:
    """``key`` of every parameter of ``group`` in a ``{name: {key: value}}`` table."""
    return [v[key] for n, v in parameters.items() if group_of(n) == group]
