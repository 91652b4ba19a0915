"""A Cramér–Rao bound computed independently of wheelcal's Fisher and covariance code.

The accuracy tests judge the estimator against the CRLB at the truth.  If that
bound came from the code under test (the analytic Jacobian of
``wheelcal.model.forward``, the whitening of ``wheelcal.estimate.joint.noise_model``,
the inversion of ``wheelcal.estimate.joint.information``, the reporting transform),
an error there would move the yardstick with the thing measured.  Here only
the model's *prediction* v(x) (eq. 6) is used — itself checked against physics
by tests/physics_oracle.py — and everything else is redone from first
principles:

* parameters are perturbed directly in the *reported* coordinates (ϑ₀, ω_k,
  tilt in degrees, ZYX Euler angles in degrees built by scipy, gains,
  offsets), so no reporting transform is needed;
* ∂v/∂x by the 4th-order central difference (−v₊₂ + 8v₊₁ − 8v₋₁ + v₋₂)/(12h);
* the Gaussian likelihood of the simulator's noise: white with σ per axis
  (F = Σ JᵀJ/σ²), or per axis the stationary AR process A(z) x = e — exactly:
  the first p samples with their stationary covariance (autocovariance from the
  impulse response of 1/A), the rest through the innovation filter A(z), whose
  output is white with σ_e² = σ²/Σh_j²;
* the covariance is numpy's (pseudo-)inverse of the diagonally scaled Fisher matrix.

The scenario's bounds are cached (one per truth, sampling plan and noise).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal
from scipy.linalg import toeplitz
from scipy.spatial.transform import Rotation as SciRotation

from wheelcal.model import BenchParams, CalibrationParams, Rotation, SensorParams, SpinParams
from wheelcal.model import predict as model_predict


@dataclass(frozen=True, eq=False)
class IndependentBound:
    """Covariance bound on the reported parameters, by name."""

    names: tuple[str, ...]
    values: np.ndarray
    covariance: np.ndarray
    fisher: np.ndarray  # in the reported coordinates

    @property
    def std(self) -> np.ndarray:
        """One-sigma bound per parameter."""
        return np.sqrt(np.diag(self.covariance))

    def std_of(self, name: str) -> float:
        """One-sigma bound of one named parameter."""
        return float(self.std[self.names.index(name)])

    def as_dict(self) -> dict[str, float]:
        """Name → σ."""
        return dict(zip(self.names, map(float, self.std), strict=True))


def reported_names(spin_degree: int) -> tuple[str, ...]:
    """The CONTRACT's names, in the order wheelcal reports them."""
    omegas = tuple(f"omega{k}_radps" + (str(k + 1) if k else "") for k in range(spin_degree + 1))
    return (
        "theta0_rad",
        *omegas,
        "tilt_deg",
        "euler_1_deg",
        "euler_2_deg",
        "euler_3_deg",
        *(f"gain_{a}" for a in "xyz"),
        *(f"offset_{a}_mps2" for a in "xyz"),
    )


def truth_vector(truth: CalibrationParams) -> np.ndarray:
    """The truth in reported coordinates (Euler angles from the matrix by scipy)."""
    euler = SciRotation.from_matrix(truth.bench.misalignment.matrix).as_euler("ZYX", degrees=True)
    return np.concatenate(
        [
            [truth.spin.theta0_rad],
            truth.spin.omega_radps,
            [np.rad2deg(truth.bench.tilt_rad)],
            euler,
            truth.sensor.gain,
            truth.sensor.offset_mps2,
        ]
    )


def _params(x: np.ndarray, truth: CalibrationParams) -> CalibrationParams:
    k = truth.spin.omega_radps.size
    rot = SciRotation.from_euler("ZYX", x[k + 2 : k + 5], degrees=True).as_matrix()
    return CalibrationParams(
        spin=SpinParams(x[0], x[1 : k + 1]),
        bench=BenchParams(np.deg2rad(x[k + 1]), truth.bench.radius_m, Rotation(rot)),
        sensor=SensorParams(offset_mps2=x[k + 8 : k + 11], gain=x[k + 5 : k + 8]),
        gravity_mps2=truth.gravity_mps2,
        effects=truth.effects,
    )


