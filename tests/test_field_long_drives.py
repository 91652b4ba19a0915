"""Long field drives: ten and thirty minutes of a car, through the default path.

A drive of minutes is not a two-minute drive made longer: the factory gyro's bias
walks and warms up (the simulator's road car, :func:`~wheelcal.simulate.car_drive`),
the stops add up, and the gyro's sensitivity to acceleration turns every speed
change into a slow roll on the camber track.  Each test names the defect it guards:

* the start's slow phase lost what the gyro's bias turned Θ during the stops (its gains
  came out 0.2–0.3 on a 10-minute drive and the fit had to find its way back, on 30
  minutes it did not: refused as ``gain_range`` or ``undetermined``);
* a 10-minute drive calibrated, but offsets 11–12 σ_CRLB and gains 4–11 σ_CRLB off the
  truth: the wheel angle could not follow the bias's walk, and the camber track missed
  the speed-shaped roll G makes of the hub's acceleration.

CI runs the 10-minute drive; ``-m slow`` the 30-minute one.  Both calibrate; both are
strict xfails now for the road car's camber gap (the camber at the centre, and the axle
axis's offset that trades with it, further off than the accelerometer's bound).
"""

from __future__ import annotations

import numpy as np
import pytest

import wheelcal
from test_field_calibration import CHECKED, Z_MAX, _crlb_at_truth, _truth_value
from wheelcal.estimate.field.fit import _gyro_rows_filled
from wheelcal.estimate.field.gyro_axle import gyro_axle
from wheelcal.estimate.field.start import field_start
from wheelcal.session.field import field_window
from wheelcal.simulate import car_drive, simulate_field


def _drive(minutes: float, seed: int = 3):
    rng = np.random.default_rng(seed)
    return simulate_field(car_drive(rng, duration_s=60.0 * minutes), rng)


def test_the_start_of_a_ten_minute_drive_keeps_the_bias_across_its_stops():
    """The start's in-plane gains within 5 % of the truth (they were 0.2–0.3)."""
    sim = _drive(10.0)
    window = _gyro_rows_filled(field_window(sim.recording).recording)
    t = window.time_s
    tc = t - 0.5 * (t[0] + t[-1])
    axle = gyro_axle(tc, window.gyro_radps)
    start = field_start(tc, window.accel_mps2, window.info.gravity_or_standard_mps2, axle)
    axle_axis = int(np.argmax(np.abs(sim.truth.bench.misalignment.matrix[:, 2])))
    in_plane = [k for k in range(3) if k != axle_axis]
    gain = start.params.sensor.gain[in_plane]
    np.testing.assert_allclose(gain, sim.truth.sensor.gain[in_plane], rtol=0.05)
    assert abs(start.params.bench.radius_m / sim.truth.radius_m - 1.0) < 0.05


def _assert_calibrated_within_the_bound(sim) -> None:
    cal = wheelcal.calibrate(sim.recording)
    assert cal.session.geometry == "rolling"
    crlb = _crlb_at_truth(cal, sim.truth)
    nulls = dict(cal.undetermined)
    z = {
        name: (cal.result.value_of(name) - _truth_value(sim.truth, name, cal.result.centre_s))
        / crlb[name]
        for name in CHECKED
        if name not in nulls
    }
    assert {"gain_y", "gain_z", "radius_m", "tilt_deg"} & set(z), nulls
    worst = max(z.items(), key=lambda kv: abs(kv[1]))
    assert abs(worst[1]) <= Z_MAX, z


# 10 minutes: every parameter within 2.4 σ_CRLB since the camber's passes settle (the axle
# axis's offset, 6.5 σ_CRLB off before, now null: its σ above the gate); it was a strict xfail.
def test_a_ten_minute_car_drive_is_calibrated_within_the_bound():
    _assert_calibrated_within_the_bound(_drive(10.0))


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="30 minutes: calibrated (it was refused as undetermined: the G across the axle's "
    "propagated prior was taken from a prediction off its own zero point, 4 m/s² rms per σ), "
    "gains within 1.3 σ_CRLB and the radius 2.1, but the camber at the window's centre 4.6 "
    "σ_CRLB off and the axle axis's offset with it 5.6 (7.9 of the camber's σ and 5.5 before "
    "its passes settled): the road car's camber gap",
)
def test_a_thirty_minute_car_drive_is_calibrated_within_the_bound():
    _assert_calibrated_within_the_bound(_drive(30.0))
