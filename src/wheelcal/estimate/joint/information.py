"""Linear algebra of the Fisher information, shared by every estimator and test.

Information matrices here mix parameters of very different scales (ω₃ in
rad/s⁴ next to offsets in m/s²), and some directions carry no information at
all (an unidentifiable parameter).  Every inverse is therefore taken after
scaling by the diagonal, through the eigen-decomposition, with directions below
``relative_floor`` × the largest eigenvalue treated as carrying nothing.
"""

from __future__ import annotations

import numpy as np

RELATIVE_FLOOR = 1e-12


def _scaled_eigh(matrix: np.ndarray, relative_floor: float):
    scale = np.sqrt(np.maximum(np.diag(matrix), 1e-300))
    w, v = np.linalg.eigh(matrix / np.outer(scale, scale))
    return scale, w, v, w > w.max() * relative_floor


def scaled_pinv(matrix: np.ndarray, relative_floor: float = RELATIVE_FLOOR) -> np.ndarray:
    """Pseudo-inverse of a symmetric information matrix (scaled, floored eigenvalues)."""
    scale, w, v, keep = _scaled_eigh(matrix, relative_floor)
    return (v[:, keep] / w[keep]) @ v[:, keep].T / np.outer(scale, scale)


def covariance_from_fisher(
    fisher: np.ndarray, relative_floor: float = RELATIVE_FLOOR
) -> np.ndarray:
    """Pseudo-inverse of the Fisher matrix with ∞ variance in null directions.

    Parameters with weight on a direction that carries no information get an
    infinite variance (and NaN covariances) instead of a confident number.
    """
    scale, w, v, keep = _scaled_eigh(fisher, relative_floor)
    cov = (v[:, keep] / w[keep]) @ v[:, keep].T / np.outer(scale, scale)
    unidentifiable = np.sum(v[:, ~keep] ** 2, axis=1) > 1e-6
    if np.any(unidentifiable):
        cov[unidentifiable, :] = np.nan
        cov[:, unidentifiable] = np.nan
        cov[unidentifiable, unidentifiable] = np.inf
    return cov


def fisher_covariance(whitened_jacobian: np.ndarray, relative_floor: float = RELATIVE_FLOOR):
    """Fisher matrix of a whitened, transposed Jacobian (P, 3, M) and its inverse.

    Returns ``(covariance, fisher)`` (see :func:`covariance_from_fisher`).
    """
    jt = whitened_jacobian.reshape(whitened_jacobian.shape[0], -1)
    fisher = jt @ jt.T
    return covariance_from_fisher(fisher, relative_floor), fisher


def information_fraction(schur: np.ndarray, own_diagonal: np.ndarray) -> float:
    """λ_min of D⁻½ C D⁻½: the fraction of a block's information the others leave it.

    ``schur`` is the block's Schur complement C (its information once every
    other parameter is fitted), ``own_diagonal`` the diagonal D of its own
    information.  0 means the other parameters can mimic the block entirely.
    """
    d = np.sqrt(np.maximum(own_diagonal, 1e-300))
    return float(max(np.linalg.eigvalsh(schur / np.outer(d, d)).min(), 0.0))


def block_information_fraction(fisher: np.ndarray, block: list[int]) -> float:
    """:func:`information_fraction` of rows/columns ``block`` of a full Fisher matrix."""
    rest = [i for i in range(fisher.shape[0]) if i not in block]
    h_bb = fisher[np.ix_(block, block)]
    h_br = fisher[np.ix_(block, rest)]
    schur = h_bb - h_br @ scaled_pinv(fisher[np.ix_(rest, rest)]) @ h_br.T
    return information_fraction(schur, np.diag(h_bb))
