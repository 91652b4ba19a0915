"""Wheels in the field: a rolling wheel's calibration with the wheel angle from its gyroscope."""

from wheelcal.estimate.field.fit import YAW_RMS_RADPS, FieldFit, FieldResult
from wheelcal.estimate.field.gyro_axle import gyro_axle
from wheelcal.estimate.field.lean_check import LeanCheck

__all__ = ["YAW_RMS_RADPS", "FieldFit", "FieldResult", "LeanCheck", "gyro_axle"]
