"""Held-out error: how much of the data a support's fit leaves unexplained on data it was not
fitted on, and its residual in units of the noise — the numbers the choice of k and the verdict
read (:mod:`~lsindy_cas.identify.selection`, :mod:`~lsindy_cas.identify.status`).

Folds are whole trajectories when there are four or more, otherwise contiguous stretches of each
run (five folds).  Driven data: the fraction of the held-out work the fit does not explain;
passive data: the fraction of the held-out term changes the conserved combination does not cancel.
"""
from __future__ import annotations

import numpy as np

from .energy_balance import EnergyBalance
from .fitting import null_vector
from .uncertainty import recentre

__all__ = ["fold_ids", "cv_error", "chi_of", "CV_FLOOR"]

# Held-out errors below this (a relative residual of 1e-9, the accuracy of a simulation at
# rtol 1e-11 over a few hundred steps) are numerically zero and count as equal.
CV_FLOOR = 1e-18


def fold_ids(bal: EnergyBalance, n_folds: int = 5):
    """Held-out folds: (n_rows,) fold id, and whether whole trajectories are held out."""
    groups = np.zeros(len(bal.A), dtype=int) if bal.groups is None else bal.groups
    n_groups = int(groups.max()) + 1
    if n_groups >= 4:
        return groups % min(n_folds, n_groups), True
    ids = np.empty(len(groups), dtype=int)
    for g in range(n_groups):
        idx = np.flatnonzero(groups == g)
        ids[idx] = (np.arange(len(idx)) * n_folds) // len(idx)
    return ids, False


def cv_error(bal: EnergyBalance, S, folds=None):
    """Pooled held-out relative error of support S, and the per-fold errors.

    Driven: ‖A_te ξ − b_te‖² / ‖b_te‖² with ξ fitted on the other folds.  Passive: the fraction of
    the held-out term changes that the conserved combination fitted on the other folds does not
    cancel, ‖A_te η‖² / Σ_j ‖A_te,j η_j‖².
    """
    S = list(S)
    ids, whole = fold_ids(bal) if folds is None else folds
    num, den = [], []
    for f in np.unique(ids):
        te, tr = ids == f, ids != f
        Atr, btr = bal.A[tr][:, S], (None if bal.b is None else bal.b[tr])
        Ate, bte = bal.A[te][:, S], (None if bal.b is None else bal.b[te])
        if bal.centred and not whole:
            Atr, btr = recentre(bal, tr, Atr, btr)
            Ate, bte = recentre(bal, te, Ate, bte)
        if bal.b is None:
            eta = null_vector(Atr)
            num.append(float(np.sum((Ate @ eta) ** 2)))
            den.append(float(np.sum((Ate * eta) ** 2)))
        else:
            xi = np.linalg.lstsq(Atr, btr, rcond=None)[0]
            num.append(float(np.sum((Ate @ xi - bte) ** 2)))
            den.append(float(bte @ bte))
    num, den = np.array(num), np.array(den)
    with np.errstate(divide="ignore", invalid="ignore"):
        per = np.where(den > 0, num / den, 0.0)
    pooled = float(num.sum() / den.sum()) if den.sum() > 0 else 0.0
    return max(pooled, CV_FLOOR), np.maximum(per, CV_FLOOR)


def chi_of(bal, coef, noise) -> float:
    """Residual of the coefficients ``coef`` on the driven balance in units of the noise they carry
    into it (:meth:`~.uncertainty.NoiseModel.chi`)."""
    # the residual itself, not score·‖b‖²: the score comes from the normal equations, whose
    # round-off (~1e-14 relative) would read as a misfit on clean data
    r = bal.A @ coef - bal.b
    return noise.chi(coef, float(r @ r), CV_FLOOR * float(bal.b @ bal.b))
