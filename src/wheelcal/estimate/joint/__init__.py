"""The joint maximum-likelihood fit of every parameter at once (:mod:`.fit`) and its parts.

The front other packages import from: the fit (:class:`JointFit`), its frozen result
(:class:`CalibrationResult`), its start (:class:`InitialGuess`, whose
:meth:`~InitialGuess.implied_mean_gain` a session checks before fitting) and the noise
model (:class:`NoiseModel`); the refits without what the model cannot explain
(:func:`without_disturbances`, :func:`clear_of_rails`); the normal equations with a
wheel-angle spline that a freed motion asks for (:func:`normal_with_spline`: its chunks
and quadrature stay here); the bounds and checks on a design — the Cramér–Rao bound,
identifiability, twins, the systematic budget, the reported transforms; and the
building blocks the closed loop's score tests and the planner assemble their own normal
equations from — the chunked accumulation (:data:`CHUNK_SAMPLES`, :func:`accumulate`),
the Fisher information by quadrature (:func:`quadrature_rows`, :func:`stride_for`), the
gyroscope's equations and rests, the candidate columns and the pseudo-inverse of an
information matrix; a fit's wheel angle at every sample (:func:`wheel_angle_rad`).
The sibling subsystems (``field``, ``gyro``, ``paper``) and the rests import from
here too: the effects' priors (:func:`effect_priors`), the start's gains
(:func:`scaled_gains`), the gyro's prediction and regressed start
(:func:`gyro_prediction`, :func:`with_gyro_start`) and the column sums of a block of
samples (:func:`column_means`, :func:`centred_rows`).
"""

from wheelcal.estimate.joint.candidate_columns import candidate_extra, lean_scores
from wheelcal.estimate.joint.columns import centred_rows, column_means
from wheelcal.estimate.joint.crlb import Bound, cramer_rao_bound
from wheelcal.estimate.joint.decimation import SAMPLES_PER_TURN, decimation_stride
from wheelcal.estimate.joint.fisher_quadrature import (
    QuadratureRows,
    quadrature_rows,
    stride_for,
    whitened_rows,
)
from wheelcal.estimate.joint.fit import GEOMETRY_MODES, JointFit, gyro_samples, with_gyro_start
from wheelcal.estimate.joint.freed_check import FreedCheck
from wheelcal.estimate.joint.gyro_equations import accumulate_gyro, gyro_effect, gyro_prediction
from wheelcal.estimate.joint.gyro_rests import GyroRests
from wheelcal.estimate.joint.identifiability import Identifiability, check_identifiability
from wheelcal.estimate.joint.information import (
    block_information_fraction,
    covariance_from_fisher,
    scaled_pinv,
)
from wheelcal.estimate.joint.initial import InitialGuess, scaled_gains
from wheelcal.estimate.joint.levenberg_marquardt import levenberg_marquardt
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.normal_equations import (
    CHUNK_SAMPLES,
    NormalEquations,
    accumulate,
    effect_priors,
    quadrature_hessian,
    whitened_back,
)
from wheelcal.estimate.joint.refit import clear_of_rails, without_disturbances
from wheelcal.estimate.joint.reporting import report_transform, transform_covariance
from wheelcal.estimate.joint.result import CalibrationResult
from wheelcal.estimate.joint.rotating import revolution_mean, rotating_phase
from wheelcal.estimate.joint.spline_normal import normal_with_spline
from wheelcal.estimate.joint.systematic import (
    DEFAULT_CLOCK_STD_PPM,
    DEFAULT_GRAVITY_STD_MPS2,
    GIVEN_GRAVITY_STD_MPS2,
    SystematicBudget,
    nuisance_columns,
    nuisance_extra,
    systematic_budget,
)
from wheelcal.estimate.joint.twins import choose_twin
from wheelcal.estimate.joint.wheel_angle import wheel_angle_rad

__all__ = [
    "CHUNK_SAMPLES",
    "DEFAULT_CLOCK_STD_PPM",
    "DEFAULT_GRAVITY_STD_MPS2",
    "GEOMETRY_MODES",
    "GIVEN_GRAVITY_STD_MPS2",
    "SAMPLES_PER_TURN",
    "Bound",
    "CalibrationResult",
    "FreedCheck",
    "GyroRests",
    "Identifiability",
    "InitialGuess",
    "JointFit",
    "NoiseModel",
    "NormalEquations",
    "QuadratureRows",
    "SystematicBudget",
    "accumulate",
    "accumulate_gyro",
    "block_information_fraction",
    "candidate_extra",
    "centred_rows",
    "check_identifiability",
    "choose_twin",
    "clear_of_rails",
    "column_means",
    "covariance_from_fisher",
    "cramer_rao_bound",
    "decimation_stride",
    "effect_priors",
    "gyro_effect",
    "gyro_prediction",
    "gyro_samples",
    "lean_scores",
    "levenberg_marquardt",
    "normal_with_spline",
    "nuisance_columns",
    "nuisance_extra",
    "quadrature_hessian",
    "quadrature_rows",
    "report_transform",
    "revolution_mean",
    "rotating_phase",
    "scaled_gains",
    "scaled_pinv",
    "stride_for",
    "systematic_budget",
    "transform_covariance",
    "wheel_angle_rad",
    "whitened_back",
    "whitened_rows",
    "with_gyro_start",
    "without_disturbances",
]
