"""Plausibility gates: a calibration is given out only when it passes them.

A fit can converge to numbers that look like a calibration and are not one —
a radius typed in mm, a unit mislabelled, a spin sampled too slowly, a wheel
driven rather than free.  Two bands (defaults justified in the README,
"When wheelcal refuses"):

**Refuse** (:class:`~wheelcal.recording.CalibrationRefused`, exit 1):

* ``unit`` — the gains average ≈ 1/9.8 or ≈ 9.8: samples in g labelled m/s²
  or the reverse;
* ``gain_range`` — a determined gain outside [0.5, 2]: no accelerometer is
  that far from nominal; by eq. (9) the radius is the likely culprit (the
  message names the factor and the radius the data would imply if the gains
  were exactly 1, as a diagnosis, and asks for the radius to be measured);
* ``offset_range`` — a determined offset above 0.3 g;
* ``convergence`` — the fit did not converge in the directions the data
  determine;
* ``undetermined`` — the recording determines none of the gains;
* ``sampling`` — fewer than ``min_samples_per_turn`` samples per turn at the
  fastest rate: successive samples more than 90° of wheel angle apart leave
  the direction and count of turns to guesswork;
* ``motion`` — the spin law cannot follow the wheel: freeing the motion (a
  spline of ϑ) would move a gain or offset significantly and by more than its
  σ (:mod:`wheelcal.session.motion_check`), even on a shortened window, and
  there is no gyroscope to follow the motion;
* ``turns`` — fewer than 10 turns in the window;
* ``misfit`` — the residual at the wheel's harmonics (what the model should
  have explained) exceeds ``max_harmonic_ratio`` × the independent noise
  floor: the fit does not describe the data at all, whatever it converged to;
* ``lean`` — a wheel in the field whose camber, freed to move (a spline on top
  of the gyro's track), would shift an in-plane gain or offset or the radius
  significantly and by more than its σ (:mod:`wheelcal.estimate.field.lean_check`);
  shifts of the axle axis's own gain and offset only make those null instead.
* ``clock`` — the samples are stamped off their nominal rate and the gyro
  confirms that the clock, not the sensor, is off
  (:mod:`wheelcal.session.clock_check`).

**Warn** (exit 0, the warning names the cause and the fix): a gain or offset
outside datasheet tolerances; the mean gain γ̄ far from 1 (a radius error
r → βr scales every gain by 1/β, eq. 9; the implied radius is r·γ̄); a
residual well above the independent noise floor; a rest that does not read
|a| = g after calibration; a stamped rate off its nominal rate by enough to
bias the calibration beyond 2 σ if the clock were the cause (``clock:``).

**Undetermined** parameters — statistical σ above the datasheet tolerance,
i.e. the recording tells less than the datasheet — are reported as ``null``
with the reason, never as a usable-looking number.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from wheelcal.estimate.joint import CalibrationResult
from wheelcal.model import AXES, STANDARD_GRAVITY_MPS2
from wheelcal.recording import CalibrationRefused
from wheelcal.session.motion_check import MotionCheck
from wheelcal.session.noise_reference import NoiseReference
from wheelcal.session.rest_check import RestCheck

#: The fit needs this many wheel turns in the window (paper: ~100 in 90 s).
MIN_TURNS = 10.0
#: An axis whose gain lies outside this range while another's lies inside reads what no
#: accelerometer axis does: the recording does not determine it (reported null).
PHYSICAL_GAIN_RANGE = (0.5, 2.0)
#: … and so does one whose offset exceeds this (g) while another's does not.
PHYSICAL_MAX_OFFSET_G = 0.3


@dataclass(frozen=True)
class Gates:
    """Thresholds of the refusal and warning bands (see the module docstring)."""

    # refuse
    gain_range: tuple[float, float] = (0.5, 2.0)
    max_offset_g: float = 0.3
    min_samples_per_turn: float = 4.0
    motion_z: float = 4.0
    motion_shift_sigma: float = 1.0
    max_window_s: float = 300.0
    min_window_s: float = 20.0
    max_harmonic_ratio: float = 5.0
    #: A wheel in the field: how far its camber may change during the drive (°), from
    #: the gyro's roll about the direction of travel — no limit by default: the camber
    #: follows the gyro's track, and the lean check judges what it does to the answer.
    max_lean_change_deg: float = float("inf")
    #: The lean check: a camber free to move may shift a parameter by up to this many σ
    #: of its own difference (significance) …
    lean_z: float = 4.0
    #: … or by up to this many σ of the fit (materiality); beyond both, it moved.
    lean_shift_sigma: float = 1.0
    #: A rolling wheel's axle axis offset trades with its camber: null above this σ (m/s²).
    field_axle_offset_std_mps2: float = 0.1
    # warn
    gain_tolerance: float = 0.05
    offset_tolerance_g: float = 0.1
    mean_gain_tolerance: float = 0.05
    unexplained_ratio: float = 1.5
    rest_alpha: float = 0.01
    #: The sample clock is judged only when the stamped rate is further than this
    #: (relative) from its nominal rate (10× a crystal's 100 ppm).
    clock_tolerance: float = 0.001

    def __post_init__(self) -> None:
        lo, hi = (float(x) for x in self.gain_range)
        if not 0 < lo < 1 < hi:
            raise ValueError(f"gain_range must satisfy 0 < low < 1 < high, got {self.gain_range}")
        object.__setattr__(self, "gain_range", (lo, hi))
        for name in (
            "max_offset_g",
            "min_samples_per_turn",
            "motion_z",
            "motion_shift_sigma",
            "gain_tolerance",
            "offset_tolerance_g",
            "mean_gain_tolerance",
            "max_window_s",
            "min_window_s",
            "max_harmonic_ratio",
            "lean_z",
            "lean_shift_sigma",
            "field_axle_offset_std_mps2",
            "clock_tolerance",
        ):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        if not self.max_lean_change_deg > 0:
            raise ValueError(
                f"max_lean_change_deg must be positive (inf: no limit), got "
                f"{self.max_lean_change_deg}"
            )
        if not self.unexplained_ratio > 1:
            raise ValueError(f"unexplained_ratio must be > 1, got {self.unexplained_ratio}")
        if not 0 < self.rest_alpha < 1:
            raise ValueError(f"rest_alpha must lie in (0, 1), got {self.rest_alpha}")
        if not self.min_window_s < self.max_window_s:
            raise ValueError("min_window_s must be below max_window_s")

    def to_dict(self) -> dict:
        """The thresholds, for the calibration JSON (no limit: null)."""
        out = {}
        for k, v in self.__dict__.items():
            if isinstance(v, tuple):
                v = list(v)
            elif isinstance(v, float) and not np.isfinite(v):
                v = None
            out[k] = v
        return out


@dataclass(frozen=True, eq=False)
class Assessment:
    """What the gates made of a calibration that was not refused."""

    gates: Gates
    noise: NoiseReference | None
    motion: MotionCheck | None
    rest_checks: tuple[RestCheck, ...]
    undetermined: tuple[tuple[str, str], ...]  # (parameter, reason)
    warnings: tuple[str, ...]
    window_note: str = ""
    extra: dict = field(default_factory=dict)
    #: The gyroscope's calibration (wheelcal.estimate.gyro.block), when there is one.
    gyro: object | None = None
    #: The sample clock's check (wheelcal.session.clock_check), its warning among ``warnings``.
    clock: object | None = None

    @property
    def undetermined_names(self) -> tuple[str, ...]:
        """Names of the parameters reported as null."""
        return tuple(name for name, _ in self.undetermined)


def _g(value: float) -> str:
    return f"{value:.4g}"


def undetermined_parameters(result: CalibrationResult, gates: Gates) -> list[tuple[str, str]]:
    """Gains and offsets whose σ exceeds the datasheet tolerance, with the reason."""
    limits = {f"gain_{a}": gates.gain_tolerance for a in AXES}
    limits.update(
        {f"offset_{a}_mps2": gates.offset_tolerance_g * STANDARD_GRAVITY_MPS2 for a in AXES}
    )
    causes = " ".join(w for w in result.identifiability.warnings if "poorly determined" not in w)
    out = []
    for name, limit in limits.items():
        std = result.std_of(name)
        if not std <= limit:
            what = "∞ (no information)" if not np.isfinite(std) else _g(std)
            reason = (
                f"this recording cannot determine it: σ = {what}, more than the datasheet "
                f"tolerance {_g(limit)}"
            )
            out.append((name, reason + (f"; {causes}" if causes else "")))
    return out


def refuse_implausible(
    result: CalibrationResult,
    gates: Gates,
    undetermined: list,
    rest_level_mps2: float | None = None,
) -> list[tuple[str, str]]:
    """Raise :class:`CalibrationRefused` for the refusal band's post-fit gates.

    ``rest_level_mps2``: |a| the rests read in the stated unit (see
    :func:`refuse_gain_scale`), ``None`` without rests.

    Returns ``undetermined`` with the axes that are implausible on their own added
    (a gain outside :data:`PHYSICAL_GAIN_RANGE` or an offset above
    :data:`PHYSICAL_MAX_OFFSET_G` while another axis reads a plausible one): such an
    axis is one the recording does not determine — an axle axis that sees only the
    turns and a changing camber, say — and it is reported null with the reason, the
    other axes calibrated.  Then the gates as given (``gain_range``, ``max_offset_g``)
    judge the axes left: gains off by one factor (a radius or a unit, eq. 9) or
    offsets beyond the limit refuse the recording.
    """
    source = result.source
    undetermined = list(undetermined)
    bad = {name for name, _ in undetermined}
    gains = {a: result.value_of(f"gain_{a}") for a in AXES if f"gain_{a}" not in bad}
    radius = result.params.bench.radius_m
    if not gains:
        raise CalibrationRefused(
            source,
            "undetermined",
            "this recording determines none of the gains (" + undetermined[0][1] + ")",
            "spin the wheel by hand and let it slow down freely for 60–120 s, with the "
            "sensor mounted tilted on the wheel",
        )
    lo, hi = PHYSICAL_GAIN_RANGE
    wild = {a: v for a, v in gains.items() if not lo <= v <= hi}
    sound = {a: v for a, v in gains.items() if a not in wild}
    if wild and sound:
        undetermined += _alone(result, "gain", wild, sound, f"outside [{lo:g}, {hi:g}]")
        gains = sound
    mean_gain = float(np.exp(np.mean(np.log(np.abs(list(gains.values()))))))
    listing = ", ".join(f"gain_{a} = {_g(v)}" for a, v in gains.items())
    lo, hi = gates.gain_range
    if any(not lo <= v <= hi for v in gains.values()):
        refuse_gain_scale(
            source, mean_gain, radius, listing, gates, rest_level_mps2, result.layout.fit_radius
        )
    bad = {name for name, _ in undetermined}
    offsets = {
        a: result.value_of(f"offset_{a}_mps2") for a in AXES if f"offset_{a}_mps2" not in bad
    }
    physical = PHYSICAL_MAX_OFFSET_G * STANDARD_GRAVITY_MPS2
    alone = {a: v for a, v in offsets.items() if abs(v) > physical}
    plausible = {a: v for a, v in offsets.items() if a not in alone}
    if alone and plausible:
        where = f"above {PHYSICAL_MAX_OFFSET_G:g} g"
        undetermined += _alone(result, "offset", alone, plausible, where)
        offsets = plausible
    limit = gates.max_offset_g * STANDARD_GRAVITY_MPS2
    large = {a: v for a, v in offsets.items() if abs(v) > limit}
    if large:
        listing = ", ".join(f"offset_{a} = {_g(v)} m/s²" for a, v in large.items())
        raise CalibrationRefused(
            source,
            "offset_range",
            f"{listing}: above {gates.max_offset_g:g} g, which no working accelerometer has",
            "check the unit and the radius, and that the wheel spun freely (see the window)",
        )
    if not result.converged:
        raise CalibrationRefused(
            source,
            "convergence",
            "the fit did not converge (" + _convergence_text(result) + ")",
            "check the free-spin window (--start-s/--end-s) and the radius",
        )
    return undetermined


def _alone(
    result: CalibrationResult, kind: str, wild: dict, sound: dict, where: str
) -> list[tuple[str, str]]:
    """Null reasons for axes implausible on their own (:func:`refuse_implausible`)."""
    unit = " m/s²" if kind == "offset" else ""
    others = ", ".join(f"{a} {_g(v)}{unit}" for a, v in sound.items())
    out = []
    for a, v in wild.items():
        name = f"{kind}_{a}" + ("_mps2" if kind == "offset" else "")
        std = result.std_of(name)
        out.append(
            (
                name,
                f"the fit gives {_g(v)}{unit} (σ {_g(std)}), {where}, which no accelerometer "
                f"axis reads while its others read {others}: this recording does not "
                "determine this axis (what it sees the model does not describe)",
            )
        )
    return out


#: Rests that read |a| within this fraction of g confirm the stated unit (a unit error
#: is a factor of 9.8; a radius error does not move a rest's reading at all).
REST_UNIT_TOLERANCE = 0.1


def rest_level(rests) -> float | None:
    """Median |a| the rests read, in the recording's stated unit (``None`` without rests)."""
    levels = [float(np.linalg.norm(r.mean_mps2)) for r in rests]
    return float(np.median(levels)) if levels else None


