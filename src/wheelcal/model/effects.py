"""Optional model extensions ("effects"): what the paper's model may lack.

Each effect has named parameters whose zero means *absent*, so the paper's
model is a point inside every extended model (nested hypotheses: a score test
at the base fit is valid).  Effects act at one of two stages of eq. (6):

* **spin** — they change ϑ(t), ω(t), ω̇(t) (and through eq. (1) the applied
  acceleration): :class:`SpinPolynomialExtension`, :class:`Imbalance`;
* **sensor** — they add Δv to v = o + Γ s: :class:`QuadraticNonlinearity`,
  :class:`OffsetWarmup`, :class:`OffsetDrift`, :class:`GainDrift`,
  :class:`CrossAxis`.

Every effect supplies its value and exact partial derivatives (the model
assembles the Jacobian by the chain rule), a human description, and its
contract name for the calibration JSON (``effects.<name>``).  Time t is the
model's centred time, so drifting quantities are reported at the window centre.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from wheelcal.model.kinematics import Kinematics
from wheelcal.model.parameters import STANDARD_GRAVITY_MPS2

#: A MEMS gyro's sensitivity to linear acceleration, °/s per g (MPU-9250 class: 0.1):
#: the default σ of the prior on G (:class:`GyroReading`).
G_SENSITIVITY_PRIOR_DPS_PER_G = 0.1


@dataclass(frozen=True, eq=False)
class SpinDelta:
    """Changes of ϑ, ω, ω̇ and their derivatives.

    ``d_own_*``: (k, N) w.r.t. the effect's parameters.  ``d_theta_*``,
    ``d_omega_*``: (N,) partials of the changes w.r.t. the incoming ϑ and ω
    (chain rule for the spin coefficients); ``None`` when they vanish.
    """

    theta: np.ndarray
    omega: np.ndarray
    omega_dot: np.ndarray
    d_own_theta: np.ndarray | None = None
    d_own_omega: np.ndarray | None = None
    d_own_omega_dot: np.ndarray | None = None
    by_theta: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # ∂(Δϑ, Δω, Δω̇)/∂ϑ
    by_omega: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # ∂(Δϑ, Δω, Δω̇)/∂ω
    by_tilt: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # ∂(Δϑ, Δω, Δω̇)/∂α


@dataclass(frozen=True, eq=False)
class SensorDelta:
    """Δv (N, 3) and its partials.

    ``d_own``: (k, 3, N); ``d_sensed``: (N, 3, 3) = ∂Δv/∂s or None;
    ``d_gain``: (3, 3, N) = ∂Δv/∂γ (rows γ_x, γ_y, γ_z) or None.
    """

    delta: np.ndarray
    d_own: np.ndarray | None = None
    d_sensed: np.ndarray | None = None
    d_gain: np.ndarray | None = None


class Effect(ABC):
    """A named, optional extension of the model (zero parameters = absent)."""

    name: ClassVar[str]
    param_names: ClassVar[tuple[str, ...]]
    stage: ClassVar[str]  # "spin" or "sensor"
    description: ClassVar[str]
    #: Sensor-intrinsic effects are shared by every recording of one sensor.
    sensor_intrinsic: ClassVar[bool] = False
    #: Effects that only move the offset over time (Δv independent of s).
    offset_like: ClassVar[bool] = False
    #: False for an effect no single recording can identify (the fit's own parameters
    #: span it on one mounting): the single-recording screen lists it without testing.
    one_recording_identifies: ClassVar[bool] = True
    #: A sensor effect that follows time (a warm-up, a drift): its law is known within
    #: the fitted window only, so the rests around it cannot test or check it.
    varies_in_time: ClassVar[bool] = False

    @property
    def size(self) -> int:
        """Number of parameters."""
        return len(self.param_names)

    def settings(self) -> dict:
        """Fixed settings of this instance (e.g. a time constant) for reports."""
        return {}

    def refinements(self) -> tuple[Effect, ...]:
        """Finer alternatives of a setting (e.g. τ), tried once the effect is detected."""
        return ()

    def with_free_setting(self) -> Effect | None:
        """The same effect with its setting (e.g. τ) as a fitted parameter, if it has one."""
        return None

    def values_from(self, other_values: np.ndarray, other: Effect) -> np.ndarray:
        """Starting values for this effect from a fitted ``other`` of the same family."""
        return np.asarray(other_values, dtype=float)

    def prior_std_values(self) -> np.ndarray | None:
        """σ of Gaussian priors per parameter (∞: none), or None: no prior at all.

        The fit adds them as pseudo-observations (e.g. a gyro's sensitivity to
        acceleration, known to its sensor class).
        """
        return None

    def prior_mean_values(self) -> np.ndarray:
        """The priors' means (zero unless an effect says otherwise: a scale's 1)."""
        return np.zeros(self.size)

    def label(self) -> str:
        """Name plus settings, e.g. ``offset_warmup(tau_s=25)``."""
        s = self.settings()
        return (
            self.name
            if not s
            else f"{self.name}(" + ", ".join(f"{k}={v:.3g}" for k, v in s.items()) + ")"
        )

    def spin_delta(
        self, values: np.ndarray, t_s: np.ndarray, kin: Kinematics, jacobian: bool
    ) -> SpinDelta:
        """Spin-stage change (only for ``stage == "spin"``)."""
        raise NotImplementedError

    def sensor_delta(
        self,
        values: np.ndarray,
        t_s: np.ndarray,
        sensed: np.ndarray,
        gain: np.ndarray,
        jacobian: bool,
    ) -> SensorDelta:
        """Sensor-stage change (only for ``stage == "sensor"``)."""
        raise NotImplementedError

    def __repr__(self) -> str:
        return self.label()

    def __eq__(self, other: object) -> bool:
        return type(self) is type(other) and self.settings() == other.settings()

    def __hash__(self) -> int:
        return hash((type(self).__name__, tuple(sorted(self.settings().items()))))


class _SpinEffect(Effect, ABC):
    stage = "spin"

    @abstractmethod
    def spin_delta(self, values, t_s, kin, jacobian): ...

    def own_rows(
        self, t_s: np.ndarray, kin: Kinematics, sin_theta: np.ndarray, cos_theta: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(∂ϑ, ∂ω, ∂ω̇)/∂θ at θ = 0, each (k, N): the effect's own rows of ``spin_delta``.

        ``sin_theta``/``cos_theta`` are sin ϑ, cos ϑ of ``kin`` (the bench force has
        them), so an effect that needs them does not take them again.
        """
        d = self.spin_delta(np.zeros(self.size), t_s, kin, True)
        return d.d_own_theta, d.d_own_omega, d.d_own_omega_dot


