"""A batch at a glance, for people without a Rerun viewer: ``<out>/overview.png``.

One panel per parameter (gains, offsets, tilt, misalignment, and the radius
when it was fitted): each session's estimate with its ±σ error bar, the group
mean (per sensor and mounting) as a dashed line, and, for offsets and gains,
the sensor's pooled value with its ±σ band.  Then one panel per axis: the
residual's mean per bin of the wheel angle ϑ (``fit.residual_by_wheel_angle``
of each calibration), every session a line — a pattern that repeats every
turn is an effect the model lacks (an imbalance, a nonlinearity).  A group of
more than :data:`DENSE_SESSIONS` sessions is drawn denser: uncapped bars and,
for the residuals, the group's median with its 5–95 % band.

If the points scatter much more than their bars, σ does not cover something
that varies between sessions (remounting, temperature); ``report.md`` says by
how much.

matplotlib (the ``plots`` extra) is imported inside :func:`overview_png`, and
through its object API only (``Figure`` + the Agg canvas): no pyplot, no global
state.  Without it, the function says so instead of drawing.
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping, Sequence

import numpy as np

from wheelcal.calibration import read_only_document
from wheelcal.io import MARK_TEXT
from wheelcal.model import GAIN_NAMES, OFFSET_NAMES

OVERVIEW_FILE = "overview.png"
MISSING_MATPLOTLIB = "matplotlib is not installed (pip install 'wheelcal[plots]')"
PANEL_PARAMETERS = (
    *GAIN_NAMES,
    *OFFSET_NAMES,
    "tilt_deg",
    "euler_1_deg",
    "euler_2_deg",
    "euler_3_deg",
    "radius_m",
)
_POOLED = {
    **{f"gain_{a}": ("gain", "gain_std", k) for k, a in enumerate("xyz")},
    **{f"offset_{a}_mps2": ("offset_mps2", "offset_std_mps2", k) for k, a in enumerate("xyz")},
}
_COLUMNS = 4
#: Above this many sessions in a group, points lose their caps and the residual
#: panel draws the group's median and 5–95 % band instead of one line per session:
#: a thousand capped bars or lines are one blob (and most of the drawing time).
DENSE_SESSIONS = 150


def _number(x) -> float:
    return math.nan if x is None else float(x)


def overview_png(
    calibrations: Sequence[Mapping],
    sensors: Sequence[Mapping] = (),
    title: str = "",
    numbers: Sequence[int] | None = None,
    dpi: int = 80,
    origin: str | None = None,
) -> tuple[bytes | None, str]:
    """The overview as PNG bytes, or ``(None, why not)``.

    Parameters
    ----------
    calibrations:
        Session calibration dictionaries (``wheelcal.calibration/1``), in report order.
    sensors:
        Pooled sensor calibrations (``wheelcal.sensor_calibration/1``): their
        value ±σ is drawn as a band on the offset and gain panels.
    title:
        The figure's title (the pipeline's name).
    numbers:
        The sessions' numbers in ``report.md`` (default 1, 2, …).
    dpi:
        Resolution; the figure is 14.4 in wide.
    origin:
        The mark of wheelcal's outputs (:mod:`wheelcal.io.ownership`), stored as
        the PNG's ``wheelcal-output`` text.
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        return None, MISSING_MATPLOTLIB
    if not calibrations:
        return None, "no session was calibrated"
    numbers = list(numbers) if numbers is not None else list(range(1, len(calibrations) + 1))
    calibrations = [read_only_document(cal) for cal in calibrations]
    groups: dict[tuple[str, str], list[int]] = {}
    for i, cal in enumerate(calibrations):
        src = cal.get("source", {})
        key = (str(src.get("sensor_id") or "-"), str(src.get("mounting_id") or "-"))
        groups.setdefault(key, []).append(i)
    colours = {key: f"C{k % 10}" for k, key in enumerate(groups)}
    names = [
        p for p in PANEL_PARAMETERS if any(p in cal.get("parameters", {}) for cal in calibrations)
    ]
    rows = math.ceil(len(names) / _COLUMNS) + 1
    fig = Figure(figsize=(3.6 * _COLUMNS, 2.7 * rows), dpi=dpi)
    fig.subplots_adjust(left=0.06, right=0.98, bottom=0.05, top=0.94, wspace=0.3, hspace=0.45)
    FigureCanvasAgg(fig)
    if title:
        fig.suptitle(f"{title}: {len(calibrations)} calibrated sessions")
    axes = fig.subplots(rows, _COLUMNS, squeeze=False)
    pooled = {str(s.get("sensor_id") or "-"): s for s in sensors}
    for ax, name in zip(axes.flat, names, strict=False):
        _parameter_panel(ax, name, calibrations, groups, colours, numbers, pooled)
    for ax in list(axes.flat)[len(names) : (rows - 1) * _COLUMNS]:
        ax.set_axis_off()
    bottom = axes[-1]
    for k, axis in enumerate("xyz"):
        _residual_panel(bottom[k], k, axis, calibrations, groups, colours)
    _legend_panel(bottom[3], groups, colours)
    buffer = io.BytesIO()
    # the mark of wheelcal's outputs (wheelcal.io.ownership): a PNG text chunk
    marked = {MARK_TEXT: origin} if origin else {}
    fig.savefig(buffer, format="png", metadata={"Software": None, **marked})
    return buffer.getvalue(), ""


