"""Rerun files: written atomically, read back with rerun.chunk.RrdReader, values checked.

The files are decoded with the SDK's own reader (``RrdReader(path).stream()``
→ chunks → Arrow record batches), so every assertion is on what a viewer
would load: entity paths, timelines, values, the text panel and the
blueprint store.
"""

import copy
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
import rerun.blueprint as rrb
from rerun import FileSink as rr_file_sink
from rerun.chunk import Chunk, RrdReader

from wheelcal.calibration.session_json import calibration_dict
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.estimate.residual_profile import binned_mean_by_angle
from wheelcal.session.fit import session_of_fit
from wheelcal.session.window import find_free_spin
from wheelcal.simulate import table2
from wheelcal.simulate.session import simulate_session
from wheelcal.viz.angle_profile import angle_profile
from wheelcal.viz.arrow_chunks import (
    column,
    duration_index,
    row_columns,
    scalars_column,
    sequence_index,
    static_chunk,
    tensor_f64,
)
from wheelcal.viz.batch_rrd import write_batch_rrd
from wheelcal.viz.blueprint_chunks import blueprint_chunks, send_blueprint_chunks
from wheelcal.viz.rrd_writer import RrdWriteError
from wheelcal.viz.session_blueprint import (
    GLOBAL_VIEW_PATH,
    SIGNAL_DATA,
    SIGNAL_MODEL,
    XYZ_COMPONENT,
    GlobalTimeAxis,
    Layout,
    per_file_chunks,
    session_layout,
    time_panel,
)
from wheelcal.viz.session_rrd import (
    ANGLE_BINS,
    BAND_ENTITY,
    CHUNK_ROWS,
    TIME_MARGIN_S,
    recorded_at,
    session_rrd,
    wheel_angle_rad,
    write_session_rrd,
)

# ---------------------------------------------------------------- reading back


def written(path, recording_id, send):
    """What ``send(stream)`` logs into a fresh stream, as an .rrd file at ``path``."""
    stream = rr.RecordingStream("wheelcal", recording_id=recording_id)
    sink = stream.binary_stream()
    send(stream)
    path.write_bytes(sink.read(flush=True))
    stream.disconnect()
    return path


def read_store(path, blueprint=False):
    """{entity path: [chunks]} of the recording (or blueprint) store."""
    reader = RrdReader(path)
    store = reader.blueprints()[0] if blueprint else None
    chunks = {}
    for chunk in reader.stream(store=store).to_chunks():
        chunks.setdefault(chunk.entity_path, []).append(chunk)
    return chunks


def temporal(chunks, entity, component, timeline):
    """(index values, component values) of an entity's temporal rows, sorted by index."""
    index, values = [], []
    for chunk in chunks[entity]:
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        column = batch.column(timeline)
        if str(column.type).startswith("duration"):
            column = column.cast("int64")
        index.append(column.to_numpy())
        values.extend(batch.column(component).to_pylist())
    index = np.concatenate(index)
    order = np.argsort(index, kind="stable")
    return index[order], [values[i] for i in order]


def xyz(chunks, entity, component=XYZ_COMPONENT, timeline="time"):
    """(index values, (N, 3) array) of an entity's {x, y, z} rows of one component.

    Null rows (``/signal``'s model outside the window) are left out.
    """
    index, rows = temporal(chunks, entity, component, timeline)
    kept = [i for i, r in enumerate(rows) if r is not None]
    return index[kept], np.array([[rows[i][0][a] for a in "xyz"] for i in kept], dtype=float)


def static(chunks, entity, component):
    """The static value of one component (its first row)."""
    for chunk in chunks[entity]:
        batch = chunk.to_record_batch()
        if chunk.is_static and component in batch.schema.names:
            return batch.column(component).to_pylist()[0]
    raise KeyError(f"{entity}: no static {component}")


def blueprint_views(path):
    """[(view class, display name, origin)] in the file's blueprint."""
    views = []
    for chunks in read_store(path, blueprint=True).values():
        for chunk in chunks:
            batch = chunk.to_record_batch()
            if "ViewBlueprint:display_name" in batch.schema.names:
                row = [
                    batch.column(f"ViewBlueprint:{c}").to_pylist()[-1][0]
                    for c in ("class_identifier", "display_name", "space_origin")
                ]
                views.append(tuple(row))
    return views


def blueprint_component(path, component):
    """All values of one blueprint component, e.g. ``TimePanelBlueprint:timeline``."""
    out = []
    for chunks in read_store(path, blueprint=True).values():
        for chunk in chunks:
            batch = chunk.to_record_batch()
            if component in batch.schema.names:
                out.extend(batch.column(component).to_pylist())
    return out


def blueprint_entities(path):
    return set(read_store(path, blueprint=True))


# ---------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def session():
    """A full simulated session (rest, push, 90 s free spin at 200 Hz, brake, rest), fitted."""
    sim = simulate_session(table2(rng=np.random.default_rng(5)), np.random.default_rng(6))
    recording = sim.recording
    window = find_free_spin(recording)
    result = JointFit().fit(recording.window(window.start_s, window.end_s))
    return recording, window, result


def judged(result, recording, window):
    """The fit judged as a session (what the writers take)."""
    return session_of_fit(result, recording, window)


@pytest.fixture(scope="module")
def session_file(session, tmp_path_factory):
    recording, window, result = session
    path = tmp_path_factory.mktemp("rrd") / "s1.rrd"
    assert write_session_rrd(path, judged(result, recording, window)) == path
    return path, read_store(path)


def no_leftovers(directory):
    """No temporary files from the atomic writer."""
    return [p.name for p in directory.iterdir() if p.name.endswith(".tmp")] == []


# ---------------------------------------------------------------- session file


def test_session_entity_paths(session_file):
    _, chunks = session_file
    expected = {
        "/signal",
        "/window",
        "/residual/fit",
        *(f"/residual_angle_mean/{a}/{e}" for a in "xyz" for e in ("fit", BAND_ENTITY)),
        "/spin/omega_radps",
        "/spin/omega_measured_radps",
        "/report",
        "/verdict",
        *(f"/noise_band/{a}/{e}" for a in "xyz" for e in ("upper", "lower")),
        # the simulated session rests before and after: their Allan deviation, with axes
        "/allan/readouts",
        "/allan/curve_names",
        "/allan/noise_density",
        "/allan/random_walk_bound",
        *(f"/allan/axes/{e}" for e in ("frame", "grid", "labels")),
        *(f"/allan/{a}" for a in "xyz"),
    }
    assert set(chunks) - {"/__properties"} == expected


def test_raw_signal_is_the_whole_recording(session, session_file):
    recording, _, _ = session
    _, chunks = session_file
    t_ns, values = xyz(chunks, "/signal", SIGNAL_DATA)
    np.testing.assert_array_equal(t_ns, np.rint(recording.time_s * 1e9).astype(np.int64))
    np.testing.assert_array_equal(values, recording.accel_mps2)
    # One row per sample for the data and the model: the model's times are the data's.
    assert sum(c.num_rows for c in chunks["/signal"] if not c.is_static) == recording.samples


