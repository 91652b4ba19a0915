"""Free-spin window detection on whole simulated sessions (rest, push, spin, brake, rest).

Requirement: the window found lies inside the true free spin and covers at
least 90 % of it — for either spin direction, any mounting, 100–1000 Hz.
"""

from dataclasses import replace

import numpy as np
import pytest

from wheelcal.io import read_recording, write_recording
from wheelcal.model import Rotation, SpinParams
from wheelcal.recording import Recording, RecordingError
from wheelcal.session.window import FreeSpinWindow, WindowSearch, find_free_spin
from wheelcal.simulate import NoiseSpec, Quantiser, Scenario, simulate, table1, table2
from wheelcal.simulate.presets import random_setup
from wheelcal.simulate.session import SessionPlan, simulate_session


def check(window: FreeSpinWindow, truth_s: tuple[float, float]) -> float:
    start, end = truth_s
    assert start <= window.start_s < window.end_s <= end, (window, truth_s)
    coverage = (window.end_s - window.start_s) / (end - start)
    assert coverage >= 0.90, (window, truth_s, coverage)
    return coverage


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5, 6])
def test_random_setups(seed):
    """Random tilt (10°–85°), mounting, direction, rate (100–1000 Hz), spin and hand."""
    rng = np.random.default_rng(seed)
    scenario = random_setup(rng)
    scenario = replace(scenario, duration_s=min(scenario.duration_s, 75.0))
    plan = SessionPlan(
        rest_before_s=rng.uniform(1, 5),
        push_s=rng.uniform(0.5, 1.0),
        stop_s=rng.uniform(0.8, 2.5),
        rest_after_s=rng.uniform(1, 4),
        hand_jitter_mps2=rng.uniform(0, 1.5),
    )
    sim = simulate_session(scenario, rng, plan)
    window = find_free_spin(sim.recording)
    check(window, sim.window_s)
    assert "free spin" in window.reason


@pytest.mark.parametrize("rate_hz", [100.0, 1000.0])
@pytest.mark.parametrize("direction", [1, -1])
def test_direction_and_rate(rate_hz, direction):
    base = table2(rng=np.random.default_rng(7))
    spin = base.truth.spin
    truth = base.truth.with_changes(spin=SpinParams(spin.theta0_rad, direction * spin.omega_radps))
    scenario = Scenario(truth=truth, duration_s=60.0, rate_hz=rate_hz)
    sim = simulate_session(scenario, np.random.default_rng(8))
    window = find_free_spin(sim.recording)
    check(window, sim.window_s)
    assert window.omega_start_radps > window.omega_end_radps > 0  # |ω| decays


@pytest.mark.parametrize(
    "euler_deg", [(0.0, 0.0, 0.0), (90.0, 0.0, 0.0), (0.0, 90.0, 90.0), (180.0, 45.0, 10.0)]
)
def test_any_mounting(euler_deg):
    """Axis-aligned and permuted mountings too: no sensor axis is assumed to be radial."""
    base = table1()
    bench = replace(base.truth.bench, misalignment=Rotation.from_euler_deg(*euler_deg))
    scenario = Scenario(truth=base.truth.with_changes(bench=bench), duration_s=60.0)
    sim = simulate_session(scenario, np.random.default_rng(9))
    check(find_free_spin(sim.recording), sim.window_s)


def test_noisy_quantised_coloured():
    base = table2(rng=np.random.default_rng(10))
    scenario = Scenario(
        truth=base.truth,
        duration_s=60.0,
        rate_hz=500.0,
        noise=NoiseSpec(0.3, bandwidth_hz=40.0),
        quantiser=Quantiser(full_scale_g=8.0, bits=12),
    )
    sim = simulate_session(scenario, np.random.default_rng(11), SessionPlan(hand_jitter_mps2=2.0))
    check(find_free_spin(sim.recording), sim.window_s)


def test_after_an_mcap_round_trip(tmp_path):
    """Times keep their meaning through a file (origin = first sample, epoch kept)."""
    base = table2(rng=np.random.default_rng(12))
    sim = simulate_session(Scenario(truth=base.truth, duration_s=60.0), np.random.default_rng(13))
    write_recording(sim.recording, tmp_path / "s.mcap", encoding="json", batch_size=20)
    check(find_free_spin(read_recording(tmp_path / "s.mcap")), sim.window_s)


def test_plain_free_spin_recording():
    """A recording that is all free spin: the window is (almost) all of it."""
    sim = simulate(table1(), np.random.default_rng(14))
    window = find_free_spin(sim.recording)
    check(window, (0.0, sim.recording.duration_s))


