"""Exact algebra of the model: eq. (1), the Jacobian, the twins and the null space (9)–(13)."""

import numpy as np
import pytest

from wheelcal.estimate.joint.twins import choose_twin, to_contract_frame, twin_of
from wheelcal.model import (
    BenchParams,
    CalibrationParams,
    ParameterLayout,
    Rotation,
    SensorParams,
    SpinParams,
    evaluate,
    predict,
)
from wheelcal.simulate import table1


def _params(**kw) -> CalibrationParams:
    base = dict(
        spin=SpinParams(0.3, [9.0, -0.05, 4e-4, 1e-6]),
        bench=BenchParams(np.deg2rad(40.0), 0.28, Rotation.from_euler_deg(30.0, 20.0, 25.0)),
        sensor=SensorParams([0.2, -0.1, 0.3], [0.98, 1.01, 1.03]),
    )
    base.update(kw)
    return CalibrationParams(**base)


def test_eq1_with_identity_misalignment():
    p = _params(
        bench=BenchParams(np.deg2rad(30.0), 0.25, Rotation.identity()),
        sensor=SensorParams([0, 0, 0], [1, 1, 1]),
        spin=SpinParams(0.0, [10.0, -0.2]),
    )
    g = p.gravity_mps2
    v = predict(p, np.array([0.0]))[0]
    # ϑ = 0, ω = 10, ω̇ = −0.2: a = (r ω² + g sinα, r ω̇, g cosα).
    assert np.allclose(v, [0.25 * 100 + g * 0.5, 0.25 * -0.2, g * np.cos(np.deg2rad(30))])


@pytest.mark.parametrize("fit_radius", [False, True])
def test_analytic_jacobian_matches_central_differences(fit_radius):
    p = _params()
    layout = ParameterLayout(fit_tilt=not fit_radius, fit_radius=fit_radius)
    t = np.linspace(-40.0, 40.0, 3001)
    analytic = evaluate(p, t, layout, jacobian=True).jacobian
    x = layout.pack(p)
    for k, name in enumerate(layout.names):
        # Steps scaled so each coefficient moves the phase by ~1e-6 rad at the window edge.
        power = int(name[5]) + 1 if name.startswith("omega") else 0
        h = 1e-6 / 40.0**power
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        fd = (predict(layout.unpack(xp, p), t) - predict(layout.unpack(xm, p), t)).T / (2 * h)
        scale = np.abs(fd).max()
        assert np.abs(analytic[k] - fd).max() < 1e-6 * scale, name


def test_spin_time_shift_describes_the_same_motion():
    spin = SpinParams(0.5, [9.0, -0.09, 5e-4, 2e-6])
    t = np.linspace(0.0, 90.0, 50)
    shifted = spin.shifted(45.0)
    wrap = lambda a: (a + np.pi) % (2 * np.pi) - np.pi  # noqa: E731
    assert np.allclose(wrap(shifted.theta_at(t - 45.0) - spin.theta_at(t)), 0.0, atol=1e-9)
    assert np.allclose(shifted.omega_at(t - 45.0), spin.omega_at(t))


def test_table1_preset_is_start_time_converted_to_centre():
    truth = table1().truth.spin
    # Start-time profile: ω(0) = 9, dips near 65 s, ω(90) = 6.408 rad/s.
    assert np.isclose(truth.omega_at(np.array([-45.0]))[0], 9.0)
    assert np.isclose(truth.omega_at(np.array([45.0]))[0], 9 - 8.1 + 4.05 + 1.458)
    assert np.isclose(truth.omega_radps[3], 2e-6)


def test_discrete_twin_is_an_exact_symmetry_and_smaller_offset_wins():
    p = _params()
    t = np.linspace(-30, 30, 2000)
    twin = twin_of(p)
    assert np.allclose(predict(twin, t), predict(p, t), atol=1e-10)
    choice = choose_twin(twin)
    assert np.allclose(choice.chosen.sensor.offset_mps2, p.sensor.offset_mps2, atol=1e-12)
    assert not choice.ambiguous


def test_contract_frame_folds_tilt_without_changing_the_signal():
    p = _params()
    t = np.linspace(-30, 30, 500)
    for tilt in (np.deg2rad(130.0), np.deg2rad(-50.0), np.deg2rad(400.0)):
        q = p.with_changes(bench=BenchParams(tilt, p.bench.radius_m, p.bench.misalignment))
        c = to_contract_frame(q)
        assert 0.0 <= c.bench.tilt_rad <= np.pi / 2
        assert np.allclose(predict(c, t), predict(q, t), atol=1e-9)


def test_twin_ambiguity_flagged_near_vertical_wheel():
    p = _params(bench=BenchParams(np.deg2rad(88.0), 0.28, Rotation.from_euler_deg(30, 20, 25)))
    assert choose_twin(p).ambiguous


