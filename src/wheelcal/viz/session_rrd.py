"""Rerun view of one calibrated session: ``<out>/<stem>.rrd``.

What is in the file (entity paths; ``<set>`` names a residual set — ``fit``
for this calibration, more can be added, see below; ``<a>`` is an axis):

* ``/signal`` — the data v(t) over the whole recording and the model
  o + Γ R a(t) (eq. 6) over the fitted window, m/s²: one row per sample on
  ``time`` with two components, ``Signal:data_mps2`` and ``Signal:model_mps2``,
  each a struct {x, y, z} (the model's null outside the window);
* ``/window`` — state lane *before* / *free spin* / *after* on ``time``: the
  free-spin window (also selected in the time panel);
* ``/residual/<set>`` — data − model, m/s², a struct {x, y, z} per row on
  ``time`` (:data:`~wheelcal.viz.session_blueprint.XYZ_COMPONENT`);
* ``/residual_angle_mean/<a>/<set>`` — static bar chart: the residual's mean
  in 72 bins of 5° of ϑ mod 360°, abscissa in degrees (a real angle axis);
  ``/residual_angle_mean/<a>/band_2sigma`` — ±2σ of each bin's mean
  (:mod:`wheelcal.viz.angle_profile`; each bin twice, up and down), grey:
  noise alone stays inside;
* ``/spin/omega_radps`` — ω(t) of the model, eq. (2), over the window
  (the cubic, plus the spline of a gyro-aided fit; at most
  :data:`OMEGA_POINTS` samples);
* ``/spin/omega_measured_radps`` — ω as measured: by the gyroscope when the
  recording has one, else per turn from the accelerometer
  (:mod:`wheelcal.viz.measured_rate`; the legend says which);
* ``/report`` — static markdown: source, window, fit summary, every parameter
  with value, statistical σ and systematic σ, the warnings;
* with a closed-loop diagnosis that added effects (:meth:`RrdFile.log_diagnosis`):
  ``/closed_loop/angle/<a>/paper_model`` and ``…/with_effects`` (the
  residual's mean per 5° of ϑ before and after),
  ``/closed_loop/trend/paper_model`` and ``…/with_effects`` (its mean per
  2 s, {x, y, z} rows on ``time``) and ``/closed_loop/report`` (the effects
  added with their score tests; parameters before and after).

The recording properties carry the recording's own start time (its first
sample's Unix time) and name.

Timeline ``time``: a duration, seconds since the recording's epoch
(``Recording.epoch_unix_ns``): the clock of ``source.window_s`` in the
calibration JSON.  Times are rounded to whole nanoseconds here (Rerun's own
float conversion truncates: 0.005 s would become 4 999 999 ns).

Why the wheel angle.  Effects the model leaves out — an unbalanced wheel (ω
ripple once per turn), a sensor off the assumed radius, cross-axis
sensitivity — are periodic in ϑ, not in t: against time they hide in the
noise, folded on ϑ they line up.  Averaging ≈ 240 samples per 5° bin (90 s
at 200 Hz) lowers the noise ≈ 15×, so a ϑ-periodic pattern of a few mm/s²
stands out of the grey band.  (Rerun 0.41 plots scalars against one timeline
for all views, so an angle *timeline* would empty every time plot; the bars
carry ϑ as their own abscissa.)

The layout is :mod:`wheelcal.viz.session_blueprint`.

More residual sets: inside :func:`session_rrd`, call
:meth:`RrdFile.log_residuals`; the set lands in the same per-axis views
(the blueprint is written last and knows every set).  Other logging functions
(e.g. the rests' Allan deviation under ``/allan``) register their view with
:meth:`RrdFile.add_view`::

    with session_rrd(path, session) as rrd:
        rrd.log_diagnosis(session.diagnosis)
        rrd.add_view("time_series", "/allan", "Allan deviation of the rests")

Speed: no data are decimated (except ω, which is a polynomial).  Rerun's
cost grows with the number of *rows* (each carries a 16-byte row id and its
time), so the three axes share a row (a struct; ≈ 4× faster than one entity
per axis), and so do the data and the model: ≈ 36 000 rows for a 90 s /
200 Hz session, ≈ 2.4 MB.  The rest is
per message: each chunk costs ≈ 40–100 µs in Rerun (Arrow IPC schema,
compression, hand-over between its threads), and the blueprint is ≈ 70 of
them.  So the layout is built once per process; the static rows (the window
lane's states, the bar charts' abscissa) are converted once per process and
every entity group goes to Rerun as ready chunks in one ``send_chunks`` call
(:mod:`wheelcal.viz.arrow_chunks`: the sample columns are built from numpy
directly, not through Rerun's generic converters).  Long series are cut
into chunks of :data:`CHUNK_ROWS` rows, the size the viewer's store keeps
anyway: one chunk of 18 001 rows made Rerun's file sink fetch fresh memory
pages for every file (see :data:`CHUNK_ROWS`).  The file is written by
Rerun's file sink on its own thread.  ``benchmarks/bench_rrd.py --ref <rev>``
measures a file against an earlier revision in the same process.
"""

from __future__ import annotations

import contextlib
import datetime
import functools
import math
import os
import zlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun as rr
from rerun.chunk import Chunk

from wheelcal.estimate.joint import CalibrationResult
from wheelcal.model import AXES, STANDARD_GRAVITY_MPS2, predict, wheel_kinematics
from wheelcal.recording import Recording
from wheelcal.session import FreeSpinWindow, SessionResult
from wheelcal.viz.angle_profile import angle_profile
from wheelcal.viz.arrow_chunks import (
    ArrowColumn,
    column,
    duration_index,
    row_columns,
    scalars_column,
    static_chunk,
    tensor_f64,
)
from wheelcal.viz.blueprint_chunks import send_blueprint_chunks
from wheelcal.viz.measured_rate import MeasuredRate, gyro_rate, per_turn_rate
from wheelcal.viz.rrd_writer import rrd_file
from wheelcal.viz.session_blueprint import (
    AFTER_COLOR,
    AXIS_COLORS,
    BEFORE_COLOR,
    SIGNAL_DATA,
    SIGNAL_MODEL,
    TIME_TIMELINE,
    TREND_S,
    XYZ_COMPONENT,
    ExtraView,
    Layout,
    layout_chunks,
    per_file_chunks,
)

