"""The physical model: bench motion and sensor (pure numpy, no I/O).

Layer 1.  The front other packages import from: the parameters and their layout
(:mod:`.parameters`, :mod:`.layout`, :mod:`.rotation`), the forward model and its
derivatives — columns and the adjoint passes the normal equations are built from
(:mod:`.forward`), the effects beyond the paper's model (:mod:`.effects`,
:mod:`.temperature_offset`), the kinematics of a spun or rolling wheel
(:mod:`.kinematics`, :mod:`.bench`, :mod:`.rolling`, :mod:`.gyro_angle`), the
AR(1) noise filter (:mod:`.ar_process`) and a sensor's correction (:mod:`.correction`).
"""

from wheelcal.model.ar_process import ar_variance_gain, fir_filter
from wheelcal.model.bench import BenchForce, bench_force
from wheelcal.model.correction import SensorCorrection
from wheelcal.model.effects import (
    G_SENSITIVITY_PRIOR_DPS_PER_G,
    CrossAxis,
    Effect,
    GyroReading,
    OffsetWarmup,
    SpinSpline,
    cubic_bspline_basis,
    cubic_bspline_slots,
    default_candidates,
    intrinsic_candidates,
    make_effect,
)
from wheelcal.model.forward import (
    EvaluatedModel,
    ModelOutput,
    ReverseAt,
    candidate_columns,
    evaluate,
    jacobian_transpose_times,
    nuisance_sensitivity,
    output_at_samples,
    predict,
    reverse_pass,
    spin_adjoint,
    spin_columns,
    wheel_kinematics,
)
from wheelcal.model.gyro_angle import GyroAngle
from wheelcal.model.kinematics import Kinematics, spin_kinematics
from wheelcal.model.layout import GAIN_NAMES, OFFSET_NAMES, ParameterLayout
from wheelcal.model.parameters import (
    AXES,
    STANDARD_GRAVITY_MPS2,
    BenchParams,
    CalibrationParams,
    SensorParams,
    SpinParams,
    spin_coefficient_names,
)
from wheelcal.model.rolling import Rolling
from wheelcal.model.rotation import EULER_CONVENTION, Rotation, exp_so3, hat
from wheelcal.model.temperature_offset import temperature_candidates

__all__ = [
    "AXES",
    "EULER_CONVENTION",
    "GAIN_NAMES",
    "G_SENSITIVITY_PRIOR_DPS_PER_G",
    "OFFSET_NAMES",
    "STANDARD_GRAVITY_MPS2",
    "BenchForce",
    "BenchParams",
    "CalibrationParams",
    "CrossAxis",
    "Effect",
    "EvaluatedModel",
    "GyroAngle",
    "GyroReading",
    "Kinematics",
    "ModelOutput",
    "OffsetWarmup",
    "ParameterLayout",
    "ReverseAt",
    "Rolling",
    "Rotation",
    "SensorCorrection",
    "SensorParams",
    "SpinParams",
    "SpinSpline",
    "ar_variance_gain",
    "bench_force",
    "candidate_columns",
    "cubic_bspline_basis",
    "cubic_bspline_slots",
    "default_candidates",
    "evaluate",
    "exp_so3",
    "fir_filter",
    "hat",
    "intrinsic_candidates",
    "jacobian_transpose_times",
    "make_effect",
    "nuisance_sensitivity",
    "output_at_samples",
    "predict",
    "reverse_pass",
    "spin_adjoint",
    "spin_coefficient_names",
    "spin_columns",
    "spin_kinematics",
    "temperature_candidates",
    "wheel_kinematics",
]
