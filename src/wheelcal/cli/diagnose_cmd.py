"""``wheelcal diagnose FILE.mcap --out DIR`` — the closed loop on each recording."""

from __future__ import annotations

import argparse
import sys

from wheelcal.cli.errors import SessionsFailed
from wheelcal.cli.options import add_session_arguments, output_folder, session_options


def register(sub) -> None:
    """Add the ``diagnose`` parser."""
    p = sub.add_parser(
        "diagnose",
        help="find effects the paper's model lacks, fit them, report before and after",
        description=(
            "Calibrate, then score-test candidate effects (spin-down beyond the cubic, wheel "
            "imbalance, sensor nonlinearity, offset warm-up and drift, gain drift, cross-axis "
            "coupling) on the residual; add the most significant, refit, repeat until none is "
            "significant. Writes <stem>.diagnosis.json and the final <stem>.calibration.json."
        ),
    )
    p.add_argument("files", nargs="+", metavar="FILE.mcap")
    p.add_argument("--out", required=True, metavar="DIR")
    p.add_argument("--alpha", type=float, default=0.01, help="family-wise significance level")
    p.add_argument("--rrd", action="store_true", help="Rerun recording with residuals before/after")
    add_session_arguments(p)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Diagnose every file; exit 1 if any failed."""
    import dataclasses

    from wheelcal.batch.session import calibrate_session
    from wheelcal.cli.errors import UsageError
    from wheelcal.cli.summary import diagnosis_summary

    if not 0 < args.alpha < 1:
        raise UsageError("--alpha must lie in (0, 1)")
    options = dataclasses.replace(
        session_options(args, rrd=args.rrd), diagnose=True, alpha=args.alpha
    )
    output_folder(args.out)  # before any session: a read-only folder is found now
    failed = 0
    for path in args.files:
        outcome = calibrate_session(path, options, args.out)
        if not outcome.ok:
            failed += 1
            print(f"FAILED  {outcome.error}", file=sys.stderr)
            continue
        print(diagnosis_summary(outcome))
    if failed:
        raise SessionsFailed(f"{failed} of {len(args.files)} recording(s) failed")
    return 0
