"""A wheel rolling on the ground: rigid-body kinematics of the hub (the ``rolling`` effect).

Scope: a wheel **rolling without slip** at a camber γ = 90° − α (a vertical
wheel: γ = 0; a wheelchair's 16–20°), steered or yawing at a rate ψ̇ about the
vertical — a robot's, a car's or a wheelchair's wheel with an IMU on it.  The
camber may change during the drive (a road's cross-slope and crown, a banked
curve, a steered wheel's caster, a body's roll): its change is a measured
**camber track** (below).  Out of scope: wheel slip, the road's grade in the hub's
travel direction (a second-order share of ρ ω̇).

Frames (CONTRACT): bench frame fixed to the wheel, Z the axle (its upper end,
outboard on a cambered wheel), X radial from the sensor to the hub, Y = Z × X.
The upward unit vector in the bench frame is n = (cos γ cos ϑ, cos γ sin ϑ,
sin γ) and the wheel's angular velocity Ω = ψ̇ n − ω e_Z, ω = ϑ̇ its rate on its
carrier.  Rolling without slip: σ v = ρ Ω_z with Ω_z = ψ̇ sin γ − ω (σ = ±1 the
vehicle's side, v ≥ 0 the hub's speed, ρ the rolling radius).  The exact
specific force (derived in the world frame in
:mod:`wheelcal.simulate.field_kinematics`) less eq. (1) at α = 90° − γ is
this effect's Δa (s = sin ϑ, c = cos ϑ, sγ = sin γ, cγ = cos γ,
Ω̇_z = ψ̈ sγ − ω̇):

    Δa_X = −ρ Ω̇_z s − ρ Ω_z ψ̇ sγ c + r (ψ̇² cγ² s² + ψ̇² sγ² − 2 ω ψ̇ sγ)
    Δa_Y =  ρ Ω̇_z c − ρ Ω_z ψ̇ sγ s − r ψ̈ sγ − r ψ̇² cγ² s c
    Δa_Z =  ρ Ω_z ψ̇ cγ + r cγ (ψ̈ s + 2 ω ψ̇ c − ψ̇² sγ c)

(the sensor on the wheel's mid-plane; an offset h along the axle is left out).
On a vertical wheel (γ = 0) it reads as below.

A vertical wheel (α = 90°, the axle horizontal): u = (cos ϑ, sin ϑ, 0) is the
upward unit vector in the bench frame and the wheel's angular velocity is

    Ω = −ω e_Z + ψ̇ u                                              (bench frame)

(the wheel's spin −ω e_Z, see :mod:`wheelcal.simulate.gyro`, plus the yaw of
the vehicle; u̇ = ω (−sin ϑ, cos ϑ, 0), so the spin still gives ϑ̇ = ω).

Rolling without slip keeps the contact point c = hub − ρ u at rest, with ρ the
rolling radius: v_hub = Ω × ρ u = −ρ ω f, f = e_Z × u = (−sin ϑ, cos ϑ, 0) the
direction of travel.  In the world, f turns with the yaw: ḟ = ψ̇ u × f = ψ̇ e_Z,
so the hub accelerates by

    a_hub = −ρ ω̇ f − ρ ω ψ̇ e_Z          (travel ρ·ω̇; lateral v·ψ̇ along the axle)

The sensor sits at p = −r X from the hub (r its distance from the axle, the
bench radius), and adds Ω̇ × p + Ω × (Ω × p) with, in the bench frame,

    Ω̇ = (ψ̈ cos ϑ − ψ̇ ω sin ϑ,  ψ̈ sin ϑ + ψ̇ ω cos ϑ,  −ω̇).

Eq. (1)'s a = (r ω² + g cos ϑ, r ω̇ + g sin ϑ, 0) holds the spin's share; the
rest, Δa, is this effect (s = sin ϑ, c = cos ϑ):

    Δa_X =  ρ ω̇ s + r ψ̇² s²
    Δa_Y = −ρ ω̇ c − r ψ̇² s c
    Δa_Z = −ρ ω ψ̇ + r ψ̈ s + 2 r ω ψ̇ c

(the γ = 0 case of the formulas above).  The cross term 2 r ω ψ̇ cos ϑ turns
once per turn along the axle, at the frequency of gravity: a car wheel at
10 m/s (ρ = 0.3 m, ω ≈ 33 rad/s) in a 0.3 rad/s turn with the sensor at
r = 0.2 m feels ±4 m/s² of it.

**The yaw rate comes from the gyro**: ψ̇(t) is the gyro's reading across the
axle, demodulated with the wheel angle (the field fit's
:func:`~wheelcal.estimate.field.gyro_axle.yaw_across`).  The gyro's scale across
the wheel axis is not calibrated by the spin, so the effect may fit a scale κ
with ψ̇ = κ ψ̇_gyro (or,
``yaw_scale_free=False``, take the yaw as measured by a calibrated gyro; with
``yaw_across_axle`` the series is the yaw's share across the axle, ψ̇ cos γ):

    parameters  ρ (``radius_m``)  and  κ (``yaw_scale``),

and Δa is the formula above with ρ and κ ψ̇_gyro, κ ψ̈_gyro.  At (ρ, κ) = (0, 0)
Δa = 0: the fixed wheel is a point of the rolling model, so the field fit tells
the two apart by the size of ρ it fits (:mod:`wheelcal.estimate.field.fit`).

**The camber track.**  On a road the camber is not one number: the wheel rolls
about its direction of travel as the road's cross-slope changes, in a banked
curve, as a steered wheel's caster turns it, as a body rolls.  The gyro reads
that roll across the axle, along the direction of travel, and its integral is
the camber's change l(t) (:func:`wheelcal.estimate.field.gyro_axle.camber_track`,
zero at the window's centre and held where the wheel rests, where the gyro's own
errors cannot be told from a roll).  The gyro's axes across the axle read it on
the scale they read the yaw, so

    γ(t) = γ₀ + κ l(t) + Σ_k c_k N_k(t),

κ the yaw's scale, N_k the shapes the gyro's own errors give l (a steady rate, a
share of the yaw, …; parameters ``camber_<name>``), which the accelerometer's
gravity along the axle pins.  γ₀ = 90° − α is the fit's tilt (the camber at the
window's centre).  Gravity is then g (cos γ(t) cos ϑ, cos γ(t) sin ϑ, sin γ(t)):
the effect adds its change from eq. (1)'s,

    Δa_g = g (Δc cos ϑ, Δc sin ϑ, Δs),   Δc = cos γ(t) − cos γ₀,  Δs = sin γ(t) − sin γ₀

and the turns' terms above take the camber of the moment, Γ(t) = γ₀ + Δγ(t), for
sin γ and cos γ (in a curve banked by 5° a car's lateral force turns 0.09 g·v ψ̇
into the wheel's plane).  A 5° change moves a_Z by 0.85 m/s² — the axle axis's
signal, which calibrates its gain; unmodelled, it leaves that axis's gain at
nowhere near 1 and its offset astray.  The camber's rate λ = γ̇ is the carrier's
roll, which adds its own forces at the sensor (:class:`_RollTerms`: 2 r ω λ along the
axle, the roll's Coriolis term, 0.2 m/s² on a car's rim at 0.03 rad/s of roll).  With
no track (``camber_track_rad=None``) the camber is γ₀ throughout.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from wheelcal.model.effects import Effect, samples_of
from wheelcal.model.kinematics import Kinematics
from wheelcal.model.parameters import STANDARD_GRAVITY_MPS2


@dataclass(frozen=True, eq=False)
class ForceDelta:
    """A change Δa (N, 3) of the bench-frame specific force, and its partials.

    ``d_own`` (k, N, 3) w.r.t. the effect's parameters; ``by_theta``,
    ``by_omega``, ``by_omega_dot`` (N, 3) w.r.t. ϑ, ω, ω̇ (chain rule into the
    spin rows); ``by_radius`` (N, 3) w.r.t. the bench radius r; ``by_tilt`` (N, 3)
    w.r.t. the tilt α (a cambered wheel's γ = 90° − α).
    """

    delta: np.ndarray
    d_own: np.ndarray | None = None
    by_theta: np.ndarray | None = None
    by_omega: np.ndarray | None = None
    by_omega_dot: np.ndarray | None = None
    by_radius: np.ndarray | None = None
    by_tilt: np.ndarray | None = None


class Rolling(Effect):
    """A wheel rolling on level ground, vertical or cambered (module docstring).

    Parameters
    ----------
    time_s:
        Centred times of the yaw-rate series.
    yaw_rate_radps:
        ψ̇_gyro(t), the yaw rate measured by the gyro (rad/s), one per time.
    yaw_accel_radps2:
        ψ̈_gyro(t); default: the series' numerical derivative.
    yaw_scale_free:
        Fit κ and ε (default).  ``False`` holds κ = 1, ε = 0 and fits ρ alone (parameters:
        ``radius_m``): the yaw rate taken as given (from a calibrated gyro).
    yaw_offset_free:
        With ``yaw_scale_free``: fit ε too (default); ``False`` holds ε = 0.
    yaw_scale_prior_std:
        With ``yaw_scale_free``: a Gaussian prior κ ~ N(1, this²) (``None``: none).  A
        gyro's scale across its axle is known only to its sensor class's tolerance, and
        on a vertical wheel κ multiplies every force of the turns along the axle, as
        that axis's gain does: without the prior the two are one.
    yaw_across_axle:
        The series is y = ψ̇ cos γ = ψ̇ sin α, the yaw rate's share across the axle (what
        a gyro's rotating components show), so ψ̇ = κ y / sin α + ε with the fitted
        tilt.  ``False`` (default): the series is ψ̇ itself.
    camber_track_rad:
        l(t), the camber's change measured by the gyro (rad, one per time; module
        docstring), or ``None`` (a constant camber).
    camber_basis:
        With a track: the series N_k(t) its errors take (name → one value per time),
        each with a parameter ``camber_<name>`` (module docstring).
    """

    name = "rolling"
    stage = "force"
    param_names = ("radius_m", "yaw_scale", "yaw_offset_radps")
    description = "wheel rolling on level ground: hub travel ρ·ω̇, turns ρ·ω·ψ̇, Ω cross terms"

    def __init__(
        self,
        time_s: np.ndarray,
        yaw_rate_radps: np.ndarray,
        yaw_accel_radps2: np.ndarray | None = None,
        yaw_scale_free: bool = True,
        yaw_across_axle: bool = False,
        yaw_offset_free: bool = True,
        yaw_scale_prior_std: float | None = None,
        camber_track_rad: np.ndarray | None = None,
        camber_basis: dict[str, np.ndarray] | None = None,
    ) -> None:
        t = np.asarray(time_s, dtype=float)
        rate = np.asarray(yaw_rate_radps, dtype=float)
        if t.ndim != 1 or t.size < 2 or rate.shape != t.shape or not np.all(np.diff(t) > 0):
            raise ValueError("need increasing times and one yaw rate per time")
        if not np.all(np.isfinite(rate)):
            raise ValueError("the yaw rate must be finite")
        accel = np.gradient(rate, t) if yaw_accel_radps2 is None else yaw_accel_radps2
        accel = np.asarray(accel, dtype=float)
        if accel.shape != t.shape:
            raise ValueError("one yaw acceleration per time")
        self.time_s, self.yaw_rate_radps, self.yaw_accel_radps2 = t, rate, accel
        self.yaw_scale_free = bool(yaw_scale_free)
        self.yaw_across_axle = bool(yaw_across_axle)
        self.yaw_offset_free = bool(yaw_offset_free) and self.yaw_scale_free
        if yaw_scale_prior_std is not None and not (
            np.isfinite(yaw_scale_prior_std) and yaw_scale_prior_std > 0
        ):
            raise ValueError("yaw_scale_prior_std must be a positive number or None")
        self.yaw_scale_prior_std = yaw_scale_prior_std if self.yaw_scale_free else None
        self._set_camber(camber_track_rad, camber_basis)
        names = ["radius_m"]
        if self.yaw_scale_free:
            names.append("yaw_scale")
            if self.yaw_offset_free:
                names.append("yaw_offset_radps")
        self._camber_first = len(names)
        names += [f"camber_{name}" for name in self.camber_basis]
        self.param_names = tuple(names)

    def _set_camber(self, track, basis) -> None:
        self.camber_track_rad, self.camber_basis = _camber_series(self.time_s, track, basis)
        self._camber = (
            None
            if self.camber_track_rad is None
            else _CamberSeries.of(self.time_s, [self.camber_track_rad, *self.camber_basis.values()])
        )

    def prior_std_values(self) -> np.ndarray | None:
        """σ of the priors (∞: none): κ's, if given, or None."""
        if self.yaw_scale_prior_std is None:
            return None
        std = np.full(self.size, np.inf)
        std[self.param_names.index("yaw_scale")] = self.yaw_scale_prior_std
        return std

    def prior_mean_values(self) -> np.ndarray:
        """The priors' means: κ = 1 (the gyro's nominal scale across its axle)."""
        return self.initial_values(0.0)

    def initial_values(self, rolling_radius_m: float) -> np.ndarray:
        """The parameters at ρ = ``rolling_radius_m``, κ = 1 and everything else 0."""
        values = np.zeros(self.size)
        values[0] = rolling_radius_m
        if self.yaw_scale_free:
            values[1] = 1.0
        return values

    @property
    def has_camber_track(self) -> bool:
        """Whether the camber follows a measured track (module docstring)."""
        return self.camber_track_rad is not None

    @property
    def ties_tilt(self) -> bool:
        """A yaw measured across the axle makes the turns' forces depend on α."""
        return self.yaw_across_axle

    def settings(self) -> dict:
        """The yaw rate's size over the recording, and the camber track's (reports only)."""
        out = {
            "yaw_rate_rms_radps": float(np.sqrt(np.mean(self.yaw_rate_radps**2))),
            "yaw_rate_max_radps": float(np.max(np.abs(self.yaw_rate_radps))),
        }
        if self.camber_track_rad is not None:
            low, high = np.percentile(self.camber_track_rad, [2.0, 98.0])
            out["camber_track_range_deg"] = float(np.rad2deg(high - low))
        return out

    def __eq__(self, other: object) -> bool:
        """Only the same instance: the effect carries its recording's yaw series."""
        return self is other

    def __hash__(self) -> int:
        """Identity hash (see :meth:`__eq__`)."""
        return id(self)

    def with_yaw(
        self,
        yaw_rate_radps: np.ndarray,
        yaw_accel_radps2: np.ndarray,
        camber_track_rad: np.ndarray | None = None,
        camber_basis: dict[str, np.ndarray] | None = None,
    ) -> Rolling:
        """The same effect with another yaw series (its settings and priors kept).

        ``camber_track_rad``, ``camber_basis``: another camber track and basis too (an
        effect with one only; the basis by the same names, default the effect's own).
        """
        rate = np.asarray(yaw_rate_radps, dtype=float)
        accel = np.asarray(yaw_accel_radps2, dtype=float)
        if rate.shape != self.time_s.shape or accel.shape != self.time_s.shape:
            raise ValueError("one yaw rate and one yaw acceleration per time")
        out = copy.copy(self)
        out.yaw_rate_radps, out.yaw_accel_radps2 = rate, accel
        if camber_track_rad is not None:
            if self.camber_track_rad is None:
                raise ValueError("a camber track replaces one: this effect has none")
            basis = self.camber_basis if camber_basis is None else camber_basis
            if list(basis) != list(self.camber_basis):
                raise ValueError("a camber basis replaces one of the same names")
            out._set_camber(camber_track_rad, basis)
        return out

    def with_camber_basis(self, extra: dict[str, np.ndarray]) -> Rolling:
        """The same effect with more camber series (each a parameter ``camber_<name>``).

        Without a track the camber's change is the new series alone (l = 0): a camber
        free to move, against which the fitted one is judged (the field fit's lean check).
        """
        out = copy.copy(self)
        track = self.camber_track_rad
        track = np.zeros_like(self.time_s) if track is None else track
        out._set_camber(track, {**self.camber_basis, **extra})
        out.param_names = self.param_names + tuple(f"camber_{name}" for name in extra)
        return out

    def camber_change(self, values: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """γ(t) − γ₀ = κ l(t) + Σ c_k N_k(t) at centred times ``t_s`` (0 without a track)."""
        t = np.asarray(t_s, dtype=float)
        if self._camber is None:
            return np.zeros_like(t)
        return self._camber_weights(values) @ self._camber.at(t)[:, 0]

    def _camber_weights(self, values: np.ndarray) -> np.ndarray:
        """(κ, c_1 … c_K): the weights of the track and its basis."""
        values = np.asarray(values, dtype=float)
        kappa = float(values[1]) if self.yaw_scale_free else 1.0
        return np.concatenate([[kappa], values[self._camber_first :]])

    @property
    def camber_names(self) -> tuple[str, ...]:
        """The parameters of the camber track's basis (``camber_<name>``)."""
        return self.param_names[self._camber_first :]

    def yaw(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ψ̇_gyro and ψ̈_gyro at centred times ``t_s``."""
        t = np.asarray(t_s, dtype=float)
        on_grid = samples_of(self.time_s, t)
        if on_grid is not None:  # the series' own samples: the same numbers, taken
            return self.yaw_rate_radps[on_grid], self.yaw_accel_radps2[on_grid]
        return (
            np.interp(t, self.time_s, self.yaw_rate_radps),
            np.interp(t, self.time_s, self.yaw_accel_radps2),
        )

    def force_delta(
        self,
        values: np.ndarray,
        t_s: np.ndarray,
        kin: Kinematics,
        radius_m: float,
        jacobian: bool,
        tilt_rad: float = np.pi / 2,
        gravity_mps2: float = STANDARD_GRAVITY_MPS2,
    ) -> ForceDelta:
        """Δa of the module docstring at tilt α = ``tilt_rad`` (camber γ = 90° − α).

        With its partials when ``jacobian`` (``by_tilt``: ∂Δa/∂α, through the
        camber and, for a yaw measured across the axle, through ψ̇ = κ y / sin α).
        ``gravity_mps2``: g, which the camber track turns (module docstring).
        """
        values = np.asarray(values, dtype=float)
        t_s = np.asarray(t_s, dtype=float)
        rho = float(values[0])
        kappa = float(values[1]) if self.yaw_scale_free else 1.0
        offset = float(values[2]) if self.yaw_offset_free else 0.0
        rate_g, accel_g = self.yaw(t_s)
        rows = None
        if self._camber is None:
            sg, cg = float(np.cos(tilt_rad)), float(np.sin(tilt_rad))  # sin γ, cos γ
        else:  # the turns at the camber of the moment, Γ(t) = γ₀ + Δγ(t)
            rows = self._camber.at(t_s)  # (1 + K, 3, n): value, rate, rate of change
            weights = self._camber_weights(values)
            change, roll, roll_dot = (weights @ rows[:, j] for j in range(3))
            camber = np.pi / 2 - tilt_rad + change
            sg, cg = np.sin(camber), np.cos(camber)
        m = 1.0 / cg if self.yaw_across_axle else 1.0
        yaw, yaw_dot = kappa * m * rate_g + offset, kappa * m * accel_g  # ψ̇, ψ̈
        s, c = np.sin(kin.theta_rad), np.cos(kin.theta_rad)
        terms = _CamberTerms(rho, radius_m, yaw, yaw_dot, kin, s, c, sg, cg)
        delta = terms.delta()
        track = roll_terms = None
        if rows is not None:
            track = _TrackTerms(float(gravity_mps2), camber, float(np.pi / 2 - tilt_rad), s, c)
            roll_terms = _RollTerms(radius_m, roll, roll_dot, yaw, kin.omega_radps, s, c, cg)
            delta = delta + track.delta() + roll_terms.delta()
        if not jacobian:
            return ForceDelta(delta)
        by_yaw, by_yaw_dot = terms.by_yaw(), terms.by_yaw_dot()
        if roll_terms is not None:
            by_yaw = by_yaw + roll_terms.by_yaw()
        d_own = np.zeros((self.size, s.size, 3))
        d_own[0] = terms.by_rho()
        if self.yaw_scale_free:
            d_own[1] = by_yaw * np.broadcast_to(m * rate_g, s.shape)[:, None]
            d_own[1] += by_yaw_dot * np.broadcast_to(m * accel_g, s.shape)[:, None]
            if self.yaw_offset_free:
                d_own[2] = by_yaw  # ∂/∂ε
        turn_by_tilt = terms.by_sin_camber() * _column(-cg) + terms.by_cos_camber() * _column(sg)
        if roll_terms is not None:  # the roll's terms through cos Γ(t)
            turn_by_tilt += roll_terms.by_cos_camber() * _column(sg)
        if self.yaw_across_axle:  # ∂m/∂α = −sin γ / cos²γ
            dm = -sg / (cg * cg)
            turn_by_tilt += by_yaw * _column(kappa * dm * rate_g)
            turn_by_tilt += by_yaw_dot * _column(kappa * dm * accel_g)
        by_tilt, by_theta = turn_by_tilt, terms.by_theta()
        by_omega, by_radius = terms.by_omega(), terms.by_radius()
        if track is not None:
            by_theta = by_theta + track.by_theta() + roll_terms.by_theta()
            by_omega = by_omega + roll_terms.by_omega()
            by_radius = by_radius + roll_terms.by_radius()
            by_tilt = by_tilt + track.by_tilt()
            # Δγ moves gravity and, through Γ(t), the turns' terms (∂/∂Δγ = −∂/∂α there);
            # its rate λ and λ̇ move the roll's own terms
            by_change = track.by_change() - turn_by_tilt
            by_roll, by_roll_dot = roll_terms.by_roll(), roll_terms.by_roll_dot()
            columns = [1] if self.yaw_scale_free else []
            columns += list(range(self._camber_first, self.size))
            series = rows if self.yaw_scale_free else rows[1:]
            for k, row in zip(columns, series, strict=True):
                d_own[k] += by_change * row[0][:, None]
                d_own[k] += by_roll * row[1][:, None] + by_roll_dot * row[2][:, None]
        return ForceDelta(
            delta,
            d_own,
            by_theta,
            by_omega,
            terms.by_omega_dot(),
            by_radius,
            by_tilt,
        )


def _column(x) -> np.ndarray | float:
    """A per-sample factor as a column (N, 1), a scalar as it is."""
    return x[:, None] if np.ndim(x) else x


def _camber_series(
    time_s: np.ndarray, track: np.ndarray | None, basis: dict[str, np.ndarray] | None
) -> tuple[np.ndarray | None, dict[str, np.ndarray]]:
    """The camber track and its basis, checked (None and {} without a track)."""
    if track is None:
        if basis:
            raise ValueError("camber_basis needs a camber track")
        return None, {}
    track = np.asarray(track, dtype=float)
    basis = {str(k): np.asarray(v, dtype=float) for k, v in (basis or {}).items()}
    for series in (track, *basis.values()):
        if series.shape != time_s.shape or not np.all(np.isfinite(series)):
            raise ValueError("the camber track and its basis: finite, one value per time")
    return track, basis


@dataclass(frozen=True, eq=False)
class _CamberSeries:
    """The camber track and its basis stacked: value, rate and its rate of change (1 + K, 3, N)."""

    time_s: np.ndarray
    stacked: np.ndarray

    @classmethod
    def of(cls, time_s: np.ndarray, series: list[np.ndarray]) -> _CamberSeries:
        values = np.asarray(series, dtype=float)  # (1 + K, N): every series in one gradient
        rate = np.gradient(values, time_s, axis=1)
        return cls(time_s, np.stack([values, rate, np.gradient(rate, time_s, axis=1)], axis=1))

    def at(self, t: np.ndarray) -> np.ndarray:
        """Every row at centred times ``t`` (linear interpolation), (1 + K, 3, n)."""
        grid = self.time_s
        on_grid = samples_of(grid, t)
        if on_grid is not None:  # the grid's own samples: the same numbers, gathered
            return self.stacked[:, :, on_grid]
        right = np.clip(np.searchsorted(grid, t), 1, grid.size - 1)
        left = right - 1
        weight = np.clip((t - grid[left]) / (grid[right] - grid[left]), 0.0, 1.0)
        return self.stacked[:, :, left] * (1.0 - weight) + self.stacked[:, :, right] * weight


@dataclass(frozen=True, eq=False)
class _RollTerms:
    """The carrier's roll λ = γ̇ about the direction of travel, seen by the sensor at r.

    The carrier turns at ψ̇ n + λ t, t = (−sin ϑ, cos ϑ, 0) the direction of travel in
    the bench frame (it rolls through the hub, whose path is unchanged), so the sensor
    at p = −r X gains, from Ω̇ × p + Ω × (Ω × p) with Ω̇'s share λ̇ t + λ ψ̇ l − ω λ (t × Z)
    (l = (−sin γ c, −sin γ s, cos γ), the axle's lateral):

        Δa = r (2 λ ψ̇ cos γ s c + λ² c²,  −2 λ ψ̇ cos γ c² + λ² s c,  λ̇ c − 2 ω λ s)

    — the roll's Coriolis term 2 r ω λ along the axle: 0.2 m/s² on a car's rim at 0.03
    rad/s of roll (the yaw's is 2 r ω ψ̇ cos γ c, in :class:`_CamberTerms`).
    """

    r: float
    roll: np.ndarray  # λ
    roll_dot: np.ndarray  # λ̇
    yaw: np.ndarray | float  # ψ̇
    omega: np.ndarray
    s: np.ndarray
    c: np.ndarray
    cg: np.ndarray

    def _stack(self, x, y, z) -> np.ndarray:
        out = np.empty((self.s.size, 3))
        out[:, 0], out[:, 1], out[:, 2] = x, y, z
        return out

    def delta(self) -> np.ndarray:
        return self.r * self.by_radius()

    def by_radius(self) -> np.ndarray:
        lam, P, s, c, cg = self.roll, self.yaw, self.s, self.c, self.cg
        return self._stack(
            2 * lam * P * cg * s * c + lam * lam * c * c,
            -2 * lam * P * cg * c * c + lam * lam * s * c,
            self.roll_dot * c - 2 * self.omega * lam * s,
        )

    def by_theta(self) -> np.ndarray:
        r, lam, P, s, c, cg = self.r, self.roll, self.yaw, self.s, self.c, self.cg
        return self._stack(
            r * (2 * lam * P * cg * (c * c - s * s) - 2 * lam * lam * c * s),
            r * (4 * lam * P * cg * c * s + lam * lam * (c * c - s * s)),
            r * (-self.roll_dot * s - 2 * self.omega * lam * c),
        )

    def by_omega(self) -> np.ndarray:
        zero = np.zeros_like(self.s)
        return self._stack(zero, zero, -2 * self.r * self.roll * self.s)

    def by_yaw(self) -> np.ndarray:
        r, lam, s, c, cg = self.r, self.roll, self.s, self.c, self.cg
        return self._stack(2 * r * lam * cg * s * c, -2 * r * lam * cg * c * c, np.zeros_like(s))

    def by_cos_camber(self) -> np.ndarray:
        r, lam, P, s, c = self.r, self.roll, self.yaw, self.s, self.c
        return self._stack(2 * r * lam * P * s * c, -2 * r * lam * P * c * c, np.zeros_like(s))

    def by_roll(self) -> np.ndarray:
        r, lam, P, s, c, cg = self.r, self.roll, self.yaw, self.s, self.c, self.cg
        return self._stack(
            r * (2 * P * cg * s * c + 2 * lam * c * c),
            r * (-2 * P * cg * c * c + 2 * lam * s * c),
            -2 * r * self.omega * s,
        )

    def by_roll_dot(self) -> np.ndarray:
        zero = np.zeros_like(self.s)
        return self._stack(zero, zero, self.r * self.c)


@dataclass(frozen=True, eq=False)
class _TrackTerms:
    """Gravity turned by the camber's change (module docstring, "The camber track").

    Γ = γ₀ + Δγ(t), γ₀ = π/2 − α; Δa_g = g (Δc c, Δc s, Δs).
    """

    g: float
    camber: np.ndarray  # Γ(t)
    base: float  # γ₀
    s: np.ndarray
    c: np.ndarray

    def _stack(self, cos_part: np.ndarray, sin_part: np.ndarray) -> np.ndarray:
        out = np.empty((self.s.size, 3))
        out[:, 0] = self.g * cos_part * self.c
        out[:, 1] = self.g * cos_part * self.s
        out[:, 2] = self.g * sin_part
        return out

    def delta(self) -> np.ndarray:
        return self._stack(
            np.cos(self.camber) - np.cos(self.base), np.sin(self.camber) - np.sin(self.base)
        )

    def by_change(self) -> np.ndarray:
        """∂Δa_g/∂Δγ (per sample)."""
        return self._stack(-np.sin(self.camber), np.cos(self.camber))

    def by_theta(self) -> np.ndarray:
        dc = self.g * (np.cos(self.camber) - np.cos(self.base))
        out = np.zeros((self.s.size, 3))
        out[:, 0] = -dc * self.s
        out[:, 1] = dc * self.c
        return out

    def by_tilt(self) -> np.ndarray:
        """∂Δa_g/∂α = −∂Δa_g/∂γ₀ (Δγ held)."""
        return -self._stack(
            -np.sin(self.camber) + np.sin(self.base), np.cos(self.camber) - np.cos(self.base)
        )


@dataclass(frozen=True, eq=False)
class _CamberTerms:
    """Δa of a rolling wheel with camber, and its partials (module docstring's formulas).

    P = ψ̇, Pd = ψ̈, w = ω, wd = ω̇; s, c = sin ϑ, cos ϑ; sg, cg = sin γ, cos γ;
    Ω_z = P sg − w and Ω̇_z = Pd sg − wd (the wheel's rate about its axle, and its
    change: the rate the hub's travel follows, σ v = ρ Ω_z).
    """

    rho: float
    r: float
    P: np.ndarray
    Pd: np.ndarray
    kin: Kinematics
    s: np.ndarray
    c: np.ndarray
    sg: float
    cg: float

    @property
    def w(self) -> np.ndarray:
        return self.kin.omega_radps

    @property
    def wd(self) -> np.ndarray:
        return self.kin.omega_dot_radps2

    def _stack(self, x, y, z) -> np.ndarray:
        out = np.empty((self.s.size, 3))
        out[:, 0], out[:, 1], out[:, 2] = x, y, z
        return out

    def delta(self) -> np.ndarray:
        rho, r, P, Pd, w, s, c, sg, cg = self._vars()
        oz, ozd = P * sg - w, self._oz_dot()
        P2 = P * P
        return self._stack(
            -rho * ozd * s
            - rho * oz * P * sg * c
            + r * (P2 * cg * cg * s * s + P2 * sg * sg - 2 * w * P * sg),
            rho * ozd * c - rho * oz * P * sg * s - r * Pd * sg - r * P2 * cg * cg * s * c,
            rho * oz * P * cg + r * cg * (Pd * s + 2 * w * P * c - P2 * sg * c),
        )

    def _oz_dot(self) -> np.ndarray:
        """Ω̇_z: the yaw's acceleration along the axle less the wheel's own (ρ·ω̇ is the travel)."""
        return self.Pd * self.sg - self.wd

    def _vars(self):
        return self.rho, self.r, self.P, self.Pd, self.w, self.s, self.c, self.sg, self.cg

    def by_rho(self) -> np.ndarray:
        _, _, P, _, w, s, c, sg, cg = self._vars()
        oz, ozd = P * sg - w, self._oz_dot()
        return self._stack(-ozd * s - oz * P * sg * c, ozd * c - oz * P * sg * s, oz * P * cg)

    def by_radius(self) -> np.ndarray:
        _, _, P, Pd, w, s, c, sg, cg = self._vars()
        P2 = P * P
        return self._stack(
            P2 * cg * cg * s * s + P2 * sg * sg - 2 * w * P * sg,
            -Pd * sg - P2 * cg * cg * s * c,
            cg * (Pd * s + 2 * w * P * c - P2 * sg * c),
        )

    def by_theta(self) -> np.ndarray:
        rho, r, P, Pd, w, s, c, sg, cg = self._vars()
        oz, ozd = P * sg - w, self._oz_dot()
        P2 = P * P
        return self._stack(
            -rho * ozd * c + rho * oz * P * sg * s + 2 * r * P2 * cg * cg * s * c,
            -rho * ozd * s - rho * oz * P * sg * c - r * P2 * cg * cg * (c * c - s * s),
            r * cg * (Pd * c - 2 * w * P * s + P2 * sg * s),
        )

    def by_omega(self) -> np.ndarray:
        rho, r, P, _, _, s, c, sg, cg = self._vars()
        return self._stack(
            rho * P * sg * c - 2 * r * P * sg, rho * P * sg * s, -rho * P * cg + 2 * r * cg * P * c
        )

    def by_omega_dot(self) -> np.ndarray:
        rho, s, c = self.rho, self.s, self.c
        return self._stack(rho * s, -rho * c, np.zeros_like(s))

    def by_yaw(self) -> np.ndarray:
        rho, r, P, _, w, s, c, sg, cg = self._vars()
        d_ozp = 2 * P * sg - w  # ∂(Ω_z ψ̇)/∂ψ̇
        return self._stack(
            -rho * sg * c * d_ozp + r * (2 * P * cg * cg * s * s + 2 * P * sg * sg - 2 * w * sg),
            -rho * sg * s * d_ozp - 2 * r * P * cg * cg * s * c,
            rho * cg * d_ozp + r * cg * (2 * w * c - 2 * P * sg * c),
        )

    def by_yaw_dot(self) -> np.ndarray:
        rho, r, s, c, sg, cg = self.rho, self.r, self.s, self.c, self.sg, self.cg
        return self._stack(-rho * sg * s, rho * sg * c - r * sg, r * cg * s)

    def by_sin_camber(self) -> np.ndarray:
        """∂Δa/∂(sin γ) with ψ̇, ψ̈ held."""
        rho, r, P, Pd, w, s, c, sg, cg = self._vars()
        oz = P * sg - w
        P2 = P * P
        return self._stack(
            -rho * Pd * s - rho * P * c * (P * sg + oz) + r * (2 * P2 * sg - 2 * w * P),
            rho * Pd * c - rho * P * s * (P * sg + oz) - r * Pd,
            rho * P2 * cg - r * cg * P2 * c,
        )

    def by_cos_camber(self) -> np.ndarray:
        """∂Δa/∂(cos γ) with ψ̇, ψ̈ held."""
        rho, r, P, Pd, w, s, c, sg, cg = self._vars()
        oz = P * sg - w
        P2 = P * P
        return self._stack(
            2 * r * P2 * cg * s * s,
            -2 * r * P2 * cg * s * c,
            rho * oz * P + r * (Pd * s + 2 * w * P * c - P2 * sg * c),
        )
