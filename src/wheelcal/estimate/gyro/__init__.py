"""The gyroscope: its calibration on the wheel, the yaw of a rolling wheel, the rolling fit."""

from wheelcal.estimate.gyro.block import gyro_by_product, gyro_from_fit, regress_gyro
from wheelcal.estimate.gyro.knots import choose_knot_spacing
from wheelcal.estimate.gyro.rolling_fit import fit_window
from wheelcal.estimate.gyro.yaw import demodulate_yaw

__all__ = [
    "choose_knot_spacing",
    "demodulate_yaw",
    "fit_window",
    "gyro_by_product",
    "gyro_from_fit",
    "regress_gyro",
]
