"""Rerun view of a batch: each parameter per session with its ±σ, the value you apply, a verdict.

Input: the per-session calibration dictionaries of
:func:`wheelcal.calibration.session_json.calibration_dict` (as loaded from
``<stem>.calibration.json``) — ``source.file``, ``source.sensor_id``,
``source.mounting_id`` and ``parameters: {name: {value, std}}`` (JSON ``null``,
an undetermined σ, is accepted) — and, from a batch run, its ``report.json``
dictionary: the sensors' pooled calibrations (the value you apply), each
group's statistics (ratio, its p, the systematic σ) and every session's
status, clip share, window, effects and notes.

Timeline ``session``: a sequence, the session's number — as in ``report.md``
and the files (``session001`` is 1; by default 1, 2, … in input order), the
same numbering in every group, so a number names one file.  Entities, with
``<g>`` = ``<sensor_id>/<mounting_id>`` (``unspecified`` where empty; escaped
as entity-path parts) and ``<p>`` a contract parameter name:

* ``/batch/<g>/<p>/value`` — the estimate, one point per session (an angle
  unwrapped about the sessions' circular mean, :mod:`wheelcal.calibration.angles`);
* ``/batch/<g>/<p>/band`` — value − σ and value + σ, steps centred on each session;
* ``/batch/<g>/<p>/applied`` — the value you apply as a line across the group's
  sessions, and ``…/applied_band`` its ± σ: for a gain or an offset the sensor's
  pooled calibration (``sensors/<id>.calibration.json``, over all its sessions),
  for the bench's parameters the group's (circular) mean ± its σ (std / √n);
* ``/batch/<g>/<p>/problem`` — the sessions with a problem (a warning, an
  outlier, an undetermined parameter, a fit that did not converge), ringed;
* ``/batch/<g>/report`` — markdown: per parameter the applied value ± σ, σ sys,
  mean, std (ddof = 1), predicted std (RMS of the σ), ratio, its p and ⚠ (p < 0.01),
  as ``report.json``; the spin's parameters (θ₀, ω₀ … ω₃) mean and std only;
* ``/report`` — markdown: every session — number, ⚠, file, status, clip share,
  window, effects found, notes — failed and refused ones included.

If the scatter of the points matches their bands (ratio ≈ 1), σ is honest;
ratio ≫ 1 means something varies between sessions that σ does not cover.

Blueprint: the sessions tab first; per group a tab of its repeatable parameters,
two plots a row (wide enough for the viewer to label every session's number on
the x-axis) beside the group report, and a tab of its spins.  It opens on the
first group's tab, paused on ``session``, every plot over all sessions on one
shared x-axis, the side panels collapsed (see
:mod:`wheelcal.viz.session_blueprint` for the shared axis).  No legends: the
group report says what each mark is.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from wheelcal.calibration import Calibration, as_angles
from wheelcal.viz.blueprint_chunks import blueprint_chunks, send_blueprint_chunks
from wheelcal.viz.rrd_writer import rrd_file
from wheelcal.viz.session_blueprint import GLOBAL_VIEW_PATH

APPLICATION_ID = "wheelcal_batch"
SESSION_TIMELINE = "session"
UNSPECIFIED = "unspecified"
#: Parameters of the hand spin (θ₀, ω₀ … ω₃): each session has its own by nature.
PER_SESSION_PREFIXES = ("theta", "omega")
#: A ratio whose χ² p-value is below this is flagged ⚠ (as report.md).
FLAG_P = 0.01
#: The sensor's pooled block, per parameter: (value key, σ key, systematic σ key, axis).
_POOLED = {
    **{f"gain_{a}": ("gain", "gain_std", "gain_std", k) for k, a in enumerate("xyz")},
    **{
        f"offset_{a}_mps2": ("offset_mps2", "offset_std_mps2", "offset_std_mps2", k)
        for k, a in enumerate("xyz")
    },
}

_VALUE_COLOR = (38, 110, 210)
_BAND_COLOR = (38, 110, 210, 110)
_APPLIED_COLOR = (20, 20, 20)
_APPLIED_BAND_COLOR = (20, 20, 20, 90)
_PROBLEM_COLOR = (230, 20, 20)
_LINKED = rrb.TimeAxis(link=rrb.components.LinkAxis.LinkToGlobal)


def per_session(name: str) -> bool:
    """True for a parameter of the hand spin, which differs per session by nature."""
    return name.startswith(PER_SESSION_PREFIXES)


@dataclass
class _Group:
    """Sessions of one sensor and mounting."""

    sensor_id: str
    mounting_id: str
    sessions: list[int] = field(default_factory=list)
    # name -> list of (session number, value, std); value/std NaN when absent or null
    parameters: dict[str, list[tuple[int, float, float]]] = field(default_factory=dict)

    @property
    def path(self) -> str:
        return "batch/" + "/".join(
            rr.escape_entity_path_part(part or UNSPECIFIED)
            for part in (self.sensor_id, self.mounting_id)
        )

    @property
    def title(self) -> str:
        return f"{self.sensor_id or UNSPECIFIED} / {self.mounting_id or UNSPECIFIED}"


@dataclass(frozen=True)
class _Applied:
    """The value a user applies for one parameter of a group, its σ and systematic σ."""

    value: float
    std: float
    systematic_std: float
    source: str  # "sensor" (the pooled calibration) or "group" (the group's mean)


def _parameter_rank(name: str) -> int:
    """Sensor parameters first, then bench, then motion and effects (as the session report)."""
    for rank, prefix in enumerate(("gain_", "offset_", "tilt_", "euler_", "radius_")):
        if name.startswith(prefix):
            return rank
    return 10 if per_session(name) else 9


def _groups(
    sessions: Sequence[Mapping], numbers: Sequence[int]
) -> tuple[list[_Group], list[tuple[int, str]]]:
    """Group the sessions by (sensor_id, mounting_id), in order of first appearance."""
    groups: dict[tuple[str, str], _Group] = {}
    files: list[tuple[int, str]] = []
    for index, (number, session) in enumerate(zip(numbers, sessions, strict=True)):
        try:
            cal = session if isinstance(session, Calibration) else Calibration(session)
            key = (cal.sensor_id, cal.mounting_id)
            files.append((number, cal.source_file or f"session {number}"))
            group = groups.setdefault(key, _Group(*key))
            group.sessions.append(number)
            for name, (value, std) in cal.parameters.items():
                group.parameters.setdefault(name, []).append((number, value, std))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ValueError(
                f"batch .rrd: session {index} (number {number}) is not a calibration "
                f"(needs source and parameters {{name: {{value, std}}}}): {exc!r}"
            ) from None
    for group in groups.values():
        group.parameters = dict(
            sorted(group.parameters.items(), key=lambda item: _parameter_rank(item[0]))
        )
        for name, entries in group.parameters.items():  # angles as angles
            values = as_angles(name, [v for _, v, _ in entries])
            group.parameters[name] = [
                (i, float(v), s) for (i, _, s), v in zip(entries, values, strict=True)
            ]
    return list(groups.values()), files


def group_statistics(entries: list[tuple[int, float, float]]) -> dict[str, float]:
    """Mean, std (ddof = 1), predicted std (RMS of σ) and ratio, as ``report.json``.

    The values are a group's as :func:`_groups` keeps them: angles already unwrapped.
    """
    values = np.array([v for _, v, _ in entries if math.isfinite(v)])
    stds = np.array([s for _, v, s in entries if math.isfinite(v)])
    mean = float(values.mean()) if values.size else math.nan
    std = float(values.std(ddof=1)) if values.size > 1 else math.nan
    predicted = float(np.sqrt(np.mean(stds**2))) if stds.size else math.nan
    ratio = std / predicted if predicted > 0 else math.nan
    return {"mean": mean, "std": std, "predicted_std": predicted, "ratio": ratio}


def _number(x) -> float:
    return math.nan if x is None else float(x)


def _applied(group: _Group, name: str, sensors: Mapping[str, Mapping], stats: Mapping) -> _Applied:
    """What a user applies: the sensor's pooled value, else the group's mean ± std/√n."""
    sensor = sensors.get(group.sensor_id)
    if sensor is not None and name in _POOLED:
        value_key, std_key, sys_key, k = _POOLED[name]
        block = sensor.get("sensor", {})
        systematic = sensor.get("systematic", {}).get(sys_key) or [None] * 3
        return _Applied(
            _number(block[value_key][k]),
            _number(block[std_key][k]),
            _number(systematic[k]),
            "sensor",
        )
    entries = group.parameters[name]
    n = sum(math.isfinite(v) for _, v, _ in entries)
    s = group_statistics(entries)
    sigma = s["std"] / math.sqrt(n) if n > 1 else math.nan
    systematic = _number(stats.get("systematic_std", {}).get(name))
    return _Applied(s["mean"], sigma, systematic, "group")


def _fmt(x: float, digits: int) -> str:
    return f"{x:.{digits}g}" if math.isfinite(x) else "—"


def _series(stream, path: str, index: np.ndarray, values: np.ndarray, style) -> None:
    stream.log(path, style, static=True)
    stream.send_columns(
        path,
        indexes=[rr.TimeColumn(SESSION_TIMELINE, sequence=index)],
        columns=rr.Scalars.columns(scalars=values),
    )


def _log_parameter(
    stream: rr.RecordingStream,
    path: str,
    entries: list[tuple[int, float, float]],
    applied: _Applied | None = None,
    problems: frozenset[int] = frozenset(),
) -> None:
    index = np.array([i for i, _, _ in entries], dtype=np.int64)
    value = np.array([v for _, v, _ in entries])
    std = np.array([s for _, _, s in entries])
    shown = np.isfinite(value)
    if not shown.any():
        return
    style = rr.SeriesPoints(
        colors=[_VALUE_COLOR], names=["estimate ± σ"], markers=["circle"], marker_sizes=[4.0]
    )
    _series(stream, f"{path}/value", index[shown], value[shown], style)
    banded = shown & np.isfinite(std)
    if banded.any():
        band = np.column_stack([value[banded] - std[banded], value[banded] + std[banded]])
        style = rr.SeriesLines(
            colors=[_BAND_COLOR] * 2,
            names=["±σ"] * 2,
            widths=[1.0, 1.0],
            interpolation_mode="StepMid",
        )
        _series(stream, f"{path}/band", index[banded], band, style)
    problem = shown & np.isin(index, sorted(problems))
    if problem.any():
        style = rr.SeriesPoints(
            colors=[_PROBLEM_COLOR],
            names=["problem session"],
            markers=["circle"],
            marker_sizes=[7.0],
        )
        _series(stream, f"{path}/problem", index[problem], value[problem], style)
    if applied is not None and math.isfinite(applied.value):
        ends = np.array([index[shown].min(), index[shown].max()], dtype=np.int64)
        label = "the sensor's pooled value" if applied.source == "sensor" else "the group mean"
        style = rr.SeriesLines(colors=[_APPLIED_COLOR], names=[label], widths=[1.5])
        _series(stream, f"{path}/applied", ends, np.full(2, applied.value), style)
        if math.isfinite(applied.std):
            band = np.array([[applied.value - applied.std, applied.value + applied.std]] * 2)
            style = rr.SeriesLines(
                colors=[_APPLIED_BAND_COLOR] * 2, names=[f"{label} ± σ"] * 2, widths=[1.0, 1.0]
            )
            _series(stream, f"{path}/applied_band", ends, band, style)


def _numbers_text(numbers: Sequence[int]) -> str:
    """``1–10`` for a run, else the list."""
    if numbers and list(numbers) == list(range(numbers[0], numbers[0] + len(numbers))):
        return f"{numbers[0]}–{numbers[-1]}" if len(numbers) > 1 else str(numbers[0])
    return ", ".join(map(str, numbers))


def _group_stats(report: Mapping | None, group: _Group) -> Mapping:
    """The group's entry of ``report.json`` (its ratios' p and systematic σ), if given."""
    for g in (report or {}).get("groups", []):
        if (g.get("sensor_id") or "", g.get("mounting_id") or "") == (
            group.sensor_id,
            group.mounting_id,
        ):
            return g
    return {}


def _group_report(
    group: _Group, sensors: Mapping[str, Mapping], report: Mapping | None = None
) -> str:
    stats = _group_stats(report, group)
    sensor = sensors.get(group.sensor_id)
    pooled_from = (
        f"the sensor's pooled calibration ({sensor.get('sessions', '?')} sessions, "
        f"{str(sensor.get('method', '')).replace('_', ' ')})"
        if sensor
        else "no pooled calibration given"
    )
    lines = [
        f"# {group.title}",
        "",
        f"{len(group.sessions)} sessions: {_numbers_text(group.sessions)}",
        "",
        "| parameter | apply ± σ | σ sys | std | ratio | p |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    spin = []
    for name, entries in group.parameters.items():
        s = group_statistics(entries)
        if per_session(name):
            spin.append(f"| `{name}` | {_fmt(s['mean'], 7)} | {_fmt(s['std'], 2)} |")
            continue
        entry = stats.get("parameters", {}).get(name, {})
        p = _number(entry.get("ratio_p_value"))
        flag = " ⚠" if math.isfinite(p) and p < FLAG_P else ""
        a = _applied(group, name, sensors, stats)
        mark = "" if a.source == "sensor" else "ᵍ"
        lines.append(
            f"| {name} | {_fmt(a.value, 6)}{mark} ± {_fmt(a.std, 2)} | "
            f"{_fmt(a.systematic_std, 2)} | {_fmt(s['std'], 2)} "
            f"| {_fmt(s['ratio'], 3)} | {_fmt(p, 2)}{flag} |"
        )
    lines += [
        "",
        f"**apply**: gains and offsets from {pooled_from} — the value to apply, its "
        "statistical σ, and σ sys (radius, gravity, clock: shared, not divided by √n); ᵍ: "
        "the bench's parameters, this group's (circular) mean ± std/√n. **std** over the "
        "sessions, ddof = 1; **ratio** std / the RMS of the sessions' σ (≈ 1 "
        "when σ is honest) and its **p** (χ², n − 1 dof); ⚠ p < 0.01: something varies between "
        "sessions that σ misses. Angles are averaged as angles.",
        "",
        "Plots: blue points, each session ± σ; black line, the value to apply, with its ± σ; "
        "red rings, sessions to look at (why: the sessions tab).",
    ]
    if spin:
        lines += [
            "",
            "**Per session by nature** — the hand spin (start angle θ₀, rate ω₀ … ω₃) "
            "differs every time; no ratio:",
            "",
            "| parameter | mean | std |",
            "|---|---:|---:|",
            *spin,
        ]
    return "\n".join(lines) + "\n"


#: A session that clipped more than this share of its samples (per cent) is one to look at:
#: its window and its σ lost that much of the spin.
CLIPPED_PROBLEM_PERCENT = 5.0


def problems_of(entry: Mapping) -> list[str]:
    """Why a person must look at a session: refused, failed, warnings, outliers, clipping."""
    if entry.get("gate"):
        return [f"refused ({entry['gate']})"]
    if entry.get("status") == "failed":
        return ["failed"]
    notes = entry.get("notes", [])
    out = []
    warned = sum(n.startswith("⚠") for n in notes)
    if warned:
        out.append(f"{warned} warning{'s' if warned > 1 else ''}")
    out += [n.split(" (")[0] for n in notes if n.startswith(("outlier", "undetermined"))]
    clip = entry.get("clipped_percent") or 0.0
    if clip >= CLIPPED_PROBLEM_PERCENT:
        out.append(f"{clip:.2g} % clipped")
    return out


def _problem(entry: Mapping) -> bool:
    return bool(problems_of(entry))


def _sessions_by_number(report: Mapping | None) -> dict[int, Mapping]:
    """``report.json``'s per-session entries by session number (1, 2, … as report.md)."""
    return {i: e for i, e in enumerate((report or {}).get("per_session", []), start=1)}


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _effects_text(entry: Mapping) -> str:
    found = entry.get("effects_found") or []
    if entry.get("status") == "failed" or "model" not in entry:
        return "–"
    if entry.get("model") == "paper":
        return "not screened"
    if not found:
        return "none"
    return ", ".join(f"{e['effect']} (p = {_fmt(_number(e.get('p_corrected')), 2)})" for e in found)


