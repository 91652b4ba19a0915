"""The field fit's σ parts against Monte Carlo: the gyro's angle walk, and its noise density.

The angle walk (:func:`wheelcal.estimate.field.robust.angle_walk_covariance`) is a
linearised propagation (its per-sample response, summed from each time on).  The
oracle shares neither: ``scipy.optimize.least_squares`` refits the model to noise-free
samples with the wheel angle walked by the gyro's integrated white noise, 40
times, and the spread of the answers is compared with the propagated σ.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from wheelcal.estimate.field.gyro_axle import rate_noise_density
from wheelcal.estimate.field.robust import angle_walk_covariance, block_meat, robust_result
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.model import (
    BenchParams,
    CalibrationParams,
    Rotation,
    SensorParams,
    SpinParams,
    evaluate,
)
from wheelcal.model.gyro_angle import GyroAngle
from wheelcal.model.layout import ParameterLayout
from wheelcal.recording import Recording, SessionInfo

RATE_HZ = 100.0
#: A consumer gyro's noise density, 3×.
DENSITY_RADPS_RTHZ = np.deg2rad(0.03)
#: The parameters whose internal and reported values are the same.
SAME = ("omega0_radps", "gain_x", "gain_y", "gain_z")
SAME += ("offset_x_mps2", "offset_y_mps2", "offset_z_mps2", "gyro_angle.scale")


def _rate(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A wheel that speeds up and slows down (a drive's rate, no stops)."""
    rate = 9.0 + 4.0 * np.sin(0.21 * t) + 1.5 * np.cos(0.67 * t)
    return rate, 0.84 * np.cos(0.21 * t) - 1.005 * np.sin(0.67 * t)


def _truth(angle: GyroAngle) -> CalibrationParams:
    return CalibrationParams(
        spin=SpinParams(0.4, [0.01]),
        bench=BenchParams(np.deg2rad(60.0), 0.2, Rotation.from_euler_deg(20.0, -10.0, 35.0)),
        sensor=SensorParams([0.2, -0.1, 0.3], [0.98, 1.01, 1.03]),
        effects={angle.name: [1.0]},
    )


def _walked_layout(t, rate, rate_dot, walk) -> ParameterLayout:
    """α free, r known (the paper's bench); the angle walked by ``walk``, the rate clean."""
    angle = GyroAngle(t, rate, rate_dot)
    angle.angle = angle.angle + walk
    return ParameterLayout(spin_degree=0, fit_tilt=True, fit_radius=False, effects=(angle,))


def _refit(t, accel, layout, truth) -> np.ndarray:
    def residual(x):
        return (evaluate(layout.unpack(x, truth), t, layout).predicted_mps2 - accel).ravel()

    def jacobian(x):
        out = evaluate(layout.unpack(x, truth), t, layout, jacobian=True)
        return out.jacobian.transpose(2, 1, 0).reshape(-1, layout.size)

    return least_squares(residual, layout.pack(truth), jac=jacobian, method="lm").x


def _fitted_drive(rng: np.random.Generator) -> tuple:
    """A minute's drive without a walk, fitted (white noise, equal on the axes): t, the rate,
    its derivative, the layout, the truth, the clean and the noisy samples, the result."""
    t = np.linspace(-30.0, 30.0, 6001)
    rate, rate_dot = _rate(t)
    layout = _walked_layout(t, rate, rate_dot, np.zeros_like(t))
    truth = _truth(layout.effects[0])
    clean = evaluate(truth, t, layout).predicted_mps2
    noisy = clean + 1e-3 * rng.standard_normal(clean.shape)
    fit = JointFit(spin_degree=0, geometry="radius", coloured_noise=False, effects=layout.effects)
    result = fit.fit(Recording(t, noisy, SessionInfo(radius_m=0.2)), initial=truth)
    return t, rate, rate_dot, layout, truth, clean, noisy, result


