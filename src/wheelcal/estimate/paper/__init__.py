"""The paper's four-step estimator (Pedersini, section III-A … D), kept for comparison."""
