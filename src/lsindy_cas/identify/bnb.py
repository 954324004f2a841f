"""Exact best subset by branch and bound: the best admissible k-support without enumerating C(p, k).

The supports containing the forced (prior) terms are the leaves of a tree over the free terms taken
in the library's order (low degrees first), or optionally a *screening order* (forward stepwise
first, :func:`screening_order`).  A node fixes the terms I it
has chosen and the position of the last one; its subtree holds every support I ∪ T with T drawn
from the terms after that position (the allowed set F).  Every support of a subtree is a subset of
U = forced ∪ I ∪ F, which gives a lower bound on its score valid for the whole subtree:

- driven (b ≠ 0): the relative residual of least squares on U — adding columns never increases a
  residual, so ``score(S) ≥ score(U)`` for S ⊂ U;
- passive (b = None): the smallest eigenvalue of the normalised Gram matrix Ĝ_U — by Cauchy
  interlacing λ_min(Ĝ_S) ≥ λ_min(Ĝ_U) for every principal submatrix.

The bounds of all children of a node come from one pass: after deflating I, a Cholesky sweep over
the allowed terms from the *last* one backwards gives the residual of every suffix (driven); for
passive data the smallest eigenvalue of a few nested suffixes bounds all children between them.

Nodes are expanded best-first (lowest bound; among bounds at round-off, deepest first and then the
lowest partial score, which makes the first descent the forward-stepwise model).  Leaves are scored
exactly as the exhaustive search scores them (:func:`lsindy_cas.identify.search._score_chunks`) and
visited best-first through the same rules (degenerate, reducible, then ``admissible``): a leaf
becomes the incumbent only when it passes them all.  A subtree is pruned when its bound is not below
the incumbent by more than ``tol`` (default ``SCORE_RESOLUTION``, the resolution of a Gram-based
score): no support in it can beat the incumbent by more than round-off.

Certificate: ``gap`` = incumbent − (smallest bound left unexplored or pruned), clipped at 0; the
search is *proven* when the tree was exhausted (then gap ≤ tol).  A time limit or Ctrl-C stops the
search with the best admissible support found so far and its gap, marked as not proven.
"""
from __future__ import annotations

import heapq
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .._validate import check_real
from .admissibility import NO_SCALE_REASON, REDUCIBLE_REASON, reducible
from .fitting import coef_on_support, normalise_columns
from .search import DEGENERACY_TOL, Candidate, SearchResult, _score_chunks

__all__ = ["branch_and_bound", "screening_order", "SCORE_RESOLUTION", "SKIP_TOL"]

# Scores are relative residuals (or eigenvalues of a unit-diagonal Gram matrix) in [0, 1] computed
# from Gram matrices: two of them closer than this are a round-off tie.
SCORE_RESOLUTION = 1e-12
# Pivots of a unit-diagonal Gram matrix below this are exact linear dependence (round-off of n·eps):
# such a column adds nothing to the span of a superset (its contribution is < 1e-18 of ‖b‖²).
SKIP_TOL = 1e-13
_POOL = 2000               # scored leaves kept as runners-up (best first)
_REPORT_EVERY = 0.25       # seconds between progress reports
_MAX_OPEN = 2_000_000      # open nodes kept (memory, ~0.5 GB): beyond, stop as not proven


@dataclass
class _Node:
    pos: tuple              # positions (in the screening order) of the chosen free terms
    bound: float            # lower bound on every score in the subtree
    partial: float          # score of forced ∪ chosen terms alone (ordering only)


class _Basis:
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
        basis = _Basis(G, c)
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


def _suffix_explained(Gd, cd, stop_at: float) -> np.ndarray:
    """Driven: explained ‖y‖² of every suffix of the columns of ``Gd`` (index i: columns i..n−1).

    A Cholesky sweep from the last column backwards; exactly dependent columns (pivot < SKIP_TOL)
    add nothing.  Stops once the explained part reaches ``stop_at`` or the span is exhausted; the
    suffixes not reached get NaN (or, when the span is exhausted, the final value).
    """
    n = len(cd)
    S, v = Gd.copy(), cd.copy()
    out = np.full(n, np.nan)
    E = 0.0
    for t in range(n - 1, -1, -1):
        d = S[t, t]
        if d > SKIP_TOL:
            sd = np.sqrt(d)
            yt = v[t] / sd
            E += yt * yt
            if t:
                l = S[:t, t] / sd
                S[:t, :t] -= np.outer(l, l)
                v[:t] -= l * yt
        out[t] = E
        if t and (E >= stop_at or np.diag(S)[:t].max() <= SKIP_TOL):
            if np.diag(S)[:t].max() <= SKIP_TOL:
                out[:t] = E
            break
    return out


