"""The wheel angle from the gyroscope: ϑ(t) integrated from the measured rate (``gyro_angle``).

A wheel in the field is driven, braked, steered: no polynomial follows its
angle for long, and a spline with knots every half second costs hundreds of
parameters.  Its gyroscope measures the rate itself.  About the axle it reads
(:mod:`wheelcal.model.rolling`; k the gyro's scale, γ = 90° − α the camber)

    ω_g = k (ω − ψ̇ sin γ)            (−k Ω_z: the wheel's rate about its axle)

and across the axle the carrier's yaw, turning with the wheel,

    y = k ψ̇ cos γ                     (demodulated with ϑ: wheelcal.estimate.field)

so that ω = s (ω_g + y cot α) with s = 1/k.  This effect adds

    Δϑ = s (Θ_g + Ψ_y cot α),   Δω = s (ω_g + y cot α),   Δω̇ = s (ω̇_g + ẏ cot α)

with Θ_g = ∫ ω_g dt and Ψ_y = ∫ y dt from the window's centre, to a spin
polynomial of degree 0 (ϑ₀ + ω₀ t: the phase, and the gyro's bias along the
axle, −ω₀/s).  Parameter: ``scale`` s (rad per rad of the integrated gyro).
On a vertical wheel (α = 90°) cot α = 0: the yaw does not enter; on a cambered
one the wheel turns on its carrier by ψ̇ sin γ in a turn, and the accelerometer
sees that turn of gravity's phase — which is what measures the camber.

The gyro's noise, integrated, walks the angle by q √T (≈ 2 mrad over two
minutes of a consumer gyro).  The angle is taken as measured and its three
parameters (ϑ₀, ω₀, s) are fitted; the walk is below what the accelerometer
resolves on a car, but on a robot's wheel it moves the camber and the axle
axis's offset by 1–2 σ, so the field fit adds its propagated covariance to the
reported σ (:mod:`wheelcal.estimate.field.robust`).

**The gyro's response across its axle.**  A gyro's axes differ in scale by
1–2 %, so its reading along the axle also sees a rate across it: the yaw, as
k ψ̇ cos γ (m_x cos ϑ + m_y sin ϑ) with m of order 10⁻².  Where the wheel turns
many times per heading change (a car) it averages out; a robot turning on the
spot (ψ̇ large, ω small) would read it as a camber of ≈ m.  With ``cross``
series (y cos ϑ, y sin ϑ at a previous fit's ϑ) the effect adds
s (m_x C_x + m_y C_y), C = ∫ y (cos ϑ, sin ϑ) dt, and fits m (``cross_x``, ``cross_y``).

**A camber that changes.**  The yaw's share ψ̇ sin γ turns the wheel on its
carrier with the camber of the moment: with a camber track l(t) (the camber's
change, :mod:`wheelcal.model.rolling`) cot α becomes cot(α − l) ≈ cot α + l / sin²α,
and the effect adds s (Ψ_l, y l, (y l)˙) / sin²α, Ψ_l = ∫ y l dt (a 5° banked
curve at 0.03 rad/s of yaw turns the angle by 0.05 rad in 20 s).

**A bias that walks.**  A gyro's bias is not one number over half an hour: it
walks (a factory IMU's 0.002–0.005 °/s/√s) and warms up, and ω₀ t cannot follow
its integral (on a 30-minute drive 15° of angle).  With ``walk_spacing_s`` the
bias is ω₀ plus a piecewise-linear b(t) = Σ_j d_j ρ_j(t), ρ_j rising from 0 to 1
across knot interval j (so b = 0 at the window's start and d_j is the bias's
change over interval j), and the effect adds s (∫b dt, b, ḃ).  The d_j are fitted
under the walk's own prior, d_j ~ N(0, q² Δ) (``walk_prior_radps_per_sqrt_s`` q, Δ
the interval): where the gravity's phase pins the angle they follow it, and a
slow phase the walk could make (a camber's ψ̇ sin γ over minutes) stays the
turns' to measure.  The columns are evaluated from the knots, not stored.

**Its sensitivity to acceleration.**  A MEMS gyro reads ~0.1 °/s per g of
specific force.  A robot's hub sensor at 2 g of centripetal force, or the
lateral force of a turn, would turn that into an angle drift of the turn's
shape — again read as a camber.  With the accelerometer's samples a(t) the
effect adds s g·∫a dt with g fitted under a prior of that size (the effect's
``prior_std_values``, which the fit adds as pseudo-observations).
"""

