"""A wheel in the field, calibrated: the wheel angle from its gyro, the geometry from the data.

A car's, a robot's or a wheelchair's wheel is driven, braked, steered and
stopped; its hub travels and turns, it may lean (camber), and nobody measured
where the sensor sits.  The gyroscope measures the motion, so (module
:mod:`wheelcal.model.gyro_angle`) the wheel angle is the integrated gyro rate,
and the accelerometer's model is eq. (1) plus the rolling wheel's forces
(:mod:`wheelcal.model.rolling`).  The fit runs in passes, each a joint ML fit
(:class:`~wheelcal.estimate.joint.fit.JointFit`) of a few parameters:

1. **a fixed axle** — the gains, offsets, R, the sensor's radius r (gravity
   fixes the gains' scale), the phase ϑ₀, the gyro's bias along the axle (ω₀)
   and its scale s; fitted only where pass 2 finds neither travel nor turns;
2. **the hub's travel** ρ ω̇ added (ρ the rolling radius), from the start: a hub
   that travels shows ρ many σ from zero;
3. **the turns**: the yaw rate demodulated from the gyro across the axle with
   the wheel angle of pass 2 (:func:`~wheelcal.estimate.field.gyro_axle.yaw_across`),
   first taken as measured, then with its scale κ free under a prior N(1, σ_κ²)
   (the gyro's axes across the axle are as good as the sensor's tolerance; on a
   vertical wheel κ and the axle axis's gain are one, and the prior's σ is what
   that gain is known to); the tilt α is fitted too: on a cambered wheel the
   turns turn gravity's phase by ψ̇ sin γ, which measures γ = 90° − α, and with
   it r (both are free only then).

The σ are the sandwich's, with the gyro's angle walk and its G across the axle (held at
zero, its prior propagated) added (:mod:`wheelcal.estimate.field.robust`).

The answer's geometry (:class:`FieldGeometry`) says which it was — a rolling
wheel (vertical or cambered, with γ) or a fixed axle — and why.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.field.gyro_axle import (
    CAMBER_TRACK_MIN_RAD,
    CamberChoice,
    CamberTrack,
    GyroAxle,
    LeanInTurns,
    across_basis,
    camber_track,
    gyro_axle,
    lean_change_rad,
    lean_in_turns,
    lean_rate_radps,
    rate_noise_density,
    refined_axle,
    smoothed_accel,
    yaw_across,
)
from wheelcal.estimate.field.lean_check import LeanCheck, camber_extension, lean_check
from wheelcal.estimate.field.robust import robust_result_with
from wheelcal.estimate.field.start import field_start
from wheelcal.estimate.joint import CalibrationResult, JointFit
from wheelcal.model import (
    G_SENSITIVITY_PRIOR_DPS_PER_G,
    STANDARD_GRAVITY_MPS2,
    CalibrationParams,
    CrossAxis,
    GyroAngle,
    Rolling,
    Rotation,
    SpinParams,
    evaluate,
    wheel_kinematics,
)
from wheelcal.recording import Recording, RecordingError

#: ρ / σ_ρ above which the hub travels (pass 2): a rolling wheel.
TRAVEL_Z = 5.0
#: The yaw (rms, rad/s) above which the carrier turns: a rolling wheel's turns.
YAW_RMS_RADPS = 0.01
#: The final fit's AR noise model reaches back at least this long (s).  A road's
#: vibration is a band (5–60 Hz) above a white floor; an AR model too short to
#: shape its lower edge spreads its power down to the wheel's turn rate (< 1 Hz at a
#: wheelchair's pace), where the signal is: 10 lags at 400 Hz made the σ 2–4× too
#: large; 0.2 s of memory resolves a few Hz.
AR_MEMORY_S = 0.2
#: The passes that lead the way run on about this many samples.
LEAD_SAMPLES = 4000
#: Gauss–Newton steps of the fixed axle's pass (pass 1).
LEAD_ITERATIONS = 12
#: The hub's travel (pass 2) runs from the start on about this many samples, this many
#: steps: it only tells a rolling wheel from a fixed axle (ρ's size) and gives the turns'
#: pass its wheel angle and R.  6 steps on 2000 of a car drive's samples find the same
#: geometry, and the passes after it the same answer to 0.02 of its σ (16 drives), in a
#: third of the time of pass 1's 12 on 4000 and then 12 more.
TRAVEL_SAMPLES = 2000
TRAVEL_ITERATIONS = 6
#: Gains outside this range after the leading passes are restarted at 1.
PLAUSIBLE_GAIN = (0.7, 1.4)
#: The gyro's bias walks on a long drive (:class:`~wheelcal.model.GyroAngle`'s walk): its
#: change is fitted per knot interval of about this length (s) …
WALK_SPACING_S = 60.0
#: … on a drive of at least this many intervals (two minutes keep one bias, ω₀) …
WALK_MIN_INTERVALS = 3
#: … under the prior of a factory IMU's walk, °/s/√s (the simulator draws 0.002–0.005).
#: A factory gyro's bias walks and warms up; the angle integrates it, and ω₀ t cannot
#: follow: over a 30-minute car drive the angle strayed 15° rms from the truth (two
#: minutes: under 1°), and gravity's phase, the camber track and the gains with it.
WALK_PRIOR_DPS_PER_SQRT_S = 0.005
#: σ of the prior on the yaw's scale κ: the gyro's axes across the axle against their
#: nominal scale (a MEMS gyro's sensitivity tolerance, ~1–3 % per axis, halved by the
#: two axes' mean).
YAW_SCALE_PRIOR_STD = 0.01
#: The gyro angle's camber and the camber's track are refitted to the ones the fit finds
#: at most this often on every sample …
CONSISTENT_PASSES = 6
#: … until the two differ by less than this (rad; :func:`_consistent_angle`) …
CONSISTENT_RAD = np.deg2rad(0.02)
#: … and as tightly on the thinned samples of the passes that lead the way, with the
#: cross-axis terms: there the passes are cheap, and they lead the final fit on every
#: sample near its own camber (though a rim's 25–55 Hz folds onto the wheel's band at
#: 120 Hz / 3: three thinnings of one drive lie 4–12 σ of its parameters apart).
LEAD_CONSISTENT_RAD = CONSISTENT_RAD
#: The thinned samples' passes run at most this often.
LEAD_CONSISTENT_PASSES = 30
#: Each pass moves the wheel angle the track is read at, and the camber the angle takes,
#: this share of the way to the fit's (a full step makes the two overshoot each other) …
CONSISTENT_STEP = 0.5
#: … mixed with the passes before (Anderson's acceleration over this many: the map has
#: a slow direction, where a damped step alone took 10–25 passes on every sample, and
#: four left car drives' cambers and radii 4–12 σ short of where the passes settle) …
ANDERSON_DEPTH = 3
#: … and the passes stop, keeping their steadiest state, where a pass moves them more
#: than this many times the least a pass moved them — from this pass on (the first
#: passes move the track more before they settle: the thinned passes stopped at their
#: second, 0.15° then 0.69°, on a drive they settle in eight).
DIVERGING = 3.0
DIVERGE_AFTER = 4
#: The propagated nuisances' shifts are taken over this fraction of their σ (the
#: derivative; :func:`_across_g_shifts`).
SHIFT_STEP = 0.01


@dataclass(frozen=True)
class FieldGeometry:
    """What the data say the wheel is, and why."""

    kind: str  # "rolling" or "fixed"
    camber_deg: float | None  # a rolling wheel's γ = 90° − α (None: fixed axle)
    reason: str
    travel_z: float  # ρ / σ_ρ of pass 2
    yaw_rms_radps: float
    #: How far the camber changed during the drive, from the gyro (2–98 % range, °).
    lean_change_deg: float = 0.0
    #: The part of it that follows the turns (:func:`~.gyro_axle.lean_in_turns`), rolling only.
    lean_in_turns: LeanInTurns | None = None
    #: Whether the camber follows the gyro's track (rolling only).
    camber: CamberChoice | None = None
    #: What a camber free to move would change (:mod:`~.lean_check`; rolling only).
    lean_check: LeanCheck | None = None


@dataclass(frozen=True, eq=False)
class FieldResult:
    """The final fit, the geometry found, and the passes' notes."""

    result: CalibrationResult
    geometry: FieldGeometry
    axle: GyroAxle
    #: σ of each reported parameter from the gyro's G across the axle alone (held at zero,
    #: its prior propagated: :func:`_across_g_shifts`); empty where not propagated.
    g_across_std: dict[str, float] = dataclasses.field(default_factory=dict)


