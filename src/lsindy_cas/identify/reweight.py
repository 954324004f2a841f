"""Re-selection of the support on the noise-weighted energy balance (errors in variables).

After the first search, :meth:`LagrangianSINDy._refine` weights each row of the balance by the
inverse variance of the fitted energy and searches the support again at the same k: weighting
can change which support explains the data best when the noise varies along the trajectories.

With a large library the first search is a branch and bound, and the weighted one is much
harder to prove: weighting shrinks the rows that carry most of the signal, so the winner's score
sits closer to the bounds of the subtrees (measured on the double pendulum, rich protocol, 10 runs,
σ = 1e-2, 209 terms, k = 6: the first search proved its winner in 4,878 nodes, the weighted one ran
past 1.1 million nodes and half an hour — and it ignored ``time_limit``).  So the weighted search
here gets a budget of work (:mod:`~lsindy_cas.identify.bnb_drive` units, the same stopping point
on every machine): as much as the first search spent, at least :data:`MIN_WORK` — and, like every
branch and bound, at most the caller's ``time_limit`` seconds.  The outcome is recorded honestly:

- proven, or cut short with a support that scores better on the weighted balance than the first
  one: the weighted search's own result and certificate (then not proven, with its gap);
- cut short without beating the first support (the same one, or a worse one: a cut-short search
  need not have reached the first winner yet): the first search's certificate stands for that
  support (it is proven best on the unweighted balance), and the weighted check is attached as
  ``reweighted`` (``{"proven", "gap", "nodes", "seconds", "work"}``) so the model file and printout can say
  that no better support was found on the weighted balance within the budget.
"""
from __future__ import annotations

import math

import numpy as np

from .search import score_supports
from .selection import SCOUT_WORK, select

__all__ = ["reselect", "MIN_WORK"]

#: the weighted branch and bound gets at least this much work: an automatic-k scout's
MIN_WORK = SCOUT_WORK


def budget(first):
    """Work allowed to the weighted search (None: no limit, the exhaustive path)."""
    if getattr(first, "method", "exhaustive") == "exhaustive":
        return None                            # exhaustive again: fast, no limit applies
    return max(MIN_WORK, float(getattr(first, "work", 0.0) or 0.0))


def reselect(bal_w, forced, sel, *, scale_system, admissible, time_limit=None, progress=None,
             backend=None):
    """The selection at ``sel.k`` on the weighted balance ``bal_w``.

    Returns
    -------
    (Selection, bool)
        The selection to keep and whether its support differs from ``sel``'s.  ``sel`` itself when
        no admissible support passes on the weighted balance or the weighted search was
        interrupted before finding one.
    """
    first = sel.search
    try:
        sel_w = select(bal_w, forced, n_terms=sel.k, scale_system=scale_system,
                       admissible=admissible, time_limit=time_limit,
                       work_limit=budget(first), progress=progress, backend=backend)
    except (ValueError, KeyboardInterrupt):
        return sel, False
    res = sel_w.search
    if res.proven or first.method != "bnb":
        return sel_w, sel_w.support != sel.support
    if sel_w.support != sel.support and not _scores_above(bal_w, sel.support, sel_w.support):
        return sel_w, True       # cut short, but it found a support the weights prefer
    # cut short without beating the first support: keep the first certificate (proven on the
    # unweighted balance) and say what the weighted check did
    first.reweighted = {"proven": False, "gap": float(res.gap) if math.isfinite(res.gap) else None,
                        "nodes": int(res.nodes), "seconds": float(res.seconds),
                        "work": float(res.work)}
    return sel, False


def _scores_above(bal, kept, found) -> bool:
    """Whether ``found`` scores no better than ``kept`` on the balance ``bal`` (same score as the
    search: unexplained fraction of the column-normalised balance, or the passive eigenvalue)."""
    D = bal.D if bal.passive else None
    scores, _ = score_supports(bal.A, None if bal.passive else bal.b,
                               np.array([sorted(kept), sorted(found)], dtype=np.int64), D=D)
    return bool(scores[1] >= scores[0])
