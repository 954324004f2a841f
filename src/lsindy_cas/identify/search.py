"""Best-subset search over k-term supports, batched over subsets, with forced prior terms.

Every support S (|S| = k, containing the forced prior terms) is scored from the normalised Gram
matrix Ĝ = Âᵀ Â of the column-scaled design matrix Â, so no least-squares problem is solved per
subset: the scores of all supports come from one batched k×k Cholesky factorisation.

- driven systems (b ≠ 0, paper eqs. 4–5): relative residual 1 − ‖L_S⁻¹ ĉ_S‖² / ‖b‖², with
  Ĝ_S = L_S L_Sᵀ and ĉ = Âᵀ b — scale-free, in [0, 1];
- passive systems (b = 0): the smallest eigenvalue of Ĝ_S, i.e. the squared smallest singular
  value of the column-normalised Â_S — how nearly the support conserves something.

Supports whose terms are linearly dependent *as functions* (trig identities such as
sin² + cos² = 1 make many) are recognised from the Cholesky pivots of the Gram matrix of the state
gradients ∇Θ and skipped: such a support is a smaller support in disguise and its coefficients are
not unique.  Candidates are then visited best-first and the first one the ``admissible`` callback
accepts (e.g. prior terms present, kinetic energy positive definite) wins.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from math import comb
from typing import Callable

import numpy as np

from .admissibility import NO_SCALE_REASON, REDUCIBLE_REASON, clearly_not_pd, reducible
from .findings import UndeterminedError
from .fitting import coef_on_support, column_norms, normal_equations, normalise_columns
from .subset_tree import combinations, subtree_scores, subtree_supports, tree_scores

__all__ = ["combinations", "Candidate", "SearchResult", "Visit", "best_subset", "visit", "score_all",
           "score_supports", "DEGENERACY_TOL", "NoAdmissibleModel"]

# Pivots of a unit-diagonal Gram matrix are 1 − R² of each column against the previous ones.
# Exact identities give ~1e-15 (round-off); genuinely distinct smooth terms on 100+ samples give
# > 1e-8.  1e-10 separates the two with margin.
DEGENERACY_TOL = 1e-10
_CHUNK = 200_000


def _cholesky_batched(G: np.ndarray):
    """Cholesky of a stack (B, k, k) of symmetric matrices; returns L and the pivots (B, k).

    Non-positive pivots (rank-deficient supports) are clamped so nothing raises; callers mask
    them out using the pivots.
    """
    B, k, _ = G.shape
    L = np.zeros_like(G)
    piv = np.empty((B, k))
    for j in range(k):
        d = G[:, j, j] - np.einsum("bi,bi->b", L[:, j, :j], L[:, j, :j])
        piv[:, j] = d
        ljj = np.sqrt(np.maximum(d, 1e-300))
        L[:, j, j] = ljj
        if j + 1 < k:
            L[:, j + 1:, j] = (G[:, j + 1:, j] - np.einsum("bri,bi->br", L[:, j + 1:, :j],
                                                           L[:, j, :j])) / ljj[:, None]
    return L, piv


def _forward(L: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Solve L y = c for a stack of lower-triangular L (B, k, k), c (B, k)."""
    y = np.empty_like(c)
    for j in range(c.shape[1]):
        y[:, j] = (c[:, j] - np.einsum("bi,bi->b", L[:, j, :j], y[:, :j])) / L[:, j, j]
    return y


class NoAdmissibleModel(UndeterminedError):
    """A search found no physically admissible model of ``k`` terms: a verdict on the data
    (with this library and these options), so ``lsindy identify`` exits 3 on it, not 2.

    ``proven``: every support was ruled out (none exists); otherwise the search stopped first
    (``seconds``, ``work``: what it spent) and the question is open.
    """

    def __init__(self, message: str, k: int, proven: bool, seconds: float = 0.0, work: float = 0.0):
        super().__init__(message)
        self.k, self.proven, self.seconds, self.work = int(k), bool(proven), float(seconds), work


@dataclass
class Candidate:
    """One scored support, as listed in the diagnostics."""

    support: tuple
    score: float
    admissible: bool | None = None
    reason: str = ""
    coef: np.ndarray | None = field(default=None, repr=False)


