"""Rerun view of a batch: each parameter per session with its ±σ band, by sensor and mounting.

Input: the per-session calibration dictionaries of
:func:`wheelcal.calibration.session_json.calibration_dict` (as loaded from
``<stem>.calibration.json``); only ``source.file``, ``source.sensor_id``,
``source.mounting_id`` and ``parameters: {name: {value, std}}`` are read
(JSON ``null`` — an undetermined σ — is accepted).

Timeline ``session``: a sequence, the session's number — as in ``report.md``
and the files (``session001`` is 1; by default 1, 2, … in input order), the
same numbering in every group, so a number names one file; the report panel
lists them.  Entities, with ``<g>`` = ``<sensor_id>/<mounting_id>``
(``unspecified`` where empty; escaped as entity-path parts) and ``<p>`` a
contract parameter name (``gain_x``, ``tilt_deg``, ``drift.rate_mps3`` …):

* ``/batch/<g>/<p>/value`` — the estimate, one point per session;
* ``/batch/<g>/<p>/band`` — two series, value − σ and value + σ, drawn as
  steps centred on each session (an error bar per session, joined), only
  for sessions with a finite σ;
* ``/batch/<g>/<p>/mean`` — the group mean, as a flat line across its sessions;
* ``/batch/<g>/report`` — markdown: per parameter mean, std (ddof = 1),
  predicted std (RMS of the per-session σ) and their ratio, as in
  ``report.json``; the spin's parameters (θ₀, ω₀ … ω₃: each hand spin has
  its own) get mean and std only, marked "per session" — their scatter is
  the hands', not the estimator's, so a ratio would mean nothing;
* ``/report`` — markdown: the session index → file table and the groups.

If the scatter of the points matches the bands (ratio ≈ 1), σ is honest;
ratio ≫ 1 means something varies between sessions that σ does not cover
(remounting, temperature, a systematic error).

Blueprint: per group a tab with one plot per repeatable parameter, a row per
family — gains, offsets, the bench (tilt, mounting angles, radius) — (legend:
"estimate", "±σ", "mean") next to the group report, and a tab with the
spin's parameters (titled "per session"); a first tab with the overall
report.  It opens on the first group's tab, paused on ``session``, every plot
over all sessions (two sessions of room at the left, where the legend sits)
on one shared x-axis, the side panels collapsed (see
:mod:`wheelcal.viz.session_blueprint` for the shared axis).
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

from wheelcal.calibration.document import Calibration
from wheelcal.viz.blueprint_chunks import blueprint_chunks, send_blueprint_chunks
from wheelcal.viz.rrd_file import rrd_file
from wheelcal.viz.session_blueprint import GLOBAL_VIEW_PATH

APPLICATION_ID = "wheelcal_batch"
SESSION_TIMELINE = "session"
UNSPECIFIED = "unspecified"
#: Parameters of the hand spin (θ₀, ω₀ … ω₃): each session has its own by nature.
PER_SESSION_PREFIXES = ("theta", "omega")

_VALUE_COLOR = (38, 110, 210)
_BAND_COLOR = (38, 110, 210, 110)
_MEAN_COLOR = (120, 120, 120)
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
    return list(groups.values()), files


def group_statistics(entries: list[tuple[int, float, float]]) -> dict[str, float]:
    """Mean, std (ddof = 1), predicted std (RMS of σ) and ratio, as ``report.json``."""
    values = np.array([v for _, v, _ in entries if math.isfinite(v)])
    stds = np.array([s for _, v, s in entries if math.isfinite(v)])
    mean = float(values.mean()) if values.size else math.nan
    std = float(values.std(ddof=1)) if values.size > 1 else math.nan
    predicted = float(np.sqrt(np.mean(stds**2))) if stds.size else math.nan
    ratio = std / predicted if predicted > 0 else math.nan
    return {"mean": mean, "std": std, "predicted_std": predicted, "ratio": ratio}


def _fmt(x: float, digits: int) -> str:
    return f"{x:.{digits}g}" if math.isfinite(x) else "—"


def _log_parameter(
    stream: rr.RecordingStream, path: str, entries: list[tuple[int, float, float]]
) -> None:
    index = np.array([i for i, _, _ in entries], dtype=np.int64)
    value = np.array([v for _, v, _ in entries])
    std = np.array([s for _, _, s in entries])
    shown = np.isfinite(value)
    if not shown.any():
        return
    style = rr.SeriesPoints(
        colors=[_VALUE_COLOR], names=["estimate"], markers=["circle"], marker_sizes=[4.0]
    )
    stream.log(f"{path}/value", style, static=True)
    stream.send_columns(
        f"{path}/value",
        indexes=[rr.TimeColumn(SESSION_TIMELINE, sequence=index[shown])],
        columns=rr.Scalars.columns(scalars=value[shown]),
    )
    banded = shown & np.isfinite(std)
    if banded.any():
        band = np.column_stack([value[banded] - std[banded], value[banded] + std[banded]])
        # One legend entry for both lines (the legend groups series by name).
        style = rr.SeriesLines(
            colors=[_BAND_COLOR] * 2,
            names=["±σ"] * 2,
            widths=[1.0, 1.0],
            interpolation_mode="StepMid",
        )
        stream.log(f"{path}/band", style, static=True)
        stream.send_columns(
            f"{path}/band",
            indexes=[rr.TimeColumn(SESSION_TIMELINE, sequence=index[banded])],
            columns=rr.Scalars.columns(scalars=band),
        )
    mean = float(value[shown].mean())
    style = rr.SeriesLines(colors=[_MEAN_COLOR], names=["mean"], widths=[1.0])
    stream.log(f"{path}/mean", style, static=True)
    stream.send_columns(
        f"{path}/mean",
        indexes=[rr.TimeColumn(SESSION_TIMELINE, sequence=index[shown])],
        columns=rr.Scalars.columns(scalars=np.full(int(shown.sum()), mean)),
    )


def _numbers_text(numbers: Sequence[int]) -> str:
    """``1–10`` for a run, else the list."""
    if numbers and list(numbers) == list(range(numbers[0], numbers[0] + len(numbers))):
        return f"{numbers[0]}–{numbers[-1]}" if len(numbers) > 1 else str(numbers[0])
    return ", ".join(map(str, numbers))


def _group_report(group: _Group) -> str:
    lines = [
        f"# {group.title}",
        "",
        f"{len(group.sessions)} sessions: {_numbers_text(group.sessions)}",
        "",
        "| parameter | mean | std | pred. std | ratio |",
        "|---|---:|---:|---:|---:|",
    ]
    spin = []
    for name, entries in group.parameters.items():
        s = group_statistics(entries)
        if per_session(name):
            spin.append(f"| `{name}` | {_fmt(s['mean'], 7)} | {_fmt(s['std'], 2)} |")
            continue
        lines.append(
            f"| `{name}` | {_fmt(s['mean'], 7)} | {_fmt(s['std'], 2)} "
            f"| {_fmt(s['predicted_std'], 2)} | {_fmt(s['ratio'], 3)} |"
        )
    lines += [
        "",
        "std: ddof = 1 over the sessions; pred. std: RMS of their σ; ratio = std / pred. std "
        "(≈ 1 when σ is honest; ≫ 1: something varies between sessions that σ misses).",
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


def _overall_report(groups: list[_Group], files: list[tuple[int, str]]) -> str:
    lines = [
        f"# wheelcal batch — {len(files)} sessions, {len(groups)} "
        + ("group" if len(groups) == 1 else "groups"),
        "",
        "| # | file | sensor | mounting |",
        "|---:|---|---|---|",
    ]
    owner = {i: g for g in groups for i in g.sessions}
    for number, file in files:
        sensor, mounting = owner[number].sensor_id, owner[number].mounting_id
        lines.append(
            f"| {number} | `{file}` | {sensor or UNSPECIFIED} | {mounting or UNSPECIFIED} |"
        )
    return "\n".join(lines) + "\n"


class _GlobalSessionAxis:
    """All sessions on the shared x-axis, room for the legend at the left (a blueprint part)."""

    def __init__(self, first: int, last: int) -> None:
        self.range = rrb.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(seq=first - 2),
            end=rrb.TimeRangeBoundary.absolute(seq=last + 1),
        )

    def _log_to_stream(self, stream) -> None:
        stream.log(GLOBAL_VIEW_PATH, rrb.TimeAxis(view_range=self.range))


def _family(name: str) -> int:
    """The row a parameter's plot goes in: gains, offsets, the bench (tilt, mounting, radius)."""
    return min(_parameter_rank(name), 2)


