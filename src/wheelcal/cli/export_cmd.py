"""``wheelcal export CAL.json --format yaml|c`` — the correction for ROS configs or firmware."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from wheelcal.cli.overwrite import FORCE_HELP, POLICY_EPILOG

#: imu_tk's calibration files: the accelerometer's and (from a pooled sensor file) the gyro's.
IMU_TK_FORMATS = ("imu_tk_acc", "imu_tk_gyro")
#: The command's one-line help and its --help description.
HELP = "export a calibration as Kalibr imu.yaml, an imu_calib file or a C header"
DESCRIPTION = (
    "Print (or write with --out) the bias and 3x3 correction of a calibration: "
    "yaml = Kalibr's imu.yaml keys (accelerometer_* and gyroscope_* noise_density: the "
    "white noise's sigma per sample / sqrt(rate), Kalibr's definition; *_random_walk: the "
    "rests' Allan bound, marked as one; update_rate, rostopic) with wheelcal's imu0 block; "
    "imu_calib = the ROS imu_calib package's SM and bias; c = a C header; imu_tk_acc, "
    "imu_tk_gyro = imu_tk's CalibratedTriad files. A sensor's file with the gyro's full "
    "matrix adds the gyro (Kalibr's scale-misalignment keys)."
)


def register(sub) -> None:
    """Add the ``export`` parser."""
    p = sub.add_parser("export", help=HELP, description=DESCRIPTION, epilog=POLICY_EPILOG)
    p.add_argument("calibration", metavar="CAL.json")
    p.add_argument(
        "--format",
        choices=("yaml", "imu_calib", "c", *IMU_TK_FORMATS),
        required=True,
        help="yaml: Kalibr's imu.yaml (+ wheelcal's imu0 block); imu_calib: the ROS imu_calib "
        "package's file; c: a C header; imu_tk_acc, imu_tk_gyro: imu_tk's CalibratedTriad files",
    )
    p.add_argument("--out", metavar="FILE", help="write here (atomically) instead of stdout")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--prefix", default="WHEELCAL", help="C identifier prefix")
    p.add_argument(
        "--allow-partial",
        action="store_true",
        help="export a calibration with undetermined parameters: those axes get identity rows "
        "(gain 1, offset 0), marked in comments",
    )
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Export."""
    from wheelcal.calibration import load_calibration, to_c_header, to_imu_calib, to_imu_tk, to_yaml
    from wheelcal.cli.errors import UsageError
    from wheelcal.cli.options import readable_inputs
    from wheelcal.cli.overwrite import claim
    from wheelcal.io import Output, OutputExistsError, atomic_write_text, mark_line, origin_of

    readable_inputs(("CAL.json", args.calibration))  # a FIFO would wait forever
    if args.out and Path(args.out).is_dir():
        raise UsageError(f"--out {args.out} is a folder; give the file to write")
    origin = origin_of([args.calibration])
    exists = False
    if args.out:
        output = Output(Path(args.out), origin, (args.calibration,))
        exists = claim([output], args.force, "export")
    calibration = load_calibration(args.calibration, allow_partial=args.allow_partial)
    try:
        if args.format == "yaml":
            text = to_yaml(calibration)
        elif args.format == "imu_calib":
            text = to_imu_calib(calibration)
        elif args.format in IMU_TK_FORMATS:
            text = to_imu_tk(calibration, args.format.removeprefix("imu_tk_"))
        else:
            text = to_c_header(calibration, args.prefix)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if args.out:
        line = mark_line(origin)  # marks the file as wheelcal's (no path: a comment stays one)
        text = text + f"/* {line} */\n" if args.format == "c" else f"# {line}\n" + text
        try:
            atomic_write_text(args.out, text, replace=exists)
        except OutputExistsError as exc:  # created meanwhile by someone else
            raise UsageError(str(exc)) from None
    else:
        sys.stdout.write(text)
    return 0
