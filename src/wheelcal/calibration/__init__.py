"""The calibration documents: one typed :class:`Calibration`, its JSON, export and apply.

Layer 7 (above ``session``, beside ``viz``).  A session's document
(``wheelcal.calibration/1``, :mod:`.session_json`) and a sensor's pooled one
(``wheelcal.sensor_calibration/1``, :mod:`.sensor_json`) load through one
:meth:`Calibration.from_json`; the closed loop's report (:mod:`.diagnosis_json`);
the exports a ROS node, Kalibr or firmware read (:mod:`.export`); a calibrated copy
of a recording (:mod:`.apply`).
"""

from wheelcal.calibration.document import Calibration

__all__ = ["Calibration"]
