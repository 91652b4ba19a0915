"""Wheels in the field through the default path: ``wheelcal.calibrate`` with no radius.

The simulator (:mod:`wheelcal.simulate.field`) draws car, robot and wheelchair
drives with turns, stops, road vibration and camber; each is calibrated with
default options (``--geometry auto``), so the geometry, the sensor's radius and
the camber come from the data.  Every reported parameter must lie within
``Z_MAX`` σ_CRLB of the truth, the bound taken **at the truth** (the truth's
sensor and bench in the final model, the fit's noise model: a fit's own σ could
be inflated to pass anything), or be reported null.

CI runs one drive of each kind; ``-m slow`` runs the study of the issue
(``STUDY_DRIVES`` per kind): ≥ 95 % calibrated, geometry right in ≥ 99 %, the
reported σ against the observed spread of (value − truth).
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest

import wheelcal
from wheelcal.estimate.joint.crlb import cramer_rao_bound
from wheelcal.model import BenchParams
from wheelcal.recording import CalibrationRefused, RecordingError
from wheelcal.session.gates import Gates
from wheelcal.simulate import (
    bench_spin,
    car_drive,
    robot_drive,
    simulate_field,
    stand_spin,
    wheelchair_coast,
)
from wheelcal.simulate.logger_glitches import Glitches

DRIVES = {"car": car_drive, "robot": robot_drive, "wheelchair": wheelchair_coast}


def _car_with_its_ranges(rng):
    """A car drive with an Xsens-DOT's ranges, ±16 g and ±2000 °/s: both clip above ~37 km/h."""
    from wheelcal.simulate.noise import Quantiser

    scenario = car_drive(rng)
    gyro = dataclasses.replace(scenario.gyro, full_scale_dps=2000.0)
    return dataclasses.replace(scenario, gyro=gyro, quantiser=Quantiser(full_scale_g=16.0))


#: Drives outside the study's three kinds, by name.
OTHER_DRIVES = {"car with its ranges": _car_with_its_ranges}
SENSOR = ("gain_x", "gain_y", "gain_z", "offset_x_mps2", "offset_y_mps2", "offset_z_mps2")
#: The parameters checked against the truth (the rolling radius ρ is not the sensor's).
CHECKED = (*SENSOR, "radius_m", "tilt_deg")
Z_MAX = 5.0
STUDY_DRIVES = int(os.environ.get("WHEELCAL_FIELD_STUDY_DRIVES", "100"))


def _truth_value(truth, name: str, centre_s: float) -> float:
    """The truth of a reported parameter; the tilt at the window's centre (a camber that
    changes is reported there, as the CONTRACT has drifting quantities)."""
    if name.startswith("gain_"):
        return float(truth.sensor.gain["xyz".index(name[-1])])
    if name.startswith("offset_"):
        return float(truth.sensor.offset_mps2["xyz".index(name[7])])
    return {"radius_m": truth.radius_m, "tilt_deg": truth.tilt_at_deg(centre_s)}[name]


def _crlb_at_truth(calibration, truth) -> dict[str, float]:
    """σ_CRLB of each reported parameter with the truth's sensor, radius and tilt."""
    r = calibration.result
    fitted = r.params.bench
    tilt = np.deg2rad(truth.tilt_at_deg(r.centre_s))
    bench = BenchParams(tilt, truth.radius_m, fitted.misalignment)
    at_truth = r.params.with_changes(sensor=truth.sensor, bench=bench)
    bound = cramer_rao_bound(at_truth, r.centred_time_s, r.noise, r.layout)
    out = dict(zip(bound.names, bound.std, strict=True))
    lean = calibration.to_dict()["bench"].get("lean", {})
    if lean.get("track", {}).get("followed"):
        # The camber at the window's centre is set, with a track, by the gyro's errors the
        # track carries (its g-sensitivity across the axle, 0.1 °/s/g: 1–3° of camber on a
        # car) more than by the accelerometer's noise, which the bound holds alone (0.06°);
        # the fit propagates that prior into its σ, and the spread of study drives matches
        # it (σ/spread ≥ 1).  The tilt is judged against that σ where it is the larger.
        out["tilt_deg"] = max(out["tilt_deg"], r.std_of("tilt_deg"))
    return out


