"""The layout of a session ``.rrd``: what a person sees when the file opens.

Tab **calibration** (always):

* left, three columns x / y / z — *data and model* against time; the
  *residual* (data − model) against time; the *mean residual per 5° of ϑ* as
  bars on a real angle axis 0–360°, with the ±2σ that noise alone gives a bin
  mean as a grey band;
* right — the calibration report, ω(t) (model, and the measured rate: gyro or
  per turn from the accelerometer), and any extra views a logging function
  registered (:meth:`wheelcal.viz.session_rrd.RrdFile.add_view`, e.g. the
  rests' Allan deviation under ``/allan``);
* across the bottom, the free-spin window lane (before / free spin / after).

Tab **closed loop** (when the closed loop added effects): the paper's model
against the final one — the residual per 5° of ϑ (effects that repeat every
turn: an imbalance, a sensor off its radius) and the residual's mean per
:data:`TREND_S` against time (effects that drift: a warm-up, a gain drift) —
and a report naming the effects added with their tests and the parameters
before and after.

How it opens: paused, on the ``time`` timeline, the free-spin window selected;
every time view shows the whole recording (the fitted window and the rests
around it) and all of them share one x-axis (zoom one, all follow).  Rerun
0.41 keeps that shared range on a built-in "global view" of the blueprint
(``LinkAxis.LinkToGlobal``: a linked view ignores its own range), so the file
sets it there (:data:`GLOBAL_VIEW_PATH`; the id is the viewer's constant
``GLOBAL_VIEW_ID``, which the public API does not expose — a Rerun upgrade that
moves it leaves the views linked but following the playhead;
``tests/test_viz_rrd.py`` checks the entity and ``tools/render_rrd.py`` shows
the result).  The side panels start collapsed, the time panel folded to its
play bar: the views get the screen.

Per-axis views show one axis of a three-axis entity: the samples are stored
as one struct {x, y, z} per row (:data:`XYZ_COMPONENT`; ``/signal`` holds
the data and the model as two such components on one row per sample, the
model's null outside the window: the cheap layout) and each view's
visualizers pick a field (a component mapping with a selector, rerun-sdk
0.41).  So a legend lists exactly the series drawn ("data", "model";
"paper's model", "with effects").

Speed: the layout is turned into blueprint chunks once per process and per
layout key (:func:`layout_chunks`); a file adds two chunks of its own — the
time panel (its selection) and the global time axis (its range).
"""

from __future__ import annotations

import functools
import uuid
from dataclasses import dataclass

import numpy as np
import pyarrow as pa
import rerun as rr
import rerun.blueprint as rrb
from rerun.blueprint.encodings import VisualizerComponentMapping
from rerun.chunk import Chunk

from wheelcal.model import AXES
from wheelcal.viz.arrow_chunks import ArrowColumn, column
from wheelcal.viz.blueprint_chunks import blueprint_chunk, blueprint_chunks, blueprint_rows

TIME_TIMELINE = "time"
#: The struct component of three-axis samples: one {x, y, z} per row, m/s².
XYZ_ARCHETYPE = "Xyz"
XYZ_COMPONENT = f"{XYZ_ARCHETYPE}:mps2"
#: ``/signal``'s two components, each a struct {x, y, z} per row (the model's null
#: outside the fitted window).
SIGNAL_DATA = "Signal:data_mps2"
SIGNAL_MODEL = "Signal:model_mps2"
#: Rerun 0.41's ``GLOBAL_VIEW_ID`` (re_viewer_context): the shared x-range of linked views.
GLOBAL_VIEW_ID = uuid.UUID("5c0dca6a-e63f-9cf7-f657-2602590474cc")
GLOBAL_VIEW_PATH = f"view/{GLOBAL_VIEW_ID}/TimeAxis"

Rgb = tuple[int, int, int]
AXIS_COLORS: tuple[Rgb, Rgb, Rgb] = ((220, 50, 47), (40, 160, 60), (38, 110, 210))
DATA_COLOR: Rgb = (150, 150, 150)
#: Sets in the closed-loop tab: the paper's model (before) and the final one (after).
BEFORE_COLOR: Rgb = (230, 120, 20)
AFTER_COLOR: Rgb = (38, 110, 210)