APPLICATION_ID = "wheelcal"
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
#: Entity name of the ±2σ band of the bin means (drawn under the bars).
BAND_ENTITY = "band_2sigma"
#: Space left of the first and right of the last sample in the time views, s.
TIME_MARGIN_S = 0.5

Rgb = tuple[int, int, int]

_SET_PALETTE: tuple[Rgb, ...] = (
    (38, 110, 210),
    (230, 120, 20),
    (130, 60, 180),
    (20, 160, 160),
    (200, 40, 120),
    (120, 120, 40),
)
_BAND_COLOR = (150, 150, 150, 90)
_WINDOW_STATES = ("before", "free spin", "after")


def _time_ns(time_s: np.ndarray) -> np.ndarray:
    """Seconds to whole nanoseconds, rounded (Rerun's own float conversion truncates)."""
    return np.rint(np.asarray(time_s, dtype=float) * 1e9).astype(np.int64)


@functools.lru_cache(maxsize=4)
def _descriptor(component: str) -> rr.ComponentDescriptor:
    """The descriptor Rerun's ``DynamicArchetype`` gives ``Archetype:field``."""
    archetype, name = component.split(":")
    (batch,) = rr.DynamicArchetype.columns(archetype=archetype, components={name: np.zeros(1)})
    return batch.component_descriptor()


def xyz_column(
    values: np.ndarray, component: str = XYZ_COMPONENT, valid: np.ndarray | None = None
) -> ArrowColumn:
    """One struct {x, y, z} (float64) per row of ``values`` (N, 3), e.g. :data:`XYZ_COMPONENT`.

    Rows where ``valid`` (N,) is False are null: no value at that time.
    """
    by_axis = np.ascontiguousarray(np.asarray(values, dtype=np.float64).T)  # one copy
    struct = pa.StructArray.from_arrays([pa.array(f) for f in by_axis], names=list(AXES))
    offsets = pa.array(np.arange(by_axis.shape[1] + 1, dtype=np.int32))
    mask = None if valid is None else pa.array(~np.asarray(valid, dtype=bool))
    return ArrowColumn(_descriptor(component), pa.ListArray.from_arrays(offsets, struct, mask=mask))


def _row_chunks(path: str, time_s: np.ndarray, values: np.ndarray, make_column) -> list[Chunk]:
    """Temporal rows on ``time`` in consecutive chunks of at most :data:`CHUNK_ROWS`."""
    time_ns = _time_ns(time_s)
    chunks = []
    for start in range(0, len(values), CHUNK_ROWS):
        rows = slice(start, start + CHUNK_ROWS)
        index = [duration_index(TIME_TIMELINE, time_ns[rows])]
        chunks.append(Chunk.from_columns(path, indexes=index, columns=[make_column(values[rows])]))
    return chunks


def xyz_chunks(path: str, time_s: np.ndarray, values: np.ndarray) -> list[Chunk]:
    """An entity of three-axis samples (N, 3): {x, y, z} rows on ``time``."""
    return _row_chunks(path, time_s, values, xyz_column)


@functools.lru_cache(maxsize=32)
def _scalar_style(label: str, color: Rgb | None, points: bool) -> tuple[ArrowColumn, ...]:
    """Static style of a one-series ``Scalars`` entity, as one-row columns (once per process)."""
    colors = None if color is None else [color]
    if points:
        return row_columns(rr.SeriesPoints(names=[label], colors=colors, marker_sizes=[1.5]))
    return row_columns(rr.SeriesLines(names=[label], colors=colors, widths=[2.0]))


def scalar_chunks(
    path: str,
    time_s: np.ndarray,
    values: np.ndarray,
    label: str,
    color: Rgb | None = None,
    points: bool = False,
) -> list[Chunk]:
    """A one-series ``Scalars`` entity on ``time`` with its static legend label and style."""
    style = static_chunk(path, _scalar_style(label, color, points))
    return [style, *_row_chunks(path, time_s, np.asarray(values, dtype=float), scalars_column)]


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


def _check_set_name(name: str) -> None:
    if not name or "/" in name or name != name.strip():
        raise ValueError(f"a residual set name must be one entity-path part, got {name!r}")


def wheel_angle_rad(result: CalibrationResult) -> np.ndarray:
    """ϑ(t) of eq. (2) at the fitted samples (not wrapped), rad."""
    return wheel_kinematics(result.params, result.centred_time_s, result.layout.effects).theta_rad


def signal_chunks(
    data_time_s: np.ndarray,
    data_mps2: np.ndarray,
    model_time_s: np.ndarray,
    model_mps2: np.ndarray,
) -> list[Chunk]:
    """``/signal``: the data and the model in one row per time (module docstring).

    The rows are the union of both sets of times (to the nanosecond; the model's
    are the data's inside the window): a component is null where its series has
    no sample.
    """
    t_data, v_data = _check_series(data_time_s, data_mps2, "signal 'data'")
    t_model, v_model = _check_series(model_time_s, model_mps2, "signal 'model'")
    ns_data, ns_model = _time_ns(t_data), _time_ns(t_model)
    at = np.minimum(np.searchsorted(ns_data, ns_model), ns_data.size - 1)
    if np.array_equal(ns_data[at], ns_model):
        ns = ns_data  # the model's times are the data's (a window of the recording)
    else:
        ns = np.concatenate([ns_data, ns_model])
        ns.sort()
        ns = ns[np.concatenate([[True], np.diff(ns) != 0])]
    series = []
    for at, v in ((ns_data, v_data), (ns_model, v_model)):
        rows = np.searchsorted(ns, at)
        values = np.zeros((ns.size, 3))
        values[rows] = v
        valid = np.zeros(ns.size, dtype=bool)
        valid[rows] = True
        series.append((values, valid))
    chunks = []
    for start in range(0, ns.size, CHUNK_ROWS):
        rows = slice(start, start + CHUNK_ROWS)
        index = [duration_index(TIME_TIMELINE, ns[rows])]
        columns = [
            xyz_column(values[rows], component, None if valid[rows].all() else valid[rows])
            for (values, valid), component in zip(series, (SIGNAL_DATA, SIGNAL_MODEL), strict=True)
        ]
        chunks.append(Chunk.from_columns("signal", indexes=index, columns=columns))
    return chunks


