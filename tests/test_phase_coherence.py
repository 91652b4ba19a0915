"""The gyro-aided start's grid search: the running product against the direct sums."""

import numpy as np

from wheelcal.estimate.joint.initial import _coherence


def test_the_running_product_equals_the_direct_sums():
    rng = np.random.default_rng(4)
    angle = np.cumsum(rng.uniform(0.0, 0.1, 800))
    z = np.exp(1j * (1.013 * angle + 0.4)) + 0.1 * rng.normal(size=800)
    for first, step in ((0.94, 5e-4), (-0.94, -5e-4)):
        grid = first + step * np.arange(240)
        direct = np.abs(np.exp(-1j * np.outer(grid, angle)) @ z)
        got = _coherence(z, angle, first, step, grid.size)
        assert np.allclose(got, direct, rtol=1e-9, atol=1e-9 * direct.max())
    assert abs(0.94 + 5e-4 * np.argmax(_coherence(z, angle, 0.94, 5e-4, 240)) - 1.013) < 1e-3