def test_no_spin_is_an_error():
    t = np.arange(0, 30, 0.005)
    rest = np.tile([0.2, -0.1, 9.8], (t.size, 1)) + np.random.default_rng(0).normal(
        0, 0.05, (t.size, 3)
    )
    with pytest.raises(RecordingError, match=r"rest\.mcap: no free spin found"):
        find_free_spin(Recording(time_s=t, accel_mps2=rest, source="rest.mcap"))


def test_short_spin_is_an_error():
    base = table2(rng=np.random.default_rng(15))
    sim = simulate_session(Scenario(truth=base.truth, duration_s=8.0), np.random.default_rng(16))
    with pytest.raises(
        RecordingError, match=r"no free spin found: .* lasts [0-9.]+ s \(need 10 s\)"
    ):
        find_free_spin(sim.recording, WindowSearch(min_duration_s=10.0))


def test_a_day_long_gap_costs_memory_by_samples_not_by_time_span():
    """A recording built directly (no reader to drop stray stamps) with a 1-day gap.

    The window search used to resample the whole span to a regular grid:
    17 million points for 18,000 samples (2.8 GB, 14 s).  Now each stretch
    between long gaps is searched on its own: the calibration is the one of
    the spin alone, and the peak allocation stays that of a normal recording.
    """
    import tracemalloc

    from wheelcal.session.fit import SessionFit

    spin = simulate(table1(), np.random.default_rng(4)).recording
    rest_t = spin.time_s[-1] + 86_400.0 + np.arange(2000) / 200.0
    rest_v = np.array([0.3, -0.2, 9.9]) + 0.05 * np.random.default_rng(5).normal(size=(2000, 3))
    gappy = replace(
        spin,
        time_s=np.concatenate([spin.time_s, rest_t]),
        accel_mps2=np.concatenate([spin.accel_mps2, rest_v]),
    )
    tracemalloc.start()
    try:
        outcome = SessionFit().run(gappy)
        peak_bytes = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # A regular grid over the day would need 17.3 M × 3 × 8 B = 415 MB for one copy.
    assert peak_bytes < 100e6
    alone = SessionFit().run(spin)
    assert outcome.window.recording.samples == alone.window.recording.samples
    np.testing.assert_allclose(outcome.result.values, alone.result.values, rtol=1e-12)
    assert "stretches between gaps" in outcome.window.reason


def test_a_given_gyro_window_across_a_day_long_gap_is_refused_in_bounded_memory():
    """--gyro on with --start-s/--end-s spanning a 1-day gap: the wheel-angle spline's
    knots follow the time span, so the window is refused before any is built (it used
    to build B-spline bases of ~5,000 knots × 6,000 samples per candidate spacing)."""
    import tracemalloc

    from wheelcal.session.fit import SessionFit
    from wheelcal.simulate import hostile
    from wheelcal.simulate.gyro import GyroSpec

    session = hostile.clean(np.random.default_rng(1), gyro=GyroSpec()).recording
    later = session.time_s[-1] + 86_400.0 + np.arange(2000) / 200.0
    rest = np.array([0.3, -0.2, 9.9]) + 0.05 * np.random.default_rng(5).normal(size=(2000, 3))
    gappy = replace(
        session,
        time_s=np.concatenate([session.time_s, later]),
        accel_mps2=np.concatenate([session.accel_mps2, rest]),
        gyro_radps=np.concatenate([session.gyro_radps, np.zeros((2000, 3))]),
        temperature_c=None,
    )
    fit = SessionFit(gyro="on", start_s=float(session.time_s[0]), end_s=float(later[-1]))
    tracemalloc.start()
    try:
        with pytest.raises(RecordingError, match=r"spans a gap of 8\.64e\+04 s"):
            fit.run(gappy)
        peak_bytes = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak_bytes < 50e6


def test_the_drive_is_cut_where_the_rate_is_missing_but_one_row_is_bridged():
    from wheelcal.session.window import angle_stretches

    for rate_hz in (10.0, 100.0, 400.0):
        t = np.arange(0.0, 20.0, 1.0 / rate_hz)
        gyro = np.ones((t.size, 3))
        gyro[t.size // 3] = np.nan  # one glitch row: bridged at any rate
        assert angle_stretches(t, gyro) == [slice(0, t.size)]
        hole = (t > 12.0) & (t < 12.3)  # 0.3 s clipped: cut
        gyro[hole] = np.nan
        first, last = np.flatnonzero(hole)[[0, -1]]
        assert angle_stretches(t, gyro) == [slice(0, first), slice(last + 1, t.size)]
        kept = ~hole  # … and so is a gap in the stamps (rows dropped)
        assert angle_stretches(t[kept], gyro[kept]) == [slice(0, first), slice(first, kept.sum())]
