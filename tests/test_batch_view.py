"""What a person reads off a batch's Rerun file (issue 39), read back with Rerun's reader.

* each parameter's plot carries the value to apply — the sensor's pooled calibration for
  its gains and offsets, with its ± σ — and rings the sessions to look at;
* the group table has σ sys, the ratio's p and ⚠ as ``report.json``; the sessions tab
  lists every session — status (refused ones too), clip share, window, effects, notes;
* angles are averaged as angles: Euler angles either side of ±180° and θ₀ either side of
  ±π give a mean near ±180° (not 0°) and a small std, in the file and in ``report.json``.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

from test_viz_rrd import batch_sessions, read_store, session, static, temporal  # noqa: F401
from wheelcal.batch.report import build_report
from wheelcal.calibration.angles import circular_mean, unwrapped
from wheelcal.calibration.sensor_json import sensor_calibration_dict, session_estimate
from wheelcal.closedloop.pooling import pool_sessions
from wheelcal.viz.batch_rrd import write_batch_rrd

GROUP = "/batch/imu\\/B/m1"  # sensor "imu/B" escaped, mounting "m1"


def _report(calibrations, failed=()):
    """``report.json`` as the runner builds it: sessions in order, a failed one among them."""
    per_session = [
        {"file": c["source"]["file"], "stem": None, "status": "calibrated", "calibration": None}
        for c in calibrations
    ]
    per_session += [{**f, "stem": None, "status": "failed", "calibration": None} for f in failed]
    report = build_report(calibrations, list(failed), per_session=per_session)
    by_sensor: dict[str, list] = {}
    for c in calibrations:
        by_sensor.setdefault(c["source"]["sensor_id"], []).append(c)
    sensors = []
    for sensor_id, members in by_sensor.items():
        pooled = pool_sessions([session_estimate(c) for c in members])
        doc = sensor_calibration_dict(sensor_id, pooled, members)
        sensors.append({"sensor_id": sensor_id, **doc, "sessions": len(members)})
    report["sensors"] = sensors
    return report


@pytest.fixture(scope="module")
def batch(batch_sessions, tmp_path_factory):  # noqa: F811
    """Five sessions of two sensors, one refused after them (number 6), one scattered gain."""
    calibrations = copy.deepcopy(batch_sessions)
    for i, c in enumerate(calibrations):  # imu/B (sessions 1, 3, 5): a gain that scatters
        if c["source"]["sensor_id"] == "imu/B":
            c["parameters"]["gain_y"]["value"] += 0.01 * i
            c["sensor"]["gain"][1] += 0.01 * i
    calibrations[2]["fit"]["warnings"] = ["the residual is 2.0× its noise floor"]
    calibrations[2]["source"]["notes"] = ["dropped 900 clipped samples (4.5 %) at the rails x"]
    failed = [{"file": "run5.mcap", "error": "run5.mcap: refused (unit): …", "gate": "unit"}]
    report = _report(calibrations, failed)
    path = tmp_path_factory.mktemp("batch") / "batch.rrd"
    write_batch_rrd(path, calibrations, [1, 2, 3, 4, 5], report)
    return calibrations, report, read_store(path)


def test_each_plot_carries_the_value_to_apply(batch):
    _, report, chunks = batch
    (sensor,) = [s for s in report["sensors"] if s["sensor_id"] == "imu/B"]
    value, std = sensor["sensor"]["gain"][0], sensor["sensor"]["gain_std"][0]
    index, line = temporal(chunks, f"{GROUP}/gain_x/applied", "Scalars:scalars", "session")
    assert index.tolist() == [1, 5] and [v[0] for v in line] == [value, value]
    _, band = temporal(chunks, f"{GROUP}/gain_x/applied_band", "Scalars:scalars", "session")
    assert band[0] == pytest.approx([value - std, value + std], rel=1e-15)
    names = static(chunks, f"{GROUP}/gain_x/applied", "SeriesLines:names")
    assert names == ["the sensor's pooled value"]


def test_the_group_table_has_sigma_sys_p_and_the_flag(batch):
    _, report, chunks = batch
    text = static(chunks, f"{GROUP}/report", "TextDocument:text")[0]
    (group,) = [g for g in report["groups"] if g["sensor_id"] == "imu/B"]
    stats = group["parameters"]["gain_y"]
    assert stats["ratio_p_value"] < 0.01  # a gain scattering 10 mm/m between sessions
    row = next(line for line in text.splitlines() if line.startswith("| gain_y |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2] == f"{group['systematic_std']['gain_y']:.2g}"  # σ sys
    assert cells[-1] == f"{stats['ratio_p_value']:.2g} ⚠"
    calm = next(line for line in text.splitlines() if line.startswith("| gain_x |"))
    assert "⚠" not in calm


def test_the_sessions_tab_lists_every_session_and_what_to_look_at(batch):
    calibrations, _, chunks = batch
    text = static(chunks, "/report", "TextDocument:text")[0]
    rows = {
        int(line.split("|")[1]): line
        for line in text.splitlines()
        if line.startswith("| ") and line.split("|")[1].strip().isdigit()
    }
    assert sorted(rows) == [1, 2, 3, 4, 5, 6]
    assert "refused (unit)" in rows[6] and "⚠ refused (unit)" in rows[6]
    assert "⚠ 1 warning" in rows[3] and "4.5 %" in rows[3]
    window = calibrations[0]["source"]["window_s"]
    assert f"{window[0]:.2f}–{window[1]:.2f}" in rows[1]
    assert "⚠" not in rows[2].split("|")[2]
    assert "⚠ 2 to look at: 3, 6" in text.splitlines()[0]
    # the plots ring the calibrated one of them
    index, _ = temporal(chunks, f"{GROUP}/gain_x/problem", "Scalars:scalars", "session")
    assert index.tolist() == [3]


def test_angles_are_averaged_as_angles(batch_sessions, tmp_path):  # noqa: F811
    calibrations = copy.deepcopy(batch_sessions)
    values = [179.9, -179.8, 179.7, -179.9, 179.95]
    thetas = [3.1, -3.12, 3.13, -3.1, 3.14]
    for c, v, t in zip(calibrations, values, thetas, strict=True):
        c["source"]["sensor_id"], c["source"]["mounting_id"] = "imu", "m"
        c["parameters"]["euler_1_deg"]["value"] = v
        c["parameters"]["theta0_rad"]["value"] = t
    report = _report(calibrations)
    stats = report["groups"][0]["parameters"]["euler_1_deg"]
    assert abs(abs(stats["mean"]) - 180.0) < 0.2 and stats["std"] < 0.2
    path = write_batch_rrd(tmp_path / "b.rrd", calibrations, report=report)
    chunks = read_store(path)
    _, plotted = temporal(chunks, "/batch/imu/m/euler_1_deg/value", "Scalars:scalars", "session")
    assert np.ptp([v[0] for v in plotted]) < 0.6  # unwrapped about ±180°, not spread over 360°
    text = static(chunks, "/batch/imu/m/report", "TextDocument:text")[0]
    theta_row = next(line for line in text.splitlines() if "theta0_rad" in line)
    mean = float(theta_row.split("|")[2])
    assert abs(abs(mean) - np.pi) < 0.05  # not ≈ 0.01, the plain mean
    # the helper: the circular mean, and whole turns only
    assert abs(abs(circular_mean(values, 360.0)) - 180.0) < 0.1
    moved = unwrapped(values, 360.0) - np.array(values)
    np.testing.assert_allclose(moved / 360.0, np.round(moved / 360.0), atol=1e-12)