def test_the_angle_walk_matches_the_spread_of_refits():
    rng = np.random.default_rng(3)
    t, rate, rate_dot, layout, truth, clean, noisy, result = _fitted_drive(rng)
    walk_sd = np.sqrt(np.diag(angle_walk_covariance(result, noisy, DENSITY_RADPS_RTHZ)))
    sigma_rate = DENSITY_RADPS_RTHZ * np.sqrt(RATE_HZ)
    values = []
    for _ in range(40):
        walk = np.cumsum(sigma_rate * rng.standard_normal(t.size)) / RATE_HZ
        values.append(_refit(t, clean, _walked_layout(t, rate, rate_dot, walk), truth))
    spread = np.std(np.array(values), axis=0, ddof=1)
    names = list(layout.names)
    for name in SAME:
        s, sd = spread[names.index(name)], walk_sd[result.names.index(name)]
        print(f"{name:18s} spread {s:.3e}  the walk's σ {sd:.3e}")
        # 40 refits: the spread's own error is ±11 % (1σ)
        assert 0.7 < s / sd < 1.4, (name, s, sd)
    s = np.rad2deg(spread[names.index("tilt_rad")])
    assert 0.7 < s / walk_sd[result.names.index("tilt_deg")] < 1.4


def test_the_rate_noise_density_comes_from_the_samples():
    rng = np.random.default_rng(8)
    t = np.arange(0.0, 60.0, 1.0 / 400.0)
    rate, _ = _rate(t)
    rate = 3.0 * rate + 0.2 * t  # speeding up and down, far above the noise per sample
    sigma = DENSITY_RADPS_RTHZ * np.sqrt(400.0)
    noisy = rate + sigma * rng.standard_normal(t.size)
    noisy[1000] = 3.7e7  # one logger glitch
    found = rate_noise_density(t, noisy)
    assert abs(found / DENSITY_RADPS_RTHZ - 1.0) < 0.03, found


def test_the_meat_with_lags_follows_anti_correlated_blocks():
    # Block scores g_b = e_b − 0.6 e_{b−1} (the whitened residual anti-correlated across
    # neighbouring blocks): the variance of their sum per block is (1 − 0.6)² = 0.16, while
    # the blocks alone say 1 + 0.36.  The Bartlett-weighted lags bring the meat down by
    # 2 (1 − 1/(L+1)) 0.6 (its expectation), and it stays positive semi-definite.
    rng = np.random.default_rng(3)
    e = rng.standard_normal((2, 200_001))
    sums = e[:, 1:] - 0.6 * e[:, :-1]
    blocks = sums.shape[1]
    alone = block_meat(sums, lags=0) / blocks
    np.testing.assert_allclose(np.diag(alone), 1.36, rtol=0.02)
    for lags in (1, 5):
        meat = block_meat(sums, lags=lags) / blocks
        expected = 1.36 - 2 * (1 - 1 / (lags + 1)) * 0.6
        np.testing.assert_allclose(np.diag(meat), expected, rtol=0.03)
        assert abs(meat[0, 1]) < 0.02
        assert np.linalg.eigvalsh(block_meat(sums[:, :7], lags=lags)).min() >= -1e-12


def test_a_nuisance_held_joins_the_covariance_as_the_refit_moves():
    # robust_result(shifts=(Δ,)) adds δp δpᵀ, δp the fit's answer to the prediction
    # shifted by Δ (what one σ of a nuisance the fit holds does).  Oracle: scipy's
    # least squares refitted to the clean samples plus Δ, against the clean samples.
    t, _, _, layout, truth, clean, noisy, result = _fitted_drive(np.random.default_rng(5))
    # a slow rate error's share of the prediction: once per turn, growing with time
    shift = np.column_stack(
        [
            2e-3 * np.cos(0.9 * t) * (1 + t / 30.0),
            1e-3 * np.sin(0.3 * t),
            5e-4 * np.ones_like(t),
        ]
    )
    held = robust_result(result, noisy)
    joined = robust_result(result, noisy, shifts=(shift,))
    added = np.sqrt(np.maximum(np.diag(joined.covariance) - np.diag(held.covariance), 0.0))
    moved = _refit(t, clean + shift, layout, truth) - _refit(t, clean, layout, truth)
    names = list(layout.names)
    for name in SAME:
        expected = abs(moved[names.index(name)])
        found = added[result.names.index(name)]
        print(f"{name:18s} refit moved {expected:.3e}  propagated {found:.3e}")
        assert abs(found - expected) <= 0.05 * expected + 1e-9, (name, found, expected)
    assert max(abs(moved[names.index(n)]) for n in SAME) > 1e-4  # the shift does move the fit