class _Search:
    """State of one branch and bound (see the module notes)."""

    def __init__(self, A, b, k, forced, admissible, D, scale_system, tol, n_report, screen=True):
        self.A, self.b, self.k = A, b, k
        self.forced = [int(j) for j in forced]
        self.admissible, self.scale_system, self.tol = admissible, scale_system, tol
        self.n_report = n_report
        An, _ = normalise_columns(A)
        self.G = An.T @ An
        self.c = None if b is None else An.T @ b
        self.bb = None if b is None else float(b @ b)
        self.GD = None
        if b is None:
            Dn, _ = normalise_columns(D)
            self.GD = Dn.T @ Dn
        p = A.shape[1]
        free = [j for j in range(p) if j not in set(self.forced)]
        self.order = (screening_order(self.G, self.c, self.forced, free, k, self.GD) if screen
                      else np.array(free, dtype=np.int64))
        self.r = k - len(self.forced)
        self.incumbent, self.winner, self.null_dim = np.inf, None, 0
        self.candidates, self.n_reducible, self.n_examined = [], 0, 0
        self.pool_S, self.pool_s = [], []
        self.n_leaves = self.n_degenerate = self.nodes = 0
        self.lower_pruned = np.inf
        self.current = None

    # ----------------------------------------------------------------- bounds
    def _score(self, explained):
        return np.clip(1.0 - explained / self.bb, 0.0, 1.0) if self.bb > 0 else np.zeros_like(explained)

    def children(self, node: _Node):
        """(positions, bounds, partial scores) of a node's non-leaf children, or scores its leaves."""
        n, depth = len(self.order), len(node.pos)
        left = self.r - depth
        last = node.pos[-1] if node.pos else -1
        js = np.arange(last + 1, n - left + 1)
        U = self.forced + [int(self.order[j]) for j in node.pos]
        if left == 1:
            self.leaves(U, js)
            return None
        rest = self.order[last + 1:]
        if self.b is not None:
            basis = _Basis(self.G, self.c)
            for m in U:
                basis.add(m)
            Gd, cd = basis.deflated(rest)
            eI = float(basis.y @ basis.y)
            piv = np.diag(Gd)[:len(js)]
            partial = self._score(eI + cd[:len(js)] ** 2 / np.maximum(piv, 1e-300))
            stop = (1.0 - (self.incumbent - self.tol)) * self.bb if np.isfinite(self.incumbent) else np.inf
            E = _suffix_explained(Gd, cd, stop - eI)[:len(js)]
            bounds = np.where(np.isnan(E), node.bound, self._score(eI + np.nan_to_num(E)))
            ok = piv >= DEGENERACY_TOL
        else:
            bounds = np.full(len(js), node.bound)
            idx = np.hstack([np.broadcast_to(np.array(U, np.int64), (len(js), len(U))),
                             self.order[js][:, None]])
            partial = np.linalg.eigvalsh(self.G[idx[:, :, None], idx[:, None, :]])[:, 0]
            length, done = left, np.zeros(len(js), dtype=bool)
            while True:                       # nested suffixes of growing length bound the children
                idx = list(U) + [int(j) for j in rest[len(rest) - length:]]
                lam = np.linalg.eigvalsh(self.G[np.ix_(idx, idx)])[0]
                new = (np.arange(len(js)) + length >= len(rest)) & ~done   # child's suffix ⊂ this one
                bounds[new] = np.maximum(bounds[new], lam)
                done |= new
                if length >= len(rest):
                    break
                length = min(len(rest), 2 * length)
            ok = np.ones(len(js), dtype=bool)
        bounds = np.maximum(bounds, node.bound)       # a child's superset is inside the parent's
        return [(_Node(node.pos + (int(j),), float(bd), float(pa)))
                for j, bd, pa, o in zip(js, bounds, partial, ok) if o]

    # ----------------------------------------------------------------- leaves
    def leaves(self, U, js):
        """Score the supports U + order[j] and visit those that could beat the incumbent."""
        S = np.sort(np.hstack([np.broadcast_to(np.array(U, np.int64), (len(js), len(U))),
                               self.order[js][:, None]]), axis=1)
        scores, deg = np.empty(len(S)), np.empty(len(S), dtype=bool)
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            _score_chunks(self.G, self.GD, self.c, self.bb, S, scores, deg, None)
        self.n_leaves += len(S)
        self.n_degenerate += int(deg.sum())
        S, scores = S[~deg], scores[~deg]
        self.pool_S.append(S)
        self.pool_s.append(scores)
        if sum(len(s) for s in self.pool_s) > 50 * _POOL:
            self._trim_pool()
        order = np.argsort(scores, kind="stable")
        hopeful = order[scores[order] < self.incumbent - self.tol]
        if len(hopeful) < len(order):
            self.lower_pruned = min(self.lower_pruned, float(scores[order[len(hopeful)]]))
        if not len(hopeful):
            return
        red = reducible(self.G, self.c, S[hopeful])
        for idx, r in zip(hopeful, red):
            Sx = tuple(int(j) for j in S[idx])
            self.n_examined += 1
            if r:
                self.n_reducible += 1
                if self.n_reducible <= self.n_report:
                    self.candidates.append(Candidate(Sx, float(scores[idx]), False, REDUCIBLE_REASON))
                continue
            coef, nd = coef_on_support(self.A, self.b, Sx, self.scale_system)
            cand = Candidate(Sx, float(scores[idx]), coef=coef)
            if coef is None:
                cand.admissible, cand.reason = False, NO_SCALE_REASON
            elif self.admissible is None:
                cand.admissible = True
            else:
                cand.admissible, cand.reason = self.admissible(Sx, coef)
            self.candidates.append(cand)
            if cand.admissible:
                self.incumbent, self.winner, self.null_dim = cand.score, cand, nd
                return

    def _trim_pool(self):
        S, s = np.vstack(self.pool_S), np.concatenate(self.pool_s)
        keep = np.argsort(s, kind="stable")[:_POOL]
        self.pool_S, self.pool_s = [S[keep]], [s[keep]]

    # ----------------------------------------------------------------- search
    def run(self, time_limit, progress):
        t0 = time.monotonic()
        heap = [((0.0, 0, 0.0), 0, _Node((), 0.0, 1.0))]
        counter, interrupted, stopped, last_report = 1, False, False, t0
        try:
            while heap:
                node = heapq.heappop(heap)[2]
                if node.bound >= self.incumbent - self.tol:
                    self.lower_pruned = min(self.lower_pruned, node.bound)
                    continue
                self.current = node
                self.nodes += 1
                kids = self.children(node)
                self.current = None
                for ch in kids or ():
                    if ch.bound >= self.incumbent - self.tol:
                        self.lower_pruned = min(self.lower_pruned, ch.bound)
                        continue
                    key = (ch.bound if ch.bound > self.tol else 0.0, -len(ch.pos), ch.pos[-1],
                           ch.partial)
                    heapq.heappush(heap, (key, counter, ch))
                    counter += 1
                now = time.monotonic()
                if progress is not None and now - last_report > _REPORT_EVERY:
                    last_report = now
                    self._report(progress, heap, now - t0)
                if heap and (len(heap) > _MAX_OPEN or
                             (time_limit is not None and now - t0 > time_limit)):
                    stopped = True
                    break
        except KeyboardInterrupt:
            interrupted = True
        lower = min([self.lower_pruned] + [h[2].bound for h in heap]
                    + ([self.current.bound] if self.current is not None else []))
        seconds = time.monotonic() - t0
        if progress is not None:
            self._report(progress, heap, seconds)
        return lower, not (heap or interrupted or stopped or self.current is not None), seconds, interrupted

    def _report(self, progress, heap, elapsed):
        lower = min([self.lower_pruned] + [h[2].bound for h in heap])
        gap = max(0.0, self.incumbent - lower) if np.isfinite(self.incumbent) else float("inf")
        progress(self.nodes, 0)
        status = getattr(progress, "status", None)
        if status is not None:
            status(f"gap {gap:.2e}, best {self.incumbent:.3e}, {elapsed:.1f} s")


