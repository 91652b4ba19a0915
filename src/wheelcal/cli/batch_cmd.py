"""``wheelcal batch PIPELINE.toml`` — many sessions in parallel, with the repeatability report."""

from __future__ import annotations

import argparse

#: The command's one-line help and its --help description.
HELP = "run a pipeline file: calibrate many recordings in parallel, write the report"
DESCRIPTION = (
    "Run the sessions of a pipeline file (see pipelines/) in parallel and write "
    "<output>/<stem>.calibration.json per session, one pooled "
    "<output>/sensors/<sensor_id>.calibration.json per sensor (export and apply take it), "
    "report.json, report.md, sessions.csv, overview.png and, with Rerun on, .rrd "
    "recordings. Up-to-date sessions are skipped. "
    "Exit status 1 if any session failed (the others still run)."
)


def register(sub) -> None:
    """Add the ``batch`` parser."""
    p = sub.add_parser("batch", help=HELP, description=DESCRIPTION)
    p.add_argument("pipeline", metavar="PIPELINE.toml")
    p.add_argument("--workers", type=int, help="override the pipeline's number of local workers")
    p.add_argument("--out", metavar="DIR", help="override the pipeline's output folder")
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Run the pipeline and summarise."""
    import dataclasses
    from pathlib import Path

    from wheelcal.batch.pipeline import PipelineError, load_pipeline
    from wheelcal.batch.report import counts_sentence
    from wheelcal.batch.runner import run_batch
    from wheelcal.cli.errors import SessionsFailed, UsageError
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
    try:
        outcome = run_batch(pipeline, BatchProgress())
    except PipelineError as exc:
        raise UsageError(str(exc)) from None
    print(f"{pipeline.name}: {counts_sentence(outcome.counts())} in {outcome.wall_s:.1f} s")
    state = "written" if outcome.report_written else "unchanged"
    print(f"report ({state}): " + ", ".join(outcome.report_paths))
    if outcome.failed:
        raise SessionsFailed(
            f"{len(outcome.failed)} session(s) failed: "
            + "; ".join(r.source for r in outcome.failed)
        )
    return 0