@dataclass
class SearchResult:
    """Outcome of a best-subset search.

    Attributes
    ----------
    support : tuple of int
        Indices of the selected terms (sorted).
    coef : array (p,)
        Coefficients in the units of the data (zeros off the support).
    score : float
        Scale-free score of the support (relative residual, or smallest normalised eigenvalue).
    candidates : list of Candidate
        The supports visited, best first, with why each was accepted or rejected.
    n_supports : int
        How many supports were scored; ``n_degenerate`` of them were linearly dependent.
    null_dim : int
        Passive scheme: dimension of the (near) null space on the chosen support.
    scores, supports : arrays (n_supports,), (n_supports, k)
        Every scored support and its score.
    n_reducible : int
        Better-scoring supports skipped because a coefficient vanished (smaller model in disguise).
    method : {"exhaustive", "bnb"}
        How the supports were searched (:mod:`lsindy_cas.identify.bnb` for branch and bound).
    proven : bool
        Whether the support is certified best admissible (always for the exhaustive search; for
        branch and bound when the tree was exhausted, not after a time limit or Ctrl-C).
    gap : float
        Winner's score minus the smallest lower bound left unexplored (0 when exhaustive).
    nodes : int
        Branch and bound: nodes expanded.
    seconds : float
        Branch and bound: time of the search.
    work : float
        Branch and bound: work spent (:mod:`~lsindy_cas.identify.bnb_drive` units).
    interrupted : bool
        Branch and bound: stopped by Ctrl-C.
    """

    support: tuple
    coef: np.ndarray
    score: float
    candidates: list
    n_supports: int
    n_degenerate: int
    null_dim: int = 0
    scores: np.ndarray | None = field(default=None, repr=False)
    supports: np.ndarray | None = field(default=None, repr=False)
    n_reducible: int = 0
    method: str = "exhaustive"
    proven: bool = True
    gap: float = 0.0
    nodes: int = 0
    seconds: float = 0.0
    work: float = 0.0
    interrupted: bool = False


def _gather(G: np.ndarray, S: np.ndarray) -> np.ndarray:
    return G[S[:, :, None], S[:, None, :]]


def score_supports(A: np.ndarray, b: np.ndarray | None, supports: np.ndarray,
                   D: np.ndarray | None = None, progress: Callable | None = None):
    """Scores (n_supports,) and degeneracy mask for every support, batched.

    Parameters
    ----------
    A : array (m, p)
        Design matrix (e.g. Γ).
    b : array (m,) or None
        Right-hand side (dE/dt); ``None`` for the passive (null-space) score.
    supports : int array (n_supports, k)
    D : array (m', p), optional
        Matrix whose column dependence marks a support as degenerate (default ``A``).
    progress : callable ``(n_done, n_total)``, optional
        Called after each batch of supports (for progress bars).
    """
    if b is None and D is None:
        raise ValueError("the passive score needs the gradient matrix D to tell conserved "
                         "quantities from identities")
    An, _ = normalise_columns(A)
    G = An.T @ An
    if D is not None:
        Dn, _ = normalise_columns(D)
        GD = Dn.T @ Dn
    c = None if b is None else An.T @ b
    bb = None if b is None else float(b @ b)
    scores = np.empty(len(supports))
    degenerate = np.empty(len(supports), dtype=bool)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        score_chunks(G, GD if D is not None else None, c, bb, supports, scores, degenerate, progress)
    return scores, degenerate


def score_chunks(G, GD, c, bb, supports, scores, degenerate, progress):
    for lo in range(0, len(supports), _CHUNK):
        S = supports[lo:lo + _CHUNK]
        GS = _gather(G, S)
        deg = np.zeros(len(S), dtype=bool)
        if GD is not None:
            deg |= _cholesky_batched(_gather(GD, S))[1].min(axis=1) < DEGENERACY_TOL
        if c is None:
            sc = np.linalg.eigvalsh(GS)[:, 0]
        else:
            L, piv = _cholesky_batched(GS)
            deg |= piv.min(axis=1) < DEGENERACY_TOL
            y = _forward(L, c[S])
            sc = 1.0 - np.einsum("bi,bi->b", y, y) / bb if bb > 0 else np.zeros(len(S))
        scores[lo:lo + _CHUNK] = np.maximum(sc, 0.0)
        degenerate[lo:lo + _CHUNK] = deg
        if progress is not None:
            progress(min(lo + _CHUNK, len(supports)), len(supports))


