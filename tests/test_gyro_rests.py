"""The gyroscope at rest (estimate/joint/gyro_rests.py): its readings there, and their use.

The oracle is the simulator's gyro equation at ω = 0, ω_meas = b + G·(R a)/g₀,
with R a the force the sensor senses (its true (v̄ − o)/Γ at the rest) — not
the model's code.
"""

from __future__ import annotations

import dataclasses
import re
from types import SimpleNamespace

import numpy as np
import pytest
from scipy import stats

import wheelcal
from gyro_truth import gyro_truth_values
from loop_truth import sigmas_from_truth
from test_one_answer import _session
from wheelcal.estimate.joint.gyro_rests import REST_FLOOR_DPS, GyroRests
from wheelcal.estimate.rests import find_rests


@pytest.fixture(scope="module")
def unbalanced():
    """The one-answer matrix's unbalanced 46° bench with a gyro, and its rests."""
    session = _session("imbalance 0.3 46", True)
    rec = session.recording
    spin = (float(rec.time_s[0]) + 5.0, float(rec.time_s[-1]) - 5.0)
    rests = find_rests(rec, spin)
    assert len(rests) == 2
    return session, rests


def test_a_rest_reads_the_gyro_bias_and_its_sensitivity_to_the_force(unbalanced):
    session, rests = unbalanced
    spec, truth = session.scenario.gyro, session.truth
    gain, offset = np.asarray(truth.sensor.gain), np.asarray(truth.sensor.offset_mps2)
    for rest in rests:
        sensed = (rest.mean_mps2 - offset) / gain  # R a at the rest
        expected = np.asarray(spec.bias_radps) + spec.g_sensitivity_radps_per_mps2 @ sensed
        z = (rest.gyro_mean_radps - expected) / rest.gyro_mean_std_radps
        assert np.all(np.abs(z) < 4.0), z
    # The model's force at the rest, in the wheel frame: gravity, g cos α along the axle.
    forces = GyroRests.of(rests).forces_mps2(truth)
    g, tilt = truth.gravity_mps2, truth.bench.tilt_rad
    np.testing.assert_allclose(forces[:, 2], g * np.cos(tilt), atol=0.02)
    np.testing.assert_allclose(np.hypot(forces[:, 0], forces[:, 1]), g * np.sin(tilt), atol=0.02)


def test_the_model_of_a_rest_holds_at_the_truth(unbalanced):
    # b + G_X a_X + G_Y a_Y with the simulator's true reading: χ² of the rests' means
    # on their noise alone (no floor) is that of 3 × 2 normal deviates.
    session, rests = unbalanced
    found = GyroRests.of(rests)
    sharp = GyroRests(
        found.accel_mps2, found.gyro_radps, np.array([r.gyro_mean_std_radps for r in rests])
    )
    values = gyro_truth_values(session.scenario.gyro, session.truth)
    chi2, _, _ = sharp.normal_terms(session.truth, values, g_sensitivity=True)
    assert chi2 < stats.chi2.ppf(0.999, 6), chi2
    # ... and a G off by its prior's σ along the rest's force is seen.
    shifted = values.copy()
    shifted[6:9] += np.deg2rad(0.1) / 9.80665
    wrong, _, _ = sharp.normal_terms(session.truth, shifted, g_sensitivity=True)
    assert wrong > 10 * stats.chi2.ppf(0.999, 6), wrong


def test_the_rest_rows_gradient_and_gram_are_the_cost_s(unbalanced):
    session, rests = unbalanced
    found = GyroRests.of(rests)
    values = gyro_truth_values(session.scenario.gyro, session.truth)
    values = values + np.random.default_rng(3).normal(0, 1e-4, values.size)
    cost, grad, gram = found.normal_terms(session.truth, values, g_sensitivity=True)
    step = 1e-6
    for k in range(values.size):
        up, down = values.copy(), values.copy()
        up[k] += step
        down[k] -= step
        c_up = found.normal_terms(session.truth, up, True)[0]
        c_down = found.normal_terms(session.truth, down, True)[0]
        # cost = Σ r², gradient Jᵀr = ½ ∂cost, Gram JᵀJ = ½ ∂²cost (linear in the values)
        assert 0.5 * (c_up - c_down) / (2 * step) == pytest.approx(grad[k], rel=1e-5, abs=1e-3)
        assert 0.5 * (c_up - 2 * cost + c_down) / step**2 == pytest.approx(
            gram[k, k], rel=1e-3, abs=1e-3
        )
    assert np.all(gram[:3] == 0) and np.all(grad[:3] == 0)  # a wheel at rest shows no scale