def refuse_gain_scale(
    source: str,
    mean_gain: float,
    radius_m: float,
    listing: str,
    gates: Gates,
    rest_level_mps2: float | None = None,
    radius_fitted: bool = False,
) -> None:
    """Refuse gains far from 1 (``unit`` or ``gain_range``), naming every likely cause.

    A factor near g is a unit stated wrongly; any factor is, by eq. (9), also a
    radius error — radius ×0.1 and m/s² labelled g both give gains ≈ 10, and
    the spin alone cannot tell them apart — so both are named when both fit.
    The rests can: a sensor at rest reads |a| = g in the right unit whatever
    the radius, so rests at ≈ 9.8 m/s² (``rest_level_mps2``) rule the unit out
    and the refusal is ``gain_range``, the radius named alone.
    """
    lo, hi = gates.gain_range
    g = STANDARD_GRAVITY_MPS2
    implied = radius_m * mean_gain
    # A diagnosis, never a value to type: r·γ̄ equals the true radius only if the gains
    # average exactly 1, and a sensor 1 % off would bias every gain by 1 % if it were copied.
    radius_text = (
        f"the {radius_m:.4g} m given is off by a factor of about {mean_gain:.3g}: by eq. (9) a "
        f"radius error scales every gain, and the data would imply {implied:.4g} m only if "
        "the gains were exactly 1"
    )
    if radius_fitted:
        radius_text = (
            f"the gains share a factor of about {mean_gain:.3g} with the radius the fit found "
            f"({radius_m:.4g} m): by eq. (9) the two trade, and gravity, which should fix "
            "the gains' scale, did not"
        )
    measure = (
        "measure the radius (axle centre to the sensor's centre, in metres) and give that "
        "measured value with --radius; do not type the implied radius in: it hides the "
        "sensor's own gain error"
    )
    head = f"{listing}: outside [{lo:g}, {hi:g}], which no accelerometer is"
    if rest_level_mps2 is not None and abs(rest_level_mps2 / g - 1) < REST_UNIT_TOLERANCE:
        raise CalibrationRefused(
            source,
            "gain_range",
            f"{head}: {radius_text} (not the unit: the rests read |a| = "
            f"{rest_level_mps2:.3g} m/s², gravity, in the unit the file states)",
            measure,
        )
    for factor, seen, stated, unit in ((1 / g, "g", "m/s²", "g"), (g, "m/s²", "g", "m/s^2")):
        if abs(np.log(mean_gain / factor)) < np.log(1.35):
            raise CalibrationRefused(
                source,
                "unit",
                f"{head}. The gains are about {'1/' if factor < 1 else ''}{g:.2f}: the samples "
                f"look like {seen} but are labelled {stated} — or {radius_text}",
                f"state the unit (--accel-unit {unit}, or the channel's unit metadata), or "
                f"{measure}",
            )
    raise CalibrationRefused(source, "gain_range", f"{head}: {radius_text}", measure)


