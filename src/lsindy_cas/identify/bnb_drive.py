"""Driving the trees of a branch and bound in turn: slices of work, the shared incumbent, progress.

Every tree of :func:`lsindy_cas.identify.bnb.branch_and_bound` covers all supports (in its own
order of the terms), so the first one exhausted proves the incumbent; each tree's lower bound holds
for every support it has not examined, so the largest one bounds the gap.

The trees take turns by *work*, not by the clock: a node expanded counts one unit, a leaf examined
(a fit and the admissibility rules) ``EXAMINE_COST`` units.  So which tree finds what first, and
where a ``work_limit`` stops the search, are the same on every machine; ``time_limit`` (seconds)
is the only thing that depends on the clock.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .._validate import check_real
from .fitting import coef_on_support
from .search import Candidate, NoAdmissibleModel, SearchResult

__all__ = ["drive", "check_inputs", "nothing_admissible", "BnbState", "drive_and_conclude",
           "EXAMINE_COST", "SLICE_WORK", "RUNNERS_UP"]

REPORT_EVERY = 0.25       # seconds between progress reports
# A leaf examined costs about ten nodes expanded: measured 0.55 ms per examination against ~30 µs
# per node (double pendulum, 209 terms: 5010 rich rows and the paper's 101 rows).
EXAMINE_COST = 10
# Work units per turn of a tree: ~0.1-0.3 s on the double pendulum's trees (16-31 k units/s
# measured, rich and paper data) — short enough that a tree which finds the model in a few nodes
# (the basis-pursuit order on rich data) is reached quickly, long enough that turns cost nothing.
SLICE_WORK = 5000
RUNNERS_UP = 2000               # scored leaves kept as runners-up (best first)


def drive(trees, time_limit, progress, slices=None, work_limit=None, cursor=None):
    """Advance the trees in turn (``slices[i]`` slices of SLICE_WORK units each for tree i,
    default one), sharing the incumbent, until one is exhausted, ``time_limit`` seconds pass or
    ``work_limit`` units are spent (module notes).  ``cursor`` ([tree index, work its slice ends
    at or None], updated in place) lets a later call go on with the turn a limit cut short, so
    that a search stopped and driven again expands the same nodes as one that never stopped.

    Returns (lower, proven, seconds, interrupted).
    """
    t0 = time.monotonic()
    deadline = np.inf if time_limit is None else t0 + time_limit
    budget = np.inf if work_limit is None else float(work_limit)
    state, interrupted, reported = "open", False, t0
    per = slices or [1] * len(trees)
    cursor = [0, None] if cursor is None else cursor

    def spent():
        return sum(t.work for t in trees)

    try:
        while state == "open":
            i, end = cursor
            s = trees[i]
            if end is not None and s.work >= end:      # this turn is over: the next tree's
                cursor[:] = [(i + 1) % len(trees), None]
                continue
            if end is None:
                end = cursor[1] = s.work + per[i] * SLICE_WORK
            best = min(trees, key=lambda t: t.incumbent)
            s.incumbent, s.winner, s.null_dim = best.incumbent, best.winner, best.null_dim
            state = s.advance(deadline, min(end, s.work + budget - spent()))
            now = time.monotonic()
            if progress is not None and now - reported >= REPORT_EVERY:
                _report(progress, trees, now - t0)
                reported = now
            if state == "open" and (now > deadline or spent() >= budget):
                state = "stopped"
    except KeyboardInterrupt:
        interrupted = True
    best = min(trees, key=lambda t: t.incumbent)
    for s in trees:
        s.incumbent, s.winner, s.null_dim = best.incumbent, best.winner, best.null_dim
    if progress is not None:
        _report(progress, trees, time.monotonic() - t0)
    lower = max(s.lower() for s in trees)
    return lower, state == "done" and not interrupted, time.monotonic() - t0, interrupted


def _report(progress, trees, elapsed):
    inc = min(t.incumbent for t in trees)
    lower = max(t.lower() for t in trees)
    gap = max(0.0, inc - lower) if np.isfinite(inc) else float("inf")
    progress(sum(t.nodes for t in trees), 0)
    status = getattr(progress, "status", None)
    if status is not None:
        status(f"gap {gap:.2e}, best {inc:.3e}, {elapsed:.1f} s")


def check_inputs(A, b, D, k, forced, time_limit, tol):
    """The arguments every branch and bound (one process or a cluster) checks before any work.

    Returns ``(forced sorted without repeats, k, time_limit, tol)``; raises ValueError/TypeError.
    """
    p = A.shape[1]
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
    return forced, k, time_limit, tol


def nothing_admissible(k, candidates, proven, seconds, nodes, n_leaves, work=0.0):
    """The error (:class:`~lsindy_cas.identify.search.NoAdmissibleModel`) of a branch and bound
    that examined no admissible support, with the reasons its candidates were refused."""
    why = "; ".join(sorted({c.reason for c in candidates if c.reason}))
    return NoAdmissibleModel(f"no physically admissible {k}-term model "
                             + ("among all supports" if proven else f"found in {seconds:.1f} s")
                             + f" ({nodes:,} nodes, {n_leaves:,} supports scored"
                             + (f"; reasons: {why})" if why else ")"), k, proven, seconds, work)


@dataclass
class BnbState:
    """The trees of a branch and bound that stopped before it was proven (``SearchResult.state``
    or ``NoAdmissibleModel.state``): ``branch_and_bound(..., resume=state)`` goes on from there."""
    trees: list
    slices: list | None
    seconds: float = 0.0
    cursor: list = field(default_factory=lambda: [0, None])   # drive's turn, to go on with

    @property
    def work(self) -> int:
        return sum(t.work for t in self.trees)


def drive_and_conclude(state: BnbState, time_limit, progress, work_limit) -> SearchResult:
    """Drive the trees for up to ``work_limit`` more units (or ``time_limit`` more seconds), then
    the result or the error, with the totals of every call so far."""
    trees, s = state.trees, state.trees[0]
    work_limit = check_real("work_limit", work_limit, positive=True, allow_none=True)
    lower, proven, seconds, interrupted = drive(
        trees, time_limit, progress, state.slices,
        None if work_limit is None else state.work + work_limit, state.cursor)
    state.seconds += seconds
    # leaves dropped from a full queue were never examined: proven only if none could win
    proven = proven and all(t.lower_dropped >= s.incumbent - s.tol for t in trees)
    total = {name: sum(getattr(t, name) for t in trees)
             for name in ("n_leaves", "n_degenerate", "nodes", "n_reducible")}
    open_state = None if proven or interrupted else state
    if s.winner is None and interrupted:
        raise KeyboardInterrupt            # nothing to return: let the caller stop
    if s.winner is None:
        exc = nothing_admissible(s.k, s.candidates, proven, state.seconds, total["nodes"],
                                 total["n_leaves"], state.work)
        exc.state = open_state
        raise exc
    S = np.vstack([x for t in trees for x in t.pool_S])
    sc = np.concatenate([x for t in trees for x in t.pool_s])
    keep = np.argsort(sc, kind="stable")[:RUNNERS_UP]
    sup, sc = S[keep], sc[keep]
    w = s.winner
    coef, nd = coef_on_support(s.A, s.b, w.support, s.scale_system)     # as the exhaustive path
    null_dim = s.null_dim
    if coef is not None:
        w.coef, null_dim = coef, nd
    seen = {c.support for c in s.candidates}
    runners = [Candidate(tuple(int(j) for j in S), float(v)) for S, v in zip(sup, sc)
               if tuple(int(j) for j in S) not in seen][:s.n_report]
    cands = sorted(s.candidates, key=lambda c: c.score) + runners
    res = SearchResult(w.support, w.coef, w.score, cands, total["n_leaves"],
                       total["n_degenerate"], null_dim, sc, sup, total["n_reducible"])
    res.method, res.proven, res.interrupted = "bnb", proven, interrupted
    res.gap = max(0.0, w.score - lower)
    res.nodes, res.seconds, res.work = total["nodes"], state.seconds, state.work
    res.state = open_state
    return res
