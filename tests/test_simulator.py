import numpy as np
import pytest

from wheelcal.model import predict
from wheelcal.simulate import NoiseSpec, Quantiser, preset, random_setup, simulate, table1, table2


def test_white_noise_level_and_independence():
    x = NoiseSpec(0.08).sample(200_000, 200.0, np.random.default_rng(0))
    assert np.allclose(x.std(axis=0), 0.08, rtol=0.01)
    lag1 = np.mean(x[1:] * x[:-1], axis=0) / x.var(axis=0)
    assert np.all(np.abs(lag1) < 0.01)


def test_band_limited_noise_has_the_marginal_std_and_is_coloured():
    spec = NoiseSpec(0.08, bandwidth_hz=20.0)
    x = spec.sample(400_000, 200.0, np.random.default_rng(1))
    assert np.allclose(x.std(axis=0), 0.08, rtol=0.01)
    lag1 = np.mean(x[1:] * x[:-1], axis=0) / x.var(axis=0)
    assert np.all(lag1 > 0.5)
    # Whitening with the exact AR polynomial gives the stated innovation std.
    a = spec.ar_polynomial(200.0)
    e = np.convolve(x[:, 0], a, mode="valid")
    assert np.isclose(e.std(), spec.innovation_std(200.0)[0], rtol=0.01)


def test_quantiser_lsb_and_clipping():
    q = Quantiser(full_scale_g=4.0, bits=16)
    assert np.isclose(q.lsb_mps2, 8 * 9.80665 / 65536)
    lo, hi = q.limits_mps2
    out = q.apply(np.array([[100.0, -100.0, 0.1234]]))
    assert out[0, 0] == hi and out[0, 1] == lo
    assert abs(out[0, 2] - 0.1234) <= q.lsb_mps2 / 2


def test_simulation_is_the_model_plus_noise():
    scenario = table1()
    sim = simulate(scenario, np.random.default_rng(3))
    clean = predict(sim.truth, scenario.centred_times_s())
    assert np.allclose(sim.clean_mps2, clean)
    assert sim.recording.samples == 18001
    assert np.isclose(sim.recording.duration_s, 90.0)
    assert np.allclose((sim.recording.accel_mps2 - clean).std(axis=0), 0.08, rtol=0.05)


def test_same_seed_same_recording_different_seed_different():
    a = simulate(table1(), np.random.default_rng(5)).recording.accel_mps2
    b = simulate(table1(), np.random.default_rng(5)).recording.accel_mps2
    c = simulate(table1(), np.random.default_rng(6)).recording.accel_mps2
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_table2_draws_a_new_spin_each_time_and_needs_rng():
    s1 = table2(rng=np.random.default_rng(1)).truth.spin.omega_radps
    s2 = table2(rng=np.random.default_rng(2)).truth.spin.omega_radps
    assert not np.allclose(s1, s2)
    with pytest.raises(ValueError, match="rng"):
        preset("table2")
    with pytest.raises(ValueError, match="unknown preset"):
        preset("table9")


def test_random_setups_cover_both_spin_directions_and_avoid_degenerate_mountings():
    rng = np.random.default_rng(0)
    signs, min_angle = set(), 90.0
    for _ in range(40):
        s = random_setup(rng)
        signs.add(np.sign(s.truth.spin.omega_radps[0]))
        cos = np.abs(s.truth.bench.misalignment.matrix)
        min_angle = min(min_angle, np.rad2deg(np.arccos(cos.max())))
        assert 10.0 <= np.rad2deg(s.truth.bench.tilt_rad) <= 85.0
    assert signs == {-1.0, 1.0}
    assert min_angle >= 15.0
