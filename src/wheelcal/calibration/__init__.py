"""The calibration documents: one typed :class:`Calibration`, its JSON, export and apply.

Layer 6 (above ``session``, below ``viz``).  A session's document
(``wheelcal.calibration/1``, :mod:`.session_json`) and a sensor's pooled one
(``wheelcal.sensor_calibration/1``, :mod:`.sensor_json`) load through one
:meth:`Calibration.from_json`; :meth:`Calibration.compute` is the one session
function and :meth:`Calibration.write` (:mod:`.session_files`) the one writer of a
session's files, :func:`calibrate_into` (:mod:`.session_outcome`) both, a failure
turned into a :class:`SessionOutcome`; the typed values a :class:`Calibration`
carries (:mod:`.values`: :class:`CalibrationDiagnosis`, :class:`AddedEffect`,
:class:`CalibrationFacts`), which also write its document; the
closed loop's report (:mod:`.diagnosis_json`);
the exports a ROS node, Kalibr or firmware read (:mod:`.export`); a calibrated copy
of a recording (:mod:`.apply`).
"""

from wheelcal.calibration.allan_json import rests_allan
from wheelcal.calibration.angles import as_angles
from wheelcal.calibration.apply import apply_calibration
from wheelcal.calibration.diagnosis_json import write_diagnosis
from wheelcal.calibration.document import Calibration, read_only_document
from wheelcal.calibration.export import to_c_header, to_imu_calib, to_imu_tk, to_yaml
from wheelcal.calibration.sensor_json import (
    joint_estimate,
    sensor_calibration_dict,
    sensor_calibration_text,
    session_estimate,
    write_sensor_calibration,
)
from wheelcal.calibration.session_files import (
    WrittenFiles,
    keep_as_stale,
    session_outputs,
    session_stem,
    write_session_files,
)
from wheelcal.calibration.session_json import calibration_dict, load_calibration, write_calibration
from wheelcal.calibration.session_outcome import SessionOutcome, calibrate_into, failed_outcome
from wheelcal.calibration.values import AddedEffect, CalibrationDiagnosis, CalibrationFacts

__all__ = [
    "AddedEffect",
    "Calibration",
    "CalibrationDiagnosis",
    "CalibrationFacts",
    "SessionOutcome",
    "WrittenFiles",
    "apply_calibration",
    "as_angles",
    "calibrate_into",
    "calibration_dict",
    "failed_outcome",
    "joint_estimate",
    "keep_as_stale",
    "load_calibration",
    "read_only_document",
    "rests_allan",
    "sensor_calibration_dict",
    "sensor_calibration_text",
    "session_estimate",
    "session_outputs",
    "session_stem",
    "to_c_header",
    "to_imu_calib",
    "to_imu_tk",
    "to_yaml",
    "write_calibration",
    "write_diagnosis",
    "write_sensor_calibration",
    "write_session_files",
]