@dataclass(frozen=True)
class FieldFit:
    """The field fit's settings (module docstring); :meth:`fit` returns a :class:`FieldResult`.

    Parameters
    ----------
    coloured_noise, max_ar_order, ar_memory_s:
        The noise model of each pass (:class:`~wheelcal.estimate.joint.fit.JointFit`);
        the final fit's order at least ``ar_memory_s`` × the sample rate.
    travel_z, yaw_rms_radps:
        What makes a rolling wheel: the hub's travel at ρ / σ_ρ above ``travel_z``,
        or a yaw above ``yaw_rms_radps``.
    """

    coloured_noise: bool = True
    max_ar_order: int = 10
    #: The final fit's noise model reaches back this long (its AR order ≥ this × rate).
    ar_memory_s: float = AR_MEMORY_S
    travel_z: float = TRAVEL_Z
    yaw_rms_radps: float = YAW_RMS_RADPS
    fit_yaw_scale: bool = True
    #: σ of κ's prior around 1 (``YAW_SCALE_PRIOR_STD``; a factory-calibrated gyro: less).
    yaw_scale_prior_std: float = YAW_SCALE_PRIOR_STD
    #: ε in ψ̇ = κ ψ̇_gyro + ε: the gyro's sensitivity to gravity, which turns with the
    #: wheel as the vertical does, reads as a steady yaw (0.1 °/s/g: 0.0017 rad/s) that
    #: biased a robot's offsets by 5–6 σ through ρ ω ψ̇ when held at zero.
    fit_yaw_offset: bool = True
    fit_cross: bool = True
    fit_g_sensitivity: bool = True
    #: The prior on the gyro's sensitivity to acceleration, °/s/g (``--gyro-g-sensitivity``:
    #: MPU-9250 class 0.1; a factory calibration usually leaves it).  Its information joins the
    #: sandwich's meat as a prior whose mean is off by this much (``robust``), so a prior
    #: wider than the gyro widens σ.  Across the axle G is held at zero and this prior is
    #: propagated into σ (:func:`_across_g_shifts`; 0: not propagated).
    gyro_g_prior_dps_per_g: float = G_SENSITIVITY_PRIOR_DPS_PER_G
    #: σ from the sandwich and the gyro's angle walk (:mod:`~wheelcal.estimate.field.robust`).
    robust_sigma: bool = True
    #: The final fit lets the sensor's axes be non-orthogonal (:class:`CrossAxis`).
    fit_cross_axis: bool = True
    #: The camber follows the track the gyro measures (:mod:`wheelcal.model.rolling`);
    #: ``False``: one camber for the whole drive.
    camber_track: bool = True
    #: … where its part beyond the gyro's own errors spans this much (rad; ``CamberChoice``).
    camber_track_min_rad: float = CAMBER_TRACK_MIN_RAD
    #: Whether to test a camber free to move against the fitted one (:mod:`~.lean_check`).
    check_lean: bool = True
    #: The gyro's bias walk on a long drive (``WALK_SPACING_S``; None: one bias, ω₀).
    walk_spacing_s: float | None = WALK_SPACING_S
    #: Its prior (``WALK_PRIOR_DPS_PER_SQRT_S``), °/s/√s.
    walk_prior_dps_per_sqrt_s: float = WALK_PRIOR_DPS_PER_SQRT_S

    def fit(self, window: Recording) -> FieldResult:
        """Calibrate ``window`` (a drive, stops included; its gyro on the same rows).

        The passes that lead the way run on every k-th sample (about
        ``LEAD_SAMPLES``, the hub's travel ``TRAVEL_SAMPLES``; the gyro's angle is
        integrated from all of them); the final fit uses every sample.
        """
        if window.gyro_radps is None:
            raise RecordingError(f"{window.source}: a field fit needs the gyroscope")
        window = _gyro_rows_filled(window)
        t = window.time_s
        tc = t - 0.5 * (t[0] + t[-1])
        axle = gyro_axle(tc, window.gyro_radps)
        if axle is None:
            raise RecordingError(f"{window.source}: the gyroscope shows no wheel turning")
        radius = window.info.radius_m
        start, axle = self._start(window, tc, axle)
        stride = max(1, t.size // LEAD_SAMPLES)
        lead = window.thinned(stride)
        frame = (float(t[0]), float(t[-1]))  # the thinned passes keep the window's centre
        travel = Rolling(tc, np.zeros_like(tc), yaw_scale_free=False)
        moved = start.params.with_changes(effects={**start.params.effects, travel.name: [0.0]})
        travel_stride = max(1, t.size // TRAVEL_SAMPLES)
        second = self._joint(radius, False, (start.angle, travel), steps=TRAVEL_ITERATIONS)
        second = second.fit(window.thinned(travel_stride), initial=moved, frame=frame)
        rho, rho_std = second.value_of("rolling.radius_m"), second.std_of("rolling.radius_m")
        z = abs(rho) / rho_std * np.sqrt(travel_stride)  # σ_ρ of all the samples
        rolling = z > self.travel_z or axle.yaw_rms_radps > self.yaw_rms_radps
        if not rolling:
            first = self._joint(radius, False, (start.angle,)).fit(
                lead, initial=start.params, frame=frame
            )
            geometry = FieldGeometry(
                "fixed",
                None,
                f"a fixed axle: the hub does not travel (ρ at {z:.1f} σ) and the carrier does "
                f"not turn (yaw {axle.yaw_rms_radps:.3g} rad/s rms)",
                float(z),
                axle.yaw_rms_radps,
            )
            return FieldResult(first, geometry, axle)
        final, camber_choice, check, g_std = self._turns(
            window, lead, tc, axle, second, radius, stride
        )
        axle, lean_rad, in_turns = _lean(window, tc, axle, final)
        camber = 90.0 - float(np.rad2deg(final.params.bench.tilt_rad))
        why = []
        if z > self.travel_z:  # ρ as the final fit has it; its size in σ from pass 2
            rho_final = float(final.params.effect("rolling", 1)[0])
            why.append(f"the hub travels (ρ = {rho_final:.3f} m, {z:.0f} σ)")
        if axle.yaw_rms_radps > self.yaw_rms_radps:
            why.append(f"the carrier turns (yaw {axle.yaw_rms_radps:.3g} rad/s rms)")
        geometry = FieldGeometry(
            "rolling",
            camber,
            "a rolling wheel: "
            + " and ".join(why)
            + f"; camber {camber:.2f}° from the data, changing by {np.rad2deg(lean_rad):.2f}°"
            + f" ({camber_choice.reason})",
            float(z),
            axle.yaw_rms_radps,
            float(np.rad2deg(lean_rad)),
            in_turns,
            camber_choice,
            check,
        )
        return FieldResult(final, geometry, axle, g_std)

    # -- the passes -----------------------------------------------------------------------------
    def _joint(
        self,
        radius_m,
        tilt_free: bool,
        effects: tuple,
        rate_hz: float | None = None,
        steps: int = LEAD_ITERATIONS,
    ) -> JointFit:
        """A pass's joint fit.

        r given: α free (the paper's geometry); else r free, and α too once the turns
        measure it (``tilt_free``).  With ``rate_hz`` (the final fit) the noise model's
        order reaches back ``ar_memory_s`` at least; ``steps``: a leading pass's steps.
        """
        order = self.max_ar_order
        if rate_hz is not None:
            order = max(order, int(np.ceil(self.ar_memory_s * rate_hz)))
        if radius_m is not None:
            geometry = "radius"
        else:
            geometry = "free" if tilt_free else "vertical"
        return JointFit(
            spin_degree=0,
            geometry=geometry,
            coloured_noise=self.coloured_noise,
            max_ar_order=order,
            effects=effects,
            # Passes 1–2 only lead the way (a cambered wheel held vertical cannot fit):
            # a few steps give the wheel angle and R for the yaw, and ρ's size.
            max_iterations=100 if tilt_free or radius_m is not None else steps,
        )

    def _walk(self, tc: np.ndarray) -> dict:
        """The gyro angle's bias walk on this window (its keywords; {}: a short drive)."""
        spacing = self.walk_spacing_s
        if spacing is None or tc[-1] - tc[0] < WALK_MIN_INTERVALS * spacing:
            return {}
        q = np.deg2rad(self.walk_prior_dps_per_sqrt_s)
        return {"walk_spacing_s": spacing, "walk_prior_radps_per_sqrt_s": q}

    def _start(self, window: Recording, tc: np.ndarray, axle: GyroAxle) -> tuple:
        """The start (:mod:`wheelcal.estimate.field.start`) and the oriented axle."""
        start = field_start(
            tc,
            window.accel_mps2,
            window.info.gravity_or_standard_mps2,
            axle,
            radius_m=window.info.radius_m,
            walk=self._walk(tc),
        )
        return start, start.axle

    def _z_up(self, window, build, series, track: bool, model: tuple, result):
        """The final fit's twin with Z up (α → π − α; :func:`_turned`), refitted.

        The rolling effect keeps ρ and κ and restarts ε and the camber's c_k at zero
        (the track turns sign with the camber).  Kept only if the refit has Z up.
        """
        turned = series.flipped()
        angle = build.angle(turned, track)
        rolling = _z_up_rolling(build, turned, track, model[1])
        twin = _turned(result.params, angle.name, None)
        start = _rolling_start(result.params, rolling, model[1])
        for k, name in enumerate(rolling.param_names):
            if name == "yaw_offset_radps" or name.startswith("camber_"):
                start[k] = 0.0
        twin = twin.with_changes(effects={**twin.effects, rolling.name: start})
        flipped_model = (angle, rolling, *model[2:])
        rate_hz = 1.0 / float(np.median(np.diff(window.time_s)))
        refit = self._joint(window.info.radius_m, True, flipped_model, rate_hz).fit(
            window, initial=twin
        )
        if refit.params.bench.tilt_rad > np.pi / 2:
            return series, model, result
        return turned, flipped_model, refit

    def _turns(
        self, window, lead, tc, axle, travelled: CalibrationResult, radius_m, stride: int
    ) -> tuple[CalibrationResult, CamberChoice, LeanCheck | None, dict[str, float]]:
        """Pass 3: the yaw across the axle, the tilt free (module docstring).

        The yaw is first taken as the gyro's axes across the axle read it (their
        nominal scale) with one camber; then, with the wheel angle that pass gives (the
        track's demodulation needs it to a few mrad: pass 2's, off by more, turns the
        gyro's bias into a roll), the camber's track is read and joins; then the yaw's
        scale κ is fitted too, under its prior (``yaw_scale_prior_std``): a robot on a
        hub sensor turns the axle axis's forces by κ × its gain alone, and κ taken as
        exact left that gain biased by the gyro's 1–2 % scale errors at ten times its σ.
        All on the thinned samples (``lead``); the chosen model is then fitted to every
        sample.
        """
        params = _plausible_gains(travelled.params)
        smoothed = smoothed_accel(tc, window.accel_mps2)
        frame = (float(window.time_s[0]), float(window.time_s[-1]))
        g_prior = np.deg2rad(self.gyro_g_prior_dps_per_g) / STANDARD_GRAVITY_MPS2
        accel = smoothed if self.fit_g_sensitivity else None
        build = _Build(tc, accel, g_prior, self.fit_cross, self._walk(tc))
        series = build.series(window.gyro_radps, axle, params, travelled.layout.effects)
        joint = self._joint(radius_m, True, ())

        def held_fit(series: _Series, initial: CalibrationParams, track: bool, before):
            """The turns with κ = 1 (and the camber's track, if ``track``); Z made to point up."""
            angle, held = build.angle(series, track), build.rolling(series, track, held=True)
            effects = {**initial.effects, angle.name: _angle_start(initial, angle)}
            effects[held.name] = _rolling_start(initial, held, before)
            fit = dataclasses.replace(joint, effects=(angle, held))
            result = fit.fit(lead, initial=initial.with_changes(effects=effects), frame=frame)
            if result.params.bench.tilt_rad > np.pi / 2:
                # Z came out pointing down (the start cannot tell up from down on a nearly
                # vertical wheel): the same physics with the frame turned 180° about X —
                # α → 180° − α, R → R·diag(1, −1, −1), ϑ → −ϑ (the gyro's axle from its
                # other end), and the camber's change γ → −γ.
                series = series.flipped()
                angle, held = build.angle(series, track), build.rolling(series, track, held=True)
                fit = dataclasses.replace(joint, effects=(angle, held))
                twin = _turned(result.params, angle.name, held.name)
                result = fit.fit(lead, initial=twin, frame=frame)
            return result, (angle, held), series

        result, model, series = held_fit(series, params, False, None)
        # the track read again at this pass's angle and R, in its frame
        series = build.series(
            window.gyro_radps, series.oriented, result.params, result.layout.effects
        )
        choice = series.track.choice(self.camber_track_min_rad)
        if not self.camber_track:
            choice = dataclasses.replace(choice, used=False, reason="one camber (as asked)")
        track = choice.used
        if track:
            result, model, series = held_fit(series, result.params, True, model[1])
            # the wheel angle's ψ̇ sin γ(t) at the camber that pass found
            series = dataclasses.replace(series, angle_track_rad=_fitted_change(result))
            model = (build.angle(series, track), model[1])
        if self.fit_yaw_scale:
            # κ free under its prior: where the data do not pin it (a vertical wheel's
            # turns scale the axle axis's forces by κ × its gain), the gain's σ carries
            # the gyro's tolerance instead of a κ = 1 taken as exact.
            angle, held = model
            free = build.rolling(
                series,
                track,
                held=False,
                offset_free=self.fit_yaw_offset,
                scale_prior_std=self.yaw_scale_prior_std,
            )
            start = _rolling_start(result.params, free, held)
            effects = {**result.params.effects, free.name: start}
            freed = result.params.with_changes(effects=effects)
            fit = dataclasses.replace(joint, effects=(angle, free))
            refined = fit.fit(lead, initial=freed, frame=frame)
            if refined.params.bench.tilt_rad <= np.pi / 2:
                result, model = refined, (angle, free)
        if self.fit_cross_axis:
            # the axle axis's gain from the turns, not from a leak; on the thinned samples
            # already, so that their passes lead to the final fit's camber (without the
            # terms it lay 0.3° from theirs on a car drive, however tightly they converged)
            axes = CrossAxis()
            model = (*model, axes)
            effects = {**result.params.effects, axes.name: [0.0] * 3}
            fit = dataclasses.replace(joint, effects=model)
            result = fit.fit(lead, initial=result.params.with_changes(effects=effects), frame=frame)
        if track:
            series, model, result = _consistent_angle(
                build,
                window.gyro_radps,
                (series, model, result),
                joint,
                lead,
                frame,
                tolerance_rad=LEAD_CONSISTENT_RAD,
                passes=LEAD_CONSISTENT_PASSES,
            )
        rate_hz = 1.0 / float(np.median(np.diff(window.time_s)))
        if stride > 1 or self.fit_cross_axis:
            result = self._joint(radius_m, True, model, rate_hz).fit(window, initial=result.params)
        if result.params.bench.tilt_rad > np.pi / 2:
            # The final fit, on every sample and with the cross-axis terms, came out with Z
            # pointing down (a car whose axle offset the data cannot see: tilt 93.3° for a
            # truth of 86.5°, "5.2 σ" off though the same physics as 86.7°): its twin with
            # the frame turned about X, Z up, as the passes before keep it.
            series, model, result = self._z_up(window, build, series, track, model, result)
        if radius_m is None and result.params.bench.radius_m < 0:
            # r came out negative: the same forces with ϑ advanced by π; reported r > 0
            twin = _half_turned(result.params)
            result = self._joint(radius_m, True, model, rate_hz).fit(window, initial=twin)
        if track:  # the final fit's coefficients moved the camber: its angle follows
            final = self._joint(radius_m, True, model, rate_hz)
            series, model, result = _consistent_angle(
                build,
                window.gyro_radps,
                (series, model, result),
                final,
                window,
                frame,
                tolerance_rad=CONSISTENT_RAD,
                passes=CONSISTENT_PASSES,
            )
            if result.params.bench.tilt_rad > np.pi / 2:
                series, model, result = self._z_up(window, build, series, track, model, result)
        if not self.robust_sigma:
            return result, choice, None, {}
        shifts = ()
        if self.gyro_g_prior_dps_per_g > 0:
            yaw_of = _YawOf(window.gyro_radps, build, series)
            shifts = _across_g_shifts(
                result, yaw_of, series.axle.axis, smoothed, g_prior, with_cross=self.fit_cross
            )
        density = rate_noise_density(tc, series.axle.rate_radps)
        wider = camber_extension(result) if self.check_lean else None
        extension, spacing = wider if wider is not None else (None, 0.0)
        robust = robust_result_with(result, window.accel_mps2, density, shifts, extension)
        extended = robust.extended
        check = None if extended is None else lean_check(result, extension, extended, spacing)
        g_std = {}
        if robust.shift_covariance is not None:
            std = np.sqrt(np.clip(np.diag(robust.shift_covariance), 0.0, None))
            g_std = dict(zip(robust.result.names, map(float, std), strict=True))
        return robust.result, choice, check, g_std


def _consistent_angle(
    build, gyro_radps, state: tuple, joint, lead, frame, *, tolerance_rad: float, passes: int
) -> tuple:
    """The gyro angle's camber and the camber's track made the ones the fit finds.

    The wheel angle's ψ̇ sin γ(t) takes a camber's change as a series — the fitted one of
    the pass before — while the rolling wheel's forces take the camber its own
    coefficients give now.  Where the road's camber changes by degrees the two part
    (by 0.3–0.5° on car drives), and the camber at the window's centre, read from the
    turns through that angle, came out 1.3–1.5° off (6–9 σ; the axle axis's offset
    with it, 0.2 m/s²).  And the track itself is read along the direction of travel at
    a wheel angle: an angle off by δϑ reads the yaw ψ̇ δϑ as a roll, and the angle is off
    by ∫ ψ̇ δγ where the camber is — the two errors feed each other.  On a steered front
    wheel (its camber changing by 4–8° with the steering) the track read once at the
    first pass's angle held 14° of change where the truth had 8°, with an ideal gyro,
    and the camber at the centre came out 3° off (12.6 σ).  So each pass reads the
    track again at the wheel angle of the fit before and refits on ``lead`` (the passes'
    thinned samples before the final fit, every sample after it), until neither the
    track read nor the fitted change moves by ``tolerance_rad`` (``LEAD_CONSISTENT_RAD``
    on the thinned samples, ``CONSISTENT_RAD`` on every sample), ``passes`` at most.
    Each pass goes ``CONSISTENT_STEP`` of the way (a full step makes the angle and the
    track overshoot each other, and on one car drive of a hundred grow without bound),
    mixed with the passes before (:func:`_mixed_step`, ``ANDERSON_DEPTH``); where the
    passes still part (``DIVERGING``, from pass ``DIVERGE_AFTER`` on), the steadiest
    state is kept.  The frame is kept through the passes (the caller turns a Z that
    ends up pointing down).
    """
    series, model, result = state
    theta = None  # the wheel angle the track was last read at (this loop's frame)
    best = (np.inf, state)
    history: list[tuple[np.ndarray, np.ndarray]] = []  # (x, f) of the passes in this frame
    moved = np.inf
    for k in range(passes):
        change = _fitted_change(result)
        fitted = wheel_kinematics(result.params, build.centred_time_s, result.layout.effects)
        n = change.size
        if theta is None:  # the first pass: the fit's angle as it is, the camber half-way
            half = series.angle_track_rad + CONSISTENT_STEP * (change - series.angle_track_rad)
            next_x = np.concatenate([fitted.theta_rad, half])
        else:
            x = np.concatenate([theta, series.angle_track_rad])
            f = np.concatenate([fitted.theta_rad, change]) - x
            history, next_x = _mixed_step(history, x, f)
        rotation = result.params.bench.misalignment.matrix
        read = build.series_at(gyro_radps, series.oriented, next_x[:n], rotation)
        moved = max(
            np.max(np.abs(read.track.track_rad - series.track.track_rad)),
            np.max(np.abs(change - series.angle_track_rad)),
        )
        if not np.isfinite(moved) or (k >= DIVERGE_AFTER and moved > DIVERGING * best[0]):
            break  # the passes part (a drive the loop cannot settle): the steadiest kept
        if moved < best[0]:
            best = (moved, (series, model, result))
        if moved < tolerance_rad:
            break
        theta = next_x[:n]
        series = dataclasses.replace(read, angle_track_rad=next_x[n:])
        rolling = model[1].with_yaw(
            series.yaw_radps, series.yaw_dot_radps2, series.track.track_rad, series.track.basis
        )
        model = (build.angle(series, True), rolling, *model[2:])
        result = dataclasses.replace(joint, effects=model).fit(
            lead, initial=result.params, frame=frame
        )
    else:
        return series, model, result
    return best[1] if moved > tolerance_rad else (series, model, result)


def _mixed_step(history: list, x: np.ndarray, f: np.ndarray) -> tuple[list, np.ndarray]:
    """The passes' history with state x and move f = G(x) − x added, and their next state.

    Anderson's mixing (type II) over the last ``ANDERSON_DEPTH`` moves: the damped step
    x + β f, corrected along the moves of the passes before — γ = argmin ‖f − ΔF γ‖,
    x + β f − (ΔX + β ΔF) γ — which on the map's slow direction steps as Newton's would;
    with no pass before, the damped step.
    """
    history = [*history, (x, f)][-(ANDERSON_DEPTH + 1) :]
    step = x + CONSISTENT_STEP * f
    if len(history) < 2:
        return history, step
    xs = np.stack([h[0] for h in history], axis=1)
    fs = np.stack([h[1] for h in history], axis=1)
    dx, df = np.diff(xs, axis=1), np.diff(fs, axis=1)
    gamma = np.linalg.lstsq(df, f, rcond=None)[0]
    return history, step - (dx + CONSISTENT_STEP * df) @ gamma


def _z_up_rolling(build, series, track: bool, before: Rolling) -> Rolling:
    """``before``'s variant (κ held or free, ε free or not) on the turned ``series``."""
    if not before.yaw_scale_free:
        return build.rolling(series, track, held=True)
    return build.rolling(
        series,
        track,
        held=False,
        offset_free=before.yaw_offset_free,
        scale_prior_std=before.yaw_scale_prior_std,
    )


@dataclass(frozen=True, eq=False)
class _Series:
    """What the turns' passes read from the gyro at one fit's wheel angle and R.

    ``guessed`` is the axle before its refinement, ``theta_rad`` and ``rotation`` the
    angle and R it was read at (in that fit's frame); ``axle``, ``track`` and
    ``sign`` as the model now uses them (``sign`` −1 once the frame was turned about X:
    the axle seen from its other end and the camber's change turned, y and ``cross``
    kept, as :func:`_turned` turns the parameters).
    """

    guessed: GyroAxle
    axle: GyroAxle
    theta_rad: np.ndarray
    rotation: np.ndarray
    yaw_radps: np.ndarray
    yaw_dot_radps2: np.ndarray
    cross: np.ndarray | None
    track: CamberTrack
    sign: float = 1.0
    #: The camber's change the gyro angle's ψ̇ sin γ(t) takes: the fitted one of a pass
    #: before (κ l + Σ c_k N_k), not the raw track, whose gyro errors the basis holds.
    angle_track_rad: np.ndarray | None = None

    @property
    def oriented(self) -> GyroAxle:
        """The unrefined axle as the current frame sees it."""
        return self.guessed if self.sign > 0 else self.guessed.flipped()

    def flipped(self) -> _Series:
        """The frame turned 180° about X (see the class docstring)."""
        angle_track = None if self.angle_track_rad is None else -self.angle_track_rad
        return dataclasses.replace(
            self,
            axle=self.axle.flipped(),
            track=self.track.flipped(),
            sign=-self.sign,
            angle_track_rad=angle_track,
        )


@dataclass(frozen=True, eq=False)
class _Build:
    """The turns' effects, from :class:`_Series` (the field fit's settings carried)."""

    centred_time_s: np.ndarray
    accel_mps2: np.ndarray | None  # the axle reading's g-sensitivity, or None
    g_prior: float
    fit_cross: bool
    walk: dict  # the gyro angle's bias walk (FieldFit._walk)

    def series(self, gyro_radps, axle: GyroAxle, params, effects) -> _Series:
        """The yaw, the cross series and the camber's track at ``params``' ϑ and R."""
        theta = wheel_kinematics(params, self.centred_time_s, effects).theta_rad
        return self.series_at(gyro_radps, axle, theta, params.bench.misalignment.matrix)

    def series_at(self, gyro_radps, axle: GyroAxle, theta, rotation) -> _Series:
        """:meth:`series` at a given wheel angle ϑ and R (bench → sensor)."""
        tc = self.centred_time_s
        refined = refined_axle(gyro_radps, axle, theta, rotation)
        y, y_dot = yaw_across(tc, gyro_radps, refined, theta, rotation)
        # a drive of minutes (the walk's): G's share of the speed changes too
        track = camber_track(
            tc, gyro_radps, refined, theta, rotation, y, travel_accel=bool(self.walk)
        )
        cross = _cross(y, theta) if self.fit_cross else None
        return _Series(axle, refined, theta, rotation, y, y_dot, cross, track)

    def angle(self, series: _Series, track: bool) -> GyroAngle:
        axle = series.axle
        return GyroAngle(
            self.centred_time_s,
            axle.rate_radps,
            axle.rate_dot_radps2,
            series.yaw_radps,
            series.yaw_dot_radps2,
            series.cross,
            self.accel_mps2,
            self.g_prior,
            camber_track_rad=series.angle_track_rad if track else None,
            **self.walk,
        )

    def rolling(
        self,
        series: _Series,
        track: bool,
        *,
        held: bool,
        offset_free: bool = True,
        scale_prior_std: float | None = None,
    ) -> Rolling:
        """The rolling wheel: the yaw taken as read (``held``: κ = 1) or scaled by κ."""
        return Rolling(
            self.centred_time_s,
            series.yaw_radps,
            series.yaw_dot_radps2,
            yaw_scale_free=not held,
            yaw_across_axle=True,
            yaw_offset_free=offset_free,
            yaw_scale_prior_std=None if held else scale_prior_std,
            camber_track_rad=series.track.track_rad if track else None,
            camber_basis=series.track.basis if track else None,
        )


def _fitted_change(result: CalibrationResult) -> np.ndarray:
    """The camber's change κ l + Σ c_k N_k a fit found (rad, on its effect's grid)."""
    rolling = next(e for e in result.layout.effects if isinstance(e, Rolling))
    values = result.params.effect(rolling.name, rolling.size)
    return rolling.camber_change(values, rolling.time_s)


def _angle_start(params: CalibrationParams, angle: GyroAngle) -> np.ndarray:
    """The gyro angle's start: the scale s the passes before found, the cross terms kept."""
    values = np.zeros(angle.size)
    before = np.asarray(params.effects.get(angle.name, [1.0]), dtype=float)
    values[: min(before.size, angle.size)] = before[: angle.size]
    return values


def _rolling_start(
    params: CalibrationParams, rolling: Rolling, before: Rolling | None
) -> np.ndarray:
    """The rolling effect's start: what ``before`` (the pass before's) fitted, by name.

    ρ always; κ, ε and the camber's c_k where ``before`` had them (κ = 1, the rest 0
    where not).
    """
    values = rolling.initial_values(float(params.effect(rolling.name, 1)[0]))
    if before is not None and rolling.name in params.effects:
        fitted = dict(zip(before.param_names, params.effect(before.name, before.size), strict=True))
        for k, name in enumerate(rolling.param_names):
            if name in fitted:
                values[k] = fitted[name]
    return values


def _cross(yaw_radps: np.ndarray, theta_rad: np.ndarray) -> np.ndarray:
    """(2, N): y cos ϑ and y sin ϑ, the series of the axle reading's response across it."""
    return np.vstack([yaw_radps * np.cos(theta_rad), yaw_radps * np.sin(theta_rad)])


@dataclass(frozen=True, eq=False)
class _YawOf:
    """The series the turns' pass reads from a gyro: its axle refined, then demodulated."""

    gyro_radps: np.ndarray
    build: _Build
    series: _Series  # the fit's, read from ``gyro_radps``

    @property
    def theta_rad(self) -> np.ndarray:
        return self.series.theta_rad

    def __call__(self, gyro_radps: np.ndarray) -> tuple[np.ndarray, np.ndarray, CamberTrack]:
        """y, ẏ and the camber track (in the fit's frame) from ``gyro_radps``."""
        read = self.series
        again = self.build.series_at(gyro_radps, read.guessed, read.theta_rad, read.rotation)
        track = again.track if read.sign > 0 else again.track.flipped()
        return again.yaw_radps, again.yaw_dot_radps2, track


def _across_g_shifts(
    result: CalibrationResult,
    yaw_of: _YawOf,
    axis: np.ndarray,
    accel_mps2: np.ndarray,
    g_std_radps_per_mps2: float,
    *,
    with_cross: bool,
) -> tuple[np.ndarray, ...]:
    """What one σ of each entry of the gyro's G across the axle changes in the prediction.

    The gyro across the axle reads G⊥ a besides the yaw: gravity turning in the
    sensor's frame, the hub's forces.  On a fast wheel the low-pass of the yaw
    (:func:`yaw_across`) averages it to a steady rate, which ε takes; on a slow one
    (a wheelchair's 0.4 Hz) its once- and twice-per-turn parts pass into the yaw
    series, and through the turns' forces and the wheel angle (ψ̇ cot α) into the
    parameters — the hubs' radius spread 1.3× its σ.  The yaw is not fitted for
    them (6 entries, one of them a steady yaw); each entry's one σ (the prior of
    ``gyro_g_prior_dps_per_g``) is run through the same demodulation and model
    instead, at the fitted parameters, for :func:`robust_result` to propagate.
    ``axis``: the gyro's refined axle, across which G's rows are taken.

    The shift is the derivative, one σ long: the prediction at ``SHIFT_STEP`` σ of the
    entry less the prediction at none, both through the same demodulation, over
    ``SHIFT_STEP``.  The fit's own series were read at an earlier pass's angle, so the
    fitted prediction is not the zero point (0.02–0.08 m/s² rms apart on car drives: a
    "shift" of every entry that no G makes), and a whole σ is not linear on a drive of
    half an hour (its angle integrates the yaw: 4 m/s² rms).
    """
    params, layout = result.params, result.layout
    t = result.centred_time_s

    def predicted(gyro_radps: np.ndarray) -> np.ndarray:
        y, y_dot, track = yaw_of(gyro_radps)
        cross = _cross(y, yaw_of.theta_rad) if with_cross else None
        effects = _with_series(layout.effects, params, y, y_dot, cross, track)
        return evaluate(params, t, dataclasses.replace(layout, effects=effects)).predicted_mps2

    base = predicted(yaw_of.gyro_radps)
    step = SHIFT_STEP * g_std_radps_per_mps2
    shifts = []
    for across in across_basis(axis):
        for column in np.asarray(accel_mps2, dtype=float).T:
            moved = predicted(yaw_of.gyro_radps + step * np.outer(column, across))
            shifts.append((moved - base) / SHIFT_STEP)
    return tuple(shifts)


def _with_series(effects: tuple, params: CalibrationParams, y, y_dot, cross, track) -> tuple:
    """``effects`` reading the yaw series y and the camber track (the gyro angle, the forces).

    The rolling wheel takes the new track and basis.  The gyro angle's ψ̇ sin γ(t) takes
    the camber's change the passes would now find: its own (the fitted κ l + Σ c_k N_k
    of a pass before) plus the part of the change at the fitted coefficients that the
    new basis does not hold (:func:`_beyond_basis`) — the passes refit the coefficients
    to the track they read, so what the basis holds of a gyro error leaves the camber
    they find where it was.  (Taken whole, the new track's share of G moved the cars'
    camber and offsets 10–100× what a drawn G moves them by; left out, the tilt's share
    was 10–25× too small.)
    """
    old = next((e for e in effects if isinstance(e, Rolling)), None)
    out = []
    for effect in effects:
        if isinstance(effect, Rolling):
            effect = (
                effect.with_yaw(y, y_dot, track.track_rad, track.basis)
                if effect.has_camber_track
                else effect.with_yaw(y, y_dot)
            )
        out.append(effect)
    rolling = next((e for e in out if isinstance(e, Rolling)), None)
    for k, effect in enumerate(out):
        if not isinstance(effect, GyroAngle):
            continue
        angle_track = None
        if effect.camber_track_rad is not None and rolling is not None:
            values = params.effect(rolling.name, rolling.size)
            change = rolling.camber_change(values, rolling.time_s)
            change = change - old.camber_change(values, old.time_s)
            angle_track = effect.camber_track_rad + _beyond_basis(change, rolling)
        out[k] = effect.with_yaw(y, y_dot, cross, angle_track)
    return tuple(out)


def _beyond_basis(change: np.ndarray, rolling: Rolling) -> np.ndarray:
    """``change`` less its least-squares fit by ``rolling``'s camber basis (itself: none)."""
    basis = rolling.camber_basis
    if not basis:
        return change
    columns = np.column_stack([np.asarray(b, dtype=float) for b in basis.values()])
    coef, *_ = np.linalg.lstsq(columns, change, rcond=None)
    return change - columns @ coef


def _lean(window: Recording, tc, axle: GyroAxle, final: CalibrationResult) -> tuple:
    """The axle refined at the final fit's ϑ and R, the camber's change and its turns' part.

    The change is the fitted camber track's 2–98 % range (rad; κ l(t) + δ τ(t),
    :mod:`wheelcal.model.rolling`), or :func:`lean_change_rad` from the gyro where the
    model has no track; the part that follows the turns is a :class:`LeanInTurns`.
    """
    params = final.params
    kin = wheel_kinematics(params, tc, final.layout.effects)
    rotation = params.bench.misalignment.matrix
    axle = refined_axle(window.gyro_radps, axle, kin.theta_rad, rotation)
    yaw, _ = yaw_across(tc, window.gyro_radps, axle, kin.theta_rad, rotation)
    lean_rate = lean_rate_radps(tc, window.gyro_radps, axle, kin.theta_rad, rotation)
    rolling = next(e for e in final.layout.effects if isinstance(e, Rolling))
    if rolling.has_camber_track:
        values = params.effect(rolling.name, rolling.size)
        low, high = np.percentile(rolling.camber_change(values, tc), [2.0, 98.0])
        change = float(high - low)
    else:
        change = lean_change_rad(tc, lean_rate, kin.theta_rad, yaw)
    rho = float(params.effect("rolling", 1)[0])
    lateral = rho * kin.omega_radps * yaw  # v ψ̇, up to its sign
    in_turns = lean_in_turns(tc, lean_rate, kin.theta_rad, yaw, lateral)
    return axle, change, in_turns


def _gyro_rows_filled(window: Recording) -> Recording:
    """The gyro's rows left out by the reader (a logger's glitch: NaN) interpolated.

    The wheel angle integrates the rate: a row missing is a gap in the angle, and a
    row interpolated from its neighbours costs the angle ~ω̈ Δt³ (nothing).
    """
    valid = window.gyro_valid
    if valid.all():
        return window
    if np.count_nonzero(valid) < 10:
        raise RecordingError(f"{window.source}: the gyroscope has too few valid rows")
    t = window.time_s
    gyro = np.column_stack([np.interp(t, t[valid], window.gyro_radps[valid, i]) for i in range(3)])
    return dataclasses.replace(window, gyro_radps=gyro)


def _plausible_gains(params: CalibrationParams) -> CalibrationParams:
    """Gains the leading passes let wander, restarted at 1 before the turns' pass.

    (An axis along the axle sees little but a cambered wheel's g sin γ, which the
    passes held vertical cannot place.)
    """
    gain = np.array(params.sensor.gain, dtype=float)
    wild = (gain < PLAUSIBLE_GAIN[0]) | (gain > PLAUSIBLE_GAIN[1])
    if not np.any(wild):
        return params
    gain[wild] = 1.0
    sensor = dataclasses.replace(params.sensor, gain=gain)
    return params.with_changes(sensor=sensor)


def _turned(
    params: CalibrationParams, angle_name: str, rolling_name: str | None
) -> CalibrationParams:
    """The frame turned 180° about X: α → π − α, R → R·D, ϑ₀, ω₀ → −ϑ₀, −ω₀ (s kept, m → −m).

    The camber track's coefficients c_k (the rolling effect's, with a track) restart at
    zero: the track turns sign with the camber, its basis keeps the first frame's ϑ.
    """
    bench = params.bench
    flip = np.diag([1.0, -1.0, -1.0])
    bench = dataclasses.replace(
        bench,
        tilt_rad=np.pi - bench.tilt_rad,
        misalignment=Rotation.composed(bench.misalignment.matrix @ flip),
    )
    spin = SpinParams(-params.spin.theta0_rad, -params.spin.omega_radps)
    effects = dict(params.effects)
    angle = np.array(effects[angle_name], dtype=float)
    angle[1:] = -angle[1:]  # the axle's response across it, seen from its other end
    effects[angle_name] = angle
    if rolling_name is not None and rolling_name in effects:
        rolling = np.array(effects[rolling_name], dtype=float)
        rolling[1:] = 0.0  # the held rolling's (ρ, c_k)
        effects[rolling_name] = rolling
    return params.with_changes(bench=bench, spin=spin, effects=effects)


def _half_turned(params: CalibrationParams) -> CalibrationParams:
    """ϑ advanced by π: r → −r, R → R·diag(−1, −1, 1), ϑ₀ → ϑ₀ + π (the same forces).

    Gravity's and the hub's in-plane components turn sign with ϑ + π, and so do the
    sensor's own centripetal and tangential forces with −r; R's turn about Z restores
    both in the sensor's frame.
    """
    bench = params.bench
    bench = dataclasses.replace(
        bench,
        radius_m=-bench.radius_m,
        misalignment=Rotation.composed(bench.misalignment.matrix @ np.diag([-1.0, -1.0, 1.0])),
    )
    spin = SpinParams(params.spin.theta0_rad + np.pi, params.spin.omega_radps)
    return params.with_changes(bench=bench, spin=spin)
