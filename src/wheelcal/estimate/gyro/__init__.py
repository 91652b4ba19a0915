"""The gyroscope: its calibration on the wheel, the yaw of a rolling wheel, the rolling fit."""
