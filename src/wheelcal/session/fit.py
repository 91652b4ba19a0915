"""A whole recording → a calibration that passed the gates, or a refusal.

The joint fit (:mod:`wheelcal.estimate.joint.fit`) answers "what parameters
explain this window best"; a calibration also needs "does this window fit the
model at all, and is the answer plausible".  :class:`SessionFit` does both:

1. the free-spin window (found, or given), capped at ``max_window_s``;
2. the ``sampling`` gate on the window finder's fastest rate;
3. the joint fit, then the independent noise reference (rests, else the
   residual's spectrum) and the turn-by-turn motion check.  If the phase
   errors drift — the spin law cannot follow the wheel (a very long spin, a
   driven wheel) — the window is shortened (its start kept: the fastest,
   most informative part) and fitted again, down to ``min_window_s``; then
   the ``motion`` gate refuses;
4. the post-fit gates (:mod:`wheelcal.session.gates`): sampling at the
   fitted rate, turns, undetermined parameters, gain/offset ranges, units,
   convergence;
5. the warning band, and the rests' |a| = g check.

The result carries an :class:`~wheelcal.session.gates.Assessment`; its
warnings are appended to the result's.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from wheelcal.closedloop import ClosedLoop
from wheelcal.estimate import RestSegment, find_rests
from wheelcal.estimate.gyro import fastest_rate_radps, gyro_aided, gyro_block, gyro_rows
from wheelcal.estimate.joint import (
    CalibrationResult,
    InitialGuess,
    JointFit,
    clear_of_rails,
    wheel_angle_rad,
    without_disturbances,
)
from wheelcal.model import EvaluatedModel
from wheelcal.recording import CalibrationRefused, Recording, RecordingError
from wheelcal.session.clock_check import check_clock
from wheelcal.session.gates import (
    Assessment,
    Gates,
    gyro_findings,
    noise_warnings,
    refuse_few_turns,
    refuse_gain_scale,
    refuse_implausible,
    refuse_misfit,
    refuse_undersampled,
    rest_level,
    rest_warnings,
    tolerance_warnings,
    undetermined_parameters,
)
from wheelcal.session.motion_check import MotionCheck, broadband_noise, check_motion
from wheelcal.session.noise_reference import NoiseReference, noise_reference
from wheelcal.session.rest_check import check_rests
from wheelcal.session.result import SessionResult, WindowChoice, attempted
from wheelcal.session.window import (
    MAX_BRIDGED_GAP_S,
    FreeSpinWindow,
    find_free_spin,
    find_motion_window,
    fitted_stretches,
)

#: Each retry keeps this fraction of the window (its start).
SHRINK = 0.6
#: ``--gyro auto`` keeps the free spin's answer when it covers at least this share of the
#: motion the gyroscope measures; else it fits the whole motion (a second push, a brake …).
FREE_SPIN_SHARE = 0.8
GYRO_MODES = ("auto", "on", "off")
#: Refusals of the accelerometer-only fit that a gyroscope can overcome (``--gyro auto``).
GYRO_CAN_HELP = ("motion", "undetermined", "turns")


def choose_window(
    recording: Recording,
    start_s: float | None = None,
    end_s: float | None = None,
    max_window_s: float | None = None,
) -> WindowChoice:
    """The free-spin window: given (``start_s``/``end_s``) or found, capped in length."""
    if start_s is not None:
        reason = f"window given on the command line: {start_s:g}–{end_s:g} s"
        return WindowChoice(recording.window(start_s, end_s), None, reason)
    found = find_free_spin(recording)
    start, end, reason = found.start_s, found.end_s, found.reason
    if max_window_s is not None and end - start > max_window_s:
        end = start + max_window_s
        reason += (
            f"; capped to its first {max_window_s:g} s (eq. (2)'s cubic describes a spin-down "
            "for minutes, not for the whole of a long spin)"
        )
    return WindowChoice(recording.window(start, end), found, reason)


@dataclass(frozen=True)
class SessionFit:
    """Window → joint fit → gates, for one recording (see the module docstring)."""

    fitter: JointFit = field(default_factory=JointFit)
    gates: Gates = field(default_factory=Gates)
    start_s: float | None = None
    end_s: float | None = None
    #: "auto": the free spin's cubic unless only the gyro can follow the motion;
    #: "on": always fit the gyro with a flexible wheel angle; "off": ignore it.
    gyro: str = "auto"
    #: The closed loop run on the fit before the gates judge it (None: the paper's
    #: model as fitted).  The gates then judge the loop's final model.
    closed_loop: ClosedLoop | None = None
    #: What the result says was fitted: the geometry asked for, and the model.
    geometry: str = "radius"

    def __post_init__(self) -> None:
        if self.gyro not in GYRO_MODES:
            raise ValueError(f"gyro must be one of {GYRO_MODES}, got {self.gyro!r}")

    def run(self, recording: Recording) -> SessionResult:
        """Calibrate ``recording`` (rests, push and stop included).

        Raises
        ------
        CalibrationRefused
            When a gate refuses (the exception names the gate, the reason and the fix).
        RecordingError
            When the recording cannot be used at all (no free spin, no radius …).
        """
        answer = self.attempt(recording)
        if isinstance(answer, RecordingError):
            raise answer
        return answer

    def attempt(self, recording: Recording) -> SessionResult | RecordingError:
        """:meth:`run`'s answer as a value: the session, or the refusal (never raised).

        The accelerometer's free spin first, unless the gyro is asked for; a refusal
        the gyroscope can overcome (:meth:`judge`) then asks the gyro-aided fit.
        """
        has_gyro = _usable_gyro(recording)
        if self.gyro == "on" and not has_gyro:
            return RecordingError(
                f"{recording.source}: --gyro on, but the recording has no usable gyroscope"
            )
        if has_gyro and self.gyro == "on":
            return attempted(self._run_with_gyro, recording, "--gyro on")
        free = attempted(self._run_free_spin, recording)
        if not (has_gyro and self.gyro == "auto"):
            return free
        verdict = self.judge(free)
        if isinstance(verdict, str):  # the gyro can do what the accelerometer could not
            return attempted(self._run_with_gyro, recording, verdict)
        if isinstance(verdict, RecordingError):
            return verdict
        judged = attempted(self._with_gyro_block, verdict)
        if isinstance(judged, RecordingError) or self.start_s is not None:
            return judged
        return self._whole_motion(recording, judged)  # every second the gyro measures counts

    @staticmethod
    def judge(free: SessionResult | RecordingError) -> SessionResult | RecordingError | str:
        """The accelerometer's answer, with a gyroscope at hand (``--gyro auto``).

        The session stands; a refusal the gyro can overcome (:data:`GYRO_CAN_HELP`,
        or no free spin at all) becomes the reason to fit with the gyro (a string);
        any other refusal stands.
        """
        if isinstance(free, CalibrationRefused):
            if free.gate not in GYRO_CAN_HELP:
                return free
            return f"the accelerometer alone was refused ({free.gate}: {free.reason})"
        if isinstance(free, RecordingError):
            return f"no free spin ({free})"
        return free

    def _with_gyro_block(self, outcome: SessionResult) -> SessionResult:
        """The free spin's answer with the gyroscope judged from it, and the clock again."""
        result = outcome.result
        rows = gyro_rows(result, outcome.window.recording)
        block = gyro_block(result, rows, reading=self.fitter.gyro_reading())
        findings = tuple(gyro_findings(result.source, block, outcome.rests, self.gates))
        assessment = outcome.assessment
        # The clock judged again, with the gyro's evidence (it may refuse, or clear).
        bad = set(assessment.undetermined_names)
        clock = check_clock(result, bad, self.gates.clock_tolerance, block)
        kept = tuple(w for w in assessment.warnings if not _is_clock_warning(w, assessment))
        clock_warning = (clock.warning,) if clock.warning else ()
        assessment = dataclasses.replace(
            assessment,
            gyro=block,
            clock=clock,
            warnings=kept + findings + clock_warning,
        )
        return dataclasses.replace(outcome, assessment=assessment)

    def _whole_motion(self, recording: Recording, free: SessionResult) -> SessionResult:
        """The gyro-aided fit of the whole motion when the free spin left much of it out.

        ``--gyro auto`` keeps the free spin's answer (the accelerometer's own) when
        it covers at least :data:`FREE_SPIN_SHARE` of the motion the gyroscope
        measures; otherwise a second push, a driven stretch or a brake would be
        left out, and the whole motion is fitted with the flexible wheel angle.
        If that fit is refused, the free spin's answer stands, with a warning.
        """
        motion = attempted(find_motion_window, recording)
        if isinstance(motion, RecordingError):
            return free
        span = free.result.time_s[[0, -1]]
        free_s = float(span[1] - span[0])
        # Both windows are capped at max_window_s: an hour's spin gains nothing.
        if free_s >= FREE_SPIN_SHARE * min(motion.duration_s, self.gates.max_window_s):
            return free
        why = (
            f"the free spin {span[0]:.2f}–{span[1]:.2f} s ({free_s:.1f} s) is "
            f"{100 * free_s / motion.duration_s:.0f} % of the {motion.duration_s:.1f} s of "
            "motion the gyroscope measures: the whole motion is fitted"
        )
        whole = attempted(self._run_with_gyro, recording, why, motion)
        if not isinstance(whole, RecordingError):
            return whole
        gate = getattr(whole, "gate", "") or "error"
        warning = (
            f"the whole motion the gyroscope measures ({motion.duration_s:.1f} s) could not "
            f"be fitted ({gate}: {getattr(whole, 'reason', whole)}): calibrated on the free spin "
            f"alone ({free_s:.1f} s)"
        )
        assessment = dataclasses.replace(
            free.assessment, warnings=(*free.assessment.warnings, warning)
        )
        return dataclasses.replace(free, assessment=assessment)

    def _run_with_gyro(
        self, recording: Recording, why: str, found: FreeSpinWindow | None = None
    ) -> SessionResult:
        """The gyro-aided fit: the whole motion, a spline wheel angle, both streams.

        ``found``: the motion window when the caller has found it already.
        """
        gates = self.gates
        if self.start_s is not None:
            found = None
            window = recording.window(self.start_s, self.end_s)
            reason = f"window given on the command line: {self.start_s:g}–{self.end_s:g} s"
        else:
            if found is None:
                found = find_motion_window(recording)
            start, end = found.start_s, min(found.end_s, found.start_s + gates.max_window_s)
            window = recording.window(start, end)
            reason = found.reason + (
                f"; capped to its first {gates.max_window_s:g} s" if end < found.end_s else ""
            )
        _refuse_long_gap(window)
        rests = find_rests(recording, (float(window.time_s[0]), float(window.time_s[-1])))
        aided = gyro_aided(self.fitter, window, rests)
        fitter = aided.fitter
        guess = fitter.start(window)
        _check_implied_radius(guess, window, gates, rests)
        result = fitter.fit(window, guess=guess)
        notes = [
            f"gyro-aided ({why}): wheel angle = cubic + spline with knots every "
            f"{aided.knot_spacing_s:g} s (chosen by BIC on the gyro's rate)"
        ]
        result, window, disturbed_note = without_disturbances(fitter, result, window)
        notes.append(disturbed_note)
        if window.clip_limits_mps2 is not None:
            result, window, rail_note = clear_of_rails(fitter, result, window)
            notes.append(rail_note)
        fastest = fastest_rate_radps(result, aided.gyro_radps)
        refuse_undersampled(recording.source, window.rate_hz, fastest, gates)
        refuse_few_turns(result)
        result, diagnosis = self._refined(result, window, rests)
        # The gyro block judges the samples fitted, no others.
        block = gyro_block(result, gyro_rows(result, window))
        notes.append(_stretches_note(window))
        choice = WindowChoice(window, found, "; ".join([reason, *(n for n in notes if n)]))
        assessment = assess(result, rests, gates, None, block)
        return self._result(recording, result, assessment, choice, rests, diagnosis)

    def _refined(
        self,
        result: CalibrationResult,
        window: Recording,
        rests: tuple[RestSegment, ...],
        evaluated: EvaluatedModel | None = None,
    ) -> tuple[CalibrationResult, object | None]:
        """The closed loop's final model (and its report), or the fit as it is."""
        if self.closed_loop is None:
            return result, None
        diagnosis = self.closed_loop.run(window, base=result, evaluated=evaluated, rests=rests)
        return diagnosis.final, diagnosis

    def _run_free_spin(self, recording: Recording) -> SessionResult:
        """The accelerometer-only fit of the free spin (the paper's cubic)."""
        gates = self.gates
        choice = choose_window(recording, self.start_s, self.end_s, gates.max_window_s)
        fastest = None
        if choice.found is not None:
            fastest = max(abs(choice.found.omega_start_radps), abs(choice.found.omega_end_radps))
            refuse_undersampled(recording.source, recording.rate_hz, fastest, gates)
        spin_s = choice.recording.time_s[[0, -1]]
        exclude = (choice.found.start_s, choice.found.end_s) if choice.found else tuple(spin_s)
        rests = find_rests(recording, exclude)
        window = choice.recording
        note = rail_note = ""
        while True:
            guess = self.fitter.start(window, fastest)  # a shortened window: no faster
            _check_implied_radius(guess, window, gates, rests)
            result, evaluated = self.fitter.fit_evaluated(window, guess=guess)
            fitted = window
            if window.clip_limits_mps2 is not None:
                result, fitted, rail_note = clear_of_rails(self.fitter, result, window)
            # The closed loop before the motion check: an effect of the spin (a spin-down
            # beyond the cubic, an imbalance) is what the check would otherwise cut away.
            final, diagnosis = self._refined(result, fitted, rests, evaluated)
            motion, reference = _motion(final, fitted, rests, evaluated)
            if motion is None or not motion.inadequate(gates.motion_z, gates.motion_shift_sigma):
                break
            if window.duration_s * SHRINK < gates.min_window_s:
                raise CalibrationRefused(
                    recording.source,
                    "motion",
                    "the wheel's motion is not a free spin that eq. (2) can describe: letting "
                    f"the wheel angle follow a smooth spline would move {motion.worst()} "
                    f"(score χ² = {motion.statistic:.0f} on {motion.dof} dof) — a driven "
                    "wheel, a second push, or speed changes",
                    "record a free spin (push once, then let go), choose its window with "
                    "--start-s/--end-s, or record the gyroscope",
                )
            t0 = float(window.time_s[0])
            shorter = window.duration_s * SHRINK
            note = (
                f"the spin law could not follow the whole window (freeing the motion moved "
                f"{motion.worst()}); shortened to its first {shorter:.0f} s"
            )
            window = window.window(t0, t0 + shorter)
        window = fitted
        note = "; ".join(x for x in (note, rail_note) if x)
        if note:
            choice = WindowChoice(window, choice.found, choice.reason + "; " + note)
        omega = final.params.spin.omega_at(final.centred_time_s[[0, -1]])
        refuse_undersampled(recording.source, window.rate_hz, float(np.max(np.abs(omega))), gates)
        refuse_few_turns(final)
        assessment = assess(final, rests, gates, motion, reference=reference)
        return self._result(recording, final, assessment, choice, rests, diagnosis)

    def _result(self, recording, result, assessment, choice, rests, diagnosis) -> SessionResult:
        model = "paper" if self.closed_loop is None else "closed_loop"
        return SessionResult(
            source=recording.source,
            result=result,
            assessment=assessment,
            window=choice,
            rests=rests,
            diagnosis=diagnosis,
            recording=recording,
            geometry=self.geometry,
            model=model,
        )