def test_null_space_of_eq_9_to_13_leaves_the_data_unchanged():
    """Why r must be known: scaling r, sinα and 1/Γ and shifting o_z gives the same v(t)."""
    p = _params(bench=BenchParams(np.deg2rad(40.0), 0.28, Rotation.identity()))
    beta = 1.05
    alpha2 = np.arcsin(beta * np.sin(p.bench.tilt_rad))
    gain2 = p.sensor.gain / beta
    g = p.gravity_mps2
    dz = gain2[2] * g * np.cos(alpha2) - p.sensor.gain[2] * g * np.cos(p.bench.tilt_rad)
    q = p.with_changes(
        bench=BenchParams(alpha2, 0.28 * beta, Rotation.identity()),
        sensor=SensorParams(p.sensor.offset_mps2 - [0, 0, dz], gain2),
    )
    t = np.linspace(-30, 30, 1000)
    assert np.allclose(predict(q, t), predict(p, t), atol=1e-10)


def test_parameters_validate_themselves():
    with pytest.raises(ValueError, match="gains must be positive"):
        SensorParams([0, 0, 0], [1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="3 values"):
        SensorParams([0, 0], [1, 1, 1])
    with pytest.raises(ValueError, match="both be free"):
        ParameterLayout(fit_tilt=True, fit_radius=True)


def test_layout_pack_unpack_round_trip():
    p = _params()
    layout = ParameterLayout()
    x = layout.pack(p)
    assert len(x) == layout.size == 15
    q = layout.unpack(x, p)
    assert np.allclose(predict(q, np.linspace(-5, 5, 50)), predict(p, np.linspace(-5, 5, 50)))
    assert layout.names[layout.index("gain_y")] == "gain_y"


def test_equal_offset_twins_report_positive_spin():
    """A vertical wheel (α = 90°): both twins share the offsets; the positive spin is kept."""
    p = _params(bench=BenchParams(np.pi / 2, 0.28, Rotation.from_euler_deg(30, 20, 25)))
    negative = twin_of(p)
    assert negative.spin.omega_radps[0] < 0
    for start in (p, negative):
        choice = choose_twin(start)
        assert choice.chosen.spin.omega_radps[0] > 0 and choice.ambiguous


@pytest.mark.parametrize(
    ("degree", "fit_tilt", "fit_radius"),
    [(3, True, False), (3, False, True), (2, False, False), (1, True, False), (0, True, False)],
)
def test_jacobian_transpose_times_equals_the_jacobians_product(degree, fit_tilt, fit_radius):
    from wheelcal.model.forward import jacobian_transpose_times

    spin = SpinParams(0.3, [9.0, -0.05, 4e-4, 1e-6][: degree + 1])
    params = _params(spin=spin)
    layout = ParameterLayout(spin_degree=degree, fit_tilt=fit_tilt, fit_radius=fit_radius)
    t = np.linspace(-20.0, 20.0, 3001)
    weights = np.random.default_rng(4).normal(size=(3, t.size))
    full = evaluate(params, t, layout, jacobian=True)
    expected = full.jacobian.reshape(layout.size, -1) @ weights.reshape(-1)
    got = jacobian_transpose_times(params, t, layout, weights, evaluate(params, t, layout))
    scale = np.sqrt(np.sum(full.jacobian.reshape(layout.size, -1) ** 2, axis=1) * t.size)
    np.testing.assert_allclose(got / scale, expected / scale, rtol=0, atol=1e-12)
    assert np.all(np.abs(expected / scale) > 1e-6)  # every entry is tested, none is zero


@pytest.mark.parametrize("per_sample_w", [False, True])
def test_spin_rows_to_v_equals_the_straightforward_sums(per_sample_w):
    """The batched W[:, :2] product (constant W) and the per-axis loop (W per sample)."""
    from wheelcal.model.bench import bench_force
    from wheelcal.model.forward import _spin_rows_to_v
    from wheelcal.model.kinematics import spin_kinematics

    p = _params()
    t = np.linspace(-40.0, 40.0, 2001)
    kin = spin_kinematics(p.spin, t, derivatives=True)
    force = bench_force(kin, p.bench.tilt_rad, p.bench.radius_m, p.gravity_mps2)
    w = p.sensor.gain[:, None] * p.bench.misalignment.matrix
    rng = np.random.default_rng(3)
    w3 = w[:, :, None] + (rng.normal(0, 0.01, (3, 3, t.size)) if per_sample_w else 0.0)
    rows = (kin.d_theta, kin.d_omega, kin.d_omega_dot)
    got = _spin_rows_to_v(w3, force, rows, kin.omega_radps, p.bench.radius_m)
    r, g_sin = p.bench.radius_m, force.g_sin_tilt
    dax = -g_sin * np.sin(kin.theta_rad) * kin.d_theta + 2 * r * kin.omega_radps * kin.d_omega
    day = g_sin * np.cos(kin.theta_rad) * kin.d_theta + r * kin.d_omega_dot
    expected = np.stack([w3[i, 0] * dax + w3[i, 1] * day for i in range(3)], axis=1)
    scale = np.abs(expected).max(axis=(1, 2))[:, None, None]
    np.testing.assert_allclose(got / scale, expected / scale, rtol=0, atol=1e-14)