def _parameter_panel(ax, name, calibrations, groups, colours, numbers, pooled) -> None:
    for key, members in groups.items():
        xs, ys, es = [], [], []
        for i in members:
            entry = calibrations[i].get("parameters", {}).get(name)
            if entry is None:
                continue
            xs.append(numbers[i])
            ys.append(_number(entry.get("value")))
            es.append(_number(entry.get("std")))
        if not xs:
            continue
        bars = [e if math.isfinite(e) else 0.0 for e in es]
        if len(xs) > DENSE_SESSIONS:
            _dense_points(ax, xs, ys, bars, colours[key])
        else:
            ax.errorbar(xs, ys, yerr=bars, fmt="o", ms=3.5, capsize=2, color=colours[key], lw=1)
        finite = [y for y in ys if math.isfinite(y)]
        if finite:
            mean = sum(finite) / len(finite)
            ax.hlines(mean, min(xs) - 0.4, max(xs) + 0.4, colors=colours[key], linestyles="--")
        sensor = pooled.get(key[0])
        if sensor is not None and name in _POOLED:
            value_key, std_key, k = _POOLED[name]
            value = _number(sensor["sensor"][value_key][k])
            std = _number(sensor["sensor"][std_key][k])
            if math.isfinite(value) and math.isfinite(std):
                ax.axhspan(value - std, value + std, color=colours[key], alpha=0.15, lw=0)
                ax.axhline(value, color=colours[key], lw=0.8)
    ax.set_title(name, fontsize=10)
    ax.set_xlabel("session", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.ticklabel_format(axis="y", useOffset=False, style="sci", scilimits=(-3, 4))
    # Few ticks: tick layout is most of the drawing time.
    ax.yaxis.get_major_locator().set_params(nbins=4)
    ax.xaxis.get_major_locator().set_params(nbins=6, integer=True)


def _residual_panel(ax, k, axis, calibrations, groups, colours) -> None:
    from matplotlib.collections import LineCollection

    drawn = 0
    for key, members in groups.items():
        curves = []  # one collection per group: one artist, however many sessions
        for i in members:
            profile = calibrations[i].get("fit", {}).get("residual_by_wheel_angle")
            if not profile or not profile.get("centres_deg"):
                continue
            values = [_number(row[k]) for row in profile["mean_mps2"]]
            curves.append(np.column_stack([np.asarray(profile["centres_deg"], float), values]))
        if len(curves) > DENSE_SESSIONS and _band(ax, curves, colours[key]):
            drawn += len(curves)
        elif curves:
            ax.add_collection(LineCollection(curves, colors=colours[key], lw=0.8, alpha=0.6))
            drawn += len(curves)
    if drawn:
        ax.autoscale_view()
    ax.axhline(0.0, color="0.5", lw=0.6)
    ax.set_xlim(0, 360)
    ax.set_xticks([0, 90, 180, 270, 360])
    ax.yaxis.get_major_locator().set_params(nbins=4)
    ax.set_title(f"residual {axis} (m/s²) vs wheel angle ϑ", fontsize=10)
    ax.set_xlabel("ϑ mod 360° (mean per bin)", fontsize=8)
    ax.tick_params(labelsize=7)
    if not drawn:
        ax.text(
            0.5,
            0.5,
            "no residual profile in\nthe calibration files",
            ha="center",
            va="center",
            transform=ax.transAxes,
            fontsize=8,
        )


def _dense_points(ax, xs, ys, bars, colour: str) -> None:
    """Points with thin uncapped bars, as one collection (``errorbar`` builds them one by one)."""
    from matplotlib.collections import LineCollection

    x, y, e = (np.asarray(v, dtype=float) for v in (xs, ys, bars))
    segments = np.stack([np.column_stack([x, y - e]), np.column_stack([x, y + e])], axis=1)
    ax.add_collection(LineCollection(segments, colors=colour, lw=0.4, alpha=0.35))
    ax.plot(x, y, "o", ms=1.5, color=colour)


def _band(ax, curves: list[np.ndarray], colour: str) -> bool:
    """The curves' median and 5–95 % band, if they share their bins (else False)."""
    centres = curves[0][:, 0]
    if any(c.shape != curves[0].shape or not np.array_equal(c[:, 0], centres) for c in curves):
        return False
    values = np.stack([c[:, 1] for c in curves])
    if not np.isfinite(values).any():
        return False
    low, mid, high = np.nanpercentile(values, [5.0, 50.0, 95.0], axis=0)
    ax.fill_between(centres, low, high, color=colour, alpha=0.25, lw=0)
    ax.plot(centres, mid, color=colour, lw=1.0)
    return True


def _legend_panel(ax, groups, colours) -> None:
    ax.set_axis_off()
    lines = ["Groups (sensor / mounting):"]
    for key, members in groups.items():
        lines.append(f"● {key[0]} / {key[1]} ({len(members)} sessions)")
    lines += [
        "",
        "points: estimate ± σ (statistical)",
        *(
            ["residual: median, 5–95 % band"]
            if any(len(m) > DENSE_SESSIONS for m in groups.values())
            else []
        ),
        "dashed: group mean",
        "band: the sensor's pooled value ± σ",
    ]
    for row, text in enumerate(lines):
        colour = "black"
        if text.startswith("●"):
            colour = colours[list(groups)[row - 1]]
        ax.text(
            0.0,
            1.0 - 0.085 * row,
            text,
            transform=ax.transAxes,
            fontsize=8,
            va="top",
            color=colour,
            wrap=True,
        )
