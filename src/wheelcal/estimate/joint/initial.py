"""A closed-form starting point for the joint fit, from the data and r (or α) only.

1. **Wheel plane.**  Everything that varies in v(t) lies in span(W e_X, W e_Y)
   (W = ΓR); the direction of least variance is normal to it (the paper's T').
2. **Phase.**  In that plane the rotating gravity g sinα (cosϑ We_X + sinϑ We_Y)
   traces an ellipse; after removing the slow centripetal trend and mapping the
   ellipse to a circle, atan2 gives ϑ up to sign and a constant, and a
   polynomial fit of the unwrapped angle gives the spin of eq. (2).
3. **Linear regression.**  With ϑ(t) fixed, v = c₀ + c₁ ω² + c_c cosϑ' + c_s sinϑ'
   (+ the tiny r ω̇ term) is linear: c₁ = r We_X, c₀ = o + g cosα We_Z.
4. **Phase constant.**  ϑ = ϑ' − c with c chosen so the rotating part's We_X is
   parallel to c₁ (centripetal acceleration points along X).
5. **Gains.**  R's first two columns are orthonormal, so with Gw = g sinα W e_X,Y
   the three equations Σᵢ(Gwₓᵢ)²qᵢ = Σᵢ(Gw_yᵢ)²qᵢ = 1, Σᵢ Gwₓᵢ Gw_yᵢ qᵢ = 0 give
   qᵢ = 1/(g sinα γᵢ)².  The scale g sinα comes from |c₁| = r|We_X| (radius
   mode), from the known tilt (tilt / vertical modes), or — when the wheel hardly
   slowed — from the assumption that the gains average 1.
6. **Rotation and offset.**  R = nearest rotation to [Γ⁻¹We_X, Γ⁻¹We_Y, ×];
   o = c₀ − g cosα Γ R e_Z.

The sign of ϑ' may come out reversed; that lands on the discrete twin, which is
an exact symmetry of the model and is resolved after the fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.fft import fft

from wheelcal.estimate.joint.columns import centred_rows, column_means, row_gram
from wheelcal.estimate.joint.decimation import thinning_stride
from wheelcal.estimate.joint.rotating import revolution_mean, rotating_phase
from wheelcal.model import (
    BenchParams,
    CalibrationParams,
    Rotation,
    SensorParams,
    SpinParams,
    cubic_bspline_basis,
)

_TREND_DEGREE = 6
_MAX_SAMPLES = 4000
_RELIABLE_T_STAT = 10.0
#: Above this condition number of DᵀD the regression of step 3 uses an SVD (error ≲ cond · ε).
_NORMAL_EQUATIONS_MAX_COND = 1e8


@dataclass(frozen=True, eq=False)
class InitialGuess:
    """Starting parameters and notes on how they were found."""

    params: CalibrationParams
    spin_down_resolved: bool  # whether c₁ (centripetal) was measurable
    notes: tuple[str, ...]
    #: Radius mode: the radius for which the gains would average 1 (their geometric
    #: mean), from c₁ = r·We_X and the rotating part G·We_X; None if not measurable.
    implied_radius_m: float | None = None

    def implied_mean_gain(self, radius_m: float | None) -> float | None:
        """The gains' average that the start puts at ``radius_m``: r_implied / r.

        Known before the fit: with a radius off by ×1000 (mm typed as m) it is far
        from 1 already, where the fit itself would wander off for reasons that hide
        the cause.  None when the start could not measure it or no radius is given.
        """
        if self.implied_radius_m is None or radius_m is None:
            return None
        return self.implied_radius_m / radius_m


def initial_guess(
    t_s: np.ndarray,
    accel_mps2: np.ndarray,
    gravity_mps2: float,
    radius_m: float | None = None,
    tilt_rad: float | None = None,
    spin_degree: int = 3,
    spline=None,
    omega_radps: np.ndarray | None = None,
    fastest_radps: float | None = None,
) -> InitialGuess:
    """Starting parameters from samples ``accel_mps2`` at centred times ``t_s``.

    Give ``radius_m`` (radius mode) or ``tilt_rad`` (tilt / vertical modes).
    ``spline`` (a :class:`~wheelcal.model.effects.SpinSpline`) lets the phase
    follow any motion: the unwrapped phase is fitted by the cubic plus the
    spline, whose coefficients are returned in ``params.effects``.
    ``omega_radps`` (|ω| per sample, e.g. from a gyroscope) replaces the
    phase's derivative in the regression of step 3: differentiating a noisy
    phase over short knots would attenuate the centripetal term.
    ``fastest_radps``: the wheel's fastest |ω| in the window when it is known
    (the window search measures it); it sets the thinning instead of a
    spectrum of every sample (without a spline).
    """
    if (radius_m is None) == (tilt_rad is None):
        raise ValueError("give exactly one of radius_m and tilt_rad")
    t, v, stride, turn_hz_all = _thinned(t_s, accel_mps2, spline, fastest_radps)
    measured = None if omega_radps is None else np.asarray(omega_radps, dtype=float)[::stride]
    half = max(np.abs(t).max(), 1e-9)
    tau = t / half
    # One Legendre basis on τ ∈ [−1, 1] for the trend of step 1 and the phase of step 2.
    legendre = np.polynomial.legendre.legvander(tau, max(_TREND_DEGREE, spin_degree + 1))
    legendre_gram = legendre.T @ legendre
    notes: list[str] = []

    u = _plane_coordinates(v, t, legendre, legendre_gram, spline, measured, turn_hz_all)  # 1.
    phase, omega_measured = _phase(u, t, measured)  # 2.
    spin = _spin_of_phase(phase, half, legendre, legendre_gram, spin_degree)
    theta = spin.theta_at(t)
    omega_t = spin.omega_at(t)
    spline_coef = None
    if spline is not None:  # the rest of the phase, on the spline basis
        b, d1, _ = cubic_bspline_basis(t, spline.start_s, spline.spacing_s, spline.size)
        spline_coef, *_ = np.linalg.lstsq(b.T, phase - theta, rcond=None)
        theta = theta + spline_coef @ b
        omega_t = omega_t + spline_coef @ d1
    if omega_radps is not None:
        omega_t = omega_measured

    rot = _rotating_terms(t, v, theta, omega_t)  # 3. and 4.
    if not rot.resolved:
        notes.append("spin-down too small to locate the radial axis from the data")
    spin = SpinParams(theta0_rad=spin.theta0_rad - rot.shift, omega_radps=spin.omega_radps)

    # 5. Gains up to the common scale G = g sinα, then the scale.
    scaled_gain = _scaled_gains(rot.gw_x, rot.gw_y)  # = G·γᵢ
    if scaled_gain is None:
        notes.append("gain ratios not resolvable from the rotating signal; started from unit gains")
        amp = 0.5 * (np.linalg.norm(rot.gw_x) + np.linalg.norm(rot.gw_y))
        scaled_gain = np.full(3, amp)
    bench, sensor, implied_radius = _bench_and_sensor(
        rot, scaled_gain, gravity_mps2, radius_m, tilt_rad
    )
    params = CalibrationParams(
        spin=spin,
        bench=bench,
        sensor=sensor,
        gravity_mps2=gravity_mps2,
        effects={} if spline_coef is None else {spline.name: spline_coef},
    )
    return InitialGuess(
        params=params,
        spin_down_resolved=rot.resolved,
        notes=tuple(notes),
        implied_radius_m=implied_radius,
    )


def _thinned(
    t_s: np.ndarray, accel_mps2: np.ndarray, spline, fastest_radps: float | None
) -> tuple[np.ndarray, np.ndarray, int, float | None]:
    """The samples thinned to a few thousand, the stride, and the turn rate when measured.

    A few thousand samples pin the starting point down; more only cost time.  The
    thinning keeps ≥ 16 samples per turn at twice the dominant turn rate, so a long
    recording is never aliased (estimate/joint/decimation.py).  The dominant turn
    rate of all samples (Hz) is returned when it was measured (always with a spline).
    """
    t_all = np.asarray(t_s, dtype=float)
    v_all = np.asarray(accel_mps2, dtype=float)
    turn_hz_all = None
    if spline is None and t_all.size < 2 * _MAX_SAMPLES:
        stride = 1  # too few samples to thin: the turn rate would not change that
    else:
        rate_all = 1.0 / np.median(np.diff(t_all))
        if spline is None and fastest_radps is not None:
            omega_max = 2 * abs(fastest_radps)  # the same margin as the dominant line's below
        else:
            turn_hz_all = _dominant_frequency(_plane_signal(v_all), rate_all)
            omega_max = 2 * 2 * np.pi * turn_hz_all
        stride = thinning_stride(t_all.size, _MAX_SAMPLES, rate_all, omega_max)
    return t_all[::stride], v_all[::stride], stride, turn_hz_all


def _plane_coordinates(
    v: np.ndarray,
    t: np.ndarray,
    legendre: np.ndarray,
    legendre_gram: np.ndarray,
    spline,
    measured: np.ndarray | None,
    turn_hz_all: float | None,
) -> np.ndarray:
    """Step 1, the wheel plane: the signal's coordinates in it (2, n), its slow part removed.

    The plane holds the principal directions of the centred signal.  For a free
    spin the slow part (r ω², offsets) is a smooth trend; for any other motion
    (the spline case: pushes, a motor's steps) it jumps, and only the mean over
    one revolution removes it whatever ω(t) does.  The signal is kept as rows
    (axis, sample): numpy is slow on (N, 3) columns.
    """
    if spline is None:
        vc = centred_rows(v, column_means(v))
    else:
        vc = _rotating_part(v, t, 2 * np.pi * turn_hz_all, measured)
    _, vecs = np.linalg.eigh(row_gram(vc))
    u = vecs[:, 1:].T @ vc  # (2, n): the plane's coordinates
    if spline is None:
        trend = _legendre_fit(legendre, legendre_gram, _TREND_DEGREE, u.T)
        u = u - trend.T @ legendre[:, : _TREND_DEGREE + 1].T
    return u


def _phase(
    u: np.ndarray, t: np.ndarray, measured: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """Step 2, the phase ϑ'(t): smooth over ~1/8 turn, make the ellipse a circle, unwrap.

    With a ``measured`` rate the phase follows its integral
    (:func:`_phase_from_rate`), which also returns the rate rescaled to ω.
    """
    rate_hz = 1.0 / np.median(np.diff(t))
    turn_hz = _dominant_frequency(u, rate_hz)
    width = max(1, int(rate_hz / max(turn_hz, 1e-3) / 8))
    if width > 1:
        kernel = np.ones(width) / width
        u = np.vstack([np.convolve(u[k], kernel, mode="same") for k in range(2)])
    evals, evecs = np.linalg.eigh(row_gram(u) / u.shape[1])
    circle = (evecs.T @ u) / np.sqrt(np.maximum(evals, 1e-30))[:, None]  # (2, n)
    if measured is None:
        return np.unwrap(np.arctan2(circle[1], circle[0])), None
    return _phase_from_rate(t, circle.T, measured)


@dataclass(frozen=True, eq=False)
class _RotatingTerms:
    """Steps 3 and 4: the regression's terms, the phase constant, W e_X and W e_Y scaled by G."""

    c0: np.ndarray  # o + g cosα W e_Z
    c1: np.ndarray  # r W e_X (the centripetal term)
    gw_x: np.ndarray  # G W e_X
    gw_y: np.ndarray  # G W e_Y
    shift: float  # ϑ = ϑ' − shift
    resolved: bool  # whether c₁ was measurable


def _rotating_terms(
    t: np.ndarray, v: np.ndarray, theta: np.ndarray, omega_t: np.ndarray
) -> _RotatingTerms:
    """Steps 3 and 4: the regression on [1, ω², cosϑ', sinϑ'], then the phase constant.

    r ω̇ is left to the fit.  The phase constant comes from the direction of the
    centripetal term (X points along it).
    """
    design = np.column_stack([np.ones_like(t), omega_t**2, np.cos(theta), np.sin(theta)])
    coef, xtx_inv = _regression(design, v)
    resid = v - design @ coef
    dof = max(len(t) - design.shape[1], 1)
    s2 = np.array([resid[:, k] @ resid[:, k] for k in range(3)]) / dof
    se_c1 = np.inf if xtx_inv is None else np.sqrt(xtx_inv[1, 1] * s2.mean())
    c0, c1, c_cos, c_sin = coef
    resolved = bool(np.linalg.norm(c1) > _RELIABLE_T_STAT * se_c1 * np.sqrt(3))
    shift = np.arctan2(c_sin @ c1, c_cos @ c1) if resolved else 0.0
    gw_x = c_cos * np.cos(shift) + c_sin * np.sin(shift)
    gw_y = -c_cos * np.sin(shift) + c_sin * np.cos(shift)
    return _RotatingTerms(c0, c1, gw_x, gw_y, shift, resolved)


def _spin_of_phase(
    phase: np.ndarray, half: float, legendre: np.ndarray, gram: np.ndarray, spin_degree: int
) -> SpinParams:
    """The spin polynomial of eq. (2) fitted to the unwrapped phase at τ = t / ``half``.

    The polynomial in τ through Legendre coefficients: the same least-squares
    polynomial as polyfit's, from a well-conditioned basis (normal equations suffice).
    """
    phase_legendre = _legendre_fit(legendre, gram, spin_degree + 1, phase)
    phase_coef_tau = np.polynomial.legendre.leg2poly(phase_legendre)
    phase_coef = phase_coef_tau / half ** np.arange(spin_degree + 2)
    omega = np.arange(1, spin_degree + 2) * phase_coef[1:]  # ω_k = (k+1)·c_{k+1}
    return SpinParams(theta0_rad=phase_coef[0], omega_radps=omega)


def _bench_and_sensor(
    rot: _RotatingTerms,
    scaled_gain: np.ndarray,
    gravity_mps2: float,
    radius_m: float | None,
    tilt_rad: float | None,
) -> tuple[BenchParams, SensorParams, float | None]:
    """Steps 5 (the scale, tilt, gains, a radius) and 6 (rotation, offset); the implied radius."""
    g_sin, implied_radius = _common_scale(rot, scaled_gain, gravity_mps2, radius_m, tilt_rad)
    sin_tilt = float(np.clip(g_sin / gravity_mps2, 1e-3, 1.0))
    tilt = float(np.arcsin(sin_tilt)) if tilt_rad is None else float(tilt_rad)
    gain = scaled_gain / g_sin
    radius = radius_m
    if radius is None:
        w_x = rot.gw_x / g_sin
        radius = float(abs(rot.c1 @ w_x) / (w_x @ w_x)) if rot.resolved else 0.3
        if not radius > 0:
            radius = 0.3
    # 6. Rotation and offset.
    r_x = rot.gw_x / scaled_gain
    r_y = rot.gw_y / scaled_gain
    rotation = Rotation.nearest(np.column_stack([r_x, r_y, np.cross(r_x, r_y)]))
    offset = rot.c0 - gravity_mps2 * np.cos(tilt) * gain * rotation.matrix[:, 2]
    return (
        BenchParams(tilt_rad=tilt, radius_m=radius, misalignment=rotation),
        SensorParams(offset_mps2=offset, gain=np.clip(gain, 0.2, 5.0)),
        implied_radius,
    )


def _common_scale(
    rot: _RotatingTerms,
    scaled_gain: np.ndarray,
    gravity_mps2: float,
    radius_m: float | None,
    tilt_rad: float | None,
) -> tuple[float, float | None]:
    """Step 5's scale G = g sinα, and the radius for which the gains would average 1.

    From the known tilt (tilt / vertical modes), from |c₁| = r|We_X| (radius
    mode), or — when the wheel hardly slowed — from gains averaging 1.
    """
    implied_radius = None
    if tilt_rad is not None:
        g_sin = gravity_mps2 * np.sin(tilt_rad)
    elif rot.resolved:
        # c₁ = r Γ Rₓ and gw_x = G Γ Rₓ, so G = r (gw_x·c₁)/|c₁|².
        g_per_r = (rot.gw_x @ rot.c1) / (rot.c1 @ rot.c1)
        g_sin = radius_m * g_per_r
        if g_per_r > 0:  # gains averaging 1 means G = their (scaled) geometric mean
            implied_radius = float(np.exp(np.mean(np.log(scaled_gain))) / g_per_r)
        if not g_sin > 0:
            g_sin = float(np.exp(np.mean(np.log(scaled_gain))))
    else:
        g_sin = float(np.exp(np.mean(np.log(scaled_gain))))  # gains average 1
    return g_sin, implied_radius


def _regression(design: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Least-squares coefficients of v on the columns of ``design``, and (DᵀD)⁻¹ (None: singular).

    The normal equations (their matrix serves the t-test anyway) unless the columns
    are nearly dependent (ω² almost constant): then the SVD's least squares.
    """
    gram = design.T @ design
    if np.linalg.cond(gram) < _NORMAL_EQUATIONS_MAX_COND:
        coef = np.linalg.solve(gram, design.T @ v)
    else:
        coef, *_ = np.linalg.lstsq(design, v, rcond=None)
    try:
        return coef, np.linalg.inv(gram)
    except np.linalg.LinAlgError:
        return coef, None


def _phase_from_rate(
    t: np.ndarray, circle: np.ndarray, rate: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """ϑ(t) = a + b ∫rate dt, with a and b from the rotating signal by coherent demodulation.

    A measured rate (a gyro: unknown sign, scale within a few %, small bias)
    gives the phase's *shape*; the rotating gravity, z = e^{±i(ϑ + c)}, gives
    the rest.  |mean(z e^{−i b S(t)})| (S = ∫rate dt) peaks at the right b —
    no unwrapping, so a push or a step cannot make the phase slip a turn.
    """
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])
    z = circle[:, 0] + 1j * circle[:, 1]
    span = max(float(np.max(np.abs(angle))), 1e-9)
    # b within ±6 % of ±1 on a grid that moves the phase < 0.3 rad over the window,
    # evaluated on a thinned copy (the peak is broad enough), then refined.
    step = min(0.5 / span, 1e-3)
    count = np.arange(0.94, 1.06, step).size
    grid = np.concatenate([0.94 + step * np.arange(count), -0.94 - step * np.arange(count)])
    thin = max(1, z.size // 800)
    power = np.concatenate(
        [_coherence(z[::thin], angle[::thin], sign * 0.94, sign * step, count) for sign in (1, -1)]
    )
    b = float(grid[int(np.argmax(power))])
    for _ in range(3):  # the demodulated phase's remaining drift refines b
        rest = np.unwrap(np.angle(z * np.exp(-1j * b * angle)))
        b += float(np.polyfit(angle, rest, 1)[0])
    a = float(np.angle(np.mean(z * np.exp(-1j * b * angle))))
    return a + b * angle, b * rate


def _coherence(z: np.ndarray, angle: np.ndarray, first: float, step: float, count: int):
    """|Σ z e^{−i b·angle}| for b = first + k·step, k = 0 … count − 1.

    The factors of successive b differ by e^{−i step·angle}: a running product,
    one complex exponential per sample instead of one per sample and b.
    """
    turn = np.exp(-1j * step * angle)
    current = z * np.exp(-1j * first * angle)
    out = np.empty(count)
    for k in range(count):
        out[k] = abs(current.sum())
        current *= turn
    return out


def _rotating_part(
    v: np.ndarray, t: np.ndarray, omega_radps: float, rate: np.ndarray | None
) -> np.ndarray:
    """The samples (n, 3) minus their mean over one revolution, as rows (3, n).

    The revolutions are counted by the measured rate's integral when there is
    one (a gyro), else by a rough phase of the smoothed derivative.
    """
    rate_hz = 1.0 / np.median(np.diff(t))
    rows = np.ascontiguousarray(v.T)
    if rate is not None:
        ramp = np.concatenate([[0.0], np.cumsum(np.abs(0.5 * (rate[1:] + rate[:-1])) * np.diff(t))])
    else:
        width = max(1, int(rate_hz * 2 * np.pi / max(omega_radps, 1e-3) / 8))
        smooth = rows
        if width > 1:
            kernel = np.ones(width) / width
            smooth = np.vstack([np.convolve(rows[k], kernel, mode="same") for k in range(3)])
        rough, _ = rotating_phase(np.gradient(smooth, axis=1))
        ramp = np.maximum.accumulate(rough)
    max_half = int(np.pi / max(omega_radps / 8, 1e-3) * rate_hz)
    return rows - revolution_mean(rows, ramp, max_half)


def _plane_signal(v: np.ndarray) -> np.ndarray:
    """V projected on its two principal directions of largest variance (the wheel plane), (2, N)."""
    step = max(1, v.shape[0] // 20000)  # second moments need no anti-aliasing
    mean = column_means(v[::step])
    centred = centred_rows(v, mean)
    _, vecs = np.linalg.eigh(row_gram(centred[:, ::step]))
    return vecs[:, 1:].T @ centred


def _legendre_fit(legendre: np.ndarray, gram: np.ndarray, degree: int, y: np.ndarray) -> np.ndarray:
    """Least-squares coefficients of y (n,) or (n, k) on the Legendre columns 0…degree.

    ``legendre`` holds P₀…P_D at τ (n, D + 1) and ``gram`` its LᵀL.  On τ spread
    over [−1, 1] the columns are near-orthogonal (LᵀL ≈ n·diag(1/(2j+1)), condition
    ≈ 2D + 1), so the normal equations lose nothing and take a tenth of an SVD.
    """
    size = degree + 1
    return np.linalg.solve(gram[:size, :size], legendre[:, :size].T @ y)


def _dominant_frequency(u: np.ndarray, rate_hz: float) -> float:
    """|f| of the strongest line of u[0] + i u[1] (u: (2, n)), DC left out."""
    z = u[0] + 1j * u[1]
    nfft = 1 << int(np.ceil(np.log2(z.size)))  # power of two: fast and fine enough
    spec = np.abs(fft(z - z.mean(), nfft))
    spec[0] = 0.0
    k = int(np.argmax(spec))
    # np.fft.fftfreq's value at bin k, without building the whole axis.
    return float(abs((k if k < (nfft + 1) // 2 else k - nfft) * (1.0 / (nfft * (1.0 / rate_hz)))))


def _scaled_gains(gw_x: np.ndarray, gw_y: np.ndarray) -> np.ndarray | None:
    """G·γᵢ from orthonormality of R's first two columns (None if ill-posed)."""
    system = np.vstack([gw_x**2, gw_y**2, gw_x * gw_y])
    if np.linalg.cond(system) > 1e8:
        return None
    q = np.linalg.solve(system, np.array([1.0, 1.0, 0.0]))
    if np.any(q <= 0):
        return None
    return 1.0 / np.sqrt(q)


#: G·γᵢ from R's first two columns (shared with the field fit's start).
scaled_gains = _scaled_gains