def _assert_within_the_bound(calibration, truth) -> None:
    """Every checked parameter not reported null within ``Z_MAX`` σ_CRLB of the truth."""
    crlb = _crlb_at_truth(calibration, truth)
    for name in CHECKED:
        if name in dict(calibration.undetermined):
            continue
        truth_value = _truth_value(truth, name, calibration.result.centre_s)
        error = calibration.result.value_of(name) - truth_value
        assert abs(error / crlb[name]) <= Z_MAX, (name, error / crlb[name])


@dataclasses.dataclass(frozen=True)
class Drive:
    kind: str
    seed: int
    geometry: str
    refused: str | None
    z_crlb: dict  # name → (value − truth) / σ_CRLB at the truth
    z_reported: dict  # name → (value − truth) / reported σ
    nulls: tuple
    warnings: tuple = ()


def _calibrate(kind: str, seed: int) -> Drive:
    rng = np.random.default_rng(seed)
    sim = simulate_field({**DRIVES, **OTHER_DRIVES}[kind](rng), rng)
    assert sim.recording.info.radius_m is None  # a logger stores no radius
    try:
        cal = wheelcal.calibrate(sim.recording)
    except (CalibrationRefused, RecordingError) as exc:
        return Drive(kind, seed, "", str(exc), {}, {}, ())
    r = cal.result
    crlb = _crlb_at_truth(cal, sim.truth)
    nulls = tuple(n for n, _ in cal.undetermined)
    z_crlb, z_rep = {}, {}
    for name in CHECKED:
        if name in nulls or name not in r.names:
            continue
        error = r.value_of(name) - _truth_value(sim.truth, name, r.centre_s)
        z_crlb[name] = error / crlb[name]
        z_rep[name] = error / r.std_of(name)
    warnings = tuple(cal.session.assessment.warnings)
    return Drive(kind, seed, cal.session.geometry, None, z_crlb, z_rep, nulls, warnings)


@pytest.mark.parametrize("kind", sorted(DRIVES))
def test_a_drive_calibrates_with_default_options_and_no_radius(kind):
    drive = _calibrate(kind, seed=11)
    assert drive.refused is None, drive.refused
    assert drive.geometry == "rolling"
    worst = max(drive.z_crlb.items(), key=lambda kv: abs(kv[1]))
    assert abs(worst[1]) <= Z_MAX, (kind, worst, drive.z_crlb)
    # the radius and the tilt are always reported; what is null is a sensor parameter
    assert {"radius_m", "tilt_deg"} <= set(drive.z_crlb)
    assert set(drive.nulls) <= set(SENSOR)


def test_a_robot_whose_gyro_reads_gravity_as_a_steady_yaw():
    """Regression: with the yaw's steady offset ε held at zero, this drive's r was 7.5 σ off."""
    drive = _calibrate("robot", seed=308)
    assert drive.refused is None, drive.refused
    worst = max(drive.z_crlb.items(), key=lambda kv: abs(kv[1]))
    assert abs(worst[1]) <= Z_MAX, worst


def test_a_robot_whose_gyro_has_a_bias_across_the_axle():
    """Regression: the bias (0.026 rad/s) leaned the gyro's axle by 0.15° and read as a yaw
    turning with the wheel; offset_y came out 7 σ off."""
    drive = _calibrate("robot", seed=1061)
    assert drive.refused is None, drive.refused
    worst = max(drive.z_crlb.items(), key=lambda kv: abs(kv[1]))
    assert abs(worst[1]) <= Z_MAX, worst


