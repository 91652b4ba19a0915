"""``wheelcal apply CAL.json IN.mcap OUT.mcap`` — a calibrated copy of a recording."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from wheelcal.cli.overwrite import FORCE_HELP, POLICY_EPILOG

#: The command's one-line help and its --help description.
HELP = "write a copy of a recording with a calibrated accelerometer topic added"
DESCRIPTION = (
    "Read IN (any recording calibrate reads: MCAP, ROS 1 .bag, rosbag2 .db3 or folder) and "
    "write OUT.mcap with <topic>/calibrated: a = matrix @ (v - bias) for every sample. An "
    "MCAP is copied with every channel kept; from a bag, its IMU topic is copied beside the "
    "calibrated one. Samples a calibration would leave out (clipped, outliers, repeated "
    "stamps) are corrected too and flagged on <topic>/calibrated/flags; the calibration is "
    "stored as metadata."
)


def register(sub) -> None:
    """Add the ``apply`` parser."""
    p = sub.add_parser("apply", help=HELP, description=DESCRIPTION, epilog=POLICY_EPILOG)
    p.add_argument("calibration", metavar="CAL.json")
    p.add_argument("source", metavar="IN")
    p.add_argument("destination", metavar="OUT.mcap")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--topic", help="accelerometer topic to correct (default: the calibration's)")
    p.add_argument("--out-topic", help="name of the calibrated topic (default <topic>/calibrated)")
    p.add_argument("--format", choices=("ros2", "json"), help="encoding of the calibrated topic")
    p.add_argument(
        "--allow-partial",
        action="store_true",
        help="apply a calibration with undetermined parameters (those axes pass unchanged)",
    )
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Apply and report."""
    from wheelcal.calibration import apply_calibration
    from wheelcal.cli.errors import CommandFailed, UsageError
    from wheelcal.cli.options import readable_inputs
    from wheelcal.cli.overwrite import claim
    from wheelcal.io import Output, describe_error, origin_of, output_mark, special_file_kind

    readable_inputs(("CAL.json", args.calibration))
    kind = special_file_kind(args.source)
    rosbag2 = kind == "a folder" and os.path.isfile(os.path.join(args.source, "metadata.yaml"))
    if kind is not None and not rosbag2:
        raise UsageError(f"IN {args.source} is {kind}, not a file to read")
    if os.path.isdir(args.destination):
        raise UsageError(f"OUT.mcap {args.destination} is a folder; give the file to write")
    if os.path.exists(args.source) and os.path.exists(args.destination):
        if os.path.samefile(args.source, args.destination):
            raise UsageError(f"OUT.mcap {args.destination} is IN itself; give a new file")
    inputs = (args.calibration, args.source)
    origin = origin_of(inputs)
    exists = claim([Output(Path(args.destination), origin, inputs)], args.force, "apply")
    try:
        applied = apply_calibration(
            args.calibration,
            args.source,
            args.destination,
            args.topic,
            args.out_topic,
            args.format,
            allow_partial=args.allow_partial,
            replace=exists,
            mark=output_mark(origin, inputs),
        )
    except Exception as exc:  # incl. MemoryError, RecursionError: named, never a traceback
        if getattr(args, "debug", False):
            raise
        message = describe_error(exc)
        if not isinstance(exc, ValueError | OSError) or not message:
            message = f"{type(exc).__name__}: {exc}".rstrip(": ")
        if args.source not in message and args.calibration not in message:
            message = f"{args.source}: {message}"
        raise CommandFailed(f"error: {message}") from None
    print(f"wrote {args.destination}: {applied.summary()}")
    if applied.gyro_note:
        print(applied.gyro_note)
    return 0