def best_subset(A: np.ndarray, b: np.ndarray | None, k: int, forced=(), *,
                admissible: Callable | None = None, D: np.ndarray | None = None,
                scale_system: tuple | None = None, max_visits: int = 20_000,
                n_report: int = 10, progress: Callable | None = None,
                structure: tuple | None = None, kinetic: np.ndarray | None = None,
                backend=None) -> SearchResult:
    """Best k-term support of ``A ξ ≈ b`` (or of a null vector of ``A`` when ``b`` is None).

    Parameters
    ----------
    A : array (m, p)
    b : array (m,) or None
        ``None`` selects the passive scheme: ξ spans the near null space of ``A_S`` and is scaled
        by ``scale_system`` (paper eq. 8).
    k : int
        Number of terms.
    forced : sequence of int
        Terms every support must contain (prior knowledge).
    admissible : callable ``(support, coef) -> (bool, reason)``, optional
        Physical admissibility test; the best-scoring admissible support wins.
    D : array, optional
        Gradient matrix for degeneracy detection (see ``score_supports``).
    scale_system : (A_s, b_s), optional
        Passive scheme: a short actuated record with A_s ξ = b_s that fixes scale (and, when the
        null space on the support has dimension > 1, the combination).
    max_visits : int
        How many of the best supports may be examined for admissibility before giving up.
    progress : callable ``(n_done, n_total)``, optional
        Progress callback for the scoring pass.
    structure : (banned, required), optional
        What the admissibility rules rule out before any fit (:func:`visit`).
    kinetic : array (s, n, n, p), optional
        Driven data: ∂²θ/∂q̇∂q̇ at some sample states, for the batched kinetic rule (:func:`visit`).
    backend : object, optional
        Where the supports are scored (its ``score_all``; e.g.
        :class:`~lsindy_cas.identify.distributed.DaskBackend`); None: in this process.
    """
    m, p = A.shape
    forced = sorted(set(int(j) for j in forced))
    if not 1 <= k <= p:
        raise ValueError(f"n_terms must be between 1 and the library size {p}, got {k}")
    if len(forced) > k:
        raise ValueError(f"{len(forced)} prior terms do not fit in n_terms = {k}")
    scorer = score_all if backend is None else backend.score_all
    supports, scores, degenerate = scorer(A, b, k, forced, D, progress)
    v = visit(A, b, supports, scores, degenerate, admissible=admissible, scale_system=scale_system,
              max_visits=max_visits, n_report=n_report, structure=structure, kinetic=kinetic)
    if v.winner is None:
        ruled = (f" (and {v.n_ruled:,} more that the rules exclude before any fit)"
                 if v.n_ruled else "")
        every = v.n_examined + v.n_ruled >= int(np.isfinite(np.where(degenerate, np.inf, scores)).sum())
        raise NoAdmissibleModel(
            f"no physically admissible {k}-term model among the {v.n_examined} best "
            f"supports{ruled}; try another n_terms, prior or library (reasons: "
            + "; ".join(sorted({c.reason for c in v.candidates if c.reason})) + ")", k, every)
    return v.result(supports, scores, degenerate)


@dataclass
class Visit:
    """Outcome of :func:`visit`: the winner (None if nothing passed) and what was seen."""

    winner: Candidate | None
    null_dim: int
    candidates: list
    n_examined: int
    n_reducible: int
    n_ruled: int = 0          # supports the structure rules out before any fit (not visited)

    def result(self, supports, scores, degenerate) -> SearchResult:
        w = self.winner
        return SearchResult(w.support, w.coef, w.score, self.candidates, len(supports),
                            int(degenerate.sum()), self.null_dim, scores, supports, self.n_reducible)


