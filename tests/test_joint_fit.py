"""Single-recording recovery by the joint fit, judged against the CRLB at the truth."""

import dataclasses

import numpy as np
import pytest

from wheelcal.estimate.joint.fit import JointFit
from wheelcal.estimate.joint.reporting import report_transform
from wheelcal.model import BenchParams, Rotation, SensorParams, SpinParams
from wheelcal.recording import RecordingError
from wheelcal.session.gates import Gates, undetermined_parameters
from wheelcal.simulate import NoiseSpec, Scenario, simulate, table1
from wheelcal.study.montecarlo import scenario_bound


def _z_scores(result, scenario) -> dict[str, float]:
    bound = scenario_bound(scenario, result.layout)
    diff = result.values - bound.values
    diff[0] = (diff[0] + np.pi) % (2 * np.pi) - np.pi
    return dict(zip(bound.names, diff / bound.std, strict=True))


def test_table1_recovered_within_4_crlb(table1_session):
    result = JointFit().fit(table1_session.recording)
    z = _z_scores(result, table1_session.scenario)
    assert result.converged
    assert max(abs(v) for v in z.values()) < 4.0, z
    assert result.params.spin.omega_radps[0] > 0
    assert not result.warnings


def test_reported_sigma_is_the_fisher_bound_at_the_estimate(table1_session):
    result = JointFit().fit(table1_session.recording)
    bound = scenario_bound(table1_session.scenario, result.layout)
    # White noise at 0.08: the reported σ is the CRLB up to the noise estimate (~1 %).
    assert np.allclose(result.std / bound.std, 1.0, atol=0.05)
    assert np.allclose(result.noise.marginal_std_mps2, 0.08, rtol=0.03)


def test_opposite_spin_direction_reports_the_same_bench():
    base = table1()
    spin = base.truth.spin
    reversed_truth = base.truth.with_changes(spin=SpinParams(-spin.theta0_rad, -spin.omega_radps))
    scenario = dataclasses.replace(base, truth=reversed_truth)
    result = JointFit().fit(simulate(scenario, np.random.default_rng(4)).recording)
    z = _z_scores(result, scenario)
    assert max(abs(v) for v in z.values()) < 4.0, z
    assert result.params.spin.omega_radps[0] < 0
    # The same bench as the forward spin, judged by the CRLB at the truth (never the fit's σ).
    bound = scenario_bound(scenario, result.layout)
    assert abs(result.value_of("tilt_deg") - 45.0) < 4 * bound.std_of("tilt_deg")
    euler = result.params.bench.misalignment.euler_deg()
    for i, truth in enumerate((30.0, 20.0, 25.0)):
        assert abs(euler[i] - truth) < 4 * bound.std_of(f"euler_{i + 1}_deg"), (i, euler)


def test_low_pass_noise_sigma_accounts_for_fewer_effective_samples():
    scenario = table1(NoiseSpec(0.08, bandwidth_hz=20.0))
    result = JointFit().fit(simulate(scenario, np.random.default_rng(5)).recording)
    white = JointFit(coloured_noise=False).fit(
        simulate(scenario, np.random.default_rng(5)).recording
    )
    bound = scenario_bound(scenario, result.layout)
    z = _z_scores(result, scenario)
    assert max(abs(v) for v in z.values()) < 4.0
    assert np.allclose(result.std / bound.std, 1.0, atol=0.1)
    # A white-noise model would claim about half the true σ (effective fraction ≈ 0.25).
    assert np.all(white.std[5:] / bound.std[5:] < 0.7)
    assert min(result.noise.to_dict()["ar_order"]) >= 2


def test_missing_radius_is_a_clear_error(table1_session):
    rec = table1_session.recording
    rec = dataclasses.replace(
        rec, info=dataclasses.replace(rec.info, radius_m=None), source="bench3.mcap"
    )
    with pytest.raises(RecordingError, match=r"bench3\.mcap.*radius"):
        JointFit().fit(rec)


