"""A wheel rolling on the ground (issue 13, "rolling wheel"): kinematics, and its fit.

* **Oracle**: the rolling effect's specific force against an independent
  construction — the wheel's orientation in a world frame from ϑ(t) and the
  heading ψ(t), its angular velocity from finite differences of that
  orientation, the hub's velocity from the no-slip condition at the contact
  point, the sensor's position differentiated twice numerically, gravity
  removed, rotated into the bench frame.  The simulated gyro's extra rate ψ̇ u
  is checked against the same numerical angular velocity.
* **Exact Jacobian** of the model with the effect (central differences).
* **Fit**: a rolling wheel is the field fit's (:mod:`wheelcal.estimate.field`,
  issue 41 item 6: the joint fit's ``geometry="rolling"``, the closed loop's
  rolling candidate and the second rolling simulator were folded into it).
  ``--geometry rolling`` and ``geometry="rolling"`` ask for it by name: a vertical
  car wheel from the field simulator (:mod:`wheelcal.simulate.field`) with the
  radius given, and a cambered one without, each calibrated within 5 σ_CRLB at the
  truth (the bound of ``tests/test_field_calibration.py``); the slow study checks
  the reported σ against the observed spread over many drives.  A wheel that does
  not roll, or a recording without a gyroscope, is refused by name.
* **Undeclared**: the same vertical drive with default options (``--geometry
  auto``) takes the field fit too, with the same numbers.
"""

from __future__ import annotations

import numpy as np
import pytest

from wheelcal.model import (
    BenchParams,
    CalibrationParams,
    ParameterLayout,
    Rotation,
    SensorParams,
    SpinParams,
    evaluate,
    predict,
)
from wheelcal.model.kinematics import Kinematics
from wheelcal.model.rolling import Rolling

G = 9.80665
RHO, R_SENSOR = 0.31, 0.13


def _motion(t):
    """A smooth ϑ(t) (speeding up, wobbling) and heading ψ(t) (a turn that tightens)."""
    theta = 0.4 + 20.0 * t + 1.5 * t**2 + 0.3 * np.sin(2.1 * t)
    omega = 20.0 + 3.0 * t + 0.63 * np.cos(2.1 * t)
    omega_dot = 3.0 - 1.323 * np.sin(2.1 * t)
    psi = 0.2 + 0.3 * t + 0.25 * np.sin(0.9 * t)
    psi_dot = 0.3 + 0.225 * np.cos(0.9 * t)
    psi_ddot = -0.2025 * np.sin(0.9 * t)
    return theta, omega, omega_dot, psi, psi_dot, psi_ddot


def _orientation(t):
    """Bench → world rotation: Z the axle (horizontal, heading ψ), up = cosϑ X + sinϑ Y."""
    theta, _, _, psi, _, _ = _motion(np.atleast_1d(t))
    up = np.array([0.0, 0.0, 1.0])
    out = []
    for th, ps in zip(theta, psi, strict=True):
        z = np.array([-np.sin(ps), np.cos(ps), 0.0])
        x = np.cos(th) * up + np.sin(th) * np.cross(up, z)
        y = np.cross(z, x)
        out.append(np.column_stack([x, y, z]))
    return np.array(out)


def _world_rate(t, h=1e-5):
    """Ω in the world frame from the orientation alone: Ṙ Rᵀ = [Ω]×."""
    rdot = (_orientation(t + h) - _orientation(t - h)) / (2 * h)
    skew = rdot @ np.transpose(_orientation(t), (0, 2, 1))
    return np.column_stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]])


def _hub_velocity(t):
    """No slip: the wheel's point at the contact c = hub − ρ e_up is at rest."""
    return RHO * np.cross(_world_rate(t), [0.0, 0.0, 1.0])


def _oracle_specific_force(t, h=1e-4, h_arm=2e-5):
    """Bench-frame specific force of the sensor at p = −r X, by finite differences."""
    hub_accel = (_hub_velocity(t + h) - _hub_velocity(t - h)) / (2 * h)

    def offset(tt):
        return _orientation(tt) @ np.array([-R_SENSOR, 0.0, 0.0])

    arm_accel = (offset(t + h_arm) - 2 * offset(t) + offset(t - h_arm)) / h_arm**2
    force_world = hub_accel + arm_accel + np.array([0.0, 0.0, G])
    return np.einsum("nji,nj->ni", _orientation(t), force_world)  # Rᵀ f


