"""The typed recording between the readers and the estimators, and its own checks.

Layer 2 (above ``model``): :class:`Recording` (times in s, samples (N, 3) in m/s²,
the session's facts), the repairs and checks of its samples (:mod:`.samples`, the
gyroscope's :mod:`.gyro`, the temperature's :mod:`.temperature`) and the errors that
name a recording and what is wrong with it.
"""

from wheelcal.recording.recording import (
    DEFAULT_RADIUS_STD_M,
    SESSION_FACT_KEYS,
    CalibrationRefused,
    Recording,
    RecordingError,
    SessionInfo,
)

__all__ = [
    "DEFAULT_RADIUS_STD_M",
    "SESSION_FACT_KEYS",
    "CalibrationRefused",
    "Recording",
    "RecordingError",
    "SessionInfo",
]
