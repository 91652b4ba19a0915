r"""The gyroscope's full matrix, pooled over the mountings of one sensor.

**Model.**  The gyro reads ω_meas = M Ω + b + G f in the accelerometer's
orthonormal sensor frame (Ω the body rate, f the specific force, both in that
frame; M the gyro's 3×3 response — three scales, its axes' misalignment to the
accelerometer and their non-orthogonality —, b its bias, G its sensitivity to
linear acceleration).  On a fixed bench Ω = −ω R e_Z and f = R a(t), with R the
mounting (bench → sensor) the accelerometer's fit measures, so a session's
gyro reading w ω + b_s + gx a_X + gy a_Y (:class:`~wheelcal.model.effects.GyroReading`)
measures

    w  = M d,               d = −R e_Z   (the wheel axis in the sensor frame)
    b_s = b + c G R e_Z,     c = g cos α  (a_Z is constant: it merges with b)
    gx = G R e_X,  gy = G R e_Y.

One mounting sees M along one axis d; mountings whose wheel axes are three
independent directions of the sensor determine all nine entries (and G's
columns along R e_X, R e_Y of each mounting determine G, hence b).

**Fit.**  Linear in θ = (vec M row-major, b, vec G) for given R and α: a
generalised least squares over the sessions, each weighted by the inverse of

    C_s + J_s C_geo,s J_sᵀ,

C_s the session's covariance of (w, b_s, gx, gy) with its prior on G taken
out (G's prior N(0, σ_G²) enters once here, not once per session), and
C_geo,s the covariance of its R (as a right perturbation δ, from its Euler
angles' covariance) and α, carried by J_s = ∂(prediction)/∂(δ, α) at the
current θ (R's σ, 0.005–0.03°, is what limits M: the gyro's own noise makes
w ~10× more precise).  Two passes: J_s needs θ.  The spread check is the
pooled accelerometer's: σ × max(1, √χ²_red).

**Undetermined.**  Entries with weight on a direction of θ the mountings do
not reach (the wheel axes span a plane or a line), or with σ above
:data:`MAX_MATRIX_STD`, are NaN with the reason; the mountings' axes and what
they measure (M d) are evidence either way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint import covariance_from_fisher
from wheelcal.model import Rotation, hat

#: Entries of M with a larger σ carry no usable number (the scale is 1, a gyro's
#: misalignment 0.01–0.03): null, with the reason.
MAX_MATRIX_STD = 0.05
#: Parameter names, in θ's order.
AXES = "xyz"
MATRIX_NAMES = tuple(f"matrix_{a}{b}" for a in AXES for b in AXES)
BIAS_NAMES = tuple(f"bias_{a}_radps" for a in AXES)
G_NAMES = tuple(f"g_sensitivity_{a}{b}" for a in AXES for b in AXES)
NAMES = MATRIX_NAMES + BIAS_NAMES + G_NAMES
_M, _B, _G = slice(0, 9), slice(9, 12), slice(12, 21)
_E = np.eye(3)


@dataclass(frozen=True, eq=False)
class GyroMountingObservation:
    """One session's gyro reading along its wheel axis, and the geometry it was read in.

    ``values``: w (3), b_s (3), gx (3), gy (3) in rad/s and rad/s per m/s²;
    ``covariance`` theirs (12×12, the session's posterior); ``rotation`` R
    (bench → sensor); ``geometry_covariance`` of (δ, α) in rad² — δ the right
    perturbation of R (4×4); ``g_prior_std`` the σ of the session's prior on each
    entry of gx, gy (None: no prior).
    """

    label: str
    mounting_id: str
    values: np.ndarray
    covariance: np.ndarray
    rotation: np.ndarray
    tilt_rad: float
    gravity_mps2: float
    geometry_covariance: np.ndarray
    g_prior_std: float | None = None

    def __post_init__(self) -> None:
        for name, shape in (
            ("values", (12,)),
            ("covariance", (12, 12)),
            ("rotation", (3, 3)),
            ("geometry_covariance", (4, 4)),
        ):
            value = np.array(getattr(self, name), dtype=float).reshape(shape)
            if not np.all(np.isfinite(value)):
                raise ValueError(f"{self.label}: the gyro reading's {name} is not finite")
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def axis(self) -> np.ndarray:
        """The wheel axis in the sensor frame, d = −R e_Z (an ideal gyro reads ω d)."""
        return -self.rotation[:, 2]

    def design(self) -> np.ndarray:
        """A (12×21): the prediction A θ of (w, b_s, gx, gy) — linear in θ = (M, b, G)."""
        r = self.rotation
        c = self.gravity_mps2 * np.cos(self.tilt_rad)
        a = np.zeros((12, 21))
        a[0:3, _M] = np.kron(_E, self.axis)  # (M d)_j = Σ_k M_jk d_k
        a[3:6, _B] = _E
        a[3:6, _G] = c * np.kron(_E, r[:, 2])  # c (G R e_Z)_j
        a[6:9, _G] = np.kron(_E, r[:, 0])
        a[9:12, _G] = np.kron(_E, r[:, 1])
        return a

    def geometry_jacobian(self, theta: np.ndarray) -> np.ndarray:
        """∂(prediction)/∂(δ, α) at θ, (12×4): R → R exp([δ]×) turns R e_k by −R [e_k]× δ."""
        m = theta[_M].reshape(3, 3)
        g = theta[_G].reshape(3, 3)
        r = self.rotation
        c = self.gravity_mps2 * np.cos(self.tilt_rad)
        turn = [-r @ hat(_E[k]) for k in range(3)]  # ∂(R e_k)/∂δ
        jac = np.zeros((12, 4))
        jac[0:3, :3] = -m @ turn[2]
        jac[3:6, :3] = c * g @ turn[2]
        jac[3:6, 3] = -self.gravity_mps2 * np.sin(self.tilt_rad) * (g @ r[:, 2])
        jac[6:9, :3] = g @ turn[0]
        jac[9:12, :3] = g @ turn[1]
        return jac

    def data_only(self) -> tuple[np.ndarray, np.ndarray, bool]:
        """(values, covariance) with the session's prior on G taken out, and whether it was.

        Information form: the posterior's information less the prior's 1/σ_G²
        on the six G entries, the same information vector (the prior's mean is
        0).  Left in when that is not positive definite (the data barely see G).
        """
        if self.g_prior_std is None:
            return self.values, self.covariance, False
        info = np.linalg.inv(self.covariance)
        vector = info @ self.values
        data = info.copy()
        data[6:, 6:] -= np.eye(6) / self.g_prior_std**2
        try:
            np.linalg.cholesky(data)
        except np.linalg.LinAlgError:
            return self.values, self.covariance, False
        cov = np.linalg.inv(data)
        return cov @ vector, 0.5 * (cov + cov.T), True


@dataclass(frozen=True, eq=False)
class MountingEvidence:
    """What one mounting's sessions measured: its wheel axis and M along it."""

    mounting_id: str
    sessions: int
    axis: np.ndarray  # mean unit wheel axis d in the sensor frame
    axis_spread_deg: float  # largest angle of a session's axis from the mean
    measured: np.ndarray  # mean w = M d (rad/s per rad/s)

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {
            "mounting_id": self.mounting_id,
            "sessions": self.sessions,
            "wheel_axis_in_sensor_frame": self.axis.tolist(),
            "wheel_axis_spread_deg": self.axis_spread_deg,
            "matrix_times_axis": self.measured.tolist(),
        }


@dataclass(frozen=True, eq=False)
class PooledGyro:
    """The gyro's pooled M, b and G with their σ (NaN where the mountings cannot see them)."""

    values: np.ndarray  # θ in NAMES order (NaN: undetermined)
    std: np.ndarray
    covariance: np.ndarray  # 21×21, after the spread check (NaN rows: undetermined)
    mountings: tuple[MountingEvidence, ...]
    axes_singular_values: np.ndarray  # of the mountings' unit axes, ÷ √(mountings)
    least_seen_axis: np.ndarray
    undetermined: tuple[tuple[str, str], ...]
    sessions: tuple[str, ...]
    skipped: tuple[tuple[str, str], ...]
    chi2_red: float
    dof: int
    scale: float
    priors_taken_out: int
    g_prior_std: float | None
    warnings: tuple[str, ...] = ()

    @property
    def matrix(self) -> np.ndarray:
        """M (3×3)."""
        return self.values[_M].reshape(3, 3)

    @property
    def matrix_std(self) -> np.ndarray:
        """σ of M's entries (3×3)."""
        return self.std[_M].reshape(3, 3)

    @property
    def matrix_covariance(self) -> np.ndarray:
        """Covariance of vec(M), row-major (9×9)."""
        return self.covariance[_M, _M]

    @property
    def bias_radps(self) -> np.ndarray:
        """The bias b (3), rad/s."""
        return self.values[_B]

    @property
    def bias_std_radps(self) -> np.ndarray:
        """σ of b (3)."""
        return self.std[_B]

    @property
    def g_sensitivity(self) -> np.ndarray:
        """G, rad/s per m/s² (3×3)."""
        return self.values[_G].reshape(3, 3)

    @property
    def g_sensitivity_std(self) -> np.ndarray:
        """σ of G's entries (3×3)."""
        return self.std[_G].reshape(3, 3)

    @property
    def independent_axes(self) -> int:
        """How many independent wheel axes the mountings give (≥ 10 % of a full set's spread)."""
        return int(np.sum(self.axes_singular_values > 0.1 * np.sqrt(1 / 3)))

    @property
    def complete(self) -> bool:
        """Every entry of M and b determined: a correction can be applied."""
        return bool(np.all(np.isfinite(self.values[:12])))

    def correction(self) -> tuple[np.ndarray, np.ndarray]:
        """(M⁻¹, b): the corrected rate ω = M⁻¹ (reading − b).  Raises if incomplete."""
        if not self.complete:
            raise ValueError("the gyro's matrix or bias is not determined by these mountings")
        return np.linalg.inv(self.matrix), self.bias_radps


def pool_gyro(observations: Sequence[GyroMountingObservation]) -> PooledGyro:
    """M, b and G of one sensor from its sessions' gyro readings (module docstring)."""
    if not observations:
        raise ValueError("pooling the gyro needs at least one session with a gyro reading")
    data = [obs.data_only() for obs in observations]
    prior_std = next((o.g_prior_std for o in observations if o.g_prior_std is not None), None)
    prior = np.zeros((21, 21))
    if prior_std is not None:
        prior[_G, _G] = np.eye(9) / prior_std**2
    designs = [obs.design() for obs in observations]
    theta = _solve(designs, data, [c for _, c, _ in data], prior)[0]
    for _ in range(2):  # the geometry's share of each session's covariance needs θ
        covs = [
            c + j @ obs.geometry_covariance @ j.T
            for obs, (_, c, _), j in (
                (obs, d, obs.geometry_jacobian(theta))
                for obs, d in zip(observations, data, strict=True)
            )
        ]
        theta, fisher, chi2 = _solve(designs, data, covs, prior)
    cov = covariance_from_fisher(fisher)
    n_obs = 12 * len(observations) + (9 if prior_std is not None else 0)
    dof = n_obs - 21
    chi2_red = chi2 / dof if dof > 0 else float("nan")
    scale = float(np.sqrt(max(1.0, chi2_red))) if dof > 0 else 1.0
    cov = cov * scale**2
    std = np.sqrt(np.where(np.isfinite(np.diag(cov)), np.diag(cov), np.inf))
    mountings = _mountings(observations)
    singular, least = _axes_spread(mountings)
    undetermined = _undetermined(std, least, len(mountings), singular)
    values = theta.copy()
    for name, _ in undetermined:
        i = NAMES.index(name)
        values[i] = np.nan
        std[i] = np.nan
        cov[i, :] = cov[:, i] = np.nan
    warnings = []
    if dof > 0 and chi2_red > 2.0:
        warnings.append(
            f"the sessions' gyro readings scatter {scale:.2g}× more than their σ "
            f"(χ²_red {chi2_red:.3g} on {dof} dof): σ scaled by {scale:.2g}"
        )
    return PooledGyro(
        values=values,
        std=std,
        covariance=cov,
        mountings=mountings,
        axes_singular_values=singular,
        least_seen_axis=least,
        undetermined=tuple(undetermined),
        sessions=tuple(o.label for o in observations),
        skipped=(),
        chi2_red=float(chi2_red),
        dof=int(dof),
        scale=scale,
        priors_taken_out=sum(taken for _, _, taken in data),
        g_prior_std=prior_std,
        warnings=tuple(warnings),
    )


def _solve(designs, data, covs, prior) -> tuple[np.ndarray, np.ndarray, float]:
    """θ, its information and the χ² (prior included) of the weighted least squares."""
    fisher = prior.copy()
    vector = np.zeros(21)
    weights = []
    for a, (y, _, _), c in zip(designs, data, covs, strict=True):
        w = np.linalg.inv(c)
        weights.append(w)
        fisher += a.T @ w @ a
        vector += a.T @ w @ y
    # Scaled eigen-solve: M's, b's and G's information differ by 10⁸.
    scale = np.sqrt(np.maximum(np.diag(fisher), 1e-300))
    eigval, eigvec = np.linalg.eigh(fisher / np.outer(scale, scale))
    keep = eigval > eigval.max() * 1e-12
    theta = (eigvec[:, keep] / eigval[keep]) @ (eigvec[:, keep].T @ (vector / scale)) / scale
    chi2 = float(theta @ prior @ theta)
    for a, (y, _, _), w in zip(designs, data, weights, strict=True):
        r = y - a @ theta
        chi2 += float(r @ w @ r)
    return theta, fisher, chi2


def _mountings(observations: Sequence[GyroMountingObservation]) -> tuple[MountingEvidence, ...]:
    groups: dict[str, list[GyroMountingObservation]] = {}
    for obs in observations:
        groups.setdefault(obs.mounting_id, []).append(obs)
    out = []
    for mounting_id, members in groups.items():
        axes = np.array([m.axis for m in members])
        mean = axes.mean(axis=0)
        mean /= np.linalg.norm(mean)
        spread = float(np.rad2deg(np.arccos(np.clip(np.min(axes @ mean), -1.0, 1.0))))
        measured = np.mean([m.values[:3] for m in members], axis=0)
        out.append(MountingEvidence(mounting_id, len(members), mean, spread, measured))
    return tuple(out)


def _axes_spread(mountings: Sequence[MountingEvidence]) -> tuple[np.ndarray, np.ndarray]:
    """The mountings' unit axes: their singular values ÷ √n, and the direction seen least.

    Three orthogonal axes give 1/√3 each; a direction no mounting sees, 0.
    """
    axes = np.array([m.axis for m in mountings])
    _, s, vt = np.linalg.svd(axes, full_matrices=True)
    singular = np.zeros(3)
    singular[: s.size] = s / np.sqrt(len(mountings))
    return singular, vt[-1]


def _undetermined(std, least, n_mountings: int, singular) -> list[tuple[str, str]]:
    """Entries of M the mountings cannot see (null with the reason)."""
    out = []
    independent = int(np.sum(singular > 0.1 * np.sqrt(1 / 3)))
    for k, name in enumerate(MATRIX_NAMES):
        sigma = std[k]
        if np.isfinite(sigma) and sigma <= MAX_MATRIX_STD:
            continue
        if independent == 1:
            reason = (
                f"the {n_mountings} mounting(s) give one wheel axis in the sensor frame: M is "
                "measured along it only (the scale and direction there, see "
                "mountings[].matrix_times_axis) — add mountings with the wheel axis near two "
                "other sensor axes (three independent axes, e.g. near x, y and z, determine "
                "all nine entries)"
            )
        elif independent < 3:
            reason = (
                f"the {n_mountings} mounting(s) give {independent} independent wheel axes in "
                "the sensor frame: M is measured only in their plane (see "
                f"mountings[].matrix_times_axis); the direction {np.round(least, 3).tolist()} "
                "is not seen — add a mounting with the wheel axis along it (three independent "
                "axes, e.g. near the sensor's x, y and z, determine all nine entries)"
            )
        else:
            reason = (
                f"σ {sigma:.3g} > {MAX_MATRIX_STD:g}: the mountings' wheel axes are too close "
                "to one plane to separate this entry — spread them (near the sensor's x, y, z)"
            )
        out.append((name, reason))
    return out


def geometry_covariance(rotation: np.ndarray, cov_deg2: np.ndarray) -> np.ndarray:
    """(δ, α)'s covariance (rad²) from that of (euler_1..3, tilt) in deg² (4×4).

    The reported angles move by ε = J δ for R → R exp([δ]×)
    (:meth:`~wheelcal.model.Rotation.euler_jacobian_deg`), so δ = J⁻¹ ε; the tilt
    in degrees → radians.
    """
    to_rad = np.zeros((4, 4))
    to_rad[:3, :3] = np.linalg.inv(Rotation(np.asarray(rotation, dtype=float)).euler_jacobian_deg())
    to_rad[3, 3] = np.pi / 180.0
    return to_rad @ np.asarray(cov_deg2, dtype=float) @ to_rad.T
