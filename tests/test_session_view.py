"""What a person reads off a session's Rerun file (issue 39): the verdict on the first screen.

Read back with Rerun's own reader (``tests/test_viz_rrd.py``'s helpers):

* the verdict strip is the calibration JSON's: the same warnings, in the same order, the
  effects found with their evidence, the clipped share, the window's words;
* a session clipped at ±4 g shows its rail: the rail as a line across the recording, every
  clipped sample the reader dropped as a point at its reading, and the window's words
  say that part of the spin was dropped for clipping;
* the time views draw each pixel's min and max (never their average), and the residual
  carries its ±2σ noise lines;
* the Allan plot has its axes: a frame, a labelled tick per decade of τ and of σ.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
import rerun as rr

from test_viz_rrd import blueprint_contents, blueprint_views, read_store, static, temporal
from wheelcal.cli.main import main
from wheelcal.io import read_recording


def _calibrated(tmp_path, name, *simulate):
    rec = tmp_path / f"{name}.mcap"
    assert main(["simulate", str(rec), *simulate]) == 0
    assert main(["calibrate", str(rec), "--out", str(tmp_path), "--rrd", "--quiet"]) == 0
    doc = json.loads((tmp_path / f"{name}.calibration.json").read_text())
    return rec, doc, read_store(tmp_path / f"{name}.rrd"), tmp_path / f"{name}.rrd"


@pytest.fixture(scope="module")
def warned(tmp_path_factory):
    """Table I's sensor (gains 0.9 and 1.1, offsets 1 m/s²): warnings from the gates."""
    return _calibrated(tmp_path_factory.mktemp("warned"), "t1", "--preset", "table1")


@pytest.fixture(scope="module")
def clipped(tmp_path_factory):
    """A ±4 g, 16-bit session whose fast first turns clip on x (16 % of the samples)."""
    return _calibrated(tmp_path_factory.mktemp("clipped"), "q", "--quantise", "--seed", "4")


def _verdict(chunks) -> str:
    return static(chunks, "/verdict", "TextDocument:text")[0]


def test_the_panels_warnings_are_the_jsons(warned):
    _, doc, chunks, _ = warned
    warnings = doc["fit"]["warnings"]
    assert len(warnings) >= 4  # the gates' tolerance warnings, not only the fit's
    text = _verdict(chunks)
    head = f"- **warnings ({len(warnings)})**"
    assert head in text
    listed = [line[4:] for line in text.split(head, 1)[1].splitlines() if line.startswith("  - ")]
    assert listed == warnings
    assert doc["source"]["window_reason"] in text


def test_the_verdict_names_the_effects_and_their_evidence(tmp_path):
    import sys

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parents[1] / "tools"))
    from render_rrd import imbalance_recording

    rec = tmp_path / "imbalance.mcap"
    imbalance_recording(rec)
    assert main(["diagnose", str(rec), "--out", str(tmp_path), "--rrd"]) == 0
    doc = json.loads((tmp_path / "imbalance.calibration.json").read_text())
    evidence = doc["effects"]["imbalance"]["evidence"]
    text = _verdict(read_store(tmp_path / "imbalance.rrd"))
    first = text.splitlines()[0]  # the strip's first line: on screen whatever its height
    assert "**imbalance**" in first
    assert f"χ² = {evidence['statistic']:.4g}, {evidence['dof']} dof" in first
    assert f"p = {evidence['p_corrected']:.2g}" in first


def test_a_clipped_sessions_plot_shows_the_rail(clipped):
    rec, doc, chunks, path = clipped
    recording = read_recording(rec)
    rail = float(recording.clip_limits_mps2[0, 1])
    assert rail == pytest.approx(39.2254, abs=1e-3)  # +4 g on x
    # the rail: a line across the whole recording at its value
    t_ns, values = temporal(chunks, "/range/x/high", "Scalars:scalars", "time")
    assert [v[0] for v in values] == [rail, rail]
    assert t_ns[0] == 0 and t_ns[-1] == round(recording.time_s[-1] * 1e9)
    # every clipped sample the reader dropped, as a point at its reading on the rail
    (note,) = [n for n in recording.notes if "clipped" in n]
    dropped = int(re.search(r"dropped (\d+) clipped", note).group(1))
    t_ns, values = temporal(chunks, "/clipped/x/at_rail", "Scalars:scalars", "time")
    assert len(values) == dropped == recording.clipped_time_s.size
    assert np.all(np.abs(np.array([v[0] for v in values]) - rail) <= 0.005 * rail)
    np.testing.assert_array_equal(t_ns, np.rint(recording.clipped_time_s * 1e9))
    # the x view draws them (its contents), each pixel as min and max
    contents = blueprint_contents(path)
    queries = [q for (e, c, _), v in contents.items() if c == "ViewContents:query" for q in v[0]]
    assert "/range/x/**" in queries and "/clipped/x/**" in queries
    policies = {
        p
        for (e, c, _), v in contents.items()
        if c == "SeriesLines:aggregation_policy"
        for p in v[0]
    }
    assert policies == {rr.components.AggregationPolicy.MinMax.value}  # never Average
    # and the strip and the window's words say it
    text = _verdict(chunks)
    assert f"**clipped**: {dropped} of {recording.samples + dropped} samples (16 %)" in text
    reason = doc["source"]["window_reason"]
    assert "spin whose samples clipped" in reason and f"{dropped} samples clipped" in reason


def test_the_residual_carries_its_two_sigma_lines(clipped):
    _, doc, chunks, _ = clipped
    floor = doc["fit"]["noise_floor_mps2"]
    start, end = doc["source"]["window_s"]
    for k, axis in enumerate("xyz"):
        for name, sign in (("upper", 1), ("lower", -1)):
            entity = f"/noise_band/{axis}/{name}"
            t_ns, values = temporal(chunks, entity, "Scalars:scalars", "time")
            assert [v[0] for v in values] == pytest.approx([sign * 2 * floor[k]] * 2)
            assert t_ns.tolist() == [round(start * 1e9), round(end * 1e9)]


def test_the_allan_plot_has_axes(warned):
    _, doc, chunks, path = warned
    labels = static(chunks, "/allan/axes/labels", "Points2D:labels")
    assert {"10 ms", "0.1 s", "1 s"} <= set(labels)
    assert any(label.endswith("m/s²") and label.startswith("10") for label in labels)
    allan = doc["fit"]["allan"]
    (strip,) = static(chunks, "/allan/x", "LineStrips2D:strips")
    curve = np.array(strip)
    np.testing.assert_allclose(curve[:, 0], np.log10(allan["tau_s"]), rtol=1e-6)
    np.testing.assert_allclose(
        curve[:, 1], -np.log10(np.array(allan["adev_mps2"])[:, 0]), rtol=1e-6
    )
    (density_line,) = static(chunks, "/allan/noise_density", "LineStrips2D:strips")
    n = max(doc["imu_noise"]["accelerometer"]["noise_density_mps2_rthz"])
    # the exported density's line: σ(1 s) = N
    line = np.array(density_line)
    at_one = np.interp(0.0, line[:, 0], line[:, 1])
    assert at_one == pytest.approx(-np.log10(n), rel=1e-6)
    assert any(v[1].startswith("rests: Allan deviation") for v in blueprint_views(path))
