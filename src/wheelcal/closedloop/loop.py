"""The closed loop: test candidate effects on the residual, add the strongest, refit, repeat.

1. Fit the paper's model (joint ML fit).
2. Score-test every candidate effect at that fit (:mod:`wheelcal.closedloop.score`);
   effects the recording cannot identify are set aside and listed.
3. If the most significant one survives the family-wise level ``alpha`` after a
   Bonferroni correction over the candidates tested (a τ grid counts once per
   grid point), add it, refit everything, and go to 2.
4. Stop when nothing is significant.

The report gives every step's statistic, dof and p-value, the residual and the
parameters before and after, and how far the paper's model was biased, in
units of the final σ.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from wheelcal.closedloop.harmonics import wheel_harmonics
from wheelcal.closedloop.score import ScoreTest, gyro_stream, score_tests, screen
from wheelcal.estimate import RestSegment
from wheelcal.estimate.joint import CalibrationResult, JointFit
from wheelcal.model import (
    GAIN_NAMES,
    OFFSET_NAMES,
    Effect,
    EvaluatedModel,
    default_candidates,
    temperature_candidates,
)
from wheelcal.recording import Recording

#: Parameters whose base-model bias is reported in σ units.
BIAS_PARAMETERS = ("tilt_deg", *GAIN_NAMES, *OFFSET_NAMES)


@dataclass(frozen=True)
class ClosedLoop:
    """Configuration of the closed loop.

    Parameters
    ----------
    fit:
        The joint fit used for the base model and every refit.
    candidates:
        Effects to try (default: :func:`wheelcal.model.effects.default_candidates`).
    alpha:
        Family-wise significance level for adding an effect (Bonferroni-corrected).
    max_steps:
        Most effects added.
    """

    fit: JointFit = field(default_factory=JointFit)
    candidates: tuple[Effect, ...] = field(default_factory=default_candidates)
    alpha: float = 0.01
    max_steps: int = 4

    def run(
        self,
        recording: Recording,
        base: CalibrationResult | None = None,
        evaluated: EvaluatedModel | None = None,
        rests: tuple[RestSegment, ...] = (),
    ) -> Diagnosis:
        """Diagnose one recording (cut to its free-spin window).

        ``base``: the fit of the paper's model there, when the caller has it;
        ``evaluated``: the model at ``base`` as that fit's last pass left it (the
        first screen then forms no model of its own); ``rests``: the recording's
        rests around the window, static readings the screen adds as a stream of
        their own (:mod:`~wheelcal.closedloop.rest_stream`).
        """
        if base is None:
            base, evaluated = self.fit.fit_evaluated(recording)
        current = base
        steps: list[Step] = []
        tests: list[ScoreTest] = []
        # A measured temperature is a covariate the offsets may follow (model/temperature_offset).
        candidates = self.candidates + temperature_candidates(
            recording.time_s - base.centre_s, getattr(recording, "temperature_c", None)
        )
        # The gyro's readings at the rests join its stream wherever it is fitted or screened.
        gyro_rests = self.fit.rests_of(rests)
        gyro = gyro_stream(base, recording, self.fit.gyro_reading(), gyro_rests)
        fit, frame = _motion_fit(self.fit, base, with_gyro=gyro is not None)
        if gyro is not None:
            fit = dataclasses.replace(fit, gyro_rests=gyro_rests)
        for _ in range(self.max_steps):
            if current is not base:
                gyro = gyro_stream(current, recording, self.fit.gyro_reading(), gyro_rests)
            tests, rest_tests = screen(
                current,
                recording,
                candidates,
                evaluated if current is base else None,
                gyro,
                rests,
            )
            best = self._best(tests) or self._best(rest_tests)
            tests = tests + rest_tests
            if best is None:
                break
            effect = self._refined(best.effect, current, recording)
            effects = (*_own_effects(current), effect)
            # With a gyro the refit fits both streams; its reading starts where the
            # screen's regression (or the fit) left it.
            initial = current.params if gyro is None else gyro.params
            refit = dataclasses.replace(fit, effects=effects).fit(
                recording, initial=initial, frame=frame
            )
            free = effect.with_free_setting()
            if free is not None:  # e.g. τ of a warm-up: fitted once the amplitudes are there
                start = free.values_from(refit.params.effect(effect.name, effect.size), effect)
                initial = refit.params.with_changes(
                    effects={**refit.params.effects, free.name: start}
                )
                effects = (*_own_effects(current), free)
                refit = dataclasses.replace(fit, effects=effects).fit(
                    recording, initial=initial, frame=frame
                )
            steps.append(Step(test=best, tests=tuple(tests), result=refit))
            current = refit
        seen = {t.effect.label() for t in tests if t.identifiable}
        not_identifiable = tuple(
            t for t in tests if not t.identifiable and t.effect.label() not in seen
        )
        return Diagnosis(
            base=base,
            steps=tuple(steps),
            final=current,
            final_tests=tuple(tests),
            not_identifiable=not_identifiable,
            alpha=self.alpha,
        )

    def _best(self, tests: list[ScoreTest]) -> ScoreTest | None:
        """The most significant identifiable test, if it passes the family-wise level."""
        usable = [t for t in tests if t.identifiable]
        if not usable:
            return None
        best = min(usable, key=lambda t: t.p_corrected)
        return best if best.p_corrected < self.alpha else None

    @staticmethod
    def _refined(effect: Effect, current: CalibrationResult, recording: Recording) -> Effect:
        """A detected effect with its setting (e.g. τ) moved to the best of a finer grid.

        The decision used the coarse grid's corrected p-value; the refinement
        only chooses the setting the data prefer (largest score statistic).
        """
        options = effect.refinements()
        if not options:
            return effect
        tests = [t for t in score_tests(current, recording, options) if t.identifiable]
        return max(tests, key=lambda t: t.statistic).effect if tests else effect


#: Effects a gyro-aided fit adds itself (its motion model), not the loop's.
_MOTION_EFFECTS = ("spin_spline", "gyro")


def _own_effects(result: CalibrationResult) -> tuple[Effect, ...]:
    return tuple(e for e in result.layout.effects if e.name not in _MOTION_EFFECTS)


def _motion_fit(
    fit: JointFit, base: CalibrationResult, with_gyro: bool = False
) -> tuple[JointFit, tuple | None]:
    """The loop's fit with the base's gyro and wheel-angle spline, and the base's frame.

    A gyro-aided base (its layout holds the gyro reading and a spline) is refitted
    the same way, on the same time origin and knots.  ``with_gyro``: the recording
    has a gyroscope, so every refit fits it too (a free-spin base kept the
    accelerometer alone; an effect found with the gyro's help needs its stream).
    """
    names = {e.name: e for e in base.layout.effects}
    if not any(n in names for n in _MOTION_EFFECTS) and not with_gyro:
        return fit, None
    spline = names.get("spin_spline")
    fit = dataclasses.replace(
        fit,
        use_gyro="gyro" in names or with_gyro,
        spline_spacing_s=None if spline is None else spline.spacing_s,
    )
    frame = None
    if spline is not None:  # the spline's window is the fit's frame (centred times)
        frame = (base.centre_s + spline.start_s, base.centre_s + spline.end_s)
    return fit, frame


@dataclass(frozen=True, eq=False)
class Step:
    """One added effect: its test (among all the tests of that round) and the refit."""

    test: ScoreTest
    tests: tuple[ScoreTest, ...]
    result: CalibrationResult


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """Base fit, the steps of the loop, the final model, and what could not be told."""

    base: CalibrationResult
    steps: tuple[Step, ...]
    final: CalibrationResult
    final_tests: tuple[ScoreTest, ...]
    not_identifiable: tuple[ScoreTest, ...]
    alpha: float

    @property
    def effects(self) -> tuple[Effect, ...]:
        """Effects in the final model."""
        return self.final.layout.effects

    def base_bias_sigma(self) -> dict[str, float]:
        """(base − final) / σ_final for the sensor parameters and the tilt."""
        out = {}
        for name in BIAS_PARAMETERS:
            if name in self.base.names and name in self.final.names:
                out[name] = (
                    self.base.value_of(name) - self.final.value_of(name)
                ) / self.final.std_of(name)
        return out

    def harmonics(self, which: str = "final") -> dict:
        """Residual amplitude per wheel-angle harmonic (``base`` or ``final``)."""
        fit = self.final if which == "final" else self.base
        theta = fit.params.spin.theta_at(fit.centred_time_s)
        return wheel_harmonics(theta, fit.residual_mps2)
