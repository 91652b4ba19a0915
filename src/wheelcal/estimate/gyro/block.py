"""The gyroscope's calibration, a by-product of the wheel: scale and axis along it, biases.

The gyro reads ω_meas = w ω(t) + b + G_X a_X + G_Y a_Y
(:class:`~wheelcal.model.effects.GyroReading`) with w = k u.  Reported: the
scale k = |w| along the wheel axis, the axis u in
the gyro's own frame, the biases b, each with σ (k and u by the delta
method: ∂k/∂w = u, ∂u/∂w = (I − u uᵀ)/k), and the angle between u and the
ideal −R e_Z — a diagnostic of the gyro-to-accelerometer misalignment and
per-axis scale errors, never a constraint on R.  Only one gyro axis (the
wheel's) is excited, so the gyro's other scales and its misalignment are
*not* calibrated.

Two sources: the joint fit itself when the gyro was fitted with the
accelerometer (driven motion, ``--gyro on``), or — when ``--gyro auto`` kept
the free spin's cubic — a regression of the gyro on the fitted ω(t), with the
gyro's own AR noise model (σ conditional on the fitted spin, whose own
uncertainty is far smaller).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint import (
    CalibrationResult,
    GyroRests,
    NoiseModel,
    accumulate_gyro,
    gyro_effect,
    gyro_prediction,
    scaled_pinv,
)
from wheelcal.model import (
    G_SENSITIVITY_PRIOR_DPS_PER_G,
    CalibrationParams,
    GyroReading,
    ParameterLayout,
    wheel_kinematics,
)

#: A typical MEMS gyro's sensitivity to linear acceleration (MPU-9250: 0.1 °/s/g).
G_SENSITIVITY_DPS_PER_G = G_SENSITIVITY_PRIOR_DPS_PER_G


@dataclass(frozen=True, eq=False)
class GyroCalibration:
    """Scale, axis and biases of the gyroscope, with σ."""

    scale: float
    scale_std: float
    axis: np.ndarray
    axis_std: np.ndarray
    bias_radps: np.ndarray
    bias_std_radps: np.ndarray
    axis_angle_deg: float
    residual_rms_radps: np.ndarray
    source: str
    #: Systematic σ of the bias: an unmodelled sensitivity to linear acceleration
    #: (datasheet-typical G) times the mean specific force of this bench.
    bias_systematic_std_radps: np.ndarray
    #: G R e_X and G R e_Y (rad/s per m/s², gyro axes) with σ, when fitted.
    g_sensitivity: np.ndarray | None = None
    g_sensitivity_std: np.ndarray | None = None
    #: The residual's once-per-turn amplitude per gyro axis (rad/s): what an
    #: imbalance's rate ripple or a larger sensitivity to acceleration would leave.
    once_per_turn_radps: np.ndarray | None = None
    #: σ of the prior on G (rad/s per m/s²), when there is one.
    g_prior_std: float | None = None
    #: How many rests' gyro readings the joint fit used (estimate/joint/gyro_rests.py);
    #: None for a regression on the fitted rate.
    rests_used: int | None = None
    #: The reading's parameters (w, b, then G_X, G_Y when fitted) and their covariance:
    #: what the pooled gyro fit over several mountings needs (closedloop/gyro_matrix.py).
    reading_values: np.ndarray | None = None
    reading_covariance: np.ndarray | None = None
    reading_names: tuple[str, ...] = ()
    #: g of the fit: b is the reading at zero rate with G R e_Z · g cos α in it.
    gravity_mps2: float | None = None
    #: The wheel axis d = −R e_Z in the accelerometer's frame (what w = M d measures M
    #: along) and its σ from R's covariance.
    wheel_axis: np.ndarray | None = None
    wheel_axis_std: np.ndarray | None = None

    def to_dict(self) -> dict:
        """The calibration JSON's ``gyro`` block."""
        return {
            "scale": self.scale,
            "scale_std": self.scale_std,
            "axis": self.axis.tolist(),
            "axis_std": self.axis_std.tolist(),
            "bias_radps": self.bias_radps.tolist(),
            "bias_std_radps": self.bias_std_radps.tolist(),
            "bias_systematic_std_radps": self.bias_systematic_std_radps.tolist(),
            "g_sensitivity_assumed_dps_per_g": G_SENSITIVITY_DPS_PER_G,
            **(
                {
                    "g_sensitivity_radps_per_mps2": {
                        "along_X": self.g_sensitivity[:3].tolist(),
                        "along_Y": self.g_sensitivity[3:].tolist(),
                    },
                    "g_sensitivity_std_radps_per_mps2": {
                        "along_X": self.g_sensitivity_std[:3].tolist(),
                        "along_Y": self.g_sensitivity_std[3:].tolist(),
                    },
                }
                if self.g_sensitivity is not None
                else {}
            ),
            "axis_angle_to_wheel_axis_deg": self.axis_angle_deg,
            "residual_rms_radps": self.residual_rms_radps.tolist(),
            **(
                {"residual_once_per_turn_radps": self.once_per_turn_radps.tolist()}
                if self.once_per_turn_radps is not None
                else {}
            ),
            **(
                {"g_sensitivity_prior_std_radps_per_mps2": self.g_prior_std}
                if self.g_prior_std is not None
                else {}
            ),
            **({"rests_used": self.rests_used} if self.rests_used is not None else {}),
            **self._reading_dict(),
            **(
                {
                    "wheel_axis_in_sensor_frame": self.wheel_axis.tolist(),
                    "wheel_axis_std": self.wheel_axis_std.tolist(),
                }
                if self.wheel_axis is not None
                else {}
            ),
            "source": self.source,
            "calibrated": "scale along the wheel axis, the axis direction, the three biases",
            "note": "u is free: it tilts from −R·e_Z by the gyro's own misalignment and "
            "per-axis scale errors; the gyro's other scales are not excited by the wheel. The "
            "bias is the reading at zero rate on this bench: a gyro's sensitivity to linear "
            "acceleration times the bench's mean specific force adds to it (systematic σ)",
        }

    def _reading_dict(self) -> dict:
        """``reading``: w, b, G_X, G_Y with their full covariance (additive; pooled fits use it)."""
        if self.reading_values is None or self.reading_covariance is None:
            return {}
        return {
            "reading": {
                "equation": "reading = w * omega + b + gx * a_X + gy * a_Y (bench-frame force a)",
                "names": list(self.reading_names),
                "values": self.reading_values.tolist(),
                "covariance": self.reading_covariance.tolist(),
                **({"gravity_mps2": self.gravity_mps2} if self.gravity_mps2 is not None else {}),
            }
        }