def _convergence_text(result: CalibrationResult) -> str:
    for warning in result.warnings:
        if warning.startswith("the fit did not converge"):
            return warning.partition("(")[2].rstrip(")")
    return "unknown reason"


def tolerance_warnings(result: CalibrationResult, gates: Gates, bad: set[str]) -> list[str]:
    """The warning band on the sensor parameters (datasheet tolerances, mean gain)."""
    out = []
    gains = {a: result.value_of(f"gain_{a}") for a in AXES if f"gain_{a}" not in bad}
    for a, v in gains.items():
        if abs(v - 1) > gates.gain_tolerance:
            out.append(
                f"gain_{a} = {_g(v)} is {100 * abs(v - 1):.1f} % from 1, beyond the "
                f"±{100 * gates.gain_tolerance:g} % sensitivity tolerance of typical datasheets "
                "(--gain-tolerance sets it for your sensor)"
            )
    offset_limit = gates.offset_tolerance_g * STANDARD_GRAVITY_MPS2
    for a in AXES:
        name = f"offset_{a}_mps2"
        if name in bad:
            continue
        v = result.value_of(name)
        if abs(v) > offset_limit:
            out.append(
                f"offset_{a} = {_g(v)} m/s² ({abs(v) / STANDARD_GRAVITY_MPS2 * 1e3:.0f} mg) is "
                f"beyond the ±{gates.offset_tolerance_g * 1e3:g} mg zero-g tolerance of typical "
                "datasheets (--offset-tolerance-g sets it for your sensor)"
            )
    if len(gains) == 3:
        mean_gain = float(np.mean(list(gains.values())))
        if abs(mean_gain - 1) > gates.mean_gain_tolerance:
            radius = result.params.bench.radius_m
            out.append(
                f"the gains average {mean_gain:.4f}, {100 * abs(mean_gain - 1):.1f} % from 1. "
                f"By eq. (9) a radius error r → βr scales every gain by 1/β and no data can "
                f"tell the two apart: either the radius is {radius * mean_gain:.4g} m rather "
                f"than the {radius:.4g} m given (re-measure it), or the sensor's sensitivity "
                f"is {100 * (mean_gain - 1):+.1f} %"
            )
    return out


