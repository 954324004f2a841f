"""Swing-up far from the goal: a beam search over input sequences on the model, :class:`BeamSearch`.

From the current state, every input choice (the task's levels; for a continuous input its bounds
and 0) is tried at each of ``depth`` samples; after each sample only the ``width`` best partial
sequences by the heuristic ``cost(x)`` are kept (states outside the limits are dropped).  A
sequence whose state enters the capture set (``capture(x)``: the local stabiliser's region or the
reach condition) ends the search at the earliest such sample — the shortest way in that the beam
saw.  Otherwise the sequence with the lowest terminal cost wins.  The first input is applied; the
rest, shifted by one sample, is kept in the beam at the next call (warm start), so a plan is
only abandoned for a better one.

All children of a depth are simulated in one call of the model's discrete map (CasADi ``map``).
"""
from __future__ import annotations

import numpy as np

__all__ = ["BeamSearch"]

# samples simulated per call when a kept plan is checked (one CasADi call instead of one per
# sample; plans are tens to hundreds of samples long)
CHUNK = 32


def _mapped(step, size):
    """``step`` over ``size`` columns as an MX function (what :func:`compiled_function` takes)."""
    import casadi as ca
    X = ca.MX.sym("X", step.size1_in(0), size)
    U = ca.MX.sym("U", step.size1_in(1), size)
    return ca.Function("step_map", [X, U], [step.map(size)(X, U)], ["X", "U"], ["X_next"])


def _maybe_compiled(f, jit):
    if not jit:
        return f
    import casadi as ca
    from .compiled import compiled_function
    if not f.is_a("MXFunction"):
        args = [ca.MX.sym(f.name_in(i), f.sparsity_in(i)) for i in range(f.n_in())]
        f = ca.Function(f.name(), args, f.call(args), f.name_in(), f.name_out())
    return compiled_function(f)


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
    """

    def __init__(self, step, candidates, depth, width, cost, capture, lower, upper, cells=20,
                 jit=False):
        self.candidates = np.asarray(candidates, float)
        self.k = len(self.candidates)
        self.depth, self.width = int(depth), int(width)
        self.cost, self.capture = cost, capture
        self.lower, self.upper = lower, upper
        self.size = self.width * self.k
        self.step = _maybe_compiled(_mapped(step, self.size), jit)
        self.roll = _maybe_compiled(step.mapaccum("roll", CHUNK), jit)
        self.plan, self.captured = None, False
        self.cells = int(cells)

    def reset(self):
        self.plan, self.captured = None, False

    def _advance(self, X, U):
        N = len(X)
        Xp = np.zeros((self.size, X.shape[1]))
        Up = np.zeros((self.size, U.shape[1]))
        Xp[:N], Up[:N] = X, U
        return np.asarray(self.step(Xp.T, Up.T)).T[:N]

    def _diverse(self, X, order):
        """The ``width`` best of ``order`` with at most one per cell of a grid that splits
        each state's spread among the children into ``CELLS`` (near-copies waste the beam)."""
        lo, span = X.min(axis=0), np.ptp(X, axis=0)
        cell = np.floor((X[order] - lo) / np.where(span > 0, span, 1.0) * self.cells)
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
            X = np.asarray(self.roll(x, U.T)).T[:len(part)]
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
        if self.captured and self.plan is not None and self._still_captures(x, self.plan):
            first, self.plan = int(self.plan[0]), (self.plan[1:] if len(self.plan) > 1 else None)
            return first
        X, seqs = x[None, :], np.zeros((1, 0), int)
        warm = self.plan
        best_seq, best_h = None, np.inf
        for d in range(self.depth):
            N = len(X)
            child = np.repeat(np.arange(N), self.k)
            choice = np.tile(np.arange(self.k), N)
            Xn = self._advance(X[child], self.candidates[choice])
            seqs_n = np.hstack([seqs[child], choice[:, None]])
            ok = np.all(np.isfinite(Xn), axis=1)
            ok &= np.all((Xn >= self.lower) & (Xn <= self.upper), axis=1)
            if not np.any(ok):
                break
            Xn, seqs_n = Xn[ok], seqs_n[ok]
            hit = self.capture(Xn)
            h = self.cost(Xn)
            if np.any(hit):
                i = np.flatnonzero(hit)[np.argmin(h[hit])]
                best_seq, best_h = seqs_n[i], -np.inf
                break
            order = self._diverse(Xn, np.argsort(h, kind="stable"))
            if warm is not None and d < len(warm):
                # keep the previous plan's path in the beam (it is one of the children)
                on = np.flatnonzero(np.all(seqs_n == warm[:d + 1], axis=1))
                if on.size and on[0] not in order:
                    order[-1] = on[0]
            X, seqs = Xn[order], seqs_n[order]
            i = int(np.argmin(h[order]))
            best_seq, best_h = seqs[i], h[order][i]
        if best_seq is None:               # every child leaves the limits: least-bad first input
            self.plan = None
            return None
        self.plan = best_seq[1:] if len(best_seq) > 1 else None
        self.captured = bool(best_h == -np.inf)
        self.last_cost = best_h
        return int(best_seq[0])
