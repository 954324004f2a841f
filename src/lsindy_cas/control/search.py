"""Swing-up far from the goal: a beam search over input sequences on the model, :class:`BeamSearch`.

From the current state, every input choice (the task's levels; for a continuous input its bounds
and 0) is tried at each of ``depth`` samples; after each sample only the ``width`` best partial
sequences by the heuristic ``cost(x)`` are kept (states outside the limits are dropped).  A
sequence whose state enters the capture set (``capture(x)``: the local stabiliser's region or the
reach condition) ends the search at the earliest such sample — the shortest way in that the beam
saw.  Otherwise the sequence with the lowest terminal cost wins.  The first input is applied; the
rest, shifted by one sample, is kept in the beam at the next call (warm start), so a plan is
only abandoned for a better one.

Anytime: with a ``budget`` one call expands at most that many samples.  A search that needs more
goes on at the next calls; each of them applies the previous plan's next input (with none, the
best partial sequence's) and the beam keeps only the sequences that begin with the inputs applied,
so the plan adopted when the search ends starts where they leave off.  With ``restart`` the
search is instead dropped at the end of the call (its best partial sequence's first input is
applied) and the next call starts again from the measured state: a receding horizon that keeps
a plan only once one enters the capture set.

All children of a depth are simulated in one call of the model's discrete map (CasADi ``map``).
"""
from __future__ import annotations

import numpy as np

__all__ = ["BeamSearch", "maybe_compiled"]

# samples simulated per call when a kept plan is checked (one CasADi call instead of one per
# sample; plans are tens to hundreds of samples long)
CHUNK = 32


def _mapped(step, size):
    """``step`` over ``size`` columns as an MX function (what :func:`compiled_function` takes)."""
    import casadi as ca
    X = ca.MX.sym("X", step.size1_in(0), size)
    U = ca.MX.sym("U", step.size1_in(1), size)
    return ca.Function("step_map", [X, U], [step.map(size)(X, U)], ["X", "U"], ["X_next"])