@functools.lru_cache(maxsize=16)
def _bar_chart_shared(centres_deg: tuple[float, ...], rgba: tuple[int, ...]) -> tuple:
    """A bar chart's abscissa (°), bar widths and colour, as one-row columns (once per process)."""
    chart = rr.BarChart(
        np.zeros(len(centres_deg)),
        abscissa=np.array(centres_deg),
        widths=np.full(len(centres_deg), 360.0 / ANGLE_BINS),
        color=rgba,
    )
    values = rr.BarChart.descriptor_values()
    return tuple(c for c in row_columns(chart) if c.component_descriptor() != values)


def angle_bar_chunks(
    base: str, name: str, theta_rad: np.ndarray, residual_mps2: np.ndarray, rgb: Rgb, band: bool
) -> list[Chunk]:
    """``<base>/<a>/<name>``: mean residual per 5° of ϑ per axis (and its ±2σ band if asked).

    The bars are translucent (sets overlap in one view); the band, grey, sits
    under them at ``<base>/<a>/band_2sigma``: each bin twice in its abscissa,
    first up to +2σ, then down to −2σ.
    """
    profile = angle_profile(theta_rad, residual_mps2, ANGLE_BINS)
    centres = tuple(profile.centres_deg.tolist())
    values = rr.BarChart.descriptor_values()
    shared = _bar_chart_shared(centres, (*rgb, 170))
    chunks = []
    for k, axis in enumerate(AXES):
        bars = (column(values, tensor_f64(profile.mean_mps2[:, k])), *shared)
        chunks.append(static_chunk(f"{base}/{axis}/{name}", bars))
        if band:
            # One chart, each bin twice: a bar up to +2σ and one down to −2σ.
            two_sigma = np.nan_to_num(2 * profile.std_of_mean_mps2[:, k])
            grey = _bar_chart_shared(centres + centres, _BAND_COLOR)
            bars = (column(values, tensor_f64(np.concatenate([two_sigma, -two_sigma]))), *grey)
            chunks.append(static_chunk(f"{base}/{axis}/{BAND_ENTITY}", bars))
    return chunks


def log_residuals(
    stream: rr.RecordingStream,
    name: str,
    time_s: np.ndarray,
    residual_mps2: np.ndarray,
    theta_rad: np.ndarray,
    color: Rgb | None = None,
    band: bool = False,
) -> None:
    """Log one set of residuals against time and against the wheel angle ϑ.

    Writes ``/residual/<name>`` ({x, y, z} rows on ``time``) and the static
    bar charts ``/residual_angle_mean/<axis>/<name>`` (mean per 5° of ϑ).
    Prefer :meth:`RrdFile.log_residuals`, which also puts the set in the
    blueprint's per-axis views.

    Parameters
    ----------
    stream:
        The session's stream.
    name:
        Name of the set, one entity-path part (e.g. ``fit``, ``after``).
    time_s:
        Sample times (N,), seconds on the recording's clock (``time`` timeline).
    residual_mps2:
        Data − model (N, 3), m/s².
    theta_rad:
        Wheel angle ϑ at each sample (N,), rad, not wrapped (its turns give
        the bins' σ, :mod:`wheelcal.viz.angle_profile`).
    color:
        RGB of this set; default :func:`set_color` of the name.
    band:
        Also log the ±2σ band of the bin means (the calibration's own set).
    """
    _check_set_name(name)
    t, r = _check_series(time_s, residual_mps2, f"residual set {name!r}")
    theta = np.asarray(theta_rad, dtype=float).reshape(-1)
    if theta.size != t.size or not np.all(np.isfinite(theta)):
        raise ValueError(f"residual set {name!r}: need {t.size} finite angles, got {theta.size}")
    rgb = set_color(name) if color is None else tuple(color)
    chunks = xyz_chunks(f"residual/{name}", t, r)
    chunks += angle_bar_chunks("residual_angle_mean", name, theta, r, rgb, band)
    stream.send_chunks(chunks)


