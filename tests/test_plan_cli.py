"""``wheelcal plan`` end to end: the table, the JSON keys, the mounting search, bad usage."""

from __future__ import annotations

import json

import pytest

from wheelcal.cli.main import main

#: A short plan keeps the CLI runs quick; the numbers scale, the layout does not.
SHORT = ["--duration", "45", "--rate", "100", "--omega-end", "6.5"]


def _json(capsys, *argv: str) -> dict:
    assert main(["plan", *SHORT, "--json", *argv]) == 0
    return json.loads(capsys.readouterr().out)


def test_table_lists_every_sensor_parameter_with_both_uncertainties(capsys):
    assert main(["plan", *SHORT]) == 0
    out = capsys.readouterr().out
    assert "Cramér–Rao bound" in out
    for name in ("tilt_deg", "euler_1_deg", "gain_x", "gain_z", "offset_x_mps2", "offset_z_mps2"):
        line = next(line for line in out.splitlines() if line.strip().startswith(name))
        assert len(line.split()) == 4, line  # name, planned, statistical, systematic
    assert "radius ±0.001 m" in out  # the systematic sources of radius mode
    assert "Geometry modes" in out and "vertical" in out and "◀ plan" in out
    assert "Best mounting" not in out  # only with --mounting any


def test_json_keys(capsys):
    doc = _json(capsys, "--no-tradeoffs")
    assert doc["format"] == "wheelcal.plan/1"
    assert {"setup", "parameters", "systematic", "warnings", "notes", "tradeoffs"} <= set(doc)
    assert doc["setup"]["radius_m"] == 0.28 and doc["setup"]["tilt_deg"] == 45.0
    assert set(doc["parameters"]["offset_z_mps2"]) == {"value", "std", "systematic_std"}
    assert doc["parameters"]["gain_x"]["std"] > 0
    sources = doc["systematic"]["sources"]
    assert set(sources) == {"radius", "gravity", "sample_clock"}
    assert {"linear", "first_order", "second_order", "shift_plus_1sigma"} <= set(sources["radius"])
    assert doc["mounting_search"] is None and doc["tradeoffs"] == []


def test_vertical_mode_states_the_second_order_gain_term(capsys):
    doc = _json(capsys, "--geometry", "vertical", "--no-tradeoffs")
    tilt = doc["systematic"]["sources"]["tilt"]
    assert tilt["linear"]["gain_x"] == pytest.approx(0.0, abs=1e-12)
    assert tilt["second_order"]["gain_x"] < 0  # −δ²/2
    assert any("second order" in note and "misses it" in note for note in doc["notes"])
    assert "radius_m" in doc["parameters"] and "tilt_deg" not in doc["parameters"]


def test_mounting_any_finds_a_better_mounting_than_the_default(capsys):
    doc = _json(capsys, "--mounting", "any", "--no-tradeoffs")
    search = doc["mounting_search"]
    assert search["reference"]["euler_deg"] == pytest.approx([30.0, 20.0, 25.0])
    assert search["best"]["objective_mps2"] < search["reference"]["objective_mps2"]
    assert search["improvement"] > 1.5
    assert 10.0 <= search["best"]["tilt_deg"] <= 80.0
    assert main(["plan", *SHORT, "--mounting", "any", "--fixed-tilt", "--no-tradeoffs"]) == 0
    out = capsys.readouterr().out
    assert "best at your tilt" in out and "× smaller" in out
    assert "best, tilt free" not in out


@pytest.mark.parametrize(
    "argv",
    [
        ["--mounting", "1", "2"],
        ["--mounting", "a", "b", "c"],
        ["--geometry", "vertical", "--tilt-deg", "80"],
        ["--omega-start", "5", "--omega-end", "9"],
        ["--tilt-deg", "120"],
        ["--mounting", "any", "--tilt-range", "50", "20"],
    ],
)
def test_bad_usage_exits_2(capsys, argv):
    assert main(["plan", *argv]) == 2
    assert "wheelcal plan: error:" in capsys.readouterr().err