def structurally_inadmissible(structure: tuple, S: np.ndarray) -> np.ndarray:
    """Which supports (rows of ``S``) the rules reject before any fit: a banned term, or no term
    of one of the required sets (``structure = (banned, required)``,
    :func:`~lsindy_cas.identify.screening.structure_of`)."""
    banned, required = structure
    S = np.asarray(S, dtype=np.int64)
    p = 1 + max([int(S.max()) if S.size else 0] + [int(j) for j in banned]
                + [int(np.max(r)) for r in required if len(r)])
    out = np.zeros(len(S), dtype=bool)
    for lo in range(0, len(required) + (not required), 63):   # 63 sets per bit mask; bit 63: banned
        mask = np.zeros(p, dtype=np.uint64)
        sets = required[lo:lo + 63]
        for i, r in enumerate(sets):
            mask[np.asarray(r, dtype=np.int64)] |= np.uint64(1 << i)
        mask[list(banned)] |= np.uint64(1 << 63)
        met = np.bitwise_or.reduce(mask[S], axis=1) if S.size else np.zeros(0, np.uint64)
        want = np.uint64((1 << len(sets)) - 1)
        out |= ((met & want) != want) | ((met >> np.uint64(63)) != 0)
    return out


def visit(A: np.ndarray, b: np.ndarray | None, supports: np.ndarray, scores: np.ndarray,
          degenerate: np.ndarray, *, admissible: Callable | None = None,
          scale_system: tuple | None = None, max_visits: int = 20_000, n_report: int = 10,
          structure: tuple | None = None, kinetic: np.ndarray | None = None) -> Visit:
    """Visit the scored supports best-first; the first one that passes every rule wins.

    Shared by the exhaustive search and the beam of :mod:`lsindy_cas.identify.selection`.  Per
    block of candidates the reducible ones are rejected batched
    (:func:`lsindy_cas.identify.admissibility.reducible`); each other one is fitted
    (:func:`lsindy_cas.identify.fitting.coef_on_support`) and judged by ``admissible``.  At most
    ``max_visits`` supports are fitted; ``n_report`` reducible ones and ``n_report`` runners-up
    are kept for the diagnostics.  With ``structure`` (``(banned, required)`` of
    :func:`~lsindy_cas.identify.screening.structure_of`, in the columns of ``A``) the supports
    that the rules reject before any fit (a banned term, or no term of a required set) are not
    visited, except the ``n_report`` best-scoring of them (fitted and judged as before, so the
    diagnostics keep their reasons): the rules are exact, so the winner is the same, found with
    fewer fits — or found at all, where inadmissible ones used to exhaust ``max_visits``.
    With ``kinetic`` (driven data: ∂²θ/∂q̇∂q̇ at some sample states, shape (s, n, n, p), in the
    columns of ``A``) the supports of a block whose fit is clearly not positive definite
    (:func:`~lsindy_cas.identify.admissibility.clearly_not_pd`, batched) count as visited but
    are not fitted one by one, again except the first ``n_report`` of them: same winner, same
    stopping point, fewer fits.
    """
    keys = np.where(degenerate, np.inf, scores)
    n_ruled = 0
    if structure is not None:          # ruled out before any fit: never visited (docstring)
        ruled = np.flatnonzero(~degenerate & structurally_inadmissible(structure, supports))
        if len(ruled) > n_report:      # but the best n_report of them, for their reasons
            best = np.argpartition(keys[ruled], n_report)[:n_report]
            keys[np.delete(ruled, best)] = np.inf
            n_ruled = len(ruled) - n_report
    n_ok = int(np.isfinite(keys).sum())
    order = _best_first(keys, min(n_ok, 8192))
    G, c = normal_equations(A, b)
    candidates, winner, null_dim, n_visited, n_reducible, pos = [], None, 0, 0, 0, 0
    n_pre, scales = 0, None
    if kinetic is not None and c is not None:
        scales = column_norms(A)
        scales = np.where(scales > 0, scales, 1.0)
    while pos < n_ok and n_visited < max_visits and winner is None:
        if pos + 256 > len(order) and len(order) < n_ok:
            order = _best_first(keys, min(n_ok, 4 * len(order)))
        block = order[pos:pos + 256]
        # cheap batched rejection: a k-term fit whose own coefficients say "fewer terms"; only
        # the first n_report of those and the others are looked at one by one, in order
        red = reducible(G, c, supports[block])
        n_red = np.cumsum(red)
        pre = np.zeros(len(block), dtype=bool)      # clearly not positive definite (docstring)
        if scales is not None and not red.all():
            live = np.flatnonzero(~red)
            pre[live] = clearly_not_pd(kinetic, G, c, scales, supports[block[live]])
            marked = np.flatnonzero(pre)
            pre[marked[:max(0, n_report - n_pre)]] = False
            n_pre += len(marked)
        look = np.union1d(np.flatnonzero(red)[:max(0, n_report - n_reducible)],
                          np.flatnonzero(~red))
        base, start = n_reducible, pos
        pos, n_reducible = start + len(block), base + int(n_red[-1])
        for j in look:
            idx = block[j]
            S = tuple(supports[idx].tolist())
            if red[j]:
                candidates.append(Candidate(S, float(scores[idx]), False, REDUCIBLE_REASON))
                continue
            n_visited += 1
            if pre[j]:
                continue
            coef, nd = coef_on_support(A, b, S, scale_system)
            cand = Candidate(S, float(scores[idx]), coef=coef)
            if coef is None:
                cand.admissible, cand.reason = False, NO_SCALE_REASON
            elif admissible is None:
                cand.admissible = True
            else:
                cand.admissible, cand.reason = admissible(S, coef)
            candidates.append(cand)
            if cand.admissible:
                winner, null_dim = cand, nd
                pos, n_reducible = start + j + 1, base + int(n_red[j])
                break
    # a few runners-up for the diagnostics
    if pos + n_report > len(order):
        order = _best_first(keys, min(n_ok, pos + n_report))
    for idx in order[pos:pos + n_report]:
        candidates.append(Candidate(tuple(int(j) for j in supports[idx]), float(scores[idx])))
    return Visit(winner, null_dim, candidates, pos, n_reducible, n_ruled)