def _wheel_axis(result: CalibrationResult) -> tuple[np.ndarray, np.ndarray]:
    """The wheel axis d = −R e_Z in the accelerometer's frame, and its σ (from R's covariance).

    R → R exp([δ]×) turns d by R [e_Z]× δ, and the angles by ε = J δ
    (:meth:`~wheelcal.model.Rotation.euler_jacobian_deg`).
    """
    from wheelcal.model import hat

    rotation = result.params.bench.misalignment
    names = [f"euler_{k}_deg" for k in (1, 2, 3)]
    index = [result.names.index(n) for n in names]
    cov_deg2 = result.covariance[np.ix_(index, index)]
    turn = (
        rotation.matrix
        @ hat(np.array([0.0, 0.0, 1.0]))
        @ np.linalg.inv(rotation.euler_jacobian_deg())
    )
    cov = turn @ cov_deg2 @ turn.T
    return -rotation.matrix[:, 2], np.sqrt(np.maximum(np.diag(cov), 0.0))


def _mean_force_mps2(result: CalibrationResult) -> float:
    """|mean specific force| over the fitted window, in the sensor's axes."""
    from wheelcal.model import evaluate

    sensed = evaluate(result.params, result.centred_time_s, result.layout).sensed_mps2
    return float(np.linalg.norm(np.mean(sensed, axis=0)))