def _stretches_note(window: Recording) -> str:
    """``fitted a–b, c–d s`` when the fitted samples are more than one stretch (else empty)."""
    stretches = fitted_stretches(window.time_s, window.rate_hz)
    if len(stretches) < 2:
        return ""
    listed = ", ".join(f"{a:.2f}–{b:.2f}" for a, b in stretches)
    total = sum(b - a for a, b in stretches)
    return f"fitted {len(stretches)} stretches: {listed} s ({total:.1f} s)"


def _refuse_long_gap(window: Recording) -> None:
    """A spline of the wheel angle has knots over the window's time span, not its samples.

    Windows found automatically never span a long gap; a window given with
    --start-s/--end-s might, and its knots would then grow with the gap.
    """
    steps = np.diff(window.time_s)
    longest = float(steps.max()) if steps.size else 0.0
    if longest > MAX_BRIDGED_GAP_S:
        raise RecordingError(
            f"{window.source}: the window spans a gap of {longest:.3g} s without samples "
            f"(longer than {MAX_BRIDGED_GAP_S:g} s): the gyro-aided fit's wheel angle cannot "
            "bridge it; choose a window on one side with --start-s/--end-s"
        )


def _check_implied_radius(
    guess: InitialGuess, window: Recording, gates: Gates, rests: tuple[RestSegment, ...] = ()
) -> None:
    """Refuse before fitting when the start already puts the gains far from 1.

    The start's :meth:`~wheelcal.estimate.joint.InitialGuess.implied_mean_gain`
    at the window's radius against the gates' gain range.  The ``rests`` tell a
    unit error from a radius error (:func:`~wheelcal.session.gates.refuse_gain_scale`).
    """
    mean_gain = guess.implied_mean_gain(window.info.radius_m)
    if mean_gain is None:
        return
    lo, hi = gates.gain_range
    if not lo <= mean_gain <= hi:
        refuse_gain_scale(
            window.source,
            mean_gain,
            window.info.radius_m,
            f"the gains average ≈ {mean_gain:.4g}",
            gates,
            rest_level(rests),
        )


