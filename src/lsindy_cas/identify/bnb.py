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
lowest partial score, which makes the first descent the forward-stepwise model).  A node with two
terms left (rank-deficient data) scores the leaves of all its children in one batch, exactly as
the exhaustive search does (:func:`.search.score_chunks`).  Leaves are visited through the same rules
(degenerate, reducible, then ``admissible``): a leaf becomes the incumbent only when it passes them
all; with more rows than terms every hopeful leaf is examined as scored, with fewer (rank-deficient
data, every bound 0 until deep, ~1 ms per examination) only a batch's best one when it beats every
leaf examined so far, the others queued.  A subtree is pruned when its bound is not below the
incumbent by more than ``tol`` (default ``SCORE_RESOLUTION``, the resolution of a Gram-based
score): none of its supports beats the incumbent beyond round-off.

Before any bound, the admissibility rules prune exactly (:func:`structure_of`): terms no energy has
are left out, and a subtree whose terms miss every term with ∂²θ/∂q̇_i² ≠ 0 for some coordinate i
(no positive-definite kinetic part) is dropped.  By default the trees in the library order, the
basis-pursuit order (when it finds a sparse fit) and the screening order are searched in turn,
sharing the incumbent (the first exhausted proves it).  Candidates are fitted on the factor R of
A = QR (p rows instead of m); the winner is refitted on A, as the exhaustive search fits it.

