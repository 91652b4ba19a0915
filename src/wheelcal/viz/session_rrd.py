"""Rerun view of one calibrated session: ``<out>/<stem>.rrd``.

What is in the file (entity paths; ``<set>`` names a residual set — ``fit``
for this calibration, more can be added, see below; ``<a>`` is an axis):

* ``/signal/raw`` — v(t) over the whole recording, m/s², three series x, y, z
  (one row of three scalars per sample, timeline ``time``);
* ``/signal/model`` — o + Γ R a(t) (eq. 6) over the fitted window, same layout;
* ``/window`` — state lane *before* / *free spin* / *after* on ``time``: the
  free-spin window (also pre-selected in the time panel, so it is shaded in
  every time plot);
* ``/residual/<set>`` — data − model, m/s², x, y, z per row, on **both**
  timelines ``time`` and ``wheel_angle_mdeg`` (the same rows);
* ``/residual_angle_mean/<a>/<set>`` — static bar chart: the residual averaged
  in 72 bins of 5° of ϑ mod 360°, abscissa in degrees;
* ``/spin/omega_radps`` — ω(t) of eq. (2) over the window, rad/s (the cubic,
  plus the spline of a gyro-aided fit; at most :data:`OMEGA_POINTS` samples);
* ``/spin/omega_gyro_radps`` — with a gyroscope, ω as it measures it,
  (ω_meas − b)·w/|w|² (its scale and bias from the calibration's gyro block);
* ``/report`` — static markdown: source, window, fit summary, every parameter
  with value, statistical σ and systematic σ, the warnings.

Timelines:

* ``time`` — a duration timeline, seconds since the recording's epoch
  (``Recording.epoch_unix_ns``): the clock of ``source.window_s`` in the
  calibration JSON.  Times are rounded to whole nanoseconds here (Rerun's own
  float conversion truncates: 0.005 s would become 4 999 999 ns).
* ``wheel_angle_mdeg`` — a sequence timeline whose "time" is the wheel angle
  ϑ(t) mod 360° in millidegrees (integers 0 … 359 999: Rerun sequence
  timelines are integers, and the unit travels in the name).

Why the angle gets two views.  Effects the model leaves out — an unbalanced
wheel (ω ripple once per turn), a sensor off the assumed radius, cross-axis
sensitivity — are periodic in ϑ, not in t: against time they hide in the
noise, folded on ϑ they line up.  Rerun 0.41 plots scalars only against the
timeline selected in the time panel (one for all views; per-view timelines
are an open feature request), so

1. the bar chart ``/residual_angle_mean`` has ϑ (degrees) as its own
   abscissa and shows with any timeline; averaging ≈ 240 samples per bin
   (90 s at 200 Hz) lowers the noise ≈ 15×, so a ϑ-periodic pattern of a
   few mm/s² stands out;
2. every residual sample also sits on the ``wheel_angle_mdeg`` timeline: the
   view "residual vs ϑ" draws them as a scatter (colour = axis, marker = set)
   once that timeline is selected (time plots are empty then, and the scatter
   is empty on ``time``).

Blueprint (:func:`session_blueprint`): left, three columns x / y / z — raw and
model; the window lane across them; residual against time; mean residual per
5° of ϑ (bar chart); right — the report, ω(t), the residual scatter against ϑ.
The per-axis views show one series of the three-column entities through a
view default (``SeriesLines.visible_series``; one blueprint entity per view,
where a per-entity override took two).  Time plots share their x-axis zoom.
The layout is converted to blueprint chunks once per process and residual-set
list (:mod:`wheelcal.viz.blueprint_chunks`); each file adds only its time
panel, with the free-spin window pre-selected.

More residual sets (the closed loop's "before/after"): inside
:func:`session_rrd`, call :meth:`SessionRrd.log_residuals`; the set lands in
the same per-axis views (the blueprint is written last and knows every set)::

    with session_rrd(path, result, recording, window) as rrd:
        rrd.log_residuals("after", after.time_s, after.residual_mps2,
                          wheel_angle_rad(after))

Speed: no data are decimated (except ω, which is a polynomial).  Rerun's
cost grows with the number of *rows* (each carries a 16-byte row id and its
time), so the three axes share a row (≈ 4× faster than one entity per axis):
≈ 56 000 rows for a 90 s / 200 Hz session, ≈ 2.4 MB.  The rest is per
message: each chunk costs ≈ 40–100 µs in Rerun (Arrow IPC schema,
compression, hand-over between its threads), and the blueprint is ≈ 50 of
them.  So the layout is built once per process (see above); the static rows
(styles, the window lane's states, the bar charts' abscissa) are converted
once per process and every entity group goes to Rerun as ready chunks in one
``send_chunks`` call (:mod:`wheelcal.viz.arrow_chunks`: the sample columns
are built from numpy directly, not through Rerun's generic converters).  Long
series are cut into chunks of :data:`CHUNK_ROWS` rows, the size the viewer's
store keeps anyway: one chunk of 18 001 rows made Rerun's file sink fetch
fresh memory pages for every file (see :data:`CHUNK_ROWS`).  The file is written
by Rerun's file sink on its own thread.  ``benchmarks/bench_rrd.py --ref
<rev>`` measures a file against an earlier revision in the same process.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb
from rerun.chunk import Chunk

from wheelcal.estimate.residual_profile import binned_mean_by_angle
from wheelcal.estimate.result import CalibrationResult
from wheelcal.estimate.window import FreeSpinWindow
from wheelcal.model import predict
from wheelcal.model.forward import wheel_kinematics
from wheelcal.model.parameters import AXES
from wheelcal.recording import Recording
from wheelcal.viz.arrow_chunks import (
    ArrowColumn,
    column,
    duration_index,
    row_columns,
    scalars_column,
    sequence_index,
    static_chunk,
    tensor_f64,
)
from wheelcal.viz.blueprint_chunks import (
    blueprint_chunk,
    blueprint_chunks,
    blueprint_rows,
    send_blueprint_chunks,
)
from wheelcal.viz.rrd_file import rrd_file

APPLICATION_ID = "wheelcal"
TIME_TIMELINE = "time"
ANGLE_TIMELINE = "wheel_angle_mdeg"
#: Bins of ϑ for the mean-residual bar chart (5° each).
ANGLE_BINS = 72
#: The residual set of the calibration itself.
FIT_SET = "fit"
#: At most this many samples of ω(t) (a polynomial: nothing is lost).
OMEGA_POINTS = 1000
#: At most this many rows per temporal chunk: the size the viewer's store keeps its own
#: chunks to (Rerun's ``ChunkStoreConfig``, 4096 rows).  Rerun's file sink encodes a
#: chunk into one buffer; at 18 001 rows (≈ 1 MB) its allocator fetches fresh pages
#: for every one: ≈ 1 200 minor page faults per session file against ≈ 740 in
#: 4096-row chunks (each in its own process; ≈ 1 650 against ≈ 520, and 9 % less CPU
#: time, alternating both in one process).
CHUNK_ROWS = 4096

Rgb = tuple[int, int, int]

_AXIS_COLORS: tuple[Rgb, Rgb, Rgb] = ((220, 50, 47), (40, 160, 60), (38, 110, 210))
_RAW_COLORS: tuple[Rgb, Rgb, Rgb] = ((160, 160, 160),) * 3
_SET_PALETTE: tuple[Rgb, ...] = (
    (38, 110, 210),
    (230, 120, 20),
    (130, 60, 180),
    (20, 160, 160),
    (200, 40, 120),
    (120, 120, 40),
)
_WINDOW_STATES = ("before", "free spin", "after")
_MARKERS = ("circle", "cross", "diamond", "plus", "square", "asterisk")


def _time_ns(time_s: np.ndarray) -> np.ndarray:
    """Seconds to whole nanoseconds, rounded (Rerun's own float conversion truncates)."""
    return np.rint(np.asarray(time_s, dtype=float) * 1e9).astype(np.int64)


@functools.lru_cache(maxsize=64)
def _series_style(
    names: tuple[str, ...], colors: tuple[Rgb, ...] | None, width: float | None
) -> tuple[ArrowColumn, ...]:
    """Static ``rr.SeriesLines`` styling as one-row columns, built once per process."""
    return row_columns(
        rr.SeriesLines(
            names=list(names),
            colors=None if colors is None else list(colors),
            widths=None if width is None else [width] * len(names),
        )
    )


def _series_chunks(
    path: str,
    style: tuple[ArrowColumn, ...],
    time_s: np.ndarray,
    values: np.ndarray,
    sequences: dict[str, np.ndarray] | None = None,
) -> list[Chunk]:
    """The static style and the temporal ``Scalars`` rows of one series entity.

    The rows go in consecutive chunks of at most :data:`CHUNK_ROWS`, each on
    the ``time`` timeline and on the sequence timelines of ``sequences``
    (name → one integer per row).
    """
    time_ns = _time_ns(time_s)
    chunks = [static_chunk(path, style)]
    for start in range(0, len(values), CHUNK_ROWS):
        rows = slice(start, start + CHUNK_ROWS)
        indexes = [duration_index(TIME_TIMELINE, time_ns[rows])]
        indexes += [sequence_index(name, seq[rows]) for name, seq in (sequences or {}).items()]
        columns = [scalars_column(values[rows])]
        chunks.append(Chunk.from_columns(path, indexes=indexes, columns=columns))
    return chunks


def angle_mdeg(theta_rad: np.ndarray) -> np.ndarray:
    """ϑ mod 360° in whole millidegrees (0 … 359 999), the ``wheel_angle_mdeg`` values."""
    mdeg = np.rint(np.rad2deg(np.mod(np.asarray(theta_rad, dtype=float), 2 * np.pi)) * 1e3)
    return np.mod(mdeg.astype(np.int64), 360_000)


def set_color(name: str) -> Rgb:
    """Colour of a residual set: ``fit`` first in the palette, others by a stable hash."""
    if name == FIT_SET:
        return _SET_PALETTE[0]
    return _SET_PALETTE[1 + zlib.crc32(name.encode()) % (len(_SET_PALETTE) - 1)]


def _check_series(time_s, values, what: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(time_s, dtype=float).reshape(-1)
    v = np.asarray(values, dtype=float)
    if v.shape != (t.size, 3):
        raise ValueError(f"{what}: need N times and (N, 3) values, got {t.shape} and {v.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
        raise ValueError(f"{what}: non-finite times or values")
    return t, v


def wheel_angle_rad(result: CalibrationResult) -> np.ndarray:
    """ϑ(t) of eq. (2) at the fitted samples (not wrapped), rad."""
    return wheel_kinematics(result.params, result.centred_time_s, result.layout.effects).theta_rad


def log_signal(
    stream: rr.RecordingStream,
    name: str,
    time_s: np.ndarray,
    accel_mps2: np.ndarray,
    colors: tuple[Rgb, Rgb, Rgb],
    width: float = 1.0,
) -> None:
    """Log (N, 3) samples in m/s² as ``/signal/<name>``: three line series on ``time``."""
    t, v = _check_series(time_s, accel_mps2, f"signal {name!r}")
    style = _series_style(tuple(f"{name} {a}" for a in AXES), tuple(colors), width)
    stream.send_chunks(_series_chunks(f"signal/{name}", style, t, v))


def log_residuals(
    stream: rr.RecordingStream,
    name: str,
    time_s: np.ndarray,
    residual_mps2: np.ndarray,
    theta_rad: np.ndarray,
    color: Rgb | None = None,
) -> None:
    """Log one set of residuals against time and against the wheel angle ϑ.

    Writes ``/residual/<name>`` (x, y, z per row, on the ``time`` and
    ``wheel_angle_mdeg`` timelines) and the static bar charts
    ``/residual_angle_mean/<axis>/<name>`` (mean per 5° of ϑ).  Prefer
    :meth:`SessionRrd.log_residuals`, which also puts the set in the
    blueprint's per-axis views.

    Parameters
    ----------
    stream:
        The session's stream.
    name:
        Name of the set, one entity-path part (e.g. ``fit``, ``before``, ``after``).
    time_s:
        Sample times (N,), seconds on the recording's clock (``time`` timeline).
    residual_mps2:
        Data − model (N, 3), m/s².
    theta_rad:
        Wheel angle ϑ at each sample (N,), rad, wrapped or not.
    color:
        RGB of this set; default :func:`set_color` of the name.
    """
    if not name or "/" in name or name != name.strip():
        raise ValueError(f"a residual set name must be one entity-path part, got {name!r}")
    t, r = _check_series(time_s, residual_mps2, f"residual set {name!r}")
    theta = np.asarray(theta_rad, dtype=float).reshape(-1)
    if theta.size != t.size or not np.all(np.isfinite(theta)):
        raise ValueError(f"residual set {name!r}: need {t.size} finite angles, got {theta.size}")
    rgb = set_color(name) if color is None else tuple(color)
    style = _series_style(tuple(f"{name} {a}" for a in AXES), (rgb,) * 3, 1.0)
    angles = {ANGLE_TIMELINE: angle_mdeg(theta)}
    chunks = _series_chunks(f"residual/{name}", style, t, r, angles)
    centres_deg, mean, _ = binned_mean_by_angle(theta, r, ANGLE_BINS)
    # The axes share abscissa, widths and colour (one conversion per process).
    shared = _bar_chart_shared(tuple(centres_deg.tolist()), rgb)
    values = rr.BarChart.descriptor_values()
    for k, axis in enumerate(AXES):
        bars = (column(values, tensor_f64(mean[:, k])), *shared)
        chunks.append(static_chunk(f"residual_angle_mean/{axis}/{name}", bars))
    stream.send_chunks(chunks)


@functools.lru_cache(maxsize=16)
def _bar_chart_shared(centres_deg: tuple[float, ...], rgb: Rgb) -> tuple[ArrowColumn, ...]:
    """A mean-residual bar chart's abscissa, bar widths and colour, as one-row columns."""
    chart = rr.BarChart(
        np.zeros(len(centres_deg)),
        abscissa=np.array(centres_deg),
        widths=np.full(len(centres_deg), 360.0 / ANGLE_BINS),
        color=(*rgb, 170),  # translucent: several sets overlap in one view
    )
    values = rr.BarChart.descriptor_values()
    return tuple(c for c in row_columns(chart) if c.component_descriptor() != values)


@functools.lru_cache(maxsize=1)
def _window_configuration() -> tuple[ArrowColumn, ...]:
    """Labels and colours of the window lane's states (one-row columns, built once)."""
    return row_columns(
        rr.StateConfiguration(
            values=list(_WINDOW_STATES),
            labels=[
                "before (rest, push; not fitted)",
                "free spin (fitted)",
                "after (brake, rest; not fitted)",
            ],
            colors=np.array([0x9E9E9EFF, 0x43A047FF, 0x9E9E9EFF], dtype=np.uint32),
        )
    )


def log_window(
    stream: rr.RecordingStream, start_s: float, end_s: float, first_s: float, last_s: float
) -> None:
    """The free-spin window as a state lane ``/window`` on ``time``."""
    times, states = [start_s], [_WINDOW_STATES[1]]
    if first_s < start_s:
        times.insert(0, first_s)
        states.insert(0, _WINDOW_STATES[0])
    if end_s < last_s:
        times.append(end_s)
        states.append(_WINDOW_STATES[2])
    lane = Chunk.from_columns(
        "window",
        indexes=[duration_index(TIME_TIMELINE, _time_ns(np.array(times)))],
        columns=rr.StateChange.columns(state=states),
    )
    stream.send_chunks([static_chunk("window", _window_configuration()), lane])


def _fmt(x: float, digits: int) -> str:
    if not math.isfinite(x):
        return "∞ (not determined)" if x > 0 else str(x)
    return f"{x:.{digits}g}"


def _report_rank(name: str) -> int:
    """Sensor parameters first, then bench, then motion and effects."""
    for rank, prefix in enumerate(("gain_", "offset_", "tilt_", "euler_", "radius_")):
        if name.startswith(prefix):
            return rank
    return 9


def report_markdown(
    result: CalibrationResult, window: FreeSpinWindow | None, start_s: float, end_s: float
) -> str:
    """The text panel: source, window, fit summary, parameters ± σ, warnings, notes.

    Values are printed with 7 significant digits (``f"{value:.7g}"``), σ with 2.
    """
    info = result.info
    topic = f" (topic `{result.topic}`)" if result.topic else ""
    reason = window.reason if window is not None else "window given (not searched)"
    status = "converged" if result.converged else "**NOT converged**"
    rms = ", ".join(f"{v:.4g}" for v in result.residual_rms_mps2)
    noise = ", ".join(f"{v:.4g}" for v in result.noise.marginal_std_mps2)
    lines = [
        f"# wheelcal — {Path(result.source).name}",
        "",
        f"- **source**: `{result.source}`{topic}",
        f"- **sensor**: `{info.sensor_id or '—'}` · **mounting**: `{info.mounting_id or '—'}`",
        f"- **window**: {start_s:.3f}–{end_s:.3f} s ({end_s - start_s:.1f} s) — {reason}",
        f"- **fit**: {result.time_s.size} samples, {status} after {result.iterations} iterations",
        f"- **residual RMS** (x, y, z): {rms} m/s² · **noise σ**: {noise} m/s²",
        "",
        "## Parameters",
        "",
        "σ stat: one sigma from this recording's noise.  σ sys: what the data cannot see "
        "(radius, gravity, clock), shared by every session on the same bench.",
        "",
        "| parameter | value | σ stat | σ sys |",
        "|---|---:|---:|---:|",
    ]
    budget = result.systematic
    sys_std = dict(zip(budget.names, budget.total_std, strict=True))
    std = result.std
    for i in sorted(range(len(result.names)), key=lambda i: (_report_rank(result.names[i]), i)):
        name = result.names[i]
        sys = float(sys_std.get(name, 0.0))
        # Parameters the unseen quantities do not move get round-off (~1e-14): print 0.
        sys_text = _fmt(sys, 2) if sys > 1e-6 * float(std[i]) else "0"
        lines.append(
            f"| `{name}` | {_fmt(float(result.values[i]), 7)} | {_fmt(float(std[i]), 2)} "
            f"| {sys_text} |"
        )
    lines += ["", "## Warnings", ""]
    lines += [f"- {w}" for w in result.warnings] or ["- none"]
    if result.notes:
        lines += ["", "## Notes", ""] + [f"- {n}" for n in result.notes]
    return "\n".join(lines) + "\n"


def _only_axis(k: int) -> list[bool]:
    return [j == k for j in range(3)]


def _session_root(residual_sets: tuple[str, ...]) -> rrb.Horizontal:
    """The views of the session layout (module docstring), in their containers.

    Parameters
    ----------
    residual_sets:
        Names of the logged residual sets; each gets its per-axis overrides.
    """
    linked = rrb.TimeAxis(link=rrb.components.LinkAxis.LinkToGlobal)

    # A per-axis view shows one of the three series of every entity in it: a view
    # default (one blueprint entity) rather than a per-entity override (two each).
    def signal_view(k: int) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(
            origin="/signal",
            name=f"{AXES[k]}: raw and model (m/s²)",
            axis_x=linked,
            defaults=[rr.SeriesLines.from_fields(visible_series=_only_axis(k))],
        )

    def residual_view(k: int) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(
            origin="/residual",
            name=f"{AXES[k]}: residual, data − model (m/s²)",
            axis_x=linked,
            defaults=[rr.SeriesLines.from_fields(visible_series=_only_axis(k))],
        )

    def mean_view(k: int) -> rrb.BarChartView:
        return rrb.BarChartView(
            origin=f"/residual_angle_mean/{AXES[k]}",
            name=f"{AXES[k]}: mean residual per 5° of ϑ (deg; m/s²)",
        )

    # One scatter for all axes (axis colours; sets told apart by their marker).
    scatter = rrb.TimeSeriesView(
        origin="/residual",
        name=f"residual vs ϑ: select timeline {ANGLE_TIMELINE}",
        overrides={
            f"/residual/{s}": rr.SeriesPoints(
                colors=list(_AXIS_COLORS),
                markers=[_MARKERS[j % len(_MARKERS)]] * 3,
                marker_sizes=[1.5] * 3,
            ).visualizer()
            for j, s in enumerate(residual_sets)
        },
    )

    left = rrb.Vertical(
        rrb.Horizontal(*[signal_view(k) for k in range(3)]),
        rrb.StateTimelineView(origin="/window", name="free-spin window", time_view=linked),
        rrb.Horizontal(*[residual_view(k) for k in range(3)]),
        rrb.Horizontal(*[mean_view(k) for k in range(3)]),
        row_shares=[3, 0.6, 3, 3],
    )
    right = rrb.Vertical(
        rrb.TextDocumentView(origin="/report", name="calibration"),
        rrb.TimeSeriesView(origin="/spin", name="ω(t) (rad/s)", axis_x=linked),
        scatter,
        rrb.Spatial2DView(origin="/allan", name="rests: Allan deviation (log10 τ, log10 σ)"),
        row_shares=[3, 1, 2, 1.5],
    )
    return rrb.Horizontal(left, right, column_shares=[3, 1])


def session_time_panel(start_s: float, end_s: float) -> rrb.TimePanel:
    """The time panel on ``time`` with the free-spin window [start_s, end_s] pre-selected."""
    selection = rrb.components.AbsoluteTimeRange(min=round(start_s * 1e9), max=round(end_s * 1e9))
    return rrb.TimePanel(timeline=TIME_TIMELINE, time_selection=selection)


def session_blueprint(
    start_s: float, end_s: float, residual_sets: tuple[str, ...] = (FIT_SET,)
) -> rrb.Blueprint:
    """The session layout (module docstring); the free-spin window is pre-selected.

    The files get the same blueprint through :func:`_layout_chunks` (built once
    per process) and :func:`session_time_panel`.

    Parameters
    ----------
    start_s, end_s:
        The window on the ``time`` timeline, s.
    residual_sets:
        Names of the logged residual sets; each gets its per-axis overrides.
    """
    return rrb.Blueprint(_session_root(residual_sets), session_time_panel(start_s, end_s))


@functools.lru_cache(maxsize=16)
def _layout_chunks(residual_sets: tuple[str, ...]) -> tuple:
    """The blueprint without its time panel as chunks, built once per process and set list."""
    return blueprint_chunks(rrb.Blueprint(_session_root(residual_sets)))


@functools.lru_cache(maxsize=1)
def _time_panel_rows() -> tuple[str, bool, tuple[ArrowColumn, ...], ArrowColumn]:
    """The time panel's entity, its columns and the one of them that varies (the selection)."""
    ((path, static, columns),) = blueprint_rows(session_time_panel(0.0, 0.0))
    (selection,) = [c for c in columns if c.component_descriptor().component.endswith("selection")]
    return path, static, columns, selection


def _time_panel_chunk(start_s: float, end_s: float) -> Chunk:
    """:func:`session_time_panel` as a chunk; only the selection is converted per file."""
    path, static, columns, selection = _time_panel_rows()
    # ``rrb.components.AbsoluteTimeRange``: whole ns, as the panel rounds them.
    ns = {"min": round(start_s * 1e9), "max": round(end_s * 1e9)}
    value = pa.array([ns], type=selection.as_arrow_array().type.value_type)
    varying = [column(c.component_descriptor(), value) if c is selection else c for c in columns]
    return blueprint_chunk(path, static, varying)


def send_session_blueprint(
    stream: rr.RecordingStream, start_s: float, end_s: float, residual_sets: tuple[str, ...]
) -> None:
    """Send :func:`session_blueprint` into ``stream``, the layout from the per-process cache."""
    panel = _time_panel_chunk(start_s, end_s)
    send_blueprint_chunks(stream, (*_layout_chunks(tuple(residual_sets)), panel))


@dataclass
class SessionRrd:
    """A session file being written: its stream and the residual sets logged so far."""

    stream: rr.RecordingStream
    residual_sets: list[str] = field(default_factory=list)

    def log_residuals(
        self,
        name: str,
        time_s: np.ndarray,
        residual_mps2: np.ndarray,
        theta_rad: np.ndarray,
        color: Rgb | None = None,
    ) -> None:
        """Add a residual set (see :func:`log_residuals`) to the file and its blueprint."""
        if name in self.residual_sets:
            raise ValueError(f"residual set {name!r} is already in this file")
        log_residuals(self.stream, name, time_s, residual_mps2, theta_rad, color)
        self.residual_sets.append(name)


@contextlib.contextmanager
def session_rrd(
    path: str | os.PathLike,
    result: CalibrationResult,
    recording: Recording,
    window: FreeSpinWindow | None,
    durable: bool = True,
) -> Iterator[SessionRrd]:
    """Log a session into a new file; the caller may add residual sets inside the block.

    The file appears (atomically) when the block ends without an exception,
    with the blueprint written last; an exception leaves no file (see
    :func:`wheelcal.viz.rrd_file.rrd_file`).

    Parameters
    ----------
    path:
        Destination ``.rrd``.
    result:
        The calibration (residuals, parameters, noise, warnings).
    recording:
        The whole recording the window was cut from (raw signal, all samples).
    window:
        The free-spin window that was searched, or ``None`` when the window
        was given (then the fitted samples' span is marked).
    durable:
        fsync the file (see :func:`wheelcal.io.atomic.atomic_output`).

    Yields
    ------
    SessionRrd
        ``.log_residuals(...)`` adds a set; ``.stream`` is the Rerun stream.
    """
    # Plot on the recording's clock, whatever epoch the result counts from.
    shift_s = (result.epoch_unix_ns - recording.epoch_unix_ns) * 1e-9
    fit_time_s = result.time_s + shift_s
    if window is not None:
        start_s, end_s = window.start_s, window.end_s
    else:
        start_s, end_s = float(fit_time_s[0]), float(fit_time_s[-1])
    name = Path(result.source).name or Path(path).stem
    with rrd_file(path, APPLICATION_ID, name, durable=durable) as stream:
        if recording.epoch_unix_ns:
            stream.send_recording_start_time_nanos(recording.epoch_unix_ns)
        log_signal(stream, "raw", recording.time_s, recording.accel_mps2, _RAW_COLORS)
        model = predict(result.params, result.centred_time_s, result.layout)  # Eq. (6)
        log_signal(stream, "model", fit_time_s, model, _AXIS_COLORS, width=1.5)
        log_window(stream, start_s, end_s, float(recording.time_s[0]), float(recording.time_s[-1]))
        every = max(1, math.ceil(fit_time_s.size / OMEGA_POINTS))
        omega_t = result.centred_time_s[::every]
        kin = wheel_kinematics(result.params, omega_t, result.layout.effects)  # Eq. (2) (+ spline)
        chunks = _series_chunks(
            "spin/omega_radps",
            _series_style(("ω (model)",), None, None),
            fit_time_s[::every],
            kin.omega_radps,
        )
        chunks += _gyro_rate_chunks(result, recording, shift_s, every)
        chunks += allan_chunks(result)
        markdown = report_markdown(result, window, start_s, end_s)
        report = rr.TextDocument(markdown, media_type=rr.MediaType.MARKDOWN)
        chunks.append(static_chunk("report", row_columns(report)))
        stream.send_chunks(chunks)
        rrd = SessionRrd(stream)
        rrd.log_residuals(FIT_SET, fit_time_s, result.residual_mps2, wheel_angle_rad(result))
        yield rrd
        send_session_blueprint(stream, start_s, end_s, tuple(rrd.residual_sets))


def allan_chunks(result: CalibrationResult) -> list[Chunk]:
    """``/allan``: the rests' overlapping Allan deviation, log10 σ against log10 τ, per axis.

    A log-log plot drawn as 2-D line strips (x = log10 τ/s, y = log10 σ/(m/s²)),
    the white-noise density marked at τ = 1 s and the bias instability's
    minimum, and the read-outs as text (``/allan/readouts``).  Nothing when the
    recording has no rests.
    """
    from wheelcal.io.allan_json import rests_allan

    noise = None if result.assessment is None else result.assessment.noise
    block = None if noise is None else rests_allan(noise.rests)
    if block is None:
        return []
    tau = np.log10(np.asarray(block["tau_s"]))
    adev = np.log10(np.asarray(block["adev_mps2"]))
    density = np.log10(np.asarray(block["white_noise_density_mps2_rthz"]))
    bias = np.asarray(block["bias_instability_mps2"]) * 0.664  # back to σ_min on the curve
    bias_tau = np.log10(np.asarray(block["bias_instability_tau_s"]))
    chunks = []
    for k, axis in enumerate(AXES):
        strip = rr.LineStrips2D([np.column_stack([tau, adev[:, k]])], colors=[_AXIS_COLORS[k]])
        marks = rr.Points2D(
            [[0.0, density[k]], [bias_tau[k], np.log10(bias[k])]],
            colors=[_AXIS_COLORS[k]] * 2,
            radii=[0.02, 0.02],
            labels=[f"N_{axis}", f"B_{axis}"],
        )
        chunks.append(static_chunk(f"allan/{axis}", row_columns(strip)))
        chunks.append(static_chunk(f"allan/{axis}/readouts", row_columns(marks)))
    lines = [
        f"Allan deviation of {block['rests_s']:.3g} s of rests (x: log10 τ/s, y: log10 σ/(m/s²))",
        "",
        "| axis | N (m/s²/√Hz) | B (m/s²) | K (m/s³/√Hz) |",
        "|---|---:|---:|---:|",
    ]
    for k, axis in enumerate(AXES):
        lines.append(
            f"| {axis} | {block['white_noise_density_mps2_rthz'][k]:.3g} | "
            f"{block['bias_instability_mps2'][k]:.3g}"
            f"{'' if block['bias_instability_is_floor'][k] else ' (bound)'} | "
            f"{block['random_walk_mps3_rthz'][k]:.3g}"
            f"{'' if block['random_walk_seen'][k] else ' (bound)'} |"
        )
    text = rr.TextDocument("\n".join(lines), media_type=rr.MediaType.MARKDOWN)
    chunks.append(static_chunk("allan/readouts", row_columns(text)))
    return chunks


def _gyro_rate_chunks(result, recording, shift_s: float, every: int) -> list[Chunk]:
    """``/spin/omega_gyro_radps``: ω as the gyro measures it, (ω_meas − b)·w/|w|²."""
    gyro = getattr(recording, "gyro_radps", None)
    block = None if result.assessment is None else result.assessment.gyro
    if gyro is None or block is None:
        return []
    w = block.scale * block.axis
    fitted = np.searchsorted(recording.time_s, result.time_s + shift_s)[::every]
    fitted = fitted[fitted < recording.time_s.size]
    rows = gyro[fitted]
    ok = np.all(np.isfinite(rows), axis=1)
    omega = (rows[ok] - block.bias_radps) @ w / (w @ w)
    return _series_chunks(
        "spin/omega_gyro_radps",
        _series_style(("ω (gyro)",), None, None),
        recording.time_s[fitted][ok],
        omega,
    )


def write_session_rrd(
    path: str | os.PathLike,
    result: CalibrationResult,
    recording: Recording,
    window: FreeSpinWindow | None,
    durable: bool = True,
) -> Path:
    """Write the session's ``.rrd`` (see the module docstring) atomically.

    Parameters
    ----------
    path:
        Destination, conventionally ``<out>/<stem>.rrd``.
    result:
        The calibration of the windowed recording.
    recording:
        The whole recording.
    window:
        The searched free-spin window, or ``None`` if it was given.
    durable:
        fsync the file (see :func:`wheelcal.io.atomic.atomic_output`).

    Returns
    -------
    Path
        ``path``.
    """
    with session_rrd(path, result, recording, window, durable=durable):
        pass
    return Path(path)