def _identity_params(values=(RHO, 1.0, 0.0)) -> CalibrationParams:
    return CalibrationParams(
        spin=SpinParams(0.0, [1.0]),
        bench=BenchParams(np.pi / 2, R_SENSOR, Rotation.identity()),
        sensor=SensorParams([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
        effects={"rolling": np.asarray(values, float)},
    )


def test_rolling_force_matches_the_finite_difference_oracle():
    t = np.linspace(0.0, 3.0, 61)
    theta, omega, omega_dot, _, psi_dot, psi_ddot = _motion(t)
    effect = Rolling(t, psi_dot, psi_ddot)
    model = evaluate(
        _identity_params(),
        t,
        effects=(effect,),
        kinematics=Kinematics(theta, omega, omega_dot),
    ).predicted_mps2
    oracle = _oracle_specific_force(t)
    error = np.abs(model - oracle).max()
    # The turn matters: without the rolling effect the model misses metres per s².
    assert np.abs(oracle[:, 2]).max() > 2.0
    assert error < 2e-5, error  # the oracle's own finite-difference error: 8.5e-6


def test_the_gyro_reads_spin_and_yaw_as_the_oracle_turns():
    t = np.linspace(0.0, 3.0, 31)
    theta, omega, _, _, psi_dot, _ = _motion(t)
    body = np.einsum("nji,nj->ni", _orientation(t), _world_rate(t))
    up = np.column_stack([np.cos(theta), np.sin(theta), np.zeros_like(t)])
    expected = -omega[:, None] * np.array([0.0, 0.0, 1.0]) + psi_dot[:, None] * up
    assert np.abs(body - expected).max() < 1e-6


def test_zero_means_absent_and_the_jacobian_is_exact():
    t = np.linspace(-20.0, 20.0, 1501)
    yaw = 0.3 * np.sin(0.4 * t) + 0.05
    effect = Rolling(t, yaw)
    base = CalibrationParams(
        spin=SpinParams(0.3, [18.0, 0.4, -0.02, 1e-4]),
        bench=BenchParams(np.pi / 2, R_SENSOR, Rotation.from_euler_deg(30.0, 20.0, 25.0)),
        sensor=SensorParams([0.2, -0.1, 0.3], [0.98, 1.01, 1.03]),
    )
    layout = ParameterLayout(fit_tilt=False, effects=(effect,))
    assert np.array_equal(predict(base, t), predict(base, t, layout))
    p = base.with_changes(effects={"rolling": np.array([RHO, 0.97, 0.02])})
    analytic = evaluate(p, t, layout, jacobian=True).jacobian
    x = layout.pack(p)
    for k, name in enumerate(layout.names):
        h = 1e-6 / 20.0 ** int(name[5]) if name.startswith("omega") else 1e-6
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        fd = (
            predict(layout.unpack(xp, p), t, layout) - predict(layout.unpack(xm, p), t, layout)
        ).T / (2 * h)
        assert np.abs(analytic[k] - fd).max() < 1e-5 * np.abs(fd).max() + 1e-12, name


# --- the fit: the field fit, asked for by name ------------------------------------------

SENSOR = ("gain_x", "gain_y", "gain_z", "offset_x_mps2", "offset_y_mps2", "offset_z_mps2")
Z_MAX = 5.0


def _vertical_car(seed: int, include_radius: bool = True, camber_deg: float | None = 0.0):
    """A car's drive from the field simulator: turns, stops, vibration; the radius in the file.

    With ``camber_deg`` = 0 a vertical wheel on a level road (``road=False``: the scope of
    the joint fit's rolling geometry this replaces); ``None``: a cambered wheel on a road.
    """
    from wheelcal.simulate import car_drive, simulate_field

    rng = np.random.default_rng(seed)
    options = {"include_radius": include_radius}
    if camber_deg is not None:
        options.update(camber_deg=camber_deg, road=False)
    return simulate_field(car_drive(rng, **options), rng)


def _z_crlb(cal, truth) -> dict[str, float]:
    """(value − truth) / σ_CRLB at the truth of every reported sensor parameter and the tilt
    (and the radius, when fitted); parameters reported null are left out."""
    from test_field_calibration import _crlb_at_truth, _truth_value

    crlb = _crlb_at_truth(cal, truth)
    nulls = {name for name, _ in cal.undetermined}
    out = {}
    for name in (*SENSOR, "tilt_deg", "radius_m"):
        if name in nulls or name not in cal.result.names:
            continue
        error = cal.result.value_of(name) - _truth_value(truth, name, cal.result.centre_s)
        out[name] = error / crlb[name]
    return out


def _rolling_radius_z(cal, truth) -> float:
    """ρ's error in units of its reported σ."""
    rho = cal.result.value_of("rolling.radius_m")
    return (rho - truth.rolling_radius_m) / cal.result.std_of("rolling.radius_m")


def test_geometry_rolling_is_the_field_fit_within_5_sigma_crlb():
    import wheelcal

    sim = _vertical_car(3)
    assert sim.recording.info.radius_m == pytest.approx(sim.truth.radius_m)
    cal = wheelcal.calibrate(sim.recording, geometry="rolling")
    session = cal.session
    assert (session.geometry, session.model, session.geometry_source) == (
        "rolling",
        "field",
        "given",
    )
    assert session.geometry_reason.startswith("the rolling geometry was given")
    assert "radius_m" not in cal.result.names  # given: held, not fitted
    z = _z_crlb(cal, sim.truth)
    assert set(SENSOR) - {n for n, _ in cal.undetermined} <= set(z)
    assert max(abs(v) for v in z.values()) <= Z_MAX, z
    assert abs(_rolling_radius_z(cal, sim.truth)) <= Z_MAX
    # Undeclared (the default --geometry auto) the carrier's turns route it to the same
    # fit: the same numbers, only the geometry's source and reason differ.
    auto = wheelcal.calibrate(sim.recording)
    assert (auto.session.model, auto.session.geometry_source) == ("field", "detected")
    np.testing.assert_allclose(auto.result.values, cal.result.values, rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(auto.result.std, cal.result.std, rtol=1e-12, atol=0.0)
    # A window given is the field fit's window (not the drive it would find).
    given = wheelcal.calibrate(sim.recording, geometry="rolling", start_s=5.0, end_s=95.0)
    assert given["source"]["window_s"] == [5.0, 95.0]
    assert given["source"]["window_reason"].startswith("window given on the command line")
    assert given.session.model == "field"


def test_geometry_rolling_on_the_command_line_without_a_radius(tmp_path):
    import json

    from wheelcal.cli.main import main
    from wheelcal.io import write_recording

    sim = _vertical_car(4, include_radius=False, camber_deg=None)  # cambered 0–2°
    path = tmp_path / "drive.mcap"
    write_recording(sim.recording, path)
    assert main(["calibrate", str(path), "--out", str(tmp_path), "--geometry", "rolling"]) == 0
    document = json.loads((tmp_path / "drive.calibration.json").read_text())
    bench = document["bench"]
    assert (bench["geometry"], bench["geometry_source"], bench["radius_source"]) == (
        "rolling",
        "given",
        "fitted",
    )
    rho = document["effects"]["rolling"]["radius_m"]
    assert abs(rho["value"] - sim.truth.rolling_radius_m) <= Z_MAX * rho["std"]
    import wheelcal

    again = wheelcal.calibrate(path, geometry="rolling")
    z = _z_crlb(again, sim.truth)
    assert {"radius_m", "tilt_deg"} <= set(z)
    assert max(abs(v) for v in z.values()) <= Z_MAX, z
    # the file is the API's answer
    np.testing.assert_allclose(document["sensor"]["gain"], again["sensor"]["gain"], rtol=1e-12)
    assert bench["radius_m"] == pytest.approx(again.result.value_of("radius_m"), rel=1e-12)


def test_geometry_rolling_refuses_a_wheel_that_does_not_roll_and_needs_a_gyroscope():
    import dataclasses

    import wheelcal
    from wheelcal.recording import CalibrationRefused, RecordingError
    from wheelcal.simulate import bench_spin, simulate_field

    rng = np.random.default_rng(2)
    sim = simulate_field(bench_spin(rng, include_radius=True), rng)  # a fixed, tilted axle
    with pytest.raises(CalibrationRefused) as refused:
        wheelcal.calibrate(sim.recording, geometry="rolling")
    assert refused.value.gate == "motion"
    assert refused.value.reason.startswith("the rolling geometry was given"), refused.value
    assert "a fixed axle: the hub does not travel" in refused.value.reason
    assert "geometry= auto (the default)" in refused.value.fix  # in the API's words
    no_gyro = dataclasses.replace(sim.recording, gyro_radps=None)
    needs = "the rolling geometry needs the recording's gyroscope"
    with pytest.raises(RecordingError, match=needs):
        wheelcal.calibrate(no_gyro, geometry="rolling")
    with pytest.raises(RecordingError, match=needs):
        wheelcal.calibrate(sim.recording, geometry="rolling", gyro="off")


#: The groups of the study (``docs/rolling/montecarlo.py`` prints them).
GROUPS = {
    "gain": SENSOR[:3],
    "offset": SENSOR[3:],
    "tilt": ("tilt_deg",),
    "rho": ("rolling.radius_m",),
}


def _study_run(seed: int) -> tuple[dict, dict] | str:
    """One vertical car drive with the radius given, ``geometry="rolling"``: per parameter
    (value − truth) / σ_CRLB at the truth, and (value − truth) / reported σ; or the gate
    that refused it."""
    import wheelcal
    from test_field_calibration import _crlb_at_truth
    from wheelcal.recording import CalibrationRefused

    sim = _vertical_car(seed)
    try:
        cal = wheelcal.calibrate(sim.recording, geometry="rolling")
    except CalibrationRefused as refused:
        return refused.gate
    z = _z_crlb(cal, sim.truth)
    crlb = _crlb_at_truth(cal, sim.truth)
    error = cal.result.value_of("rolling.radius_m") - sim.truth.rolling_radius_m
    z["rolling.radius_m"] = error / crlb["rolling.radius_m"]
    scaled = {
        name: z[name] * crlb[name] / cal.result.std_of(name)
        for name in z
        if name in cal.result.names
    }
    return z, scaled


def study_table(runs) -> dict[str, tuple[float, float, float]]:
    """Per group: worst |error| / σ_CRLB, spread / σ_CRLB, reported σ / spread (refusals,
    a gate's name, left out)."""
    runs = [run for run in runs if not isinstance(run, str)]
    out = {}
    for group, names in GROUPS.items():
        z = np.array([run[0][n] for run in runs for n in names if n in run[0]])
        scaled = np.array([run[1][n] for run in runs for n in names if n in run[1]])
        out[group] = (
            float(np.max(np.abs(z))),
            float(np.std(z, ddof=1)),
            float(1.0 / np.std(scaled, ddof=1)),
        )
    return out


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="drive 118 (a level road, camber 0): its camber 5.04 σ_CRLB off (4.92 at f29857d). "
    "The gyro's G reads the speed changes as a roll the 2-minute basis lacks (0.89° beyond "
    "it: the track is followed); zeroed G gives 0.02° off, and the basis's travel_accel "
    "term 3.3 σ_CRLB, but it raises the measured drives' rms z to 1.30; open in issue 37",
)
def test_geometry_rolling_drives_within_5_sigma_crlb_and_honest_sigma_full():
    """Vertical car wheels with the radius given (40 drives): ≥ 90 % calibrated (a refusal
    names its gate), every parameter within 5 σ_CRLB at the truth, and the reported σ /
    observed spread in 0.7–1.4 per group — the camber's at least 0.7: where its track is
    followed, its σ carries the gyro's g-sensitivity prior (``_crlb_at_truth``), which a
    level road's drives do not draw (1.73 on these)."""
    runs = [_study_run(100 + seed) for seed in range(40)]
    assert sum(not isinstance(run, str) for run in runs) >= 0.9 * len(runs), runs
    for group, (worst, _, honest) in study_table(runs).items():
        assert worst <= Z_MAX, (group, worst)
        assert honest >= 0.7, (group, honest)
        assert group == "tilt" or honest <= 1.4, (group, honest)
