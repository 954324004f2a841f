"""Standard errors of the identified coefficients (H's and, through eq. 7, L's).

A delete-a-group jackknife (Quenouille–Tukey; Efron & Tibshirani, *An Introduction to the
Bootstrap*, 1993, ch. 11) on the balance the coefficients were fitted to (weighted, as fitted):
each group of rows is left out in turn, the coefficients on the chosen support are re-fitted
(:class:`lsindy_cas.identify.uncertainty.Jackknife`, per-group Gram matrices, so a replicate is
one small solve), and the spread of the replicates gives the standard error.

The groups are what is independent in the data.  The all-windows integral form carries the
work integral's random walk through a whole run, so neighbouring rows and even distant stretches
of one run share noise; with enough runs (``MIN_RUNS``) the groups are whole runs, otherwise
contiguous stretches of every run (:func:`lsindy_cas.identify.uncertainty.block_ids`).

What it does not cover: a bias of the estimator (smoothing, the remaining errors-in-variables
bias), which is second order in the noise, and — passive scheme — the noise of the short scale
record, which is added as a relative error common to every coefficient (eq. 8's least squares).
The Lagrangian's errors come from the same replicates mapped through the (linear) Legendre
transform, so they are exact for the linear map, also for non-homogeneous terms.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..mechanics.legendre import legendre
from .balance import EnergyBalance
from .uncertainty import N_BLOCKS, Jackknife

__all__ = ["CoefErrors", "coefficient_errors", "MIN_RUNS"]

# Fewest runs for a jackknife over whole runs (fewer: over stretches of every run).  With fewer
# groups the standard error is itself too uncertain (a jackknife over g groups has g − 1 degrees of
# freedom; P(|t_{g−1}| ≤ 1) is 0.61 for g = 5, 0.66 for g = 10, 0.68 for g → ∞).
MIN_RUNS = 5


@dataclass
class CoefErrors:
    """Standard errors of a fit's coefficients.

    Attributes
    ----------
    hamiltonian : array (p,)
        Standard error of each energy coefficient (0 off the support).
    lagrangian : array (p,)
        Standard error of each Lagrangian coefficient (eq. 7; 0 off the support).
    method : str
        How they were obtained, e.g. ``"jackknife over 10 runs"``.
    """

    hamiltonian: np.ndarray
    lagrangian: np.ndarray
    method: str


def coefficient_errors(bal: EnergyBalance, coef: np.ndarray, library, X=None,
                       scale_system=None, by: str = "auto") -> CoefErrors:
    """Jackknife standard errors of ``coef`` (p,) fitted on ``bal``.

    Parameters
    ----------
    bal : EnergyBalance
        The balance ``coef`` was fitted to (weighted as fitted).
    coef : array (p,)
        The reported energy coefficients (their support is re-fitted per replicate).
    library : Library
        For the Legendre transform of the replicates.
    X : array (n_samples, 2n), optional
        Sample states, needed only for non-homogeneous terms (see :func:`legendre`).
    scale_system : (A_s, b_s), optional
        Passive scheme: the actuated record that fixes the scale.
    by : {"auto", "runs", "blocks"}
        Groups left out: whole runs, contiguous stretches of every run, or runs when there are at
        least ``MIN_RUNS`` of them (default).
    """
    coef = np.asarray(coef, float)
    S = np.flatnonzero(coef)
    p = len(coef)
    if by not in ("auto", "runs", "blocks"):
        raise ValueError(f"by must be 'auto', 'runs' or 'blocks', got {by!r}")
    n_runs = bal.n_groups
    use_runs = by == "runs" or (by == "auto" and n_runs >= MIN_RUNS)
    if use_runs and n_runs < 2:
        raise ValueError("a jackknife over runs needs at least 2 runs")
    if S.size == 0:
        return CoefErrors(np.zeros(p), np.zeros(p), "none (empty model)")
    jack = Jackknife(bal, ids=bal.groups if use_runs else None)
    reps, _ = jack.replicates(S, coef[S], scale_system)
    se_h = np.zeros(p)
    se_h[S] = jack.se(reps)
    # the same replicates through eq. 7 (linear in the coefficients)
    full = np.zeros((len(reps), p))
    full[:, S] = reps
    try:
        reps_l = np.array([legendre(library, r, X) for r in full])
        se_l = jack.se(reps_l)
    except ValueError:          # a replicate with no Legendre transform: unknown
        se_l = np.where(coef != 0, np.nan, 0.0)
    if bal.passive and scale_system is not None:
        rel = _scale_error(bal, coef, scale_system)
        se_h = np.hypot(se_h, rel * np.abs(coef))
        lag = legendre(library, coef, X)
        se_l = np.hypot(se_l, rel * np.abs(lag))
    method = (f"jackknife over {jack.n_blocks} runs" if use_runs else
              f"jackknife over {jack.n_blocks} stretches of the data")
    return CoefErrors(se_h, se_l, method)


def _scale_error(bal, coef, scale_system) -> float:
    """Relative standard error of the passive energy's scale c in A_s (c ξ) ≈ b_s (eq. 8).

    Least squares of one factor on the scale record's rows, with contiguous blocks for the error
    (the record's rows share the work integral's noise, as in the training runs).
    """
    As, bs = scale_system
    a = As @ coef
    denom = float(a @ a)
    if not denom > 0:
        return 0.0
    c = float(a @ bs) / denom               # ≈ 1: coef is already scaled
    r = bs - c * a
    blocks = np.array_split(np.arange(len(r)), min(N_BLOCKS, len(r)))
    var = sum(float(a[i] @ r[i]) ** 2 for i in blocks) / denom ** 2
    return float(np.sqrt(var) / abs(c)) if c else 0.0
