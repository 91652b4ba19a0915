"""The field fit's camber passes: their mixing settles a map with a slow direction.

The passes iterate x → G(x) (the wheel angle the track is read at, and the camber the
gyro angle takes).  On a car drive G has a slow direction (a damped step alone took
10–25 passes on every sample) and one that overshoots (a full step grew without bound on
one drive).  The oracle here is a linear map with both, whose fixed point is solved
directly.
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.field.fit import CONSISTENT_STEP, _mixed_step


def _linear_map(rng: np.random.Generator):
    """G(x) = A x + b with A's eigenvalues 0.95 (slow), −0.9 (overshooting) and 0.3."""
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    a = q @ np.diag([0.95, -0.9, 0.3]) @ q.T
    b = rng.normal(size=3)
    return a, b, np.linalg.solve(np.eye(3) - a, b), q


def _passes(a, b, x, count: int) -> np.ndarray:
    history: list = []
    for _ in range(count):
        history, x = _mixed_step(history, x, a @ x + b - x)
    return x


def test_the_mixed_passes_settle_where_a_damped_step_alone_does_not():
    rng = np.random.default_rng(7)
    for _ in range(5):
        a, b, fixed, modes = _linear_map(rng)
        start = fixed + modes @ rng.uniform(0.5, 1.0, 3)  # every direction's share
        error = np.linalg.norm(_passes(a, b, start, 8) - fixed) / np.linalg.norm(start - fixed)
        assert error < 1e-6, error
        # the damped step alone: the slow direction contracts by 1 − β (1 − 0.95) a pass
        damped = start.copy()
        for _ in range(8):
            damped = damped + CONSISTENT_STEP * (a @ damped + b - damped)
        assert np.linalg.norm(damped - fixed) / np.linalg.norm(start - fixed) > 0.3


def test_the_first_pass_is_the_damped_step():
    history, x = _mixed_step([], np.array([1.0, 2.0]), np.array([2.0, -4.0]))
    np.testing.assert_allclose(x, [1.0 + 2.0 * CONSISTENT_STEP, 2.0 - 4.0 * CONSISTENT_STEP])
    assert len(history) == 1
