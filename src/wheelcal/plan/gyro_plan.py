"""How many mountings, and which, the gyroscope's full matrix needs — and its predicted σ.

A session sees the gyro's response M along one direction, the wheel axis
d = −R e_Z in the sensor frame (:mod:`wheelcal.closedloop.gyro_matrix`): one
mounting calibrates the scale along that axis, two a plane of M, and three
whose wheel axes are independent — near the sensor's x, y and z
(:func:`~wheelcal.simulate.mountings.mounting_near`, the plan's mounting with
its sensor axes relabelled) — all nine entries.

The prediction is the pooled fit's own covariance at the planned truth: per
mounting, the accelerometer's Cramér–Rao bound on R and α (the planner's
Fisher information at that mounting) and the gyro reading's information
(white noise of the gyro's density on the planned ω(t) and force, the G prior);
``sessions`` such sessions per mounting, pooled by
:func:`~wheelcal.closedloop.gyro_matrix.pool_gyro`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from wheelcal.closedloop import GyroMountingObservation, PooledGyro, geometry_covariance, pool_gyro
from wheelcal.estimate.joint import decimation_stride
from wheelcal.model import G_SENSITIVITY_PRIOR_DPS_PER_G, GyroReading, bench_force, spin_kinematics
from wheelcal.plan.bench_plan import PlannedSetup
from wheelcal.plan.fisher import bound_from_fisher, fisher_information
from wheelcal.simulate import GyroSpec, mounting_near

#: The mountings the full matrix needs: the wheel axis near each of the sensor's axes.
FULL_MATRIX_AXES = ("x", "y", "z")
_GEOMETRY = ("euler_1_deg", "euler_2_deg", "euler_3_deg", "tilt_deg")


@dataclass(frozen=True, eq=False)
class GyroPlan:
    """The mountings planned for the gyro's matrix and the σ the pooled fit will report."""

    axes: tuple[str, ...]
    mountings_euler_deg: tuple[tuple[float, float, float], ...]
    sessions_per_mounting: int
    noise_density_dps_rthz: float
    pooled: PooledGyro
    #: σ of the scale along the wheel axis from one session (what one mounting gives).
    one_session_scale_std: float

    @property
    def determined(self) -> bool:
        """All nine entries of M determined by these mountings."""
        return bool(np.all(np.isfinite(self.pooled.matrix)))

    def to_dict(self) -> dict:
        """JSON-ready."""

        def num(x):
            return float(x) if np.isfinite(x) else None

        return {
            "needs": "three mountings whose wheel axes are independent directions of the sensor "
            "(near its x, y and z)",
            "mountings": [
                {"wheel_axis_near": a, "euler_deg": list(e)}
                for a, e in zip(self.axes, self.mountings_euler_deg, strict=True)
            ],
            "sessions_per_mounting": self.sessions_per_mounting,
            "gyro_noise_density_dps_rthz": self.noise_density_dps_rthz,
            "matrix_std": [[num(v) for v in row] for row in self.pooled.matrix_std],
            "bias_std_radps": [num(v) for v in self.pooled.bias_std_radps],
            "undetermined": [{"parameter": p, "reason": r} for p, r in self.pooled.undetermined],
            "one_session_scale_std": self.one_session_scale_std,
        }

    def lines(self) -> list[str]:
        """The planner's text: what to mount, and what it will give."""
        out = [
            "its full 3x3 matrix needs 3 mountings with the wheel axis along three "
            "independent sensor directions (near x, y and z); one mounting calibrates only the "
            f"scale along its wheel axis (σ {self.one_session_scale_std:.2g} per session)",
        ]
        for axis, euler in zip(self.axes, self.mountings_euler_deg, strict=True):
            angles = ", ".join(f"{e:.1f}" for e in euler)
            out.append(f"  wheel axis near the sensor's {axis}: mounting (ZYX) {angles}°")
        if self.determined:
            worst = float(np.nanmax(self.pooled.matrix_std))
            bias = float(np.nanmax(self.pooled.bias_std_radps))
            out.append(
                f"  with {self.sessions_per_mounting} spin(s) each: σ of M's entries ≤ {worst:.2g},"
                f" of the bias ≤ {bias:.2g} rad/s"
            )
        else:
            out.append(f"  these mountings leave M undetermined: {self.pooled.undetermined[0][1]}")
        return out


