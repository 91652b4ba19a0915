"""The gain and offset Gram blocks formed per axis equal the dense whitened product.

:mod:`wheelcal.estimate.sensor_gram` leaves the six one-axis columns out of the
whitening and the dense Gram product; here the same buffer is whitened whole
and multiplied densely, under white and coloured noise (orders differing per
axis, correlated innovations), with and without extra columns and a spline.
"""

import numpy as np
import pytest

from wheelcal.estimate.noise_model import NoiseModel
from wheelcal.estimate.normal_equations import (
    _filled_buffer,
    _whitened_gram,
    accumulate,
    sensor_rows,
)
from wheelcal.estimate.systematic import nuisance_columns, nuisance_extra
from wheelcal.model import ParameterLayout
from wheelcal.model.effects import QuadraticNonlinearity, SpinSpline
from wheelcal.simulate import simulate, table1

CORRELATED = np.array([[1.0, 0.3, -0.2], [0.3, 2.0, 0.5], [-0.2, 0.5, 1.5]]) * 1e-2
NOISES = {
    "white": NoiseModel((np.ones(1), np.ones(1), np.ones(1)), CORRELATED),
    "coloured": NoiseModel(
        (np.array([1.0, -0.6, 0.2]), np.ones(1), np.array([1.0, 0.4])), CORRELATED
    ),
}


@pytest.fixture(scope="module")
def session():
    sim = simulate(table1(), np.random.default_rng(5))
    rec = sim.recording
    t = rec.time_s[:3000] - rec.time_s[1500]
    return sim.truth, t, rec.accel_mps2[:3000]


def _dense(buf, residual, noise):
    _, jw = noise.whiten(residual, buf)
    jt = jw.reshape(jw.shape[0], -1)
    return jt @ jt.T


@pytest.mark.parametrize("noise", NOISES.values(), ids=NOISES.keys())
@pytest.mark.parametrize("extras", [False, True])
def test_sensor_blocks_equal_the_dense_product(session, noise, extras):
    params, t, v = session
    layout = ParameterLayout()
    extra = nuisance_extra(nuisance_columns(layout)) if extras else None
    buf, residual, sensed, _ = _filled_buffer(params, t, v, layout, extra, None)
    rows = sensor_rows(layout)
    assert rows == slice(layout.blocks["gain"].start, layout.blocks["offset"].stop)
    fast, entries = _whitened_gram(buf, sensed, noise, rows)
    dense = _dense(buf, residual, noise)
    assert entries == 3 * (t.size - noise.order)
    scale = np.sqrt(np.outer(np.diag(dense), np.diag(dense)))
    assert np.max(np.abs(fast - dense) / scale) < 1e-12


@pytest.mark.parametrize("noise", NOISES.values(), ids=NOISES.keys())
def test_accumulate_with_a_spline_equals_the_dense_product(session, noise):
    params, t, v = session
    spline = SpinSpline(float(t[0]), float(t[-1]), 1.0)
    layout = ParameterLayout(effects=(spline,))
    params = params.with_changes(effects={spline.name: np.zeros(spline.size)})
    normal = accumulate(params, t, v, layout, noise)  # local views, sensor blocks per axis
    buf, residual, _, _ = _filled_buffer(params, t, v, layout, None, None)
    dense = _dense(buf, residual, noise)
    scale = np.sqrt(np.maximum(np.outer(np.diag(dense), np.diag(dense)), 1e-300))
    assert np.max(np.abs(normal.hessian - dense[:-1, :-1]) / scale[:-1, :-1]) < 1e-10
    g = dense[:-1, -1]
    assert np.allclose(normal.gradient, g, rtol=1e-10, atol=1e-10 * np.abs(g).max())


def test_a_sensor_effect_keeps_the_dense_product():
    assert sensor_rows(ParameterLayout(effects=(QuadraticNonlinearity(axis=0),))) is None