#: A residual sample beyond this many robust σ of its axis is an isolated spike.
SPIKE_SIGMAS = 8.0


def isolated_spikes(
    residual_mps2: np.ndarray, time_s: np.ndarray | None = None
) -> tuple[int, str, np.ndarray] | None:
    """Residual samples far beyond the rest (a glitch, a knock): count, the worst, rms without.

    Robust σ per axis (1.4826 × median |r|); a sample beyond :data:`SPIKE_SIGMAS` of
    it on any axis is a spike (Gaussian noise gives one such in ~10¹⁴ samples).
    Returns None when there is none; else the count, the worst in words and the
    residual rms per axis with the spikes left out.
    """
    r = np.asarray(residual_mps2, dtype=float)
    if r.shape[0] < 20:
        return None
    sigma = 1.4826 * np.median(np.abs(r - np.median(r, axis=0)), axis=0)
    z = np.abs(r) / np.maximum(sigma, 1e-12)
    spikes = np.any(z > SPIKE_SIGMAS, axis=1)
    count = int(spikes.sum())
    if count == 0 or count > 1e-3 * r.shape[0]:  # many: not isolated (vibration, a misfit)
        return None
    row, axis = np.unravel_index(int(np.argmax(z)), z.shape)
    when = f" at t = {time_s[row]:.2f} s" if time_s is not None else ""
    worst = f"{r[row, axis]:+.3g} m/s² on {AXES[axis]}{when}"
    return count, worst, np.sqrt(np.mean(r[~spikes] ** 2, axis=0))