def test_smaller_offset_twin_is_reported_whatever_the_start():
    session = simulate(table1(), np.random.default_rng(6))
    from wheelcal.estimate.joint.twins import twin_of

    start = twin_of(session.truth)  # start the fit on the wrong twin
    result = JointFit().fit(session.recording, initial=start)
    assert np.allclose(result.params.sensor.offset_mps2, [1, -1, 1], atol=0.05)


def _scenario_with(rotation: Rotation, spin: SpinParams | None = None) -> Scenario:
    base = table1()
    truth = base.truth.with_changes(
        bench=BenchParams(base.truth.bench.tilt_rad, 0.28, rotation),
        sensor=SensorParams([0.1, -0.2, 0.15], [1.01, 0.99, 1.02]),
    )
    if spin is not None:
        truth = truth.with_changes(spin=spin)
    return dataclasses.replace(base, truth=truth)


def test_sensor_axis_along_the_wheel_axis_is_reported_not_identifiable():
    scenario = _scenario_with(Rotation.from_euler_deg(20.0, 0.0, 2.0))  # z within 2° of Z
    result = JointFit().fit(simulate(scenario, np.random.default_rng(7)).recording)
    assert "gain_z" in result.identifiability.poorly_determined
    assert any("sensor axis z lies" in w for w in result.warnings)
    assert any("gain_z is poorly determined" in w for w in result.warnings)
    # What the recording cannot determine is reported as undetermined (null in the JSON);
    # its value is not judged at all — σ_CRLB at the truth is 0.22 in gain.
    undetermined = {name for name, _ in undetermined_parameters(result, Gates())}
    assert undetermined == {"gain_z", "offset_z_mps2"}
    # Everything else is determined and lies within 4 σ_CRLB of the truth.
    z = _z_scores(result, scenario)
    determined = {k: v for k, v in z.items() if k not in undetermined}
    assert max(abs(v) for v in determined.values()) < 4.0, determined


def test_a_wheel_that_hardly_slows_is_flagged():
    spin = SpinParams(0.2, [10.0, -1e-4, 0.0, 0.0])
    scenario = _scenario_with(Rotation.from_euler_deg(30, 20, 25), spin=spin)
    result = JointFit().fit(simulate(scenario, np.random.default_rng(8)).recording)
    assert any("hardly slowed" in w for w in result.warnings)
    assert result.identifiability.poorly_determined


@pytest.mark.parametrize("mode", ["tilt", "vertical"])
def test_geometry_modes_recover_the_radius(mode):
    base = table1()
    tilt_deg = 45.0 if mode == "tilt" else 90.0
    truth = base.truth.with_changes(
        bench=BenchParams(np.deg2rad(tilt_deg), 0.28, base.truth.bench.misalignment)
    )
    scenario = dataclasses.replace(base, truth=truth)
    fitter = JointFit(geometry=mode, known_tilt_deg=tilt_deg if mode == "tilt" else None)
    rec = simulate(scenario, np.random.default_rng(9)).recording
    rec = dataclasses.replace(rec, info=dataclasses.replace(rec.info, radius_m=None))
    result = fitter.fit(rec)
    z = _z_scores(result, scenario)
    assert "radius_m" in result.names
    assert max(abs(v) for v in z.values()) < 4.0, z


def test_systematic_radius_budget_matches_a_fit_with_the_wrong_radius(table1_session):
    rec = table1_session.recording
    right = JointFit().fit(rec)
    wrong = JointFit().fit(
        dataclasses.replace(rec, info=dataclasses.replace(rec.info, radius_m=0.281))
    )
    radius = next(s for s in right.systematic.sources if s.name == "radius")
    predicted = radius.shift_per_unit * 0.001
    observed = wrong.values - right.values
    for name in ("gain_x", "gain_y", "gain_z", "tilt_deg", "offset_z_mps2"):
        i = right.names.index(name)
        assert np.isclose(observed[i], predicted[i], rtol=0.05), name
    # Eq. (9): gains scale like 1/r, so 1 mm in 280 mm is 0.36 % of gain.
    assert np.allclose(
        right.systematic.std_of("gain_x") / right.value_of("gain_x"), 1 / 280, rtol=0.2
    )


