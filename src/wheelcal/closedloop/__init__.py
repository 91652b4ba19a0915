"""The closed loop: find what the model lacks in the residual, add it, report before and after.

Layer 5 (above ``estimate``, below ``session``).  On one recording
(:mod:`.loop`): score tests of candidate effects at the fit (:mod:`.score`; the
gyroscope's stream, and the rests' — :mod:`.rest_stream`), the significant ones
added and everything refitted.  Over a sensor's recordings (:mod:`.pooling`,
:mod:`.sensor_closure`, :mod:`.sensor_fit`): pooled tests of effects the sensor
shares, a joint sensor fit, and the pooled calibration.
"""
