"""The discrete twin and the contract frame keep the data with motion effects and the gyro.

Under (α, R, o, ϑ) → (α, R·diag(1,−1,−1), o + 2g cosα ΓRe_Z, −ϑ) the accelerometer
data are identical; the effects that follow the phase (a spline correction, higher
spin coefficients, an imbalance) and the gyro's w must be mirrored with it, or the
twin would not be the same model.  Exact algebra: predictions equal to 1e-9.
"""

import numpy as np
import pytest

from wheelcal.estimate.joint.gyro_equations import gyro_prediction
from wheelcal.estimate.joint.twins import to_contract_frame, twin_of
from wheelcal.model import (
    BenchParams,
    CalibrationParams,
    ParameterLayout,
    Rotation,
    SensorParams,
    SpinParams,
    predict,
)
from wheelcal.model.effects import GyroReading, Imbalance, SpinPolynomialExtension, SpinSpline


def _params(tilt_deg: float) -> tuple[CalibrationParams, ParameterLayout]:
    spline = SpinSpline(-30.0, 30.0, 10.0)
    rng = np.random.default_rng(3)
    effects = {
        spline.name: rng.normal(0, 0.05, spline.size),
        "spin_extension": np.array([1e-7, -2e-9]),
        "imbalance": np.array([0.2, -0.3]),
        "gyro": np.array(
            [-0.3, 0.5, -0.8, 0.01, -0.02, 0.003, 2e-4, -1e-4, 5e-5, 1e-4, 2e-4, -3e-5]
        ),
    }
    params = CalibrationParams(
        spin=SpinParams(theta0_rad=0.4, omega_radps=(9.0, -0.05, 2e-4, 1e-6)),
        bench=BenchParams(np.deg2rad(tilt_deg), 0.28, Rotation.from_euler_deg(20, 30, 40)),
        sensor=SensorParams(offset_mps2=(0.1, -0.2, 0.3), gain=(1.01, 0.99, 1.02)),
        effects=effects,
    )
    layout = ParameterLayout(
        effects=(spline, SpinPolynomialExtension(), Imbalance(), GyroReading())
    )
    return params, layout


@pytest.mark.parametrize("tilt_deg", [30.0, 120.0, -40.0])
def test_twin_and_contract_frame_keep_accelerometer_and_gyro_data(tilt_deg):
    params, layout = _params(tilt_deg)
    t = np.linspace(-30, 30, 3001)
    v = predict(params, t, layout)
    w = gyro_prediction(params, t, layout)
    for other in (twin_of(params), to_contract_frame(params)):
        np.testing.assert_allclose(predict(other, t, layout), v, atol=1e-9)
        np.testing.assert_allclose(gyro_prediction(other, t, layout), w, atol=1e-9)
