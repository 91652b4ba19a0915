"""Statistics of the columns of an (N, 3) array of samples, without numpy's slow paths.

numpy reduces an (N, 3) C-ordered array over axis 0 one row of three at a
time (``x.mean(axis=0)`` on 18,000 samples: 0.25 ms, 50× a column's own
``sum``), and broadcasts ``x - mean`` over rows of three (90 µs).  The
samples arrive as (N, 3), so the front end's statistics go column by column
or through one transposed copy (3, N) whose rows are contiguous.

The numbers equal numpy's up to round-off: a column's ``sum`` adds pairwise,
the axis-0 reduction in sequence.
"""

from __future__ import annotations

import numpy as np


def column_means(x: np.ndarray) -> np.ndarray:
    """Mean of each column of ``x`` (N, k): ``x.mean(axis=0)``."""
    return np.array([x[:, k].mean() for k in range(x.shape[1])])


def difference_stds(x: np.ndarray) -> np.ndarray:
    """Std of each column's first differences: ``np.std(np.diff(x, axis=0), axis=0)``."""
    rows = np.ascontiguousarray(x.T, dtype=float)
    steps = rows[:, 1:] - rows[:, :-1]
    steps -= steps.mean(axis=1, keepdims=True)
    return np.sqrt(np.einsum("ij,ij->i", steps, steps) / max(steps.shape[1], 1))


def column_rms(x: np.ndarray) -> np.ndarray:
    """RMS of each column of ``x`` (N, k): ``np.sqrt(np.mean(x**2, axis=0))``."""
    rows = np.ascontiguousarray(x.T, dtype=float)
    return np.sqrt(np.einsum("ij,ij->i", rows, rows) / max(rows.shape[1], 1))


def centred_rows(x: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """(x − mean)ᵀ as a C-ordered (k, N) array: one contiguous row per column of ``x``."""
    out = np.empty((x.shape[1], x.shape[0]))
    np.subtract(x.T, mean[:, None], out=out)
    return out


def row_gram(rows: np.ndarray) -> np.ndarray:
    """The Gram matrix rows @ rowsᵀ of a few long rows, by dot products (faster than gemm)."""
    k = rows.shape[0]
    gram = np.empty((k, k))
    for i in range(k):
        for j in range(i, k):
            gram[i, j] = gram[j, i] = rows[i] @ rows[j]
    return gram