def _mean_variances(phi: float, blocks: int, reps: int, rng) -> tuple[float, list, list]:
    """A mean fitted to AR(1) blocks: its true variance, and the meat's with 1 and chosen lags."""
    from wheelcal.estimate.field.robust import chosen_lags

    e = rng.standard_normal((reps, blocks + 200))
    x = np.empty_like(e)
    x[:, 0] = e[:, 0]
    for b in range(1, e.shape[1]):
        x[:, b] = phi * x[:, b - 1] + e[:, b]
    x = x[:, 200:]
    means = x.mean(axis=1)
    one, chosen = [], []
    for row, mean in zip(x, means, strict=True):
        sums = (row - mean)[None, :]  # the score of each block at the fitted mean
        hess = np.array([[float(blocks)]])
        lags = chosen_lags(sums, hess)
        one.append(block_meat(sums, lags=1)[0, 0] / blocks**2)
        chosen.append((block_meat(sums, lags=lags)[0, 0] / blocks**2, lags))
    return float(np.var(means)), one, chosen


def test_the_lags_are_read_from_the_blocks_own_correlation():
    # Slowly correlated block scores (AR(1), φ = 0.7: the long-run variance 5.7× the
    # blocks' alone, as the gains' score on measured car drives stays correlated 5–20 s)
    # on 120 blocks: one lag leaves the mean's σ at ~0.52 of its spread; the lags chosen
    # from the data (Newey & West 1994) bring it to ~0.8, and white blocks keep few.
    rng = np.random.default_rng(12)
    truth, one, chosen = _mean_variances(0.7, 120, 400, rng)
    ratio_one = np.sqrt(np.mean(one) / truth)
    ratio_chosen = np.sqrt(np.mean([v for v, _ in chosen]) / truth)
    lags = np.array([lag for _, lag in chosen])
    assert ratio_one < 0.7, ratio_one
    assert 0.72 < ratio_chosen < 1.1, ratio_chosen
    assert ratio_chosen > ratio_one + 0.15, (ratio_one, ratio_chosen)
    assert np.median(lags) >= 5, np.median(lags)
    _, _, white = _mean_variances(0.0, 120, 200, rng)
    assert np.median([lag for _, lag in white]) <= 3


def test_each_parameter_takes_its_own_lags():
    # Three means fitted at once: the first's block scores slowly correlated (AR(1),
    # φ = 0.7), the other two white, the three drawn from a common source so they
    # correlate.  The median of the lags is a white one's: at it the slow mean's σ is
    # ~0.55 of its spread.  At its own lags (sandwich_covariance) it is ~0.8, the white
    # ones stay at their spread, and the correlations are the meat's.
    from wheelcal.estimate.field.robust import influence_lags, sandwich_covariance

    rng = np.random.default_rng(31)
    blocks, reps = 120, 300
    sigma, spread_of, lags_slow, corr = [], [], [], []
    for _ in range(reps):
        e = rng.standard_normal(blocks + 200)
        slow = np.empty_like(e)
        slow[0] = e[0]
        for b in range(1, e.size):
            slow[b] = 0.7 * slow[b - 1] + e[b]
        common = rng.standard_normal(blocks)
        x = np.stack(
            [
                slow[200:],
                common + 0.5 * rng.standard_normal(blocks),
                common + 0.5 * rng.standard_normal(blocks),
            ]
        )
        means = x.mean(axis=1)
        sums = x - means[:, None]
        hess = np.eye(3) * blocks
        own = np.maximum(1, influence_lags(sums, hess))
        cov = sandwich_covariance(np.linalg.inv(hess), sums, own, np.zeros(3))
        sigma.append(np.sqrt(np.diag(cov)))
        spread_of.append(means)
        lags_slow.append(own[0])
        corr.append(cov[1, 2] / np.sqrt(cov[1, 1] * cov[2, 2]))
    ratio = np.sqrt(np.mean(np.square(sigma), axis=0)) / np.std(spread_of, axis=0)
    print("σ/spread", ratio, "slow lags", np.median(lags_slow), "corr", np.mean(corr))
    assert 0.72 < ratio[0] < 1.1, ratio
    assert np.all((ratio[1:] > 0.85) & (ratio[1:] < 1.15)), ratio
    assert np.median(lags_slow) >= 5
    assert 0.7 < np.mean(corr) < 0.9  # the white pair's correlation, 1 / 1.25