def _steps(x: np.ndarray, half_window_s: float) -> np.ndarray:
    """Finite-difference steps: ~1e-5 rad of wheel angle at the window's end, 1e-4° etc."""
    k = x.size - 11
    spin = [1e-5] + [1e-5 * (j + 1) / half_window_s ** (j + 1) for j in range(k)]
    return np.array([*spin, 1e-4, 1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6, 1e-5, 1e-5, 1e-5])


def _effect_steps(effect) -> np.ndarray:
    """Steps for an effect's parameters (all enter linearly or nearly so)."""
    if effect.name == "gyro":  # w (~1), bias (rad/s), G (rad/s per m/s², ~2e-4)
        return np.array([1e-6] * 6 + [1e-8] * (effect.size - 6))
    if effect.name == "imbalance":
        return np.full(effect.size, 1e-4)
    return np.full(effect.size, 1e-5)  # spline coefficients (rad) and others


def finite_difference_jacobian(
    truth: CalibrationParams,
    t_s: np.ndarray,
    effects: tuple = (),
    free_effects: tuple = (),
    predict=model_predict,
) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """Names, truth values and ∂v/∂x (P, N, 3 or 6) by central differences of the prediction.

    ``effects`` are held at their true values; ``free_effects`` are fitted (their
    parameters follow the paper's, named ``<effect>.<parameter>``).  A free
    :class:`~wheelcal.model.effects.GyroReading` adds the gyro stream: columns
    3–5 of the last axis are its predicted reading w ω + b + G_X a_X + G_Y a_Y,
    with ω and a of the model at the perturbed parameters.
    """
    from wheelcal.model import evaluate

    x_paper = truth_vector(truth)
    size = x_paper.size
    gyro = next((e for e in free_effects if e.name == "gyro"), None)
    in_model = tuple(e for e in (*effects, *free_effects) if e.name != "gyro")
    x0 = np.concatenate([x_paper, *(truth.effect(e.name, e.size) for e in free_effects)])
    steps = np.concatenate(
        [_steps(x_paper, float(np.max(np.abs(t_s)))), *(_effect_steps(e) for e in free_effects)]
    )
    names = reported_names(truth.spin.degree) + tuple(
        f"{e.name}.{p}" for e in free_effects for p in e.param_names
    )

    def stream(x: np.ndarray) -> np.ndarray:
        values, start = dict(truth.effects), size
        for e in free_effects:
            values[e.name] = x[start : start + e.size]
            start += e.size
        params = _params(x[:size], truth).with_changes(effects=values)
        if gyro is None:
            return predict(params, t_s, effects=in_model)
        out = evaluate(params, t_s, effects=in_model)
        reading = gyro.reading(values["gyro"], out.kinematics.omega_radps, out.force.accel_mps2)
        return np.concatenate([out.predicted_mps2, reading], axis=1)

    jac = np.empty((x0.size, t_s.size, 3 if gyro is None else 6))
    for p, h in enumerate(steps):
        v = {}
        # 4th order for the paper's parameters; 2nd order (error ~h², 1e-10 here) for the
        # effects', which enter (nearly) linearly and may be many (a spline's).
        stencil = (-2, -1, 1, 2) if p < size else (-1, 1)
        for m in stencil:
            x = x0.copy()
            x[p] += m * h
            v[m] = stream(x)
        if p < size:
            jac[p] = (v[-2] - 8 * v[-1] + 8 * v[1] - v[2]) / (12 * h)
        else:
            jac[p] = (v[1] - v[-1]) / (2 * h)
    return names, x0, jac


def impulse_response(ar_polynomial: np.ndarray, length: int = 20_000) -> np.ndarray:
    """h_j of 1/A(z) (the AR process's MA(∞) weights)."""
    delta = np.zeros(length)
    delta[0] = 1.0
    return signal.lfilter([1.0], ar_polynomial, delta)


