"""What a batch hands a person: the per-sensor calibration, report.md, sessions.csv, the PNG.

The bundled pipeline (pipelines/table2-repeatability.toml: ten Table II
sessions, quantised to ±4 g so that some clip) runs once for the module,
without the .rrd files; the numbers are checked against the session files and
the recordings, never against the report itself.
"""

import builtins
import csv
import dataclasses
import io
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from wheelcal.batch.pipeline import load_pipeline
from wheelcal.batch.report import build_report, report_markdown, sessions_csv
from wheelcal.batch.runner import ProgressEvent, run_batch
from wheelcal.calibration import SessionOutcome
from wheelcal.calibration.sensor_json import session_estimate
from wheelcal.cli.main import main
from wheelcal.cli.progress import BatchProgress
from wheelcal.closedloop.pooling import POOLED_PARAMETERS, pool_sessions
from wheelcal.io import read_recording
from wheelcal.viz import batch_png

ROOT = Path(__file__).resolve().parents[1]
SENSOR = "mpu9250-A"


@pytest.fixture(scope="module")
def bundled(tmp_path_factory):
    """The README's main command, into a temporary folder (no .rrd: not checked here)."""
    out = tmp_path_factory.mktemp("bundled") / "out"
    pipeline = load_pipeline(ROOT / "pipelines" / "table2-repeatability.toml")
    pipeline = dataclasses.replace(
        pipeline,
        output=out,
        rerun=False,
        options=dataclasses.replace(pipeline.options, rrd=False),
        executor=dataclasses.replace(pipeline.executor, workers=2),
    )
    outcome = run_batch(pipeline)
    assert not outcome.failed
    sessions = [json.loads(Path(r.calibration_path).read_text()) for r in outcome.records]
    return out, outcome, sessions


def _raw_samples(path: str) -> int:
    """Messages on the accelerometer channel (one Imu sample each), from the MCAP summary."""
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    return sum(summary.statistics.channel_message_counts.values())


def test_one_calibration_per_sensor_pooled_from_the_session_files(bundled):
    out, outcome, sessions = bundled
    doc = json.loads((out / "sensors" / f"{SENSOR}.calibration.json").read_text())
    assert doc["format"] == "wheelcal.sensor_calibration/1" and doc["sensor_id"] == SENSOR
    assert doc["pooling"]["method"] == "precision_weighted_mean"  # no closure: no joint fit
    assert doc["pooling"]["sessions"] == 10 and len(doc["sessions"]) == 10
    assert [s["calibration"] for s in doc["sessions"]] == [
        r.calibration_path for r in outcome.records
    ]
    # The same numbers as pooling the session files directly.
    pooled = pool_sessions([session_estimate(s) for s in sessions])
    assert doc["sensor"]["gain"] == pooled.value[:3].tolist()
    assert doc["sensor"]["offset_std_mps2"] == pooled.std[3:].tolist()
    # Statistical σ ~ 1/√10 of a session's; the systematic σ is the sessions', not divided.
    session_std = np.array([s["sensor"]["gain_std"] for s in sessions])
    assert np.all(np.array(doc["sensor"]["gain_std"]) < session_std.mean(axis=0) / 2)
    session_sys = np.array([s["systematic"]["gain_std"] for s in sessions])
    np.testing.assert_allclose(doc["systematic"]["gain_std"], session_sys.mean(axis=0), rtol=0.05)
    # The correction is the contract's: a = M (v − b) with b = o, M = Γ⁻¹.
    np.testing.assert_allclose(doc["correction"]["bias_mps2"], doc["sensor"]["offset_mps2"])
    np.testing.assert_allclose(np.diag(doc["correction"]["matrix"]), 1 / pooled.value[:3])
    assert set(doc["parameters"]) == set(POOLED_PARAMETERS)


def test_export_and_apply_accept_the_sensor_calibration(bundled, tmp_path):
    out, _, sessions = bundled
    cal = out / "sensors" / f"{SENSOR}.calibration.json"
    doc = json.loads(cal.read_text())
    y = tmp_path / "imu.yaml"
    assert main(["export", str(cal), "--format", "yaml", "--out", str(y)]) == 0
    text = y.read_text()
    assert f"sensor {SENSOR}, pooled from 10 sessions" in text
    acc = yaml.safe_load(text)["imu0"]["accelerometer"]
    assert acc["bias_mps2"] == doc["correction"]["bias_mps2"]  # shortest round-trip floats
    assert acc["matrix"] == doc["correction"]["matrix"]
    header = tmp_path / "cal.h"
    assert main(["export", str(cal), "--format", "c", "--out", str(header)]) == 0
    assert "WHEELCAL_ACCEL_MATRIX" in header.read_text()
    source = sessions[0]["source"]["file"]
    copy = tmp_path / "calibrated.mcap"
    assert main(["apply", str(cal), source, str(copy)]) == 0
    raw = read_recording(source)
    corrected = read_recording(copy, topic="/imu/data_raw/calibrated")
    expected = (raw.accel_mps2 - doc["correction"]["bias_mps2"]) @ np.array(
        doc["correction"]["matrix"]
    ).T
    np.testing.assert_allclose(corrected.accel_mps2, expected, atol=1e-9)