def test_residual_series_equals_the_result(session, session_file):
    _, _, result = session
    _, chunks = session_file
    t_ns, values = xyz(chunks, "/residual/fit")
    np.testing.assert_array_equal(values, result.residual_mps2)
    assert np.max(np.abs(t_ns - result.time_s * 1e9)) <= 0.5  # rounded, not truncated
    # One timeline only: an angle timeline would empty every time plot when selected.
    for chunk in chunks["/residual/fit"]:
        names = chunk.to_record_batch().schema.names
        assert [n for n in names if ":" not in n and n != "rerun.controls.RowId"] in ([], ["time"])


def test_long_series_are_cut_into_store_sized_chunks(session, session_file):
    """≤ CHUNK_ROWS rows per chunk, in order, together every row once (a file sink cost)."""
    recording, _, result = session
    _, chunks = session_file
    for entity, n in (("/signal", recording.samples), ("/residual/fit", result.time_s.size)):
        temporal_chunks = [c for c in chunks[entity] if not c.is_static]
        sizes = [c.num_rows for c in temporal_chunks]
        assert sum(sizes) == n and len(sizes) == -(-n // CHUNK_ROWS)
        assert max(sizes) == CHUNK_ROWS
        starts = [
            c.to_record_batch().column("time").cast("int64")[0].as_py() for c in temporal_chunks
        ]
        assert starts == sorted(starts)


def test_signal_rows_are_the_union_of_data_and_model_times():
    """Model times that are not data times get rows of their own (data null there)."""
    from wheelcal.viz.session_rrd import signal_chunks

    data_t, model_t = np.array([0.0, 1.0, 2.0, 3.0]), np.array([1.0, 1.5, 3.0])
    data, model = np.arange(12.0).reshape(4, 3), -np.arange(9.0).reshape(3, 3)
    (chunk,) = signal_chunks(data_t, data, model_t, model)
    chunks = {"/signal": [chunk]}
    t_ns, values = xyz(chunks, "/signal", SIGNAL_DATA)
    np.testing.assert_array_equal(t_ns, [0, 1_000_000_000, 2_000_000_000, 3_000_000_000])
    np.testing.assert_array_equal(values, data)
    t_ns, values = xyz(chunks, "/signal", SIGNAL_MODEL)
    np.testing.assert_array_equal(t_ns, [1_000_000_000, 1_500_000_000, 3_000_000_000])
    np.testing.assert_array_equal(values, model)
    assert chunk.num_rows == 5


def test_model_plus_residual_is_the_data(session, session_file):
    recording, _, result = session
    _, chunks = session_file
    t_ns, model = xyz(chunks, "/signal", SIGNAL_MODEL)
    assert t_ns.size == result.time_s.size
    inside = np.isin(np.rint(recording.time_s * 1e9).astype(np.int64), t_ns)
    np.testing.assert_allclose(
        model + result.residual_mps2, recording.accel_mps2[inside], atol=1e-9
    )


def test_omega_is_the_fitted_spin(session, session_file):
    _, _, result = session
    _, chunks = session_file
    t_ns, omega = temporal(chunks, "/spin/omega_radps", "Scalars:scalars", "time")
    assert 100 <= t_ns.size <= 1000
    expected = result.params.spin.omega_at(t_ns * 1e-9 - result.centre_s)
    np.testing.assert_allclose(np.array(omega)[:, 0], expected, rtol=1e-9)
    assert static(chunks, "/spin/omega_radps", "SeriesLines:names") == ["model"]


def test_measured_omega_per_turn_is_the_true_rate(session_file):
    """No gyroscope: ω per turn from the accelerometer, against the simulator's true ω."""
    _, chunks = session_file
    sim = simulate_session(table2(rng=np.random.default_rng(5)), np.random.default_rng(6))
    t_ns, omega = temporal(chunks, "/spin/omega_measured_radps", "Scalars:scalars", "time")
    omega = np.array(omega)[:, 0]
    # 86 s at 7–11 rad/s: ≈ 120 turns, each one point at its middle.
    assert 100 <= t_ns.size <= 160
    truth = np.interp(t_ns * 1e-9, sim.recording.time_s, sim.omega_radps)
    # A crossing is timed to ≈ σ/(A ω) ≈ 1 ms in a turn of ≈ 0.7 s: ≈ 0.2 % per turn.
    assert np.max(np.abs(omega / truth - 1)) < 0.01
    assert abs(np.median(omega / truth - 1)) < 1e-3
    names = static(chunks, "/spin/omega_measured_radps", "SeriesPoints:names")
    assert names == ["measured: per turn (accelerometer)"]


def test_window_is_marked(session, session_file):
    recording, window, _ = session
    _, chunks = session_file
    t_ns, states = temporal(chunks, "/window", "StateChange:state", "time")
    assert [s[0] for s in states] == ["before", "free spin", "after"]
    expected = np.rint(np.array([recording.time_s[0], window.start_s, window.end_s]) * 1e9)
    np.testing.assert_array_equal(t_ns, expected.astype(np.int64))


def test_mean_residual_per_angle_bin(session, session_file):
    _, _, result = session
    _, chunks = session_file
    theta_unwrapped = wheel_angle_rad(result)
    theta = np.mod(theta_unwrapped, 2 * np.pi)
    for k, axis in enumerate("xyz"):
        base = f"/residual_angle_mean/{axis}"
        values = static(chunks, f"{base}/fit", "BarChart:values")[0]
        abscissa = static(chunks, f"{base}/fit", "BarChart:abscissa")[0]
        assert len(abscissa["buffer"]) == ANGLE_BINS  # every 5° bin holds samples
        assert static(chunks, f"{base}/fit", "BarChart:widths") == [5.0] * ANGLE_BINS
        color = static(chunks, f"{base}/fit", "BarChart:color")
        assert color == [(38 << 24) | (110 << 16) | (210 << 8) | 170]  # the fit set's, translucent
        # Independent check of one bin, 90°–95°: its mean, and its σ with each turn
        # one independent draw (the samples of a bin within one turn share their noise).
        j = 18
        assert abscissa["buffer"][j] == pytest.approx(92.5)
        inside = (theta >= np.deg2rad(90.0)) & (theta < np.deg2rad(95.0))
        r = result.residual_mps2[inside, k]
        assert values["buffer"][j] == pytest.approx(r.mean())
        turns = np.floor(theta_unwrapped[inside] / (2 * np.pi))
        per_turn = [(r[turns == u].size, r[turns == u].mean()) for u in np.unique(turns)]
        n_total = sum(n for n, _ in per_turn)
        var = sum(n**2 * (m - r.mean()) ** 2 for n, m in per_turn) / n_total**2
        var *= len(per_turn) / (len(per_turn) - 1)
        band = static(chunks, f"{base}/{BAND_ENTITY}", "BarChart:values")[0]["buffer"]
        band_at = static(chunks, f"{base}/{BAND_ENTITY}", "BarChart:abscissa")[0]["buffer"]
        assert band_at == abscissa["buffer"] * 2  # each bin twice: up, then down
        assert band[j] == pytest.approx(2 * np.sqrt(var), rel=1e-9)
        assert band[ANGLE_BINS + j] == pytest.approx(-2 * np.sqrt(var), rel=1e-9)


def test_bin_sigma_is_honest_under_coloured_noise():
    """The band's σ of a bin mean matches the scatter of bin means over many noise draws.

    Low-pass noise (41 Hz at 200 Hz, as the MPU-9250's filter) correlates the
    samples of one bin within a turn: σ/√N would be too small.
    """
    from scipy.signal import butter, lfilter

    rng = np.random.default_rng(7)
    t = np.arange(0, 60, 0.005)
    theta = 10.0 * t - 0.05 * t**2  # a spin-down, rad
    b, a = butter(2, 41.0 / 100.0)
    means, sigmas, marginal = [], [], []
    for _ in range(200):
        noise = lfilter(b, a, rng.normal(0, 0.1, size=(t.size, 3)), axis=0)
        profile = angle_profile(theta, noise, ANGLE_BINS)
        means.append(profile.mean_mps2)
        sigmas.append(profile.std_of_mean_mps2)
        marginal.append(noise.std(axis=0))
    scatter = np.std(np.array(means), axis=0, ddof=1)
    predicted = np.sqrt(np.mean(np.array(sigmas) ** 2, axis=0))
    ratio = np.median(predicted / scatter)
    assert 0.9 < ratio < 1.1
    # The naive σ/√N is too small here: that is why the turns are the clusters.
    naive = np.mean(marginal, axis=0) / np.sqrt(profile.samples)[:, None]
    assert np.median(scatter / naive) > 1.2


def test_angle_profile_mean_is_the_binned_mean(session):
    _, _, result = session
    theta = wheel_angle_rad(result)
    profile = angle_profile(theta, result.residual_mps2, ANGLE_BINS)
    centres, mean, count = binned_mean_by_angle(theta, result.residual_mps2, ANGLE_BINS)
    np.testing.assert_allclose(profile.centres_deg, centres)
    np.testing.assert_allclose(profile.mean_mps2, mean, atol=1e-15)
    np.testing.assert_array_equal(profile.samples, count)


def test_binned_mean_helper():
    theta = np.deg2rad([1.0, 2.0, 359.0, 361.0, 180.0])
    values = np.array([[1, 2, 3], [3, 4, 5], [10, 10, 10], [5, 6, 7], [0, 0, 0]], float)
    centres, mean, count = binned_mean_by_angle(theta, values, bins=4)
    np.testing.assert_allclose(centres, [45.0, 225.0, 315.0])
    np.testing.assert_allclose(mean[0], [3, 4, 5])  # 1°, 2°, 361° ≡ 1°
    np.testing.assert_array_equal(count, [3, 1, 1])


def test_report_panel(session, session_file):
    recording, window, result = session
    _, chunks = session_file
    text = static(chunks, "/report", "TextDocument:text")[0]
    media = static(chunks, "/report", "TextDocument:media_type")[0]
    assert media == "text/markdown"
    for name in ("gain_x", "offset_z_mps2", "tilt_deg"):
        assert f"| `{name}` | {result.value_of(name):.7g} | {result.std_of(name):.2g} |" in text
    assert f"{result.systematic.std_of('gain_x'):.2g}" in text
    verdict = static(chunks, "/verdict", "TextDocument:text")[0]
    assert "**warnings (" in verdict
    document = calibration_dict(judged(result, recording, window))
    assert document["source"]["window_reason"] in verdict  # the JSON's words, not its own
    # The simulator's first sample: 1.7e9 s after the Unix epoch.
    assert recording.epoch_unix_ns == 1_700_000_000_000_000_000
    assert "**recorded**: 2023-11-14 22:13:20.000 UTC" in text


def test_recorded_at():
    assert recorded_at(1_710_234_000_123_456_789) == "2024-03-12 09:00:00.123 UTC"
    assert recorded_at(0).startswith("—")


def test_the_file_carries_the_recording_start_time(tmp_path, session):
    """Rerun's recording property ``start_time`` is the recording's first sample, not 'now'."""
    import dataclasses

    recording, window, result = session
    start_ns = 1_710_234_000_000_000_000  # another start: the file must follow it
    moved = dataclasses.replace(recording, epoch_unix_ns=start_ns)
    fit = dataclasses.replace(result, epoch_unix_ns=start_ns)
    path = write_session_rrd(tmp_path / "t.rrd", judged(fit, moved, window))
    rows = [
        row["RecordingInfo:start_time"][0]
        for chunk in read_store(path)["/__properties"]
        for row in chunk.to_record_batch().to_pylist()
        if "RecordingInfo:start_time" in row
    ]
    assert rows[-1] == start_ns  # the last write wins (the SDK first writes "now")
    text = static(read_store(path), "/report", "TextDocument:text")[0]
    assert recorded_at(start_ns) in text


def view_properties(path):
    """{view display name: {property entity suffix: {component: value}}} of the blueprint."""
    contents = blueprint_contents(path)
    names = {e: v[0][0] for (e, c, _), v in contents.items() if c == "ViewBlueprint:display_name"}
    out = {}
    for view, name in names.items():
        props = out.setdefault(name, {})
        for (entity, component, _), value in contents.items():
            if entity.startswith(view + "/"):
                props.setdefault(entity[len(view) + 1 :], {})[component] = value
    return out


def overrides_of(props):
    """{(overridden entity, legend names, [source component unless Xyz,] selector)} of a view."""
    out = set()
    for suffix, components in props.items():
        if "VisualizerInstruction:component_map" not in components:
            continue
        entity = "/" + suffix.split("overrides/")[1].split("/visualizers")[0]
        (mapping,) = components["VisualizerInstruction:component_map"][0]
        names = tuple(components["SeriesLines:names"][0])
        source = mapping["source_component"]
        out.add(
            (entity, names, mapping["selector"])
            if source == XYZ_COMPONENT
            else (entity, names, source, mapping["selector"])
        )
    return out


def range_boundaries(path):
    """(kind, value) of the start and end of the global view's x-range (a union each)."""
    (chunk,) = read_store(path, blueprint=True)[f"/{GLOBAL_VIEW_PATH}"]
    struct = chunk.to_record_batch().column("TimeAxis:view_range").flatten()
    out = []
    for field in ("start", "end"):
        union = struct.field(field)
        code = union.type_codes[0].as_py()
        kind = union.type[union.type.type_codes.index(code)].name
        out.append((kind, union[0].as_py()))
    return out


def test_session_blueprint(session, session_file):
    recording, window, _ = session
    path, _ = session_file
    views = blueprint_views(path)
    classes = {v[0] for v in views}
    assert {"TimeSeries", "BarChart", "TextDocument", "StateTimeline"} <= classes
    assert ("TextDocument", "parameters (σ stat, σ sys)", "/report") in views
    assert ("TextDocument", "verdict", "/verdict") in views
    assert ("TimeSeries", "ω(t): model and measured (rad/s)", "/spin") in views
    # Opens paused on `time`, folded to its play bar, the free-spin window selected.
    assert blueprint_component(path, "TimePanelBlueprint:timeline") == [["time"]]
    paused = [[rrb.components.PlayState.Paused.value]]
    assert blueprint_component(path, "TimePanelBlueprint:play_state") == paused
    collapsed = [[rrb.components.PanelState.Collapsed.value]]
    assert blueprint_component(path, "TimePanelBlueprint:state") == collapsed
    assert blueprint_component(path, "PanelBlueprint:state") == collapsed * 2  # side panels
    (selection,) = blueprint_component(path, "TimePanelBlueprint:time_selection")
    assert selection[0] == {"min": round(window.start_s * 1e9), "max": round(window.end_s * 1e9)}
    # One shared x-range: the whole recording, the rests around the window included.
    (start, end) = range_boundaries(path)
    first, last = recording.time_s[0] - TIME_MARGIN_S, recording.time_s[-1] + TIME_MARGIN_S
    assert start == ("Absolute", round(first * 1e9))
    assert end == ("Absolute", round(last * 1e9))
    assert first < window.start_s - 1 and last > window.end_s + 1
    props = view_properties(path)
    linked = rrb.components.LinkAxis.LinkToGlobal.value
    for cls, name, _ in views:
        if cls in ("TimeSeries", "StateTimeline"):
            assert props[name]["TimeAxis"]["TimeAxis:link"] == [[linked]], name
    # Per-axis views draw one field of each entity, with a legend naming it.
    for axis in "xyz":
        signal = props[f"{axis}: data and model (m/s²; min/max per pixel)"]
        assert overrides_of(signal) == {
            ("/signal", ("data",), SIGNAL_DATA, f".{axis}"),
            ("/signal", ("model",), SIGNAL_MODEL, f".{axis}"),
        }
        assert "PlotLegend" not in signal  # Rerun's default: the legend is shown
        residual = props[f"{axis}: residual, data − model (m/s²); lines: ±2σ noise"]
        assert overrides_of(residual) == {("/residual/fit", ("data − model",), f".{axis}")}
        assert "PlotLegend" not in residual
        bars = props[f"{axis}: residual per 5° of ϑ; grey: ±2σ of noise"]
        assert bars["PlotLegend"]["PlotLegend:visible"] == [[False]]  # entity paths: the title
        assert (
            "BarChart",
            f"{axis}: residual per 5° of ϑ; grey: ±2σ of noise",
            f"/residual_angle_mean/{axis}",
        ) in views
    reader = RrdReader(path)
    assert reader.recordings()[0].application_id == "wheelcal"


def blueprint_contents(path):
    """{(entity, component, static): values} of the file's blueprint store."""
    return store_contents(path, blueprint=True)


def store_contents(path, blueprint=False):
    """{(entity, component, static): values} of the file's recording (or blueprint) store."""
    out = {}
    for entity, chunks in read_store(path, blueprint=blueprint).items():
        for chunk in chunks:
            batch = chunk.to_record_batch()
            for name in batch.schema.names:
                if ":" in name:  # components, not row ids or timelines
                    out[(entity, name, chunk.is_static)] = batch.column(name).to_pylist()
    return out


def reference_blueprint(layout, window_s):
    """The file's blueprint as Rerun's own ``send_blueprint`` writes it (without the x-range)."""
    return rrb.Blueprint(
        session_layout(layout),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        time_panel(*window_s),
    )


FIT = ("fit", "fit", (38, 110, 210))


def test_blueprint_chunks_send_what_send_blueprint_sends(tmp_path):
    """The cached-chunk path gives the blueprint store Rerun's own send_blueprint gives."""
    layout = Layout((FIT, ("after", "after", (1, 2, 3))), closed_loop=True)
    blueprint = reference_blueprint(layout, (1.5, 80.25))
    paths = []
    for name, send in (
        ("rerun", lambda s: s.send_blueprint(blueprint)),
        ("chunks", lambda s: send_blueprint_chunks(s, blueprint_chunks(blueprint))),
    ):
        paths.append(written(tmp_path / f"{name}.rrd", f"bp-{name}", send))
    expected, got = (blueprint_contents(p) for p in paths)
    kinds = {component for _, component, _ in expected}
    assert {
        "ViewBlueprint:display_name",
        "ViewContents:query",
        "VisualizerInstruction:component_map",
        "SeriesLines:names",
        "ContainerBlueprint:contents",
        "TimeAxis:link",
        "PlotLegend:visible",
        "TimePanelBlueprint:time_selection",
        "TimePanelBlueprint:play_state",
    } <= kinds
    assert got == expected
    assert RrdReader(paths[1]).blueprints()[0].application_id == "wheelcal"


def test_static_chunks_store_what_log_stores(tmp_path):
    """Pre-converted static rows (``arrow_chunks``) give the store ``log(static=True)`` gives."""
    chart = rr.BarChart(
        np.linspace(-1, 1, 72),
        abscissa=np.arange(72) * 5.0 + 2.5,
        widths=np.full(72, 5.0),
        color=(38, 110, 210, 170),
    )
    values = rr.BarChart.descriptor_values()
    shared = [c for c in row_columns(chart) if c.component_descriptor() != values]
    entities = {
        "style": [rr.SeriesLines(names=["a x", "a y"], colors=[(1, 2, 3)] * 2, widths=[1.5] * 2)],
        "lane": [
            rr.StateConfiguration(
                values=["p", "q"], labels=["P", "Q"], colors=np.array([1, 2], np.uint32)
            )
        ],
        "report": [rr.TextDocument("# title\n| a | b |", media_type=rr.MediaType.MARKDOWN)],
        "bars": [chart],
        # The bar chart's values replaced, its abscissa, widths and colour shared.
        "bars2": [
            rr.BarChart.from_fields(values=np.arange(72.0)),
            [b for b in chart.as_component_batches() if b.component_descriptor() != values],
        ],
    }
    fast = {
        **{path: static_chunk(path, row_columns(*parts)) for path, parts in entities.items()},
        "bars2": static_chunk("bars2", (column(values, tensor_f64(np.arange(72.0))), *shared)),
    }
    paths = []
    for name, send in (
        ("log", lambda s: [s.log(p, *parts, static=True) for p, parts in entities.items()]),
        ("chunks", lambda s: s.send_chunks(list(fast.values()))),
    ):
        paths.append(written(tmp_path / f"{name}.rrd", f"static-{name}", send))
    expected, got = (
        {k: v for k, v in store_contents(p).items() if k[0] != "/__properties"} for p in paths
    )
    assert {e for e, _, _ in expected} == {f"/{p}" for p in entities}
    assert all(is_static for _, _, is_static in expected)
    # "bars2" differs from "bars" in its values only, by construction.
    assert (
        expected[("/bars2", "BarChart:values", True)]
        != expected[("/bars", "BarChart:values", True)]
    )
    assert got == expected


@pytest.mark.parametrize("width", [1, 3])
def test_direct_columns_store_what_send_columns_stores(tmp_path, width):
    """Sample chunks built from numpy (``arrow_chunks``) equal ``send_columns``' rows."""
    rng = np.random.default_rng(width)
    n = 257
    values = rng.normal(size=(n, width)) if width > 1 else rng.normal(size=n)
    ns = np.cumsum(rng.integers(1, 10_000_000, size=n))
    seq = rng.integers(0, 360_000, size=n)  # unsorted, as the wheel angle
    plain_index = [
        rr.TimeColumn("time", duration=ns.astype("timedelta64[ns]")),
        rr.TimeColumn("angle", sequence=seq),
    ]
    direct_index = [duration_index("time", ns), sequence_index("angle", seq)]
    for plain, direct in zip(plain_index, direct_index, strict=True):
        assert direct.as_arrow_array().equals(plain.as_arrow_array())
    (plain_column,) = rr.Scalars.columns(scalars=values)
    direct_column = scalars_column(values)
    assert direct_column.as_arrow_array().equals(plain_column.as_arrow_array())
    assert direct_column.component_descriptor() == plain_column.component_descriptor()
    batches = []
    for name, send in (
        ("plain", lambda s: s.send_columns("e", plain_index, rr.Scalars.columns(scalars=values))),
        (
            "direct",
            lambda s: s.send_chunks([Chunk.from_columns("e", direct_index, [direct_column])]),
        ),
    ):
        path = written(tmp_path / f"{name}.rrd", f"columns-{name}", send)
        (chunk,) = read_store(path)["/e"]
        batches.append(chunk.to_record_batch().drop_columns(["rerun.controls.RowId"]))
    assert batches[1].schema == batches[0].schema
    assert batches[1].equals(batches[0])
    # Both as written (the reader may reorder rows: compare in the order of time).
    order = np.argsort(batches[1].column("time").cast("int64").to_numpy())
    stored = np.array(batches[1].column("Scalars:scalars").to_pylist())[order]
    np.testing.assert_array_equal(stored.reshape(values.shape), values)


@pytest.mark.parametrize("size", [1, 5, 72])
def test_tensor_f64_is_rerun_tensor_data(size):
    values = np.random.default_rng(size).normal(size=size)
    expected = rr.components.TensorDataBatch(values).as_arrow_array()
    got = tensor_f64(values)
    got.validate(full=True)
    assert got.type == expected.type and got.equals(expected)
    assert got.to_pylist()[0]["buffer"] == values.tolist()


def without_ids(contents):
    """Blueprint contents with the random view, container and visualizer ids blanked."""
    uuid = re.compile(r"[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}")
    raw_id = re.compile(r"\[(\d+, ){15}\d+\]")  # a 16-byte id as a list of ints
    return sorted(
        (uuid.sub("<id>", repr(key)), raw_id.sub("<id>", uuid.sub("<id>", repr(value))))
        for key, value in contents.items()
    )


@pytest.mark.parametrize("extra_sets", [(), ("after",)])
def test_session_file_blueprint_is_what_send_blueprint_sends(session, tmp_path, extra_sets):
    """A file's blueprint (cached layout, per-file ranges) equals Rerun's own send_blueprint."""
    recording, window, result = session
    path = tmp_path / "s.rrd"
    with session_rrd(path, judged(result, recording, window)) as rrd:
        for name in extra_sets:
            rrd.log_residuals(name, result.time_s, result.residual_mps2, wheel_angle_rad(result))
        layout = rrd.layout()
    assert [s[0] for s in layout.residual_sets] == ["fit", *extra_sets]
    blueprint = reference_blueprint(layout, (window.start_s, window.end_s))
    reference = written(
        tmp_path / "reference.rrd", "bp-reference", lambda s: s.send_blueprint(blueprint)
    )
    got = blueprint_contents(path)
    x_range = {k: got.pop(k) for k in list(got) if k[0] == f"/{GLOBAL_VIEW_PATH}"}
    assert list(x_range) == [(f"/{GLOBAL_VIEW_PATH}", "TimeAxis:view_range", False)]
    got, expected = (without_ids(c) for c in (got, blueprint_contents(reference)))
    assert len(expected) > 120  # ≈ 55 entities, every component
    assert got == expected


@pytest.mark.parametrize(
    "window_s, shown_s", [((1.5, 80.25), (-0.5, 99.5)), ((0.0, 1e-9), (3.0, 4e4))]
)
def test_per_file_chunks_are_the_converted_parts(window_s, shown_s):
    """The time panel and x-range built from templates equal Rerun's own conversion."""
    fast = [(c.entity_path, c.to_record_batch()) for c in per_file_chunks(window_s, shown_s)]
    slow = [
        (c.entity_path, c.to_record_batch())
        for c in blueprint_chunks(time_panel(*window_s), GlobalTimeAxis(*shown_s))
    ]
    assert len(fast) == len(slow) == 3  # the time panel is a static and a timed row
    for (path_a, a), (path_b, b) in zip(fast, slow, strict=True):
        assert path_a == path_b
        a, b = (x.drop_columns(["rerun.controls.RowId"]) for x in (a, b))
        assert a.schema == b.schema and a.equals(b)


def test_each_file_gets_its_own_time_selection_and_range(session, tmp_path):
    """The layout is cached per process; the window selection and the x-range are not."""
    import dataclasses

    recording, window, result = session
    write_session_rrd(tmp_path / "a.rrd", judged(result, recording, window))
    shorter = recording.window(0.0, window.end_s + 1.0)
    write_session_rrd(tmp_path / "b.rrd", judged(result, shorter, None))
    del dataclasses
    for name, (start, end), last in (
        ("a", (window.start_s, window.end_s), recording.time_s[-1]),
        ("b", (result.time_s[0], result.time_s[-1]), shorter.time_s[-1]),
    ):
        path = tmp_path / f"{name}.rrd"
        (selection,) = blueprint_component(path, "TimePanelBlueprint:time_selection")
        assert selection[0] == {"min": round(start * 1e9), "max": round(end * 1e9)}
        _, end_boundary = range_boundaries(path)
        assert end_boundary == ("Absolute", round((last + TIME_MARGIN_S) * 1e9))
    assert blueprint_views(tmp_path / "a.rrd") == blueprint_views(tmp_path / "b.rrd")


def test_window_none_marks_the_fitted_span(session, tmp_path):
    recording, _, result = session
    path = write_session_rrd(tmp_path / "given.rrd", judged(result, recording, None))
    chunks = read_store(path)
    t_ns, states = temporal(chunks, "/window", "StateChange:state", "time")
    assert states[1] == ["free spin"]
    assert t_ns[1] == round(result.time_s[0] * 1e9) and t_ns[2] == round(result.time_s[-1] * 1e9)
    assert "window given" in static(chunks, "/verdict", "TextDocument:text")[0]


def test_more_residual_sets(session, tmp_path):
    recording, window, result = session
    path = tmp_path / "loop.rrd"
    theta = wheel_angle_rad(result)
    after = result.residual_mps2 * 0.5
    with session_rrd(path, judged(result, recording, window)) as rrd:
        rrd.log_residuals("after", result.time_s, after, theta, label="half")
        assert rrd.residual_set_names == ["fit", "after"]
        assert not path.exists()  # written when the block ends
    chunks = read_store(path)
    _, values = xyz(chunks, "/residual/after")
    np.testing.assert_array_equal(values, after)
    assert "/residual_angle_mean/y/after" in chunks
    assert f"/residual_angle_mean/y/{BAND_ENTITY}" in chunks  # the calibration's set only
    assert not any(e.startswith("/residual_angle_mean/y/after/") for e in chunks)
    # The blueprint, written last, draws the new set in the per-axis views, with a legend.
    props = view_properties(path)["y: residual, data − model (m/s²); lines: ±2σ noise"]
    assert overrides_of(props) == {
        ("/residual/fit", ("data − model",), ".y"),
        ("/residual/after", ("half",), ".y"),
    }
    assert "PlotLegend" not in props  # shown (Rerun's default)


def test_extra_views_join_the_layout(session, tmp_path):
    """A logging function (e.g. the rests' Allan deviation) registers its view."""
    recording, window, result = session
    path = tmp_path / "allan.rrd"
    with session_rrd(path, judged(result, recording, window)) as rrd:
        rrd.stream.log("allan/x", rr.BarChart([1.0, 0.5, 0.3]), static=True)
        rrd.add_view("bar_chart", "/allan", "Allan deviation of the rests")
        with pytest.raises(ValueError, match="view kind"):
            rrd.add_view("pie", "/allan", "no such view")
    assert ("BarChart", "Allan deviation of the rests", "/allan") in blueprint_views(path)
    assert ("BarChart", "Allan deviation of the rests", "/allan") not in blueprint_views(
        write_session_rrd(tmp_path / "plain.rrd", judged(result, recording, window))
    )


# ---------------------------------------------------------------- no partial files


def test_exception_while_writing_leaves_no_file(session, tmp_path):
    recording, window, result = session
    path = tmp_path / "broken.rrd"
    with pytest.raises(RuntimeError, match="boom"):
        with session_rrd(path, judged(result, recording, window)):
            raise RuntimeError("boom")
    assert not path.exists() and no_leftovers(tmp_path)


def test_bad_data_leaves_no_file_and_keeps_the_old_one(session, tmp_path):
    recording, window, result = session
    path = tmp_path / "s.rrd"
    path.write_bytes(b"previous")
    with pytest.raises(ValueError, match="residual set 'after'"):
        with session_rrd(path, judged(result, recording, window)) as rrd:
            rrd.log_residuals("after", result.time_s, result.residual_mps2[:-1], np.zeros(3))
    with pytest.raises(ValueError, match="already"):
        with session_rrd(path, judged(result, recording, window)) as rrd:
            rrd.log_residuals("fit", result.time_s, result.residual_mps2, wheel_angle_rad(result))
    assert path.read_bytes() == b"previous" and no_leftovers(tmp_path)


def test_rerun_misuse_raises_instead_of_warning(session, tmp_path):
    """Strict mode inside the writer: a bad Rerun call aborts the file."""
    recording, window, result = session
    path = tmp_path / "misuse.rrd"
    with pytest.raises(ValueError):
        with session_rrd(path, judged(result, recording, window)) as rrd:
            rrd.stream.log("oops", rr.Scalars(["not a number"]))
    assert not path.exists() and no_leftovers(tmp_path)
    assert not rr.strict_mode()  # only inside the writer


@pytest.mark.filterwarnings("ignore:wheelcal .rrd writer:rerun.error_utils.RerunWarning")
def test_an_exception_after_a_rerun_warning_still_leaves_no_file(session, tmp_path):
    """A Rerun warning inside ``stream.log`` must not switch the writer's strict mode off.

    rerun-sdk 0.41's ``RecordingStream.log`` passes ``strict=None`` down, and the
    warning it then logs re-enters the same decorator, which restores the wrong
    strict setting: afterwards the writer's guard swallowed any exception of the
    block (a warning instead) and wrote the file.
    """
    recording, window, result = session
    path = tmp_path / "warned.rrd"
    style = rr.SeriesLines(names=["a"])
    with pytest.raises(RuntimeError, match="boom"):
        with session_rrd(path, judged(result, recording, window)) as rrd:
            with pytest.warns(rr.error_utils.RerunWarning, match="multiple times"):
                rrd.stream.log("dup", style, style, static=True)  # a component twice
            raise RuntimeError("boom")
    assert not path.exists() and no_leftovers(tmp_path)


def test_an_unfinished_file_is_an_error(session, tmp_path, monkeypatch):
    """The file sink writes on Rerun's thread; a file without the stream footer is refused."""
    recording, window, result = session
    path = tmp_path / "cut.rrd"
    path.write_bytes(b"previous")
    # A sink that stops short of the footer, as a failed write on Rerun's thread would.
    monkeypatch.setattr(rr, "FileSink", lambda p: rr_file_sink(p, write_footer=False))
    with pytest.raises(RrdWriteError, match="no stream footer"):
        write_session_rrd(path, judged(result, recording, window))
    assert path.read_bytes() == b"previous" and no_leftovers(tmp_path)


def test_rerun_verifies_the_session_file(session_file):
    """Rerun's own loader (``rerun rrd verify``, as the viewer loads a file) accepts it."""
    path, _ = session_file
    cli = Path(sys.executable).parent / "rerun"
    if not cli.exists():
        pytest.skip("the rerun command of rerun-sdk is not installed next to this Python")
    out = subprocess.run([cli, "rrd", "verify", path], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "1 file verified without error" in out.stdout + out.stderr  # "0 files" for junk


def test_a_written_file_ends_with_the_stream_footer(session_file):
    path, _ = session_file
    assert path.read_bytes()[-12:-4] == b"RRF2FOOT"
    assert no_leftovers(path.parent)


def test_rerun_disabled_is_an_error(session, tmp_path, monkeypatch):
    recording, window, result = session
    monkeypatch.setenv("RERUN", "off")
    with pytest.raises(RrdWriteError, match="RERUN=off"):
        write_session_rrd(tmp_path / "off.rrd", judged(result, recording, window))
    assert not (tmp_path / "off.rrd").exists()


def test_importing_viz_does_not_import_rerun():
    code = "import sys, wheelcal.viz; print('rerun' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_calibrate_session_writes_the_rrd(session, tmp_path):
    """The batch/CLI pipeline writes ``<out>/<stem>.rrd`` of the computed session."""
    from wheelcal.batch.session import calibrate_session
    from wheelcal.io import write_recording
    from wheelcal.session.compute import SessionOptions

    recording, _, _ = session
    mcap = tmp_path / "bench1.mcap"
    write_recording(recording, mcap)
    outcome = calibrate_session(mcap, SessionOptions(rrd=True), tmp_path / "out")
    assert outcome.ok, outcome.error
    assert outcome.rrd_path == str(tmp_path / "out" / "bench1.rrd")
    chunks = read_store(outcome.rrd_path)
    _, values = xyz(chunks, "/residual/fit")
    np.testing.assert_array_equal(values, outcome.result.residual_mps2)
    # No closed loop ran: no before/after tab.
    assert not any(e.startswith("/closed_loop") for e in chunks)
    assert "closed loop" not in {name for _, name, _ in blueprint_views(outcome.rrd_path)}


@pytest.fixture(scope="module")
def diagnosed(tmp_path_factory):
    """``wheelcal diagnose --rrd`` on a session with an imbalance nobody declared."""
    import dataclasses
    import json

    from wheelcal.cli.main import main
    from wheelcal.io import write_recording
    from wheelcal.simulate import table1
    from wheelcal.simulate.motion import ImbalancedSpin

    scenario = table1()
    motion = ImbalancedSpin(scenario.truth.spin, 0.15 * np.cos(0.7), 0.15 * np.sin(0.7))
    scenario = dataclasses.replace(scenario, motion=motion)
    recording = simulate_session(scenario, np.random.default_rng(31)).recording
    folder = tmp_path_factory.mktemp("diagnose")
    write_recording(recording, folder / "imbalance.mcap")
    assert main(["diagnose", str(folder / "imbalance.mcap"), "--out", str(folder), "--rrd"]) == 0
    report = json.loads((folder / "imbalance.diagnosis.json").read_text())
    return folder / "imbalance.rrd", report


def test_diagnose_shows_the_effects_added_before_and_after(diagnosed):
    path, report = diagnosed
    assert [step["effect"] for step in report["steps"]] == ["imbalance"]
    chunks = read_store(path)
    text = static(chunks, "/closed_loop/report", "TextDocument:text")[0]
    assert "**imbalance** (`imbalance`)" in text
    step = report["steps"][0]
    assert f"| {step['statistic']:.4g} | {step['dof']} | {step['p_corrected']:.2g} |" in text
    # Parameters before (the paper's model) and after, as the diagnosis JSON has them.
    before, after = report["base"]["parameters"], report["final"]["parameters"]
    for name in ("gain_y", "tilt_deg", "offset_y_mps2"):
        b, a = before[name]["value"], after[name]["value"]
        shift = (b - a) / after[name]["std"]
        assert f"| `{name}` | {b:.7g} | {a:.7g} | {after[name]['std']:.2g} | {shift:.2g} |" in text
        assert abs(shift) > 3  # the imbalance biased the paper's model
    assert "`imbalance.sin_radps2` (added)" in text
    # The residual folded on ϑ: the paper's model leaves a pattern that the final removes,
    # each beside the other with the ±2σ band of its bin means.
    spread = {}
    for name in ("paper_model", "with_effects"):
        bars = [
            static(chunks, f"/closed_loop/{name}/{a}/mean", "BarChart:values")[0]["buffer"]
            for a in "xyz"
        ]
        band = [
            static(chunks, f"/closed_loop/{name}/{a}/{BAND_ENTITY}", "BarChart:values")[0]
            for a in "xyz"
        ]
        assert all(len(b["buffer"]) == 2 * ANGLE_BINS for b in band)
        spread[name] = float(np.sqrt(np.mean(np.square(bars))))
    assert spread["paper_model"] > 1.3 * spread["with_effects"]
    # An imbalance repeats every turn: no trend column (it drew two identical lines)
    assert not any(e.startswith("/closed_loop/trend") for e in chunks)
    # And the tab is in the blueprint: before and after side by side, per axis.
    views = blueprint_views(path)
    assert ("TextDocument", "closed loop: what it added", "/closed_loop/report") in views
    for a in "xyz":
        for name, label in (("paper_model", "paper's model"), ("with_effects", "with effects")):
            title = f"{a}: {label} — residual per 5° of ϑ; grey: ±2σ of noise"
            assert ("BarChart", title, f"/closed_loop/{name}/{a}") in views


# ---------------------------------------------------------------- batch file


@pytest.fixture(scope="module")
def batch_sessions(session):
    """Five calibration dictionaries: two sensors, perturbed values, one undetermined σ."""
    recording, window, result = session
    base = calibration_dict(judged(result, recording, window))
    sessions = []
    for i in range(5):
        d = copy.deepcopy(base)
        d["source"]["file"] = f"run{i}.mcap"
        d["source"]["sensor_id"] = "imu A" if i % 2 else "imu/B"
        d["source"]["mounting_id"] = "" if i % 2 else "m1"
        d["parameters"]["gain_x"]["value"] += 1e-4 * i
        sessions.append(d)
    sessions[3]["parameters"]["tilt_deg"]["std"] = None  # ∞ σ → JSON null
    return sessions


def group_path(sensor, mounting):
    parts = [rr.escape_entity_path_part(p or "unspecified") for p in (sensor, mounting)]
    return "/batch/" + "/".join(parts)


def test_batch_one_point_per_session(batch_sessions, tmp_path):
    path = write_batch_rrd(tmp_path / "batch.rrd", batch_sessions)
    chunks = read_store(path)
    # Numbered from 1, as report.md and the files number them.
    for sensor, mounting, members in (("imu A", "", [2, 4]), ("imu/B", "m1", [1, 3, 5])):
        base = group_path(sensor, mounting)
        for name in ("gain_x", "offset_y_mps2", "tilt_deg"):
            index, values = temporal(chunks, f"{base}/{name}/value", "Scalars:scalars", "session")
            assert index.tolist() == members
            expected = [batch_sessions[i - 1]["parameters"][name]["value"] for i in members]
            assert [v[0] for v in values] == expected
            index, band = temporal(chunks, f"{base}/{name}/band", "Scalars:scalars", "session")
            for i, (lo, hi) in zip(index, band, strict=True):
                p = batch_sessions[i - 1]["parameters"][name]
                assert lo == pytest.approx(p["value"] - p["std"], rel=1e-15)
                assert hi == pytest.approx(p["value"] + p["std"], rel=1e-15)
    # The session with an undetermined σ has a point but no band.
    base = group_path("imu A", "")
    index, _ = temporal(chunks, f"{base}/tilt_deg/band", "Scalars:scalars", "session")
    assert index.tolist() == [2]
    # Legends name what is drawn; the two band lines share one entry.
    gain = group_path("imu/B", "m1") + "/gain_x"
    assert static(chunks, f"{gain}/value", "SeriesPoints:names") == ["estimate ± σ"]
    assert static(chunks, f"{gain}/band", "SeriesLines:names") == ["±σ", "±σ"]
    # Without a batch's report (no pooled sensor): the value to apply is the group mean.
    assert static(chunks, f"{gain}/applied", "SeriesLines:names") == ["the group mean"]


def test_batch_numbers_as_given(batch_sessions, tmp_path):
    """The runner passes report.md's numbers (a failed session 3 leaves a gap)."""
    path = write_batch_rrd(tmp_path / "batch.rrd", batch_sessions, numbers=[1, 2, 4, 5, 6])
    chunks = read_store(path)
    index, _ = temporal(
        chunks, group_path("imu A", "") + "/gain_x/value", "Scalars:scalars", "session"
    )
    assert index.tolist() == [2, 5]
    assert (
        "| 4 |  | `run2.mcap` | imu/B / m1 |" in static(chunks, "/report", "TextDocument:text")[0]
    )
    with pytest.raises(ValueError, match="one distinct number per session"):
        write_batch_rrd(tmp_path / "b.rrd", batch_sessions, numbers=[1, 1, 2, 3, 4])


def test_batch_reports_and_blueprint(batch_sessions, tmp_path):
    path = write_batch_rrd(tmp_path / "batch.rrd", batch_sessions)
    chunks = read_store(path)
    overview = static(chunks, "/report", "TextDocument:text")[0]
    assert "| 4 |  | `run3.mcap` | imu A / unspecified |" in overview
    group = static(chunks, group_path("imu/B", "m1") + "/report", "TextDocument:text")[0]
    assert "3 sessions: 1, 3, 5" in group
    gains = [batch_sessions[i]["parameters"]["gain_x"]["value"] for i in (0, 2, 4)]
    # without a batch report (no pooled sensor) the value to apply is the group mean ± std/√n
    std = np.std(gains, ddof=1)
    assert f"| gain_x | {np.mean(gains):.6g}ᵍ ± {std / np.sqrt(3):.2g} |" in group
    row = next(line for line in group.splitlines() if line.startswith("| gain_x |"))
    assert row.split("|")[4].strip() == f"{std:.2g}"
    # The spin's parameters: per session by nature, mean and std, no ratio.
    omega = [batch_sessions[i]["parameters"]["omega0_radps"]["value"] for i in (0, 2, 4)]
    spin_row = f"| `omega0_radps` | {np.mean(omega):.7g} | {np.std(omega, ddof=1):.2g} |"
    assert spin_row + "\n" in group  # the row ends there: no predicted std, no ratio
    assert group.index("Per session by nature") < group.index(spin_row)
    views = blueprint_views(path)
    assert ("TimeSeries", "gain_x", group_path("imu/B", "m1") + "/gain_x") in views
    spin_view = (
        "TimeSeries",
        "omega0_radps (per session)",
        group_path("imu/B", "m1") + "/omega0_radps",
    )
    assert spin_view in views
    assert blueprint_component(path, "TimePanelBlueprint:timeline") == [["session"]]
    paused = [[rrb.components.PlayState.Paused.value]]
    assert blueprint_component(path, "TimePanelBlueprint:play_state") == paused
    props = view_properties(path)
    assert props["gain_x"]["PlotLegend"]["PlotLegend:visible"] == [[False]]  # the report says
    linked = rrb.components.LinkAxis.LinkToGlobal.value
    assert props["gain_x"]["TimeAxis"]["TimeAxis:link"] == [[linked]]
    # Every session on the shared x-axis, one session of room either side.
    assert range_boundaries(path) == [("Absolute", 0), ("Absolute", 6)]
    # The tabs: the overview, and per group its parameters and its spins.
    names = blueprint_component(path, "ContainerBlueprint:display_name")
    assert ["imu/B / m1"] in names and ["imu/B / m1: spin (per session)"] in names
    # Each tab shows the group's report beside its plots (a view of its own in each).
    report = ("TextDocument", "repeatability", group_path("imu/B", "m1") + "/report")
    assert views.count(report) == 2
    assert RrdReader(path).recordings()[0].application_id == "wheelcal_batch"


def test_batch_bad_input(batch_sessions, tmp_path):
    with pytest.raises(ValueError, match="no sessions"):
        write_batch_rrd(tmp_path / "empty.rrd", [])
    broken = [batch_sessions[0], {"source": {"file": "x"}}]
    with pytest.raises(ValueError, match="session 1"):
        write_batch_rrd(tmp_path / "broken.rrd", broken)
    assert os.listdir(tmp_path) == []


def test_a_gyro_session_shows_measured_and_modelled_omega(tmp_path):
    # A motor-driven wheel through the gyro-aided fit: the .rrd carries ω of the
    # model (cubic + spline) and ω as the gyro measures it; they agree to the gyro's
    # noise, while the driven motion is far from any cubic.
    from wheelcal.session.fit import SessionFit
    from wheelcal.simulate import hostile
    from wheelcal.simulate.gyro import GyroSpec

    session = hostile.wandering(np.random.default_rng(300), gyro=GyroSpec())
    out = SessionFit(gyro="on").run(session.recording)
    path = write_session_rrd(tmp_path / "gyro.rrd", out)
    chunks = read_store(path)
    t_model, model = temporal(chunks, "/spin/omega_radps", "Scalars:scalars", "time")
    t_gyro, gyro = temporal(chunks, "/spin/omega_measured_radps", "Scalars:scalars", "time")
    assert static(chunks, "/spin/omega_measured_radps", "SeriesLines:names") == ["measured: gyro"]
    model = np.interp(t_gyro, t_model, np.array(model)[:, 0])
    gyro = np.array(gyro)[:, 0]
    assert t_gyro.size > 100
    assert np.sqrt(np.mean((gyro - model) ** 2)) < 0.01  # rad/s: the gyro's noise, ~2e-3
    assert np.ptp(model) > 0.5  # the motor's ±5 % of 10 rad/s is in the modelled ω


def test_the_session_writer_uses_the_sessions_gyro_calibration(tmp_path):
    """The measured ω is the gyro calibrated by the session's own gyro block."""
    import dataclasses

    from wheelcal.session.fit import SessionFit
    from wheelcal.simulate import hostile
    from wheelcal.simulate.gyro import GyroSpec
    from wheelcal.viz import write_session_rrd as _write_rrd

    session = hostile.wandering(np.random.default_rng(300), gyro=GyroSpec())
    out = SessionFit(gyro="on").run(session.recording)
    assert out.gyro is not None
    without = dataclasses.replace(out, assessment=dataclasses.replace(out.assessment, gyro=None))
    label = "SeriesLines:names"
    for name, judged_session, expected in (
        ("without", without, "measured: gyro (uncalibrated)"),
        ("with", out, "measured: gyro"),
    ):
        path = _write_rrd(tmp_path / f"{name}.rrd", judged_session)
        assert static(read_store(path), "/spin/omega_measured_radps", label) == [expected]
