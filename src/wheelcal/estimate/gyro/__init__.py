"""The gyroscope: its calibration on the wheel, the yaw of a rolling wheel, the rolling fit.

The gyro-aided joint fit's set-up and the gyro block of a fit (:mod:`.aided`) are the
estimator's, so that a session only sequences its steps.
"""

from wheelcal.estimate.gyro.aided import (
    GyroAided,
    fastest_rate_radps,
    gyro_aided,
    gyro_block,
    gyro_rows,
)
from wheelcal.estimate.gyro.block import gyro_by_product, gyro_from_fit, regress_gyro
from wheelcal.estimate.gyro.knots import choose_knot_spacing
from wheelcal.estimate.gyro.rolling_fit import fit_window
from wheelcal.estimate.gyro.yaw import demodulate_yaw

__all__ = [
    "GyroAided",
    "choose_knot_spacing",
    "demodulate_yaw",
    "fastest_rate_radps",
    "fit_window",
    "gyro_aided",
    "gyro_block",
    "gyro_by_product",
    "gyro_from_fit",
    "gyro_rows",
    "regress_gyro",
]
