"""Autoregressive noise: the whitening FIR filter and the process variance.

A stationary AR(p) process x_n + a₁x_{n−1} + … + a_p x_{n−p} = e_n is both the
simulator's band-limited sensor noise and the estimator's model of the residual;
both need its FIR whitening filter A(z) and its variance per unit innovation.
"""

from __future__ import annotations

import numpy as np


def fir_filter(a: np.ndarray, x: np.ndarray) -> np.ndarray:
    """y_n = Σ_k a_k x_{n−k} along the last axis, zero history (= lfilter(a, [1], x))."""
    y = a[0] * x
    for k in range(1, a.size):
        y[..., k:] += a[k] * x[..., :-k]
    return y


def ar_variance_gain(a: np.ndarray) -> float:
    """Σ h_k² of the all-pole filter 1/A(z): the variance of x for unit innovations.

    Exact, from the Yule–Walker equations γ(k) + Σ_j a_j γ(|k − j|) = δ_k,
    k = 0…p, solved for the autocovariances γ(0…p).
    """
    p = a.size - 1
    if p == 0:
        return 1.0
    system = np.zeros((p + 1, p + 1))
    for k in range(p + 1):
        for j in range(p + 1):
            system[k, abs(k - j)] += a[j]
    rhs = np.zeros(p + 1)
    rhs[0] = 1.0
    return float(np.linalg.solve(system, rhs)[0])