def noise_warnings(
    noise: NoiseReference,
    gates: Gates,
    residual_mps2: np.ndarray | None = None,
    time_s: np.ndarray | None = None,
) -> list[str]:
    """The warning band on the residual against the independent noise floor.

    With the ``residual`` the warning names isolated spikes (a logger's corrupt
    sample, a knock) when they alone lift the residual above the floor, not the
    bench's vibration.
    """
    ratio = float(np.max(noise.ratio))
    if not ratio > gates.unexplained_ratio:
        return []
    axis = int(np.argmax(noise.ratio))
    source = "at rest" if noise.source == "rests" else "between the wheel harmonics"
    unexplained = noise.unexplained_mps2[axis]
    vibration = noise.vibration_mps2[axis] if noise.source == "rests" else 0.0
    harmonic = noise.harmonic_mps2[axis]
    spikes = isolated_spikes(residual_mps2, time_s) if residual_mps2 is not None else None
    if spikes is not None and np.all(
        spikes[2] <= gates.unexplained_ratio * np.maximum(noise.floor_mps2, 1e-12)
    ):
        count, worst, _ = spikes
        return [
            f"the residual on {AXES[axis]} ({noise.residual_rms_mps2[axis]:.3g} m/s² rms) is "
            f"{ratio:.1f}× the sensor's noise {source} ({noise.floor_mps2[axis]:.3g} m/s²) "
            f"because of {count} isolated sample{'s' if count > 1 else ''} far from the model "
            f"(worst {worst}): a logger glitch or a knock, not vibration; too small for the "
            "reader's outlier check, it barely moves the calibration"
        ]
    if vibration >= harmonic:
        cause = (
            f"most of it is broadband ({vibration:.3g} m/s² between the wheel harmonics): the "
            "wheel vibrates as it turns (bearings, a loose mount, the road); the σ include it"
        )
    else:
        cause = (
            f"most of it repeats with the wheel angle ({harmonic:.3g} m/s² at the wheel "
            "harmonics): the model lacks an effect — run `wheelcal diagnose`"
        )
    return [
        f"the residual on {AXES[axis]} ({noise.residual_rms_mps2[axis]:.3g} m/s² rms) is "
        f"{ratio:.1f}× the sensor's noise {source} ({noise.floor_mps2[axis]:.3g} m/s²): "
        f"{unexplained:.3g} m/s² is left unexplained; {cause}"
    ]