#: The closed-loop tab's residual trend: its mean over this many seconds.
TREND_S = 2.0
#: How the time views draw many samples per pixel: the min and the max of each pixel's
#: samples (an envelope), never their average — a rail or a spike stays where it is.
AGGREGATION = "MinMax"
#: Entities of the per-axis extras (``<a>`` an axis): the sensor's range or the rails the
#: reader found, the clipped samples it dropped, and the ±2σ of the noise around 0.
RANGE_PATH = "/range/{axis}"
CLIPPED_PATH = "/clipped/{axis}"
NOISE_BAND_PATH = "/noise_band/{axis}"

_LINKED = rrb.TimeAxis(link=rrb.components.LinkAxis.LinkToGlobal)


@dataclass(frozen=True)
class ExtraView:
    """A view a logging function adds to the right column (e.g. the Allan deviation)."""

    kind: str  # "time_series", "bar_chart", "text", "spatial_2d"
    origin: str
    name: str

    def view(self) -> rrb.View:
        """The blueprint view."""
        kinds = {
            "time_series": rrb.TimeSeriesView,
            "bar_chart": rrb.BarChartView,
            "text": rrb.TextDocumentView,
            "spatial_2d": rrb.Spatial2DView,
        }
        if self.kind not in kinds:
            raise ValueError(f"view kind must be one of {sorted(kinds)}, got {self.kind!r}")
        return kinds[self.kind](origin=self.origin, name=self.name)


@dataclass(frozen=True)
class Layout:
    """What a session file holds that changes its layout (the cache key).

    Parameters
    ----------
    residual_sets:
        ``(entity name, legend label, RGB)`` of each residual set in the
        calibration tab's residual views (the calibration's own first).
    closed_loop:
        The closed loop added effects (its tab is shown).
    extra_views:
        Views registered by logging functions, in the right column.
    """

    residual_sets: tuple[tuple[str, str, Rgb], ...]
    closed_loop: bool = False
    extra_views: tuple[ExtraView, ...] = ()
    #: The verdict strip's height in lines of text (the first screen holds all of it).
    verdict_lines: int = 0
    #: What the signal views draw besides data and model: the range, the clipped samples.
    signal_extras: tuple[str, ...] = ()
    #: The closed-loop tab also shows the residual's trend (an added effect drifts in time).
    closed_loop_trend: bool = False


def axis_series(
    axis: int, label: str, color: Rgb, width: float = 1.0, component: str = XYZ_COMPONENT
) -> rrb.Visualizer:
    """A line visualizer drawing one field (x, y or z) of a component of {x, y, z} rows."""
    mapping = VisualizerComponentMapping(
        "Scalars:scalars",
        "SourceComponent",
        source_component=component,
        selector=f".{AXES[axis]}",
    )
    style = rr.SeriesLines(
        names=[label], colors=[color], widths=[width], aggregation_policy=AGGREGATION
    )
    return style.visualizer(mappings=[mapping])


#: A series of a per-axis view: entity, component, legend label, colour, width.
Series = tuple[str, str, str, Rgb, float]


def _per_axis_view(
    axis: int, title: str, series: tuple[Series, ...], legend: bool, extras: tuple[str, ...] = ()
) -> rrb.TimeSeriesView:
    """A time view of one axis of {x, y, z} entities (several series may share an entity).

    ``extras``: entity subtrees drawn with the style they were logged with (plain
    scalars of this axis: the range, the clipped samples, the noise band).
    """
    overrides: dict[str, list[rrb.Visualizer]] = {}
    for path, component, label, color, width in series:
        overrides.setdefault(path, []).append(axis_series(axis, label, color, width, component))
    return rrb.TimeSeriesView(
        origin="/",
        contents=[*overrides, *(f"{e}/**" for e in extras)],
        name=title,
        axis_x=_LINKED,
        overrides=overrides,
        # Rerun's default legend (shown) costs no blueprint entity: only a hidden one is set.
        plot_legend=None if legend else rrb.PlotLegend(visible=False),
    )


def _signal_view(k: int, extras: tuple[str, ...] = ()) -> rrb.TimeSeriesView:
    series = (
        ("/signal", SIGNAL_DATA, "data", DATA_COLOR, 1.0),
        ("/signal", SIGNAL_MODEL, "model", AXIS_COLORS[k], 1.5),
    )
    paths = tuple(
        template.format(axis=AXES[k])
        for name, template in (("range", RANGE_PATH), ("clipped", CLIPPED_PATH))
        if name in extras
    )
    title = f"{AXES[k]}: data and model (m/s²; min/max per pixel)"
    return _per_axis_view(k, title, series, legend=True, extras=paths)


