"""Running calibrations: one session end to end, and many in parallel from a pipeline file.

Layer 8 (above ``viz`` and ``plan``, beside ``study``, below ``cli``).
"""

from wheelcal.batch.pipeline import PipelineError, load_pipeline
from wheelcal.batch.report import counts_sentence
from wheelcal.batch.runner import run_batch
from wheelcal.batch.session import calibrate_session
from wheelcal.batch.termination import BatchStopped, Terminated

__all__ = [
    "BatchStopped",
    "PipelineError",
    "Terminated",
    "calibrate_session",
    "counts_sentence",
    "load_pipeline",
    "run_batch",
]
