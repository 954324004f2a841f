"""What the branch and bound knows before it searches: the screening order and the structure.

- :func:`screening_order` — the free terms, likely ones first (forward stepwise, then by one-term
  score), one of the two orders :func:`lsindy_cas.identify.bnb.branch_and_bound` searches;
- :func:`structure_of` — what an :class:`~lsindy_cas.identify.admissibility.Admissibility` rules
  out before any fit (terms no energy has; a term needed per coordinate for a positive-definite
  kinetic part), exact consequences of its rules, so pruning with them loses no admissible support.
"""
from __future__ import annotations

import numpy as np

from .search import DEGENERACY_TOL

__all__ = ["screening_order", "structure_of", "l1_order"]


def structure_of(admissible, p: int):
    """What an :class:`~lsindy_cas.identify.admissibility.Admissibility` rules out before any fit.

    Returns ``(banned, required)`` or None when ``admissible`` is not such an object: ``banned``
    the terms no admissible support contains (excluded terms, terms linear in the velocities),
    ``required`` index arrays of terms a support must meet: first, per coordinate i, the terms
    with ∂²θ_j/∂q̇_i² ≠ 0 at some checked state; then, per checked state s and coordinate i, the
    terms with ∂²θ_j/∂q̇_i² ≠ 0 *at s* (only the minimal such sets, e.g. at a state at rest only
    the q̇_i²·f(q) terms) — a support missing one has M_ii(s) = 0, so its kinetic part is not
    positive definite at s and the rule rejects it.  Both are exact consequences of the rules, so
    pruning with them loses no admissible support.
    """
    lib, hess = getattr(admissible, "library", None), getattr(admissible, "hess", None)
    if lib is None or hess is None or len(lib) != p:
        return None
    from ..mechanics.legendre import velocity_linear
    banned = set(int(j) for j in getattr(admissible, "excluded", ())) | set(velocity_linear(lib, range(p)))
    n = hess.shape[1]
    required = [np.flatnonzero(np.any(hess[:, i, i, :] != 0, axis=0)) for i in range(n)]
    return sorted(banned), required + _state_sets(hess, banned, required)


def _state_sets(hess, banned, coordinate_sets) -> list:
    """The minimal sets {j : ∂²θ_j/∂q̇_i²(x_s) ≠ 0} over states s and coordinates i (banned terms
    left out: no admissible support has them), without the per-coordinate sets already listed."""
    sets = set()
    keep = np.ones(hess.shape[-1], dtype=bool)
    keep[list(banned)] = False
    for i in range(hess.shape[1]):
        nz = (hess[:, i, i, :] != 0) & keep
        sets |= {frozenset(np.flatnonzero(row).tolist()) for row in np.unique(nz, axis=0)}
    known = {frozenset((set(r.tolist()) - set(banned))) for r in coordinate_sets}
    minimal = [a for a in sets if not any(b < a for b in sets)]
    return [np.array(sorted(a), dtype=np.int64) for a in sorted(minimal, key=len) if a not in known]


class Basis:
    """Rows R = L⁻¹ Ĝ[U, :] and y = L⁻¹ ĉ_U of a Cholesky factor over the terms U, grown by one."""

    def __init__(self, G, c):
        self.G, self.c = G, c
        self.R = np.zeros((0, G.shape[0]))
        self.y = np.zeros(0)

    def add(self, m: int) -> float:
        l = self.R[:, m]
        piv = self.G[m, m] - l @ l
        s = np.sqrt(max(piv, 1e-300))
        self.R = np.vstack([self.R, (self.G[m] - l @ self.R) / s])
        if self.c is not None:
            self.y = np.append(self.y, (self.c[m] - l @ self.y) / s)
        return piv

    def deflated(self, cols):
        """Gram matrix and right side of ``cols`` with the span of U projected out."""
        Rc = self.R[:, cols]
        Gd = self.G[np.ix_(cols, cols)] - Rc.T @ Rc
        cd = None if self.c is None else self.c[cols] - Rc.T @ self.y
        return Gd, cd


