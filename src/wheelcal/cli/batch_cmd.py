"""``wheelcal batch PIPELINE.toml`` — many sessions in parallel, with the repeatability report."""

from __future__ import annotations

import argparse
import os
import sys

from wheelcal.cli.overwrite import FORCE_HELP, POLICY_EPILOG

#: The command's one-line help and its --help description.
HELP = "run a pipeline file: calibrate many recordings in parallel, write the report"
DESCRIPTION = (
    "Run the sessions of a pipeline file (see pipelines/) in parallel and write "
    "<output>/<stem>.calibration.json per session, one pooled "
    "<output>/sensors/<sensor_id>.calibration.json per sensor (export and apply take it), "
    "report.json, report.md, sessions.csv, overview.png and, with Rerun on, .rrd "
    "recordings. Up-to-date sessions are skipped. "
    "Exit status 1 if any session failed (the others still run), or if the disk filled up "
    "(the sessions written are kept; the report is not written). SIGTERM or SIGHUP stops the "
    "batch cleanly (exit 128 + the signal): no half-written or temporary file is left, and a "
    "re-run does only the sessions missing. One output folder serves one pipeline at a time."
)


def register(sub) -> None:
    """Add the ``batch`` parser."""
    p = sub.add_parser("batch", help=HELP, description=DESCRIPTION, epilog=POLICY_EPILOG)
    p.add_argument("pipeline", metavar="PIPELINE.toml")
    p.add_argument("--workers", type=int, help="override the pipeline's number of local workers")
    p.add_argument("--out", metavar="DIR", help="override the pipeline's output folder")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run the pipeline and summarise."""
    import dataclasses
    from pathlib import Path

    from wheelcal.batch import (
        BatchStopped,
        PipelineError,
        Terminated,
        counts_sentence,
        load_pipeline,
        run_batch,
    )
    from wheelcal.cli.errors import CommandFailed, UsageError
    from wheelcal.cli.progress import BatchProgress

    try:
        pipeline = load_pipeline(args.pipeline)
    except PipelineError as exc:
        raise UsageError(str(exc)) from None
    if args.workers is not None:
        if args.workers < 1:
            raise UsageError("--workers must be >= 1")
        pipeline = dataclasses.replace(
            pipeline, executor=dataclasses.replace(pipeline.executor, workers=args.workers)
        )
    if args.out:
        pipeline = dataclasses.replace(pipeline, output=Path(args.out))
    # Rerun's writer logs every failed write (a full disk: dozens of lines) on stderr;
    # wheelcal names the failure itself.  RUST_LOG=warn shows them.
    os.environ.setdefault("RUST_LOG", "off")
    try:
        outcome = run_batch(pipeline, BatchProgress(), force=args.force)
    except PipelineError as exc:
        raise UsageError(str(exc)) from None
    except BatchStopped as exc:
        raise CommandFailed(f"error: {exc}") from None
    except Terminated as exc:
        print(
            f"wheelcal batch: stopped by {exc.name}: {exc.done} of {exc.total} session(s) "
            "calibrated before it (their outputs are complete); the others left no file. Run "
            "the batch again to finish: the sessions done are skipped",
            file=sys.stderr,
        )
        return 128 + exc.signum
    print(f"{pipeline.name}: {counts_sentence(outcome.counts())} in {outcome.wall_s:.1f} s")
    state = "written" if outcome.report_written else "unchanged"
    print(f"report ({state}): " + ", ".join(outcome.report_paths))
    if outcome.failed:
        raise CommandFailed(
            f"{len(outcome.failed)} session(s) failed: "
            + "; ".join(r.source for r in outcome.failed)
        )
    return 0