def _rest(gyro_dps, accel=(6.8, -1.9, 6.8)):
    return SimpleNamespace(
        mean_mps2=np.asarray(accel, dtype=float),
        gyro_mean_radps=np.deg2rad(np.asarray(gyro_dps, dtype=float)),
        gyro_mean_std_radps=np.full(3, np.deg2rad(0.004)),
    )


def test_rests_whose_gyro_disagree_are_not_used():
    still = [0.5, -0.2, 0.1]
    assert GyroRests.of([_rest(still), _rest(still)]).count == 2
    # Within the floor (0.02 °/s): a bias that moved a little is allowed for.
    assert GyroRests.of([_rest(still), _rest(np.add(still, REST_FLOOR_DPS))]) is not None
    # A bias that moved by 0.2 °/s between the rests: neither is used.
    assert GyroRests.of([_rest(still), _rest(np.add(still, [0.0, 0.2, 0.0]))]) is None
    # ... unless G's prior, over their different forces, explains it.
    other = _rest(np.add(still, [0.0, 0.2, 0.0]), accel=(-6.8, 1.9, 6.8))
    assert GyroRests.of([_rest(still), other], np.deg2rad(0.1) / 9.80665) is not None
    # No gyro at a rest: nothing to use.
    assert GyroRests.of([SimpleNamespace(gyro_mean_radps=None)]) is None


def test_a_calibration_uses_the_rests_and_says_so_unless_the_bias_moved(unbalanced):
    session, rests = unbalanced
    cal = wheelcal.calibrate(session.recording)
    assert cal["gyro"]["rests_used"] == 2 and cal.result.gyro_rests.count == 2
    # The bias steps by 0.2 °/s after the spin: the rests disagree, and the fit leaves them.
    rec = session.recording
    gyro = rec.gyro_radps.copy()
    after = rec.time_s >= rests[1].start_s
    gyro[after] += np.deg2rad([0.0, 0.2, 0.0])
    moved = wheelcal.calibrate(dataclasses.replace(rec, gyro_radps=gyro))
    assert moved["gyro"]["rests_used"] == 0 and moved.result.gyro_rests is None
    (warning,) = [w for w in moved.document["fit"]["warnings"] if "bias moved" in w]
    found = re.search(r"differs by ([0-9.]+) °/s on its y axis between the rests", warning)
    assert found and float(found.group(1)) == pytest.approx(0.2, abs=0.02), warning
    assert not any("bias moved" in w for w in cal.document["fit"]["warnings"])
    z = sigmas_from_truth(session, moved.result)
    assert max(abs(v) for v in z.values()) < 5.0, z


def test_a_bias_that_differs_at_the_rests_moves_the_answer_little(unbalanced):
    # Both rests read 0.05 °/s more than the spin's bias on the worst axis (2.5× the
    # floor; they still agree with each other, so they are used): the gains and offsets
    # move by 0.39 σ_CRLB at most (0.1 °/s: 0.78 σ).
    session, rests = unbalanced
    rec = session.recording
    base = sigmas_from_truth(session, wheelcal.calibrate(rec).result)
    at_rest = np.zeros(rec.time_s.size, dtype=bool)
    for rest in rests:
        at_rest |= (rec.time_s >= rest.start_s - 0.5) & (rec.time_s <= rest.end_s + 0.5)
    gyro = rec.gyro_radps.copy()
    gyro[at_rest, 2] += np.deg2rad(0.05)
    shifted = wheelcal.calibrate(dataclasses.replace(rec, gyro_radps=gyro))
    assert shifted["gyro"]["rests_used"] == 2
    moved = sigmas_from_truth(session, shifted.result)
    assert max(abs(moved[k] - base[k]) for k in base) < 0.5, (moved, base)
