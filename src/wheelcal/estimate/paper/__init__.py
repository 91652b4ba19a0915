"""The paper's four-step estimator (Pedersini, section III-A … D), kept for comparison."""

from wheelcal.estimate.paper.estimator import PaperEstimator

__all__ = ["PaperEstimator"]
