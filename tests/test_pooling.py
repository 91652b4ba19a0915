"""One calibration per sensor: the pooling of its sessions (wheelcal.closedloop.pooling).

Tiers: exact algebra on hand-made sessions; the σ rule on many synthetic
batches (pure statistics, fast); and Monte Carlo on simulated recordings fitted
by the joint fit, judged against the simulator's truth — a short version here,
the full study marked ``slow``.
"""

import dataclasses

import numpy as np
import pytest
from scipy import stats

from wheelcal.calibration.sensor_json import joint_estimate, session_estimate
from wheelcal.calibration.session_json import calibration_dict
from wheelcal.closedloop.pooling import (
    JOINT_FIT,
    POOLED_PARAMETERS,
    WEIGHTED_MEAN,
    JointEstimate,
    RecordingEstimate,
    pool_sessions,
)
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.model import SensorParams
from wheelcal.session.fit import session_of_fit
from wheelcal.simulate import simulate
from wheelcal.simulate.presets import TABLE2_GAIN, TABLE2_OFFSET_MPS2, table2

TRUTH = np.array([*TABLE2_GAIN, *TABLE2_OFFSET_MPS2])
SIGMA = np.array([1e-4, 2e-4, 7e-4, 3e-3, 3e-3, 6e-3])  # a session's σ, gains then offsets


def _session(label, value, std=SIGMA, systematic=None, mounting="m", covariance=None):
    return RecordingEstimate(
        label,
        value=value,
        std=std,
        systematic_std=SIGMA * 10 if systematic is None else systematic,
        mounting_id=mounting,
        covariance=covariance,
    )


# --- exact algebra ------------------------------------------------------------------------------


def test_weighted_mean_sigma_and_birge_scale_by_hand():
    rng = np.random.default_rng(5)
    stds = SIGMA * rng.uniform(0.5, 2.0, (4, 6))
    values = TRUTH + 3 * stds * rng.standard_normal((4, 6))  # scatter 3× their σ
    pooled = pool_sessions([_session(f"s{i}", values[i], stds[i]) for i in range(4)])
    # DerSimonian–Laird τ² from the plain 1/σ² mean, then weights 1/(σ² + τ²).
    w0 = 1 / stds**2
    q = (w0 * (values - (w0 * values).sum(0) / w0.sum(0)) ** 2).sum(0)
    tau2 = np.maximum(0.0, (q - 3) / (w0.sum(0) - (w0**2).sum(0) / w0.sum(0)))
    assert np.all(tau2 > 0)  # the sessions do scatter more than their σ here
    w = 1 / (stds**2 + tau2)
    mean = (w * values).sum(0) / w.sum(0)
    chi2_red = (w * (values - mean) ** 2).sum(0) / 3
    scale = np.sqrt(np.maximum(1.0, chi2_red))
    assert pooled.method == WEIGHTED_MEAN
    np.testing.assert_allclose(pooled.between_session_std, np.sqrt(tau2), rtol=1e-12)
    np.testing.assert_allclose(pooled.value, mean, rtol=1e-13)
    np.testing.assert_allclose(pooled.std_unscaled, 1 / np.sqrt(w.sum(0)), rtol=1e-13)
    np.testing.assert_allclose(pooled.chi2_red, chi2_red, rtol=1e-12)
    np.testing.assert_allclose(pooled.std, scale / np.sqrt(w.sum(0)), rtol=1e-12)
    np.testing.assert_array_equal(pooled.dof, 3)
    np.testing.assert_allclose(np.sqrt(np.diag(pooled.covariance)), pooled.std, rtol=1e-12)


def test_sessions_that_agree_are_pooled_by_the_plain_precision_weighted_mean():
    rng = np.random.default_rng(6)
    stds = SIGMA * rng.uniform(0.5, 2.0, (5, 6))
    values = TRUTH + 0.3 * stds * rng.standard_normal((5, 6))  # well within their σ
    pooled = pool_sessions([_session(f"s{i}", values[i], stds[i]) for i in range(5)])
    w = 1 / stds**2
    np.testing.assert_array_equal(pooled.between_session_std, 0.0)
    np.testing.assert_allclose(pooled.value, (w * values).sum(0) / w.sum(0), rtol=1e-13)
    np.testing.assert_allclose(pooled.std, 1 / np.sqrt(w.sum(0)), rtol=1e-13)


