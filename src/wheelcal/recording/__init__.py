"""The typed recording between the readers and the estimators, and its own checks.

Layer 2 (above ``model``): :class:`Recording` (times in s, samples (N, 3) in m/s²,
the session's facts), validated once, at construction — raw samples come in through
:meth:`Recording.from_samples`, which every reader and the API use — the repairs
and checks of its samples (:mod:`.samples`, the gyroscope's :mod:`.gyro`, the
temperature's :mod:`.temperature`) and the errors that name a recording and what
is wrong with it.
"""

from wheelcal.recording.errors import InputError, SampleError
from wheelcal.recording.recording import (
    ACCEL_UNITS,
    DEFAULT_RADIUS_STD_M,
    GYRO_UNITS,
    SESSION_FACT_KEYS,
    CalibrationRefused,
    Recording,
    RecordingError,
    SessionInfo,
)
from wheelcal.recording.samples import InputPolicy, rest_level
from wheelcal.recording.temperature import TemperatureReadings

__all__ = [
    "ACCEL_UNITS",
    "DEFAULT_RADIUS_STD_M",
    "GYRO_UNITS",
    "SESSION_FACT_KEYS",
    "CalibrationRefused",
    "InputError",
    "InputPolicy",
    "Recording",
    "RecordingError",
    "SampleError",
    "SessionInfo",
    "TemperatureReadings",
    "rest_level",
]
