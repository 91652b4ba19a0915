"""A simulated MEMS gyroscope on the accelerometer's clock.

Physics (CONTRACT bench frame: Z the wheel axis, X radial from the sensor to
the axle, Y = Z × X the direction of increasing ϑ).  The sensor sits at
p = −r X and moves with velocity ṗ = r ω Y.  A rigid rotation Ω gives
ṗ = Ω × p, and with Ω = c Z: Ω × (−r X) = −r c (Z × X) = −r c Y, so c = −ω:

    Ω = −ω e_Z        (bench frame; ω = dϑ/dt, signed)

The bench frame turns with the wheel, so this is also the body rate in the
bench axes, and in the sensor's axes (R maps bench → sensor) an ideal gyro
reads ``−ω R e_Z``.  (A test checks this sign by finite rotations of the
bench frame, independently of :mod:`wheelcal.model`.)

The gyro's own errors (typical of a consumer MEMS part such as the paper's
MPU-9250) make the reading

    ω_meas = (I + diag(k)) · (I + N) · Q · (−ω R e_Z) + G · (R a) / g₀ + b + n

then saturated at ±full scale and, optionally, rounded to ``bits`` counts.
The gyro's response matrix (:attr:`GyroSpec.response_matrix`, the full M of
the pooled gyro calibration, reading = M ω + b) is K = (I + diag(k)) (I + N) Q:

* k — per-axis scale errors (``scale_error``);
* N — the gyro's axes not orthogonal to each other (``non_orthogonality_deg``:
  (n_yx, n_zx, n_zy), strictly lower triangular, the gyro's y axis leaning
  towards its x by n_yx, its z towards x and y by n_zx, n_zy — Kalibr's
  lower-triangular ``M`` of the ``scale-misalignment`` model is (I + diag(k))(I + N));
* Q = exp([m]×) — the gyro's (orthogonalised) axes slightly rotated from the
  accelerometer's (``misalignment_deg``, a rotation vector in degrees; Kalibr's
  ``C_gyro_i``);
* G — sensitivity to linear acceleration, (°/s)/g (``g_sensitivity_dps_per_g``,
  a scalar for G = k·I or a 3×3 matrix); R a is the specific force in the
  sensor axes and g₀ = 9.80665 m/s².  Gravity turning through the sensor once
  per turn makes it a once-per-turn ripple on ω, like a small imbalance;
* b — bias (``bias_radps``);
* n — white noise of density ``noise_density_dps_rthz`` (°/s/√Hz), so the
  per-sample std is density · √(f_s / 2) (the Nyquist band).

Only the component along the wheel axis is excited by the motion: the
reading is ``k_w · u · ω + b + G·(R a)/g₀ + n`` with the wheel-axis response
``(k_w, u)`` of :meth:`GyroSpec.wheel_axis_response`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model import STANDARD_GRAVITY_MPS2

RADPS_PER_DPS = np.pi / 180.0


def _vector(value, name: str) -> tuple[float, float, float]:
    v = np.broadcast_to(np.asarray(value, dtype=float), (3,))
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be finite, got {value}")
    return tuple(float(x) for x in v)


def _rotation(rotvec_rad: np.ndarray) -> np.ndarray:
    """exp([m]×) by Rodrigues' formula."""
    angle = float(np.linalg.norm(rotvec_rad))
    if angle == 0.0:
        return np.eye(3)
    k = rotvec_rad / angle
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


