"""Issue 28: the rests' Allan deviation where people look — report.md and the session .rrd."""

import json

import numpy as np
import pytest

from batch_inputs import pipeline_file, simulated_recordings
from test_viz_rrd import blueprint_views, read_store, static
from wheelcal.cli.main import main
from wheelcal.estimate.allan import AllanSums
from wheelcal.session.fit import SessionFit
from wheelcal.simulate import table2
from wheelcal.simulate.session import simulate_session
from wheelcal.viz.session_rrd import write_session_rrd


def test_session_rrd_plots_the_rests_allan_deviation(tmp_path):
    recording = simulate_session(table2(rng=np.random.default_rng(5)), np.random.default_rng(6))
    recording = recording.recording
    outcome = SessionFit().run(recording)
    assert outcome.rests, "the simulated session has rests"
    path = tmp_path / "s.rrd"
    write_session_rrd(path, outcome)
    chunks = read_store(path)
    curve = AllanSums.combined([r.allan for r in outcome.rests]).deviation()
    for k, axis in enumerate("xyz"):
        (strip,) = static(chunks, f"/allan/{axis}", "LineStrips2D:strips")
        points = np.array(strip)
        np.testing.assert_allclose(points[:, 0], np.log10(curve.tau_s), atol=1e-9)
        # drawn as −log10 σ: a 2-D view's y axis points down, so larger σ is higher
        np.testing.assert_allclose(points[:, 1], -np.log10(curve.adev[:, k]), rtol=1e-6)
    density, _ = curve.white_noise_density()
    (text,) = static(chunks, "/allan/readouts", "TextDocument:text")
    assert all(f"| {a} | {d:.3g} |" in text for a, d in zip("xyz", density, strict=True))
    title = "rests: Allan deviation σ(τ), log-log; black: exported density N/√τ"
    assert ("2D", title, "/allan") in [tuple(v) for v in blueprint_views(path)]


@pytest.fixture(scope="module")
def batch_out(tmp_path_factory):
    d = simulated_recordings(tmp_path_factory.mktemp("allanbatch"), ["r0", "r1"], 90, False)
    assert main(["batch", str(pipeline_file(d / "p.toml", d / "out", f"{d}/*.mcap"))]) == 0
    return d / "out"


def test_report_md_shows_the_pooled_allan_read_outs(batch_out):
    (sensor_file,) = (batch_out / "sensors").glob("*.calibration.json")
    sensor = json.loads(sensor_file.read_text())
    allan = sensor["fit"]["allan"]
    sessions = [json.loads(p.read_text()) for p in batch_out.glob("r*.calibration.json")]
    assert allan["rests_s"] == pytest.approx(sum(s["fit"]["allan"]["rests_s"] for s in sessions))
    # pooled exactly: the count-weighted variance of the sessions' curves at τ = 1 s
    at = [s["fit"]["allan"]["tau_s"].index(1.0) for s in sessions]
    n = np.array([s["fit"]["allan"]["counts"][i] for s, i in zip(sessions, at, strict=True)])
    var = np.array([s["fit"]["allan"]["adev_mps2"][i] for s, i in zip(sessions, at, strict=True)])
    pooled = np.sqrt(n @ var**2 / n.sum())
    np.testing.assert_allclose(allan["adev_mps2"][allan["tau_s"].index(1.0)], pooled, rtol=1e-12)
    report = (batch_out / "report.md").read_text()
    assert "(Allan deviation)" in report
    section = report[report.index("(Allan deviation)") :]
    for value in allan["white_noise_density_mps2_rthz"] + allan["random_walk_mps3_rthz"]:
        assert f"{value:.3g}" in section


def test_one_loader_reads_the_sensor_calibration_and_the_session_ones(batch_out):
    """Issue 28: ``Calibration.from_json`` loads the batch's main deliverable too."""
    import wheelcal

    (sensor_file,) = (batch_out / "sensors").glob("*.calibration.json")
    doc = json.loads(sensor_file.read_text())
    cal = wheelcal.Calibration.from_json(sensor_file)
    assert cal.kind == "sensor" and cal.sensor_id == doc["sensor_id"]
    np.testing.assert_array_equal(cal.gain, doc["sensor"]["gain"])
    np.testing.assert_array_equal(cal.offset_std_mps2, doc["sensor"]["offset_std_mps2"])
    np.testing.assert_array_equal(cal.systematic_gain_std, doc["systematic"]["gain_std"])
    v = np.random.default_rng(0).normal(0, 9.8, (20, 3))
    m, b = np.array(doc["correction"]["matrix"]), np.array(doc["correction"]["bias_mps2"])
    np.testing.assert_allclose(cal.apply(v), (v - b) @ m.T, rtol=1e-12)
    assert cal.value("gain_x") == doc["parameters"]["gain_x"]["value"]
    assert "pooled from 2 sessions" in cal.summary() and "pooled from 2" in repr(cal)
    with pytest.raises(ValueError, match="radius_m: a sensor's pooled calibration"):
        _ = cal.radius_m
    session = wheelcal.Calibration.from_json(batch_out / "r0.calibration.json")
    assert session.kind == "session" and session.radius_m == pytest.approx(0.28)