def branch_and_bound(A: np.ndarray, b: np.ndarray | None, k: int, forced=(), *,
                     admissible: Callable | None = None, D: np.ndarray | None = None,
                     scale_system: tuple | None = None, time_limit: float | None = None,
                     tol: float = SCORE_RESOLUTION, n_report: int = 10,
                     progress: Callable | None = None, screen: bool = False) -> SearchResult:
    """Best admissible k-term support of ``A ξ ≈ b`` (or of a null vector) by branch and bound.

    Same inputs and result as :func:`lsindy_cas.identify.search.best_subset`, plus a certificate
    (``method="bnb"``, ``proven``, ``gap``, ``nodes``, ``seconds``, ``interrupted``).

    Parameters
    ----------
    A, b, k, forced, admissible, D, scale_system, n_report
        As for :func:`~lsindy_cas.identify.search.best_subset` (``D`` required when ``b`` is None).
    time_limit : float, optional
        Seconds after which the best admissible support found so far is returned, not proven.
    tol : float
        Prune a subtree whose bound is within ``tol`` of the incumbent (score units, ≥ 0).
    progress : callable ``(n_done, n_total)``, optional
        Called with (nodes expanded, 0) a few times a second; its ``status(text)`` method, if it has
        one, receives the current gap, best score and elapsed time.
    screen : bool
        Order the free terms by :func:`screening_order` instead of the library's order (default;
        a polynomial library lists low degrees first).  The answer is the same; measured on the
        paper's clean 1 s runs without priors the library order is faster: spherical k = 3, 16
        nodes / 1.1 s against 416 / 5.9 s; cart k = 4, proven in 499 nodes / 8.3 s against nothing
        admissible found in 15 s (benchmarks/bench_bnb.py).

    Returns
    -------
    SearchResult
        ``supports``/``scores`` hold the best scored leaves (at most 2000), not every support.
    """
    m, p = A.shape
    forced = sorted(set(int(j) for j in forced))
    k = int(k)
    if not 1 <= k <= p:
        raise ValueError(f"n_terms must be between 1 and the library size {p}, got {k}")
    if len(forced) > k:
        raise ValueError(f"{len(forced)} prior terms do not fit in n_terms = {k}")
    time_limit = check_real("time_limit", time_limit, positive=True, allow_none=True)
    tol = check_real("tol", tol, nonnegative=True)
    if b is None and D is None:
        raise ValueError("the passive score needs the gradient matrix D to tell conserved "
                         "quantities from identities")
    if k == len(forced):
        from .search import best_subset
        return best_subset(A, b, k, forced, admissible=admissible, D=D, scale_system=scale_system,
                           n_report=n_report)
    s = _Search(A, b, k, forced, admissible, D, scale_system, tol, n_report, screen)
    lower, proven, seconds, interrupted = s.run(time_limit, progress)
    if s.winner is None and interrupted:
        raise KeyboardInterrupt            # nothing to return: let the caller stop
    if s.winner is None:
        why = "; ".join(sorted({c.reason for c in s.candidates if c.reason}))
        raise ValueError(f"no physically admissible {k}-term model "
                         + ("among all supports" if proven else f"found in {seconds:.1f} s")
                         + (f" (reasons: {why})" if why else ""))
    s._trim_pool()
    sup, sc = s.pool_S[0], s.pool_s[0]
    w = s.winner
    seen = {c.support for c in s.candidates}
    runners = [Candidate(tuple(int(j) for j in S), float(v)) for S, v in zip(sup, sc)
               if tuple(int(j) for j in S) not in seen][:n_report]
    cands = sorted(s.candidates, key=lambda c: c.score) + runners
    res = SearchResult(w.support, w.coef, w.score, cands, s.n_leaves, s.n_degenerate, s.null_dim,
                       sc, sup, s.n_reducible)
    res.method, res.proven, res.interrupted = "bnb", proven, interrupted
    res.gap = max(0.0, w.score - lower)
    res.nodes, res.seconds = s.nodes, seconds
    return res