def test_report_md_opens_with_apply_this_and_shows_clipping_and_the_png(bundled):
    out, _, sessions = bundled
    md = (out / "report.md").read_text()
    lines = md.splitlines()
    assert lines[0] == "# Repeatability report — table2-repeatability"
    assert lines[2] == "10 sessions: 10 calibrated, 0 failed."
    assert lines[4] == f"## Apply this — sensor `{SENSOR}`"
    cal = out / "sensors" / f"{SENSOR}.calibration.json"
    assert f"`wheelcal export {cal} --format yaml`" in md
    doc = json.loads(cal.read_text())
    row_x = next(line for line in lines if line.startswith("| x | "))
    cells = [c.strip() for c in row_x.strip("|").split("|")]
    # bias to the 2nd digit of its σ, the matrix row, the gain, statistical and systematic σ
    assert float(cells[1]) == pytest.approx(doc["correction"]["bias_mps2"][0], abs=1e-4)
    assert cells[3] == f"{doc['systematic']['offset_std_mps2'][0]:.2g}"
    assert float(cells[4].strip("[]").split(",")[0]) == pytest.approx(
        doc["correction"]["matrix"][0][0], abs=1e-6
    )
    assert md.index("## Apply this") < md.index("## Sessions") < md.index("## sensor `")
    assert "](overview.png)" in md
    png = (out / "overview.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    # Every session that clips says so in its row (and only those).
    rows = {line.split("|")[2].strip(" `"): line for line in lines if line.startswith("| ")}
    clipping = 0
    for s in sessions:
        notes = [n for n in s["source"]["notes"] if "clipped samples" in n]
        row = rows[s["source"]["file"]]
        assert all(n in row for n in notes)
        assert ("clipped" in row) == bool(notes)
        clipping += bool(notes)
    assert 1 <= clipping < 10  # seed 2024: some sessions clip, some do not


def test_sessions_csv_counts_what_the_reader_dropped(bundled):
    out, _, sessions = bundled
    rows = list(csv.DictReader(io.StringIO((out / "sessions.csv").read_text())))
    assert len(rows) == 10
    for row, s in zip(rows, sessions, strict=True):
        assert row["file"] == s["source"]["file"] and row["status"] == "calibrated"
        # Independent count: samples in the file minus samples the reader kept.
        dropped = _raw_samples(row["file"]) - read_recording(row["file"]).samples
        assert int(row["dropped_samples"]) == dropped
        assert int(row["clipped_samples"]) == dropped  # table2 + quantiser: only clipping
        assert int(row["notes"]) == len(s["source"]["notes"])
        # Floats at their shortest faithful precision (window on the ns grid: 93.645, not …01).
        assert row["window_end_s"] == repr(round(float(row["window_end_s"]), 9))
    assert sum(int(r["clipped_samples"]) > 0 for r in rows) >= 1


def test_report_json_lists_the_sensor_file_and_the_overview(bundled):
    out, _, _ = bundled
    report = json.loads((out / "report.json").read_text())
    (sensor,) = report["sensors"]
    assert sensor["sensor_id"] == SENSOR and Path(sensor["file"]).exists()
    assert report["overview"] == {"file": "overview.png"}
    assert len(report["per_session"]) == 10
    outputs = set(report["provenance"]["outputs"])
    assert {str(out / "overview.png"), sensor["file"]} <= outputs


# --- failures, counts and stems ---------------------------------------------------------------


@pytest.fixture(scope="module")
def same_names(tmp_path_factory):
    """Two good recordings named s.mcap in different folders, a third s.mcap that is corrupt."""
    d = tmp_path_factory.mktemp("days")
    for day, seed in (("day1", 1), ("day2", 2)):
        (d / day).mkdir()
        args = ["simulate", str(d / day / "s.mcap"), "--seed", str(seed), "--free-spin-only"]
        assert main([*args, "--sensor-id", "S"]) == 0
    (d / "day3").mkdir()
    data = (d / "day1" / "s.mcap").read_bytes()
    (d / "day3" / "s.mcap").write_bytes(data[: len(data) // 3])
    return d


def _pipeline(tmp_path, inputs):
    path = tmp_path / "p.toml"
    path.write_text(
        f"[pipeline]\nname='days'\noutput='{tmp_path / 'out'}'\n"
        f"[inputs]\nglobs=['{inputs}/*/s.mcap']\n[defaults]\nradius_m=0.28\n"
        "[executor]\nworkers=1\n"
    )
    return path


def test_same_file_names_in_different_folders_get_stable_stems(tmp_path, same_names, capsys):
    path = _pipeline(tmp_path, same_names)
    assert main(["batch", str(path)]) == 1
    captured = capsys.readouterr()
    out = tmp_path / "out"
    assert sorted(p.name for p in out.glob("*.calibration.json")) == [
        "day1__s.calibration.json",
        "day2__s.calibration.json",
    ]
    # The summary and report.md agree; every failure line names the file once.
    md = (out / "report.md").read_text()
    assert "3 sessions: 2 calibrated, 1 failed" in captured.out
    assert "3 sessions: 2 calibrated, 1 failed." in md
    bad = str(same_names / "day3" / "s.mcap")
    for line in [*captured.err.splitlines(), *md.splitlines()]:
        assert line.count(bad) <= 1, line
    assert any(bad in line and "FAILED" in line for line in captured.err.splitlines())
    rows = list(csv.DictReader(io.StringIO((out / "sessions.csv").read_text())))
    assert [(r["stem"], r["status"]) for r in rows] == [
        ("day1__s", "calibrated"),
        ("day2__s", "calibrated"),
        ("day3__s", "failed"),
    ]
    # A re-run finds every output under the same stems: nothing is recomputed or rewritten.
    before = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    outcome = run_batch(load_pipeline(path))
    assert len(outcome.skipped) == 2 and not outcome.report_written
    assert {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()} == before


def test_a_refused_session_shows_its_gate_and_fix_once(tmp_path):
    failed = [
        {
            "file": "rec/a.mcap",
            "error": "rec/a.mcap: refused (gain_range): gain_x = 10.1",
            "gate": "gain_range",
            "fix": "check --radius (metres)",
        }
    ]
    per_session = [{**failed[0], "stem": "a", "status": "failed", "calibration": None}]
    report = build_report([], failed, per_session=per_session)
    md = report_markdown(report)
    row = next(line for line in md.splitlines() if line.startswith("| 1 |"))
    assert "refused (gain_range)" in row and "gain_x = 10.1" in row and row.count("rec/a.mcap") == 1
    line = next(line for line in md.splitlines() if line.startswith("- `rec/a.mcap`"))
    assert (
        line == "- `rec/a.mcap`: refused (gain_range): gain_x = 10.1 — fix: check --radius (metres)"
    )
    (row,) = list(csv.DictReader(io.StringIO(sessions_csv([], report["per_session"]))))
    assert (row["status"], row["gate"]) == ("failed", "gain_range")


def test_undetermined_parameters_and_warnings_reach_the_notes_and_the_pooling(bundled, tmp_path):
    """The trust work's additive keys (null values, sensor.undetermined, more warnings)."""
    _, _, sessions = bundled
    cals = json.loads(json.dumps(sessions[:3]))
    cals[1]["sensor"]["gain"][2] = cals[1]["sensor"]["gain_std"][2] = None
    cals[1]["sensor"]["undetermined"] = [{"parameter": "gain_z", "reason": "z along the axis"}]
    cals[1]["fit"]["warnings"] = ["residual 3.1× the noise floor"]
    report = build_report(cals, [])
    md = report_markdown(report)
    row = next(line for line in md.splitlines() if cals[1]["source"]["file"] in line)
    assert "undetermined: gain_z (z along the axis)" in row
    assert "⚠ residual 3.1× the noise floor" in row
    pooled = pool_sessions([session_estimate(c) for c in cals])
    assert pooled.used.tolist() == [3, 3, 2, 3, 3, 3]
    assert pooled.skipped == ((cals[1]["source"]["file"], "gain_z", "z along the axis"),)


# --- the PNG without matplotlib, and the progress line ------------------------------------------


def test_without_matplotlib_the_report_says_why_there_is_no_png(bundled, monkeypatch):
    _, _, sessions = bundled
    real_import = builtins.__import__

    def no_matplotlib(name, *args, **kwargs):
        if name.startswith("matplotlib"):
            raise ImportError("No module named 'matplotlib'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_matplotlib)
    png, note = batch_png.overview_png(sessions)
    assert png is None and "pip install 'wheelcal[plots]'" in note
    md = report_markdown({**build_report(sessions, []), "overview": {"file": None, "note": note}})
    assert f"Overview PNG not drawn: {note}." in md


def test_a_dense_batch_draws_each_residual_as_its_median_and_band(bundled):
    """Over DENSE_SESSIONS sessions: a band of the 5–95 % of the profiles, the median line."""
    from matplotlib.figure import Figure

    _, _, sessions = bundled
    rng = np.random.default_rng(7)
    centres = np.arange(5.0, 360.0, 10.0)
    curves = [
        np.column_stack([centres, rng.normal(0.0, 1e-3, centres.size)])
        for _ in range(batch_png.DENSE_SESSIONS + 1)
    ]
    ax = Figure().subplots()
    assert batch_png._band(ax, curves, "C0")
    values = np.stack([c[:, 1] for c in curves])
    (line,) = ax.get_lines()
    np.testing.assert_allclose(line.get_ydata(), np.median(values, axis=0))
    (band,) = ax.collections
    y = band.get_paths()[0].vertices[:, 1]
    assert y.min() == pytest.approx(np.percentile(values, 5, axis=0).min())
    assert y.max() == pytest.approx(np.percentile(values, 95, axis=0).max())
    # profiles on other bins are not pooled into one band
    assert not batch_png._band(ax, [*curves, curves[0][:-1]], "C0")
    # the points: one bar per session from value − σ to value + σ
    ax = Figure().subplots()
    batch_png._dense_points(ax, [1, 2], [1.0, 2.0], [0.1, 0.3], "C0")
    segments = ax.collections[0].get_segments()
    np.testing.assert_allclose([s[:, 1] for s in segments], [[0.9, 1.1], [1.7, 2.3]])
    many = [sessions[0]] * (batch_png.DENSE_SESSIONS + 1)
    png, note = batch_png.overview_png(many)
    assert png is not None and png.startswith(b"\x89PNG"), note


@pytest.mark.parametrize("tty", [False, True])
def test_progress_lines_carry_the_notes(tty):
    stream = io.StringIO()
    stream.isatty = lambda: tty
    progress = BatchProgress(stream)
    clip = "dropped 570 clipped samples (2.9 %)"
    for i, (notes, error) in enumerate([((), None), ((clip,), None), ((), "x.mcap: truncated")]):
        record = SessionOutcome(source=f"r{i}.mcap", stem=f"r{i}", error=error, notes=notes)
        progress(ProgressEvent(i + 1, 3, record=record))
    text = stream.getvalue()
    assert f"[2/3] ok r1.mcap — {clip}" in text
    assert "[3/3] FAILED x.mcap: truncated" in text
    assert ("[1/3] ok r0.mcap" in text) is (not tty)  # a terminal shows the bar instead
    assert ("3/3 sessions, 1 failed" in text) is tty


def test_a_sensor_file_of_an_earlier_run_without_sessions_now_is_marked_stale(bundled, tmp_path):
    from wheelcal.batch.sensors import write_sensor_calibrations

    _, _, sessions = bundled
    old = tmp_path / "sensors" / "retired.calibration.json"
    old.parent.mkdir()
    old.write_text("{}")
    (made,) = write_sensor_calibrations(tmp_path, sessions)
    assert made.path == tmp_path / "sensors" / f"{SENSOR}.calibration.json"
    assert not old.exists() and (tmp_path / "sensors" / "retired.calibration.stale.json").exists()


def test_a_sensor_nobody_could_determine_an_axis_of_is_exported_only_as_partial(
    bundled, tmp_path, capsys
):
    from wheelcal.batch.sensors import write_sensor_calibrations

    _, _, sessions = bundled
    cals = json.loads(json.dumps(sessions[:3]))
    for c in cals:  # gain_z undetermined in every session (as the trust gates write it)
        c["sensor"]["gain"][2] = c["sensor"]["gain_std"][2] = None
        c["sensor"]["undetermined"] = [{"parameter": "gain_z", "reason": "z along the axis"}]
    (made,) = write_sensor_calibrations(tmp_path, cals)
    doc = made.doc
    assert doc["sensor"]["gain"][2] is None and doc["sensor"]["gain_std"][2] is None
    assert doc["sensor"]["undetermined"][0]["parameter"] == "gain_z"
    assert doc["correction"]["identity_axes"] == ["z"]
    assert doc["correction"]["matrix"][2] == [0.0, 0.0, 1.0]
    assert main(["export", str(made.path), "--format", "yaml"]) != 0
    assert "allow-partial" in capsys.readouterr().err
    assert main(["export", str(made.path), "--format", "yaml", "--allow-partial"]) == 0
    assert "PARTIAL: axis z" in capsys.readouterr().out