class _SensorEffect(Effect, ABC):
    stage = "sensor"

    @abstractmethod
    def sensor_delta(self, values, t_s, sensed, gain, jacobian): ...

    def axis_columns(
        self, t_s: np.ndarray, sensed: np.ndarray, gain: np.ndarray
    ) -> tuple[np.ndarray, tuple[int, ...]] | None:
        """∂Δv/∂θ at θ = 0 when each parameter acts on one axis: (k, N) values, their axes.

        The lean form of ``sensor_delta(0, …, jacobian=True).d_own`` — whose row k is
        zero but on axis ``axes[k]`` — for the closed loop's screen, which needs these
        columns at every sample (its score) and at the quadrature's rows (its
        information).  ``None``: the effect has no such form (the screen then takes
        ``d_own``).
        """
        return None

    def axis_scores(
        self, t_s: np.ndarray, sensed: np.ndarray, gain: np.ndarray, weights: np.ndarray
    ) -> np.ndarray | None:
        """Σ_n (column k at sample n) · w_n (k,) of the lean columns, for weights w (3, N).

        The screen's score of the effect (weights: the residual whitened back); ``None``
        where :meth:`axis_columns` is.  An effect may sum without forming its columns.
        """
        lean = self.axis_columns(t_s, sensed, gain)
        if lean is None:
            return None
        values, axes = lean
        return np.array([values[k] @ weights[axis] for k, axis in enumerate(axes)])


class SpinPolynomialExtension(_SpinEffect):
    """Spin-down beyond the cubic: ω(t) gains ω₄t⁴ + ω₅t⁵ (+ …).

    Strong air drag (ω̇ = −c ω²) bends ω(t) more than a cubic can follow over a
    long spin; the extra coefficients are zero for the paper's model.
    """

    name = "spin_extension"
    description = "spin-down beyond the cubic (higher-order terms of eq. 2)"

    def __init__(self, extra_degrees: int = 2) -> None:
        if extra_degrees < 1:
            raise ValueError("extra_degrees must be >= 1")
        self.extra_degrees = extra_degrees
        self.param_names = tuple(f"omega{4 + j}_radps{5 + j}" for j in range(extra_degrees))

    def settings(self) -> dict:
        return {"extra_degrees": self.extra_degrees}

    def own_rows(self, t_s, kin, sin_theta, cos_theta):
        degrees = self.extra_degrees
        powers = np.empty((degrees + 2, np.size(t_s)))  # t^3 … t^(K+4)
        np.multiply(t_s, t_s, out=powers[0])
        powers[0] *= t_s
        for j in range(1, degrees + 2):
            np.multiply(powers[j - 1], t_s, out=powers[j])
        k = np.arange(4, 4 + degrees)[:, None]
        return powers[2:] / (k + 1), powers[1:-1], powers[:-2] * k

    def spin_delta(self, values, t_s, kin, jacobian):
        k = np.arange(4, 4 + self.extra_degrees)
        powers = t_s[None, :] ** np.arange(3, 4 + self.extra_degrees + 1)[:, None]  # t^3 … t^(K+1)
        p_k = powers[1:-1]  # t^4 …
        p_k1 = powers[2:]  # t^5 …
        p_km1 = powers[:-2]  # t^3 …
        d_theta = p_k1 / (k + 1)[:, None]
        d_omega = p_k
        d_omega_dot = p_km1 * k[:, None]
        return SpinDelta(
            theta=values @ d_theta,
            omega=values @ d_omega,
            omega_dot=values @ d_omega_dot,
            d_own_theta=d_theta,
            d_own_omega=d_omega,
            d_own_omega_dot=d_omega_dot,
        )


