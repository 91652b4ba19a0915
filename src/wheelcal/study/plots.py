"""Figures of the study as PNG bytes (matplotlib, Agg backend, imported here only).

* :func:`figure_mean_deviation` — the paper's Fig. 7, per group, with the
  band ±2 σ_CRLB/√n that an efficient, unbiased estimator's mean stays in;
* :func:`figure_normalised_std` — the paper's Fig. 8 with the CRLB on the same axes;
* :func:`figure_static` — six still poses against the wheel at the Table I levels;
* :func:`figure_duration` — σ of offsets and gains against recording length and rate.
"""

from __future__ import annotations

import io

import numpy as np

from wheelcal.study.duration import SENSOR_NAMES
from wheelcal.study.montecarlo import PARAMETER_GROUPS, group_of
from wheelcal.study.runner import StudyResult

_STYLE = {
    "paper": {"color": "tab:orange", "marker": "s", "label": "paper's method (ours)"},
    "joint": {"color": "tab:blue", "marker": "o", "label": "joint ML fit"},
}
_GROUP_TITLES = {
    "motion": "motion ϑ₀, ω₀…ω₃ (first-sample origin)",
    "tilt": "bench tilt α",
    "misalignment": "misalignment θ, φ, ψ",
    "gain": "gain γ",
    "offset": "offset o (m/s²)",
}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120, bbox_inches="tight")
    _pyplot().close(fig)
    return buf.getvalue()


def _group_panels():
    """Figure and axes of Fig. 7 and 8: one panel per parameter group, σ_n along x."""
    return _pyplot().subplots(1, len(PARAMETER_GROUPS), figsize=(18, 3.8), sharex=True)