def test_result_reports_contract_parameter_names(table1_session):
    result = JointFit().fit(table1_session.recording)
    params = result.parameters()
    for name in ("tilt_deg", "gain_x", "offset_z_mps2", "euler_1_deg", "omega3_radps4"):
        assert set(params[name]) == {"value", "std"}
    names, _, _ = report_transform(result.params, result.layout)
    assert names == result.names
    assert result.t0_unix_ns == result.epoch_unix_ns + 45_000_000_000


def _whitened_chi2(residual_mps2: np.ndarray, noise) -> float:
    """‖r̃‖² written out: each axis's AR filter (scipy), then the innovations' Mahalanobis norm."""
    from scipy.signal import lfilter

    p = noise.order
    innovations = np.array(
        [lfilter(a, [1.0], residual_mps2[:, k])[p:] for k, a in enumerate(noise.ar_polynomials)]
    )
    cov = np.asarray(noise.innovation_cov)
    return float(np.sum(innovations * np.linalg.solve(cov, innovations)))


def _fits_of_three_pushes():
    """The session's final fit (accelerometer only, gyro-aided), and a gyro-aided window fit
    whose iterations end on a step confirmed by the cost alone (its χ² is that step's cost)."""
    from wheelcal.estimate.gyro.knots import choose_knot_spacing
    from wheelcal.estimate.joint.fit import gyro_samples
    from wheelcal.session.fit import SessionFit
    from wheelcal.session.window import find_motion_window
    from wheelcal.simulate import hostile
    from wheelcal.simulate.gyro import GyroSpec

    recording = hostile.three_pushes(np.random.default_rng(9), gyro=GyroSpec()).recording
    for gyro in ("off", "on"):
        out = SessionFit(gyro=gyro).run(recording)
        yield out.result, out.window.recording
    found = find_motion_window(recording)
    window = recording.window(found.start_s, found.end_s)
    tc = window.time_s - 0.5 * (window.time_s[0] + window.time_s[-1])
    spacing = choose_knot_spacing(*gyro_samples(window, tc)).spacing_s
    yield JointFit(use_gyro=True, spline_spacing_s=spacing).fit(window), window


def test_goodness_of_fit_is_the_whitened_cost_at_the_result():
    # χ² is taken from the iterations' last cost (no extra pass): it must be the
    # whitened residual's squared norm at the reported parameters, every stream (the
    # gyro's readings at the rests included).
    from wheelcal.estimate.joint.fit import gyro_samples
    from wheelcal.estimate.joint.gyro_equations import accumulate_gyro

    for r, window in _fits_of_three_pushes():
        chi2 = _whitened_chi2(r.residual_mps2, r.noise)
        entries = 3 * (r.residual_mps2.shape[0] - r.noise.order)
        if r.gyro_noise is not None:
            gyro_t, rates = gyro_samples(window, window.time_s - r.centre_s)
            part = accumulate_gyro(
                r.params, gyro_t, rates, r.layout, r.gyro_noise, False, rests=r.gyro_rests
            )
            chi2, entries = chi2 + part.cost, entries + part.entries
        assert r.chi2 == pytest.approx(chi2, rel=1e-9)
        assert r.entries == entries
        k = r.layout.size
        assert r.chi2_reduced == pytest.approx(chi2 / (entries - k), rel=1e-9)
        assert r.aic == pytest.approx(chi2 + 2 * k, rel=1e-12)
        assert r.bic == pytest.approx(chi2 + k * np.log(entries), rel=1e-12)
        # the estimated noise model makes χ²ᵣ ≈ 1 (documented: not a test of the model)
        assert abs(r.chi2_reduced - 1) < 0.02
