"""Driving the trees of a branch and bound in turn: time slices, the shared incumbent, progress.

Every tree of :func:`lsindy_cas.identify.bnb.branch_and_bound` covers all supports (in its own
order of the terms), so the first one exhausted proves the incumbent; each tree's lower bound holds
for every support it has not examined, so the largest one bounds the gap.
"""
from __future__ import annotations

import time

import numpy as np

from .._validate import check_real

__all__ = ["drive", "check_inputs", "nothing_admissible"]

REPORT_EVERY = 0.25       # seconds between progress reports (and between trees)


def drive(trees, time_limit, progress, slices=None):
    """Advance the trees in turn (``slices[i]`` slices of REPORT_EVERY s each for tree i, default
    one), sharing the incumbent.

    Every tree covers all supports, so the first one exhausted proves the incumbent; each tree's
    lower bound holds for every support it has not examined, so the largest one bounds the gap.
    Returns (lower, proven, seconds, interrupted).
    """
    t0 = time.monotonic()
    deadline = np.inf if time_limit is None else t0 + time_limit
    state, interrupted = "open", False
    try:
        while state == "open":
            for s, n in zip(trees, slices or [1] * len(trees)):
                best = min(trees, key=lambda t: t.incumbent)
                s.incumbent, s.winner, s.null_dim = best.incumbent, best.winner, best.null_dim
                state = s.advance(min(deadline, time.monotonic() + n * REPORT_EVERY))
                if progress is not None:
                    _report(progress, trees, time.monotonic() - t0)
                if state != "open" or time.monotonic() > deadline:
                    break
            if time.monotonic() > deadline and state == "open":
                state = "time"
    except KeyboardInterrupt:
        interrupted = True
    best = min(trees, key=lambda t: t.incumbent)
    for s in trees:
        s.incumbent, s.winner, s.null_dim = best.incumbent, best.winner, best.null_dim
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


def nothing_admissible(k, candidates, proven, seconds, nodes, n_leaves) -> ValueError:
    """The error of a branch and bound that examined no admissible support, with the reasons its
    candidates were refused."""
    why = "; ".join(sorted({c.reason for c in candidates if c.reason}))
    return ValueError(f"no physically admissible {k}-term model "
                      + ("among all supports" if proven else f"found in {seconds:.1f} s")
                      + f" ({nodes:,} nodes, {n_leaves:,} supports scored"
                      + (f"; reasons: {why})" if why else ")"))
