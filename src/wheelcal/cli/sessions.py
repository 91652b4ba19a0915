"""The one loop of ``wheelcal calibrate`` and ``wheelcal diagnose`` over their input files.

Each file goes through :func:`wheelcal.calibration.calibrate_into` (the same
session function and writer as the API and the batch); a failing file is
reported and the others go on.  ``diagnose`` is the same call with the verbose
diagnosis: the closed loop's report is written too (``<stem>.diagnosis.json``)
and its steps are printed.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

from wheelcal.cli.errors import CommandFailed, UsageError
from wheelcal.cli.options import claim_sessions, output_folder, session_options


def run_sessions(args: argparse.Namespace, diagnose: bool = False) -> int:
    """Calibrate (``diagnose``: and diagnose) every file in ``args.files``; exit 1 if any failed."""
    from wheelcal.calibration import calibrate_into
    from wheelcal.cli.summary import diagnosis_summary, session_summary

    command = "diagnose" if diagnose else "calibrate"
    if diagnose and args.model != "closed_loop":
        raise UsageError("diagnose shows the closed loop: it cannot use --model paper")
    options = dataclasses.replace(session_options(args, rrd=args.rrd), diagnose=diagnose)
    output_folder(args.out)  # before any session: a read-only folder is found now
    claim_sessions(args, command, rrd=args.rrd, diagnose=diagnose)
    rrd_writer = None
    if args.rrd:
        from wheelcal.viz import write_session_rrd as rrd_writer
    quiet = getattr(args, "quiet", False)
    failed = 0
    for path in args.files:
        outcome = calibrate_into(path, options, args.out, rrd_writer=rrd_writer)
        if not outcome.ok:
            failed += 1
            print(session_summary(outcome), file=sys.stderr)
        elif diagnose:
            print(diagnosis_summary(outcome))
        elif not quiet:
            print(session_summary(outcome))
    if failed:
        raise CommandFailed(f"{failed} of {len(args.files)} recording(s) failed")
    return 0
