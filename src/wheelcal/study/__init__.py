"""Studies over many simulated recordings: Monte Carlo accuracy against the CRLB.

Layer 8 (above ``viz`` and ``plan``, beside ``batch``, below ``cli``).

:mod:`~wheelcal.study.montecarlo` (one scenario, one estimator, many seeds) is
the building block.  The accuracy study of the paper's Sec. IV-A
(``wheelcal study``) is :func:`wheelcal.study.runner.run_study` with settings
from :mod:`~wheelcal.study.config`; its parts: :mod:`~wheelcal.study.noise_sweep`
(Fig. 7–8, Table I), :mod:`~wheelcal.study.static` (six still poses),
:mod:`~wheelcal.study.duration` (recording length and rate),
:mod:`~wheelcal.study.origin` (the paper's time origin); outputs by
:mod:`~wheelcal.study.report`, :mod:`~wheelcal.study.plots`,
:mod:`~wheelcal.study.rerun_log` and :mod:`~wheelcal.study.output`.
"""

from wheelcal.study.config import StudyConfig, StudyConfigError, load_config, with_overrides
from wheelcal.study.montecarlo import (
    PARAMETER_GROUPS,
    MonteCarloSummary,
    group_of,
    monte_carlo,
)
from wheelcal.study.output import study_outputs, write_outputs
from wheelcal.study.runner import run_study

__all__ = [
    "PARAMETER_GROUPS",
    "MonteCarloSummary",
    "StudyConfig",
    "StudyConfigError",
    "group_of",
    "load_config",
    "monte_carlo",
    "run_study",
    "study_outputs",
    "with_overrides",
    "write_outputs",
]