def test_consistent_sessions_are_not_shrunk_below_their_weighted_sigma():
    # Sessions that agree better than their σ (χ²_red < 1) keep σ = 1/√Σw: never scaled down.
    sessions = [_session(f"s{i}", TRUTH + 0.01 * SIGMA * i) for i in range(5)]
    pooled = pool_sessions(sessions)
    np.testing.assert_allclose(pooled.scale, 1.0)
    np.testing.assert_allclose(pooled.std, SIGMA / np.sqrt(5), rtol=1e-12)


def test_systematic_sigma_is_shared_not_divided_by_root_n():
    systematic = np.array([3.6e-3, 3.6e-3, 3.7e-3, 0.019, 0.025, 0.050])
    sessions = [_session(f"s{i}", TRUTH, systematic=systematic) for i in range(9)]
    pooled = pool_sessions(sessions)
    np.testing.assert_allclose(pooled.systematic_std, systematic, rtol=1e-12)  # not /3
    np.testing.assert_allclose(pooled.std, SIGMA / 3, rtol=1e-12)  # the statistical σ is /√9
    np.testing.assert_allclose(pooled.total_std, np.hypot(SIGMA / 3, systematic))


def test_a_session_that_cannot_determine_a_parameter_is_skipped_for_it_and_named():
    values = np.tile(TRUTH, (3, 1))
    values[1, 2] = 5.0  # an absurd gain_z …
    stds = np.tile(SIGMA, (3, 1))
    stds[1, 2] = np.inf  # … that the session cannot determine (σ = ∞, JSON null)
    sessions = [_session(f"s{i}", values[i], stds[i]) for i in range(3)]
    pooled = pool_sessions(sessions)
    assert pooled.value_of("gain_z") == pytest.approx(TRUTH[2], rel=1e-14)
    assert pooled.std_of("gain_z") == pytest.approx(SIGMA[2] / np.sqrt(2))
    assert pooled.used.tolist() == [3, 3, 2, 3, 3, 3]
    assert [(s, p) for s, p, _ in pooled.skipped] == [("s1", "gain_z")]
    assert pooled.undetermined == ()


def test_a_parameter_no_session_determines_is_undetermined_and_its_axis_left_unchanged():
    values = np.tile(TRUTH, (2, 1))
    values[:, 2] = np.nan  # gain_z null in both files
    sessions = [
        dataclasses.replace(
            _session(f"s{i}", values[i]), reasons=(("gain_z", "sensor z along the wheel axis"),)
        )
        for i in range(2)
    ]
    pooled = pool_sessions(sessions)
    assert np.isnan(pooled.value_of("gain_z")) and np.isnan(pooled.std_of("gain_z"))
    assert pooled.undetermined[0][0] == "gain_z"
    assert "wheel axis" in pooled.undetermined[0][1]
    corr = pooled.correction()
    assert corr.matrix[2, 2] == 1.0 and corr.matrix[0, 0] == pytest.approx(1 / TRUTH[0])
    v = np.array([[0.3, -0.2, 9.0]])
    assert corr.apply(v)[0, 2] == pytest.approx(9.0 - TRUTH[5])


def test_the_joint_fit_is_used_when_it_determines_everything_else_the_weighted_mean():
    rng = np.random.default_rng(9)
    values = TRUTH + SIGMA * rng.standard_normal((4, 6))
    sessions = [_session(f"s{i}", values[i], mounting="a" if i < 2 else "b") for i in range(4)]
    joint_value = TRUTH + 0.1 * SIGMA
    cross = np.array([0.01, -0.015, 0.008])
    joint = JointEstimate(joint_value, SIGMA / 2, converged=True, cross_axis_rad=cross)
    pooled = pool_sessions(sessions, joint)
    assert pooled.method == JOINT_FIT
    np.testing.assert_allclose(pooled.value, joint_value)
    # The spread check uses the scatter within each mounting: ν = (2 − 1) + (2 − 1).
    np.testing.assert_array_equal(pooled.dof, 2)
    # The correction undoes v = o + Γ (I + L) s exactly.
    lower = np.zeros((3, 3))
    lower[1, 0], lower[2, 0], lower[2, 1] = cross
    s = np.array([[1.0, -2.0, 9.0]])
    raw = joint_value[3:] + s @ (np.diag(joint_value[:3]) @ (np.eye(3) + lower)).T
    np.testing.assert_allclose(pooled.correction().apply(raw), s, atol=1e-12)
    # A joint fit that did not converge, or misses a parameter, is not used — and the file says so.
    for bad in (
        dataclasses.replace(joint, converged=False),
        JointEstimate(joint_value, np.r_[SIGMA[:5], np.inf], converged=True),
    ):
        fallback = pool_sessions(sessions, bad)
        assert fallback.method == WEIGHTED_MEAN
        assert any("weighted mean instead" in w for w in fallback.warnings)


