"""The calibration documents: one typed :class:`Calibration`, its JSON, export and apply.

Layer 6 (above ``session``, below ``viz``).  A session's document
(``wheelcal.calibration/1``, :mod:`.session_json`) and a sensor's pooled one
(``wheelcal.sensor_calibration/1``, :mod:`.sensor_json`) load through one
:meth:`Calibration.from_json`; the closed loop's report (:mod:`.diagnosis_json`);
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
from wheelcal.calibration.session_json import calibration_dict, load_calibration, write_calibration

__all__ = [
    "Calibration",
    "apply_calibration",
    "as_angles",
    "calibration_dict",
    "joint_estimate",
    "load_calibration",
    "read_only_document",
    "rests_allan",
    "sensor_calibration_dict",
    "sensor_calibration_text",
    "session_estimate",
    "to_c_header",
    "to_imu_calib",
    "to_imu_tk",
    "to_yaml",
    "write_calibration",
    "write_diagnosis",
    "write_sensor_calibration",
]