def test_a_drive_with_gyro_glitches_and_leading_zero_rows_calibrates():
    """Regression: the reader leaves a glitch's row out (NaN) and the field fit's wheel
    angle could not integrate it (ValueError: one finite value per time)."""
    rng = np.random.default_rng(11)
    sim = simulate_field(car_drive(rng, glitches=Glitches(gyro_spikes=2, leading_zero_rows=5)), rng)
    cal = wheelcal.calibrate(sim.recording)
    notes = " ".join(cal.session.recording.notes)
    assert "a logger's glitch" in notes and "dropped the first 5 samples" in notes
    assert "carried across" not in cal["source"]["window_reason"]  # a glitch's row is bridged
    _assert_within_the_bound(cal, sim.truth)


@pytest.mark.parametrize("accel_range_g", [None, 16.0])
def test_a_car_whose_gyro_clips_is_calibrated_between_the_clippings(tmp_path, accel_range_g):
    """Regression: a ±2000 °/s gyro on a car wheel clips above ~35 rad/s; its rows are left
    out, and the wheel angle was interpolated across 35 s of them — refused as
    `offset_range` (−13.9 m/s², "check the unit and the radius"), and the fast stretch
    outside the window passed for a rest (|a| 250 m/s² "at rest").  Its ±16 g
    accelerometer clips there too (32 % of the samples), which had refused the file."""
    from wheelcal.io import write_recording
    from wheelcal.simulate.noise import Quantiser

    rng = np.random.default_rng(1000)
    scenario = car_drive(rng)
    gyro = dataclasses.replace(scenario.gyro, full_scale_dps=2000.0)
    quantiser = None if accel_range_g is None else Quantiser(full_scale_g=accel_range_g)
    scenario = dataclasses.replace(scenario, gyro=gyro, quantiser=quantiser)
    sim = simulate_field(scenario, rng)
    path = tmp_path / "clipping.mcap"
    write_recording(sim.recording, path)
    cal = wheelcal.calibrate(path)
    notes = " ".join(cal.session.recording.notes)
    if accel_range_g is None:  # the gyro's clipped rows are left out: NaN
        assert "clipped at the gyro range" in notes, notes
    else:  # … and with the accelerometer's, dropped: a gap
        assert "clipped samples (32 %)" in notes, notes
    assert "cannot be carried across" in cal["source"]["window_reason"]
    start_s, end_s = cal["source"]["window_s"]
    assert end_s - start_s > 30.0
    _assert_within_the_bound(cal, sim.truth)
    rests = cal.session.rests
    assert rests, "the drive's stops are rests"
    for rest in rests:  # still wheels: |a| is gravity, not a fast wheel's centripetal force
        assert abs(np.linalg.norm(rest.mean_mps2) - 9.81) < 1.0, (rest.start_s, rest.mean_mps2)


def test_a_final_fit_that_turns_z_down_reports_its_twin_with_z_up():
    """Regression: a car whose sensor clips (the drive cut to 57 s between clippings),
    its axle offset undetermined; the final fit, on every sample with the cross-axis
    terms, ended with Z pointing down — tilt 93.3 ± 1.3° for a truth of 86.5° (5.2 σ),
    though the same physics as 86.7° with the frame turned about X."""
    rng = np.random.default_rng(1030)
    sim = simulate_field(_car_with_its_ranges(rng), rng)
    cal = wheelcal.calibrate(sim.recording)
    assert cal.result.value_of("tilt_deg") <= 90.0
    _assert_within_the_bound(cal, sim.truth)


