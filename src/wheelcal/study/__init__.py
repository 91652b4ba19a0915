"""Studies over many simulated recordings: Monte Carlo accuracy against the CRLB."""

from wheelcal.study.montecarlo import (
    PARAMETER_GROUPS,
    MonteCarloSummary,
    group_of,
    monte_carlo,
)

__all__ = ["PARAMETER_GROUPS", "MonteCarloSummary", "group_of", "monte_carlo"]