def _motion(
    result: CalibrationResult,
    window: Recording,
    rests: tuple[RestSegment, ...],
    evaluated: EvaluatedModel | None = None,
) -> tuple[MotionCheck | None, NoiseReference]:
    """The motion check with the residual's broadband level as the noise, and that reference.

    ``evaluated``: the model at the result as the fit's last pass left it (its ϑ
    and bench force then serve both).
    """
    reference = noise_reference(result.residual_mps2, wheel_angle_rad(result, evaluated), rests)
    noise = broadband_noise(result.noise, reference.broadband_mps2)
    return check_motion(result, window.accel_mps2, noise, evaluated=evaluated), reference


def _is_clock_warning(warning: str, assessment: Assessment) -> bool:
    clock = assessment.clock
    return clock is not None and clock.warning is not None and warning == clock.warning


def _usable_gyro(recording: Recording) -> bool:
    gyro = getattr(recording, "gyro_radps", None)
    return gyro is not None and int(np.sum(np.all(np.isfinite(gyro), axis=1))) >= 100


def assess(
    result: CalibrationResult,
    rests: tuple[RestSegment, ...],
    gates: Gates,
    motion: MotionCheck | None = None,
    gyro=None,
    reference: NoiseReference | None = None,
    nulled: tuple[tuple[str, str], ...] = (),
) -> Assessment:
    """Apply the post-fit gates to ``result``; return their :class:`Assessment`.

    ``reference`` is the noise reference of this very result with these rests,
    when the caller has it already (the motion check needs it too).  ``nulled``:
    parameters a check before found undetermined, with the reason (the field fit's
    lean check).

    Raises :class:`CalibrationRefused` when the refusal band is hit.
    """
    found = undetermined_parameters(result, gates)
    found += [(name, why) for name, why in nulled if name not in {n for n, _ in found}]
    undetermined = refuse_implausible(result, gates, found, rest_level(rests))
    bad = {name for name, _ in undetermined}
    noise = reference or noise_reference(result.residual_mps2, wheel_angle_rad(result), rests)
    refuse_misfit(result.source, noise, gates)
    checks = () if bad else check_rests(result, rests, gates.rest_alpha)
    gyro_notes = [] if gyro is None else gyro_findings(result.source, gyro, rests, gates)
    clock = check_clock(result, bad, gates.clock_tolerance, gyro)
    warnings = (
        gyro_notes
        + tolerance_warnings(result, gates, bad)
        + noise_warnings(noise, gates, result.residual_mps2, result.time_s)
        + rest_warnings(checks, gates)
        + [f"{name} is undetermined: {reason}" for name, reason in undetermined]
        + ([clock.warning] if clock.warning else [])
    )
    return Assessment(
        gates=gates,
        noise=noise,
        motion=motion,
        rest_checks=checks,
        undetermined=tuple(undetermined),
        warnings=tuple(warnings),
        gyro=gyro,
        clock=clock,
    )