class Imbalance(_SpinEffect):
    """An imperfect counterbalance: a once-per-turn torque, ω̇ += a sinϑ + b cosϑ.

    (a, b) = ε(cos φ, sin φ) for ω̇ += ε sin(ϑ + φ); absent at (0, 0).  To first
    order in ε/ω² (quasi-steady, ω slowly varying) the motion changes by

        Δω̇ = a sinϑ + b cosϑ,  Δω = −(a cosϑ − b sinϑ)/ω,  Δϑ = −(a sinϑ + b cosϑ)/ω².
    """

    name = "imbalance"
    param_names = ("sin_radps2", "cos_radps2")
    description = "wheel imbalance: once-per-turn torque ε·sin(ϑ + φ)"

    def own_rows(self, t_s, kin, sin_theta, cos_theta):
        w = kin.omega_radps
        inv = 1.0 / np.where(np.abs(w) < 1e-3, 1e-3, w)  # as spin_delta
        inv2 = inv * inv
        theta = np.empty((2, inv.size))
        np.multiply(sin_theta, inv2, out=theta[0])
        np.multiply(cos_theta, inv2, out=theta[1])
        np.negative(theta, out=theta)
        omega = np.empty((2, inv.size))
        np.multiply(cos_theta, inv, out=omega[0])
        np.negative(omega[0], out=omega[0])
        np.multiply(sin_theta, inv, out=omega[1])
        return theta, omega, np.stack([sin_theta, cos_theta])

    def spin_delta(self, values, t_s, kin, jacobian):
        a, b = values
        s, c = np.sin(kin.theta_rad), np.cos(kin.theta_rad)
        w = kin.omega_radps
        w = np.where(np.abs(w) < 1e-3, 1e-3, w)
        u = a * s + b * c  # torque term
        du = a * c - b * s  # ∂u/∂ϑ
        d_theta = -u / w**2
        d_omega = -du / w
        d_omega_dot = u
        own_theta = np.vstack([-s / w**2, -c / w**2])
        own_omega = np.vstack([-c / w, s / w])
        own_omega_dot = np.vstack([s, c])
        by_theta = (-du / w**2, u / w, du)  # ∂/∂ϑ of (Δϑ, Δω, Δω̇); ∂du/∂ϑ = −u
        by_omega = (2 * u / w**3, du / w**2, np.zeros_like(u))
        return SpinDelta(
            theta=d_theta,
            omega=d_omega,
            omega_dot=d_omega_dot,
            d_own_theta=own_theta,
            d_own_omega=own_omega,
            d_own_omega_dot=own_omega_dot,
            by_theta=by_theta,
            by_omega=by_omega,
        )


class GyroReading(Effect):
    """The gyroscope on the wheel: ω_meas(t) = w·ω(t) + b + G_X a_X(t) + G_Y a_Y(t) (rad/s).

    On a fixed bench the gyro sees only the wheel's rotation, about the wheel
    axis: an ideal gyro reads −ω R e_Z (the wheel's angular velocity is −ω e_Z in
    the bench frame, README "Conventions").  A real one reads w ω + b with
    w = k u: scale k along the axis and a unit direction u that per-axis scale
    errors and the gyro-to-accelerometer misalignment tilt by 1–2° from −R e_Z —
    so u is free here and never constrains R.

    A MEMS gyro also responds to linear acceleration (~0.1 °/s/g): G·(R a).  On
    the wheel the specific force a(t) of eq. (1) turns once per turn and grows
    with ω², so G R e_X and G R e_Y — the columns G_X, G_Y (gyro axes, rad/s per
    m/s²) that multiply a_X and a_Y — are seen and fitted with
    ``g_sensitivity=True``; G R e_Z multiplies the constant a_Z = g cosα and is
    inseparable from the bias, which is therefore the reading at zero rate *on
    this bench*.  Left out, G's once-per-turn ripple poses as an imbalance.

    Calibrated: the scale along the wheel axis (|w|), the axis u, the biases (and
    G_X, G_Y).  Zero values are not "absent": this is a measurement, not an
    extension.

    G gets a prior from the sensor class, N(0, σ_G²) per entry with σ_G =
    ``g_prior_dps_per_g`` (°/s/g, MPU-9250 class: 0.1): G's once-per-turn term
    has the shape of an imbalance's rate ripple (which goes as 1/ω), and a free G
    would absorb it — the ripple then vanishes from the gyro and the imbalance
    hides in the accelerometer's gains.  The prior adds G/σ_G² to the gradient and
    1/σ_G² to the information of each entry (:func:`g_prior_terms`); ``None``
    leaves G free.
    """

    name = "gyro"
    stage = "gyro"
    description = "gyroscope reading w·ω + b + G·a (w = scale × axis)"
    _BASE = ("w_x", "w_y", "w_z", "bias_x_radps", "bias_y_radps", "bias_z_radps")
    _SENSITIVITY = ("gx_x", "gx_y", "gx_z", "gy_x", "gy_y", "gy_z")

    def __init__(
        self,
        g_sensitivity: bool = True,
        g_prior_dps_per_g: float | None = G_SENSITIVITY_PRIOR_DPS_PER_G,
    ) -> None:
        if g_prior_dps_per_g is not None and not (
            np.isfinite(g_prior_dps_per_g) and g_prior_dps_per_g > 0
        ):
            raise ValueError("g_prior_dps_per_g must be a positive number (°/s/g) or None")
        self.g_sensitivity = bool(g_sensitivity)
        self.g_prior_dps_per_g = None if g_prior_dps_per_g is None else float(g_prior_dps_per_g)
        self.param_names = self._BASE + (self._SENSITIVITY if self.g_sensitivity else ())

    def settings(self) -> dict:
        return {"g_sensitivity": self.g_sensitivity, "g_prior_dps_per_g": self.g_prior_dps_per_g}

    @property
    def g_prior_std_radps_per_mps2(self) -> float | None:
        """σ_G of the prior in the model's units (rad/s per m/s²), or None (no prior)."""
        if not self.g_sensitivity or self.g_prior_dps_per_g is None:
            return None
        return self.g_prior_dps_per_g * np.pi / 180.0 / STANDARD_GRAVITY_MPS2

    def g_prior_terms(self, values: np.ndarray) -> tuple[float, np.ndarray, float] | None:
        """The prior's (cost, gradient, information) on G = values[6:12], or None.

        cost = Σ G²/σ², gradient G/σ², information 1/σ² on the diagonal.
        """
        std = self.g_prior_std_radps_per_mps2
        if std is None:
            return None
        g = np.asarray(values, dtype=float)[6:12]
        weight = 1.0 / std**2
        return float(weight * (g @ g)), weight * g, weight

    def reading(
        self,
        values: np.ndarray,
        omega_radps: np.ndarray,
        force_mps2: np.ndarray | None = None,
    ) -> np.ndarray:
        """Predicted gyro samples (N, 3) for ω(t) and the bench-frame force a(t) (N, 3)."""
        values = np.asarray(values, dtype=float)
        out = np.outer(omega_radps, values[:3]) + values[3:6]
        if self.g_sensitivity:
            out += np.outer(force_mps2[:, 0], values[6:9]) + np.outer(
                force_mps2[:, 1], values[9:12]
            )
        return out