#: G beyond this many σ of its prior is a finding (the data pulled it there).
G_FINDING_SIGMAS = 3.0


def _bias_moved_between_rests(block, rests: tuple) -> str:
    """A warning when the joint fit left the rests' gyro readings out: they disagreed.

    (:class:`~wheelcal.estimate.joint.gyro_rests.GyroRests` drops rests whose gyro
    means differ beyond their σ and G's prior: the bias moved between them.)
    """
    means = [r.gyro_mean_radps for r in rests if r.gyro_mean_radps is not None]
    if block.rests_used != 0 or len(means) < 2:
        return ""
    spread = np.ptp(np.array(means), axis=0)
    axis = int(np.argmax(spread))
    return (
        f"the gyro's mean differs by {np.rad2deg(spread[axis]):.3g} °/s on its {AXES[axis]} "
        "axis between the rests, beyond its noise and its sensitivity to acceleration: its "
        "bias moved (a warm-up?), so the rests were not used to pin its bias and G — their σ "
        "are the spin's alone"
    )


def gyro_findings(source: str, block, rests: tuple, gates: Gates) -> list[str]:
    """The gyro stream's gate against its own noise floor (the rests), and G's finding.

    The gyro's residual rms over its noise at rest (pooled over the rests that
    read the gyro): above ``unexplained_ratio`` a warning, above
    ``max_harmonic_ratio`` with most of it once per turn the ``misfit`` refusal —
    the rate ripples with the wheel beyond the model (an unbalanced wheel the
    screen could not resolve).  A sensitivity to linear acceleration fitted
    beyond :data:`G_FINDING_SIGMAS` σ of its prior is reported with its likely
    causes.
    """
    out = []
    g, prior = block.g_sensitivity, block.g_prior_std
    if g is not None and prior is not None and np.max(np.abs(g)) > G_FINDING_SIGMAS * prior:
        dps_per_g = float(np.max(np.abs(g))) * STANDARD_GRAVITY_MPS2 * 180 / np.pi
        out.append(
            f"the gyro's sensitivity to linear acceleration fits {dps_per_g:.2g} °/s/g, beyond "
            f"the {prior * STANDARD_GRAVITY_MPS2 * 180 / np.pi:.2g} °/s/g of its class "
            "(--gyro-g-sensitivity): the rate ripples once per turn beyond the model — an "
            "unbalanced wheel, or a gyro more sensitive to acceleration than assumed"
        )
    moved = _bias_moved_between_rests(block, rests)
    if moved:
        out.append(moved)
    floors = [r.gyro_noise_std_radps for r in rests if r.gyro_noise_std_radps is not None]
    if not floors:
        return out
    floor = np.sqrt(np.mean(np.square(floors), axis=0))
    ratio = block.residual_rms_radps / np.maximum(floor, 1e-12)
    axis = int(np.argmax(ratio))
    if not ratio[axis] > gates.unexplained_ratio:
        return out
    ripple = block.once_per_turn_radps
    turn = ripple[axis] / np.sqrt(2) if ripple is not None else 0.0  # its rms
    excess = np.sqrt(max(block.residual_rms_radps[axis] ** 2 - floor[axis] ** 2, 0.0))
    text = (
        f"the gyro's residual on its {AXES[axis]} axis ({block.residual_rms_radps[axis]:.3g} "
        f"rad/s rms) is {ratio[axis]:.1f}× its noise at rest ({floor[axis]:.3g} rad/s); "
        f"{turn:.3g} rad/s rms of it turns once per wheel turn"
    )
    if ratio[axis] > gates.max_harmonic_ratio and turn > 0.5 * excess:
        raise CalibrationRefused(
            source,
            "misfit",
            text + ": the wheel's rate ripples once per turn beyond the model (an unbalanced "
            "wheel the effect screen could not resolve, or a gyro far more sensitive to "
            "acceleration than its class)",
            "balance the wheel (a counterweight opposite the sensor), or give the gyro's "
            "g-sensitivity with --gyro-g-sensitivity",
        )
    out.append(text + " (vibration while the wheel turns, or a rate ripple the model lacks)")
    return out