def test_session_estimate_reads_nulls_and_the_covariance_block(table1_session):
    recording = table1_session.recording
    result = JointFit().fit(recording)
    doc = calibration_dict(session_of_fit(result, recording))
    est = session_estimate(doc)
    np.testing.assert_allclose(est.value, [result.value_of(n) for n in POOLED_PARAMETERS])
    np.testing.assert_allclose(np.sqrt(np.diag(est.covariance)), est.std, rtol=1e-12)
    doc["sensor"]["gain"][1] = None
    doc["sensor"]["gain_std"][1] = None
    doc["sensor"]["undetermined"] = [{"parameter": "gain_y", "reason": "test"}]
    est = session_estimate(doc)
    assert not est.determined[1] and est.determined[[0, 2, 3, 4, 5]].all()
    assert dict(est.reasons) == {"gain_y": "test"}


def test_joint_estimate_from_a_real_sensor_fit():
    from wheelcal.closedloop.sensor_fit import SensorFit

    rng = np.random.default_rng(21)
    recs, fits = [], []
    for _ in range(2):
        scenario = dataclasses.replace(table2(rng=rng), duration_s=40.0, rate_hz=100.0)
        rec = simulate(scenario, rng).recording
        recs.append(rec)
        fits.append(JointFit().fit(rec))
    fit = SensorFit().fit(recs, fits)
    joint = joint_estimate(fit.as_dict())
    docs = [calibration_dict(session_of_fit(f, r)) for f, r in zip(fits, recs, strict=True)]
    pooled = pool_sessions([session_estimate(d) for d in docs], joint)
    assert pooled.method == JOINT_FIT
    np.testing.assert_allclose(pooled.value, [fit.value_of(n) for n in POOLED_PARAMETERS])
    np.testing.assert_allclose(pooled.std_unscaled, [fit.std_of(n) for n in POOLED_PARAMETERS])


# --- the σ rule on synthetic batches (pure statistics) --------------------------------------------


@pytest.mark.parametrize("sigma_range", [(1.0, 1.0), (0.5, 2.0)])
def test_pooled_sigma_covers_the_truth_under_3_sigma_between_session_jitter(sigma_range):
    """Sessions that scatter √10 × their σ (jitter 3σ added): ±2σ still covers ≥ 90 %.

    The scale comes from ν = 9 dof, so the expected coverage is Student t's,
    P(|t₉| < 2) = 92.3 %, also when the sessions' σ differ by 4× (the τ² in the
    weights).  Without the scale it would be 47 %; without τ², 84 % at (0.5, 2).
    """
    rng = np.random.default_rng(2024)
    batches, n = 1000, 10
    hits = 0
    for _ in range(batches):
        stds = SIGMA * rng.uniform(*sigma_range, (n, 6))
        jitter = 3 * SIGMA * rng.standard_normal((n, 6))
        values = TRUTH + stds * rng.standard_normal((n, 6)) + jitter
        pooled = pool_sessions([_session(str(i), values[i], stds[i]) for i in range(n)])
        hits += int(np.sum(np.abs(pooled.value - TRUTH) < 2 * pooled.std))
    coverage = hits / (batches * 6)
    # 6000 trials: the coverage is known to ±0.35 %.
    assert coverage >= 0.90, coverage
    assert coverage == pytest.approx(2 * stats.t.cdf(2.0, n - 1) - 1, abs=0.015)


# --- Monte Carlo on simulated recordings (joint fit per session, truth from the simulator) --------