@functools.lru_cache(maxsize=1)
def _window_configuration() -> tuple[ArrowColumn, ...]:
    """Labels and colours of the window lane's states (one-row columns, built once)."""
    return row_columns(
        rr.StateConfiguration(
            values=list(_WINDOW_STATES),
            labels=[
                "before",
                "free spin (fitted)",
                "after",
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


def model_omega(result: CalibrationResult, shift_s: float) -> tuple[np.ndarray, np.ndarray]:
    """ω(t) of the model, eq. (2) (+ spline): ≤ :data:`OMEGA_POINTS` times, recording's clock."""
    every = max(1, math.ceil(result.time_s.size / OMEGA_POINTS))
    kin = wheel_kinematics(result.params, result.centred_time_s[::every], result.layout.effects)
    return result.time_s[::every] + shift_s, kin.omega_radps


def measured_omega(
    result: CalibrationResult,
    recording: Recording,
    shift_s: float,
    model_omega_radps: np.ndarray,
    gyro_calibration=None,
) -> MeasuredRate | None:
    """ω measured over the fitted window: gyro if recorded, else per turn (accelerometer).

    ``gyro_calibration`` (a ``GyroCalibration``, the session's ``gyro``); without
    it a recorded gyro is projected on its principal axis
    (:func:`wheelcal.viz.measured_rate.gyro_rate`).
    """
    first, last = np.searchsorted(
        recording.time_s, [result.time_s[0] + shift_s, result.time_s[-1] + shift_s]
    )
    inside = slice(int(first), int(min(last + 1, recording.time_s.size)))
    sign = float(np.sign(np.median(model_omega_radps)))
    gyro = getattr(recording, "gyro_radps", None)
    if gyro is not None:
        rows = gyro[inside]
        every = max(1, math.ceil(rows.shape[0] / OMEGA_POINTS))
        measured = gyro_rate(
            recording.time_s[inside][::every], rows[::every], gyro_calibration, sign
        )
        if measured is not None:
            return measured
    return per_turn_rate(recording.time_s[inside], recording.accel_mps2[inside], model_omega_radps)


def spin_chunks(
    result: CalibrationResult, recording: Recording, shift_s: float, gyro_calibration=None
) -> list[Chunk]:
    """``/spin/omega_radps`` (the model) and ``/spin/omega_measured_radps`` (module docstring)."""
    t, omega = model_omega(result, shift_s)
    chunks = scalar_chunks("spin/omega_radps", t, omega, "model", AXIS_COLORS[2])
    measured = measured_omega(result, recording, shift_s, omega, gyro_calibration)
    if measured is not None:
        chunks += scalar_chunks(
            "spin/omega_measured_radps",
            measured.time_s,
            measured.omega_radps,
            f"measured: {measured.source}",
            (60, 60, 60),
            points=measured.source.startswith("per turn"),
        )
    return chunks


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


def _report_order(names) -> list[int]:
    return sorted(range(len(names)), key=lambda i: (_report_rank(names[i]), i))


def recorded_at(epoch_unix_ns: int) -> str:
    """A Unix time in ns as UTC, ``2024-03-12 09:00:00.000 UTC`` ("—" for 0: no Unix epoch)."""
    if not epoch_unix_ns:
        return "— (times without a Unix epoch)"
    seconds, ns = divmod(int(epoch_unix_ns), 1_000_000_000)
    stamp = datetime.datetime.fromtimestamp(seconds, datetime.UTC)
    return f"{stamp:%Y-%m-%d %H:%M:%S}.{ns // 1_000_000:03d} UTC"


def report_markdown(
    result: CalibrationResult,
    window: FreeSpinWindow | None,
    start_s: float,
    end_s: float,
    recording_epoch_unix_ns: int | None = None,
) -> str:
    """The parameters panel: every parameter ± σ stat and σ sys, then source and fit.

    Values are printed with 7 significant digits (``f"{value:.7g}"``), σ with 2.
    The warnings, notes, window and effects are the verdict strip's
    (:func:`verdict_markdown`: the calibration JSON's own).
    ``recording_epoch_unix_ns`` (default: the result's epoch) is the recording's
    first sample, printed as its start time.
    """
    if recording_epoch_unix_ns is None:
        recording_epoch_unix_ns = result.epoch_unix_ns
    info = result.info
    topic = f" (topic `{result.topic}`)" if result.topic else ""
    status = "converged" if result.converged else "**NOT converged**"
    rms = ", ".join(f"{v:.4g}" for v in result.residual_rms_mps2)
    noise = ", ".join(f"{v:.4g}" for v in result.noise.marginal_std_mps2)
    lines = [
        "| parameter | value | σ stat | σ sys |",
        "|---|---:|---:|---:|",
    ]
    budget = result.systematic
    sys_std = dict(zip(budget.names, budget.total_std, strict=True))
    std = result.std
    for i in _report_order(result.names):
        name = result.names[i]
        sys = float(sys_std.get(name, 0.0))
        # Parameters the unseen quantities do not move get round-off (~1e-14): print 0.
        sys_text = _fmt(sys, 2) if sys > 1e-6 * float(std[i]) else "0"
        lines.append(
            f"| `{name}` | {_fmt(float(result.values[i]), 7)} | {_fmt(float(std[i]), 2)} "
            f"| {sys_text} |"
        )
    lines += [
        "",
        "σ stat: one sigma from this recording's noise.  σ sys: what the data cannot see "
        "(radius, gravity, clock), shared by every session on the same bench.",
        "",
        f"- **source**: `{result.source}`{topic}",
        f"- **recorded**: {recorded_at(recording_epoch_unix_ns)} (first sample; time 0 s)",
        f"- **sensor**: `{info.sensor_id or '—'}` · **mounting**: `{info.mounting_id or '—'}`",
        f"- **window**: {start_s:.3f}–{end_s:.3f} s ({end_s - start_s:.1f} s)",
        f"- **fit**: {result.time_s.size} samples, {status} after {result.iterations} iterations",
        f"- **residual RMS** (x, y, z): {rms} m/s² · **noise σ**: {noise} m/s²",
    ]
    return "\n".join(lines) + "\n"


def _p_text(p) -> str:
    return "—" if p is None else f"{p:.2g}"


def _effects_line(document: Mapping) -> str:
    """What the closed loop added, with the evidence (or what it tested and found none of)."""
    fit = document.get("fit", {})
    if fit.get("model") == "paper":
        return "**model**: the paper's, as asked (`--model paper`): no effect screened"
    added = []
    for name, entry in document.get("effects", {}).items():
        ev = entry.get("evidence")
        if ev:
            added.append(
                f"**{name}** (χ² = {ev['statistic']:.4g}, {ev['dof']} dof, "
                f"p = {_p_text(ev.get('p_corrected'))})"
            )
        else:
            added.append(f"**{name}**")
    screen = fit.get("effects_screen", {})
    tested = len(screen.get("tested", []))
    alpha = screen.get("alpha")
    level = f" at family-wise α = {alpha:g}" if alpha is not None else ""
    if added:
        return (
            f"**model**: the paper's + {', '.join(added)} — the closed loop added "
            f"{'it' if len(added) == 1 else 'them'} ({tested} candidates tested{level}; "
            "before/after: the **closed loop** tab)"
        )
    smallest = _p_text(screen.get("smallest_p_corrected"))
    return (
        f"**model**: the paper's — the screen found none of {tested} candidate effects{level} "
        f"(smallest corrected p = {smallest})"
    )


def _residual_line(document: Mapping) -> str:
    fit = document.get("fit", {})
    ref = fit.get("noise_reference") or {}
    rms = ", ".join(f"{v:.3g}" for v in fit.get("residual_rms_mps2", []))
    if ref.get("ratio"):
        where = "the rests" if ref.get("source") == "rests" else "the residual's spectrum"
        return (
            f"**residual** {rms} m/s² (x, y, z): {max(ref['ratio']):.2f}× the sensor's noise "
            f"floor (from {where})"
        )
    return f"**residual** {rms} m/s² (x, y, z)"


def _clip_line(recording: Recording) -> str:
    """How many samples the sensor clipped, where, and what became of them."""
    info = recording.info
    fs = f"range ±{info.full_scale_g:g} g" if info.full_scale_g else "range not stated"
    if recording.clipped_time_s is None:
        return f"**clipped**: none ({fs})"
    n = recording.clipped_time_s.size
    total = n + recording.samples
    rails = recording.clip_limits_mps2
    where = ", ".join(
        f"{AXES[k]} = {rails[k, side]:+.4g} m/s²"
        for k in range(3)
        for side in range(2)
        if rails is not None and np.isfinite(rails[k, side])
    )
    return (
        f"**clipped**: {n} of {total} samples ({100 * n / total:.2g} %) at {where or 'a rail'} "
        f"({fs}): left out of the fit, drawn as magenta points on the data plots"
    )


def verdict_markdown(document: Mapping, recording: Recording) -> str:
    """The verdict strip: effects and their evidence, residual, clipping, window, warnings.

    Read from the calibration document itself (``calibration_dict``): its warnings
    are the JSON's ``fit.warnings``, its window words ``source.window_reason``.
    """
    source = document.get("source", {})
    fit = document.get("fit", {})
    undetermined = document.get("sensor", {}).get("undetermined", [])
    status = "calibrated" if not undetermined else "calibrated, partly (see warnings)"
    lines = [
        f"**{Path(str(source.get('file', '?'))).name}: {status}** · {_effects_line(document)}",
        f"- {_residual_line(document)} · {_clip_line(recording)}",
        f"- **window** {source.get('window_s', ['?', '?'])[0]}–"
        f"{source.get('window_s', ['?', '?'])[1]} s: {source.get('window_reason', '')}",
    ]
    warnings = list(fit.get("warnings", []))
    lines.append(f"- **warnings ({len(warnings)})**" + ("" if warnings else ": none"))
    lines += [f"  - {w}" for w in warnings]
    notes = [n for n in source.get("notes", []) if "clipped samples" not in n]
    if notes:
        lines.append("- **notes**: " + "; ".join(notes))
    return "\n".join(lines) + "\n"


#: Characters of markdown a line of the verdict strip holds (1920 px, Rerun's font).
VERDICT_LINE_CHARS = 210


def verdict_lines(text: str) -> int:
    """Lines the verdict strip needs on screen (each markdown line wrapped)."""
    return sum(1 + len(line) // VERDICT_LINE_CHARS for line in text.splitlines())


def closed_loop_markdown(diagnosis) -> str:
    """The closed-loop tab's text: the effects added, their tests, parameters before/after.

    Parameters
    ----------
    diagnosis:
        A :class:`wheelcal.closedloop.loop.Diagnosis`.
    """
    base, final = diagnosis.base, diagnosis.final
    rms = lambda r: ", ".join(f"{v:.4g}" for v in r.residual_rms_mps2)  # noqa: E731
    lines = [
        "# Closed loop: effects the paper's model lacks",
        "",
        f"Before: **the paper's model** (orange). After: **with the effects added** (blue). "
        f"An effect is added when its score test is significant at α = {diagnosis.alpha:g} "
        "(Bonferroni over the candidates of each step).",
        "",
        "| step | effect added | χ² | dof | p (corrected) |",
        "|---:|---|---:|---:|---:|",
    ]
    for i, step in enumerate(diagnosis.steps, start=1):
        test = step.test
        lines.append(
            f"| {i} | **{test.effect.label()}** (`{test.effect.name}`) | {test.statistic:.4g} "
            f"| {test.dof} | {test.p_corrected:.2g} |"
        )
    lines += [
        "",
        f"- **residual RMS** (x, y, z), before: {rms(base)} m/s²",
        f"- **residual RMS** (x, y, z), after: {rms(final)} m/s²",
        "",
        "## Parameters before and after",
        "",
        "Δ/σ: (before − after) in units of the final σ stat — how far the paper's model "
        "was biased.",
        "",
        "| parameter | before | after | σ after | Δ/σ |",
        "|---|---:|---:|---:|---:|",
    ]
    before = dict(zip(base.names, base.values, strict=True))
    for i in _report_order(final.names):
        name, value, std = final.names[i], float(final.values[i]), float(final.std[i])
        if name in before:
            b = float(before[name])
            shift = _fmt((b - value) / std, 2) if std > 0 else "—"
            lines.append(
                f"| `{name}` | {_fmt(b, 7)} | {_fmt(value, 7)} | {_fmt(std, 2)} | {shift} |"
            )
        else:  # a parameter of an added effect
            lines.append(f"| `{name}` (added) | — | {_fmt(value, 7)} | {_fmt(std, 2)} | — |")
    return "\n".join(lines) + "\n"


def trend(time_s: np.ndarray, values: np.ndarray, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean of ``values`` (N, 3) per ``step_s`` of time, at each step's mean time (empty: none)."""
    t = np.asarray(time_s, dtype=float)
    index = np.floor((t - t[0]) / step_s).astype(np.int64)
    count = np.bincount(index).astype(float)
    filled = count > 0
    mean_t = np.bincount(index, weights=t)[filled] / count[filled]
    columns = [np.bincount(index, weights=values[:, k])[filled] / count[filled] for k in range(3)]
    return mean_t, np.column_stack(columns)


#: Effects whose residual drifts in time rather than repeating every turn: with one of
#: them added, the closed-loop tab shows the residual's trend too.
DRIFTING_EFFECTS = (
    "offset_warmup",
    "offset_drift",
    "gain_drift",
    "temperature_offset",
    "spin_extension",
)


def drifts(diagnosis) -> bool:
    """Whether the closed loop added an effect that drifts in time (:data:`DRIFTING_EFFECTS`)."""
    return any(step.test.effect.name in DRIFTING_EFFECTS for step in diagnosis.steps)


def closed_loop_chunks(diagnosis, shift_s: float) -> list[Chunk]:
    """The closed-loop tab's entities (module docstring): the paper's model against the final.

    Per model and axis the residual per 5° of ϑ with its ±2σ band
    (``/closed_loop/<model>/<a>/mean`` and ``…/band_2sigma``), side by side; the
    trend (mean per :data:`TREND_S`) only when an added effect drifts.
    """
    base, final = diagnosis.base, diagnosis.final
    base_shift_s = shift_s + (base.epoch_unix_ns - final.epoch_unix_ns) * 1e-9
    chunks = []
    for name, fit, rgb, fit_shift_s in (
        ("paper_model", base, BEFORE_COLOR, base_shift_s),
        ("with_effects", final, AFTER_COLOR, shift_s),
    ):
        chunks += angle_bar_chunks(
            f"closed_loop/{name}", "mean", wheel_angle_rad(fit), fit.residual_mps2, rgb, band=True
        )
        if drifts(diagnosis):
            t, mean = trend(fit.time_s + fit_shift_s, fit.residual_mps2, TREND_S)
            chunks += xyz_chunks(f"closed_loop/trend/{name}", t, mean)
    report = rr.TextDocument(closed_loop_markdown(diagnosis), media_type=rr.MediaType.MARKDOWN)
    chunks.append(static_chunk("closed_loop/report", row_columns(report)))
    return chunks


#: Colours of the per-axis extras: the range or rails, the clipped samples, the noise band.
RANGE_COLOR: Rgb = (30, 30, 30)
CLIPPED_COLOR: Rgb = (200, 0, 200)
LEFT_OUT_COLOR: Rgb = (240, 170, 240)
NOISE_BAND_COLOR: Rgb = (90, 90, 90)
#: A dropped sample within this fraction of a rail is drawn as clipped on that axis.
RAIL_BAND = 0.005


def signal_extras_chunks(recording: Recording) -> tuple[list[Chunk], tuple[str, ...]]:
    """``/range/<a>/{low,high}`` and ``/clipped/<a>``, and which of the two there are.

    The range: ±full scale when the session states it, else the rails the reader
    found (where it found one); across the whole recording.  The clipped samples:
    every one the reader left out, at its reading (on its rail), as points.
    """
    chunks: list[Chunk] = []
    extras: list[str] = []
    first, last = float(recording.time_s[0]), float(recording.time_s[-1])
    fs = recording.info.full_scale_g
    if fs:
        limit = fs * STANDARD_GRAVITY_MPS2
        rails = np.array([[-limit, limit]] * 3)
        label = f"sensor range ±{fs:g} g"
    else:
        rails = recording.clip_limits_mps2
        label = "rail where it clipped"
    if rails is not None:
        t = np.array([first, last])
        for k in range(3):
            for side, end in enumerate(("low", "high")):
                rail = float(rails[k, side])
                if np.isfinite(rail):
                    text = f"{label} ({rail:+.4g} m/s²)"
                    chunks += scalar_chunks(
                        f"range/{AXES[k]}/{end}", t, np.full(2, rail), text, RANGE_COLOR
                    )
        extras.append("range")
    if recording.clipped_time_s is not None:
        t, v = recording.clipped_time_s, recording.clipped_mps2
        for k in range(3):
            at = np.zeros(t.size, dtype=bool)
            for rail in rails[k] if rails is not None else ():
                if np.isfinite(rail):
                    at |= np.abs(v[:, k] - rail) <= RAIL_BAND * abs(rail)
            for name, rows, text, color in (
                ("at_rail", at, f"clipped at the rail: {int(at.sum())}, left out", CLIPPED_COLOR),
                ("other_axis", ~at, "left out: another axis clipped", LEFT_OUT_COLOR),
            ):
                if rows.any():
                    chunks += scalar_chunks(
                        f"clipped/{AXES[k]}/{name}", t[rows], v[rows, k], text, color, points=True
                    )
        extras.append("clipped")
    return chunks, tuple(extras)


def noise_band_chunks(noise_std_mps2: np.ndarray, start_s: float, end_s: float) -> list[Chunk]:
    """``/noise_band/<a>/{upper,lower}``: ±2σ of the noise per axis across the window."""
    chunks: list[Chunk] = []
    t = np.array([start_s, end_s])
    for k in range(3):
        two = 2.0 * float(noise_std_mps2[k])
        for end, sign in (("upper", 1.0), ("lower", -1.0)):
            label = f"±2σ noise ({two:.2g} m/s²)"
            chunks += scalar_chunks(
                f"noise_band/{AXES[k]}/{end}", t, np.full(2, sign * two), label, NOISE_BAND_COLOR
            )
    return chunks


@dataclass
class RrdFile:
    """A session's ``.rrd`` file being written: its stream, and what its blueprint must show."""

    stream: rr.RecordingStream
    #: (entity name, legend label, RGB) of the residual sets logged so far.
    residual_sets: list[tuple[str, str, Rgb]] = field(default_factory=list)
    closed_loop: bool = False
    extra_views: list[ExtraView] = field(default_factory=list)
    #: Shift from the calibration's clock to the recording's, s.
    shift_s: float = 0.0
    #: Lines of the verdict strip (0: none logged).
    verdict_lines: int = 0
    #: What the data plots draw besides data and model ("range", "clipped").
    signal_extras: tuple[str, ...] = ()
    #: The closed-loop tab shows the residual's trend (a drifting effect was added).
    closed_loop_trend: bool = False

    @property
    def residual_set_names(self) -> list[str]:
        """Names of the residual sets logged so far."""
        return [name for name, _, _ in self.residual_sets]

    def log_residuals(
        self,
        name: str,
        time_s: np.ndarray,
        residual_mps2: np.ndarray,
        theta_rad: np.ndarray,
        color: Rgb | None = None,
        label: str | None = None,
    ) -> None:
        """Add a residual set (see :func:`log_residuals`) to the file and its blueprint."""
        if name in self.residual_set_names:
            raise ValueError(f"residual set {name!r} is already in this file")
        rgb = set_color(name) if color is None else tuple(color)
        band = not self.residual_sets  # the first set: the calibration's own
        log_residuals(self.stream, name, time_s, residual_mps2, theta_rad, rgb, band)
        self.residual_sets.append((name, label or name, rgb))

    def log_diagnosis(self, diagnosis) -> None:
        """The closed loop's before/after (module docstring), if it added effects.

        Parameters
        ----------
        diagnosis:
            A :class:`wheelcal.closedloop.loop.Diagnosis` whose final fit
            is this file's calibration.
        """
        if diagnosis is None or not diagnosis.steps or self.closed_loop:
            return
        self.stream.send_chunks(closed_loop_chunks(diagnosis, self.shift_s))
        self.closed_loop = True
        self.closed_loop_trend = drifts(diagnosis)

    def add_view(self, kind: str, origin: str, name: str) -> None:
        """Show ``origin`` in the calibration tab's right column.

        Parameters
        ----------
        kind:
            ``"time_series"``, ``"bar_chart"``, ``"text"`` or ``"spatial_2d"``.
        origin:
            Entity path the view shows, e.g. ``/allan``.
        name:
            The view's title.
        """
        view = ExtraView(kind, origin, name)
        view.view()  # checks the kind
        self.extra_views.append(view)

    def layout(self) -> Layout:
        """The blueprint's cache key for what was logged."""
        return Layout(
            tuple(self.residual_sets),
            self.closed_loop,
            tuple(self.extra_views),
            verdict_lines=self.verdict_lines,
            signal_extras=self.signal_extras,
            closed_loop_trend=self.closed_loop_trend,
        )


def send_session_blueprint(
    stream: rr.RecordingStream,
    layout: Layout,
    window_s: tuple[float, float],
    shown_s: tuple[float, float],
) -> None:
    """Send the session blueprint: the layout from the per-process cache, this file's ranges."""
    send_blueprint_chunks(stream, (*layout_chunks(layout), *per_file_chunks(window_s, shown_s)))


@contextlib.contextmanager
def session_rrd(
    path: str | os.PathLike,
    session: SessionResult,
    durable: bool = True,
    document: Mapping | None = None,
) -> Iterator[RrdFile]:
    """Log a session into a new file; the caller may add residual sets inside the block.

    The file appears (atomically) when the block ends without an exception,
    with the blueprint written last; an exception leaves no file (see
    :func:`wheelcal.viz.rrd_writer.rrd_file`).

    Parameters
    ----------
    path:
        Destination ``.rrd``.
    session:
        The calibrated session: its final fit (residuals, parameters, noise,
        warnings), the whole recording (raw signal, all samples), the free-spin
        window that was searched (``None`` when given: then the fitted samples'
        span is marked), the gyroscope's calibration for the measured ω and the
        rests' noise for the Allan view.
    durable:
        fsync the file (see :func:`wheelcal.io.atomic.atomic_output`).
    document:
        The session's calibration JSON (``calibration_dict``), when the caller has it:
        the verdict strip reads its warnings, effects and window words from it (made
        here otherwise).

    Yields
    ------
    RrdFile
        ``.log_residuals(...)``, ``.log_diagnosis(...)``, ``.add_view(...)``;
        ``.stream`` is the Rerun stream.
    """
    result, recording, window = session.result, session.recording, session.window.found
    # Plot on the recording's clock, whatever epoch the result counts from.
    shift_s = (result.epoch_unix_ns - recording.epoch_unix_ns) * 1e-9
    fit_time_s = result.time_s + shift_s
    if window is not None:
        start_s, end_s = window.start_s, window.end_s
    else:
        start_s, end_s = float(fit_time_s[0]), float(fit_time_s[-1])
    first_s, last_s = float(recording.time_s[0]), float(recording.time_s[-1])
    name = Path(result.source).name or Path(path).stem
    with rrd_file(path, APPLICATION_ID, name, durable=durable) as stream:
        if recording.epoch_unix_ns:  # 0: times without a Unix epoch (no start time to give)
            stream.send_recording_start_time_nanos(recording.epoch_unix_ns)
        model = predict(result.params, result.centred_time_s, result.layout)  # Eq. (6)
        stream.send_chunks(signal_chunks(recording.time_s, recording.accel_mps2, fit_time_s, model))
        log_window(stream, start_s, end_s, first_s, last_s)
        chunks = spin_chunks(result, recording, shift_s, session.gyro)
        if document is None:
            from wheelcal.calibration import calibration_dict

            document = calibration_dict(session)
        allan = allan_chunks(session.assessment.noise, document.get("imu_noise"))
        chunks += allan
        markdown = report_markdown(result, window, start_s, end_s, recording.epoch_unix_ns)
        report = rr.TextDocument(markdown, media_type=rr.MediaType.MARKDOWN)
        chunks.append(static_chunk("report", row_columns(report)))
        verdict = verdict_markdown(document, recording)
        text = rr.TextDocument(verdict, media_type=rr.MediaType.MARKDOWN)
        chunks.append(static_chunk("verdict", row_columns(text)))
        extras, signal_extras = signal_extras_chunks(recording)
        chunks += extras
        noise = session.assessment.noise
        floor = noise.floor_mps2 if noise is not None else result.noise.marginal_std_mps2
        chunks += noise_band_chunks(floor, float(fit_time_s[0]), float(fit_time_s[-1]))
        stream.send_chunks(chunks)
        rrd = RrdFile(
            stream,
            shift_s=shift_s,
            verdict_lines=verdict_lines(verdict),
            signal_extras=signal_extras,
        )
        rrd.log_residuals(
            FIT_SET,
            fit_time_s,
            result.residual_mps2,
            wheel_angle_rad(result),
            label="data − model",
        )
        if allan:
            rrd.add_view(
                "spatial_2d",
                "/allan",
                "rests: Allan deviation σ(τ), log-log; black: exported density N/√τ",
            )
        yield rrd
        shown_s = (first_s - TIME_MARGIN_S, last_s + TIME_MARGIN_S)
        send_session_blueprint(stream, rrd.layout(), (start_s, end_s), shown_s)


#: Colours of the Allan plot's frame, grid and reference lines.
_FRAME_COLOR = (60, 60, 60)
_GRID_COLOR = (200, 200, 200)
_DENSITY_COLOR = (20, 20, 20)
_WALK_COLOR = (150, 150, 150)
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _decade(exponent: int) -> str:
    """``10⁻²`` for −2 (an axis label)."""
    return "1" if exponent == 0 else f"10{str(exponent).translate(_SUPERSCRIPT)}"


def _tau_label(exponent: int) -> str:
    return {-3: "1 ms", -2: "10 ms", -1: "0.1 s", 0: "1 s", 1: "10 s", 2: "100 s"}.get(
        exponent, f"{_decade(exponent)} s"
    )


def allan_chunks(noise, imu_noise: Mapping | None = None) -> list[Chunk]:
    """``/allan``: the rests' overlapping Allan deviation as a log-log plot with its axes.

    Drawn in a 2-D view at x = log10 τ/s, y = −log10 σ/(m/s²) (a 2-D view's y axis
    points down: larger σ is drawn higher, as on paper), one decade the same length
    on both axes, so the white noise's −½ slope looks like one: a frame with a grid
    line and a labelled tick at every decade (τ in s, σ in m/s²), the curve per axis
    (labelled at its end), and the references — the exported noise density's line
    N/√τ (Kalibr's, from the white σ per sample, :mod:`wheelcal.calibration.imu_noise`)
    and the random walk's bound K√(τ/3).  The read-outs are a table at
    ``/allan/readouts``.  ``noise`` is the gates' noise floor
    (``Assessment.noise``); nothing when the recording has no rests.
    """
    from wheelcal.calibration import rests_allan

    block = None if noise is None else rests_allan(noise.rests)
    if block is None:
        return []
    tau = np.asarray(block["tau_s"], dtype=float)
    adev = np.asarray(block["adev_mps2"], dtype=float)
    accel = (imu_noise or {}).get("accelerometer") or {}
    density = accel.get("noise_density_mps2_rthz")
    walk = np.asarray(block["random_walk_mps3_rthz"], dtype=float)
    lx = np.log10(tau)
    x0, x1 = int(np.floor(lx.min())), int(np.ceil(lx.max()))
    values = [adev[np.isfinite(adev)]]
    if density:
        values.append(np.asarray(density, float) / np.sqrt(tau[[0, -1]]).reshape(-1, 1))
    ly = np.log10(np.concatenate([v.ravel() for v in values]))
    s0, s1 = int(np.floor(ly.min())), int(np.ceil(ly.max()))
    top, bottom = -s1, -s0  # screen y of the largest and the smallest σ decade
    chunks = []
    frame = [[x0, top], [x1, top], [x1, bottom], [x0, bottom], [x0, top]]
    grid = [[[x, top], [x, bottom]] for x in range(x0 + 1, x1)]
    grid += [[[x0, -e], [x1, -e]] for e in range(s0 + 1, s1)]
    chunks.append(
        static_chunk(
            "allan/axes/frame", row_columns(rr.LineStrips2D([frame], colors=[_FRAME_COLOR]))
        )
    )
    if grid:
        chunks.append(
            static_chunk(
                "allan/axes/grid",
                row_columns(rr.LineStrips2D(grid, colors=[_GRID_COLOR], radii=[0.004])),
            )
        )
    ticks = [[x, bottom + 0.18] for x in range(x0, x1 + 1)]
    tick_text = [_tau_label(x) for x in range(x0, x1 + 1)]
    ticks += [[x0 - 0.5, -e] for e in range(s0, s1 + 1)]
    tick_text += [f"{_decade(e)} m/s²" for e in range(s0, s1 + 1)]
    chunks.append(
        static_chunk(
            "allan/axes/labels",
            row_columns(
                rr.Points2D(
                    ticks,
                    labels=tick_text,
                    radii=[0.001],
                    colors=[_FRAME_COLOR],
                    show_labels=True,
                )
            ),
        )
    )
    ends, names = [], []
    for k, axis in enumerate(AXES):
        ok = np.isfinite(adev[:, k]) & (adev[:, k] > 0)
        curve = np.column_stack([lx[ok], -np.log10(adev[ok, k])])
        strip = rr.LineStrips2D([curve], colors=[AXIS_COLORS[k]], radii=[0.012])
        chunks.append(static_chunk(f"allan/{axis}", row_columns(strip)))
        ends.append(curve[-1] + [0.08, 0.0])
        names.append(axis)
    chunks.append(
        static_chunk(
            "allan/curve_names",
            row_columns(
                rr.Points2D(
                    ends, labels=names, colors=list(AXIS_COLORS), radii=[0.001], show_labels=True
                )
            ),
        )
    )
    span = np.array([tau[0], tau[-1]])
    if density:
        n = float(max(density))
        line = np.column_stack([np.log10(span), -np.log10(n / np.sqrt(span))])
        chunks.append(
            static_chunk(
                "allan/noise_density",
                row_columns(rr.LineStrips2D([line], colors=[_DENSITY_COLOR], radii=[0.006])),
            )
        )
    if np.all(np.isfinite(walk)):
        k_max = float(walk.max())
        line = np.column_stack([np.log10(span), -np.log10(k_max * np.sqrt(span / 3))])
        inside = line[:, 1] >= top  # within the frame's σ range
        if inside.all():
            chunks.append(
                static_chunk(
                    "allan/random_walk_bound",
                    row_columns(rr.LineStrips2D([line], colors=[_WALK_COLOR], radii=[0.006])),
                )
            )
    lines = [
        f"Allan deviation of {block['rests_s']:.3g} s of rests",
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


def write_session_rrd(
    path: str | os.PathLike,
    session: SessionResult,
    durable: bool = True,
    document: Mapping | None = None,
) -> Path:
    """Write the session's ``.rrd`` (see the module docstring) atomically.

    Parameters
    ----------
    path:
        Destination, conventionally ``<out>/<stem>.rrd``.
    session:
        The calibrated session (see :func:`session_rrd`); its closed loop's
        report, when it added effects, gets its before/after tab.
    durable:
        fsync the file (see :func:`wheelcal.io.atomic.atomic_output`).
    document:
        The session's calibration JSON, when the caller has it (see :func:`session_rrd`).

    Returns
    -------
    Path
        ``path``.
    """
    with session_rrd(path, session, durable, document) as rrd:
        rrd.log_diagnosis(session.diagnosis)
    return Path(path)
