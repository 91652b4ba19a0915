"""Pedersini's four-step estimator, as the paper describes it (Sec. III, Fig. 5).

With r = T v the re-aligned data (eq. 15) and W = TΓR (eq. 16):

A. **Partial re-alignment** T = T''T'.  T' (rotation about X and Y) minimises
   σ²[r'_z] (eq. 24), making w₃₁ = w₃₂ = 0; T'' (about Z) minimises the
   excursion max r_y − min r_y (eq. 26), making w₂₁ = 0, so W is upper
   triangular (eq. 21).
B. **Bench rotation.**  Then r_y = k + A sin ϑ(t) (eq. 27–28) with ϑ(t) the
   quartic of eq. (2); ⟨ϑ₀, ω₀…ω₃, A, k⟩ minimise ‖r_y − (k + A sin ϑ)‖²
   (eq. 29).
C. **Misalignment, tilt, gain.**  For each candidate ⟨R, α⟩ the gains solve the
   over-determined system (30) — w₂₁ = w₃₁ = w₃₂ = 0, w₂₂ = w̄₂₂ = A/(g sinα)
   (eq. 31) — by the pseudo-inverse (eq. 32); ⟨R, α⟩ minimise the distance
   between the zero-mean re-aligned data and model (eq. 33–34), the model
   being the full eq. (1) with the known radius r.
D. **Offset** o minimises ‖v − v^m‖² (eq. 35).

Every search is a Nelder–Mead simplex.  What the text leaves open is decided
as documented in :mod:`wheelcal.estimate.paper.steps` (starting points, the π
ambiguity of eq. 26, the sign of ϑ), and the result is reported in the
contract's canonical form (:func:`wheelcal.estimate.joint.twins.choose_twin`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint import choose_twin
from wheelcal.estimate.paper.steps import (
    Geometry,
    Motion,
    Offset,
    Realignment,
    fit_geometry,
    fit_motion,
    fit_offset,
    realign,
    resolve_signs,
)
from wheelcal.model import BenchParams, CalibrationParams, SensorParams
from wheelcal.recording import Recording, RecordingError

#: Warn when the gains leave eq. (30) unsatisfied by more than this (relative to w̄₂₂).
SYSTEM_RESIDUAL_WARNING = 1e-2
#: Below this tilt the sinusoid that carries ϑ(t) (amplitude ∝ sinα) is too weak to trust.
SMALL_TILT_WARNING_DEG = 5.0


@dataclass(frozen=True, eq=False)
class PaperEstimate:
    """Result of :meth:`PaperEstimator.fit`.

    Attributes
    ----------
    params:
        All parameters, in the contract's canonical form (α ∈ [0°, 90°], the
        discrete twin with the smaller |o|), spin about the window centre.
    realignment:
        T of eq. (15), normalised so that W = TΓR has a positive diagonal
        (X toward the axis); the bench frame it refers to is the one *before*
        the twin choice, so ``params`` may be the mirrored twin of it.
    amplitude_mps2:
        A of eq. (28), > 0 (= w₂₂ g sinα for the normalised T).
    function_evaluations:
        Objective evaluations over all searches (Nelder–Mead plus the coarse
        grids that seed step A).
    step_seconds:
        Wall time of steps ``"A"``, ``"B"``, ``"C"``, ``"D"``.
    warnings:
        Non-converged searches, an unsatisfied eq. (30), small tilt, twin ambiguity.
    """

    params: CalibrationParams
    realignment: np.ndarray
    amplitude_mps2: float
    function_evaluations: int
    step_seconds: dict[str, float]
    warnings: tuple[str, ...]


@dataclass(frozen=True)
class PaperEstimator:
    """Configuration of the four-step estimator of Sec. III.

    Parameters
    ----------
    spin_degree:
        Degree K of the ω(t) polynomial of eq. (2) (the paper's cubic: 3).
    max_evaluations:
        Budget of objective evaluations for each Nelder–Mead search.
    """

    spin_degree: int = 3
    max_evaluations: int = 6000

    def __post_init__(self) -> None:
        if self.spin_degree < 0:
            raise ValueError("spin_degree must be >= 0")
        if self.max_evaluations < 10:
            raise ValueError("max_evaluations must be at least 10")

    def fit(self, recording: Recording) -> PaperEstimate:
        """Run steps III-A to III-D on one recording (the whole of it is the window).

        Raises
        ------
        RecordingError
            If the session does not give the radius r (the paper's one known
            quantity, Sec. II-C).
        """
        radius_m = recording.info.radius_m
        if radius_m is None:
            raise RecordingError(
                f"{recording.source}: the radius r is unknown; the paper's calibration "
                "needs it (give radius_m in the session metadata)"
            )
        gravity = recording.info.gravity_or_standard_mps2
        t = recording.time_s - 0.5 * (recording.time_s[0] + recording.time_s[-1])
        v = recording.accel_mps2
        seconds: dict[str, float] = {}

        clock = time.perf_counter()
        step_a = realign(v, self.max_evaluations)
        seconds["A"] = time.perf_counter() - clock

        clock = time.perf_counter()
        r_y = v @ step_a.matrix[1]  # Eq. (25)
        raw_motion = fit_motion(t, r_y, self.spin_degree, self.max_evaluations)
        signs = resolve_signs(t, v, step_a.matrix, raw_motion, radius_m, gravity)
        seconds["B"] = time.perf_counter() - clock

        clock = time.perf_counter()
        geometry = fit_geometry(
            t,
            v,
            signs.realignment,
            signs.motion,
            signs.sin_tilt_guess,
            radius_m,
            gravity,
            self.max_evaluations,
        )
        seconds["C"] = time.perf_counter() - clock

        clock = time.perf_counter()
        params = CalibrationParams(
            spin=signs.motion.spin,
            bench=BenchParams(
                tilt_rad=geometry.tilt_rad, radius_m=radius_m, misalignment=geometry.rotation
            ),
            sensor=SensorParams(offset_mps2=np.zeros(3), gain=geometry.gain),
            gravity_mps2=gravity,
        )
        offset = fit_offset(t, v, params, self.max_evaluations)
        params = params.with_changes(
            sensor=SensorParams(offset_mps2=offset.offset_mps2, gain=geometry.gain)
        )
        seconds["D"] = time.perf_counter() - clock

        warnings = self._warnings(step_a, raw_motion, geometry, offset)
        twin = choose_twin(params)
        if twin.warning is not None:
            warnings.append(twin.warning)
        return PaperEstimate(
            params=twin.chosen,
            realignment=signs.realignment,
            amplitude_mps2=signs.motion.amplitude_mps2,
            function_evaluations=(
                step_a.evaluations
                + raw_motion.evaluations
                + geometry.evaluations
                + offset.evaluations
            ),
            step_seconds=seconds,
            warnings=tuple(warnings),
        )

    def _warnings(
        self, step_a: Realignment, raw_motion: Motion, geometry: Geometry, offset: Offset
    ) -> list[str]:
        """Searches stopped by the budget, an unsatisfied eq. (30), a small tilt."""
        warnings = []
        for step, converged in (
            ("A", step_a.converged),
            ("B", raw_motion.converged),
            ("C", geometry.converged),
            ("D", offset.converged),
        ):
            if not converged:
                warnings.append(
                    f"step {step}: Nelder–Mead stopped before converging "
                    f"(budget {self.max_evaluations} evaluations)"
                )
        if geometry.system_residual > SYSTEM_RESIDUAL_WARNING:
            warnings.append(
                "step C: the gains leave eq. (30) unsatisfied "
                f"(relative residual {geometry.system_residual:.3g}); W = TΓR is not upper "
                "triangular, so T from step A is poor"
            )
        if np.rad2deg(geometry.tilt_rad) < SMALL_TILT_WARNING_DEG:
            warnings.append(
                f"tilt {np.rad2deg(geometry.tilt_rad):.2f}° is small: the sinusoid that "
                "carries ϑ(t) is weak and every estimate is poorly determined"
            )
        return warnings