def test_the_gyros_stated_sensitivity_to_acceleration_reaches_the_field_fit():
    # --gyro-g-sensitivity had reached only the bench's fit: the field fit's prior stayed at
    # 0.1 °/s/g whatever was stated.  A tighter prior narrows the camber's σ (which trades
    # with G): 0.025° against 0.029° on this car.
    rng = np.random.default_rng(5)
    sim = simulate_field(car_drive(rng), rng)
    sigma = {}
    for stated in (0.1, 0.02):
        cal = wheelcal.calibrate(sim.recording, gyro_g_sensitivity_dps_per_g=stated)
        (angle,) = [e for e in cal.result.layout.effects if e.name == "gyro_angle"]
        expected = np.deg2rad(stated) / 9.80665
        np.testing.assert_allclose(angle.prior_std_values()[-3:], expected, rtol=1e-12)
        sigma[stated] = cal.result.std_of("tilt_deg")
    assert sigma[0.02] < 0.9 * sigma[0.1], sigma


def _leans_in_turns(warnings) -> bool:
    return any("camber follows the turns" in w for w in warnings)


def test_a_car_that_rolls_a_little_in_its_turns_follows_the_track_and_reports_the_roll():
    # 0.15°/(m/s²) of body roll: 0.95° of lean, which moved this drive's camber by 5 σ when
    # the model held one camber.  The camber now follows the gyro's track (the roll is
    # modelled, so no warning), the answer is within the bound of the truth, and the JSON
    # still says how much of the camber follows the turns (k = 0.12 ± 0.004°/(m/s²));
    # the same drive without roll holds one camber and reads no roll.
    rng = np.random.default_rng(1001)
    rolled = dataclasses.replace(car_drive(rng, road=False), body_roll_deg_per_mps2=0.15)
    sim = simulate_field(rolled, rng)
    cal = wheelcal.calibrate(sim.recording)
    assert not _leans_in_turns(cal.session.assessment.warnings)
    lean = cal.to_dict()["bench"]["lean"]  # the figures, in the calibration JSON
    assert lean["track"]["followed"] is True, lean
    assert 0.10 <= lean["in_turns_deg_per_mps2"] <= 0.16, lean
    assert lean["in_turns_deg_per_mps2"] > 5 * lean["in_turns_std_deg_per_mps2"], lean
    assert 0.2 <= lean["in_turns_deg"] < lean["change_deg"] + 0.5, lean
    _assert_within_the_bound(cal, sim.truth)
    rng = np.random.default_rng(1001)
    cal = wheelcal.calibrate(simulate_field(car_drive(rng, road=False), rng).recording)
    lean = cal.to_dict()["bench"]["lean"]
    assert lean["track"]["followed"] is False, lean
    assert abs(lean["in_turns_deg_per_mps2"]) < 0.02 and lean["change_deg"] < 1.0, lean


def test_a_steered_front_wheel_reads_its_camber_track_at_the_fitted_wheel_angle():
    """Regression (issue 37): a steered front wheel on a road (caster 6.4°: its camber
    changes by 7.7° with the steering and the road).  The track, read once at the first
    pass's wheel angle, held 14° of change where the truth has 7.7° (the angle's error
    reads the yaw as a roll) and the camber at the centre came out 3.3° off, 12.6 σ_CRLB;
    read again at each pass's angle it is 1.1 σ_CRLB off, every other parameter ≤ 3.9."""
    rng = np.random.default_rng(1065)
    sim = simulate_field(DRIVES["car"](rng), rng)
    assert sim.truth.road.caster_deg > 0  # the drive is the steered wheel it says
    gamma = sim.truth.camber_series_rad
    assert np.rad2deg(np.ptp(gamma)) > 5.0
    cal = wheelcal.calibrate(sim.recording)
    assert cal.to_dict()["bench"]["lean"]["track"]["followed"] is True
    _assert_within_the_bound(cal, sim.truth)
    crlb = _crlb_at_truth(cal, sim.truth)
    error = cal.result.value_of("tilt_deg") - sim.truth.tilt_at_deg(cal.result.centre_s)
    assert abs(error / crlb["tilt_deg"]) <= 2.5, error / crlb["tilt_deg"]


