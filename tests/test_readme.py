"""The README's two fresh-machine commands stay true: CI runs the second, this the first's job."""

import dataclasses
import json
import re
from pathlib import Path

import numpy as np

from truth_bound import SENSOR_NAMES, scenario_noise
from wheelcal.batch.pipeline import load_pipeline
from wheelcal.cli.main import main
from wheelcal.closedloop.sensor_fit import sensor_crlb
from wheelcal.estimate.joint.crlb import cramer_rao_bound
from wheelcal.simulate import NoiseSpec, Quantiser, preset
from wheelcal.simulate.session import simulate_session

ROOT = Path(__file__).resolve().parents[1]


def _commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```sh\n(.*?)\n```", text, flags=re.S)
    return [b.strip() for b in blocks[:2]]


def test_readme_opens_with_exactly_two_commands():
    text = (ROOT / "README.md").read_text()
    head = text.split("\n\n", 3)
    assert head[0].startswith("# wheelcal")
    assert head[1].startswith("```sh") and head[2].startswith("```sh")
    assert all("\n" not in c for c in _commands())


def test_ci_runs_the_readme_test_command():
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1].strip()
    assert ci == _commands()[1]
    assert "pytest" in ci and "[test]" in ci


def _truth_sessions(pipeline):
    """The pipeline's simulated sessions, rebuilt with their truth (the same random streams)."""
    spec = pipeline.simulate
    sessions = []
    for i in range(spec.count):
        rng = np.random.default_rng([spec.seed, i])
        scenario = preset(spec.preset, rng=rng)
        scenario = dataclasses.replace(
            scenario, noise=NoiseSpec(spec.noise_mps2, bandwidth_hz=spec.bandwidth_hz)
        )
        if spec.quantise:
            scenario = dataclasses.replace(scenario, quantiser=Quantiser())
        sessions.append(simulate_session(scenario, rng))
    return sessions


def _fitted_times(session, w0: float, w1: float) -> np.ndarray:
    """The window's sample times, less those the truth puts within 4 σ_n of a clipping rail.

    The session fit leaves out the samples its model puts near a rail (the reader drops
    the clipped ones); selecting by the truth instead differs by a handful of samples.
    """
    rec, scenario = session.recording, session.scenario
    lo, hi = scenario.quantiser.limits_mps2
    margin = 4 * np.max(scenario.noise.std_mps2)
    clean = session.clean_mps2
    near = np.any((clean >= hi - margin) | (clean <= lo + margin), axis=1)
    inside = (rec.time_s >= w0 - 1e-9) & (rec.time_s <= w1 + 1e-9)
    return rec.time_s[inside & ~near]


def test_main_command_runs_the_bundled_pipeline(tmp_path, monkeypatch, capsys):
    """README's first command's job, in a temp dir: the files it lists and the truth recovered."""
    main_cmd = _commands()[0]
    match = re.search(r"wheelcal batch (\S+\.toml)", main_cmd)
    assert match, main_cmd
    pipeline = load_pipeline(ROOT / match.group(1))
    assert pipeline.simulate is not None and pipeline.simulate.count == 10
    assert pipeline.rerun
    monkeypatch.chdir(tmp_path)  # the pipeline's relative output lands here
    assert main(["batch", str(ROOT / match.group(1)), "--workers", "2"]) == 0
    capsys.readouterr()
    out = tmp_path / "out" / "table2-repeatability"
    # Every file the README lists.
    sensor_file = out / "sensors" / "mpu9250-A.calibration.json"
    for name in ("report.md", "overview.png", "report.json", "sessions.csv", "batch.rrd"):
        assert (out / name).stat().st_size > 0, name
    cals = sorted(out.glob("*.calibration.json"))
    assert len(cals) == 10 and len(list(out.glob("*.rrd"))) == 11
    # report.md opens with the calibration to apply.
    assert (out / "report.md").read_text().split("\n\n")[2].startswith("## Apply this")
    report = json.loads((out / "report.json").read_text())
    assert report["sessions"] == 10 and report["failed"] == []
    # The numbers: each session and the pooled sensor against the CRLB at the simulator's truth,
    # over the windows the batch fitted (the true noise: coloured by the 41 Hz low-pass).
    sessions = _truth_sessions(pipeline)
    states, times, noises = [], [], []
    for session, path in zip(sessions, cals, strict=True):
        cal = json.loads(path.read_text())
        w0, w1 = cal["source"]["window_s"]
        centre = 0.5 * (w0 + w1)
        truth = session.truth.with_changes(
            spin=session.truth.spin.shifted(centre - session.centre_s)
        )
        t = _fitted_times(session, w0, w1) - centre
        assert abs(t.size - cal["source"]["samples"]) < 0.01 * t.size, (path.name, t.size)
        noise = scenario_noise(session.scenario)
        bound = cramer_rao_bound(truth, t, noise)
        for name in SENSOR_NAMES:
            i = bound.names.index(name)
            z = (cal["parameters"][name]["value"] - bound.values[i]) / bound.std[i]
            assert abs(z) < 4.5, (path.name, name, z)
        states.append(truth)
        times.append(t)
        noises.append(noise)
    pooled_bound = sensor_crlb(states, times, noises)
    deliverable = json.loads(sensor_file.read_text())
    truth = sessions[0].truth.sensor
    values = {
        **{f"gain_{a}": v for a, v in zip("xyz", deliverable["sensor"]["gain"], strict=True)},
        **{
            f"offset_{a}_mps2": v
            for a, v in zip("xyz", deliverable["sensor"]["offset_mps2"], strict=True)
        },
    }
    true = {
        **{f"gain_{a}": v for a, v in zip("xyz", truth.gain, strict=True)},
        **{f"offset_{a}_mps2": v for a, v in zip("xyz", truth.offset_mps2, strict=True)},
    }
    for name in SENSOR_NAMES:
        z = (values[name] - true[name]) / pooled_bound[name]
        assert abs(z) < 4.0, (name, values[name], true[name], pooled_bound[name])
