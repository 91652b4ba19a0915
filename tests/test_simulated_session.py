"""The whole-session simulator: its free spin is exactly the model, the rest is physical."""

import numpy as np
import pytest

from wheelcal.model import predict
from wheelcal.model.parameters import STANDARD_GRAVITY_MPS2
from wheelcal.simulate import NoiseSpec, Quantiser, Scenario, table1, table2
from wheelcal.simulate.session import SessionPlan, simulate_session

PLAN = SessionPlan(rest_before_s=3.0, push_s=0.8, stop_s=1.5, rest_after_s=2.0)


@pytest.fixture(scope="module")
def sim():
    base = table2(rng=np.random.default_rng(21))
    scenario = Scenario(truth=base.truth, duration_s=40.0, noise=NoiseSpec(0.08))
    return simulate_session(scenario, np.random.default_rng(22), PLAN)


def phases(sim):
    t = sim.recording.time_s
    start, end = sim.window_s
    return {
        "rest1": t < start - PLAN.push_s,
        "push": (t >= start - PLAN.push_s) & (t < start),
        "free": (t >= start) & (t <= end),
        "stop": (t > end) & (t <= end + PLAN.stop_s),
        "rest2": t > end + PLAN.stop_s,
    }


def test_layout_and_window(sim):
    rec = sim.recording
    start, end = sim.window_s
    assert start == pytest.approx(PLAN.rest_before_s + PLAN.push_s)
    assert end - start == pytest.approx(40.0)
    assert rec.duration_s == pytest.approx(end + PLAN.stop_s + PLAN.rest_after_s, abs=0.01)
    assert rec.rate_hz == pytest.approx(200.0)
    assert sim.centre_s == pytest.approx(start + 20.0)


def test_free_spin_is_exactly_the_model(sim):
    free = phases(sim)["free"]
    t = sim.recording.time_s[free] - sim.centre_s
    np.testing.assert_allclose(sim.clean_mps2[free], predict(sim.truth, t), rtol=0, atol=1e-9)
    np.testing.assert_allclose(sim.omega_radps[free], sim.truth.spin.omega_at(t), rtol=1e-12)


def test_rest_reads_gravity_only(sim):
    sensor, bench = sim.truth.sensor, sim.truth.bench
    for name in ("rest1", "rest2"):
        rest = sim.clean_mps2[phases(sim)[name]]
        assert np.ptp(rest, axis=0).max() == 0.0  # nothing moves
        bench_force = np.linalg.solve(
            sensor.gain[:, None] * bench.misalignment.matrix, rest[0] - sensor.offset_mps2
        )
        assert np.linalg.norm(bench_force) == pytest.approx(STANDARD_GRAVITY_MPS2, rel=1e-12)
        assert bench_force[2] == pytest.approx(STANDARD_GRAVITY_MPS2 * np.cos(bench.tilt_rad))


def test_push_and_brake_are_strong_and_continuous(sim):
    p = phases(sim)
    r = sim.truth.bench.radius_m
    omega, omega_dot = sim.omega_radps, sim.omega_dot_radps2
    assert np.max(np.abs(r * omega_dot[p["push"]])) > 3.0  # strong tangential push
    assert np.max(np.abs(r * omega_dot[p["stop"]])) > 1.0  # firm brake
    assert np.all(omega[p["rest1"]] == 0) and np.all(omega[p["rest2"]] == 0)
    # ω is continuous where the push hands over to the free spin, and the samples too.
    first = np.flatnonzero(p["free"])[0]
    assert abs(omega[first] - omega[first - 1]) < 0.2
    step = np.abs(np.diff(sim.clean_mps2, axis=0)).max(axis=1)
    assert step[first - 1] < 3 * np.median(step[p["free"][1:]])


def test_noise_matches_the_spec(sim):
    residual = sim.recording.accel_mps2 - sim.clean_mps2
    np.testing.assert_allclose(residual.std(axis=0), 0.08, rtol=0.05)


@pytest.mark.parametrize("direction", [1, -1])
def test_either_direction(direction):
    from wheelcal.model import SpinParams

    base = table1()
    spin = base.truth.spin
    truth = base.truth.with_changes(spin=SpinParams(spin.theta0_rad, direction * spin.omega_radps))
    sim = simulate_session(Scenario(truth=truth, duration_s=30.0), np.random.default_rng(1))
    free = phases(sim)["free"]
    assert np.all(np.sign(sim.omega_radps[free]) == direction)
    push = phases(sim)["push"]
    assert np.all(np.sign(sim.omega_dot_radps2[push][1:]) == direction)


def test_reproducible_and_quantised():
    base = table2(rng=np.random.default_rng(2))
    quantiser = Quantiser(full_scale_g=16.0, bits=16)
    scenario = Scenario(truth=base.truth, duration_s=20.0, quantiser=quantiser)
    a = simulate_session(scenario, np.random.default_rng(3))
    b = simulate_session(scenario, np.random.default_rng(3))
    c = simulate_session(scenario, np.random.default_rng(4))
    np.testing.assert_array_equal(a.recording.accel_mps2, b.recording.accel_mps2)
    assert not np.array_equal(a.recording.accel_mps2, c.recording.accel_mps2)
    counts = a.recording.accel_mps2 / quantiser.lsb_mps2
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
