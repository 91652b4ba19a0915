"""``wheelcal simulate OUT.mcap`` — a simulated recording with known truth."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from wheelcal.cli.errors import UsageError
from wheelcal.cli.options import positive_float
from wheelcal.cli.overwrite import FORCE_HELP, POLICY_EPILOG

#: The simulated gyro's range without --gyro-full-scale-dps, °/s.
DEFAULT_GYRO_FULL_SCALE_DPS = 2000.0
#: ROS 2 files carry the temperature on its own topic at 1/20 of the sample rate.
TEMPERATURE_STRIDE = 20

#: Presets drawn by the field simulator (:mod:`wheelcal.simulate.field`).
FIELD_PRESETS = ("car", "robot", "wheelchair", "stand")
#: The paper's bench (:mod:`wheelcal.simulate.presets`).
BENCH_PRESETS = ("table1", "table2")
#: Options of the bench simulator a field preset cannot honour (flag, argparse default).
BENCH_ONLY_OPTIONS = (
    ("--reverse", False),
    ("--free-spin-only", False),
    ("--quantise", False),
    ("--no-radius", False),
    ("--gyro-full-scale-dps", None),
    ("--temperature", False),
)


#: The command's one-line help and its --help description.
HELP = "write a simulated recording (MCAP) with known truth"
DESCRIPTION = (
    "Simulate a hand-spun wheel session (rest, push, free spin, brake, rest) — or, with "
    "--preset car|robot|wheelchair|stand, a wheel in the field — and write it as a contract "
    "MCAP with the wheelcal.session metadata."
)


def register(sub) -> None:
    """Add the ``simulate`` parser."""
    p = sub.add_parser("simulate", help=HELP, description=DESCRIPTION, epilog=POLICY_EPILOG)
    p.add_argument("out", metavar="OUT.mcap")
    p.add_argument(
        "--preset",
        default="table2",
        metavar="NAME",
        help="table1 or table2 (default): the paper's bench; car, robot, wheelchair or stand: a "
        "wheel in the field with a gyroscope, no radius stored (the field simulator: --seed, "
        "--noise, --bandwidth-hz, --format, --batch, --sensor-id, --mounting-id and --truth "
        "apply; the bench's other options are refused)",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (noise and hand spin)")
    p.add_argument("--noise", type=float, help="noise std in m/s² (default: the preset's)")
    p.add_argument("--bandwidth-hz", type=positive_float, help="low-pass-filtered noise corner")
    p.add_argument("--format", choices=("ros2", "json"), default="ros2", help="message encoding")
    p.add_argument("--batch", type=int, default=20, help="samples per JSON message")
    p.add_argument("--reverse", action="store_true", help="spin the wheel the other way")
    p.add_argument("--free-spin-only", action="store_true", help="no rest, push or stop")
    p.add_argument("--quantise", action="store_true", help="16-bit ±4 g output with clipping")
    p.add_argument("--no-radius", action="store_true", help="leave radius_m out of the metadata")
    p.add_argument(
        "--gyro",
        action="store_true",
        help="add a gyroscope (MPU-9250-class errors; ROS 2: angular_velocity, JSON: gyro rows)",
    )
    p.add_argument(
        "--gyro-full-scale-dps",
        type=positive_float,
        default=None,
        metavar="DPS",
        help="gyro range ±DPS °/s, stored as gyro_full_scale_dps (default 2000; 250 clips a "
        "hand spin)",
    )
    p.add_argument(
        "--temperature",
        action="store_true",
        help="add a sensor temperature (ROS 2: a sensor_msgs/msg/Temperature topic at 1/20 of "
        "the rate; JSON: temperature_c)",
    )
    p.add_argument(
        "--body-roll-deg-per-mps2",
        type=float,
        default=0.0,
        metavar="DEG",
        help="--preset car|robot|wheelchair: the wheel's camber changes by DEG per m/s² of "
        "lateral acceleration (a body rolling in its turns; wheelcal refuses such a drive "
        "as 'lean')",
    )
    p.add_argument(
        "--sensor-id",
        default="sim-sensor",
        help="sensor_id stored in the file (default sim-sensor)",
    )
    p.add_argument(
        "--mounting-id",
        default="sim-mounting",
        help="mounting_id stored in the file (default sim-mounting)",
    )
    p.add_argument("--truth", metavar="JSON", help="also write the ground truth here")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.set_defaults(handler=run)


def _claim(args: argparse.Namespace) -> tuple[dict, bool]:
    """The outputs' mark, and whether they exist (claimed first: before any work).

    ``simulate`` reads no file: the same *options* are its same input.
    """
    from wheelcal.cli.overwrite import claim
    from wheelcal.io import Output, origin_of, output_mark

    skip = {"out", "truth", "force", "debug", "handler", "command"}
    origin = origin_of(options={k: v for k, v in vars(args).items() if k not in skip})
    paths = [args.out] + ([args.truth] if args.truth else [])
    exists = claim([Output(Path(p), origin) for p in paths], args.force, "simulate")
    return output_mark(origin), exists


def run(args: argparse.Namespace) -> int:
    """Simulate and write."""
    import dataclasses

    import numpy as np

    from wheelcal.io import MARK_KEY, MARK_RECORD, atomic_write_text, write_recording
    from wheelcal.model import SpinParams
    from wheelcal.simulate import (
        GyroSpec,
        NoiseSpec,
        Quantiser,
        TemperatureSpec,
        preset,
        simulate,
        simulate_session,
    )

    mark, exists = _claim(args)
    rng = np.random.default_rng(args.seed)
    if args.preset not in (*BENCH_PRESETS, *FIELD_PRESETS):
        raise UsageError(
            f"unknown preset {args.preset!r}; choose from the paper's bench "
            f"({', '.join(BENCH_PRESETS)}) or a wheel in the field ({', '.join(FIELD_PRESETS)})"
        )
    if args.preset in FIELD_PRESETS:
        return _run_field(args, rng, mark, exists)
    try:
        scenario = preset(args.preset, rng=rng)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if args.noise is not None or args.bandwidth_hz is not None:
        std = args.noise if args.noise is not None else scenario.noise.std_mps2
        scenario = dataclasses.replace(
            scenario, noise=NoiseSpec(std, bandwidth_hz=args.bandwidth_hz)
        )
    if args.reverse:
        spin = scenario.truth.spin
        truth = scenario.truth.with_changes(spin=SpinParams(-spin.theta0_rad, -spin.omega_radps))
        scenario = dataclasses.replace(scenario, truth=truth)
    if args.quantise:
        scenario = dataclasses.replace(scenario, quantiser=Quantiser())
    info = scenario.info.merged(sensor_id=args.sensor_id, mounting_id=args.mounting_id)
    if args.gyro:
        full_scale = args.gyro_full_scale_dps or DEFAULT_GYRO_FULL_SCALE_DPS
        info = info.merged(gyro_full_scale_dps=full_scale)
        scenario = dataclasses.replace(scenario, gyro=GyroSpec(full_scale_dps=full_scale))
    if args.temperature:
        scenario = dataclasses.replace(scenario, temperature=TemperatureSpec())
    scenario = dataclasses.replace(scenario, info=info)
    if args.free_spin_only:
        sim = simulate(scenario, rng, source=args.out)
        recording, window = sim.recording, (0.0, scenario.duration_s)
    else:
        full = simulate_session(scenario, rng, source=args.out)
        recording, window = full.recording, full.window_s
    if args.no_radius:  # (a Scenario always knows its radius; the file need not)
        recording = dataclasses.replace(recording, info=dataclasses.replace(info, radius_m=None))
    write_recording(
        recording,
        args.out,
        encoding=args.format,
        batch_size=args.batch,
        temperature_stride=TEMPERATURE_STRIDE,
        replace=exists,
        metadata={MARK_RECORD: mark},
    )
    if args.truth:
        truth = {**truth_dict(scenario, window), MARK_KEY: mark}
        atomic_write_text(args.truth, json.dumps(truth, indent=2) + "\n", replace=exists)
    spin = f"free spin {window[0]:.2f}–{window[1]:.2f} s"
    extras = [name for name, on in (("gyro", args.gyro), ("temperature", args.temperature)) if on]
    also = f", with {' and '.join(extras)}" if extras else ""
    print(f"wrote {args.out}: {recording.samples} samples, {spin}{also}")
    return 0


def truth_dict(scenario, window) -> dict:
    """The simulated truth in contract names (for checking a calibration)."""
    truth = scenario.truth
    return {
        "format": "wheelcal.truth/1",
        "window_s": list(window),
        "sensor": {
            "offset_mps2": truth.sensor.offset_mps2.tolist(),
            "gain": truth.sensor.gain.tolist(),
        },
        "bench": {
            "radius_m": truth.bench.radius_m,
            "tilt_deg": truth.bench.tilt_deg,
            "misalignment_euler_deg": truth.bench.misalignment.euler_deg().tolist(),
        },
        "motion": truth.spin.to_dict(),
        "noise": {
            "std_mps2": list(scenario.noise.std_mps2),
            "bandwidth_hz": scenario.noise.bandwidth_hz,
        },
        **({"gyro": gyro_truth(scenario)} if scenario.gyro is not None else {}),
    }


def gyro_truth(scenario) -> dict:
    """The simulated gyro's errors and its true response along the wheel axis (rad/s units)."""
    spec = scenario.gyro
    scale, axis = spec.wheel_axis_response(scenario.truth.bench.misalignment.matrix)
    return {
        "model": "w = (I + diag(scale_error)) M (-omega R e_Z) + G (R a)/g0 + bias + noise",
        "scale_along_wheel_axis": scale,
        "axis": axis.tolist(),
        "bias_radps": list(spec.bias_radps),
        "scale_error": list(spec.scale_error),
        "misalignment_deg": list(spec.misalignment_deg),
        "g_sensitivity_dps_per_g": [list(row) for row in spec.g_sensitivity_dps_per_g],
        "noise_density_dps_rthz": spec.noise_density_dps_rthz,
        "noise_std_radps": spec.noise_std_radps(scenario.rate_hz),
        "full_scale_dps": spec.full_scale_dps,
    }


