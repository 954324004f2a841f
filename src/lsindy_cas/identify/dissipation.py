"""Rayleigh dissipation in the energy balance: dE/dt = P − q̇·∂R/∂q̇,  R = Σ_j ρ_j R_j(q̇).

Each candidate term R_j contributes a column c_j = q̇·∂R_j/∂q̇ (its dissipated power per unit
coefficient; a Coulomb term |v| gives |v| exactly): the derivative form adds c_j to the energy
columns, the integral form its time integral over each window (centred per run as the energy
columns, :mod:`lsindy_cas.identify.balance`).  ∫ c_j dt is taken by Simpson's rule on
``SUBSTEPS`` sub-intervals of every sampling interval with the states interpolated by a cubic
spline: 4th order where c_j is smooth, and the kink of |v| at a velocity reversal costs only
O((h/SUBSTEPS)²) once per reversal.

How the search sees them.  The dissipation columns are in every model, like prior terms: least
squares with columns that are always present is least squares on everything projected off their
span (Frisch–Waugh–Lovell), so the balance handed to the energy search is ``P⊥A ξ = P⊥b`` (or
``P⊥A ξ ≈ 0`` for passive data) and every part of the search, selection, errors-in-variables and
diagnostics works unchanged.  Given the energy coefficients ξ, the dissipation coefficients are
ρ = argmin ‖D ρ − (b − A ξ)‖.  Terms the data do not support are then removed one at a time
(least significant first, :func:`prune`) and the model is refitted without them, so they come out
exactly zero.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..mechanics.rayleigh import check_velocity_only
from ..symbolic.library import Library
from .admissibility import REDUCIBLE_TOL
from .findings import UndeterminedError
from .work import increments_preferred
from .uncertainty import N_BLOCKS, T_CRIT, Jackknife

__all__ = ["full_rayleigh", "fold_scale", "norm_term", "dissipation_library", "power_columns",
           "dissipation_columns", "project", "rayleigh_coef", "prune", "check_dissipation",
           "quadrature_floor", "floored_chi", "SUBSTEPS", "COLLINEAR_RTOL"]

SUBSTEPS = 8
# Dissipation columns count as inseparable when the smallest singular value of the column-
# normalised block is below this fraction of the largest (round-off level: the data cannot tell
# the terms apart, e.g. v² and |v| on a run at constant speed).
COLLINEAR_RTOL = 1e-7
# The work counts as explained by the dissipation columns alone when what is left of it after the
# projection is below this fraction (the applied force and friction then cannot be told apart).
WORK_RTOL = 1e-6
# A fitted R dissipates no negative power beyond round-off: min power ≥ −NEG_RTOL · max |power|.
NEG_RTOL = 1e-9


def dissipation_library(coords, terms) -> Library | None:
    """The candidate terms of R as a :class:`Library` (None for none); velocities only."""
    if terms is None:
        return None
    if isinstance(terms, Library):
        lib = terms
        if lib.coords.names != list(coords.names):
            raise ValueError(f"dissipation library coordinates {lib.coords.names} differ from the "
                             f"energy library's {list(coords.names)}")
    else:
        terms = [terms] if isinstance(terms, str) else list(terms)
        if not terms:
            return None
        exprs = []
        for i, t in enumerate(terms):
            if not isinstance(t, str) and not hasattr(t, "free_symbols"):
                raise TypeError(f"dissipation term #{i + 1} must be a string, got "
                                f"{type(t).__name__}")
            exprs.append(coords.parse(t, what=f"dissipation term #{i + 1}"))
        check_velocity_only(coords, exprs)
        return Library(coords, exprs)
    check_velocity_only(lib.coords, lib.exprs)
    return lib


def power_columns(lib: Library, X) -> np.ndarray:
    """c_j = q̇·∂R_j/∂q̇ at states X: (n_samples, r)."""
    X = np.atleast_2d(np.asarray(X, float))
    n = lib.coords.n
    return np.einsum("si,sij->sj", X[:, n:], lib.dtheta_dqd(X))


def _hermite(tr, s):
    """States on the sub-grid ``s`` of every sampling interval: q by the cubic Hermite interpolant
    of (q, q̇) at the interval's ends, q̇ its derivative — a quadratic per interval with the exact
    ends and the exact mean (q_{i+1} − q_i)/h.  Local: nothing crosses a sample, where a held input
    that changes puts a kink into q̇.  Also returns the curvature q⃛ of each interval's velocity."""
    n = len(tr.coords)
    h = np.diff(tr.t)[:, None, None]
    q0, q1, v0, v1 = tr.q[:-1, None], tr.q[1:, None], tr.qd[:-1, None], tr.qd[1:, None]
    s = s[None, :, None]
    q = ((2 * s ** 3 - 3 * s ** 2 + 1) * q0 + (s ** 3 - 2 * s ** 2 + s) * h * v0
         + (-2 * s ** 3 + 3 * s ** 2) * q1 + (s ** 3 - s ** 2) * h * v1)
    v = ((6 * s ** 2 - 6 * s) * (q0 - q1) / h + (3 * s ** 2 - 4 * s + 1) * v0
         + (3 * s ** 2 - 2 * s) * v1)
    curv = (6 * (v0 + v1) + 12 * (q0 - q1) / h)[:, 0] / h[:, 0] ** 2     # v'' on each interval
    return np.concatenate([q, v], axis=2).reshape(-1, 2 * n), curv