def screening_order(G: np.ndarray, c: np.ndarray | None, forced, free, k: int,
                    GD: np.ndarray | None = None) -> np.ndarray:
    """The free terms, likely ones first: a forward-stepwise pass, then the rest by one-term score.

    Driven: each step adds the term that explains most of what forced ∪ chosen leave unexplained
    (skipping terms dependent on them); passive: the term that lowers the smallest eigenvalue of
    the chosen terms' Gram matrix most (starting from the most correlated pair).  The stepwise pass
    runs for max(2k, 8) terms; the others follow by their one-term score given the forced terms.
    """
    free = [int(j) for j in free]
    n_steps = min(len(free), max(2 * k, 8))
    chosen: list = []
    if c is not None:
        basis = Basis(G, c)
        for f in forced:
            basis.add(int(f))
        Gd, cd = basis.deflated(free)
        single = cd ** 2 / np.maximum(np.diag(Gd), 1e-300)
        single[np.diag(Gd) < DEGENERACY_TOL] = -1.0
        for _ in range(n_steps):
            Gd, cd = basis.deflated(free)
            piv = np.diag(Gd)
            gain = np.where(piv < DEGENERACY_TOL, -1.0, cd ** 2 / np.maximum(piv, 1e-300))
            gain[[free.index(j) for j in chosen]] = -np.inf
            j = free[int(np.argmax(gain))]
            if gain.max() < 0:
                break
            chosen.append(j)
            basis.add(j)
    else:
        base = [int(f) for f in forced]
        single = np.zeros(len(free))
        Gdep = G if GD is None else GD
        for _ in range(n_steps):
            best, best_j = np.inf, None
            for j in free:
                if j in chosen:
                    continue
                U = base + chosen + [j]
                if len(U) < 2:
                    # first term: the one most correlated with another free term (not an identity)
                    r = np.abs(G[j, free]) * (1 - Gdep[j, free] ** 2 >= DEGENERACY_TOL)
                    r[free.index(j)] = 0
                    val = 1 - r.max()
                else:
                    if np.linalg.eigvalsh(Gdep[np.ix_(U, U)])[0] < DEGENERACY_TOL:
                        continue
                    val = np.linalg.eigvalsh(G[np.ix_(U, U)])[0]
                if val < best:
                    best, best_j = val, j
            if best_j is None:
                break
            chosen.append(best_j)
        single = -np.abs(G[np.ix_(free, free)] - np.eye(len(free))).max(axis=1)
    rest = [free[i] for i in np.argsort(-single, kind="stable") if free[i] not in chosen]
    return np.array(chosen + rest, dtype=np.int64)


def l1_order(A: np.ndarray, b: np.ndarray | None, free, forced=(),
             rtol: float = 1e-10, max_terms: int | None = None) -> np.ndarray | None:
    """The free terms by the size of their coefficient in the least-ℓ1 exact fit (basis pursuit).

    On the column-normalised columns M = U S Vᵀ of the forced and free terms (directions with
    s > ``rtol``·s_max kept, so the system is consistent), x = argmin Σ_free |x_j| subject to
    S Vᵀ x = Uᵀ b (forced terms free of charge), a linear programme: on clean data with enough rows
    it recovers a sparse exact fit even when the terms are strongly correlated (where forward
    stepwise picks what fits best alone); on noisy data it is the least-ℓ1 least-squares fit.
    Returns the free terms, largest |x_j| first, or None for passive data or when the programme
    fails (the caller keeps its other orders).  With ``max_terms``, also None when the system is
    underdetermined (fewer kept directions than terms) and x has more than ``max_terms`` non-zero
    free coefficients: basis pursuit found no sparse fit, the LP's vertex has as many terms as
    directions and the order of the other terms (all zero) is the library's — on the paper's
    short runs this order only moves some thirty wrong terms ahead of the library order.
    """
    free = np.asarray(free, dtype=np.int64)
    if b is None or not len(free):
        return None
    from scipy.optimize import linprog        # lazy: scipy.optimize is slow to import
    cols = np.concatenate([np.asarray(forced, dtype=np.int64), free])
    M = A[:, cols]
    M = M / np.maximum(np.linalg.norm(M, axis=0), 1e-300)
    U, s, Vt = np.linalg.svd(M, full_matrices=False)
    r = int(np.sum(s > rtol * s[0])) if len(s) and s[0] > 0 else 0
    if r == 0:
        return None
    Ar = s[:r, None] * Vt[:r]
    y = U[:, :r].T @ (b / max(np.linalg.norm(b), 1e-300))
    n = len(cols)
    cost = np.ones(n)
    cost[:n - len(free)] = 0.0
    res = linprog(np.concatenate([cost, cost]), A_eq=np.hstack([Ar, -Ar]), b_eq=y,
                  bounds=(0, None), method="highs")
    if res.status != 0 or res.x is None:
        return None
    x = np.abs(res.x[:n] - res.x[n:])[n - len(free):]
    if max_terms is not None and r < n and np.sum(x > 1e-12 * max(x.max(), 1e-300)) > max_terms:
        return None
    return free[np.argsort(-x, kind="stable")]