def cubic_bspline_slots(
    t_s: np.ndarray, start_s: float, spacing_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each sample's knot interval j and its four live basis functions B_j … B_{j+3}.

    Returns ``(interval, values, slopes, curves)``: the interval index (int, N) and
    (4, N) arrays whose row m is B_{j+m}(t), B′_{j+m}(t), B″_{j+m}(t) (see
    :func:`cubic_bspline_basis`, which scatters these rows into one row per function).
    """
    t = np.asarray(t_s, dtype=float)
    position = (t - start_s) / spacing_s
    interval = np.floor(position)
    x = position - interval
    # Products, not ``**`` (numpy's float power is ~6× slower than two multiplications),
    # each row written into its (4, N) table, with the 1/Δ, 1/Δ² scales folded in.
    y = 1 - x
    x2, y2 = x * x, y * y
    x3 = x2 * x
    values = np.empty((4, t.size))
    np.multiply(y2, y, out=values[0])
    np.multiply(x3, 3.0, out=values[1])
    values[1] -= 6 * x2
    values[1] += 4.0
    np.multiply(x2, 3.0, out=values[2])
    values[2] -= 3 * x3
    values[2] += 3 * x
    values[2] += 1.0
    values[3] = x3
    values /= 6.0
    d1 = 1.0 / spacing_s
    slopes = np.empty((4, t.size))
    np.multiply(y2, -0.5 * d1, out=slopes[0])
    np.multiply(x2, 1.5 * d1, out=slopes[1])
    slopes[1] -= (2 * d1) * x
    np.multiply(x2, -1.5 * d1, out=slopes[2])
    slopes[2] += d1 * x
    slopes[2] += 0.5 * d1
    np.multiply(x2, 0.5 * d1, out=slopes[3])
    d2 = d1 * d1
    curves = np.empty((4, t.size))
    np.multiply(y, d2, out=curves[0])
    np.multiply(x, 3 * d2, out=curves[1])
    curves[1] -= 2 * d2
    np.multiply(x, -3 * d2, out=curves[2])
    curves[2] += d2
    np.multiply(x, d2, out=curves[3])
    return interval.astype(np.int64), values, slopes, curves


def samples_of(grid: np.ndarray, t: np.ndarray) -> slice | np.ndarray | None:
    """Where ``t`` lies in ``grid`` when every time is one of its samples, else None.

    There linear interpolation returns the sample itself (its weight is exactly 1 or 0),
    so a gather gives the same numbers, bit for bit, without the weights' four passes.
    A run of the grid's samples at one stride (a chunk, a thinned pass) comes as a
    slice: indexing with it is a view, not a gather; any other set as its indices.
    """
    if t.size >= 2:
        first, second = np.searchsorted(grid, t[:2])
        step = int(second - first)
        stop = int(first) + step * (t.size - 1) + 1
        if step > 0 and stop <= grid.size:
            run = slice(int(first), stop, step)
            if np.array_equal(grid[run], t):
                return run
    index = np.searchsorted(grid, t)
    if index.size and index[-1] >= grid.size:
        return None
    return index if np.array_equal(grid[index], t) else None


def cubic_bspline_basis(
    t_s: np.ndarray, start_s: float, spacing_s: float, count: int, first: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Uniform cubic B-splines B_k(t) and their first two derivatives, each (count, N).

    B_k(t) = B((t − start)/Δ − k + 3), k = first … first + count − 1, with B the
    cardinal cubic B-spline on [0, 4).  In knot interval j (t = start + (j + x)Δ,
    0 ≤ x < 1) only B_j … B_{j+3} are non-zero:

        (1 − x)³/6,  (3x³ − 6x² + 4)/6,  (−3x³ + 3x² + 3x + 1)/6,  x³/6,

    so each sample costs four values, whatever ``count`` is.  All the
    functions of a window sum to 1 on it.
    """
    t = np.asarray(t_s, dtype=float)
    interval, values, slopes, curves = cubic_bspline_slots(t, start_s, spacing_s)
    b = np.zeros((count, t.size))
    d1 = np.zeros((count, t.size))
    d2 = np.zeros((count, t.size))
    columns = np.arange(t.size)
    for m in range(4):
        row = interval + m - first
        ok = (row >= 0) & (row < count)
        r, c = row[ok], columns[ok]
        b[r, c] = values[m][ok]
        d1[r, c] = slopes[m][ok]
        d2[r, c] = curves[m][ok]
    return b, d1, d2


def cubic_bspline_sum(
    coef: np.ndarray, t_s: np.ndarray, start_s: float, spacing_s: float, first: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Σ c_k B_k(t) and its first two derivatives, each (N,), without the (count, N) bases.

    The same sums as ``coef @`` :func:`cubic_bspline_basis` (``count`` = ``coef.size``).
    On knot interval j the sum is one cubic in x (its coefficients from c_j … c_{j+3}
    and the four pieces of B): computed once per interval, evaluated per sample by
    Horner's rule — no basis matrix, whatever the count.
    """
    t = np.asarray(t_s, dtype=float)
    coef = np.asarray(coef, dtype=float)
    if t.size == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    position = (t - start_s) / spacing_s
    interval = np.floor(position)
    x = position - interval
    index = interval.astype(np.int64)
    k0 = int(index.min())
    # c_j … c_{j+3} of each interval present, zero outside 0 … count − 1.
    padded = np.concatenate([np.zeros(4), coef, np.zeros(4)])
    rows = np.clip(np.arange(k0, int(index.max()) + 1) - first, -4, coef.size) + 4
    c0, c1, c2, c3 = (padded[rows + m] for m in range(4))
    # c_j (1 − x)³/6 + c_{j+1} (3x³ − 6x² + 4)/6 + c_{j+2} (−3x³ + 3x² + 3x + 1)/6
    # + c_{j+3} x³/6 = a0 + a1 x + a2 x² + a3 x³:
    a0 = (c0 + 4 * c1 + c2) / 6
    a1 = (c2 - c0) / 2
    a2 = (c0 - 2 * c1 + c2) / 2
    a3 = (-c0 + 3 * c1 - 3 * c2 + c3) / 6
    local = index - k0
    a0, a1, a2, a3 = a0[local], a1[local], a2[local], a3[local]
    theta = ((a3 * x + a2) * x + a1) * x + a0
    omega = ((3 * a3) * x + 2 * a2) * x + a1
    omega_dot = (6 * a3) * x + 2 * a2
    return theta, omega / spacing_s, omega_dot / spacing_s**2


_BASIS_CACHE: dict = {}
#: Bytes held by the cache's arrays (kept up to date as entries come and go).
_BASIS_CACHE_BYTES = [0]
_BASIS_CACHE_SIZE = 256
#: At most this many bytes of bases are remembered (oldest dropped first): the cache
#: must not grow with the recording (a 2.9 M-sample motion check once left ~116 B per sample).
#: A gyro-aided fit with 0.5 s knots over 90 s at 200 Hz needs ~80 MB of bases.
_BASIS_CACHE_MAX_BYTES = 128 * 2**20


def _cached_basis(t: np.ndarray, start_s: float, spacing_s: float, count: int, first: int):
    """:func:`cubic_bspline_basis`, remembered: a fit evaluates the same times many times.

    The key holds the times' bytes (hashed with their length and ends), so a
    different time array never hits; the arrays returned are read-only.  At
    most :data:`_BASIS_CACHE_SIZE` entries and :data:`_BASIS_CACHE_MAX_BYTES`
    are kept; a basis larger than that is computed and not kept.
    """
    key = (
        hash(t.tobytes()),
        t.size,
        float(t[0]) if t.size else 0.0,
        start_s,
        spacing_s,
        count,
        first,
    )
    hit = _BASIS_CACHE.get(key)
    if hit is None:
        hit = cubic_bspline_basis(t, start_s, spacing_s, count, first)
        for array in hit:
            array.setflags(write=False)
        size = sum(array.nbytes for array in hit)
        if size > _BASIS_CACHE_MAX_BYTES:
            return hit
        while _BASIS_CACHE and (
            len(_BASIS_CACHE) >= _BASIS_CACHE_SIZE
            or _BASIS_CACHE_BYTES[0] + size > _BASIS_CACHE_MAX_BYTES
        ):
            dropped = _BASIS_CACHE.pop(next(iter(_BASIS_CACHE)))
            _BASIS_CACHE_BYTES[0] -= sum(array.nbytes for array in dropped)
        _BASIS_CACHE[key] = hit
        _BASIS_CACHE_BYTES[0] += size
    return hit


class SpinSpline(_SpinEffect):
    """A smooth correction of the wheel angle: Δϑ(t) = Σ c_k B_k(t) (rad).

    Uniform cubic B-splines with knots every ``spacing_s`` over the window
    [``start_s``, ``end_s``] (centred times) let ϑ(t) follow any motion slower
    than the knot spacing — a driven wheel, a long spin, a second push — where
    eq. (2)'s cubic cannot.  Δω = Σ c_k B_k′, Δω̇ = Σ c_k B_k″.  A once-per-turn
    wobble (imbalance) is far faster and stays out of it.
    """

    name = "spin_spline"
    description = "smooth correction of the wheel angle (cubic B-spline)"

    def __init__(
        self,
        start_s: float,
        end_s: float,
        spacing_s: float = 5.0,
        first: int = 0,
        count: int | None = None,
    ) -> None:
        if not (end_s > start_s and spacing_s > 0):
            raise ValueError("need end_s > start_s and spacing_s > 0")
        intervals = max(1, int(np.ceil((end_s - start_s) / spacing_s - 1e-9)))
        self.start_s, self.end_s = float(start_s), float(end_s)
        self.spacing_s = (end_s - start_s) / intervals
        total = intervals + 3
        self.first = int(first)
        count = total - self.first if count is None else int(count)
        if not (0 <= self.first and count >= 1 and self.first + count <= total):
            raise ValueError(f"basis functions {first}…{first + count - 1} outside 0…{total - 1}")
        self.param_names = tuple(f"c{k}_rad" for k in range(self.first, self.first + count))

    def settings(self) -> dict:
        out = {"start_s": self.start_s, "end_s": self.end_s, "spacing_s": self.spacing_s}
        if self.first or self.size != len(self.active(self.start_s, self.end_s)):
            out.update(first=self.first, count=self.size)
        return out

    def active(self, t_lo: float, t_hi: float) -> range:
        """Indices of the basis functions (of the whole window) not zero on [t_lo, t_hi]."""
        total = round((self.end_s - self.start_s) / self.spacing_s) + 3
        k0 = max(0, int(np.floor((t_lo - self.start_s) / self.spacing_s)))
        k1 = min(total, int(np.floor((t_hi - self.start_s) / self.spacing_s)) + 4)
        return range(k0, k1)

    def restricted(self, indices: range) -> SpinSpline:
        """The same spline seen through some of its basis functions (a chunk's)."""
        return SpinSpline(
            self.start_s, self.end_s, self.spacing_s, first=indices.start, count=len(indices)
        )

    def spin_delta(self, values, t_s, kin, jacobian):
        if not jacobian:  # the sums only: four basis functions per sample, no matrix
            theta, omega, omega_dot = cubic_bspline_sum(
                values, t_s, self.start_s, self.spacing_s, self.first
            )
            return SpinDelta(theta=theta, omega=omega, omega_dot=omega_dot)
        b, d1, d2 = _cached_basis(
            np.asarray(t_s, dtype=float), self.start_s, self.spacing_s, self.size, self.first
        )
        values = np.asarray(values, dtype=float)
        return SpinDelta(
            theta=values @ b,
            omega=values @ d1,
            omega_dot=values @ d2,
            d_own_theta=b,
            d_own_omega=d1,
            d_own_omega_dot=d2,
        )


class QuadraticNonlinearity(_SensorEffect):
    """Per-axis quadratic response: v_i += γ_i k_i s_i² (k in 1/(m/s²))."""

    description = "quadratic nonlinearity of one sensor axis"
    sensor_intrinsic = True

    def __init__(self, axis: int) -> None:
        if axis not in (0, 1, 2):
            raise ValueError("axis must be 0, 1 or 2")
        self.axis = axis
        self.name = f"nonlinearity_{'xyz'[axis]}"
        self.param_names = ("k_per_mps2",)

    def settings(self) -> dict:
        return {}

    def __eq__(self, other: object) -> bool:
        return isinstance(other, QuadraticNonlinearity) and other.axis == self.axis

    def __hash__(self) -> int:
        return hash(("nonlinearity", self.axis))

    def sensor_delta(self, values, t_s, sensed, gain, jacobian):
        i = self.axis
        k = values[0]
        s_i = sensed[:, i]
        delta = np.zeros_like(sensed)
        delta[:, i] = gain[i] * k * s_i**2
        if not jacobian:
            return SensorDelta(delta)
        d_own = np.zeros((1, 3, s_i.size))
        d_own[0, i] = gain[i] * s_i**2
        d_sensed = np.zeros((s_i.size, 3, 3))
        d_sensed[:, i, i] = 2 * gain[i] * k * s_i
        d_gain = np.zeros((3, 3, s_i.size))
        d_gain[i, i] = k * s_i**2
        return SensorDelta(delta, d_own, d_sensed, d_gain)

    def axis_columns(self, t_s, sensed, gain):
        s_i = sensed[:, self.axis]
        return (gain[self.axis] * s_i * s_i)[None, :], (self.axis,)

    def axis_scores(self, t_s, sensed, gain, weights):
        i = self.axis
        s_i = sensed[:, i]
        return np.array([gain[i] * ((s_i * weights[i]) @ s_i)])


class OffsetWarmup(_SensorEffect):
    """Thermal warm-up of the offsets: Δo_i(t) = a_i (1 − e^{−t/τ}), zero at the centre.

    A warm-up d·(1 − e^{−(t − t₀)/τ}) that started at any t₀ has this shape after
    the constant part moves into o (reported at the centre); a_i is the change
    still to come after the centre time.  τ exists only when the effect does:
    candidates are tested on a grid of τ and the p-value is corrected for it.
    """

    name = "offset_warmup"
    param_names = ("x_mps2", "y_mps2", "z_mps2")
    offset_like = True
    varies_in_time = True
    description = "offset warm-up d·(1 − e^(−t/τ))"
    sensor_intrinsic = False

    def __init__(self, tau_s: float) -> None:
        if not tau_s > 0:
            raise ValueError("tau_s must be positive")
        self.tau_s = float(tau_s)

    def settings(self) -> dict:
        return {"tau_s": self.tau_s}

    def refinements(self) -> tuple[Effect, ...]:
        # 24 time constants, log-spaced over the grid's range and a little beyond.
        return tuple(OffsetWarmup(float(t)) for t in np.geomspace(5.0, 160.0, 24))

    def with_free_setting(self) -> Effect:
        return OffsetWarmupFreeTau(self.tau_s)

    def shape(self, t_s: np.ndarray) -> np.ndarray:
        """1 − e^{−t/τ} (0 at the centre)."""
        return -np.expm1(-t_s / self.tau_s)

    def sensor_delta(self, values, t_s, sensed, gain, jacobian):
        w = self.shape(t_s)
        delta = w[:, None] * values[None, :]
        if not jacobian:
            return SensorDelta(delta)
        d_own = np.zeros((3, 3, t_s.size))
        for i in range(3):
            d_own[i, i] = w
        return SensorDelta(delta, d_own)

    def axis_columns(self, t_s, sensed, gain):
        return np.broadcast_to(self.shape(t_s), (3, t_s.size)), (0, 1, 2)


class OffsetWarmupFreeTau(OffsetWarmup):
    """Offset warm-up with τ fitted too (values: amplitudes, then ln τ).

    Only meaningful once the warm-up is present (at zero amplitude τ has no
    information), so the closed loop first fits the amplitudes at the best grid
    τ, then frees τ.  ``tau_s`` is the starting value; the fitted τ is
    exp(values[3]).
    """

    param_names = ("x_mps2", "y_mps2", "z_mps2", "log_tau_s")

    def refinements(self) -> tuple[Effect, ...]:
        return ()

    def with_free_setting(self) -> None:
        return None

    def settings(self) -> dict:
        return {"tau_start_s": self.tau_s}

    def values_from(self, other_values, other) -> np.ndarray:
        return np.concatenate([np.asarray(other_values, float)[:3], [np.log(other.tau_s)]])

    def axis_columns(self, t_s, sensed, gain):
        return None  # ∂/∂lnτ acts on every axis (and is zero at zero amplitude)

    def sensor_delta(self, values, t_s, sensed, gain, jacobian):
        amp, tau = np.asarray(values[:3]), float(np.exp(values[3]))
        decay = np.exp(-t_s / tau)
        w = 1.0 - decay
        delta = w[:, None] * amp[None, :]
        if not jacobian:
            return SensorDelta(delta)
        d_own = np.zeros((4, 3, t_s.size))
        for i in range(3):
            d_own[i, i] = w
        # ∂w/∂lnτ = τ ∂w/∂τ = −(t/τ) e^{−t/τ}
        d_own[3] = (-(t_s / tau) * decay)[None, :] * amp[:, None]
        return SensorDelta(delta, d_own)


class OffsetDrift(_SensorEffect):
    """Linear offset drift: Δo_i(t) = r_i t (zero at the centre)."""

    name = "offset_drift"
    param_names = ("x_mps2_per_s", "y_mps2_per_s", "z_mps2_per_s")
    offset_like = True
    varies_in_time = True
    description = "linear offset drift"

    def sensor_delta(self, values, t_s, sensed, gain, jacobian):
        delta = t_s[:, None] * values[None, :]
        if not jacobian:
            return SensorDelta(delta)
        d_own = np.zeros((3, 3, t_s.size))
        for i in range(3):
            d_own[i, i] = t_s
        return SensorDelta(delta, d_own)

    def axis_columns(self, t_s, sensed, gain):
        return np.broadcast_to(t_s, (3, t_s.size)), (0, 1, 2)

    def axis_scores(self, t_s, sensed, gain, weights):
        return weights @ t_s


class GainDrift(_SensorEffect):
    """Linear gain drift: γ_i(t) = γ_i (1 + h_i t), reported at the centre."""

    name = "gain_drift"
    param_names = ("x_per_s", "y_per_s", "z_per_s")
    varies_in_time = True
    description = "linear gain drift"

    def sensor_delta(self, values, t_s, sensed, gain, jacobian):
        delta = (gain * values)[None, :] * t_s[:, None] * sensed
        if not jacobian:
            return SensorDelta(delta)
        n = t_s.size
        d_own = np.zeros((3, 3, n))
        d_sensed = np.zeros((n, 3, 3))
        d_gain = np.zeros((3, 3, n))
        for i in range(3):
            d_own[i, i] = gain[i] * t_s * sensed[:, i]
            d_sensed[:, i, i] = gain[i] * values[i] * t_s
            d_gain[i, i] = values[i] * t_s * sensed[:, i]
        return SensorDelta(delta, d_own, d_sensed, d_gain)

    def axis_columns(self, t_s, sensed, gain):
        return (gain * sensed).T * t_s, (0, 1, 2)

    def axis_scores(self, t_s, sensed, gain, weights):
        return gain * ((sensed.T * weights) @ t_s)


class CrossAxis(_SensorEffect):
    """Non-orthogonal sensing axes: v = o + Γ (I + L) s, L strictly lower triangular.

    With R a free rotation, Γ(I + L)R spans every 3×3 matrix (9 = 3 + 3 + 3), so
    (l_yx, l_zx, l_zy) are the sensor's three non-orthogonality angles (rad).
    One mounting sees only two columns of ΓR: these are identifiable only from
    several mountings (see :mod:`wheelcal.closedloop.multi_mounting`).
    """

    name = "cross_axis"
    param_names = ("yx_rad", "zx_rad", "zy_rad")
    description = "cross-axis coupling (non-orthogonal sensing axes)"
    sensor_intrinsic = True
    one_recording_identifies = False
    _pairs = ((1, 0), (2, 0), (2, 1))  # (row i, column j) of L

    def matrix(self, values: np.ndarray) -> np.ndarray:
        """L (3×3, strictly lower triangular)."""
        out = np.zeros((3, 3))
        for v, (i, j) in zip(values, self._pairs, strict=True):
            out[i, j] = v
        return out

    def sensor_delta(self, values, t_s, sensed, gain, jacobian):
        lower = self.matrix(values)
        coupled = sensed @ lower.T  # (L s) per sample
        delta = gain[None, :] * coupled
        if not jacobian:
            return SensorDelta(delta)
        n = t_s.size
        d_own = np.zeros((3, 3, n))
        for p, (i, j) in enumerate(self._pairs):
            d_own[p, i] = gain[i] * sensed[:, j]
        d_sensed = np.broadcast_to(gain[:, None] * lower, (n, 3, 3)).copy()
        d_gain = np.zeros((3, 3, n))
        for i in range(3):
            d_gain[i, i] = coupled[:, i]
        return SensorDelta(delta, d_own, d_sensed, d_gain)

    def axis_columns(self, t_s, sensed, gain):
        rows = np.stack([gain[i] * sensed[:, j] for i, j in self._pairs])
        return rows, tuple(i for i, _ in self._pairs)


def warmup_grid(tau_s: tuple[float, ...] = (10.0, 20.0, 40.0, 80.0)) -> tuple[OffsetWarmup, ...]:
    """Warm-up candidates over a grid of time constants."""
    return tuple(OffsetWarmup(t) for t in tau_s)


def default_candidates() -> tuple[Effect, ...]:
    """Every effect the closed loop tries on a single recording."""
    return (
        SpinPolynomialExtension(),
        Imbalance(),
        QuadraticNonlinearity(0),
        QuadraticNonlinearity(1),
        QuadraticNonlinearity(2),
        *warmup_grid(),
        OffsetDrift(),
        GainDrift(),
        CrossAxis(),
    )


def make_effect(name: str, settings: dict | None = None) -> Effect:
    """An effect from its contract name and settings (as written in the calibration JSON)."""
    settings = settings or {}
    if name.startswith("nonlinearity_"):
        return QuadraticNonlinearity("xyz".index(name[-1]))
    if name == "offset_warmup":
        if "tau_start_s" in settings:
            return OffsetWarmupFreeTau(float(settings["tau_start_s"]))
        return OffsetWarmup(float(settings.get("tau_s", 25.0)))
    if name == "spin_extension":
        return SpinPolynomialExtension(int(settings.get("extra_degrees", 2)))
    if name == "gyro":
        return GyroReading(
            bool(settings.get("g_sensitivity", False)),
            settings.get("g_prior_dps_per_g", G_SENSITIVITY_PRIOR_DPS_PER_G),
        )
    if name == "spin_spline":
        return SpinSpline(
            float(settings["start_s"]), float(settings["end_s"]), float(settings["spacing_s"])
        )
    simple = {
        "imbalance": Imbalance,
        "offset_drift": OffsetDrift,
        "gain_drift": GainDrift,
        "cross_axis": CrossAxis,
    }
    if name not in simple:
        raise ValueError(f"unknown effect {name!r}")
    return simple[name]()


def intrinsic_candidates() -> tuple[Effect, ...]:
    """Sensor-intrinsic effects tested on all recordings of a sensor together."""
    return (
        QuadraticNonlinearity(0),
        QuadraticNonlinearity(1),
        QuadraticNonlinearity(2),
        CrossAxis(),
    )