@dataclass(frozen=True)
class GyroSpec:
    """A MEMS gyroscope's errors and output stage (see the module docstring for the model).

    Defaults are a typical MPU-9250-class part set to its ±2000 °/s range
    (the chip's power-on range, ±250 °/s = 4.36 rad/s, clips a hand-spun
    wheel: pass ``full_scale_dps=250`` to simulate that).

    Parameters
    ----------
    noise_density_dps_rthz:
        White rate noise, (°/s)/√Hz (MPU-9250: 0.01).
    bias_radps:
        Constant bias b per axis, rad/s.
    scale_error:
        Per-axis relative scale errors k (0.01 = +1 %).
    misalignment_deg:
        Rotation vector m (degrees) of the gyro's axes from the accelerometer's.
    non_orthogonality_deg:
        (n_yx, n_zx, n_zy), degrees: the gyro's axes' departure from orthogonal
        (the strictly lower-triangular N of the module docstring; default none).
    g_sensitivity_dps_per_g:
        Linear-acceleration sensitivity, (°/s)/g: a scalar (each axis to the
        acceleration along itself) or a 3×3 matrix (row: gyro axis).
    full_scale_dps:
        Range ±full scale, °/s; readings saturate there.  ``None``: no limit.
    bits:
        ``None`` for a float output; else round to counts of
        2·full_scale / 2**bits (two's complement: the top rail is one count
        below +full scale).  Needs ``full_scale_dps``.
    bias_walk_dps_per_sqrt_s:
        The bias's random walk, (°/s)/√s per axis (a factory-calibrated IMU's in-run
        instability: ~0.003; 0: none).
    bias_warmup_dps, bias_warmup_tau_s:
        A warm-up of the bias per axis, b(t) = b + d (1 − e^(−t/τ)) from the first
        sample (the chip's temperature settling; 0: none).
    """

    noise_density_dps_rthz: float = 0.01
    bias_radps: tuple[float, float, float] = (0.012, -0.021, 0.008)
    scale_error: tuple[float, float, float] = (0.008, -0.012, 0.015)
    misalignment_deg: tuple[float, float, float] = (1.0, -1.2, 0.5)
    g_sensitivity_dps_per_g: float | tuple = 0.1
    full_scale_dps: float | None = 2000.0
    bits: int | None = None
    bias_walk_dps_per_sqrt_s: float = 0.0
    bias_warmup_dps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    bias_warmup_tau_s: float = 300.0
    non_orthogonality_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.noise_density_dps_rthz) and self.noise_density_dps_rthz >= 0):
            raise ValueError("noise_density_dps_rthz must be finite and >= 0")
        object.__setattr__(self, "bias_radps", _vector(self.bias_radps, "bias_radps"))
        object.__setattr__(self, "scale_error", _vector(self.scale_error, "scale_error"))
        object.__setattr__(
            self, "misalignment_deg", _vector(self.misalignment_deg, "misalignment_deg")
        )
        object.__setattr__(
            self,
            "non_orthogonality_deg",
            _vector(self.non_orthogonality_deg, "non_orthogonality_deg"),
        )
        sens = np.asarray(self.g_sensitivity_dps_per_g, dtype=float)
        if sens.ndim == 0:
            sens = float(sens) * np.eye(3)
        if sens.shape != (3, 3) or not np.all(np.isfinite(sens)):
            raise ValueError("g_sensitivity_dps_per_g must be a finite scalar or 3×3 matrix")
        object.__setattr__(
            self, "g_sensitivity_dps_per_g", tuple(tuple(float(x) for x in row) for row in sens)
        )
        if self.full_scale_dps is not None and not self.full_scale_dps > 0:
            raise ValueError("full_scale_dps must be positive (or None)")
        if self.bits is not None and (self.full_scale_dps is None or not 2 <= self.bits <= 32):
            raise ValueError("bits needs full_scale_dps and must be in 2..32")
        object.__setattr__(
            self, "bias_warmup_dps", _vector(self.bias_warmup_dps, "bias_warmup_dps")
        )
        if not (np.isfinite(self.bias_walk_dps_per_sqrt_s) and self.bias_walk_dps_per_sqrt_s >= 0):
            raise ValueError("bias_walk_dps_per_sqrt_s must be finite and >= 0")
        if not self.bias_warmup_tau_s > 0:
            raise ValueError("bias_warmup_tau_s must be positive")

    def _bias_motion(self, n: int, rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        """(n, 3): the bias's warm-up and random walk (rad/s; drawn only if it walks)."""
        out = np.zeros((n, 3))
        warmup = np.deg2rad(np.asarray(self.bias_warmup_dps))
        if np.any(warmup):
            t = np.arange(n) / rate_hz
            out += np.outer(1.0 - np.exp(-t / self.bias_warmup_tau_s), warmup)
        if self.bias_walk_dps_per_sqrt_s > 0:
            step = np.deg2rad(self.bias_walk_dps_per_sqrt_s) / np.sqrt(rate_hz)
            out += np.cumsum(step * rng.standard_normal((n, 3)), axis=0)
        return out

    @classmethod
    def ideal(cls) -> GyroSpec:
        """A perfect gyro: no noise, bias, scale, misalignment, g-sensitivity or range."""
        return cls(0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, None, None)

    @classmethod
    def device(
        cls,
        rng: np.random.Generator,
        scale_error_std: float = 0.01,
        misalignment_std_deg: float = 1.0,
        non_orthogonality_std_deg: float = 0.3,
        bias_std_radps: float = 0.02,
        g_sensitivity_std_dps_per_g: float = 0.1,
        **fixed,
    ) -> GyroSpec:
        """One consumer MEMS gyro with its own drawn errors (each normal with these σ).

        Every device differs: its scale errors, axis misalignment and
        non-orthogonality (the full response matrix), bias and each entry of its
        3×3 sensitivity to linear acceleration are drawn from ``rng``; ``fixed``
        sets other fields (noise density, range) as given.
        """
        return cls(
            bias_radps=tuple(rng.normal(0.0, bias_std_radps, 3)),
            scale_error=tuple(rng.normal(0.0, scale_error_std, 3)),
            misalignment_deg=tuple(rng.normal(0.0, misalignment_std_deg, 3)),
            non_orthogonality_deg=tuple(rng.normal(0.0, non_orthogonality_std_deg, 3)),
            g_sensitivity_dps_per_g=tuple(
                map(tuple, rng.normal(0.0, g_sensitivity_std_dps_per_g, (3, 3)))
            ),
            **fixed,
        )

    @property
    def misalignment_matrix(self) -> np.ndarray:
        """Q = exp([m]×), accelerometer axes → the gyro's orthogonalised axes."""
        return _rotation(np.deg2rad(np.asarray(self.misalignment_deg)))

    @property
    def non_orthogonality_matrix(self) -> np.ndarray:
        """I + N, N strictly lower triangular from (n_yx, n_zx, n_zy)."""
        n_yx, n_zx, n_zy = np.deg2rad(np.asarray(self.non_orthogonality_deg))
        return np.array([[1.0, 0.0, 0.0], [n_yx, 1.0, 0.0], [n_zx, n_zy, 1.0]])

    @property
    def response_matrix(self) -> np.ndarray:
        """K = (I + diag(k)) (I + N) Q: true body rate in the accelerometer's axes → reading."""
        scale = (1.0 + np.asarray(self.scale_error))[:, None]
        return scale * (self.non_orthogonality_matrix @ self.misalignment_matrix)

    @property
    def g_sensitivity_radps_per_mps2(self) -> np.ndarray:
        """G in (rad/s)/(m/s²), 3×3."""
        return np.asarray(self.g_sensitivity_dps_per_g) * RADPS_PER_DPS / STANDARD_GRAVITY_MPS2

    def noise_std_radps(self, rate_hz: float) -> float:
        """Per-sample white-noise std, rad/s: density · √(f_s / 2)."""
        return self.noise_density_dps_rthz * RADPS_PER_DPS * float(np.sqrt(rate_hz / 2.0))

    @property
    def lsb_radps(self) -> float | None:
        """One count, rad/s (``None`` without quantisation)."""
        if self.bits is None:
            return None
        return 2.0 * self.full_scale_dps * RADPS_PER_DPS / 2**self.bits

    @property
    def limits_radps(self) -> tuple[float, float] | None:
        """Lowest and highest reading, rad/s (``None`` without a range)."""
        if self.full_scale_dps is None:
            return None
        if self.bits is None:
            fs = self.full_scale_dps * RADPS_PER_DPS
            return -fs, fs
        half = 2 ** (self.bits - 1)
        return -half * self.lsb_radps, (half - 1) * self.lsb_radps

    def wheel_axis_response(self, misalignment: np.ndarray) -> tuple[float, np.ndarray]:
        """The true (k_w, u) of ω_meas = k_w · u · ω + … for a sensor mounted with R.

        Parameters
        ----------
        misalignment:
            R (3×3, bench → accelerometer axes).

        Returns
        -------
        scale : float
            k_w = |(I + diag(k)) M (−R e_Z)| (1 for a perfect gyro).
        axis : ndarray (3,)
            The unit direction u, in the gyro's axes; a perfect gyro has u = −R e_Z.
        """
        column = self.response_matrix @ (-np.asarray(misalignment, dtype=float)[:, 2])
        scale = float(np.linalg.norm(column))
        return scale, column / scale

    def ideal_reading(self, omega_radps: np.ndarray, misalignment: np.ndarray) -> np.ndarray:
        """The perfect gyro's reading −ω R e_Z, shape (N, 3) — the sign convention in one line."""
        axis = -np.asarray(misalignment, dtype=float)[:, 2]
        return np.asarray(omega_radps, dtype=float)[:, None] * axis

    def output(
        self,
        omega_radps: np.ndarray,
        sensed_mps2: np.ndarray,
        misalignment: np.ndarray,
        rate_hz: float,
        rng: np.random.Generator,
        extra_rate_radps: np.ndarray | None = None,
    ) -> np.ndarray:
        """The gyro's readings (N, 3), rad/s, for the wheel rate and specific force at each sample.

        Parameters
        ----------
        omega_radps:
            ω(t) = dϑ/dt at each sample (signed), shape (N,).
        sensed_mps2:
            Specific force in the accelerometer's axes, R a, shape (N, 3) (the
            true one, before the accelerometer's own gain and offset).
        misalignment:
            R, bench → accelerometer axes.
        rate_hz:
            Sample rate (for the noise std).
        rng:
            The only source of randomness (one (N, 3) normal draw, if noisy).
        extra_rate_radps:
            Body rate besides the spin, bench frame (N, 3) — e.g. a rolling
            wheel's yaw ψ̇ u (:mod:`wheelcal.simulate.field_record`); ``None``: none.
        """
        ideal = self.ideal_reading(omega_radps, misalignment)
        if extra_rate_radps is not None:
            ideal = ideal + np.asarray(extra_rate_radps, dtype=float) @ np.asarray(misalignment).T
        rate = ideal @ self.response_matrix.T
        rate += np.asarray(sensed_mps2, dtype=float) @ self.g_sensitivity_radps_per_mps2.T
        rate += np.asarray(self.bias_radps)
        std = self.noise_std_radps(rate_hz)
        if std > 0:
            rate += std * rng.standard_normal(rate.shape)
        rate += self._bias_motion(rate.shape[0], rate_hz, rng)
        if self.bits is not None:
            rate = np.round(rate / self.lsb_radps) * self.lsb_radps
        limits = self.limits_radps
        if limits is not None:
            rate = np.clip(rate, *limits)
        return rate
