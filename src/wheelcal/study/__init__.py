"""Studies over many simulated recordings: Monte Carlo accuracy against the CRLB.

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

from wheelcal.study.montecarlo import (
    PARAMETER_GROUPS,
    MonteCarloSummary,
    group_of,
    monte_carlo,
)

__all__ = ["PARAMETER_GROUPS", "MonteCarloSummary", "group_of", "monte_carlo"]
