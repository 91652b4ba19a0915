"""Effect library: exact Jacobians, zero = absent, and the algebra of each effect."""

import numpy as np
import pytest

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
from wheelcal.model.effects import (
    CrossAxis,
    GainDrift,
    Imbalance,
    OffsetDrift,
    OffsetWarmup,
    QuadraticNonlinearity,
    SpinPolynomialExtension,
    default_candidates,
)

VALUES = {
    "spin_extension": [2e-8, -3e-10],
    "imbalance": [0.12, -0.08],
    "nonlinearity_x": [1e-3],
    "nonlinearity_y": [-5e-4],
    "nonlinearity_z": [8e-4],
    "offset_warmup": [0.05, -0.08, 0.1],
    "offset_drift": [1e-3, -2e-3, 5e-4],
    "gain_drift": [1e-5, -2e-5, 3e-5],
    "cross_axis": [0.01, -0.02, 0.015],
}


def _base() -> CalibrationParams:
    return CalibrationParams(
        spin=SpinParams(0.3, [9.0, -0.05, 4e-4, 1e-6]),
        bench=BenchParams(np.deg2rad(40.0), 0.28, Rotation.from_euler_deg(30.0, 20.0, 25.0)),
        sensor=SensorParams([0.2, -0.1, 0.3], [0.98, 1.01, 1.03]),
    )


def _fd_step(name: str) -> float:
    if name.startswith("omega"):
        power = int(name[5:].split("_")[0]) + 1
        return 1e-6 / 40.0**power
    return 1e-6 if "per_s" not in name else 1e-9


@pytest.mark.parametrize(
    "effect",
    [
        SpinPolynomialExtension(),
        Imbalance(),
        QuadraticNonlinearity(0),
        QuadraticNonlinearity(2),
        OffsetWarmup(25.0),
        OffsetDrift(),
        GainDrift(),
        CrossAxis(),
    ],
    ids=lambda e: e.label(),
)
def test_jacobian_with_a_nonzero_effect_matches_central_differences(effect):
    p = _base().with_changes(effects={effect.name: VALUES[effect.name]})
    layout = ParameterLayout(effects=(effect,))
    t = np.linspace(-40.0, 40.0, 2001)
    analytic = evaluate(p, t, layout, jacobian=True).jacobian
    x = layout.pack(p)
    for k, name in enumerate(layout.names):
        h = _fd_step(name.split(".")[-1])
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        fd = (
            predict(layout.unpack(xp, p), t, layout) - predict(layout.unpack(xm, p), t, layout)
        ).T / (2 * h)
        scale = np.abs(fd).max()
        assert np.abs(analytic[k] - fd).max() < 1e-5 * scale + 1e-12, name


@pytest.mark.parametrize("effect", default_candidates(), ids=lambda e: e.label())
def test_zero_means_absent(effect):
    p = _base()
    t = np.linspace(-40, 40, 500)
    layout = ParameterLayout(effects=(effect,))
    assert np.array_equal(predict(p, t), predict(p, t, layout))


def test_imbalance_first_order_motion_matches_the_ode():
    """Δϑ = −(a sinϑ + b cosϑ)/ω² against a direct integration of ϑ̈ = ω̇₀ + a sinϑ + b cosϑ."""
    from scipy.integrate import solve_ivp

    spin = SpinParams(0.3, [9.0, -0.05, 0.0, 0.0])
    a, b = 0.15, -0.05
    eff = Imbalance()
    t = np.linspace(-40, 40, 4001)
    from wheelcal.model.kinematics import spin_kinematics

    kin = spin_kinematics(spin, t)
    d = eff.spin_delta(np.array([a, b]), t, kin, False)
    theta0, omega0 = kin.theta_rad[0] + d.theta[0], kin.omega_radps[0] + d.omega[0]

    def rhs(tt, y):
        return [y[1], spin.omega_radps[1] + a * np.sin(y[0]) + b * np.cos(y[0])]

    sol = solve_ivp(rhs, (t[0], t[-1]), [theta0, omega0], t_eval=t, rtol=1e-11, atol=1e-11)
    error = (sol.y[0] - kin.theta_rad) - d.theta
    # Slowly varying differences are absorbed by the spin polynomial (eq. 2): remove a
    # quartic phase; what is left of the first-order error is ≪ the effect (~3 mrad).
    error -= np.polynomial.polynomial.polyval(t, np.polynomial.polynomial.polyfit(t, error, 4))
    assert np.abs(d.theta).max() > 1e-3
    assert np.abs(error).max() < 0.03 * np.abs(d.theta).max()


def test_warmup_is_zero_at_the_centre_and_saturates():
    w = OffsetWarmup(25.0)
    t = np.array([-45.0, 0.0, 45.0, 1e4])
    shape = w.shape(t)
    assert shape[1] == 0.0 and np.isclose(shape[3], 1.0) and shape[0] < 0 < shape[2]


def test_cross_axis_makes_the_sensor_matrix_general():
    p = _base().with_changes(effects={"cross_axis": [0.01, -0.02, 0.015]})
    cross = CrossAxis()
    t = np.linspace(-5, 5, 20)
    v = predict(p, t, effects=(cross,))
    out = evaluate(_base(), t)
    lower = cross.matrix(np.array([0.01, -0.02, 0.015]))
    expected = p.sensor.offset_mps2 + (out.sensed_mps2 @ (np.eye(3) + lower).T) * p.sensor.gain
    assert np.allclose(v, expected)
