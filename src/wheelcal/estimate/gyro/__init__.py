"""The gyroscope: its calibration on the wheel and the gyro-aided fit's set-up.

The gyro-aided joint fit's set-up and the gyro block of a fit (:mod:`.aided`) are the
estimator's, so that a session only sequences its steps.  A wheel rolling on the
ground (its yaw from the gyro) is the field fit's: :mod:`wheelcal.estimate.field`.
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

__all__ = [
    "GyroAided",
    "choose_knot_spacing",
    "fastest_rate_radps",
    "gyro_aided",
    "gyro_block",
    "gyro_by_product",
    "gyro_from_fit",
    "gyro_rows",
    "regress_gyro",
]