@pytest.mark.parametrize("seed", [3, 4])
def test_a_car_that_rolls_in_its_turns_is_calibrated_right_or_refused_by_name(seed):
    """A camber that follows the turns (body roll, 0.8°/(m/s²): 2–3° over the drive).

    With one camber the fit put it into offset_x (15 σ off) and the camber (16 σ), so
    such drives were refused; the camber now follows the gyro's track, and the answer
    must be within the bound of the truth (the camber at the window's centre) or be
    refused by name — never confidently wrong.  These two drives calibrate.
    """
    rng = np.random.default_rng(seed)
    scenario = dataclasses.replace(car_drive(rng, road=False), body_roll_deg_per_mps2=0.8)
    sim = simulate_field(scenario, rng)
    cal = wheelcal.calibrate(sim.recording)
    assert cal.to_dict()["bench"]["lean"]["track"]["followed"] is True
    _assert_within_the_bound(cal, sim.truth)


def test_a_negative_radius_has_a_twin_with_the_same_forces():
    """r → −r with ϑ + π and R·diag(−1, −1, 1): the model predicts the same samples."""
    from wheelcal.estimate.field.fit import _half_turned
    from wheelcal.model import evaluate
    from wheelcal.simulate import table1

    params = table1().truth
    t = np.linspace(-40.0, 40.0, 4001)
    twin = _half_turned(params)
    assert twin.bench.radius_m == -params.bench.radius_m
    np.testing.assert_allclose(
        evaluate(twin, t).predicted_mps2, evaluate(params, t).predicted_mps2, atol=1e-9
    )


