"""The physical model: bench motion and sensor (pure numpy, no I/O)."""

from wheelcal.model.forward import ModelOutput, evaluate, nuisance_sensitivity, predict
from wheelcal.model.layout import ParameterLayout
from wheelcal.model.parameters import (
    STANDARD_GRAVITY_MPS2,
    BenchParams,
    CalibrationParams,
    SensorParams,
    SpinParams,
)
from wheelcal.model.rotation import EULER_CONVENTION, Rotation

__all__ = [
    "EULER_CONVENTION",
    "STANDARD_GRAVITY_MPS2",
    "BenchParams",
    "CalibrationParams",
    "ModelOutput",
    "ParameterLayout",
    "Rotation",
    "SensorParams",
    "SpinParams",
    "evaluate",
    "nuisance_sensitivity",
    "predict",
]