def plan_gyro(
    setup: PlannedSetup,
    axes: Sequence[str] = FULL_MATRIX_AXES,
    sessions: int = 3,
    gyro: GyroSpec | None = None,
    stride: int | None = None,
) -> GyroPlan:
    """Predict the pooled gyro calibration of ``setup`` mounted near each of ``axes``."""
    if sessions < 1:
        raise ValueError(f"sessions must be >= 1, got {sessions}")
    gyro = gyro or GyroSpec()
    if stride is None:  # the accelerometer's bound on R: decimated, as the mounting search
        stride = decimation_stride(setup.rate_hz, setup.omega_start_radps)
    observations, eulers, scale_std = [], [], float("nan")
    for axis in axes:
        planned = setup.with_mounting(mounting_near(axis, setup.mounting))
        eulers.append(tuple(float(e) for e in planned.mounting_euler_deg))
        obs = _observation(planned, gyro, stride, f"near {axis}")
        if axis == axes[0]:
            scale_std = float(np.sqrt(obs.axis @ obs.covariance[:3, :3] @ obs.axis))
        observations += [
            dataclasses.replace(obs, label=f"{obs.label} #{k}") for k in range(sessions)
        ]
    return GyroPlan(
        axes=tuple(axes),
        mountings_euler_deg=tuple(eulers),
        sessions_per_mounting=sessions,
        noise_density_dps_rthz=gyro.noise_density_dps_rthz,
        pooled=pool_gyro(observations),
        one_session_scale_std=scale_std,
    )


def _observation(
    setup: PlannedSetup, gyro: GyroSpec, stride: int, label: str
) -> GyroMountingObservation:
    """One planned session: the truth's gyro reading with its predicted covariance."""
    params = setup.params()
    layout = setup.layout()
    t = setup.centred_times_s()
    with threadpool_limits(1):
        fisher = fisher_information(params, t, setup.noise_model(), layout, stride=stride)
    bound = bound_from_fisher(params, layout, fisher)
    index = [bound.names.index(n) if n in bound.names else None for n in _GEOMETRY]
    geometry = np.zeros((4, 4))
    for a, i in enumerate(index):
        for b, j in enumerate(index):
            if i is not None and j is not None:
                geometry[a, b] = bound.covariance[i, j]
    rotation = params.bench.misalignment.matrix
    kin = spin_kinematics(params.spin, t)
    force = bench_force(kin, params.bench.tilt_rad, params.bench.radius_m, params.gravity_mps2)
    design = np.column_stack(
        [kin.omega_radps, np.ones_like(t), force.accel_mps2[:, 0], force.accel_mps2[:, 1]]
    )
    sigma = gyro.noise_std_radps(setup.rate_hz)
    per_axis = design.T @ design / sigma**2  # (w, b, gx, gy) of one gyro axis
    info = np.zeros((12, 12))
    for j in range(3):
        rows = [j, 3 + j, 6 + j, 9 + j]
        info[np.ix_(rows, rows)] = per_axis
    prior = GyroReading(g_prior_dps_per_g=G_SENSITIVITY_PRIOR_DPS_PER_G).g_prior_std_radps_per_mps2
    info[6:, 6:] += np.eye(6) / prior**2
    m, g = gyro.response_matrix, gyro.g_sensitivity_radps_per_mps2
    g_cos = params.gravity_mps2 * np.cos(params.bench.tilt_rad)
    values = np.concatenate(
        [
            m @ -rotation[:, 2],
            np.asarray(gyro.bias_radps) + g_cos * (g @ rotation[:, 2]),
            g @ rotation[:, 0],
            g @ rotation[:, 1],
        ]
    )
    return GyroMountingObservation(
        label=label,
        mounting_id=label,
        values=values,
        covariance=np.linalg.inv(info),
        rotation=rotation,
        tilt_rad=params.bench.tilt_rad,
        gravity_mps2=params.gravity_mps2,
        geometry_covariance=geometry_covariance(rotation, geometry),
        g_prior_std=prior,
    )
