"""Rerun view of a batch: each parameter per session with its ±σ band, by sensor and mounting.

Input: the per-session calibration dictionaries of
:func:`wheelcal.io.calibration_json.calibration_dict` (as loaded from
``<stem>.calibration.json``); only ``source.file``, ``source.sensor_id``,
``source.mounting_id`` and ``parameters: {name: {value, std}}`` are read
(JSON ``null`` — an undetermined σ — is accepted).

Timeline ``session``: a sequence, the session's position in the input list
(the same numbering in every group, so the index names one file; the report
panel lists them).  Entities, with ``<g>`` = ``<sensor_id>/<mounting_id>``
(``unspecified`` where empty; escaped as entity-path parts) and ``<p>`` a
contract parameter name (``gain_x``, ``tilt_deg``, ``drift.rate_mps3`` …):

* ``/batch/<g>/<p>/value`` — the estimate, one point per session;
* ``/batch/<g>/<p>/band`` — two series, value − σ and value + σ, drawn as
  steps centred on each session (an error bar per session, joined), only
  for sessions with a finite σ;
* ``/batch/<g>/<p>/mean`` — the group mean, as a flat line across its sessions;
* ``/batch/<g>/report`` — markdown: per parameter mean, std (ddof = 1),
  predicted std (RMS of the per-session σ) and their ratio, as in
  ``report.json``;
* ``/report`` — markdown: the session index → file table and the groups.

If the scatter of the points matches the bands (ratio ≈ 1), σ is honest;
ratio ≫ 1 means something varies between sessions that σ does not cover
(remounting, temperature, a systematic error).

Blueprint: one tab per group — a grid of one plot per parameter next to the
group report — and a first tab with the overall report; the time panel opens
on ``session``.
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

from wheelcal.io.calibration import Calibration
from wheelcal.viz.rrd_file import rrd_file

APPLICATION_ID = "wheelcal_batch"
SESSION_TIMELINE = "session"
UNSPECIFIED = "unspecified"

_VALUE_COLOR = (38, 110, 210)
_BAND_COLOR = (38, 110, 210, 110)
_MEAN_COLOR = (120, 120, 120)


@dataclass
class _Group:
    """Sessions of one sensor and mounting."""

    sensor_id: str
    mounting_id: str
    sessions: list[int] = field(default_factory=list)
    # name -> list of (session index, value, std); value/std NaN when absent or null
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


def _number(x) -> float:
    """A JSON number, or NaN for null."""
    return math.nan if x is None else float(x)


def _parameter_rank(name: str) -> int:
    """Sensor parameters first, then bench, then motion and effects (as the session report)."""
    for rank, prefix in enumerate(("gain_", "offset_", "tilt_", "euler_", "radius_")):
        if name.startswith(prefix):
            return rank
    return 9


def _groups(sessions: Sequence[Mapping]) -> tuple[list[_Group], list[str]]:
    """Group the sessions by (sensor_id, mounting_id), in order of first appearance."""
    groups: dict[tuple[str, str], _Group] = {}
    files: list[str] = []
    for index, session in enumerate(sessions):
        try:
            cal = session if isinstance(session, Calibration) else Calibration(session)
            key = (cal.sensor_id, cal.mounting_id)
            files.append(cal.source_file or f"session {index}")
            group = groups.setdefault(key, _Group(*key))
            group.sessions.append(index)
            for name, (value, std) in cal.parameters.items():
                group.parameters.setdefault(name, []).append((index, value, std))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ValueError(
                f"batch .rrd: session {index} is not a calibration "
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
    stream: rr.RecordingStream, path: str, name: str, entries: list[tuple[int, float, float]]
) -> None:
    index = np.array([i for i, _, _ in entries], dtype=np.int64)
    value = np.array([v for _, v, _ in entries])
    std = np.array([s for _, _, s in entries])
    shown = np.isfinite(value)
    if not shown.any():
        return
    style = rr.SeriesPoints(
        colors=[_VALUE_COLOR], names=[name], markers=["circle"], marker_sizes=[4.0]
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
        style = rr.SeriesLines(
            colors=[_BAND_COLOR] * 2,
            names=[f"{name} − σ", f"{name} + σ"],
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
    style = rr.SeriesLines(colors=[_MEAN_COLOR], names=[f"{name} mean"], widths=[1.0])
    stream.log(f"{path}/mean", style, static=True)
    stream.send_columns(
        f"{path}/mean",
        indexes=[rr.TimeColumn(SESSION_TIMELINE, sequence=index[shown])],
        columns=rr.Scalars.columns(scalars=np.full(int(shown.sum()), mean)),
    )


def _group_report(group: _Group) -> str:
    lines = [
        f"# {group.title}",
        "",
        f"{len(group.sessions)} sessions: " + ", ".join(str(i) for i in group.sessions),
        "",
        "| parameter | mean | std | predicted std | ratio |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, entries in group.parameters.items():
        s = group_statistics(entries)
        lines.append(
            f"| `{name}` | {_fmt(s['mean'], 7)} | {_fmt(s['std'], 2)} "
            f"| {_fmt(s['predicted_std'], 2)} | {_fmt(s['ratio'], 3)} |"
        )
    lines += ["", "std: ddof = 1 over the sessions; predicted std: RMS of their σ."]
    return "\n".join(lines) + "\n"


def _overall_report(groups: list[_Group], files: list[str]) -> str:
    lines = [
        f"# wheelcal batch — {len(files)} sessions, {len(groups)} groups",
        "",
        "| session | file | sensor | mounting |",
        "|---:|---|---|---|",
    ]
    owner = {i: g for g in groups for i in g.sessions}
    for index, file in enumerate(files):
        sensor, mounting = owner[index].sensor_id, owner[index].mounting_id
        lines.append(
            f"| {index} | `{file}` | {sensor or UNSPECIFIED} | {mounting or UNSPECIFIED} |"
        )
    return "\n".join(lines) + "\n"


def batch_blueprint(groups: list[_Group]) -> rrb.Blueprint:
    """One tab per group (a plot per parameter and the group report), overview first."""
    tabs = [rrb.TextDocumentView(origin="/report", name="sessions")]
    for group in groups:
        plots = [
            rrb.TimeSeriesView(
                origin=f"/{group.path}/{rr.escape_entity_path_part(name)}",
                name=name,
                plot_legend=rrb.PlotLegend(visible=False),
            )
            for name in group.parameters
        ]
        tabs.append(
            rrb.Horizontal(
                rrb.Grid(*plots, grid_columns=3),
                rrb.TextDocumentView(origin=f"/{group.path}/report", name="repeatability"),
                column_shares=[3, 1],
                name=group.title,
            )
        )
    return rrb.Blueprint(
        rrb.Tabs(*tabs, active_tab=1 if groups else 0),
        rrb.TimePanel(timeline=SESSION_TIMELINE),
    )


def write_batch_rrd(path: str | os.PathLike, sessions: Sequence[Mapping]) -> Path:
    """Write the batch ``.rrd`` (see the module docstring) atomically.

    Parameters
    ----------
    path:
        Destination ``.rrd``; its directory must exist.
    sessions:
        Calibration dictionaries (``calibration_dict`` / loaded JSON), in
        the order that numbers them on the ``session`` timeline.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        If ``sessions`` is empty or an entry lacks ``parameters``.
    """
    if not sessions:
        raise ValueError(f"{path}: no sessions to show")
    groups, files = _groups(sessions)
    with rrd_file(path, APPLICATION_ID, Path(path).stem) as stream:
        stream.send_blueprint(batch_blueprint(groups))
        stream.log(
            "report",
            rr.TextDocument(_overall_report(groups, files), media_type=rr.MediaType.MARKDOWN),
            static=True,
        )
        for group in groups:
            for name, entries in group.parameters.items():
                _log_parameter(
                    stream, f"{group.path}/{rr.escape_entity_path_part(name)}", name, entries
                )
            stream.log(
                f"{group.path}/report",
                rr.TextDocument(_group_report(group), media_type=rr.MediaType.MARKDOWN),
                static=True,
            )
    return Path(path)