from __future__ import annotations

import copy

import numpy as np

from wheelcal.model.effects import (
    G_SENSITIVITY_PRIOR_DPS_PER_G,
    SpinDelta,
    _SpinEffect,
    samples_of,
)
from wheelcal.model.parameters import STANDARD_GRAVITY_MPS2

#: The prior on the axle reading's sensitivity to acceleration, rad/s per m/s².
G_PRIOR_RADPS_PER_MPS2 = np.deg2rad(G_SENSITIVITY_PRIOR_DPS_PER_G) / STANDARD_GRAVITY_MPS2


def _integral(t: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """∫ rate dt by the trapezoid rule, zero at t = 0 (the window's centre)."""
    out = np.empty_like(rate)
    out[0] = 0.0
    np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t), out=out[1:])
    return out - np.interp(0.0, t, out)


class GyroAngle(_SpinEffect):
    """The wheel angle integrated from the gyro (module docstring).

    Parameters
    ----------
    time_s:
        Centred times of the series (strictly increasing).
    axle_rate_radps:
        ω_g, the gyro's reading about the wheel axle, oriented so that s > 0.
    axle_rate_dot_radps2:
        ω̇_g (smoothed: the motion's, not the noise's).
    yaw_across_radps, yaw_across_dot_radps2:
        y and ẏ, the yaw's share across the axle (zeros: not known yet, or a fixed axle).
    cross_radps:
        (2, N): y cos ϑ and y sin ϑ at a previous fit's ϑ — the axle reading's response
        to the yaw across it is then fitted (``cross_x``, ``cross_y``; module docstring).
    accel_mps2:
        (N, 3): the specific force in the sensor's frame (the accelerometer, smoothed) —
        the axle reading's sensitivity to it, g = (``g_x``, ``g_y``, ``g_z``), is fitted
        under the prior ``g_prior_std`` (rad/s per m/s²; a MEMS gyro's ~0.1 °/s/g).
    camber_track_rad:
        l(t), the camber's change (rad; module docstring), or ``None`` (a constant camber).
    walk_spacing_s, walk_prior_radps_per_sqrt_s:
        The bias's walk (module docstring): knot intervals of about this length over the
        window (``None``: a constant bias), each change under a prior of σ q √Δ.
    """

    name = "gyro_angle"
    param_names = ("scale",)
    description = "wheel angle integrated from the gyroscope (scale s = 1/k)"
    uses_tilt = True
    #: On a cambered wheel in turns the phase measures α: r and α may both be free.
    ties_tilt = True

    def __init__(
        self,
        time_s: np.ndarray,
        axle_rate_radps: np.ndarray,
        axle_rate_dot_radps2: np.ndarray,
        yaw_across_radps: np.ndarray | None = None,
        yaw_across_dot_radps2: np.ndarray | None = None,
        cross_radps: np.ndarray | None = None,
        accel_mps2: np.ndarray | None = None,
        g_prior_std: float = G_PRIOR_RADPS_PER_MPS2,
        camber_track_rad: np.ndarray | None = None,
        walk_spacing_s: float | None = None,
        walk_prior_radps_per_sqrt_s: float = np.inf,
    ) -> None:
        t = np.asarray(time_s, dtype=float)
        if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0):
            raise ValueError("need strictly increasing times")
        series = [axle_rate_radps, axle_rate_dot_radps2, yaw_across_radps, yaw_across_dot_radps2]
        series = [np.zeros_like(t) if x is None else np.asarray(x, dtype=float) for x in series]
        if any(x.shape != t.shape or not np.all(np.isfinite(x)) for x in series):
            raise ValueError("one finite value per time in every series")
        self.time_s = t
        self.rate, self.rate_dot, self.yaw, self.yaw_dot = series
        self.angle = _integral(t, self.rate)
        self.yaw_angle = _integral(t, self.yaw)
        self.camber_track_rad = None
        if camber_track_rad is not None:
            track = np.asarray(camber_track_rad, dtype=float)
            if track.shape != t.shape or not np.all(np.isfinite(track)):
                raise ValueError("camber_track_rad must be finite, one value per time")
            self.camber_track_rad = track
        self._set_lean()
        self.walk_knots_s = np.zeros(0)
        self.walk_prior_std = np.zeros(0)
        if walk_spacing_s is not None:
            if not walk_spacing_s > 0:
                raise ValueError("walk_spacing_s must be positive")
            count = int(np.floor((t[-1] - t[0]) / walk_spacing_s))
            if count >= 1:
                self.walk_knots_s = np.linspace(t[0], t[-1], count + 1)
                spacing = float(self.walk_knots_s[1] - self.walk_knots_s[0])
                prior = float(walk_prior_radps_per_sqrt_s) * np.sqrt(spacing)
                self.walk_prior_std = np.full(count, prior)
        walk_names = tuple(f"walk_{j}_radps" for j in range(self.walk_prior_std.size))
        # Further rates the axle reading sees, each with a fitted coefficient:
        # (name, (∫x dt, x, ẋ), prior σ).
        self.terms: list[tuple[str, tuple, float]] = []
        if cross_radps is not None:
            cross = np.asarray(cross_radps, dtype=float)
            if cross.shape != (2, t.size) or not np.all(np.isfinite(cross)):
                raise ValueError("cross_radps must be finite, (2, N)")
            for name, row in zip(("cross_x", "cross_y"), cross, strict=True):
                self.terms.append((name, self._series(row), np.inf))
        if accel_mps2 is not None:
            accel = np.asarray(accel_mps2, dtype=float)
            if accel.shape != (t.size, 3) or not np.all(np.isfinite(accel)):
                raise ValueError("accel_mps2 must be finite, (N, 3)")
            for name, row in zip(("g_x", "g_y", "g_z"), accel.T, strict=True):
                self.terms.append((name, self._series(row), float(g_prior_std)))
        self.param_names = ("scale", *walk_names, *(name for name, _, _ in self.terms))
        self._stacked: np.ndarray | None = None

    def _series(self, rate: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return _integral(self.time_s, rate), rate, np.gradient(rate, self.time_s)

    def _set_lean(self) -> None:
        """(Ψ_l, y l, (y l)˙): the yaw times the camber track (zeros without a track)."""
        if self.camber_track_rad is None:
            zero = np.zeros_like(self.time_s)
            self.lean_series = (zero, zero, zero)
        else:
            product = self.yaw * self.camber_track_rad
            integral = _integral(self.time_s, product)
            self.lean_series = (integral, product, self.yaw_dot * self.camber_track_rad)
            # (y l)˙ = ẏ l + y l̇; l̇ (the roll rate) times a yaw of 0.03 rad/s is below
            # what ω̇ resolves, and the low-passed ẏ l is the part the motion shows.

    def with_yaw(
        self,
        yaw_across_radps: np.ndarray,
        yaw_across_dot_radps2: np.ndarray,
        cross_radps: np.ndarray | None = None,
        camber_track_rad: np.ndarray | None = None,
    ) -> GyroAngle:
        """The same effect with another yaw across the axle (and its ``cross`` series).

        Everything else — the axle rate, the accelerometer's series, the priors — is
        kept: what a change of the gyro's reading across the axle alone does.
        ``camber_track_rad``: another camber track (an effect with one only).
        """
        t = self.time_s
        yaw = np.asarray(yaw_across_radps, dtype=float)
        yaw_dot = np.asarray(yaw_across_dot_radps2, dtype=float)
        if yaw.shape != t.shape or yaw_dot.shape != t.shape:
            raise ValueError("one yaw and one yaw rate of change per time")
        out = copy.copy(self)
        out.yaw, out.yaw_dot, out.yaw_angle = yaw, yaw_dot, _integral(t, yaw)
        if camber_track_rad is not None:
            if self.camber_track_rad is None:
                raise ValueError("a camber track replaces one: this effect has none")
            track = np.asarray(camber_track_rad, dtype=float)
            if track.shape != t.shape:
                raise ValueError("one camber-track value per time")
            out.camber_track_rad = track
        out._set_lean()
        rows = {}
        if cross_radps is not None:
            rows = dict(zip(("cross_x", "cross_y"), np.asarray(cross_radps), strict=True))
        fits_cross = any(name in ("cross_x", "cross_y") for name, _, _ in self.terms)
        if fits_cross != (cross_radps is not None):
            raise ValueError("cross_radps exactly when the effect fits the cross terms")
        out.terms = [
            (name, self._series(np.asarray(rows[name], dtype=float)), prior)
            if name in rows
            else (name, series, prior)
            for name, series, prior in self.terms
        ]
        out._stacked = None
        return out

    def prior_std_values(self) -> np.ndarray | None:
        """σ of the priors on the parameters (∞: none), or None without any."""
        std = np.array([np.inf, *self.walk_prior_std] + [prior for _, _, prior in self.terms])
        return std if np.any(np.isfinite(std)) else None

    def settings(self) -> dict:
        """The gyro's rate over the window (reports only)."""
        return {"axle_rate_max_radps": float(np.max(np.abs(self.rate)))}

    def __eq__(self, other: object) -> bool:
        """Only the same instance: the effect carries its recording's series."""
        return self is other

    def __hash__(self) -> int:
        """Identity hash (see :meth:`__eq__`)."""
        return id(self)

    def _rows_at(self, t: np.ndarray) -> np.ndarray:
        """Every series at times ``t`` (linear interpolation), (3 + 3 + 3 + 3·terms, N).

        One search of the grid serves every series (they share ``time_s``).
        """
        if self._stacked is None:
            series = [self.angle, self.rate, self.rate_dot, self.yaw_angle, self.yaw, self.yaw_dot]
            series += list(self.lean_series)
            series += [x for _, triple, _ in self.terms for x in triple]
            self._stacked = np.vstack(series)
        grid = self.time_s
        on_grid = samples_of(grid, t)
        if on_grid is not None:  # the grid's own samples (a chunk, a thinned pass): no weights
            return self._stacked[:, on_grid]
        right = np.clip(np.searchsorted(grid, t), 1, grid.size - 1)
        left = right - 1
        weight = np.clip((t - grid[left]) / (grid[right] - grid[left]), 0.0, 1.0)
        return self._stacked[:, left] * (1.0 - weight) + self._stacked[:, right] * weight

    def _walk_rows(self, t: np.ndarray) -> list[np.ndarray]:
        """(∫ρ_j dt, ρ_j, ρ̇_j) at times ``t``, each (J, N): the walk's columns (zero at t = 0)."""
        knots = self.walk_knots_s
        spacing = knots[1] - knots[0]
        u = (t[None, :] - knots[:-1, None]) / spacing
        inside = (u > 0.0) & (u < 1.0)

        def antiderivative(x):  # ∫ ρ from the interval's start, in seconds
            return spacing * np.where(x <= 0.0, 0.0, np.where(x < 1.0, 0.5 * x * x, x - 0.5))

        at_zero = antiderivative(-knots[:-1] / spacing)
        integral = antiderivative(u) - at_zero[:, None]
        return [integral, np.clip(u, 0.0, 1.0), inside / spacing]

    def spin_delta(self, values, t_s, kin, jacobian, tilt_rad: float = np.pi / 2):
        """Δϑ, Δω, Δω̇ at centred times ``t_s`` and tilt α (module docstring)."""
        t = np.asarray(t_s, dtype=float)
        scale = float(values[0])
        walks = self.walk_prior_std.size
        sin_tilt = float(np.sin(tilt_rad))
        cot = float(np.cos(tilt_rad)) / sin_tilt
        csc2 = 1.0 / (sin_tilt * sin_tilt)  # ∂ cot(α − l)/∂l at l = 0
        rows = self._rows_at(t)
        base, yaw, lean = list(rows[0:3]), list(rows[3:6]), list(rows[6:9])
        total = [b + cot * y + csc2 * m for b, y, m in zip(base, yaw, lean, strict=True)]
        cross = rows[9:].reshape(len(self.terms), 3, t.size)  # (terms, ∫x / x / ẋ, N)
        if walks:
            walk = self._walk_rows(t)
            d = np.asarray(values[1 : 1 + walks], dtype=float)
            total = [x + d @ w for x, w in zip(total, walk, strict=True)]
        if len(self.terms):  # + m x of each term in turn, (3, N) at a time
            stacked = np.array(total)
            for m, series in zip(values[1 + walks :], cross, strict=True):
                stacked += float(m) * series
            total = list(stacked)
        if not jacobian:
            return SpinDelta(*(scale * x for x in total))
        d_cot = -csc2  # ∂ cot α / ∂α
        d_csc2 = -2.0 * cot * csc2  # ∂ (1 / sin²α) / ∂α
        own = [
            np.vstack([x[None]] + ([scale * walk[k]] if walks else []) + [scale * cross[:, k]])
            for k, x in enumerate(total)
        ]
        return SpinDelta(
            *(scale * x for x in total),
            d_own_theta=own[0],
            d_own_omega=own[1],
            d_own_omega_dot=own[2],
            by_tilt=tuple(scale * (d_cot * y + d_csc2 * m) for y, m in zip(yaw, lean, strict=True)),
        )