def score_all(A: np.ndarray, b: np.ndarray | None, k: int, forced=(), D: np.ndarray | None = None,
              progress: Callable | None = None):
    """Enumerate and score every k-support containing ``forced``.

    Driven data use the prefix-sharing Cholesky tree (:mod:`lsindy_cas.identify.subset_tree`); passive data
    the batched smallest eigenvalue (:func:`score_supports`).

    Returns
    -------
    supports : int array (n, k); scores : array (n,); degenerate : bool array (n,)
    """
    p = A.shape[1]
    forced = sorted(set(int(j) for j in forced))
    free = np.array([j for j in range(p) if j not in set(forced)], dtype=np.int64)
    if b is not None:
        An, _ = normalise_columns(A)
        G, c, bb = An.T @ An, An.T @ b, float(b @ b)
        if k == len(forced) or not forced:
            # one tree over every support (no per-subtree overhead).  Without forced terms the
            # first level appends free[i] exactly as a subtree's root does (same formulas, no
            # earlier rows), so the numbers are those of the Dask workers' subtrees bit for bit
            # (tests/test_distributed.py)
            supports, scores, pivots = tree_scores(G, c, bb, forced, free, k, progress)
            return supports, scores, pivots < DEGENERACY_TOL
        # subtree by subtree (supports whose smallest free column is free[i]), as the Dask
        # workers do (identify/distributed.py): the same numbers bit for bit in both
        supports = subtree_supports(forced, free, k)
        scores, pivots, done = [], [], 0
        for i in range(len(free)):
            sc, pv = subtree_scores(G, c, bb, forced, free, k, [i])
            scores.append(sc)
            pivots.append(pv)
            done += len(sc)
            if progress is not None and len(sc):
                progress(done, len(supports))
        return supports, np.concatenate(scores), np.concatenate(pivots) < DEGENERACY_TOL
    supports = subtree_supports(forced, free, k)
    scores, degenerate = score_supports(A, b, supports, D, progress)
    return supports, scores, degenerate


def _best_first(keys: np.ndarray, n: int) -> np.ndarray:
    """Indices of the ``n`` smallest keys in ascending order (ties by index), without a full sort."""
    n = min(n, len(keys))
    if n < len(keys) // 4:
        top = np.argpartition(keys, n)[:n + 1] if n < len(keys) else np.arange(len(keys))
        top = top[np.lexsort((top, keys[top]))]
        return top[:n]
    return np.argsort(keys, kind="stable")[:n]


def n_supports(p: int, k: int, n_forced: int = 0) -> int:
    """Number of k-term supports containing ``n_forced`` given terms out of ``p``."""
    return comb(p - n_forced, k - n_forced)
