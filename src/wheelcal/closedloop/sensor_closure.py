"""Sensor-level closure: pool the evidence of all recordings of one sensor.

Effects that belong to the sensor (nonlinearity, cross-axis coupling) are the
same in every recording, but each recording sees them faintly: most of a
quadratic nonlinearity is absorbed by that recording's offset and gain.  Ten
recordings together see it clearly.  For one ``sensor_id``:

1. **Pooled tests** — for each sensor-intrinsic candidate, the per-recording
   scores and informations are summed into one test of the *shared* parameter
   (its own dof; :func:`~wheelcal.closedloop.score.pooled_score_tests`), with a
   Bonferroni correction over the candidates.
2. **Joint sensor fit** — offsets, gains and the effects found shared, each
   recording's bench and spin its own (:mod:`wheelcal.closedloop.sensor_fit`);
   cross-axis coupling joins when the mountings can identify it.  What pooling
   bought is σ per parameter against the best single recording.
3. **Spread before and after** — per (sensor, mounting) group and parameter,
   the ratio of the observed spread to the one the per-recording σ predict, and
   the χ² chance of a ratio that large, Bonferroni-corrected over every
   parameter tested.  "Before" is the paper's model; "after" adds each
   recording's own effects and the sensor's pooled ones.  Offsets that warm up
   or drift are compared at the start of each recording (the sensor's cold
   offset), the value that should repeat.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import special

from wheelcal.closedloop.score import ScoreTest, pooled_score_tests
from wheelcal.closedloop.sensor_fit import SensorFit, SensorFitResult
from wheelcal.estimate.joint import CalibrationResult, JointFit
from wheelcal.model import AXES, CrossAxis, Effect, intrinsic_candidates
from wheelcal.recording import Recording

SPREAD_PARAMETERS = (
    "tilt_deg",
    "euler_1_deg",
    "euler_2_deg",
    "euler_3_deg",
    *(f"gain_{a}" for a in AXES),
    *(f"offset_{a}_mps2" for a in AXES),
)


@dataclass(frozen=True)
class ClosureInput:
    """The closure's input: one recording of the sensor, its mounting and its local effects."""

    recording: Recording
    mounting_id: str = ""
    local_effects: tuple[Effect, ...] = ()


@dataclass(frozen=True)
class SpreadTest:
    """Observed spread of one parameter over a group, before and after the effects."""

    parameter: str
    mounting_id: str
    sessions: int
    ratio_before: float
    p_before: float
    ratio_after: float
    p_after: float

    def as_dict(self, tests: int, alpha: float) -> dict:
        """JSON-ready, with Bonferroni-corrected p-values over ``tests``."""
        pb, pa = min(1.0, self.p_before * tests), min(1.0, self.p_after * tests)
        return {
            "parameter": self.parameter,
            "mounting_id": self.mounting_id,
            "sessions": self.sessions,
            "ratio_before": float(self.ratio_before),
            "p_before_corrected": float(pb),
            "inflated_before": bool(pb < alpha),
            "ratio_after": float(self.ratio_after),
            "p_after_corrected": float(pa),
            "inflated_after": bool(pa < alpha),
        }


@dataclass(frozen=True, eq=False)
class SensorClosure:
    """Everything the closure found for one sensor."""

    sensor_id: str
    sessions: int
    pooled_tests: tuple[ScoreTest, ...]
    effects_found: tuple[Effect, ...]
    sensor_fit: SensorFitResult | None
    spread: tuple[SpreadTest, ...]
    candidates_tested: tuple[str, ...]
    alpha: float

    def as_dict(self) -> dict:
        """The report's ``closure`` entry for this sensor."""
        tests = len(self.spread)
        return {
            "sensor_id": self.sensor_id,
            "sessions": self.sessions,
            "alpha": self.alpha,
            "pooled_tests": [t.as_dict() for t in self.pooled_tests],
            "effects_found": [e.name for e in self.effects_found],
            "candidates_tested": list(self.candidates_tested),
            "sensor_fit": None if self.sensor_fit is None else self.sensor_fit.as_dict(),
            "spread": [s.as_dict(tests, self.alpha) for s in self.spread],
            "spread_correction": f"Bonferroni over {tests} parameter tests",
        }


def offset_at(result: CalibrationResult, t_centred_s: float) -> np.ndarray:
    """Offset (m/s²) at a time, including warm-up and drift effects (o is at the centre)."""
    offset = result.params.sensor.offset_mps2.copy()
    t = np.array([t_centred_s])
    for effect in result.layout.effects:
        if effect.offset_like:
            values = result.params.effect(effect.name, effect.size)
            offset += effect.sensor_delta(
                values, t, np.zeros((1, 3)), result.params.sensor.gain, False
            ).delta[0]
    return offset