def test_calibrate_prints_and_writes_the_detected_geometry(tmp_path, capsys):
    from wheelcal.cli.main import main

    drive, out = tmp_path / "drive.mcap", tmp_path / "cal"
    assert main(["simulate", str(drive), "--preset", "car", "--seed", "5"]) == 0
    assert main(["calibrate", str(drive), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "geometry rolling (detected): the gyroscope shows the wheel's carrier turning" in (
        printed
    )
    assert "model: the field fit" in printed
    bench = json.loads((out / "drive.calibration.json").read_text())["bench"]
    assert (bench["geometry"], bench["radius_source"]) == ("rolling", "fitted")


def test_diagnose_of_a_wheel_in_the_field_says_the_steps_are_for_bench_spins(tmp_path, capsys):
    # The field fit has no closed loop: diagnose prints the calibration it has, says the
    # step-by-step diagnosis is for bench spins, and writes the same calibration (it
    # crashed with "'NoneType' object has no attribute 'steps'").
    from wheelcal.cli.main import main

    drive, out = tmp_path / "car.mcap", tmp_path / "diag"
    assert main(["simulate", str(drive), "--preset", "car", "--seed", "5"]) == 0
    assert main(["diagnose", str(drive), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "model: the field fit" in printed
    assert "no step-by-step diagnosis" in printed and "for bench spins" in printed
    assert (out / "car.calibration.json").exists()
    assert not (out / "car.diagnosis.json").exists()


def test_a_simulated_rolling_car_from_the_command_line(tmp_path, capsys):
    from wheelcal.cli.main import main

    drive, out = tmp_path / "roll.mcap", tmp_path / "cal"
    argv = ["simulate", str(drive), "--preset", "car", "--seed", "3"]
    assert main([*argv, "--body-roll-deg-per-mps2", "0.8"]) == 0
    assert main(["calibrate", str(drive), "--out", str(out)]) == 0
    lean = json.loads((out / "roll.calibration.json").read_text())["bench"]["lean"]
    assert lean["track"]["followed"] is True and lean["change_deg"] > 1.0
    assert set(lean["check"]) >= {"statistic", "dof", "p_value", "shift_sigma", "shift_z"}
    # a limit given on the camber's change refuses it by name
    out2 = tmp_path / "cal2"
    assert main(["calibrate", str(drive), "--out", str(out2), "--max-lean-change-deg", "1"]) == 1
    captured = capsys.readouterr()
    assert "refused (lean): the wheel's camber changes by" in captured.out + captured.err
    assert not list(out2.glob("*.calibration.json"))
    # a fixed axle cannot lean: a usage error, no file
    stand = tmp_path / "stand.mcap"
    assert main(["simulate", str(stand), "--preset", "stand", "--body-roll-deg-per-mps2", "1"]) == 2
    assert "needs a rolling wheel" in capsys.readouterr().err and not stand.exists()


def test_a_gyro_sensitive_to_gravity_is_not_read_as_a_lean():
    # G's in-plane cross terms (0.3 °/s/g, a poor MEMS part) turn gravity into
    # a rate along the direction of travel: constant while the wheel turns, set by its angle
    # while it stands.  Read as a lean, it walks over the stops (0.6° here, against 0.4° with
    # gravity's cos 2ϑ, sin 2ϑ in the lean's regressions; study cars with G drawn at
    # 0.1 °/s/g were refused as "lean" at 1.1–1.2°).  The exact check is in test_field_model.
    rng = np.random.default_rng(1009)
    scenario = car_drive(rng, camber_deg=1.0, road=False)
    g_sens = ((0.0, 0.3, 0.0), (0.3, 0.0, 0.0), (0.0, 0.0, 0.0))
    gyro = dataclasses.replace(scenario.gyro, g_sensitivity_dps_per_g=g_sens)
    sim = simulate_field(dataclasses.replace(scenario, gyro=gyro), rng)
    gates = Gates(max_lean_change_deg=0.5)
    cal = wheelcal.calibrate(sim.recording, gates=gates)
    assert cal.session.geometry == "rolling"
    _assert_within_the_bound(cal, sim.truth)


def test_the_session_says_where_its_geometry_came_from():
    rng = np.random.default_rng(5)
    sim = simulate_field(car_drive(rng, road=False), rng)
    cal = wheelcal.calibrate(sim.recording)
    session = cal.session
    assert (session.geometry, session.geometry_source, session.model) == (
        "rolling",
        "detected",
        "field",
    )
    assert "carrier turning" in session.geometry_reason
    # the hub's ρ in the reason is the answer's (a leading pass's was 20 % off), near the truth
    rho = cal.result.value_of("rolling.radius_m")
    assert f"the hub travels (ρ = {rho:.3f} m" in session.geometry_reason
    assert abs(rho - sim.truth.rolling_radius_m) < 0.01
    document = cal.to_dict()
    assert document["bench"]["geometry"] == "rolling"
    assert document["bench"]["geometry_source"] == "detected"
    assert document["bench"]["radius_source"] == "fitted"
    assert document["bench"]["radius_std_m"] > 0
    assert document["fit"]["model"] == "field"
    assert 0.0 <= document["bench"]["lean"]["change_deg"] < 1.0  # the `lean` gate's measure


def _without_radius(sim):
    rec = sim.recording
    return dataclasses.replace(rec, info=dataclasses.replace(rec.info, radius_m=None))


def test_a_vertical_wheel_on_a_stand_fits_its_radius():
    rng = np.random.default_rng(1)
    sim = simulate_field(stand_spin(rng), rng)
    cal = wheelcal.calibrate(_without_radius(sim))
    assert cal.session.geometry == "vertical"
    assert cal.session.geometry_source == "detected"
    r = cal.result
    error = r.value_of("radius_m") - sim.truth.radius_m
    assert abs(error) <= Z_MAX * _crlb_at_truth(cal, sim.truth)["radius_m"]


def test_a_tilted_fixed_axle_without_radius_asks_for_it_by_name():
    rng = np.random.default_rng(1)
    sim = simulate_field(bench_spin(rng), rng)
    with pytest.raises(RecordingError, match=r"radius .* is needed.*--radius"):
        wheelcal.calibrate(_without_radius(sim))


def test_a_bench_spin_with_its_radius_stays_the_bench_fit():
    rng = np.random.default_rng(2)
    sim = simulate_field(bench_spin(rng, include_radius=True), rng)
    cal = wheelcal.calibrate(sim.recording)
    assert (cal.session.geometry, cal.session.geometry_source) == ("bench", "detected")
    assert cal.session.model != "field"
    assert "lean" not in cal.to_dict()["bench"]  # a fixed axle has no lean to report


# --- the study (slow) -----------------------------------------------------------------


@pytest.fixture(scope="module")
def study():
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    jobs = [(kind, 1000 + seed) for kind in sorted(DRIVES) for seed in range(STUDY_DRIVES)]
    workers = int(os.environ.get("WHEELCAL_FIELD_STUDY_WORKERS", os.cpu_count() or 1))
    fork = multiprocessing.get_context("fork")  # the test module needs no import by name
    with ProcessPoolExecutor(max_workers=workers, mp_context=fork) as pool:
        drives = list(pool.map(_calibrate, *zip(*jobs, strict=True), chunksize=4))
    for kind in sorted(DRIVES):
        _print_study(kind, [d for d in drives if d.kind == kind])
    return drives


def _print_study(kind: str, drives: list[Drive]) -> None:
    done = [d for d in drives if d.refused is None]
    print(f"\n{kind}: {len(done)}/{len(drives)} calibrated, ", end="")
    print(f"rolling {sum(d.geometry == 'rolling' for d in done)}")
    for name in CHECKED:
        z = np.array([d.z_reported[name] for d in done if name in d.z_reported])
        zc = np.array([d.z_crlb[name] for d in done if name in d.z_crlb])
        if z.size:
            print(
                f"  {name:14s} n {z.size:3d}  spread/σ {np.std(z):.2f}  "
                f"spread/σ_CRLB {np.std(zc):.2f}  max|z_CRLB| {np.max(np.abs(zc)):.1f}"
            )


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(DRIVES))
def test_study_calibrates_and_detects_nearly_every_drive(study, kind):
    drives = [d for d in study if d.kind == kind]
    done = [d for d in drives if d.refused is None]
    assert len(done) >= 0.95 * len(drives), [d.refused for d in drives if d.refused]
    assert sum(d.geometry == "rolling" for d in done) >= 0.99 * len(done)


@pytest.mark.slow
@pytest.mark.parametrize("kind", sorted(DRIVES))
def test_study_no_drive_is_said_to_lean_in_its_turns(study, kind):
    # none of the study's wheels leans: the warning of a camber that follows the turns
    # (k·v ψ̇ from the gyro) must not fire on them
    warned = [d.seed for d in study if d.kind == kind and _leans_in_turns(d.warnings)]
    assert not warned, warned


@pytest.mark.slow
@pytest.mark.parametrize(
    "kind",
    [
        pytest.param(
            "car",
            marks=pytest.mark.xfail(
                strict=True,
                reason="a road car: 2 of 100 drives 5.2–5.3 σ_CRLB off, a gain each (the "
                "offsets' worst 4.7 and the camber's 2.7 since the passes settle)",
            ),
        ),
        "robot",
        # The wheelchair: worst 3.4 σ_CRLB in 100 drives since the hub's travel pass runs
        # from the start (177795a; before, 5.4 on drive 1005's tilt, now 3.4: the leading
        # passes' path moves that drive's camber by 2 σ_CRLB, the other 99 by ≤ 0.53).
        "wheelchair",
    ],
)
def test_study_every_parameter_within_5_sigma_crlb_of_the_truth(study, kind):
    bad = [
        (d.seed, name, round(z, 1))
        for d in study
        if d.kind == kind
        for name, z in d.z_crlb.items()
        if abs(z) > Z_MAX
    ]
    assert not bad, bad


#: The car on a measured drive's road (a camber that follows the road, the carrier shaking in
#: rotation): its gains' σ match their spread (spread/σ 1.02–1.07 over 100 drives) and so
#: does the radius's (1.06).  Since the camber's passes settle (the cross-axis terms in
#: the leading passes, Anderson's mixing) the offsets' and the camber's errors fell (rms
#: 0.87–1.05 and 0.74 σ_CRLB, worst 4.7 and 2.7; before, 1.0–1.2 and 0.82, worst 5.5 and
#: 2.8), their σ did not: 1.37–1.72 and 1.35× their spread.  The robot: its camber's σ is
#: 1.4× its spread, from the gyro's angle walk (what the gyro's noise moves the camber by
#: is 0.75 of the walk's propagated σ, rms over 8 drives; the offsets' 0.8–1.1).  Known
#: gaps, named; strict, so a fix shows.
_ROAD_CAR_SIGMA = pytest.mark.xfail(
    strict=True, reason="a road car's offsets' σ are 1.37–1.72× their spread"
)
_ROAD_CAR_CAMBER_SIGMA = pytest.mark.xfail(
    strict=True, reason="a road car's camber σ is 1.35× its spread (its errors fell, σ stayed)"
)
_ROBOT_CAMBER_SIGMA = pytest.mark.xfail(
    strict=True, reason="a robot's camber σ is 1.4× its spread (the angle walk's share)"
)
#: The wheelchair's camber and radius σ match their spread (0.91 and 0.90 over 100 drives;
#: 0.75 and 0.83 before 177795a, mostly drive 1005's camber, 5.4 σ_CRLB off then and 3.4
#: now).


def _sigma_over_spread(study, kind: str, names) -> dict[str, float]:
    """Reported σ / observed spread of each parameter (from 20 drives on)."""
    done = [d for d in study if d.kind == kind and d.refused is None]
    out = {}
    for name in names:
        z = np.array([d.z_reported[name] for d in done if name in d.z_reported])
        if z.size >= 20:
            out[name] = 1.0 / float(np.std(z))
    return out


@pytest.mark.slow
@pytest.mark.parametrize(
    "kind", [pytest.param("car", marks=_ROAD_CAR_SIGMA), "robot", "wheelchair"]
)
def test_study_reported_sigma_matches_the_spread(study, kind):
    ratios = _sigma_over_spread(study, kind, SENSOR)
    assert len(ratios) == len(SENSOR)
    assert all(0.8 <= r <= 1.25 for r in ratios.values()), (kind, ratios)


@pytest.mark.slow
@pytest.mark.parametrize(
    "kind",
    [
        pytest.param("car", marks=_ROAD_CAR_CAMBER_SIGMA),
        pytest.param("robot", marks=_ROBOT_CAMBER_SIGMA),
        "wheelchair",
    ],
)
def test_study_reported_sigma_of_the_geometry_matches_the_spread(study, kind):
    ratios = _sigma_over_spread(study, kind, ("radius_m", "tilt_deg"))
    assert len(ratios) == 2
    assert all(0.8 <= r <= 1.25 for r in ratios.values()), (kind, ratios)


@pytest.mark.slow
def test_study_cars_whose_sensors_clip_are_calibrated_between_the_clippings():
    # 40 car drives with the sensors' real ranges (the study's cars have none): the drive
    # is cut where the rate is missing, and what is calibrated is right; the rest is
    # refused by name.  Measured: 35 of 40 calibrated, worst 3.4 σ_CRLB (7.5 on offset_z
    # before the camber's track was read at each pass's wheel angle).
    drives = [_calibrate("car with its ranges", 1000 + seed) for seed in range(40)]
    _print_study("car with its ranges", drives)
    done = [d for d in drives if d.refused is None]
    assert len(done) >= 0.85 * len(drives), [d.refused for d in drives if d.refused]
    bad = [(d.seed, n, round(z, 1)) for d in done for n, z in d.z_crlb.items() if abs(z) > Z_MAX]
    assert not bad, bad  # (an exception other than a named refusal fails the test)