def _overall_report(
    groups: list[_Group], files: list[tuple[int, str]], report: Mapping | None = None
) -> str:
    entries = _sessions_by_number(report)
    owner = {i: g for g in groups for i in g.sessions}
    numbers = sorted(set(entries) | {n for n, _ in files})
    named = dict(files)
    problems = [n for n in numbers if n in entries and _problem(entries[n])]
    lines = [
        f"# wheelcal batch — {len(numbers)} sessions, {len(groups)} "
        + ("group" if len(groups) == 1 else "groups")
        + (f"; ⚠ {len(problems)} to look at: {_numbers_text(problems)}" if problems else ""),
        "",
        "| # | look at | file | sensor / mounting | status | clipped | window (s) | effects "
        "| notes |",
        "|---:|---|---|---|---|---:|---|---|---|",
    ]
    for number in numbers:
        e = entries.get(number, {})
        file = named.get(number) or e.get("file", "?")
        group = owner.get(number)
        who = group.title if group is not None else "–"
        status = e.get("status", "calibrated")
        if e.get("gate"):
            status = f"refused ({e['gate']})"
        window = e.get("window_s")
        clip = e.get("clipped_percent")
        lines.append(
            f"| {number} | {('⚠ ' + ', '.join(problems_of(e))) if e and _problem(e) else ''} "
            f"| `{_cell(file)}` | {_cell(who)} "
            f"| {status} | {'–' if clip is None else f'{clip:.2g} %'} "
            f"| {'–' if not window else f'{window[0]:.2f}–{window[1]:.2f}'} "
            f"| {_cell(_effects_text(e)) if e else '–'} "
            f"| {_cell('; '.join(e.get('notes', []))) if e.get('notes') else '–'} |"
        )
    return "\n".join(lines) + "\n"