def _simpson(lib, Xf, h, k):
    """Simpson increments (n_intervals, r) of c_j on ``k`` sub-intervals per interval; ``Xf`` holds
    the states on a grid of SUBSTEPS sub-intervals (k divides SUBSTEPS)."""
    m = len(h)
    c = power_columns(lib, Xf).reshape(m, SUBSTEPS + 1, -1)[:, ::SUBSTEPS // k]
    w = np.ones(k + 1)
    w[1:-1:2], w[2:-1:2] = 4.0, 2.0
    return np.einsum("k,ikj->ij", w, c) * (h / (3 * k))[:, None]


def _cumulative(lib: Library, tr, hermite: bool = True):
    """∫_{t_0}^{t_i} c_j dt per sample, (n_samples, r), and an estimate of its quadrature error.

    The states between samples: the per-interval Hermite path (``hermite``, exact data or data
    whose position increments are better than their velocities' quadrature,
    :func:`~lsindy_cas.identify.balance.increments_preferred`) or a cubic spline through q̇ (noisy
    velocities: smooth, but it rounds the kinks of a held input).  Then Simpson's rule on
    ``SUBSTEPS`` sub-intervals.  Error estimate per interval, the leading terms: Simpson's
    (SUBSTEPS against SUBSTEPS/2, /15) and the path's — for the Hermite path the velocity error
    (h³ v⃛/6)·s(s − 1)(s − ½) with v⃛ from the neighbouring intervals' curvatures; for the spline,
    its difference from the trapezoid of c_j at the samples (it rounds kinks to that order).
    """
    t = tr.t
    h = np.diff(t)
    s = np.arange(SUBSTEPS + 1) / SUBSTEPS
    if hermite:
        Xf, curv = _hermite(tr, s)
    else:
        from scipy.interpolate import CubicSpline
        tf = (t[:-1, None] + h[:, None] * s[None, :]).ravel()
        Xf = CubicSpline(t, tr.X, axis=0)(tf)
        Xf[::SUBSTEPS + 1] = tr.X[:-1]                    # sample points exact
        Xf[SUBSTEPS::SUBSTEPS + 1] = tr.X[1:]
    inc = _simpson(lib, Xf, h, SUBSTEPS)
    err = np.abs(inc - _simpson(lib, Xf, h, SUBSTEPS // 2)) / 15
    if hermite:
        jerk = np.gradient(curv, t[:-1] + h / 2, axis=0) if len(h) > 1 else np.zeros_like(curv)
        n = len(tr.coords)
        bump = (h[:, None] ** 3 * jerk / 6)[:, None, :] * (s * (s - 1) * (s - 0.5))[None, :, None]
        Xp = Xf.reshape(len(h), SUBSTEPS + 1, 2 * n).copy()
        Xp[:, :, n:] += bump
        err += np.abs(_simpson(lib, Xp.reshape(-1, 2 * n), h, SUBSTEPS) - inc)
    else:
        c = power_columns(lib, tr.X)
        err += np.abs(inc - 0.5 * (c[1:] + c[:-1]) * h[:, None])
    zero = np.zeros((1, inc.shape[1]))
    return np.vstack([zero, np.cumsum(inc, axis=0)]), np.vstack([zero, np.cumsum(err, axis=0)])


def dissipation_columns(lib: Library, trajectories, bal, noise=None, error: bool = False):
    """Rows of the dissipation columns matching the balance ``bal``'s rows: (n_rows, r).

    ``noise``: per trajectory, the noise left in each state column (None: exact data), which
    picks the velocity path of the integral form (:func:`_cumulative`).  ``error=True`` also
    returns the estimated quadrature error of each entry (zeros for the derivative form), rows
    centred and weighted as the columns'.
    """
    if bal.compressed:
        raise ValueError("dissipation needs one balance row per sample; these data are too large "
                         f"for that ({bal.n_rows:,} rows): use fewer samples")
    if bal.form == "derivative":
        D = np.vstack([power_columns(lib, tr.X) for tr in trajectories])
        return (D, np.zeros_like(D)) if error else D
    if not bal.centred:
        raise ValueError("dissipation needs the all-windows integral form (window=None)")
    out, errs, w_all, pos = [], [], bal.weights, 0
    for k, tr in enumerate(trajectories):
        C, E = _cumulative(lib, tr, increments_preferred(tr, None if noise is None else noise[k]))
        w = np.ones(tr.n_samples) if w_all is None else w_all[pos:pos + tr.n_samples]
        pos += tr.n_samples
        out.append(np.sqrt(w)[:, None] * (C - (w @ C) / w.sum()))
        errs.append(np.sqrt(w)[:, None] * (E - (w @ E) / w.sum()))
    return (np.vstack(out), np.vstack(errs)) if error else np.vstack(out)


def project(bal, Dd: np.ndarray, error, names):
    """The balance with ``A``, ``b`` projected off the span of the dissipation columns ``Dd``
    (``error``: their estimated quadrature error, same shape, or None)."""
    s = np.linalg.norm(Dd, axis=0)
    zero = [names[j] for j in np.flatnonzero(s == 0)]
    if zero:
        raise ValueError(f"dissipation term(s) {', '.join(zero)} dissipate nothing on the data "
                         "(the velocities they use never move)")
    U, sv, _ = np.linalg.svd(Dd / s, full_matrices=False)
    if sv[-1] < COLLINEAR_RTOL * sv[0]:
        raise ValueError("the data cannot separate the dissipation terms "
                         f"{', '.join(names)}: they dissipate proportional power on these runs "
                         "(too short or too uniform data); drop a term or add varied runs")
    A = bal.A - U @ (U.T @ bal.A)
    b = None if bal.b is None else bal.b - U @ (U.T @ bal.b)
    if b is not None and np.linalg.norm(b) <= WORK_RTOL * np.linalg.norm(bal.b):
        raise ValueError("the data cannot separate the dissipation terms "
                         f"{', '.join(names)} from the applied work: friction explains all of it "
                         "(e.g. Coulomb |v| under a constant force while v keeps its sign); vary "
                         "the input or add runs")
    return replace(bal, A=A, b=b, dissipation=Dd, raw=(bal.A, bal.b), dissipation_error=error)


def rayleigh_coef(bal, coef) -> np.ndarray:
    """Dissipation coefficients ρ (r,) that go with energy coefficients ``coef`` on ``bal``."""
    A, b = bal.raw
    rhs = -(A @ coef) if b is None else b - A @ coef
    s = np.linalg.norm(bal.dissipation, axis=0)
    return np.linalg.lstsq(bal.dissipation / s, rhs, rcond=None)[0] / s


def significance(bal, coef) -> np.ndarray:
    """Jackknife |t| (r,) of the dissipation coefficients fitted jointly with the energy support."""
    A, b = bal.raw
    S = list(np.flatnonzero(coef))
    r = bal.dissipation.shape[1]
    joint = replace(bal, A=np.hstack([A[:, S], bal.dissipation]), b=b, dissipation=None, raw=None)
    if b is None:       # passive: replicate and full null vectors in the jackknife's own scaling
        return Jackknife(joint).t(list(range(len(S) + r)))[len(S):]
    full = np.r_[coef[S], rayleigh_coef(bal, coef)]
    return Jackknife(joint).t(list(range(len(S) + r)), full)[len(S):]


def t_crit(m: int) -> float:
    """Critical |t| when the least significant of ``m`` candidate terms is tested: the energy
    terms' two-sided 1 % level (:data:`~lsindy_cas.identify.uncertainty.T_CRIT`, Student's t with
    N_BLOCKS − 1 degrees of freedom) divided among the m candidates (Bonferroni).  The minimum of m
    statistics is what is tested; at the plain 1 % level a spurious cross term θ̇ẋ survived in 2 of
    10 seeds of the rich protocol at σ = 1e-2 (t = 3.5, 5.0), the block jackknife's standard error
    of that term being ~1.6× too small there (measured over 10 noise draws: 3.5e-4 against a
    spread of 5.8e-4 — the integral form's residuals are random walks within a run)."""
    from scipy.stats import t as student
    return max(T_CRIT, float(student.ppf(1 - 0.005 / max(m, 1), N_BLOCKS - 1)))


def prune(bal, coef) -> list:
    """Indices (into the balance's dissipation columns) of the terms the data support.

    A term goes when its share of the balance (|ρ_j|·‖c_j‖ against the largest term's) is below
    REDUCIBLE_TOL — round-off on exact data, the rule the energy terms meet in the search — or,
    least significant first, while its jackknife |t| < :func:`t_crit` (the energy terms' test,
    :mod:`lsindy_cas.identify.uncertainty`); the others are refitted each time.
    """
    keep = list(range(bal.dissipation.shape[1]))
    energy_share = np.max(np.abs(coef) * np.linalg.norm(bal.raw[0], axis=0))
    while keep:
        sub = replace(bal, dissipation=bal.dissipation[:, keep], dissipation_error=None)
        share = np.abs(rayleigh_coef(sub, coef)) * np.linalg.norm(sub.dissipation, axis=0)
        j = int(np.argmin(share))
        if share[j] <= REDUCIBLE_TOL * max(energy_share, share.max()):
            keep.pop(j)
            continue
        t = significance(sub, coef)
        j = int(np.argmin(t))
        if t[j] >= t_crit(len(keep)):
            break
        keep.pop(j)
    return keep


def full_rayleigh(lib, active, bal, coef):
    """Dissipation coefficients (r,) over all candidate terms of ``lib`` (zeros for the dropped
    ones; None without a dissipation library), checked by :func:`check_dissipation`."""
    if lib is None:
        return None
    rho = np.zeros(len(lib))
    if bal.dissipation is not None:
        rho[active] = rayleigh_coef(bal, coef)
    check_dissipation(lib, rho, bal.X)
    return rho


def quadrature_floor(bal, coef) -> float:
    """The residual (sum of squares, in the balance's units) that the dissipation integrals' own
    quadrature error can leave with energy coefficients ``coef``: ‖E |ρ|‖², E the estimated error
    of each column entry (:func:`_cumulative`; errors taken to add up).  0 without dissipation
    columns or an error estimate (derivative form: the columns are exact)."""
    E = getattr(bal, "dissipation_error", None)
    if E is None or bal.dissipation is None or bal.b is None:
        return 0.0
    return float(np.sum((E @ np.abs(rayleigh_coef(bal, coef))) ** 2))


def floored_chi(bal, coef, chi: float) -> float:
    """χ (:meth:`~lsindy_cas.identify.uncertainty.NoiseModel.chi`) with the quadrature floor F of
    :func:`quadrature_floor` added to both the residual and its expectation: (rss + F) /
    (rss/χ + F).  On clean data the estimated noise is ~0 and an exact model's residual is the
    quadrature's, so χ ≈ 1 there instead of 1e10; a model that misses something leaves more."""
    F = quadrature_floor(bal, coef)
    if not (F > 0 and np.isfinite(chi) and chi > 0):
        return chi
    rss = float(np.sum((bal.b - bal.A @ coef) ** 2))
    return (rss + F) / (rss / chi + F)


def fold_scale(bal, scale, Ds):
    """Passive scheme with friction: the scale record's balance (A_s, b_s) with the friction work
    of ρ(ξ) = −pinv(D) A ξ (the passive balance's dissipation) folded into A_s."""
    B = np.linalg.lstsq(bal.dissipation, bal.raw[0], rcond=None)[0]     # ρ = −B ξ
    return scale.A - Ds @ B, scale.b


def norm_term(library, coef, forced) -> int:
    """Relative energy (passive data, no scale record): the term whose coefficient is set to 1 —
    the first kinetic (quadratic in q̇) prior term in library order, else the first kinetic term
    of the support.  A kinetic term keeps the sign physical: M = ∂²E/∂q̇² ≻ 0 after the division."""
    kinetic = [j for j in np.flatnonzero(coef) if library.velocity_degree(j) == 2]
    for j in [j for j in sorted(forced) if j in kinetic] + kinetic:
        return int(j)
    raise ValueError("the passive energy has no kinetic (velocity-quadratic) term to normalise by")


def check_dissipation(lib: Library, rho, X) -> None:
    """Refuse a fitted R that creates energy: dissipated power < 0 somewhere on the data or at the
    data's velocities scaled by 1e-3 (low speed, where Coulomb terms dominate), or a viscous
    (quadratic) part that is not positive semidefinite."""
    if not np.any(rho):
        return
    # also at the data's velocities scaled down: a negative Coulomb term (degree 1) hidden by a
    # viscous one (degree 2) on the data still creates energy at low speed
    n = lib.coords.n
    slow = np.hstack([X[:, :n], 1e-3 * X[:, n:]])
    power = np.r_[power_columns(lib, X) @ rho, 1e6 * (power_columns(lib, slow) @ rho)]
    top = max(np.max(np.abs(power)), 1e-300)
    if power.min() < -NEG_RTOL * top:
        raise UndeterminedError(
            "the fitted dissipation is negative (energy created, dissipated power "
            f"{power.min():.3g} W at a sample): the data do not support this friction model; "
            "check the dissipation terms and the sign of the applied forces")
    step = max(1, len(X) // 400)
    H = np.einsum("sikp,p->sik", lib.d2theta_dqd2(X[::step]), rho)
    eig = np.linalg.eigvalsh(H)
    if eig[:, 0].min() < -1e-9 * max(np.abs(eig).max(), 1e-300):
        raise UndeterminedError(
            "the fitted viscous friction is not positive semidefinite (∂²R/∂q̇² has a negative "
            "eigenvalue): refused, it would create energy")