def _run_field(args: argparse.Namespace, rng, mark: dict, exists: bool) -> int:
    """A wheel in the field (``--preset car|robot|wheelchair|stand``) and its truth."""
    import dataclasses

    from wheelcal.io import MARK_KEY, MARK_RECORD, atomic_write_text, write_recording
    from wheelcal.simulate import (
        NoiseSpec,
        car_drive,
        robot_drive,
        simulate_field,
        stand_spin,
        wheelchair_coast,
    )

    refused = [flag for flag, default in BENCH_ONLY_OPTIONS if _given(args, flag, default)]
    if refused:
        raise UsageError(
            f"--preset {args.preset} is the field simulator: {', '.join(refused)} "
            f"{'applies' if len(refused) == 1 else 'apply'} to the bench presets "
            f"({', '.join(BENCH_PRESETS)}) only"
        )
    profiles = (car_drive, robot_drive, wheelchair_coast, stand_spin)
    make = dict(zip(FIELD_PRESETS, profiles, strict=True))[args.preset]
    scenario = make(rng)
    if args.noise is not None or args.bandwidth_hz is not None:
        std = args.noise if args.noise is not None else scenario.noise.std_mps2
        scenario = dataclasses.replace(
            scenario, noise=NoiseSpec(std, bandwidth_hz=args.bandwidth_hz)
        )
    if args.body_roll_deg_per_mps2:
        if args.preset not in ("car", "robot", "wheelchair"):
            raise UsageError(
                "--body-roll-deg-per-mps2 needs a rolling wheel: car, robot or wheelchair"
            )
        scenario = dataclasses.replace(scenario, body_roll_deg_per_mps2=args.body_roll_deg_per_mps2)
    sim = simulate_field(scenario, rng)
    info = sim.recording.info.merged(sensor_id=args.sensor_id, mounting_id=args.mounting_id)
    recording = dataclasses.replace(sim.recording, info=info, source=args.out)
    write_recording(
        recording,
        args.out,
        encoding=args.format,
        batch_size=args.batch,
        replace=exists,
        metadata={MARK_RECORD: mark},
    )
    if args.truth:
        text = json.dumps({**field_truth_dict(sim.truth), MARK_KEY: mark}, indent=2) + "\n"
        atomic_write_text(args.truth, text, replace=exists)
    w0, w1 = sim.truth.window_s
    print(
        f"wrote {args.out}: {recording.samples} samples at {recording.rate_hz:.0f} Hz, "
        f"a {args.preset} wheel ({sim.truth.geometry}), motion {w0:.2f}–{w1:.2f} s, with gyro"
    )
    return 0


def _given(args: argparse.Namespace, flag: str, default) -> bool:
    """Whether the option ``flag`` was given (its value differs from its default)."""
    return getattr(args, flag.lstrip("-").replace("-", "_")) != default


def field_truth_dict(truth) -> dict:
    """A field simulation's truth in contract names (for checking a calibration)."""
    return {
        "format": "wheelcal.truth/1",
        "kind": truth.kind,
        "geometry": truth.geometry,
        "window_s": list(truth.window_s),
        "sensor": {
            "offset_mps2": truth.sensor.offset_mps2.tolist(),
            "gain": truth.sensor.gain.tolist(),
        },
        "bench": {
            "radius_m": truth.radius_m,
            "tilt_deg": truth.tilt_deg,
            "camber_deg": truth.camber_deg,
            "rolling_radius_m": truth.rolling_radius_m,
            "misalignment_euler_deg": truth.bench.misalignment.euler_deg().tolist(),
        },
    }
