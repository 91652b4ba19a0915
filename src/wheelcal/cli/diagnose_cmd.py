"""``wheelcal diagnose FILE --out DIR`` — the closed loop on each recording."""

from __future__ import annotations

import argparse

from wheelcal.cli.options import add_session_arguments
from wheelcal.cli.overwrite import FORCE_HELP, POLICY_EPILOG

#: The command's one-line help and its --help description.
HELP = "calibrate, showing the closed loop's steps before and after"
DESCRIPTION = (
    "The same calibration as `wheelcal calibrate` (which runs the closed loop too), "
    "shown step by step: score tests of candidate effects (spin-down beyond the cubic, "
    "wheel imbalance, sensor nonlinearity, offset warm-up and drift, gain drift, "
    "cross-axis coupling) on the residual; the most significant added and everything "
    "refitted, until none is significant. Writes <stem>.diagnosis.json (the steps, "
    "before and after) and the same <stem>.calibration.json as calibrate."
)


def register(sub) -> None:
    """Add the ``diagnose`` parser."""
    p = sub.add_parser("diagnose", help=HELP, description=DESCRIPTION, epilog=POLICY_EPILOG)
    p.add_argument("files", nargs="+", metavar="FILE")
    p.add_argument(
        "--out",
        required=True,
        metavar="DIR",
        help="output folder: <stem>.diagnosis.json and <stem>.calibration.json (and <stem>.rrd "
        "with --rrd)",
    )
    p.add_argument("--rrd", action="store_true", help="Rerun recording with residuals before/after")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    add_session_arguments(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Diagnose every file; exit 1 if any failed."""
    from wheelcal.cli.sessions import run_sessions

    return run_sessions(args, diagnose=True)