def whiten_columns(columns: np.ndarray, marginal_std: float, ar_polynomial) -> np.ndarray:
    """Columns (P, N) → L⁻¹ columns with L Lᵀ the exact noise covariance of one axis.

    White noise: divide by σ.  AR(p): the first p samples through the Cholesky
    factor of their stationary covariance, the rest as innovations e_n = A(z) x_n
    divided by σ_e — the exact Gaussian likelihood of a stationary AR process.
    """
    a = np.asarray(ar_polynomial if ar_polynomial is not None else [1.0], dtype=float)
    if a.size == 1:
        return columns / marginal_std
    p = a.size - 1
    h = impulse_response(a)
    sigma_e = marginal_std / np.sqrt(np.sum(h**2))
    autocov = np.array([sigma_e**2 * np.sum(h[: h.size - k] * h[k:]) for k in range(p)])
    chol = np.linalg.cholesky(toeplitz(autocov))
    head = np.linalg.solve(chol, columns[:, :p].T).T
    tail = signal.lfilter(a, [1.0], columns, axis=1)[:, p:] / sigma_e
    return np.concatenate([head, tail], axis=1)


def independent_crlb(
    truth: CalibrationParams,
    t_s: np.ndarray,
    std_mps2,
    ar_polynomial=None,
    effects: tuple = (),
    free_effects: tuple = (),
    gyro_std_radps: float | None = None,
) -> IndependentBound:
    """CRLB of the paper's parameters (and ``free_effects``') at ``truth`` for samples at ``t_s``.

    ``std_mps2``: marginal noise std per axis (or one number); ``ar_polynomial``:
    ``None`` (white) or A(z) = [1, a₁, …] of each axis's stationary AR noise.
    ``effects`` present in the truth (their values in ``truth.effects``) are
    held at their true values, not fitted.  With a GyroReading among
    ``free_effects`` the gyro stream (white noise ``gyro_std_radps`` per axis,
    independent of the accelerometer's) adds its information.
    """
    t = np.asarray(t_s, dtype=float)
    names, x0, jac = finite_difference_jacobian(truth, t, effects, free_effects)
    std = np.broadcast_to(np.asarray(std_mps2, dtype=float), (3,))
    fisher = np.zeros((x0.size, x0.size))
    for axis in range(3):
        jw = whiten_columns(jac[:, :, axis], std[axis], ar_polynomial)
        fisher += jw @ jw.T
    if jac.shape[2] == 6:
        if gyro_std_radps is None:
            raise ValueError("a fitted gyro needs gyro_std_radps")
        g = jac[:, :, 3:].reshape(x0.size, -1) / gyro_std_radps
        fisher += g @ g.T
    # numpy's (pseudo-)inverse of the diagonally scaled matrix: the inverse when F is
    # regular; with a free spline the polynomial's low coefficients are redundant with it,
    # and the bound of the identifiable parameters is the pseudo-inverse's.
    scale = np.sqrt(np.diag(fisher))
    cov = np.linalg.pinv(fisher / np.outer(scale, scale), rcond=1e-12, hermitian=True)
    cov /= np.outer(scale, scale)
    return IndependentBound(names=names, values=x0, covariance=cov, fisher=fisher)


def butterworth_ar(bandwidth_hz: float | None, rate_hz: float) -> np.ndarray | None:
    """A(z) of the simulator's band-limited noise: the poles of a 2nd-order Butterworth.

    ``None`` (white) without a bandwidth or at/above 0.45 × the rate, as the
    simulator documents (wheelcal.simulate.noise).
    """
    if bandwidth_hz is None or bandwidth_hz >= 0.45 * rate_hz:
        return None
    _, a = signal.butter(2, bandwidth_hz, fs=rate_hz)
    return a / a[0]


def scenario_crlb(scenario) -> IndependentBound:
    """Independent CRLB at a scenario's truth over its whole recording (cached)."""
    if scenario.motion is not None or scenario.vibration is not None:
        raise ValueError("the independent bound covers eq. (2) spins with sensor noise only")
    truth = scenario.truth
    key = (
        tuple(truth_vector(truth)),
        truth.bench.radius_m,
        truth.gravity_mps2,
        tuple((n, tuple(v)) for n, v in sorted(truth.effects.items())),
        scenario.duration_s,
        scenario.rate_hz,
        tuple(scenario.noise.std),
        scenario.noise.bandwidth_hz,
    )
    return _lookup(key, scenario)


_CACHE: dict[tuple, IndependentBound] = {}


def _lookup(key: tuple, scenario) -> IndependentBound:
    if key not in _CACHE:
        noise = scenario.noise
        _CACHE[key] = independent_crlb(
            scenario.truth,
            scenario.centred_times_s(),
            noise.std,
            butterworth_ar(noise.bandwidth_hz, scenario.rate_hz),
            scenario.effects,
        )
    return _CACHE[key]
