"""Running calibrations: one session end to end, and many in parallel from a pipeline file."""

from wheelcal.batch.pipeline import PipelineError, load_pipeline
from wheelcal.batch.report import counts_sentence
from wheelcal.batch.runner import run_batch
from wheelcal.batch.session import (
    SessionOutcome,
    calibrate_session,
    describe_error,
    session_outputs,
)
from wheelcal.batch.termination import BatchStopped, Terminated

__all__ = [
    "BatchStopped",
    "PipelineError",
    "SessionOutcome",
    "Terminated",
    "calibrate_session",
    "counts_sentence",
    "describe_error",
    "load_pipeline",
    "run_batch",
    "session_outputs",
]
