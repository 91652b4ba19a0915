"""The gyroscope about the wheel's axle: its direction, rate and the yaw across it.

A wheel's gyroscope reads mostly its spin: the principal direction of the rates
of a moving wheel is the axle in the gyro's frame, ŵ (to ≈ 0.01° on a drive).
About it the gyro reads ω_g = k (ω − ψ̇ sin γ); across it the carrier's yaw,
k ψ̇ cos γ, turning with the wheel (:mod:`wheelcal.model.gyro_angle`).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np
from scipy import signal

#: Rates above this (rad/s) count as a moving wheel when finding the axle.
MOVING_RADPS = 0.5
#: A wheel turning slower than this (rad/s) rests: there the gyro shows its noise.
RESTING_RADPS = 0.1
#: Corner of the low-pass before the axle rate is differentiated (Hz).
RATE_BAND_HZ = 10.0
#: Corner of the yaw's low-pass (Hz): a vehicle turns within seconds, the wheel many
#: times a second.
YAW_BAND_HZ = 2.0


@dataclass(frozen=True, eq=False)
class GyroAxle:
    """The gyro about the axle: direction ŵ (gyro frame), rate ω_g and ω̇_g per sample."""

    axis: np.ndarray
    rate_radps: np.ndarray
    rate_dot_radps2: np.ndarray
    #: |the gyro across the axle| low-passed, rms over the moving samples, less its
    #: noise: the carrier's yaw (× cos γ), whatever the wheel's angle (rad/s).
    yaw_rms_radps: float
    #: The gyro's bias across the axle (gyro frame, ⊥ ``axis``; rad/s): it reads as a
    #: yaw that turns with the wheel.
    across_bias_radps: np.ndarray

    def flipped(self) -> GyroAxle:
        """The same axle seen from its other end."""
        return GyroAxle(
            -self.axis,
            -self.rate_radps,
            -self.rate_dot_radps2,
            self.yaw_rms_radps,
            self.across_bias_radps,
        )

    def across(self, gyro_radps: np.ndarray) -> np.ndarray:
        """The gyro's samples across the axle, less its bias there."""
        across = gyro_radps - np.outer(gyro_radps @ self.axis, self.axis)
        return across - self.across_bias_radps


@functools.lru_cache(maxsize=32)
def _butter_sos(corner_hz: float, rate_hz: float) -> np.ndarray:
    """The 4th-order Butterworth low-pass (second-order sections): designed once per corner.

    (scipy's filter takes a writable array and leaves it as it was.)
    """
    return signal.butter(4, corner_hz, fs=rate_hz, output="sos")


def _lowpass(x: np.ndarray, rate_hz: float, band_hz: float) -> np.ndarray:
    sos = _butter_sos(float(min(band_hz, 0.4 * rate_hz)), float(rate_hz))
    return signal.sosfiltfilt(sos, x, axis=0)


def smoothed_accel(time_s: np.ndarray, accel_mps2: np.ndarray) -> np.ndarray:
    """The accelerometer low-passed at ``RATE_BAND_HZ``: the force the gyro feels."""
    t = np.asarray(time_s, dtype=float)
    return _lowpass(
        np.asarray(accel_mps2, dtype=float), 1.0 / float(np.median(np.diff(t))), RATE_BAND_HZ
    )


def gyro_axle(time_s: np.ndarray, gyro_radps: np.ndarray) -> GyroAxle | None:
    """The axle from the gyro's samples (one row per time), or None if the wheel never turns."""
    t = np.asarray(time_s, dtype=float)
    gyro = np.asarray(gyro_radps, dtype=float)
    moving = np.linalg.norm(gyro, axis=1) > MOVING_RADPS
    if np.count_nonzero(moving) < 10:
        return None
    axis, bias = _axis_and_bias(gyro, moving)
    rate = gyro @ axis
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    rate_dot = np.gradient(_lowpass(rate, rate_hz, RATE_BAND_HZ), t)
    across = gyro - np.outer(rate, axis) - bias
    smooth = _lowpass(across, rate_hz, YAW_BAND_HZ)  # the yaw turns with ϑ: its size only
    power = np.sum(across[moving] ** 2, axis=1)
    high = across - smooth
    noise = np.mean(np.sum(high[moving] ** 2, axis=1))  # above the band: noise (and ripple)
    yaw = float(np.sqrt(max(float(np.mean(power)) - noise, 0.0)))
    return GyroAxle(axis, rate, rate_dot, yaw, bias)


