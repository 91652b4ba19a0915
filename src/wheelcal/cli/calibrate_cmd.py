"""``wheelcal calibrate FILE... --out DIR`` — one calibration JSON per recording."""

from __future__ import annotations

import argparse

from wheelcal.cli.options import add_session_arguments
from wheelcal.cli.overwrite import FORCE_HELP, POLICY_EPILOG

#: The command's one-line help and its --help description.
HELP = "calibrate recordings (MCAP, .db3, .bag, CSV exports) → <stem>.calibration.json"
DESCRIPTION = (
    "Calibrate each recording: find the free spin, fit offsets, gains, tilt, "
    "misalignment and spin jointly, and write <out>/<stem>.calibration.json "
    "(format wheelcal.calibration/1). A failing file is reported and the others go on. "
    "Recordings are MCAP, rosbag2 .db3 and ROS 1 .bag files, and the CSV exports whose "
    "format states the units, read directly: the Xsens DOT export (units fixed by the "
    "format) and CSVs whose header states every unit (x-io NGIMU sensors.csv, x-IMU3 "
    "Inertial.csv, phyphox). Any other CSV (an Arduino log) is refused with the "
    "`wheelcal convert` command that reads it."
)


def register(sub) -> None:
    """Add the ``calibrate`` parser."""
    p = sub.add_parser("calibrate", help=HELP, description=DESCRIPTION, epilog=POLICY_EPILOG)
    p.add_argument("files", nargs="+", metavar="FILE")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--rrd", action="store_true", help="also write a Rerun recording per session")
    p.add_argument("--quiet", action="store_true", help="print only failures")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    add_session_arguments(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Calibrate every file; exit 1 if any failed."""
    from wheelcal.cli.sessions import run_sessions

    return run_sessions(args)
