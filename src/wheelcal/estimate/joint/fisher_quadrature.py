"""The Fisher information J̃ᵀJ̃ by quadrature: a fraction of the whitened rows, weighted.

H = Σ_t J̃(t)ᵀJ̃(t) sums a smooth function of time.  The model's sensitivities
(eq. 6) turn with the wheel, their products at twice its rate at most, under
slow polynomial envelopes (t^k of the spin law); the whitening filter is a
short FIR (:mod:`wheelcal.estimate.joint.noise_model`), which keeps a smooth signal
smooth.  A midpoint rule over cells of ``s`` consecutive whitened outputs —
each cell's centre row standing for all ``s`` of them — then sums the same
products as the full sum, up to a small relative error: on a 90 s / 200 Hz
spin (143 samples per turn) at s = 11, σ moves by 2.2e-5 of itself (9e-6 at
s = 7; 2.5e-5 at 1 kHz with s = 59; 5.9e-5 on a fast spin at 51 samples per
turn with s = 3; 8e-3 at 2 rows per turn; see ``tests/test_fisher_quadrature.py``).  The
outputs past the last whole cell keep their own rows (weight 1), so the
window's ends are summed exactly.

The rows the rule keeps need the Jacobian only at their FIR clusters (each
kept output and the p samples before it): the model is evaluated, whitened
and multiplied out on ≈ N (p + 1)/s samples instead of N.  The gradient
J̃ᵀr̃ is a sum of noise and has no such rule: its callers take it over every
sample, without a Jacobian (:func:`~wheelcal.estimate.joint.normal_equations.gradient_pass`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.model import SpinParams

#: Whitened outputs per wheel turn (at its fastest) that one kept row may stand for at most
#: 1/this of: s ≤ samples per turn / this.
MIN_ROWS_PER_TURN = 12.0


def quadrature_stride(
    rate_hz: float,
    omega_max_radps: float,
    order: int,
    shortest_s: float | None = None,
    rows_per_turn: float = MIN_ROWS_PER_TURN,
) -> int:
    """The cell width s (odd, so its centre is a sample), or 1: every row.

    s keeps ≥ :data:`MIN_ROWS_PER_TURN` rows per turn at ω_max, and as many per
    ``shortest_s`` (the knot spacing of a spline among the columns: its basis
    functions live a few knot intervals).  It is 1 when the clusters would take
    more evaluations than the samples (s < p + 1: each kept row needs its own p
    samples of FIR history; at s = p + 1 they take as many, and the Gram 1/s of
    the rows) or the rate is unknown.  ``rows_per_turn`` replaces
    :data:`MIN_ROWS_PER_TURN` for a sum that needs less accuracy (the closed loop's
    screen: a test's information to 1e-3, not a reported σ to 1e-5).
    """
    turn_hz = abs(omega_max_radps) / (2 * np.pi)
    if not (turn_hz > 0 and np.isfinite(rate_hz) and rate_hz > 0):
        return 1
    rows = rate_hz / turn_hz
    if shortest_s is not None:
        rows = min(rows, rate_hz * shortest_s)
    s = int(np.floor(rows / rows_per_turn))
    s -= 1 - s % 2  # odd
    return s if s > 1 and s >= order + 1 else 1


def stride_for(
    t_s: np.ndarray,
    spin: SpinParams,
    order: int,
    shortest_s: float | None = None,
    rows_per_turn: float = MIN_ROWS_PER_TURN,
) -> int:
    """:func:`quadrature_stride` for samples at times ``t_s`` of the spin law ``spin``.

    The rate is the samples' mean; the fastest |ω| is the polynomial's largest
    over the window: at its ends or where dω/dt = 0 inside (a spin-down is
    fastest at its start, a speed that rises and falls in between).
    """
    t0, t1 = float(t_s[0]), float(t_s[-1])
    span = t1 - t0
    rate = (t_s.size - 1) / span if span > 0 else float("nan")
    omega = np.asarray(spin.omega_radps, dtype=float)
    slope = np.arange(1, omega.size) * omega[1:]  # dω/dt's coefficients
    turning = np.polynomial.polynomial.polyroots(slope) if slope.size else np.empty(0)
    real = turning.real[np.abs(turning.imag) < 1e-12]
    inside = real[(real > t0) & (real < t1)]
    fastest = float(np.max(np.abs(spin.omega_at(np.concatenate([[t0, t1], inside])))))
    return quadrature_stride(rate, fastest, order, shortest_s, rows_per_turn)


@dataclass(frozen=True, eq=False)
class QuadratureRows:
    """The whitened outputs the rule keeps, their weights, and the samples they need.

    ``last`` holds the sample index of each kept output (output m of the
    whitened series is sample m + p, its FIR reaching back to sample m).
    """

    last: np.ndarray  # (n,) sample index of each kept output
    weights: np.ndarray  # (n,) rows of the full sum each stands for
    order: int  # p

    @property
    def samples(self) -> np.ndarray:
        """(p + 1, n) sample indices: row j holds each cluster's sample at lag p − j."""
        return self.last[None, :] - np.arange(self.order, -1, -1)[:, None]

    def batches(self, max_samples: int):
        """The rows in parts of at most ``max_samples`` evaluated samples (bounded memory)."""
        per = max(1, max_samples // (self.order + 1))
        for start in range(0, self.last.size, per):
            part = slice(start, start + per)
            yield QuadratureRows(self.last[part], self.weights[part], self.order)

    def weigh(self, white: np.ndarray) -> float:
        """Weigh whitened rows (k, n, 3) in place, up to the returned factor of their Gram.

        The cells' rows all weigh s: only the rows past them (weight 1) are scaled,
        by √(1/s), and the Gram of the rows is then multiplied by s.
        """
        top = float(self.weights.max()) if self.weights.size else 1.0
        odd = np.flatnonzero(self.weights != top)
        white[:, odd, :] *= np.sqrt(self.weights[odd] / top)[:, None]
        return top


def quadrature_rows(samples: int, order: int, stride: int) -> QuadratureRows:
    """Centres of the whole cells of ``stride`` outputs, then every output past them."""
    outputs = max(samples - order, 0)
    cells = outputs // stride
    centre = np.arange(cells) * stride + (stride - 1) // 2
    rest = np.arange(cells * stride, outputs)
    weights = np.concatenate([np.full(cells, float(stride)), np.ones(rest.size)])
    return QuadratureRows(np.concatenate([centre, rest]) + order, weights, order)


def whitened_rows(noise: NoiseModel, columns: np.ndarray) -> np.ndarray:
    """The whitened output at each cluster's last sample, √weight not applied.

    ``columns`` (k, 3, p + 1, n): each cluster's samples in time order, as
    :attr:`QuadratureRows.samples` lays them out; returns (k, n, 3), a row of
    three axes per cluster (a run of clusters is then a view of k rows).
    """
    p = noise.order
    if columns.shape[2] != p + 1:
        raise ValueError(f"clusters of {columns.shape[2]} samples, the noise model needs {p + 1}")
    taps = noise.tap_matrices  # C_k = L⁻¹ diag(a_k): output(t) = Σ_k C_k x(t − k)
    out = np.matmul(columns[:, :, p, :].transpose(0, 2, 1), taps[0].T)
    for k in range(1, p + 1):
        out += np.matmul(columns[:, :, p - k, :].transpose(0, 2, 1), taps[k].T)
    return out
