"""Several mountings of one sensor: the full 9-parameter sensor model (issue: close the loop, 4)."""

import dataclasses

import numpy as np
import pytest

from wheelcal.closedloop.sensor_fit import SensorFit, sensor_crlb
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.model import BenchParams, Rotation
from wheelcal.model.effects import CrossAxis
from wheelcal.simulate import simulate, table1

CROSS = [0.01, -0.015, 0.008]
BASE_ROT = Rotation.from_euler_deg(30, 20, 25)
# Turning the mounting 90° about the bench X axis puts another sensor direction along Z.
TURNED_ROT = BASE_ROT.perturbed(np.array([np.pi / 2, 0.0, 0.0]))


def _sessions(rotations, seeds):
    s = table1()
    truth = s.truth.with_changes(effects={"cross_axis": CROSS})
    out = []
    for rot, seed in zip(rotations, seeds, strict=True):
        tr = truth.with_changes(bench=BenchParams(truth.bench.tilt_rad, 0.28, rot))
        scenario = dataclasses.replace(s, truth=tr, effects=(CrossAxis(),))
        rec = simulate(scenario, np.random.default_rng(seed)).recording
        out.append((scenario, rec, JointFit().fit(rec)))
    return out


@pytest.fixture(scope="module")
def two_mountings():
    return _sessions([BASE_ROT, TURNED_ROT], [41, 42])


def test_two_mountings_recover_cross_axis_within_4_crlb(two_mountings):
    scenarios, recs, fits = zip(*two_mountings, strict=True)
    result = SensorFit(shared_effects=(CrossAxis(),)).fit(recs, fits)
    assert result.converged and not result.warnings
    times = [s.centred_times_s() for s in scenarios]
    noises = [NoiseModel.white(s.noise.std) for s in scenarios]
    bound = sensor_crlb([s.truth for s in scenarios], times, noises, (CrossAxis(),))
    truth = scenarios[0].truth
    expected = {
        **{f"cross_axis.{p}": v for p, v in zip(CrossAxis.param_names, CROSS, strict=True)},
        **{f"gain_{a}": g for a, g in zip("xyz", truth.sensor.gain, strict=True)},
        **{f"offset_{a}_mps2": o for a, o in zip("xyz", truth.sensor.offset_mps2, strict=True)},
    }
    z = {n: (result.value_of(n) - v) / bound[n] for n, v in expected.items()}
    assert max(abs(v) for v in z.values()) < 4.0, z
    assert len(result.names) == 9  # the full sensor model: 3 offsets, 3 gains, 3 angles
    # Cross-axis coupling hides in a single-mounting calibration: the offsets are biased there.
    single = fits[0]
    assert (
        max(abs(single.value_of(f"offset_{a}_mps2") - expected[f"offset_{a}_mps2"]) for a in "xyz")
        > 0.05
    )


def test_the_same_mounting_twice_cannot_identify_cross_axis(two_mountings):
    _, rec, fit = two_mountings[0]
    ((_, rec2, fit2),) = _sessions([BASE_ROT], [43])
    result = SensorFit(shared_effects=(CrossAxis(),)).fit([rec, rec2], [fit, fit2])
    assert "cross_axis.yx_rad" not in result.names
    assert result.information_fraction["cross_axis"] < 1e-4
    assert any("cannot identify" in w and "cross_axis" in w for w in result.warnings)


def test_pooling_reduces_sigma_against_the_best_single_recording(two_mountings):
    _, recs, fits = zip(*two_mountings, strict=True)
    result = SensorFit().fit(recs, fits)
    gains = result.pooling_gain()
    assert set(gains) >= {"gain_x", "offset_z_mps2"}
    assert all(g > 1.0 for g in gains.values())
