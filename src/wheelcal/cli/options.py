"""Argument groups shared by several commands."""

from __future__ import annotations

import argparse

from wheelcal.cli.errors import UsageError
from wheelcal.session import SESSION_GEOMETRIES


def positive_float(text: str) -> float:
    """Parse a number > 0 (argparse type)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text}")
    return value


def add_session_arguments(parser: argparse.ArgumentParser) -> None:
    """Session facts, topic, window and geometry (calibrate, diagnose, batch overrides)."""
    g = parser.add_argument_group("session facts (override the file's wheelcal.session record)")
    g.add_argument(
        "--radius", type=positive_float, metavar="M", help="sensor distance from the axle (m)"
    )
    g.add_argument(
        "--radius-std", type=float, metavar="M", help="uncertainty of the radius (m; default 0.001)"
    )
    g.add_argument("--gravity", type=positive_float, metavar="MPS2", help="local gravity (m/s²)")
    g.add_argument(
        "--full-scale-g", type=positive_float, metavar="G", help="sensor range, for clipping"
    )
    g.add_argument("--sensor-id", help="sensor identifier (for reports)")
    g.add_argument("--mounting-id", help="mounting identifier (for reports)")
    w = parser.add_argument_group("data")
    w.add_argument("--topic", help="accelerometer topic (default: the only one)")
    w.add_argument(
        "--accel-unit",
        choices=("m/s^2", "g"),
        help="unit of the samples when the file states it wrongly, or a CSV states none (g means "
        "9.80665 m/s²)",
    )
    w.add_argument(
        "--start-s", type=float, help="start of the free-spin window (s from the first sample)"
    )
    w.add_argument("--end-s", type=float, help="end of the free-spin window")
    w.add_argument(
        "--gyro",
        choices=("auto", "on", "off"),
        default="auto",
        help="use the gyroscope: auto (default: only when the free spin's cubic cannot follow "
        "the motion), on (always, with a flexible wheel angle), off",
    )
    w.add_argument(
        "--gyro-g-sensitivity",
        type=positive_float,
        default=0.1,
        metavar="DPS_PER_G",
        help="the gyro's typical sensitivity to linear acceleration, °/s per g (default 0.1, "
        "MPU-9250 class): the σ of its prior, so that it cannot absorb an unbalanced wheel's "
        "rate ripple (bench and field fits; state a gyro's measured value when you know it)",
    )
    m = parser.add_argument_group("geometry")
    m.add_argument(
        "--geometry",
        choices=SESSION_GEOMETRIES,
        default="auto",
        help="auto (default): read from the data — a bench's free spin (needs --radius), or, "
        "with a gyroscope, a wheel rolling in the field (car, robot, wheelchair: vertical or "
        "cambered, the sensor's radius fitted) or a vertical wheel on a stand; or say what is "
        "known: the radius, the tilt (--tilt-deg), a vertical wheel, or a wheel rolling on "
        "the ground (rolling: the field fit, with --radius if known, else the radius fitted)",
    )
    m.add_argument(
        "--model",
        choices=("closed_loop", "paper"),
        default="closed_loop",
        help="closed_loop (default): the paper's model plus every effect the recording shows "
        "it lacks (an unbalanced wheel, a warm-up, a nonlinearity …, each tested at "
        "family-wise --alpha); paper: the paper's bare model, labelled as such",
    )
    m.add_argument(
        "--alpha",
        type=float,
        default=0.01,
        help="family-wise significance level of the closed loop's effect screen (default 0.01)",
    )
    m.add_argument("--tilt-deg", type=float, help="measured tilt for --geometry tilt")
    m.add_argument("--tilt-std-deg", type=float, default=0.5, help="uncertainty of the known tilt")
    g.add_argument(
        "--force-gravity",
        action="store_true",
        help="accept a --gravity outside Earth's 9.7–9.9 m/s²",
    )
    add_gate_arguments(parser)


#: Command-line flag → Gates field, for the plausibility gates (README "When wheelcal refuses").
GATE_FLAGS = {
    "max_offset_g": "refuse offsets above this many g (default 0.3)",
    "min_samples_per_turn": "refuse fewer samples per wheel turn at the fastest rate (default 4)",
    "max_window_s": "longest free-spin window fitted, s (default 300)",
    "gain_tolerance": "warn when a gain is further than this from 1 (default 0.05)",
    "offset_tolerance_g": "warn when an offset exceeds this many g (default 0.1)",
    "mean_gain_tolerance": "warn when the mean gain is further than this from 1 (default 0.05)",
    "unexplained_ratio": "warn when the residual exceeds this × the noise floor (default 1.5)",
    "max_harmonic_ratio": "refuse when the residual at the wheel harmonics exceeds this × "
    "the noise floor (default 5)",
    "max_lean_change_deg": "refuse a drive whose wheel camber changes by more than this, ° "
    "(default: no limit — the camber follows the gyro's track and the lean check judges it)",
    "lean_z": "the lean check: a camber free to move must shift a gain, offset or the radius "
    "by more than this many σ of the shift's own σ to count (default 4)",
    "lean_shift_sigma": "… and by more than this many σ of the fit (default 1)",
    "clock_tolerance": "judge the sample clock only when the stamped rate is further than this "
    "(relative) from its nominal rate (default 0.001 = 1000 ppm)",
}


def add_gate_arguments(parser: argparse.ArgumentParser) -> None:
    """Overrides of the plausibility gates (refusal and warning bands)."""
    g = parser.add_argument_group("plausibility gates (README: When wheelcal refuses)")
    g.add_argument(
        "--gain-range",
        nargs=2,
        type=positive_float,
        metavar=("LOW", "HIGH"),
        help="refuse gains outside [LOW, HIGH] (default 0.5 2)",
    )
    for name, text in GATE_FLAGS.items():
        g.add_argument("--" + name.replace("_", "-"), type=positive_float, help=text)


def gates_from_args(args: argparse.Namespace):
    """The Gates given by the command line (defaults where not given)."""
    from wheelcal.session import Gates

    given = {name: getattr(args, name, None) for name in GATE_FLAGS}
    if getattr(args, "gain_range", None) is not None:
        given["gain_range"] = tuple(args.gain_range)
    try:
        return Gates(**{k: v for k, v in given.items() if v is not None})
    except ValueError as exc:
        raise UsageError(f"plausibility gates: {exc}") from None


def session_options(args: argparse.Namespace, rrd: bool = False):
    """SessionOptions from parsed arguments (UsageError on inconsistent ones)."""
    from wheelcal.session import SessionOptions

    if args.geometry == "tilt" and args.tilt_deg is None:
        raise UsageError("--geometry tilt needs --tilt-deg")
    gates = gates_from_args(args)
    try:
        return SessionOptions(
            topic=args.topic,
            radius_m=args.radius,
            radius_std_m=args.radius_std,
            gravity_mps2=args.gravity,
            full_scale_g=args.full_scale_g,
            sensor_id=args.sensor_id,
            mounting_id=args.mounting_id,
            start_s=args.start_s,
            end_s=args.end_s,
            geometry=args.geometry,
            known_tilt_deg=args.tilt_deg,
            tilt_std_deg=args.tilt_std_deg,
            rrd=rrd,
            accel_unit=args.accel_unit,
            gates=gates,
            force_gravity=args.force_gravity,
            gyro=args.gyro,
            model=args.model,
            alpha=args.alpha,
            gyro_g_sensitivity_dps_per_g=args.gyro_g_sensitivity,
        )
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def output_folder(path: str):
    """The ``--out`` folder, created and proven writable (UsageError naming it otherwise)."""
    from wheelcal.io import OutputFolderError, prepare_output_folder

    try:
        return prepare_output_folder(path, what="--out folder")
    except OutputFolderError as exc:
        raise UsageError(str(exc)) from None


def readable_inputs(*inputs: tuple[str, str]) -> None:
    """Refuse (UsageError, exit 2) an input that is a FIFO, device or folder, before reading.

    ``inputs`` are (what, path) pairs, e.g. ``("IN.csv", args.source)``: reading
    a FIFO waits for a writer forever and ``/dev/zero`` never ends.
    """
    from wheelcal.io import special_file_kind

    for what, path in inputs:
        kind = special_file_kind(path)
        if kind is not None:
            raise UsageError(f"{what} {path} is {kind}, not a file to read")


def claim_sessions(args: argparse.Namespace, command: str, rrd: bool, diagnose: bool) -> None:
    """Claim every session's outputs before the first is computed (UsageError if refused)."""
    from wheelcal.calibration import session_outputs
    from wheelcal.cli.overwrite import claim

    outputs = [o for path in args.files for o in session_outputs(path, args.out, rrd, diagnose)]
    claim(outputs, args.force, command)