def _pooled_batches(seed: int, batches: int, sessions: int, jitter: float):
    """Pool ``batches`` batches of simulated Table II sessions (40 s at 100 Hz each).

    ``jitter`` × a session's σ is added to each session's true gains and offsets
    (an effect between sessions that the model lacks); the truth of the sensor
    stays :data:`TRUTH`.  Returns the pooled values and σ, (batches, 6) each.
    """
    rng = np.random.default_rng(seed)

    def scenario():
        return dataclasses.replace(table2(rng=rng), duration_s=40.0, rate_hz=100.0)

    pilot = JointFit().fit(simulate(scenario(), rng).recording)
    sigma = np.array([pilot.std_of(n) for n in POOLED_PARAMETERS])
    values, stds = [], []
    for _ in range(batches):
        docs = []
        for _ in range(sessions):
            s = scenario()
            true = TRUTH + jitter * sigma * rng.standard_normal(6)
            s = dataclasses.replace(
                s,
                truth=s.truth.with_changes(
                    sensor=SensorParams(offset_mps2=true[3:], gain=true[:3])
                ),
            )
            recording = simulate(s, rng).recording
            docs.append(calibration_dict(session_of_fit(JointFit().fit(recording), recording)))
        pooled = pool_sessions([session_estimate(d) for d in docs])
        values.append(pooled.value)
        stds.append(pooled.std)
    return np.array(values), np.array(stds)


def _sigma_ratio(values, stds):
    """Observed spread over batches / the RMS of the reported σ, per parameter."""
    return values.std(axis=0, ddof=1) / np.sqrt(np.mean(stds**2, axis=0))


def test_pooled_sigma_matches_the_spread_of_repeated_batches_short():
    values, stds = _pooled_batches(seed=7, batches=40, sessions=10, jitter=0.0)
    ratio = _sigma_ratio(values, stds)
    # 40 batches give each ratio to ±11 %: the short version checks all six together.
    overall = float(np.sqrt(np.mean(ratio**2)))
    assert 0.8 <= overall <= 1.25, ratio
    bias = np.abs(values.mean(axis=0) - TRUTH) / (values.std(axis=0, ddof=1) / np.sqrt(40))
    assert bias.max() < 4.0, bias


def test_pooled_sigma_covers_the_truth_with_between_session_jitter_short():
    values, stds = _pooled_batches(seed=8, batches=40, sessions=10, jitter=3.0)
    coverage = float(np.mean(np.abs(values - TRUTH) < 2 * stds))
    # 240 trials estimate the coverage to ±1.7 %: the full study asserts ≥ 90 %.
    assert coverage >= 0.85, coverage
    assert 0.8 <= float(np.sqrt(np.mean(_sigma_ratio(values, stds) ** 2))) <= 1.25


@pytest.mark.slow
def test_pooled_sigma_matches_the_spread_of_repeated_batches_full():
    # Sessions that agree are pooled with σ ≥ 1/√Σw (the max(1, ·) and a τ² > 0 by chance
    # both err on the safe side): the expected ratio is ≈ 0.92, known to ±4 % at 300 batches.
    values, stds = _pooled_batches(seed=17, batches=300, sessions=10, jitter=0.0)
    ratio = _sigma_ratio(values, stds)
    print(
        "σ ratio (spread / reported) per parameter:",
        dict(zip(POOLED_PARAMETERS, ratio, strict=True)),
    )
    assert np.all((ratio >= 0.8) & (ratio <= 1.25)), ratio
    bias = np.abs(values.mean(axis=0) - TRUTH) / (values.std(axis=0, ddof=1) / np.sqrt(300))
    assert bias.max() < 4.0, bias


@pytest.mark.slow
def test_pooled_sigma_covers_the_truth_with_between_session_jitter_full():
    values, stds = _pooled_batches(seed=18, batches=200, sessions=10, jitter=3.0)
    coverage = np.mean(np.abs(values - TRUTH) < 2 * stds, axis=0)
    ratio = _sigma_ratio(values, stds)
    print("±2σ coverage per parameter:", dict(zip(POOLED_PARAMETERS, coverage, strict=True)))
    print("σ ratio with jitter:", dict(zip(POOLED_PARAMETERS, ratio, strict=True)))
    assert float(coverage.mean()) >= 0.90, coverage
    assert np.all((ratio >= 0.8) & (ratio <= 1.25)), ratio
