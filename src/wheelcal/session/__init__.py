"""One recording end to end: its window, the fit, the closed loop, the checks and the gates.

Layer 5 (above ``closedloop``, below ``calibration``).  :mod:`.compute` turns a
recording and the options into a calibration's result (no files); :mod:`.fit` is
the sequence (window → joint fit → closed loop → motion check → gates), with the
window search (:mod:`.window`), the noise reference (:mod:`.noise_reference`), the
motion and rest checks and the gates (:mod:`.gates`).
"""

from wheelcal.session.compute import (
    SESSION_GEOMETRIES,
    SessionOptions,
    compute_recording,
    compute_session,
)
from wheelcal.session.gates import Assessment, Gates
from wheelcal.session.result import CamberTrackReport, LeanReport, SessionResult
from wheelcal.session.window import FreeSpinWindow, fitted_stretches

__all__ = [
    "SESSION_GEOMETRIES",
    "Assessment",
    "CamberTrackReport",
    "FreeSpinWindow",
    "Gates",
    "LeanReport",
    "SessionOptions",
    "SessionResult",
    "compute_recording",
    "compute_session",
    "fitted_stretches",
]