def _residual_view(k: int, sets: tuple[tuple[str, str, Rgb], ...], title: str):
    series = tuple(
        (f"/residual/{name}", XYZ_COMPONENT, label, rgb, 1.0) for name, label, rgb in sets
    )
    band = (NOISE_BAND_PATH.format(axis=AXES[k]),)
    return _per_axis_view(k, title, series, legend=True, extras=band)


def _angle_view(origin: str, title: str, legend: bool) -> rrb.BarChartView:
    return rrb.BarChartView(
        origin=origin,
        name=title,
        plot_legend=rrb.PlotLegend(corner="RightBottom", visible=legend),
    )


def _calibration_tab(layout: Layout) -> rrb.Vertical:
    sets = layout.residual_sets
    # One grid (not a column of rows) and the lane across the bottom: every container
    # is a blueprint entity, and each costs the file as much as a view's property.
    per_axis = rrb.Grid(
        *[_signal_view(k, layout.signal_extras) for k in range(3)],
        *[
            _residual_view(k, sets, f"{AXES[k]}: residual, data − model (m/s²); lines: ±2σ noise")
            for k in range(3)
        ],
        *[
            _angle_view(
                f"/residual_angle_mean/{AXES[k]}",
                f"{AXES[k]}: residual per 5° of ϑ; grey: ±2σ of noise",
                legend=len(sets) > 1,
            )
            for k in range(3)
        ],
        grid_columns=3,
        row_shares=[3, 2.4, 2.4],
    )
    right = [
        rrb.TextDocumentView(origin="/report", name="parameters (σ stat, σ sys)"),
        # The legend in Rerun's default corner (bottom left: ω spins down, away from it).
        rrb.TimeSeriesView(origin="/spin", name="ω(t): model and measured (rad/s)", axis_x=_LINKED),
        *[extra.view() for extra in layout.extra_views],
    ]
    # The parameter table keeps its rows on screen whatever views join it.
    shares = [4.6, 1.2, *[2.3] * len(layout.extra_views)]
    main = rrb.Horizontal(
        per_axis, rrb.Vertical(*right, row_shares=shares), column_shares=[3, 1.15]
    )
    lane = rrb.StateTimelineView(origin="/window", name="free-spin window", time_view=_LINKED)
    if not layout.verdict_lines:
        return rrb.Vertical(main, lane, row_shares=[10, 1], name="calibration")
    verdict = rrb.TextDocumentView(origin="/verdict", name="verdict")
    # On a 1080-px screen the tab has ≈ 1000 px: the strip needs its title bar and
    # padding (≈ 44 px) and ≈ 21 px a line; the other rows share the rest 10 : 1.3.
    need = 44 + 21 * layout.verdict_lines
    strip = 11.3 * need / max(1000 - need, 300)
    return rrb.Vertical(verdict, main, lane, row_shares=[strip, 10, 1.3], name="calibration")


def _closed_loop_tab(trend: bool = False) -> rrb.Horizontal:
    """Before (the paper's model) and after (with the effects) side by side, each with its band.

    Per axis two bar charts of the residual per 5° of ϑ, each with the ±2σ a bin mean
    has from noise alone; with ``trend`` (an added effect drifts in time) the
    residual's mean per :data:`TREND_S` too.
    """
    columns = []
    for name, label in (("paper_model", "paper's model"), ("with_effects", "with effects")):
        columns.append(
            rrb.Vertical(
                *[
                    _angle_view(
                        f"/closed_loop/{name}/{AXES[k]}",
                        f"{AXES[k]}: {label} — residual per 5° of ϑ; grey: ±2σ of noise",
                        legend=False,
                    )
                    for k in range(3)
                ]
            )
        )
    if trend:
        trends = (
            ("/closed_loop/trend/paper_model", XYZ_COMPONENT, "paper's model", BEFORE_COLOR, 1.5),
            ("/closed_loop/trend/with_effects", XYZ_COMPONENT, "with effects", AFTER_COLOR, 1.5),
        )
        columns.append(
            rrb.Vertical(
                *[
                    _per_axis_view(
                        k, f"{AXES[k]}: residual, mean per {TREND_S:g} s (m/s²)", trends, True
                    )
                    for k in range(3)
                ]
            )
        )
    report = rrb.TextDocumentView(origin="/closed_loop/report", name="closed loop: what it added")
    shares = [1.0] * len(columns) + [1.05]
    return rrb.Horizontal(*columns, report, column_shares=shares, name="closed loop")