def _parameter_rows(group: _Group, names: list[str]) -> rrb.Vertical:
    """One plot per parameter (estimate, ±σ, mean), a row per family (gains, offsets, …)."""
    rows: dict[int, list[rrb.TimeSeriesView]] = {}
    for i, name in enumerate(names):
        # The spin's five in rows of three; the others a row per family.
        row = 100 + i // 3 if per_session(name) else _family(name)
        rows.setdefault(row, []).append(
            rrb.TimeSeriesView(
                origin=f"/{group.path}/{rr.escape_entity_path_part(name)}",
                name=f"{name} (per session)" if per_session(name) else name,
                axis_x=_LINKED,
                plot_legend=rrb.PlotLegend(corner="LeftTop", visible=True),
            )
        )
    return rrb.Vertical(*[rrb.Horizontal(*plots) for plots in rows.values()])


def batch_blueprint(groups: list[_Group]) -> rrb.Blueprint:
    """Per group a tab of its repeatable parameters and one of its spins; the overview first."""
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
                    _parameter_rows(group, names), report, column_shares=[2, 1], name=title
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
    durable:
        fsync the file (see :func:`~wheelcal.viz.rrd_file.rrd_file`).
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
    with rrd_file(path, APPLICATION_ID, name or Path(path).stem, durable=durable) as stream:
        # The shared x-range lives on the blueprint's global view (not a public part).
        axis = _GlobalSessionAxis(min(numbers), max(numbers))
        send_blueprint_chunks(stream, blueprint_chunks(batch_blueprint(groups), axis))
        stream.log(
            "report",
            rr.TextDocument(_overall_report(groups, files), media_type=rr.MediaType.MARKDOWN),
            static=True,
        )
        for group in groups:
            for name, entries in group.parameters.items():
                _log_parameter(stream, f"{group.path}/{rr.escape_entity_path_part(name)}", entries)
            stream.log(
                f"{group.path}/report",
                rr.TextDocument(_group_report(group), media_type=rr.MediaType.MARKDOWN),
                static=True,
            )
    return Path(path)