def session_of_fit(
    result: CalibrationResult,
    recording: Recording,
    window=None,
    gates: Gates | None = None,
    diagnosis=None,
    model: str = "paper",
    geometry: str = "radius",
) -> SessionResult:
    """A fit made by hand (e.g. ``JointFit().fit(window)``) judged as a session.

    ``recording`` is the whole recording the fitted window was cut from;
    ``window`` the :class:`~wheelcal.session.window.FreeSpinWindow` it was found
    in (None: given).  The rests outside the fitted span are found, and the
    post-fit gates (:func:`assess`) applied — so the result can be written
    (:func:`wheelcal.calibration.session_json.write_calibration`, the ``.rrd``)
    like one of :class:`SessionFit`.  Raises :class:`CalibrationRefused` as
    :func:`assess` does.
    """
    span = (float(result.time_s[0]), float(result.time_s[-1]))
    exclude = (window.start_s, window.end_s) if window is not None else span
    rests = find_rests(recording, exclude)
    reason = "window found by the caller" if window is not None else "window given by the caller"
    choice = WindowChoice(recording.window(*span), window, reason)
    return SessionResult(
        source=result.source,
        result=result,
        assessment=assess(result, rests, gates or Gates()),
        window=choice,
        rests=rests,
        diagnosis=diagnosis,
        recording=recording,
        geometry=geometry,
        model=model,
    )