def session_layout(layout: Layout) -> rrb.Container:
    """The tabs of a session file (module docstring); one tab needs no tab container."""
    if not layout.closed_loop:
        return _calibration_tab(layout)
    return rrb.Tabs(
        _calibration_tab(layout), _closed_loop_tab(layout.closed_loop_trend), active_tab=0
    )


class GlobalTimeAxis:
    """The shared x-range of every linked time view (a blueprint part; module docstring)."""

    def __init__(self, start_s: float, end_s: float) -> None:
        self.range = rrb.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(nanos=round(start_s * 1e9)),
            end=rrb.TimeRangeBoundary.absolute(nanos=round(end_s * 1e9)),
        )

    def _log_to_stream(self, stream) -> None:
        stream.log(GLOBAL_VIEW_PATH, rrb.TimeAxis(view_range=self.range))


def time_panel(start_s: float, end_s: float) -> rrb.TimePanel:
    """Paused on ``time``, folded to its play bar, the free-spin window selected."""
    selection = rrb.components.AbsoluteTimeRange(min=round(start_s * 1e9), max=round(end_s * 1e9))
    return rrb.TimePanel(
        timeline=TIME_TIMELINE,
        play_state="paused",
        state="collapsed",
        time_selection=selection,
    )


@functools.lru_cache(maxsize=16)
def layout_chunks(layout: Layout) -> tuple[Chunk, ...]:
    """The layout and the side panels as chunks, built once per process and layout."""
    blueprint = rrb.Blueprint(
        session_layout(layout),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
    )
    return blueprint_chunks(blueprint)


@functools.lru_cache(maxsize=1)
def _per_file_rows() -> tuple:
    """The time panel and the global x-range as rows, converted once (values replaced per file)."""
    return tuple(blueprint_rows(time_panel(0.0, 0.0), GlobalTimeAxis(0.0, 0.0)))


def _absolute(union_type: pa.DenseUnionType, time_ns: int) -> pa.Array:
    """One ``TimeRangeBoundary.absolute(nanos=time_ns)`` as its Arrow dense union."""
    k = [f.name for f in union_type].index("Absolute")
    children = [
        pa.array([time_ns] if i == k else [], type=f.type) for i, f in enumerate(union_type)
    ]
    codes = pa.py_buffer(np.array([union_type.type_codes[k]], dtype=np.int8))
    # Built on the union type itself (``UnionArray.from_dense`` drops "not null").
    return pa.Array.from_buffers(
        union_type, 1, [None, codes, pa.py_buffer(np.zeros(1, np.int32))], children=children
    )


def _replaced(columns: tuple[ArrowColumn, ...], name: str, value: pa.Array) -> list[ArrowColumn]:
    """``columns`` with the one-row column of component ``name`` holding ``value``."""
    out = []
    for c in columns:
        if c.component_descriptor().component == name:
            c = column(c.component_descriptor(), value)
        out.append(c)
    return out


def per_file_chunks(window_s: tuple[float, float], shown_s: tuple[float, float]) -> list[Chunk]:
    """The time panel (window selected) and the global x-range of one file.

    The same rows as converting :func:`time_panel` and :class:`GlobalTimeAxis`
    (``tests/test_viz_rrd.py`` compares them); only the two values are built here.
    """
    chunks = []
    for path, static, columns in _per_file_rows():
        for c in columns:
            name = c.component_descriptor().component
            value_type = c.as_arrow_array().type.value_type
            if name == "TimePanelBlueprint:time_selection":
                window_ns = {"min": round(window_s[0] * 1e9), "max": round(window_s[1] * 1e9)}
                columns = _replaced(columns, name, pa.array([window_ns], type=value_type))
            elif name == "TimeAxis:view_range":
                ends = [
                    _absolute(value_type.field(k).type, round(v * 1e9))
                    for k, v in enumerate(shown_s)
                ]
                value = pa.StructArray.from_arrays(ends, fields=list(value_type))
                columns = _replaced(columns, name, value)
        chunks.append(blueprint_chunk(path, static, columns))
    return chunks