def _finished_group_panels(fig, axes, ylabel: str, legend_loc: str, title: str) -> bytes:
    """The PNG of :func:`_group_panels` once drawn: group titles, σ_n label, grids, legend."""
    for ax, group in zip(axes, PARAMETER_GROUPS, strict=True):
        ax.set_title(_GROUP_TITLES[group], fontsize=9)
        ax.set_xlabel("σ_n (m/s²)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel(ylabel)
    axes[0].legend(fontsize=7, loc=legend_loc)
    fig.suptitle(title, fontsize=11)
    return _png(fig)


def _series(result: StudyResult, estimator: str, quantity: str, group: str):
    levels = result.sweep.get(estimator, ())
    x = np.array([s.sigma_mps2 for s in levels])
    y = np.array([s.group_mean(getattr(s, quantity))[group] for s in levels])
    return x, y


def figure_mean_deviation(result: StudyResult, limit_pct: float = 1.0) -> bytes:
    """Fig. 7: normalised deviation 100(μ/v_true − 1) % against σ_n, one panel per group.

    Linear axes to ±``limit_pct`` (4× the paper's ±0.25 % criterion); points
    beyond are drawn at the edge as triangles pointing off-scale.
    """
    fig, axes = _group_panels()
    joint = result.sweep["joint"]
    for ax, group in zip(axes, PARAMETER_GROUPS, strict=True):
        sig = np.array([s.sigma_mps2 for s in joint])
        # 2 SE of an efficient estimator's mean, normalised as Fig. 7 (per group, RMS).
        band = np.array(
            [
                200.0
                * np.sqrt(s.group_mean((s.crlb_std / np.abs(s.truth)) ** 2)[group])
                / np.sqrt(s.runs)
                for s in joint
            ]
        )
        ax.fill_between(sig, -band, band, color="0.85", label="±2 σ_CRLB/√n")
        for estimator in result.sweep:
            x, y = _series(result, estimator, "normalised_deviation_pct", group)
            st = _STYLE[estimator]
            clipped = np.clip(y, -limit_pct, limit_pct)
            ax.plot(x, clipped, marker=st["marker"], color=st["color"], label=st["label"], ms=4)
            for sign, marker in ((1, "^"), (-1, "v")):
                off = sign * y > limit_pct
                ax.plot(x[off], clipped[off], marker, color=st["color"], ms=9)
        ax.axhline(0.25, color="k", lw=0.6, ls=":")
        ax.axhline(-0.25, color="k", lw=0.6, ls=":", label="±0.25 % (paper)")
        ax.set_xscale("log")
        ax.set_ylim(-1.08 * limit_pct, 1.08 * limit_pct)
    return _finished_group_panels(
        fig,
        axes,
        "normalised deviation (%)",
        "lower left",
        "Mean of the estimates (paper Fig. 7), Table I truth; ▲▼ = off scale",
    )


def figure_normalised_std(result: StudyResult) -> bytes:
    """Fig. 8: normalised σ against σ_n per group, CRLB on the same axes."""
    fig, axes = _group_panels()
    for ax, group in zip(axes, PARAMETER_GROUPS, strict=True):
        for estimator in result.sweep:
            x, y = _series(result, estimator, "normalised_std", group)
            st = _STYLE[estimator]
            ax.loglog(x, y, marker=st["marker"], color=st["color"], label=st["label"], ms=4)
        x, y = _series(result, "joint", "crlb_normalised_std", group)
        ax.loglog(x, y, color="k", ls="--", lw=1, label="CRLB")
    return _finished_group_panels(
        fig,
        axes,
        "σ / μ  (gain, offset: σ)",
        "upper left",
        "Spread of the estimates (paper Fig. 8), Table I truth",
    )


def figure_static(result: StudyResult) -> bytes:
    """σ of offsets and gains: six still poses against the wheel (joint fit and CRLB)."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
    names = np.array(SENSOR_NAMES)
    for ax, group, unit in zip(axes, ("offset", "gain"), ("m/s²", ""), strict=True):
        idx = [i for i, n in enumerate(names) if group_of(n) == group]
        labels = []
        series: dict[str, list[float]] = {"static": [], "wheel joint": [], "wheel CRLB": []}
        for c in result.static:
            for i in idx:
                labels.append(f"{names[i].split('_')[1]}\n{c.sigma_mps2:g}")
                series["static"].append(c.static.std[i])
                series["wheel joint"].append(c.wheel_joint_std[i])
                series["wheel CRLB"].append(c.wheel_crlb_std[i])
        x = np.arange(len(labels))
        for k, (label, vals) in enumerate(series.items()):
            ax.bar(x + (k - 1) * 0.27, vals, width=0.27, label=label)
        ax.set_xticks(x, labels, fontsize=8)
        ax.set_ylabel(f"σ {unit}".strip())
        ax.set_xlabel("axis / σ_n (m/s²)")
        ax.set_title(f"{group}s", fontsize=10)
        ax.grid(True, axis="y", which="both", alpha=0.3)
    plan = result.static[0].static.plan if result.static else None
    if plan is not None:
        fig.suptitle(
            f"Six still poses vs the wheel, both {plan.total_s:g} s at {plan.rate_hz:g} Hz "
            f"({plan.settle_s:g} s settling per pose)",
            fontsize=10,
        )
    axes[0].legend(fontsize=8)
    return _png(fig)


def figure_duration(result: StudyResult) -> bytes:
    """σ of offsets and gains against recording length (top) and sampling rate (bottom)."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5))
    rows = (
        (result.durations, "duration_s", "recording length T (s)"),
        (result.rates, "rate_hz", "sampling rate (Hz)"),
    )
    for r, (points, axis, xlabel) in enumerate(rows):
        x = np.array([getattr(p, axis) for p in points])
        for c, group in enumerate(("offset", "gain")):
            ax = axes[r, c]
            idx = [i for i, n in enumerate(SENSOR_NAMES) if group_of(n) == group]

            def mean(values, idx=idx):
                return np.array([np.mean(v[idx]) for v in values])

            ax.loglog(x, mean([p.wheel_std for p in points]), "o-", label="wheel (CRLB)")
            ax.loglog(x, mean([p.static_std for p in points]), "s-", label="six poses")
            ax.loglog(
                x,
                mean([p.static_no_settle_std for p in points]),
                "s--",
                color="tab:orange",
                alpha=0.5,
                label="six poses, no settling",
            )
            checks = [
                ch
                for ch in result.checks
                if (axis == "duration_s" and ch.rate_hz == result.config.duration.base_rate_hz)
                or (axis == "rate_hz" and ch.duration_s == result.config.duration.base_duration_s)
            ]
            if checks:
                ax.loglog(
                    [getattr(ch, axis) for ch in checks],
                    mean([ch.joint_std for ch in checks]),
                    "kx",
                    ms=9,
                    label="wheel, joint fit (Monte Carlo)",
                )
            ax.set_xticks(x, [f"{v:g}" for v in x])
            ax.minorticks_off()
            ax.set_xlabel(xlabel)
            ax.set_ylabel(f"{group} σ" + (" (m/s²)" if group == "offset" else ""))
            ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    d = result.config.duration
    fig.suptitle(
        f"Table I sensor, σ_n = {d.sigma_mps2:g} m/s² white; "
        f"top: {d.base_rate_hz:g} Hz, bottom: {d.base_duration_s:g} s; mean over axes",
        fontsize=10,
    )
    return _png(fig)


#: Output file name → figure function.
FIGURES = {
    "fig7_mean_deviation.png": figure_mean_deviation,
    "fig8_normalised_std.png": figure_normalised_std,
    "static_vs_wheel.png": figure_static,
    "duration_rate.png": figure_duration,
}
