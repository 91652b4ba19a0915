import numpy as np
import pytest

from wheelcal.model.rotation import Rotation, exp_so3, hat, log_so3


def test_exp_log_round_trip_including_near_pi():
    rng = np.random.default_rng(0)
    for angle in [1e-9, 1e-3, 0.5, 2.0, np.pi - 1e-6, np.pi - 1e-3]:
        axis = rng.standard_normal(3)
        axis /= np.linalg.norm(axis)
        m = exp_so3(angle * axis)
        assert np.allclose(m.T @ m, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(m), 1.0)
        assert np.allclose(exp_so3(log_so3(m)), m, atol=1e-9)


def test_hat_is_cross_product():
    a, b = np.array([1.0, -2.0, 0.5]), np.array([0.3, 0.1, -4.0])
    assert np.allclose(hat(a) @ b, np.cross(a, b))


def test_euler_convention_round_trip_and_definition():
    r = Rotation.from_euler_deg(30.0, 20.0, 25.0)
    assert np.allclose(r.euler_deg(), [30.0, 20.0, 25.0])
    # R = Rz(e1) Ry(e2) Rx(e3): the first column is Rz Ry e_x.
    e1, e2 = np.deg2rad([30.0, 20.0])
    assert np.allclose(
        r.matrix[:, 0], [np.cos(e1) * np.cos(e2), np.sin(e1) * np.cos(e2), -np.sin(e2)]
    )


def test_rotation_rejects_reflections_and_non_orthogonal():
    with pytest.raises(ValueError, match="proper rotation"):
        Rotation(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="proper rotation"):
        Rotation(np.eye(3) * 1.1)


def test_euler_jacobian_matches_finite_difference_of_right_perturbation():
    r = Rotation.from_euler_deg(-40.0, 10.0, 70.0)
    jac = r.euler_jacobian_deg()
    h = 1e-5
    for k in range(3):
        d = np.zeros(3)
        d[k] = h
        fd = (r.perturbed(d).euler_deg() - r.perturbed(-d).euler_deg()) / (2 * h)
        assert np.allclose(jac[:, k], fd, rtol=1e-5, atol=1e-5)


def test_euler_jacobian_closed_form_matches_central_differences_everywhere():
    # The closed form E⁻¹ against central differences of euler_deg, over the whole
    # range including e₂ near ±90° (closed form down to |cos e₂| = 1e-3, then the
    # differences themselves, whose own truncation error grows there).
    rng = np.random.default_rng(4)
    angles = [(e, 1e-8) for e in rng.uniform([-180, -89, -180], [180, 89, 180], (50, 3))]
    for euler, rtol in [*angles, ([10.0, 89.9, -30.0], 1e-6)]:
        r = Rotation.from_euler_deg(*euler)
        jac = r.euler_jacobian_deg()
        fd = r._euler_jacobian_differences()
        assert np.max(np.abs(jac - fd)) < rtol * np.max(np.abs(jac))
    locked = Rotation.from_euler_deg(10.0, 90.0, 0.0)
    assert np.array_equal(locked.euler_jacobian_deg(), locked._euler_jacobian_differences())


def test_composed_is_the_constructor_without_validation():
    r = Rotation.from_euler_deg(-40.0, 10.0, 70.0)
    product = r.matrix @ exp_so3(np.array([0.01, -0.02, 0.3]))
    assert np.array_equal(Rotation.composed(product).matrix, Rotation(product).matrix)
    assert not Rotation.composed(product).matrix.flags.writeable
    # Re-orthonormalised: round-off never accumulates over many perturbations.
    walked = r
    for _ in range(1000):
        walked = walked.perturbed(np.array([1e-3, 2e-3, -3e-3]))
    assert np.max(np.abs(walked.matrix.T @ walked.matrix - np.eye(3))) < 1e-14


def test_nearest_rotation_of_a_noisy_matrix():
    r = Rotation.from_euler_deg(10.0, -5.0, 3.0)
    noisy = r.matrix + 1e-3 * np.random.default_rng(1).standard_normal((3, 3))
    assert r.angle_to(Rotation.nearest(noisy)) < 3e-3