Certificate: ``gap`` = incumbent − (smallest bound left unexplored or pruned), clipped at 0; the
search is *proven* when the tree was exhausted (then gap ≤ tol).  A time limit or Ctrl-C stops the
search with the best admissible support found so far and its gap, marked as not proven.
"""
from __future__ import annotations

import copy
import heapq
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .admissibility import NO_SCALE_REASON, REDUCIBLE_REASON, reducible
from .fitting import coef_on_support, normalise_columns
from .bnb_drive import (EXAMINE_COST, RUNNERS_UP, BnbState, check_inputs,  # noqa: F401
                        drive_and_conclude)
from .bnb_leaves import SKIP_TOL, pair_positions, passive_bounds, trim_queue
from .bnb_leaves import suffix_explained as _suffix_explained
from .screening import Basis, l1_order, screening_order, structure_of
from .search import DEGENERACY_TOL, Candidate, SearchResult, score_chunks

__all__ = ["branch_and_bound", "BnbState", "screening_order", "structure_of", "SCORE_RESOLUTION", "SKIP_TOL"]

# Scores are relative residuals (or eigenvalues of a unit-diagonal Gram matrix) in [0, 1] computed
# from Gram matrices: two of them closer than this are a round-off tie.
SCORE_RESOLUTION = 1e-12
_MAX_OPEN = 2_000_000      # open nodes kept (memory, ~0.5 GB): beyond, stop as not proven
_MAX_QUEUED = 4_000_000    # leaves queued (~0.25 GB); beyond, the worse half dropped (not proven)
_EAGER = 1                 # hopeful leaves of a batch examined at once (the rest queued)
_LIBRARY_SLICES = 4        # library-tree slices per screening slice when BP finds no sparse fit


@dataclass
class _Node:
    pos: tuple              # positions (in the screening order) of the chosen free terms
    bound: float            # lower bound on every score in the subtree
    partial: float          # score of forced ∪ chosen terms alone (ordering only)


class BnbSearch:
    """State of one branch and bound (see the module notes)."""

    def __init__(self, A, b, k, forced, admissible, D, scale_system, tol, n_report,
                 structure=None, best_first=False):
        self.A, self.b, self.k = A, b, k
        # candidates are fitted on the triangular factor of A (same least-squares problem, same
        # singular values; p rows instead of m): A = Q R, ‖A_S ξ − b‖² = ‖R_S ξ − Qᵀb‖² + const
        self.Af, self.bf = A, b
        if A.shape[0] > 2 * A.shape[1]:      # R of [A b] holds R and Qᵀb (Q never formed)
            p = A.shape[1]
            R = np.linalg.qr(A if b is None else np.column_stack([A, b]), mode="r")
            self.Af, self.bf = R[:p, :p], (None if b is None else R[:p, p])
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
        banned, required = (set(), []) if structure is None else (set(structure[0]), structure[1])
        self.free = [j for j in range(p) if j not in set(self.forced) and j not in banned]
        # coverage: every support needs a term of each required set (structure_of)
        self.cov = np.zeros((len(required), p), dtype=bool)
        for i, idx in enumerate(required):
            self.cov[i, np.asarray(idx, dtype=np.int64)] = True
        self.cov_forced = self.cov[:, self.forced].any(axis=1)
        self.r = k - len(self.forced)
        self.incumbent, self.winner, self.null_dim = np.inf, None, 0
        self.candidates, self.n_reducible, self.n_examined = [], 0, 0
        self.pool_S, self.pool_s, self.pool_n = [], [], 0
        self.n_leaves = self.n_degenerate = self.nodes = 0
        self.lower_pruned, self.current = np.inf, None
        self.best_first, self.queue, self.n_queued = best_first, [], 0
        self.queued_leaves, self.lower_dropped, self.record = 0, np.inf, np.inf
        self.eager_all = A.shape[0] >= A.shape[1]      # see leaves(); no pair batches
        self.seen = set()                   # supports examined (shared by the trees of a search)

    def clone(self) -> "BnbSearch":
        """A second tree on the same problem, sharing the examined supports and candidates."""
        other = copy.copy(self)
        other.pool_S, other.pool_s, other.pool_n, other.queue = [], [], 0, []
        other.queued_leaves, other.lower_dropped, other.record = 0, np.inf, np.inf
        other.n_leaves = other.n_degenerate = other.nodes = other.n_examined = other.n_reducible = 0
        other.lower_pruned, other.current = np.inf, None
        return other

    # ----------------------------------------------------------------- bounds
    def _score(self, explained):
        return np.clip(1.0 - explained / self.bb, 0.0, 1.0) if self.bb > 0 else np.zeros_like(explained)

    def children(self, node: _Node, batch: bool = True):
        """A node's non-leaf children (with their bounds and partial scores), or None when it
        scored its leaves itself: one term left, or two (``batch``: the pairs of every child)."""
        n, depth = len(self.order), len(node.pos)
        left = self.r - depth
        last = node.pos[-1] if node.pos else -1
        js = np.arange(last + 1, n - left + 1)
        U = self.forced + [int(self.order[j]) for j in node.pos]
        cov_u = self.cov_forced | self.cov[:, U].any(axis=1)
        if left == 1:
            self.leaves(U, js[(cov_u[:, None] | self.cov[:, self.order[js]]).all(axis=0)])
            return None
        rest = self.order[last + 1:]
        if self.b is not None:
            basis = Basis(self.G, self.c)
            for m in U:
                basis.add(m)
            Gd, cd = basis.deflated(rest)
            eI = float(basis.y @ basis.y)
            piv = np.diag(Gd)[:len(js)]
            partial = self._score(eI + cd[:len(js)] ** 2 / np.maximum(piv, 1e-300))
            stop = (1.0 - (self.incumbent - self.tol)) * self.bb if np.isfinite(self.incumbent) else np.inf
            if batch and left == 2 and not np.isfinite(self.incumbent):
                E = np.full(len(js), np.nan)     # bounds would neither prune nor order the batch
            else:
                E = _suffix_explained(Gd, cd, stop - eI)[:len(js)]
            bounds = np.where(np.isnan(E), node.bound, self._score(eI + np.nan_to_num(E)))
            ok = piv >= DEGENERACY_TOL
        else:
            bounds, partial = passive_bounds(self.G, U, self.order[js], rest, left, node.bound)
            ok = np.ones(len(js), dtype=bool)
        bounds = np.maximum(bounds, node.bound)       # a child's superset is inside the parent's
        # a child whose superset misses a required set holds no admissible support
        ok = ok & (cov_u[:, None] | self.cov[:, self.order[js]] | self.suffix_cov[:, js + 1]).all(axis=0)
        if batch and left == 2:
            self._grandchild_leaves(U, cov_u, js[ok], bounds[ok])
            return None
        return [(_Node(node.pos + (int(j),), float(bd), float(pa)))
                for j, bd, pa, o in zip(js, bounds, partial, ok) if o]

    # ----------------------------------------------------------------- leaves
    def _grandchild_leaves(self, U, cov_u, js, bounds):
        """Two terms left: the children ``js`` (bounds ``bounds``) expanded at once — every pair
        (j, j2 > j) of a child not pruned by its bound is scored in one batch (one call instead
        of one per child: the per-call overhead dominated on wide libraries)."""
        keep = bounds < self.incumbent - self.tol
        if (~keep).any():
            self.lower_pruned = min(self.lower_pruned, float(bounds[~keep].min()))
        js = js[keep]
        if not len(js):
            return
        self.nodes += len(js)
        J1, J2 = pair_positions(js, len(self.order))
        cover = (cov_u[:, None] | self.cov[:, self.order[J1]] | self.cov[:, self.order[J2]]).all(axis=0)
        self.leaves(U, np.column_stack([J1[cover], J2[cover]]))

    def leaves(self, U, js):
        """Score the supports U + order[js] (js: positions, or rows of positions) and visit those
        that could beat the incumbent."""
        if not len(js):
            return
        ext = self.order[js]
        S = np.sort(np.hstack([np.broadcast_to(np.array(U, np.int64), (len(js), len(U))),
                               ext.reshape(len(js), -1)]), axis=1)
        scores, deg = np.empty(len(S)), np.empty(len(S), dtype=bool)
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            score_chunks(self.G, self.GD, self.c, self.bb, S, scores, deg, None)
        self.n_leaves += len(S)
        self.n_degenerate += int(deg.sum())
        S, scores = S[~deg], scores[~deg]
        self.pool_S.append(S)
        self.pool_s.append(scores)
        self.pool_n += len(scores)
        if self.pool_n > 50 * RUNNERS_UP:
            self._trim_pool()
        order = np.argsort(scores, kind="stable")
        hopeful = order[scores[order] < self.incumbent - self.tol]
        if len(hopeful) < len(order):
            self.lower_pruned = min(self.lower_pruned, float(scores[order[len(hopeful)]]))
        if self.eager_all and not self.best_first:   # every hopeful leaf at once, up to the first
            any(self.examine(tuple(int(j) for j in S[i]), float(scores[i])) for i in hopeful)
            return         # admissible (queued, noisy data took 36x the nodes: often inadmissible)
        # the batch's best leaf is examined at once when it beats every leaf examined so far (not
        # when best_first): a first incumbent early; the others are queued, one entry per batch,
        # examined when no open node's bound is below them (an exact fit, at round-off, at once)
        n_eager, i = (0 if self.best_first else _EAGER), 0
        while i < min(n_eager, len(hopeful)) and scores[hopeful[i]] < self.record:
            i += 1
            if self.examine(tuple(int(j) for j in S[hopeful[i - 1]]), float(scores[hopeful[i - 1]])):
                break
        rest = hopeful[i:]
        late = scores[rest] >= self.incumbent - self.tol       # beaten by a new incumbent
        if late.any():
            self.lower_pruned = min(self.lower_pruned, float(scores[rest[late]].min()))
        rest = rest[~late]
        if len(rest):
            heapq.heappush(self.queue, (float(scores[rest[0]]), self.n_queued, 0, S[rest], scores[rest]))
            self.n_queued, self.queued_leaves = self.n_queued + 1, self.queued_leaves + len(rest)
            if self.queued_leaves > _MAX_QUEUED:
                self._trim_queue()

    def examine(self, S: tuple, score: float) -> bool:
        """Visit one scored leaf through the rules; True when it becomes the incumbent."""
        if S in self.seen:                  # rejected by the other tree (or the incumbent)
            return False
        self.seen.add(S)
        self.n_examined += 1
        self.record = min(self.record, score)
        if reducible(self.G, self.c, np.array([S]))[0]:
            self.n_reducible += 1
            if self.n_reducible <= self.n_report:
                self.candidates.append(Candidate(S, score, False, REDUCIBLE_REASON))
            return False
        coef, nd = coef_on_support(self.Af, self.bf, S, self.scale_system)
        cand = Candidate(S, score, coef=coef)
        if coef is None:
            cand.admissible, cand.reason = False, NO_SCALE_REASON
        elif self.admissible is None:
            cand.admissible = True
        else:
            cand.admissible, cand.reason = self.admissible(S, coef)
        self.candidates.append(cand)
        if cand.admissible:
            self.incumbent, self.winner, self.null_dim = cand.score, cand, nd
        return bool(cand.admissible)

    def _trim_queue(self):       # keep the best half (the smallest score dropped stays a bound)
        self.queue, dropped, self.queued_leaves = trim_queue(self.queue, _MAX_QUEUED // 2, self.n_queued)
        self.n_queued, self.lower_dropped = self.n_queued + 1, min(self.lower_dropped, dropped)

    def _trim_pool(self):
        S, s = np.vstack(self.pool_S), np.concatenate(self.pool_s)
        keep = np.argsort(s, kind="stable")[:RUNNERS_UP]
        self.pool_S, self.pool_s, self.pool_n = [S[keep]], [s[keep]], len(keep)

    # ----------------------------------------------------------------- search
    def start(self, screen, window: bool = False) -> "BnbSearch":
        """This search's tree over the free terms in library order (False), the screening order
        (True) or the basis-pursuit order ("l1", driven data; None when it cannot be had).  Among
        nodes bounded at round-off, depth first (lexicographic), or with ``window`` the node whose
        last term comes first: every prefix over the first N terms before one using term N+1."""
        if screen in ("l1", "l1-sparse"):      # "l1-sparse": only when it finds a sparse fit
            self.order = l1_order(self.Af, self.bf, self.free, self.forced,
                                  max_terms=2 * self.r if screen == "l1-sparse" else None)
            if self.order is None:
                return None
        else:
            self.order = (screening_order(self.G, self.c, self.forced, self.free, self.k, self.GD)
                          if screen else np.array(self.free, dtype=np.int64))
        self.window = window
        oc = self.cov[:, self.order]
        self.suffix_cov = np.zeros((len(oc), len(self.order) + 1), dtype=bool)
        self.suffix_cov[:, :-1] = np.flip(np.logical_or.accumulate(np.flip(oc, 1), axis=1), 1)
        self.heap, self.counter = [((0.0, 0, 0.0), 0, _Node((), 0.0, 1.0))], 1
        return self

    @property
    def work(self) -> int:
        """Work done by this tree, in the units of :mod:`~lsindy_cas.identify.bnb_drive`."""
        return self.nodes + EXAMINE_COST * self.n_examined

    def advance(self, until: float, work_until: float = np.inf) -> str:
        """Expand until the clock passes ``until`` or the tree's work reaches ``work_until`` (at
        least one node or queued leaf per call): "done" (tree exhausted), "open" or "full"."""
        heap, owed, first = self.heap, False, True
        while heap or self.queue:
            if not first and (self.work >= work_until or time.monotonic() > until):
                return "open"
            first = False
            # a queued leaf is examined when no open node's bound is below it (both at round-off
            # count as 0, as in the nodes' keys), and (not best_first) the best one after each node
            # expanded: the incumbent improves while bounds are weak
            if self.queue and (not heap or owed or (self.queue[0][0] if self.queue[0][0] > self.tol
                                                    else 0.0) <= heap[0][0][0]):
                owed = False
                score, _, i, SS, ss = heapq.heappop(self.queue)
                self.queued_leaves -= 1
                if score >= self.incumbent - self.tol:     # so are the rest of its batch
                    self.lower_pruned = min(self.lower_pruned, score)
                    self.queued_leaves -= len(ss) - i - 1
                    continue
                if i + 1 < len(ss):
                    heapq.heappush(self.queue, (float(ss[i + 1]), self.n_queued, i + 1, SS, ss))
                    self.n_queued += 1
                self.examine(tuple(int(j) for j in SS[i]), score)
                continue
            node = heapq.heappop(heap)[2]
            if node.bound >= self.incumbent - self.tol:
                self.lower_pruned = min(self.lower_pruned, node.bound)
                continue
            self.current = node
            self.nodes += 1
            kids = self.children(node, batch=not self.eager_all)
            self.current, owed = None, not self.best_first
            for ch in kids or ():
                if ch.bound >= self.incumbent - self.tol:
                    self.lower_pruned = min(self.lower_pruned, ch.bound)
                    continue
                b0 = ch.bound if ch.bound > self.tol else 0.0
                key = ((b0, ch.pos[-1], -len(ch.pos), ch.partial) if self.window
                       else (b0, -len(ch.pos), ch.pos[-1], ch.partial))
                heapq.heappush(heap, (key, self.counter, ch))
                self.counter += 1
            if len(heap) > _MAX_OPEN:
                return "full"
        return "done"

    def lower(self) -> float:
        """Smallest bound or score left unexplored or pruned: no unexamined support scores less."""
        return min([self.lower_pruned, self.lower_dropped] + [h[2].bound for h in self.heap]
                   + [q[0] for q in self.queue[:1]]
                   + ([self.current.bound] if self.current is not None else []))


def branch_and_bound(A: np.ndarray, b: np.ndarray | None, k: int, forced=(), *,
                     admissible: Callable | None = None, D: np.ndarray | None = None,
                     scale_system: tuple | None = None, time_limit: float | None = None,
                     tol: float = SCORE_RESOLUTION, n_report: int = 10,
                     progress: Callable | None = None, screen="auto",
                     structure=None, best_first: bool = False,
                     work_limit: float | None = None, resume=None) -> SearchResult:
    """Best admissible k-term support of ``A ξ ≈ b`` (or of a null vector) by branch and bound.

    Same inputs and result as :func:`lsindy_cas.identify.search.best_subset`, plus a certificate
    (``method="bnb"``, ``proven``, ``gap``, ``nodes``, ``seconds``, ``interrupted``).

    Parameters
    ----------
    A, b, k, forced, admissible, D, scale_system, n_report
        As for :func:`~lsindy_cas.identify.search.best_subset` (``D`` required when ``b`` is None).
    time_limit : float, optional
        Seconds after which the best admissible support found so far is returned, not proven.
    work_limit : float, optional
        The same after this much work (nodes expanded plus ``EXAMINE_COST`` per leaf examined,
        :mod:`~lsindy_cas.identify.bnb_drive`): a limit that stops at the same point on every
        machine.  With ``resume``: this much more work.
    resume : BnbState, optional
        Go on with a search that stopped before it was proven (its result's or error's
        ``state``; None once proven or interrupted); the other arguments but ``time_limit``,
        ``work_limit`` and ``progress`` are then ignored.  Nothing done before is repeated; the
        result's counts and seconds are the totals of every call.
    tol : float
        Prune a subtree whose bound is within ``tol`` of the incumbent (score units, ≥ 0).
    progress : callable ``(n_done, n_total)``, optional
        Called with (nodes expanded, 0) a few times a second; its ``status(text)`` method, if it has
        one, receives the current gap, best score and elapsed time.
    screen : {"auto", True, False, "l1"}
        The order of the free terms: the library's (False; a polynomial library lists low degrees
        first), :func:`screening_order` (True), the basis-pursuit order (:func:`l1_order`,
        "l1", driven data), or all of them searched in turn sharing the incumbent, the first one
        exhausted proving it ("auto", default; the basis-pursuit tree only when basis pursuit
        finds a sparse fit or the system is not underdetermined, see ``max_terms`` of
        :func:`l1_order`).  The answer is the same; which order finds the
        winner first depends on the data (benchmarks/bench_bnb.py: the library order on the
        paper's 1 s runs, the basis-pursuit order on rich data, where it puts the true terms first).
    structure : (banned, required), optional
        Terms no admissible support has and sets each support must meet (default
        :func:`structure_of` ``(admissible)``: found when ``admissible`` is an
        :class:`~lsindy_cas.identify.admissibility.Admissibility`).
    best_first : bool
        Queue every scored leaf and examine it only when no open node's bound is below it (the
        first admissible one is then proven at once); default: examine the best leaf of each
        batch as soon as it is scored and queue the others, which finds an incumbent earlier when
        bounds are weak (and, on exact data, the exact fit as soon as its batch is scored).

    Returns
    -------
    SearchResult
        ``supports``/``scores`` hold the best scored leaves (at most 2000), not every support.
    """
    if resume is not None:               # more work on a search stopped before (``.state``)
        return drive_and_conclude(resume, time_limit, progress, work_limit)
    m, p = A.shape
    forced, k, time_limit, tol = check_inputs(A, b, D, k, forced, time_limit, tol)
    if k == len(forced):
        from .search import best_subset
        return best_subset(A, b, k, forced, admissible=admissible, D=D, scale_system=scale_system,
                           n_report=n_report)
    if structure is None:
        structure = structure_of(admissible, p)
    s = BnbSearch(A, b, k, forced, admissible, D, scale_system, tol, n_report, structure, best_first)
    slices = None
    if screen == "auto":
        l1 = s.clone().start("l1" if s.eager_all else "l1-sparse") if b is not None else None
        lib = [s.start(False)] + ([] if s.eager_all else [s.clone().start(False, window=True)])
        trees = lib + [t for t in (l1, s.clone().start(True)) if t is not None]
        if b is not None and l1 is None:    # paper runs (bench_bnb): the library order finds it
            slices = [_LIBRARY_SLICES] * len(lib) + [1] * (len(trees) - len(lib))
    else:
        trees = [s.start(screen if screen == "l1" else bool(screen))]
        if trees[0] is None:
            raise ValueError("the basis-pursuit order needs driven data (b) and a solvable "
                             "linear programme")
    return drive_and_conclude(BnbState(trees, slices), time_limit, progress, work_limit)
