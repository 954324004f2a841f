"""The support-fitting core: column normalisation and the coefficients of one support.

Every search path (the exhaustive :func:`lsindy_cas.identify.search.best_subset`, the beam of
:mod:`lsindy_cas.identify.selection`, the diagnostics) fits a support through these functions, so
the same support gets the same coefficients whichever path found it.

- driven (b ≠ 0): least squares on the column-normalised A_S, mapped back to data units;
- passive (b = None): the near null space of the column-normalised A_S.  With a scale record
  (A_s, b_s) (paper eq. 8) the combination of its basis that best explains the record's work is
  taken (least squares: when the null space has dimension > 1, e.g. energy and an angular
  momentum both conserved, the actuated record picks the energy); without one, the most nearly
  conserved direction, scaled to a largest coefficient of 1.
"""
from __future__ import annotations

import numpy as np

__all__ = ["column_norms", "normalise_columns", "normal_equations", "null_vector", "coef_on_support",
           "NULL_RTOL", "NULL_FACTOR"]

# The near null space on a support: singular values within NULL_FACTOR of the smallest, or below
# NULL_RTOL of the largest (round-off of an exactly conserved combination).
NULL_FACTOR = 1e3
NULL_RTOL = 1e-7


def column_norms(A: np.ndarray) -> np.ndarray:
    """Euclidean norm of every column of ``A`` (zeros kept).

    Computed 64 columns at a time, so a tall ``A`` (a streamed balance) needs no full-size
    temporary; each column's sum is the same as in one pass.
    """
    A = np.asarray(A)
    if A.ndim != 2 or A.shape[1] <= 64:
        return np.linalg.norm(A, axis=0)
    return np.concatenate([np.linalg.norm(A[:, j:j + 64], axis=0) for j in range(0, A.shape[1], 64)])


def normalise_columns(A: np.ndarray):
    """``(A / s, s)``: unit-norm columns and the scales ``s`` (a zero column keeps scale 1)."""
    s = column_norms(A)
    s = np.where(s > 0, s, 1.0)
    return A / s, s


def normal_equations(A: np.ndarray, b: np.ndarray | None):
    """Gram matrix Âᵀ Â and Âᵀ b (None when passive) of the column-normalised ``A``."""
    An, _ = normalise_columns(A)
    return An.T @ An, (None if b is None else An.T @ b)


def null_vector(AS: np.ndarray) -> np.ndarray:
    """Most nearly conserved combination of the columns of ``AS``, in data units (unscaled)."""
    An, s = normalise_columns(AS)
    return np.linalg.svd(An, full_matrices=False)[2][-1] / s


def coef_on_support(A: np.ndarray, b: np.ndarray | None, S, scale_system=None):
    """Coefficients (p,) of support ``S`` in data units, and the near-null-space dimension.

    Parameters
    ----------
    A : array (m, p)
    b : array (m,) or None
        ``None``: passive scheme (null space of A_S, scaled by ``scale_system``).
    S : sequence of int
    scale_system : (A_s, b_s), optional
        Passive scheme: an actuated record with A_s ξ = b_s.

    Returns
    -------
    coef : array (p,) or None
        None when the scale record cannot fix the scale (no power, or blind to the null space).
    null_dim : int
        Passive: dimension of the near null space on ``S`` (0 for driven data).
    """
    S = list(S)
    xi = np.zeros(A.shape[1])
    An, s = normalise_columns(A[:, S])
    if b is not None:
        xi[S] = np.linalg.lstsq(An, b, rcond=None)[0] / s
        return xi, 0
    _, sv, Vt = np.linalg.svd(An, full_matrices=False)
    tol = max(sv[-1] * NULL_FACTOR, sv[0] * NULL_RTOL)
    N = Vt[sv <= tol].T / s[:, None]                         # (k, null_dim), data units
    if scale_system is None:
        v = N[:, -1]
        xi[S] = v / np.max(np.abs(v))
        return xi, N.shape[1]
    As, bs = scale_system
    M = As[:, S] @ N
    if not np.any(bs) or np.linalg.norm(M) == 0:
        return None, N.shape[1]
    xi[S] = N @ np.linalg.lstsq(M, bs, rcond=None)[0]
    return xi, N.shape[1]