def offset_at_with_std(
    result: CalibrationResult, t_centred_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`offset_at` and its σ, propagated through the fit's covariance.

    The derivatives with respect to the offsets and the offset-like effects'
    parameters (amplitudes, τ) are taken by central differences.
    """
    value = offset_at(result, t_centred_s)
    movers = [e for e in result.layout.effects if e.offset_like]
    names = [f"{e.name}.{p}" for e in movers for p in e.param_names]
    std = np.empty(3)
    for i, axis in enumerate(AXES):
        cols = [result.names.index(f"offset_{axis}_mps2")] + [result.names.index(n) for n in names]
        grad = [1.0]
        for name in names:
            effect_name, param = name.split(".")
            effect = next(e for e in movers if e.name == effect_name)
            k = effect.param_names.index(param)
            values = np.array(result.params.effect(effect_name, effect.size))
            h = 1e-6 * max(1.0, abs(values[k]))
            shifted = []
            for sign in (1, -1):
                v = values.copy()
                v[k] += sign * h
                params = result.params.with_changes(
                    effects={**result.params.effects, effect_name: v}
                )
                shifted.append(
                    offset_at(dataclasses.replace(result, params=params), t_centred_s)[i]
                )
            grad.append((shifted[0] - shifted[1]) / (2 * h))
        grad = np.array(grad)
        cov = result.covariance[np.ix_(cols, cols)]
        std[i] = float(np.sqrt(grad @ cov @ grad))
    return value, std


def _comparable(result: CalibrationResult) -> dict[str, tuple[float, float]]:
    """Parameters to compare across recordings: offsets at the recording start if they move."""
    out = {
        n: (result.value_of(n), result.std_of(n)) for n in SPREAD_PARAMETERS if n in result.names
    }
    if any(e.offset_like for e in result.layout.effects):
        # The recording's first sample (power-on): where a warm-up starts.
        start, start_std = offset_at_with_std(result, -result.centre_s)
        for a, o, sd in zip(AXES, start, start_std, strict=True):
            out[f"offset_{a}_mps2"] = (float(o), float(sd))
    return out


def _ratio(values: np.ndarray, stds: np.ndarray) -> tuple[float, float]:
    n = values.size
    predicted = float(np.sqrt(np.mean(stds**2)))
    ratio = float(np.std(values, ddof=1) / predicted)
    # stats.chi2.sf's own function (its numbers), without importing scipy.stats
    return ratio, float(special.chdtrc(n - 1, (n - 1) * ratio**2))


def close_sensor(
    sensor_id: str,
    sessions: Sequence[ClosureInput],
    alpha: float = 0.01,
    fit: JointFit | None = None,
    candidates: tuple[Effect, ...] | None = None,
) -> SensorClosure:
    """Pooled tests, joint sensor fit and spread test for one sensor's recordings."""
    fit = fit or JointFit()
    candidates = candidates or intrinsic_candidates()
    recordings = [s.recording for s in sessions]
    before = [fit.fit(r) for r in recordings]
    local = [
        dataclasses.replace(fit, effects=s.local_effects).fit(s.recording, initial=b.params)
        if s.local_effects
        else b
        for s, b in zip(sessions, before, strict=True)
    ]
    pooled = tuple(pooled_score_tests(local, recordings, candidates))
    found = tuple(
        t.effect
        for t in pooled
        if t.identifiable and t.p_corrected < alpha and t.effect.name != "cross_axis"
    )
    after = [
        dataclasses.replace(fit, effects=(*s.local_effects, *found)).fit(
            s.recording, initial=lo.params
        )
        if found
        else lo
        for s, lo in zip(sessions, local, strict=True)
    ]
    sensor_fit = None
    if len(sessions) >= 2:
        shared = found
        if len({s.mounting_id for s in sessions}) >= 2:
            shared = (*found, CrossAxis())  # kept only if the mountings identify it
        sensor_fit = SensorFit(shared_effects=shared).fit(recordings, local)
    spread = []
    for mounting in sorted({s.mounting_id for s in sessions}):
        members = [i for i, s in enumerate(sessions) if s.mounting_id == mounting]
        if len(members) < 3:
            continue
        tables_before = [_comparable(before[i]) for i in members]
        tables_after = [_comparable(after[i]) for i in members]
        for name in SPREAD_PARAMETERS:
            if not all(name in t for t in tables_before + tables_after):
                continue
            vb = np.array([t[name][0] for t in tables_before])
            sb = np.array([t[name][1] for t in tables_before])
            va = np.array([t[name][0] for t in tables_after])
            sa = np.array([t[name][1] for t in tables_after])
            rb, pb = _ratio(vb, sb)
            ra, pa = _ratio(va, sa)
            spread.append(SpreadTest(name, mounting, len(members), rb, pb, ra, pa))
    tested = [t.effect.label() for t in pooled]
    for s in sessions:
        tested += [e.label() for e in s.local_effects]
    return SensorClosure(
        sensor_id=sensor_id,
        sessions=len(sessions),
        pooled_tests=pooled,
        effects_found=found,
        sensor_fit=sensor_fit,
        spread=tuple(spread),
        candidates_tested=tuple(dict.fromkeys(tested)),
        alpha=alpha,
    )
