"""An offset that follows the sensor's measured temperature: Δo_i(t) = c_i (T(t) − T₀).

MEMS offsets drift with temperature (tens of mg over a few °C for consumer
parts), and a sensor warms itself after power-on.  The closed loop can test
such a drift with a *time law* (:class:`~wheelcal.model.effects.OffsetWarmup`,
:class:`~wheelcal.model.effects.OffsetDrift`); when the recording carries the
sensor's temperature, the covariate itself is better: no τ to guess, and a
warm-up that stalls or a room that cools are followed as they happened.

T(t) is the recording's temperature channel, interpolated at the model's
centred times; T₀ is its value at the window centre, so the offsets are
reported at the centre (as every drifting quantity, CONTRACT) and c_i, in
m/s² per °C, is the sensor's temperature coefficient on this recording.  The
effect needs its recording's data, so it is made per window
(:func:`temperature_candidates`) and cannot be rebuilt from its settings alone.
"""

from __future__ import annotations

import numpy as np

from wheelcal.model.effects import SensorDelta, _SensorEffect


class TemperatureOffset(_SensorEffect):
    """Δo_i = c_i (T(t) − T₀) with T from the recording (see the module docstring)."""

    name = "temperature_offset"
    param_names = ("x_mps2_per_c", "y_mps2_per_c", "z_mps2_per_c")
    offset_like = True
    varies_in_time = True
    description = "offset following the measured temperature c·(T(t) − T(centre))"

    def __init__(self, time_s: np.ndarray, temperature_c: np.ndarray) -> None:
        t = np.asarray(time_s, dtype=float)
        temp = np.asarray(temperature_c, dtype=float)
        ok = np.isfinite(temp)
        if ok.sum() < 2 or t.shape != temp.shape:
            raise ValueError("need a temperature per sample, at least two of them finite")
        self._time_s, self._temperature_c = t[ok], temp[ok]
        self.reference_c = float(np.interp(0.0, self._time_s, self._temperature_c))

    def settings(self) -> dict:
        return {
            "reference_c": self.reference_c,
            "min_c": float(self._temperature_c.min()),
            "max_c": float(self._temperature_c.max()),
        }

    def change_c(self, t_s: np.ndarray) -> np.ndarray:
        """T(t) − T₀ at centred times."""
        return (
            np.interp(np.asarray(t_s, float), self._time_s, self._temperature_c) - self.reference_c
        )

    def sensor_delta(self, values, t_s, sensed, gain, jacobian):
        w = self.change_c(t_s)
        delta = w[:, None] * np.asarray(values, dtype=float)[None, :]
        if not jacobian:
            return SensorDelta(delta)
        d_own = np.zeros((3, 3, w.size))
        for i in range(3):
            d_own[i, i] = w
        return SensorDelta(delta, d_own)

    def axis_columns(self, t_s, sensed, gain):
        return np.broadcast_to(self.change_c(t_s), (3, np.size(t_s))), (0, 1, 2)


def temperature_candidates(time_centred_s: np.ndarray, temperature_c) -> tuple:
    """The temperature effect for a window, if it has a temperature that changes."""
    if temperature_c is None:
        return ()
    temp = np.asarray(temperature_c, dtype=float)
    finite = temp[np.isfinite(temp)]
    if finite.size < 2 or np.ptp(finite) <= 0:
        return ()
    return (TemperatureOffset(time_centred_s, temp),)