def _once_per_turn(theta_rad: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """Amplitude of the residual's first wheel harmonic per axis (least squares on cos, sin)."""
    basis = np.column_stack([np.cos(theta_rad), np.sin(theta_rad), np.ones_like(theta_rad)])
    coef, *_ = np.linalg.lstsq(basis, residual, rcond=None)
    return np.hypot(coef[0], coef[1])


def _calibration(
    values,
    cov,
    rotation,
    residual,
    source,
    mean_force,
    theta_rad=None,
    reading=None,
    gravity_mps2=None,
) -> GyroCalibration:
    values = np.asarray(values, float)
    w, b = values[:3], values[3:6]
    k = float(np.linalg.norm(w))
    u = w / k
    cov_w = cov[:3, :3]
    j_axis = (np.eye(3) - np.outer(u, u)) / k
    ideal = -rotation[:, 2]
    angle = float(np.rad2deg(np.arccos(np.clip(u @ ideal, -1.0, 1.0))))
    return GyroCalibration(
        scale=k,
        scale_std=float(np.sqrt(max(u @ cov_w @ u, 0.0))),
        axis=u,
        axis_std=np.sqrt(np.maximum(np.diag(j_axis @ cov_w @ j_axis.T), 0.0)),
        bias_radps=b,
        bias_std_radps=np.sqrt(np.maximum(np.diag(cov[3:6, 3:6]), 0.0)),
        axis_angle_deg=angle,
        residual_rms_radps=np.sqrt(np.mean(residual**2, axis=0)),
        source=source,
        bias_systematic_std_radps=np.full(
            3, G_SENSITIVITY_DPS_PER_G * np.pi / 180 / 9.80665 * mean_force
        ),
        g_sensitivity=values[6:12] if values.size == 12 else None,
        g_sensitivity_std=(
            np.sqrt(np.maximum(np.diag(cov[6:12, 6:12]), 0.0)) if values.size == 12 else None
        ),
        once_per_turn_radps=None if theta_rad is None else _once_per_turn(theta_rad, residual),
        g_prior_std=None if reading is None else reading.g_prior_std_radps_per_mps2,
        reading_values=values.copy(),
        reading_covariance=np.array(cov, dtype=float),
        reading_names=tuple(reading.param_names) if reading is not None else (),
        gravity_mps2=gravity_mps2,
    )


def gyro_from_fit(
    result: CalibrationResult, gyro_t: np.ndarray, gyro: np.ndarray
) -> GyroCalibration:
    """The gyro block of a joint fit that included the gyro."""
    effect = gyro_effect(result.layout)
    index = [result.names.index(f"gyro.{n}") for n in effect.param_names]
    values = result.values[index]
    cov = result.covariance[np.ix_(index, index)]
    residual = gyro - gyro_prediction(result.params, gyro_t, result.layout)
    rotation = result.params.bench.misalignment.matrix
    theta = wheel_kinematics(result.params, gyro_t, result.layout.effects).theta_rad
    block = _calibration(
        values,
        cov,
        rotation,
        residual,
        "joint fit",
        _mean_force_mps2(result),
        theta,
        effect,
        result.params.gravity_mps2,
    )
    rests = result.gyro_rests
    axis, axis_std = _wheel_axis(result)
    return dataclasses.replace(
        block,
        rests_used=0 if rests is None else rests.count,
        wheel_axis=axis,
        wheel_axis_std=axis_std,
    )


@dataclass(frozen=True, eq=False)
class GyroRegression:
    """The gyro's reading fitted on a given wheel rate: layout, parameters, noise, σ."""

    layout: ParameterLayout  # the fit's, with the reading last
    params: CalibrationParams  # the fit's, with the reading's values
    noise: NoiseModel  # the gyro residual's AR model
    covariance: np.ndarray  # of the reading's parameters (conditional on the wheel rate)
    residual_radps: np.ndarray  # gyro − prediction (N, 3)


def regress_gyro(
    result: CalibrationResult,
    gyro_t: np.ndarray,
    gyro: np.ndarray,
    max_ar_order: int = 10,
    reading: GyroReading | None = None,
    rests: GyroRests | None = None,
) -> GyroRegression:
    """The gyro's reading (w, b, G with its prior) by regression on the fitted ω(t).

    The start is the least-squares regression
    (:func:`~wheelcal.estimate.joint.fit.with_gyro_start`), then one Gauss–Newton step of
    the whitened problem with the prior on G (the problem is linear in the reading's
    parameters).  ``rests``: the gyro's readings at the rests
    (:class:`~wheelcal.estimate.joint.gyro_rests.GyroRests`), regressed on too.
    """
    from wheelcal.estimate.joint import with_gyro_start

    reading = reading or GyroReading()
    layout = ParameterLayout(
        spin_degree=result.layout.spin_degree,
        fit_tilt=result.layout.fit_tilt,
        fit_radius=result.layout.fit_radius,
        effects=(*result.layout.effects, reading),
    )
    params = with_gyro_start(result.params, layout, gyro_t, gyro)
    residual = gyro - gyro_prediction(params, gyro_t, layout)
    noise = NoiseModel.estimate(residual, max_ar_order)
    normal = accumulate_gyro(params, gyro_t, gyro, layout, noise, rests=rests)
    block = layout.blocks[f"effect:{reading.name}"]
    cov = scaled_pinv(normal.hessian[block, block])
    values = params.effect(reading.name, reading.size) - cov @ normal.gradient[block]
    params = params.with_changes(effects={**params.effects, reading.name: values})
    residual = gyro - gyro_prediction(params, gyro_t, layout)
    return GyroRegression(layout, params, noise, cov, residual)


def gyro_by_product(
    result: CalibrationResult,
    gyro_t: np.ndarray,
    gyro: np.ndarray,
    max_ar_order: int = 10,
    reading: GyroReading | None = None,
) -> GyroCalibration:
    """The gyro block by regression on the fitted ω(t) (the fit did not use the gyro)."""
    fitted = regress_gyro(result, gyro_t, gyro, max_ar_order, reading)
    reading = gyro_effect(fitted.layout)
    values = fitted.params.effect(reading.name, reading.size)
    cov, residual = fitted.covariance, fitted.residual_radps
    block = _calibration(
        values,
        cov,
        result.params.bench.misalignment.matrix,
        residual,
        "regression on the fitted wheel rate (the free spin's cubic was kept)",
        _mean_force_mps2(result),
        wheel_kinematics(result.params, gyro_t, result.layout.effects).theta_rad,
        reading,
        result.params.gravity_mps2,
    )
    axis, axis_std = _wheel_axis(result)
    return dataclasses.replace(block, wheel_axis=axis, wheel_axis_std=axis_std)