def refuse_misfit(source: str, noise: NoiseReference, gates: Gates) -> None:
    """The ``misfit`` gate: structure the model leaves at the wheel harmonics, ≫ the noise."""
    ratio = noise.harmonic_mps2 / np.maximum(noise.floor_mps2, 1e-12)
    axis = int(np.argmax(ratio))
    if ratio[axis] > gates.max_harmonic_ratio:
        raise CalibrationRefused(
            source,
            "misfit",
            f"the model does not describe the data: on {AXES[axis]} it leaves "
            f"{noise.harmonic_mps2[axis]:.3g} m/s² at the wheel's harmonics, "
            f"{ratio[axis]:.0f}× the sensor's noise ({noise.floor_mps2[axis]:.3g} m/s²)",
            "check the window (--start-s/--end-s) and the setup; `wheelcal diagnose` "
            "looks for the effect the model lacks",
        )


def rest_warnings(checks: tuple[RestCheck, ...], gates: Gates) -> list[str]:
    """The warning band on the rests' corrected |a|."""
    out = []
    for c in checks:
        if c.flagged:
            out.append(
                f"at rest ({c.start_s:.1f}–{c.end_s:.1f} s) the calibrated |a| is "
                f"{c.norm_mps2:.4f} m/s², not g = {c.gravity_mps2:.4f} ({c.z:+.1f} σ, family-wise "
                f"α = {gates.rest_alpha:g}): something outside the model differs between rest "
                "and spin — an offset that warms up, a nonlinearity, or a static offset unlike "
                "the dynamic one (run `wheelcal diagnose`)"
            )
    return out


def samples_per_turn(rate_hz: float, omega_max_radps: float) -> float:
    """Samples per wheel turn at the fastest rate."""
    return float(2 * np.pi * rate_hz / max(abs(omega_max_radps), 1e-12))


def refuse_undersampled(source: str, rate_hz: float, omega_max_radps: float, gates: Gates):
    """Raise the ``sampling`` gate when a turn holds too few samples."""
    per_turn = samples_per_turn(rate_hz, omega_max_radps)
    if per_turn < gates.min_samples_per_turn:
        need_hz = gates.min_samples_per_turn * abs(omega_max_radps) / (2 * np.pi)
        raise CalibrationRefused(
            source,
            "sampling",
            f"{rate_hz:.3g} Hz sampling holds {per_turn:.1f} samples per turn at the wheel's "
            f"{abs(omega_max_radps):.3g} rad/s (need ≥ {gates.min_samples_per_turn:g}): the "
            "spin cannot be resolved",
            f"record at ≥ {need_hz:.3g} Hz (200 Hz is typical) or spin slower",
        )


def refuse_few_turns(result: CalibrationResult) -> float:
    """Turns of the wheel in the fitted window; the ``turns`` gate if too few."""
    t = result.centred_time_s
    spin = result.params.spin
    turns = abs(float(spin.theta_at(t[-1:])[0] - spin.theta_at(t[:1])[0])) / (2 * np.pi)
    if turns < MIN_TURNS:
        raise CalibrationRefused(
            result.source,
            "turns",
            f"the wheel turned only {turns:.1f} times in the fitted window "
            f"(need at least {MIN_TURNS:g})",
            "spin it harder or record longer",
        )
    return turns
