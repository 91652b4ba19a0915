"""The planner for the gyroscope's full matrix: which mountings, and the σ they give (issue 38).

``wheelcal plan`` names the three mountings the gyro's matrix needs (the wheel
axis near the sensor's x, y and z) and predicts the σ of its entries
(:mod:`wheelcal.plan.gyro_plan`).  The prediction is checked against what the
default calibration then does on the plan's own simulated recordings: in CI
the σ the pooled fit reports on one set (the same bound, at the estimate), with
``-m slow`` the spread of the errors over 100 sets (each its own gyro device):
observed / predicted within 0.8–1.25 on average over the entries, each entry
within 4 standard errors (±0.28 at n = 100).
"""

from __future__ import annotations

import dataclasses
import json
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

from wheelcal.plan import PlannedSetup
from wheelcal.plan.gyro_plan import plan_gyro
from wheelcal.simulate.gyro import GyroSpec

SETUP = PlannedSetup(duration_s=60.0, omega_start_radps=11.0, omega_end_radps=7.0)


def test_plan_names_the_three_mountings_and_predicts_the_matrix(capsys):
    from wheelcal.cli.main import main

    assert main(["plan", "--no-tradeoffs"]) == 0
    text = capsys.readouterr().out
    assert "Gyroscope" in text and "needs 3 mountings" in text, text
    for axis in "xyz":
        assert f"wheel axis near the sensor's {axis}: mounting (ZYX)" in text
    assert main(["plan", "--no-tradeoffs", "--json", "--gyro-sessions", "2"]) == 0
    gyro = json.loads(capsys.readouterr().out)["gyro"]
    assert gyro["sessions_per_mounting"] == 2 and len(gyro["mountings"]) == 3
    std = np.array(gyro["matrix_std"], dtype=float)
    assert np.all(np.isfinite(std)) and np.all(std < 0.002), std


def test_fewer_mountings_are_planned_as_undetermined():
    one = plan_gyro(SETUP, axes=("z",))
    two = plan_gyro(SETUP, axes=("x", "z"))
    for plan in (one, two):
        assert not plan.determined
        assert len(plan.pooled.undetermined) == 9
        assert "undetermined" in plan.lines()[-1]
    assert np.isfinite(one.one_session_scale_std) and one.one_session_scale_std < 1e-3
    # More spins per mounting: σ falls as 1/√n (the mountings' R errors are independent).
    three, twelve = plan_gyro(SETUP, sessions=3), plan_gyro(SETUP, sessions=12)
    np.testing.assert_allclose(twelve.pooled.matrix_std, three.pooled.matrix_std / 2, rtol=0.02)


def _planned_set(seed: int):
    """The plan's three mountings × 3 spins, simulated and calibrated by default; the gyro."""
    from threadpoolctl import threadpool_limits

    from wheelcal.calibration.gyro_json import gyro_block
    from wheelcal.calibration.session_json import calibration_dict
    from wheelcal.session.compute import SessionOptions, compute_recording
    from wheelcal.simulate import simulate
    from wheelcal.simulate.mountings import mounting_near

    rng = np.random.default_rng([seed, 38])
    gyro = GyroSpec.device(rng)
    docs = []
    with threadpool_limits(1):
        for axis in "xyz":
            planned = SETUP.with_mounting(mounting_near(axis, SETUP.mounting))
            scenario = dataclasses.replace(planned.scenario(), gyro=gyro)
            info = scenario.info.merged(sensor_id="imu", mounting_id=axis)
            scenario = dataclasses.replace(scenario, info=info)
            for _ in range(3):
                recording = simulate(scenario, rng).recording
                docs.append(calibration_dict(compute_recording(recording, SessionOptions())))
        block = gyro_block(docs)["gyro"]
    error = np.array(block["matrix"], dtype=float) - gyro.response_matrix
    return error.ravel(), np.array(block["matrix_std"], dtype=float).ravel()


def test_the_planned_sigma_is_what_the_calibration_reports():
    predicted = plan_gyro(SETUP, sessions=3).pooled.matrix_std.ravel()
    error, reported = _planned_set(1)
    ratio = reported / predicted
    assert np.all((ratio > 0.8) & (ratio < 1.25)), ratio.round(3)
    assert np.all(np.abs(error) < 4 * predicted), (error / predicted).round(2)


@pytest.mark.slow
def test_the_planned_sigma_is_the_spread_monte_carlo():
    predicted = plan_gyro(SETUP, sessions=3).pooled.matrix_std.ravel()
    with ProcessPoolExecutor(2) as pool:
        runs = list(pool.map(_planned_set, range(100, 200)))
    errors = np.array([e for e, _ in runs])
    ratio = np.std(errors, axis=0, ddof=1) / predicted
    print("observed spread / planned σ per entry", ratio.round(3))
    assert 0.8 <= np.mean(ratio) <= 1.25, ratio
    assert np.all((ratio > 0.72) & (ratio < 1.28)), ratio
