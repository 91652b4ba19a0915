"""Canonical form and the discrete twins (CONTRACT, "Discrete twins").

Eq. (1) fits the data equally well with (α, o) and (180° − α, o + 2g cosα ΓR e_Z):
a_Z = g cosα is a constant, like the offset.  Re-expressed in the contract frame
(Z on the upward side, α ∈ [0°, 90°]) by turning the bench frame 180° about X
(Z → −Z, Y → −Y, ϑ → −ϑ, R → R·diag(1, −1, −1)), the twin keeps the *same*
tilt:

    (α, R, o, ϑ(t))  ≡  (α, R·D, o + 2g cosα Γ R e_Z, −ϑ(t)),   D = diag(1, −1, −1).

The residual is identical, so only prior knowledge can choose: a real offset is
far below g, so the twin with the smaller |o| is reported.  When the two
offsets differ by less than :data:`AMBIGUOUS_OFFSET_GAP_MPS2` (|α − 90°| small)
the choice is a guess and a warning says so; when they are equal (a vertical
wheel) the twin with positive spin is reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model import BenchParams, CalibrationParams, Rotation, SensorParams, SpinParams

#: Offsets that differ by less than this cannot be told apart by "offsets are small".
AMBIGUOUS_OFFSET_GAP_MPS2 = 1.0
_FLIP = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True, eq=False)
class TwinChoice:
    """The reported parameters, the rejected twin, and whether the choice is safe."""

    chosen: CalibrationParams
    rejected: CalibrationParams
    ambiguous: bool

    @property
    def warning(self) -> str | None:
        """Text for the user when the twins cannot be told apart."""
        if not self.ambiguous:
            return None
        return (
            "discrete twin ambiguity: tilt is near 90°, so the mirrored solution "
            f"(offset {np.round(self.rejected.sensor.offset_mps2, 3).tolist()} m/s²) fits "
            "equally well and its offset is not clearly larger; the smaller one was kept"
        )


def wrap_angle(angle_rad: float) -> float:
    """Angle in (−π, π]."""
    return float(np.pi - (np.pi - angle_rad) % (2 * np.pi))


def _negated_spin(spin: SpinParams) -> SpinParams:
    return SpinParams(theta0_rad=-spin.theta0_rad, omega_radps=-spin.omega_radps)


def _mirrored_effects(effects, negate: bool = False, half_turn: bool = False) -> dict:
    """Effect values of the same model after ϑ → −ϑ (``negate``) or ϑ → ϑ + π.

    Spin effects follow the phase: a spline correction Δϑ and the higher spin
    coefficients change sign with ϑ; an imbalance a sinϑ + b cosϑ becomes
    (a, −b) under ϑ → −ϑ and (−a, −b) under ϑ → ϑ + π; the gyro's w·ω keeps its
    reading when w changes sign with ω.  Sensor effects do not see ϑ.
    """
    out = dict(effects)
    for name, values in effects.items():
        v = np.array(values, dtype=float)
        if name in ("spin_spline", "spin_extension") and negate:
            v = -v
        elif name == "imbalance":
            if negate:
                v = v * np.array([1.0, -1.0])
            if half_turn:
                v = -v
        elif name == "gyro" and negate:
            v[:3] = -v[:3]  # w·ω keeps its reading
            v[9:12] = -v[9:12]  # G_Y·a_Y too: the turned frame has Y → −Y
        out[name] = v
    return out


def _with(
    params: CalibrationParams, spin=None, tilt=None, rot=None, offset=None, effects=None
) -> CalibrationParams:
    bench = params.bench
    return params.with_changes(
        spin=spin or params.spin,
        effects=params.effects if effects is None else effects,
        bench=BenchParams(
            tilt_rad=bench.tilt_rad if tilt is None else tilt,
            radius_m=bench.radius_m,
            misalignment=bench.misalignment if rot is None else rot,
        ),
        sensor=SensorParams(
            offset_mps2=params.sensor.offset_mps2 if offset is None else offset,
            gain=params.sensor.gain,
        ),
    )


def to_contract_frame(params: CalibrationParams) -> CalibrationParams:
    """The same model with α ∈ [0, π/2] and ϑ₀ ∈ (−π, π] (no change to v(t)).

    Returns ``params`` itself when it is already in that form.
    """
    if 0.0 <= params.bench.tilt_rad <= np.pi / 2 and -np.pi < params.spin.theta0_rad <= np.pi:
        return params
    alpha = wrap_angle(params.bench.tilt_rad)
    spin = params.spin
    effects = dict(params.effects)
    if alpha < 0:  # sin(−α)cosϑ = sin(α)cos(ϑ+π): move the sign into the phase
        alpha = -alpha
        spin = SpinParams(theta0_rad=spin.theta0_rad + np.pi, omega_radps=spin.omega_radps)
        effects = _mirrored_effects(effects, half_turn=True)
    rot = params.bench.misalignment
    if alpha > np.pi / 2:  # Z points down: turn the frame 180° about X
        alpha = np.pi - alpha
        rot = Rotation.composed(rot.matrix @ _FLIP)
        spin = _negated_spin(spin)
        effects = _mirrored_effects(effects, negate=True)
    spin = SpinParams(theta0_rad=wrap_angle(spin.theta0_rad), omega_radps=spin.omega_radps)
    return _with(params, spin=spin, tilt=alpha, rot=rot, effects=effects)


def twin_of(params: CalibrationParams) -> CalibrationParams:
    """The mirrored solution with the same tilt (see the module docstring)."""
    gain = params.sensor.gain
    rot = params.bench.misalignment.matrix
    shift = 2 * params.gravity_mps2 * np.cos(params.bench.tilt_rad) * gain * rot[:, 2]
    return _with(
        params,
        spin=_negated_spin(params.spin),
        rot=Rotation.composed(rot @ _FLIP),
        offset=params.sensor.offset_mps2 + shift,
        effects=_mirrored_effects(params.effects, negate=True),
    )


def choose_twin(params: CalibrationParams) -> TwinChoice:
    """Contract frame, then the twin with the smaller |offset|."""
    a = to_contract_frame(params)
    b = to_contract_frame(twin_of(a))
    norm_a = np.linalg.norm(a.sensor.offset_mps2)
    norm_b = np.linalg.norm(b.sensor.offset_mps2)
    gap = abs(norm_a - norm_b)
    if gap <= 1e-9 * max(1.0, norm_a):
        # Equal offsets (a vertical wheel, α = 90°): the axis has no upward side,
        # so report the twin that spins positively.
        a_first = a.spin.omega_radps[0] >= 0
    else:
        a_first = norm_a < norm_b
    chosen, rejected = (a, b) if a_first else (b, a)
    return TwinChoice(chosen=chosen, rejected=rejected, ambiguous=gap < AMBIGUOUS_OFFSET_GAP_MPS2)
