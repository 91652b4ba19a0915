"""The closed loop: find what the model lacks in the residual, add it, report before and after.

Layer 4 (above ``estimate``, below ``session``).  On one recording
(:mod:`.loop`): score tests of candidate effects at the fit (:mod:`.score`; the
gyroscope's stream, and the rests' — :mod:`.rest_stream`), the significant ones
added and everything refitted.  Over a sensor's recordings (:mod:`.pooling`,
:mod:`.sensor_closure`, :mod:`.sensor_fit`): pooled tests of effects the sensor
shares, a joint sensor fit, and the pooled calibration.
"""

from wheelcal.closedloop.gyro_matrix import (
    GyroMountingObservation,
    PooledGyro,
    geometry_covariance,
    pool_gyro,
)
from wheelcal.closedloop.loop import ClosedLoop, Diagnosis
from wheelcal.closedloop.pooling import (
    JOINT_FIT,
    POOLED_PARAMETERS,
    JointEstimate,
    PooledSensor,
    RecordingEstimate,
    pool_sessions,
)
from wheelcal.closedloop.sensor_closure import ClosureInput, close_sensor

__all__ = [
    "JOINT_FIT",
    "POOLED_PARAMETERS",
    "ClosedLoop",
    "ClosureInput",
    "Diagnosis",
    "GyroMountingObservation",
    "JointEstimate",
    "PooledGyro",
    "PooledSensor",
    "RecordingEstimate",
    "close_sensor",
    "geometry_covariance",
    "pool_gyro",
    "pool_sessions",
]
