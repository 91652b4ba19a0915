"""Wheels in the field: a rolling wheel's calibration with the wheel angle from its gyroscope."""
