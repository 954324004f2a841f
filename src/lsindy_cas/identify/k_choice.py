"""How the automatic scan of :func:`~lsindy_cas.identify.selection.select` compares the models
of different k (module notes there): a larger k must cut the held-out error by ``IMPROVEMENT``,
significantly over the folds, and lower χ when the noise is known; a model that fits the data to
the noise (χ ≤ ``CHI_OK``) or to the held-out floor of clean data (``EXACT_CV``) ends the scan."""
from __future__ import annotations

import numpy as np

from .selection_records import Step

__all__ = ["IMPROVEMENT", "CHI_OK", "CHI_MISS", "EXACT_CV", "better", "gain", "fair",
           "fits_data", "fits",
           "choose"]

IMPROVEMENT = 2.0
# χ of a correct model is ≈ 1 − k/m_eff in theory; measured 0.2–1.7 for the true energies of the
# benchmark systems at σ = 1e-3 … 1e-1 (the noise estimate is good to ~20 %, and neighbouring rows
# share smoothed noise).  Models missing a real term measured χ ≳ 40.
CHI_OK = 2.0
# A model whose χ exceeds this misses part of the data: the scan does not stop on it, a beam's
# model this poor is checked by a scout at the same k, and the verdict (status.CHI_BAD) calls it so.
CHI_MISS = 10.0
# A held-out error below this (relative residual 1e-5) is a fit to the quadrature floor of clean
# data: true energies measured 1e-18 (Acrobot, double pendulum, 2-10 ms samples), the best wrong
# models of one term more 5e-8 - 8e-6 (Acrobot, 48 runs), so nothing of more terms can do better.
EXACT_CV = 1e-10
_T95 = {1: 6.31, 2: 2.92, 3: 2.35, 4: 2.13, 5: 2.02}   # one-sided 5 % t quantiles, by dof


def better(new: Step, old: Step) -> bool:
    """Does ``new`` cut the held-out error of ``old`` by IMPROVEMENT, significantly over folds —
    and, when the noise is known, also its residual in units of its own expected noise?"""
    if not new.cv * IMPROVEMENT < old.cv:
        return False
    if np.isfinite(new.chi) and np.isfinite(old.chi) and not new.chi < old.chi:
        return False
    return gain(new, old)


def gain(new: Step, old: Step) -> bool:
    """Is the held-out error of ``new`` below that of ``old`` in a paired one-sided test over the
    folds (5 %), by any factor?"""
    if not new.cv < old.cv:
        return False
    d = np.log(old.cv_folds) - np.log(new.cv_folds)        # per-fold log improvement
    if len(d) < 2:
        return True
    se = d.std(ddof=1) / np.sqrt(len(d))
    return bool(d.mean() > _T95.get(len(d) - 1, 1.65) * se)


def choose(steps) -> tuple:
    """(best, fits) over the scored steps in order of k, by the scan's rules (module notes)."""
    best = fitted = None
    for step in steps:
        if fitted is None and fits_data(step):
            fitted = step
        if best is None or better(step, best):
            best = step
    return best, fitted


def fits_data(step: Step) -> bool:
    """Does the step's model fit the data to the noise or the clean-data floor (:func:`fits`)?"""
    return fits(step.chi, step.cv)


def fits(chi: float, held_out_error: float) -> bool:
    """Does a model fit the data as well as any can: to the noise (χ ≤ CHI_OK) or to the held-out
    floor of clean data (EXACT_CV)?  The scan stops there, and the verdict does not ask for the
    smaller k's a search left undecided."""
    return bool((np.isfinite(chi) and chi <= CHI_OK) or held_out_error <= EXACT_CV)


def fair(step: Step) -> bool:
    """Does the step's model explain the data up to a missing detail (χ ≤ CHI_MISS)?  Without a
    noise model there is no scale to judge it by, and it counts as fair."""
    return not step.chi > CHI_MISS
