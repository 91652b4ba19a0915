"""The typed calibration object of the Python API (it lives in :mod:`wheelcal.io.calibration`)."""

from wheelcal.io.calibration import Calibration

__all__ = ["Calibration"]