class _GlobalSessionAxis:
    """All sessions on the shared x-axis, one session of room either side (a blueprint part)."""

    def __init__(self, first: int, last: int) -> None:
        self.range = rrb.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(seq=first),
            end=rrb.TimeRangeBoundary.absolute(seq=last),
        )

    def _log_to_stream(self, stream) -> None:
        stream.log(GLOBAL_VIEW_PATH, rrb.TimeAxis(view_range=self.range))


def _parameter_grid(group: _Group, names: list[str]) -> rrb.Grid:
    """One plot per parameter, two a row: wide enough for every session's number."""
    plots = [
        rrb.TimeSeriesView(
            origin=f"/{group.path}/{rr.escape_entity_path_part(name)}",
            name=f"{name} (per session)" if per_session(name) else name,
            axis_x=_LINKED,
            plot_legend=rrb.PlotLegend(visible=False),
        )
        for name in names
    ]
    return rrb.Grid(*plots, grid_columns=2)


def batch_blueprint(groups: list[_Group]) -> rrb.Blueprint:
    """Per group a tab of its repeatable parameters and one of its spins; the sessions first."""
    tabs = [rrb.TextDocumentView(origin="/report", name="sessions")]
    for group in groups:
        repeatable = [name for name in group.parameters if not per_session(name)]
        spin = [name for name in group.parameters if per_session(name)]
        for names, title in (
            (repeatable, group.title),
            (spin, f"{group.title}: spin (per session)"),
        ):
            if not names:
                continue
            # A view lives in one container: each tab gets its own view of the report.
            report = rrb.TextDocumentView(origin=f"/{group.path}/report", name="repeatability")
            tabs.append(
                rrb.Horizontal(
                    _parameter_grid(group, names), report, column_shares=[3, 1], name=title
                )
            )
    return rrb.Blueprint(
        rrb.Tabs(*tabs, active_tab=1 if groups else 0),
        rrb.TimePanel(timeline=SESSION_TIMELINE, play_state="paused", state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )


def write_batch_rrd(
    path: str | os.PathLike,
    sessions: Sequence[Mapping],
    numbers: Sequence[int] | None = None,
    report: Mapping | None = None,
    durable: bool = True,
    name: str | None = None,
) -> Path:
    """Write the batch ``.rrd`` (see the module docstring) atomically.

    Parameters
    ----------
    path:
        Destination ``.rrd``; its directory must exist.
    sessions:
        Calibration dictionaries (``calibration_dict`` / loaded JSON).
    numbers:
        The sessions' numbers on the ``session`` timeline, as ``report.md``
        numbers them (default 1, 2, … in the order given).
    report:
        The batch's ``report.json`` dictionary (``sensors``, ``groups``,
        ``per_session``): the values to apply, the ratios' p, σ sys, and every
        session's status; without it the file shows the sessions' own numbers.
    durable:
        fsync the file (see :func:`~wheelcal.viz.rrd_writer.rrd_file`).
    name:
        The recording's name in the viewer (default: the file's stem).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        If ``sessions`` is empty, an entry lacks ``parameters``, or the
        numbers are not one distinct integer per session.
    """
    if not sessions:
        raise ValueError(f"{path}: no sessions to show")
    numbers = list(range(1, len(sessions) + 1)) if numbers is None else [int(n) for n in numbers]
    if len(numbers) != len(sessions) or len(set(numbers)) != len(numbers):
        raise ValueError(f"{path}: need one distinct number per session, got {numbers}")
    groups, files = _groups(sessions, numbers)
    sensors = {str(s.get("sensor_id") or ""): s for s in (report or {}).get("sensors", [])}
    entries = _sessions_by_number(report)
    problems = frozenset(n for n, e in entries.items() if _problem(e))
    with rrd_file(path, APPLICATION_ID, name or Path(path).stem, durable=durable) as stream:
        # The shared x-range lives on the blueprint's global view (not a public part).
        every = sorted(set(numbers) | set(entries))
        axis = _GlobalSessionAxis(min(every) - 1, max(every) + 1)
        send_blueprint_chunks(stream, blueprint_chunks(batch_blueprint(groups), axis))
        stream.log(
            "report",
            rr.TextDocument(
                _overall_report(groups, files, report), media_type=rr.MediaType.MARKDOWN
            ),
            static=True,
        )
        for group in groups:
            stats = _group_stats(report, group)
            for name, entries_ in group.parameters.items():
                applied = None if per_session(name) else _applied(group, name, sensors, stats)
                _log_parameter(
                    stream,
                    f"{group.path}/{rr.escape_entity_path_part(name)}",
                    entries_,
                    applied,
                    problems,
                )
            stream.log(
                f"{group.path}/report",
                rr.TextDocument(
                    _group_report(group, sensors, report), media_type=rr.MediaType.MARKDOWN
                ),
                static=True,
            )
    return Path(path)