def _axis_and_bias(gyro: np.ndarray, moving: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The axle ŵ and the gyro's bias across it, b⊥, from g = ω ŵ + b + (the yaw, turning).

    The principal direction of the moving rates leans toward a bias across the axle
    (by b⊥/ω: 0.15° for 0.03 rad/s at 10 rad/s), and the bias then reads as a yaw
    turning with the wheel; on a robot that biased the offsets by 5–7 σ.  The bias
    stays put while the rate changes (speed changes, stops), so a regression of the
    rates on [ω, 1] separates them; the yaw, turning with the wheel, averages out.
    """
    _, vectors = np.linalg.eigh(gyro[moving].T @ gyro[moving])
    axis = vectors[:, -1]
    gyro = gyro[np.all(np.isfinite(gyro), axis=1)]  # a row left out (a glitch) is NaN
    rate = gyro @ axis
    design = np.column_stack([rate, np.ones_like(rate)])
    if rate.size < 10 or np.ptp(rate) < MOVING_RADPS or np.linalg.cond(design) > 1e6:
        return axis, np.zeros(3)
    for _ in range(2):
        (slope, bias), *_ = np.linalg.lstsq(design, gyro, rcond=None)
        axis = slope / np.linalg.norm(slope)
        rate = gyro @ axis
        design[:, 0] = rate
    bias = bias - (bias @ axis) * axis  # along the axle: the fit's ω₀
    return axis, bias


def _side(theta_rad: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """R (−sin ϑ, cos ϑ, 0): across the axle, ⊥ the vertical's share — the direction of travel."""
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    return np.column_stack([-s, c, np.zeros_like(c)]) @ rotation.T


def across_basis(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors ⊥ ``axis`` (a unit vector) and to each other: the plane across it."""
    first = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    first /= np.linalg.norm(first)
    return first, np.cross(axis, first)


def refined_axle(
    gyro_radps: np.ndarray, axle: GyroAxle, theta_rad: np.ndarray, rotation: np.ndarray
) -> GyroAxle:
    """The axle and the bias across it again, now that the wheel angle ϑ is known.

    The carrier's yaw turns with the wheel as R u(ϑ) (:func:`yaw_across`); across the
    axle and ⊥ it, along R (−sin ϑ, cos ϑ, 0), the gyro reads no motion of a wheel
    on a carrier that does not lean — only ω d (the axle's error d) and the bias
    b⊥, both turning with ϑ: p = ω d·side + b⊥·side, linear in d and b⊥.  The
    regression of :func:`gyro_axle` cannot keep a robot's yaw (1 rad/s turns at a
    few rad/s of spin) out of b⊥: 0.023 rad/s off, read as a lean of 3°.  Every row
    finite (the field fit fills a glitch's rows first).
    """
    gyro = np.asarray(gyro_radps, dtype=float)
    a = axle.axis
    e1, e2 = across_basis(a)
    # in the gyro's own plane ⊥ ŵ: its axes and the accelerometer's differ by a degree or
    # two, which a side direction with a share along ŵ would read as the axle's error
    side = _side(theta_rad, rotation)
    s1, s2 = side @ e1, side @ e2
    norm = np.hypot(s1, s2)
    s1, s2 = s1 / norm, s2 / norm
    rate = gyro @ a
    design = np.column_stack([rate * s1, rate * s2, s1, s2])
    coef, *_ = np.linalg.lstsq(design, (gyro @ e1) * s1 + (gyro @ e2) * s2, rcond=None)
    axis = a + coef[0] * e1 + coef[1] * e2
    axis /= np.linalg.norm(axis)
    bias = coef[2] * e1 + coef[3] * e2
    return dataclasses.replace(axle, axis=axis, across_bias_radps=bias - (bias @ axis) * axis)


def rate_noise_density(time_s: np.ndarray, rate_radps: np.ndarray) -> float:
    """The white noise density q (rad/s/√Hz) of a rate, from its second differences.

    A second difference cancels the rate's own change to first order (a wheel
    speeding up by 5 rad/s² moves 0.05 rad/s between samples at 100 Hz, 20× a
    consumer gyro's noise) and has 6 σ² of variance for white noise; the median
    absolute deviation ignores glitches and jolts.
    """
    rate = np.asarray(rate_radps, dtype=float)
    if rate.size < 10:
        return 0.0
    second = rate[2:] - 2.0 * rate[1:-1] + rate[:-2]
    sigma = 1.4826 * float(np.median(np.abs(second - np.median(second)))) / np.sqrt(6.0)
    return sigma * float(np.sqrt(np.median(np.diff(np.asarray(time_s, dtype=float)))))


def yaw_across(
    time_s: np.ndarray,
    gyro_radps: np.ndarray,
    axle: GyroAxle,
    theta_rad: np.ndarray,
    rotation: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The gyro across the axle as a yaw rate: y = k ψ̇ cos γ, and ẏ.

    The yaw's share turns with the wheel as R u(ϑ), u = (cos ϑ, sin ϑ, 0) (R bench →
    sensor, the accelerometer's: the gyro's axes lie within a degree or two of it on
    one chip), so y is the gyro across the axle projected on R u(ϑ), low-passed to
    ``YAW_BAND_HZ``.  An error δ of ϑ scales it by cos δ only (the fit's ϑ is within
    a few mrad of the truth).  Its size is *not* taken from the power across the axle:
    on a road that power holds the wheel's own rotations — the knuckle's pitch and roll
    as the tyre and the suspension shake, 10–20 Hz, which squaring folds down into
    the band — and on measured car drives it read 0.07–0.1 rad/s of yaw where the car
    body's own gyro read 0–0.03 (the fit's axle-axis gain then came out 0.02–0.6 for
    a factory-calibrated sensor).
    """
    t = np.asarray(time_s, dtype=float)
    across = axle.across(np.asarray(gyro_radps, dtype=float))
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    y = _lowpass(np.sum(across * _up(theta_rad, rotation), axis=1), rate_hz, YAW_BAND_HZ)
    return y, np.gradient(_lowpass(y, rate_hz, YAW_BAND_HZ), t)


def _up(theta_rad: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """R (cos ϑ, sin ϑ, 0): the in-plane up, along which the yaw's share turns."""
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    return np.column_stack([c, s, np.zeros_like(c)]) @ rotation.T


#: Corner of the camber track's low-pass (Hz): a road's camber changes over metres.
CAMBER_BAND_HZ = 2.0


@dataclass(frozen=True, eq=False)
class CamberTrack:
    """The camber's change l(t) from the gyro, and the shapes its own errors take.

    ``basis`` (name → series): what the gyro's errors add to l while the wheel turns
    (:func:`camber_track`); the fit takes each with a coefficient of its own, which
    the accelerometer's gravity along the axle pins.  All zero at the window's centre
    (t = 0) and held where the wheel rests.
    """

    track_rad: np.ndarray
    basis: dict[str, np.ndarray]

    def flipped(self) -> CamberTrack:
        """The same track in the frame turned 180° about X (γ → −γ; the basis is kept)."""
        return CamberTrack(-self.track_rad, self.basis)

    @property
    def range_rad(self) -> float:
        """The track's 2–98 % range (rad)."""
        return _range(self.track_rad)

    def unexplained_rad(self) -> np.ndarray:
        """L less its least-squares fit by the basis: what the gyro's own errors cannot make."""
        basis = np.column_stack(list(self.basis.values()))
        coef, *_ = np.linalg.lstsq(basis, self.track_rad, rcond=None)
        return self.track_rad - basis @ coef

    def choice(self, min_change_rad: float) -> CamberChoice:
        """Whether the fit should follow this track (:class:`CamberChoice`)."""
        unexplained = _range(self.unexplained_rad())
        used = unexplained >= min_change_rad
        total, part = np.rad2deg(self.range_rad), np.rad2deg(unexplained)
        limit = np.rad2deg(min_change_rad)
        if used:
            reason = (
                f"the gyro reads the camber changing by {total:.2f}°, {part:.2f}° of it "
                "beyond what its own errors make: the camber follows that track"
            )
        else:
            reason = (
                f"the gyro's roll across the axle ({total:.2f}°) is what its own errors make "
                f"but for {part:.2f}° (below {limit:g}°): one camber for the drive"
            )
        return CamberChoice(used, float(self.range_rad), float(unexplained), reason)


def _range(x: np.ndarray) -> float:
    low, high = np.percentile(x, [2.0, 98.0])
    return float(high - low)


#: A camber track whose part beyond the gyro's own errors spans less than this (rad)
#: is not followed: 0.5° moves the axle's share of gravity by 0.09 m/s², and a track
#: made of the gyro's errors alone (simulated drives: ≤ 0.16°) only costs information.
CAMBER_TRACK_MIN_RAD = float(np.deg2rad(0.5))


@dataclass(frozen=True)
class CamberChoice:
    """Whether the camber follows the gyro's track, and the evidence (a decision, a value)."""

    used: bool
    #: The track's 2–98 % range and that of its part the gyro's errors cannot make (rad).
    track_range_rad: float
    unexplained_range_rad: float
    reason: str


def _held_integral(t: np.ndarray, rate: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """∫ rate dt over the samples where the wheel moves, zero at t = 0."""
    x = rate * moving
    out = np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * np.diff(t))])
    return out - np.interp(0.0, t, out)


def camber_track(
    time_s: np.ndarray,
    gyro_radps: np.ndarray,
    axle: GyroAxle,
    theta_rad: np.ndarray,
    rotation: np.ndarray,
    yaw_radps: np.ndarray,
    *,
    travel_accel: bool = False,
) -> CamberTrack:
    """The camber's change during the drive, from the gyro (:mod:`wheelcal.model.rolling`).

    A wheel rolls about its direction of travel as the road's cross-slope changes, in
    a banked curve, as its caster turns it when steered or its carrier rolls: the gyro
    reads that rate across the axle, ⊥ the yaw's direction, along R (−sin ϑ, cos ϑ, 0)
    (:func:`refined_axle`).  Low-passed to ``CAMBER_BAND_HZ`` and integrated, it is the
    camber's change l(t).  Where the wheel rests the gyro's bias and its g-sensitivity
    read as a roll that is not there (0.1 °/s/g: a degree in a 10 s stop), so l is
    held there — a car at a standstill does not roll.  While the wheel turns the
    gyro's own errors leave (``basis``, each integrated like l):

    * ``drift_radps``: a steady rate (G's share of gravity along the travel, a bias left);
    * ``heading``: y, the yaw (the gyro's axes turned about the axle against the
      accelerometer's: the side direction sees a share of the yaw);
    * ``heading_sin2``, ``heading_cos2``: y sin 2ϑ, y cos 2ϑ (its two axes across the
      axle of different scale: a robot turning on the spot does not average it out);
    * ``gravity_cos2_radps``, ``gravity_sin2_radps``: cos 2ϑ, sin 2ϑ low-passed like the
      rate (G's entries across the axle turn gravity, which rotates in the sensor's
      frame, into rates at 2ϑ that a slow wheel's band lets through);
    * ``travel_accel`` (with ``travel_accel``: the field fit's drives of minutes): ω̇_g,
      the hub's acceleration along the travel (ρ ω̇) over ρ.  Like gravity, a force that
      stands still in the carrier's frame turns in the sensor's as the side direction
      does, and G's symmetric part across the axle reads it as a steady rate: gravity's
      is ``drift_radps``, the speed changes' integrates to the speed — on a 10-minute car
      drive at 0.1 °/s/g, a track off by a speed-shaped share that moved the offsets by
      11 σ_CRLB.  (On the measured 2-minute drives the freedom it adds moved one drive's
      lean check past its limit, and the simulated ones do not need it: not there.)

    The fit takes l with the yaw's scale κ and each of these with a coefficient; the
    accelerometer's gravity along the axle (g sin γ) anchors them: a real roll moves it,
    the gyro's errors do not.  ``time_s`` centred (the window's centre at 0);
    ``yaw_radps``: :func:`yaw_across`'s y.
    """
    t = np.asarray(time_s, dtype=float)
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    across = axle.across(np.asarray(gyro_radps, dtype=float))
    moving = (np.abs(axle.rate_radps) > RESTING_RADPS).astype(float)
    twice = 2.0 * np.asarray(theta_rad, dtype=float)
    y = np.asarray(yaw_radps, dtype=float)
    # the rate across the axle, cos 2ϑ, sin 2ϑ (and ω̇_g) low-passed alike: one filter pass
    columns = [np.sum(across * _side(theta_rad, rotation), axis=1), np.cos(twice), np.sin(twice)]
    if travel_accel:
        columns.append(np.asarray(axle.rate_dot_radps2, dtype=float))
    passed = _lowpass(np.column_stack(columns), rate_hz, CAMBER_BAND_HZ)
    rate = passed[:, 0]
    rates = {
        "drift_radps": np.ones_like(t),
        "heading": y,
        "heading_sin2": y * np.sin(twice),
        "heading_cos2": y * np.cos(twice),
        "gravity_cos2_radps": passed[:, 1],
        "gravity_sin2_radps": passed[:, 2],
    }
    if travel_accel:
        rates["travel_accel"] = passed[:, 3]
    basis = {name: _held_integral(t, x, moving) for name, x in rates.items()}
    return CamberTrack(_held_integral(t, rate, moving), basis)


@dataclass(frozen=True)
class LeanInTurns:
    """The part of the camber that follows the turns: γ = k·a, a = ρ ω y (rad, per m/s²)."""

    per_lateral_mps2_rad: float  # k
    std_rad: float  # σ of k
    range_rad: float  # |k| × the lateral acceleration's 2–98 % range

    @property
    def z(self) -> float:
        """|k| / σ_k (inf when σ is 0)."""
        return abs(self.per_lateral_mps2_rad) / self.std_rad if self.std_rad > 0 else np.inf


def lean_rate_radps(
    time_s: np.ndarray,
    gyro_radps: np.ndarray,
    axle: GyroAxle,
    theta_rad: np.ndarray,
    rotation: np.ndarray,
) -> np.ndarray:
    """The gyro along the direction of travel, low-passed to 1 Hz: the lean's rate (rad/s).

    A carrier that leans (a car's body roll, a bicycle) turns the wheel about the
    direction of travel, which the gyro reads across the axle and ⊥ the yaw's
    direction: along R (−sin ϑ, cos ϑ, 0) (:func:`refined_axle`).  What the gyro's own
    errors put there is for :func:`lean_change_rad` and :func:`lean_in_turns` to take out.
    """
    t = np.asarray(time_s, dtype=float)
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    across = axle.across(np.asarray(gyro_radps, dtype=float))
    return _lowpass(np.sum(across * _side(theta_rad, rotation), axis=1), rate_hz, 1.0)


def _gravity_through_g(t: np.ndarray, theta_rad: np.ndarray, rate_hz: float) -> np.ndarray:
    """(N, 2): cos 2ϑ and sin 2ϑ, low-passed like the lean rate.

    The gyro's sensitivity to linear acceleration G (~0.1 °/s/g) turns gravity, which
    rotates in the sensor's frame, into rates; read along the direction of travel they
    are g·[c₀ + c₁ cos 2ϑ + c₂ sin 2ϑ] (from G's entries across the axle).  Moving, the
    low-pass averages the 2ϑ terms out and c₀ is a constant rate; stopped, the wheel's
    angle makes them a rate that depends on where it stopped — read as a lean that walks
    during every stop (1.1–1.2° over a car's drive at 0.1 °/s/g) unless taken out.
    """
    twice = 2.0 * np.asarray(theta_rad, dtype=float)
    return _lowpass(np.column_stack([np.cos(twice), np.sin(twice)]), rate_hz, 1.0)


#: The lean rate is regressed at this spacing (its low-pass keeps ≲ 1 Hz: about independent).
LEAN_STEP_S = 0.5


def lean_in_turns(
    time_s: np.ndarray,
    lean_rate: np.ndarray,
    theta_rad: np.ndarray,
    yaw_radps: np.ndarray,
    lateral_mps2: np.ndarray,
) -> LeanInTurns:
    """How much of the camber follows the lateral acceleration (a body's roll in its turns).

    The lean rate (:func:`lean_rate_radps`) regressed on the lateral acceleration's
    rate d(ρ ω y)/dt, with what the gyro's own errors put there (bias, gravity through G,
    y, y sin 2ϑ, y cos 2ϑ: :func:`lean_change_rad`), every ``LEAN_STEP_S``.  A carrier that
    rolls in its turns has k ≠ 0 far beyond its σ; the range of the lean is then |k|
    times the lateral acceleration's — free of the gyro's walk, which the detrended
    track of :func:`lean_change_rad` carries (0.02–0.56° without lean).
    """
    t = np.asarray(time_s, dtype=float)
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    twice = 2.0 * np.asarray(theta_rad, dtype=float)
    lateral = np.asarray(lateral_mps2, dtype=float)
    design = np.column_stack(
        [
            np.ones_like(t),
            _gravity_through_g(t, theta_rad, rate_hz),
            yaw_radps,
            yaw_radps * np.sin(twice),
            yaw_radps * np.cos(twice),
            np.gradient(lateral, t),
        ]
    )
    rows = np.arange(0, t.size, max(1, round(LEAN_STEP_S * rate_hz)))
    x, y = design[rows], np.asarray(lean_rate, dtype=float)[rows]
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    dof = rows.size - x.shape[1]
    if dof <= 0:
        return LeanInTurns(0.0, np.inf, 0.0)
    scale = float(np.sum((y - x @ coef) ** 2)) / dof
    cov = scale * np.linalg.pinv(x.T @ x)
    k = float(coef[-1])
    low, high = np.percentile(lateral, [2.0, 98.0])
    return LeanInTurns(k, float(np.sqrt(max(cov[-1, -1], 0.0))), abs(k) * float(high - low))


def lean_change_rad(
    time_s: np.ndarray, lean_rate: np.ndarray, theta_rad: np.ndarray, yaw_radps: np.ndarray
) -> float:
    """How far the wheel's camber changes during the drive (2–98 % range, rad), from the gyro.

    The lean rate's integral (:func:`lean_rate_radps`) is the lean — less what the
    gyro's own errors put there: a constant and a drift (bias and noise), gravity
    through its g-sensitivity (:func:`_gravity_through_g`), the heading
    ∫y (its axes' misalignment about the axle), and ∫y sin 2ϑ, ∫y cos 2ϑ (the scale
    difference of its axes across the axle, which a robot turning on the spot does
    not average out).
    """
    t = np.asarray(time_s, dtype=float)
    dt = np.gradient(t)
    lean = np.cumsum(lean_rate * dt)
    twice = 2.0 * np.asarray(theta_rad, dtype=float)
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    gravity = np.cumsum(_gravity_through_g(t, theta_rad, rate_hz) * dt[:, None], axis=0)
    design = np.column_stack(
        [
            np.ones_like(t),
            t - t.mean(),
            gravity,
            np.cumsum(yaw_radps * dt),
            np.cumsum(yaw_radps * np.sin(twice) * dt),
            np.cumsum(yaw_radps * np.cos(twice) * dt),
        ]
    )
    coef, *_ = np.linalg.lstsq(design, lean, rcond=None)
    low, high = np.percentile(lean - design @ coef, [2.0, 98.0])
    return float(high - low)
