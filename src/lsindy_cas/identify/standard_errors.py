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
from math import comb

import numpy as np

from ..mechanics.legendre import legendre
from .energy_balance import EnergyBalance
from .uncertainty import N_BLOCKS, Jackknife

__all__ = ["CoefErrors", "coefficient_errors", "propagated_std", "difference_noise", "MIN_RUNS"]

# Fewest runs for a jackknife over whole runs (fewer: over stretches of every run).  With fewer
# groups the standard error is itself too uncertain (a jackknife over g groups has g − 1 degrees of
# freedom; P(|t_{g−1}| ≤ 1) is 0.61 for g = 5, 0.66 for g = 10, 0.68 for g → ∞).
MIN_RUNS = 5
# Order of the differences behind the noise level that floors the smoother's (propagated_std):
# a smooth signal's k-th difference shrinks as (ω Δt)^k while white noise's grows as 2^k; at
# k = 6 the paper protocol's runs (100 Hz) give 0.8–1.3 σ on the double pendulum and cart, up to
# 1.5 σ on the spherical pendulum's fast φ̇ (orders 3–6 measured; higher orders only add noise).
DIFF_ORDER = 6


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


def propagated_std(fit) -> np.ndarray | None:
    """Standard errors (p,) of the energy's coefficients propagated from the estimated state noise
    through everything the fit did to it, with the rows' correlations (a model-based sandwich).

    The all-windows integral form's rows share noise: the smoother spreads each sample's noise
    over its neighbours, and the work integral carries every velocity's noise into all later rows
    of its run.  A jackknife over stretches treats the stretches as independent and a sandwich over
    single rows treats the rows as independent; on the noise sweep's paper protocol (cart, σ =
    1e-3) the first overstates the coefficients' scatter ~2×, the second understates it ~2×.
    Here every row's error is written as a linear map of the raw measurement noise e (white, σ̂
    per column: the larger of the smoother's estimate and :func:`difference_noise` — the
    smoother's likelihood estimate of a measured velocity's noise is biased low on short runs,
    which made these errors ~25 % too small: double pendulum, paper protocol, σ = 1e-3, 80 seeds:
    velocity σ̂ 0.5 σ on average, down to 0.0; RMS error / mean standard error 1.33, with the
    true σ 1.13): ε = Σ_k (diag(∇_k E) − T_k) H_k e_k, H_k the smoother of column k
    (the identity without smoothing), T_k the work integral's dependence on that column under its
    rule (trapezoid of q̇, position increments, spline of Q·q̇), and the coefficients' error
    G⁻¹Aᵀε has covariance G⁻¹ (Σ_k σ̂_k² Aᵀ L_k L_kᵀ A) G⁻¹ exactly to first order — the
    correlation length of the integration windows included, whatever it is.

    Returns None where the map is not built: passive or dissipative balances, compressed or
    fixed-window rows, estimated velocities (their noise comes from the positions), runs longer
    than one smoothing block.
    """
    from ..data.whittaker import MAX_BLOCK, smoother_map
    bal, coef = fit.balance, np.asarray(fit.coef, float)
    S = np.flatnonzero(coef)
    if (bal.passive or bal.b is None or bal.dissipation is not None or not fit.smoothing
            or not bal.centred or bal.form != "integral" or len(bal.A) != len(bal.X)
            or bal.D is None or not S.size or bal.intercept is not None):
        return None
    n_c = bal.X.shape[1] // 2
    grads = bal.D.reshape(len(bal.X), 2 * n_c, -1)[:, :, S] @ coef[S]         # ∇E per sample
    w = np.ones(len(bal.A)) if bal.weights is None else bal.weights
    groups = np.zeros(len(bal.A), int) if bal.groups is None else bal.groups
    A = bal.A[:, S]
    M = np.zeros((len(S), len(S)))
    for g, sm in enumerate(fit.smoothing):
        rows = np.flatnonzero(groups == g)
        tr = sm.raw
        n = len(rows)
        if tr.velocities != "measured" or n != tr.n_samples or n > MAX_BLOCK:
            return None
        smoothed = np.allclose(bal.X[rows], sm.trajectory.X, rtol=0, atol=1e-12 * (
            1 + np.abs(sm.trajectory.X).max()))
        B = np.sqrt(w[rows])[:, None] * A[rows]            # Aᵀ ε = Bᵀ u (rows already centred)
        rule = bal.work_rules[g] if bal.work_rules else "quadrature"
        sigma = np.maximum(sm.noise, difference_noise(tr.X))
        for k in range(2 * n_c):
            if not sigma[k] > 0:
                continue
            Lk = B.T * grads[rows, k]                        # Bᵀ diag(∇_k E)
            T = _work_map(tr, rule, k, n_c)
            if T is not None:
                Lk = Lk - B.T @ T
            if smoothed and sm.lam[k] > 0:
                U, f = smoother_map(tr.t, tr.Q, sm.lam[k])
                Lk = ((Lk @ U) * f) @ U.T                    # · H_k = U diag(f) Uᵀ
            M += sigma[k] ** 2 * (Lk @ Lk.T)
    G = A.T @ A
    try:
        Gi = np.linalg.inv(G)
    except np.linalg.LinAlgError:
        return None
    cov = Gi @ M @ Gi
    out = np.zeros(len(coef))
    out[S] = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return out


def difference_noise(X: np.ndarray, order: int = DIFF_ORDER) -> np.ndarray:
    """Noise level (2n,) of each raw state column from its ``order``-th differences: white noise
    σ gives differences of variance C(2·order, order) σ², a signal smooth at the sampling rate
    almost none; the median absolute difference (÷ 0.6745 for a normal) keeps a few fast
    stretches from counting.  A signal with content near the sampling rate raises it (never lowers
    it); zeros when the run is too short."""
    X = np.asarray(X, float)
    if len(X) <= order + 2:
        return np.zeros(X.shape[1])
    d = np.diff(X, n=order, axis=0)
    return np.median(np.abs(d), axis=0) / 0.6745 / np.sqrt(comb(2 * order, order))


def _work_map(tr, rule: str, k: int, n_c: int):
    """(n, n) matrix T: the cumulative work's first-order change per unit change of state column
    ``k`` at each sample, under the work rule (None: the work does not depend on the column)."""
    n, h = tr.n_samples, np.diff(tr.t)
    velocity, c = k >= n_c, k % n_c
    Q = tr.Q[:, c]
    if rule == "none" or not np.any(Q):
        return None
    per = np.zeros((n - 1, n))                               # interval j's work vs sample m
    j = np.arange(n - 1)
    if rule == "increments" and not velocity:
        per[j, j + 1], per[j, j] = Q[:-1], -Q[:-1]
    elif rule == "quadrature" and velocity:
        per[j, j] += 0.5 * h * Q[:-1]
        per[j, j + 1] += 0.5 * h * Q[:-1]
    elif rule == "spline" and velocity:                      # ≈ trapezoid of P = Q·q̇
        per[j, j] += 0.5 * h * Q[:-1]
        per[j, j + 1] += 0.5 * h * Q[1:]
    else:
        return None
    return np.vstack([np.zeros((1, n)), np.cumsum(per, axis=0)])