def maybe_compiled(f, jit):
    """``f`` compiled to C when ``jit``, called through preallocated buffers
    (:class:`~.fastcall.NumericFunction`: no DM conversions, ~0.1 ms per call)."""
    from .fastcall import NumericFunction
    if jit:
        import casadi as ca
        from .compiled import compiled_function
        if not f.is_a("MXFunction"):
            args = [ca.MX.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
            f = ca.Function(f.name(), args, f.call(args), f.name_in(), f.name_out())
        f = compiled_function(f)
    return NumericFunction(f)


class BeamSearch:
    """Beam search over discrete input sequences.

    Parameters
    ----------
    step : casadi.Function
        ``(x (n,), u (m,)) -> x_next`` over one sample.
    candidates : ndarray (k, m)
        The input vectors tried at each sample.
    depth, width : int
        Samples looked ahead; partial sequences kept per sample.
    cost : callable
        ``X (N, n) -> (N,)`` heuristic, lower is better.
    capture : callable
        ``X (N, n) -> bool (N,)``: the goal region the search aims into.
    lower, upper : ndarray (n,)
        State limits (±inf where none).
    cells : int
        Diversity: at most one kept sequence per cell of a grid splitting each state's spread
        among the children into ``cells``.
    jit : bool
        Compile the mapped model map to C (:mod:`~.compiled`; on the Acrobot 0.73 instead of
        3.2 ms per call of 192 children, 0.6 s to compile once).
    budget : int or None
        Samples expanded per call at most (None: a search runs to its end in one call).
    restart : bool
        Drop an unfinished search at the end of the call instead of going on with it.

    Attributes
    ----------
    stats : dict
        Counts since construction: plans ``kept``, ``searches`` started, inputs ``commits``
        (applied while a search goes on), ``restarts``, and how searches ended (``hit``,
        ``depth``, ``dead``).
    """

    def __init__(self, step, candidates, depth, width, cost, capture, lower, upper, cells=20,
                 jit=False, budget=None, restart=False):
        self.candidates = np.asarray(candidates, float)
        self.k = len(self.candidates)
        self.depth, self.width = int(depth), int(width)
        self.cost, self.capture = cost, capture
        self.lower, self.upper = lower, upper
        self.size = self.width * self.k
        self.step = maybe_compiled(_mapped(step, self.size), jit)
        self.roll = maybe_compiled(step.mapaccum("roll", CHUNK), jit)
        self.cells = int(cells)
        n = len(self.lower)
        # cell indices run 0..cells: the grid numbered in base cells + 1 when it fits int64
        self._radix = ((self.cells + 1) ** np.arange(n, dtype=np.int64)
                       if n * np.log2(self.cells + 1) < 62 else None)
        self.budget = None if budget is None else max(1, int(budget))
        self.restart = bool(restart)
        self.stats = {"kept": 0, "searches": 0, "commits": 0}
        self.reset()

    def reset(self):
        self.plan, self.captured, self._job = None, False, None

    def _advance(self, X, U):
        N = len(X)
        Xp = np.zeros((self.size, X.shape[1]))
        Up = np.zeros((self.size, U.shape[1]))
        Xp[:N], Up[:N] = X, U
        return self.step(Xp.T, Up.T).T[:N]

    def _diverse(self, X, order):
        """The ``width`` best of ``order`` with at most one per cell of a grid that splits
        each state's spread among the children into ``cells`` (near-copies waste the beam)."""
        lo, span = X.min(axis=0), np.ptp(X, axis=0)
        cell = np.floor((X[order] - lo) / np.where(span > 0, span, 1.0) * self.cells)
        if self._radix is not None:      # one integer per cell: a 1-D unique, ~10x faster
            cell = cell.astype(np.int64) @ self._radix
            _, first = np.unique(cell, return_index=True)
        else:
            _, first = np.unique(cell, axis=0, return_index=True)
        return order[np.sort(first)][:self.width]

    def _still_captures(self, x, plan):
        """Whether ``plan`` (input indices), simulated from ``x``, stays inside the limits and
        enters the capture set: then it is kept without a new search.  Simulated ``CHUNK``
        samples per call of the model's accumulated map."""
        for s in range(0, len(plan), CHUNK):
            part = plan[s:s + CHUNK]
            U = np.zeros((CHUNK, self.candidates.shape[1]))
            U[:len(part)] = self.candidates[part]
            X = self.roll(x, U.T).T[:len(part)]
            bad = ~(np.all(np.isfinite(X), axis=1)
                    & np.all((X >= self.lower) & (X <= self.upper), axis=1))
            hit = self.capture(np.nan_to_num(X))
            first_bad = np.argmax(bad) if np.any(bad) else len(part)
            if np.any(hit[:first_bad]):
                return True
            if first_bad < len(part):
                return False
            x = X[-1]
        return False

    def __call__(self, x):
        """Index of the input to apply now (None when every sequence leaves the limits)."""
        x = np.asarray(x, float)
        if self._job is None:
            if self.captured and self.plan is not None and self._still_captures(x, self.plan):
                self.stats["kept"] += 1
                first = int(self.plan[0])
                self.plan = self.plan[1:] if len(self.plan) > 1 else None
                return first
            self.stats["searches"] += 1
            self._job = {"X": x[None, :], "seqs": np.zeros((1, 0), int), "warm": self.plan,
                         "done": 0, "best": None, "best_h": np.inf, "h": np.zeros(1)}
        return self._work()

    def _work(self):
        """Expand the running search by at most ``budget`` samples.  When it ends, its plan (the
        part after the inputs already applied) is adopted.  Otherwise this call's input is its
        best partial sequence's first (restart mode: the search is dropped, the next call
        starts again from the measured state), or the one after the inputs applied so far (the
        warm plan's while the beam holds it), and the beam keeps only the sequences that agree."""
        job = self._job
        k = job["done"]
        end = None
        for _ in range(self.depth if self.budget is None else self.budget):
            if job["seqs"].shape[1] >= self.depth:
                break
            end = self._expand(job)
            if end is not None:
                break
        if end is None and job["seqs"].shape[1] >= self.depth:
            end = "depth"
        best = job["best"]
        if end is not None:
            self._job = None
            self.stats[end] = self.stats.get(end, 0) + 1
            if best is None or len(best) <= k:     # every child leaves the limits
                self.plan, self.captured = None, False
                return None
            tail = best[k:]
            self.plan = tail[1:] if len(tail) > 1 else None
            self.captured = end == "hit"
            self.last_cost = job["best_h"]
            return int(tail[0])
        if self.restart:
            self._job = None
            self.stats["restarts"] = self.stats.get("restarts", 0) + 1
            self.plan, self.captured = (best[1:] if len(best) > 1 else None), False
            return int(best[0])
        seqs, warm = job["seqs"], job["warm"]
        if warm is not None and k < len(warm) and np.any(seqs[:, k] == warm[k]):
            choice = int(warm[k])
        else:
            choice = int(best[k])
        keep = seqs[:, k] == choice
        job["X"], job["seqs"], job["h"] = job["X"][keep], seqs[keep], job["h"][keep]
        i = int(np.argmin(job["h"]))
        job["best"], job["best_h"] = job["seqs"][i], job["h"][i]
        job["done"] = k + 1
        self.stats["commits"] += 1
        return choice

    def _expand(self, job):
        """One sample deeper: None, or why the search ends ("hit", "dead")."""
        X, seqs, warm = job["X"], job["seqs"], job["warm"]
        d = seqs.shape[1]
        N = len(X)
        child = np.repeat(np.arange(N), self.k)
        choice = np.tile(np.arange(self.k), N)
        Xn = self._advance(X[child], self.candidates[choice])
        seqs_n = np.hstack([seqs[child], choice[:, None]])
        ok = np.all(np.isfinite(Xn), axis=1)
        ok &= np.all((Xn >= self.lower) & (Xn <= self.upper), axis=1)
        if not np.any(ok):
            return "dead"
        Xn, seqs_n = Xn[ok], seqs_n[ok]
        hit = self.capture(Xn)
        h = self.cost(Xn)
        if np.any(hit):
            i = np.flatnonzero(hit)[np.argmin(h[hit])]
            job["best"], job["best_h"] = seqs_n[i], -np.inf
            return "hit"
        order = self._diverse(Xn, np.argsort(h, kind="stable"))
        if warm is not None and d < len(warm):
            # keep the previous plan's path in the beam (it is one of the children)
            on = np.flatnonzero(np.all(seqs_n == warm[:d + 1], axis=1))
            if on.size and on[0] not in order:
                order[-1] = on[0]
        job["X"], job["seqs"], job["h"] = Xn[order], seqs_n[order], h[order]
        i = int(np.argmin(job["h"]))
        job["best"], job["best_h"] = job["seqs"][i], job["h"][i]
        return None
