"""The branch and bound on a Dask cluster: subtrees as tasks, the incumbent shared.

The single-process search (:func:`lsindy_cas.identify.bnb.branch_and_bound`) keeps, for each of its
trees (library, basis-pursuit and screening order), a heap of open nodes; a node is a subtree, and
its bound holds for every support in it.  Here the driver keeps those heaps as the pool of work:

1. *Warm-up and frontier.*  The ordinary search runs on the driver for ``warmup`` seconds (a small
   problem is proven there and never leaves the process; on rich data the basis-pursuit tree finds
   the true support in the first nodes), then each tree is expanded best-first until it has
   ``FRONTIER`` open nodes per worker.
2. *Tasks.*  A task takes the lowest-bound open nodes of one tree (the tree with the least worker
   time so far, as one process gives its trees equal time slices) and runs the ordinary best-first search on them for at most
   ``task_seconds``, then returns its winner, its records and the nodes it left open, which go back
   into the pool (so a large subtree is split again: the load balances itself).  ``2 × workers``
   tasks are in flight.  The problem — normalised Gram matrix, the triangular factor the candidates
   are fitted on, the admissibility rules, the trees' orders — is scattered to the workers once;
   a task carries only its nodes (a few integers each).
3. *Shared incumbent.*  The best admissible score found anywhere lives in a ``distributed.Variable``:
   each task reads it every ``SYNC_EVERY`` s and prunes against it, and publishes its own winner
   when that is better (two tasks publishing at once may leave the worse value; each re-publishes
   at its next read, and a stale value only prunes less, never wrongly).  The driver passes the
   best score it knows to every new task too.
4. *Answer.*  When a tree's pool is empty and none of its tasks is out, that tree is exhausted and
   the incumbent proven (as in one process: the first tree exhausted proves it); the tasks still
   out are told to stop (the shared value set to −∞) and awaited (their winners may be the one
   the shared value came from).  A time limit or Ctrl-C stops the same way, not proven.  The winner is the
   lowest admissible score found, exact ties broken by the smaller support; its coefficients are
   refitted on the driver exactly as in one process, so a support found by both has bit-identical
   coefficients.  The certificate is that of one process: ``gap`` = winner − the largest over
   trees of the smallest bound left, ``nodes`` summed over the driver and every task,
   ``seconds`` of the whole search; plus ``tasks`` (how many ran).

Same answer as one process: both return an admissible support whose score is within ``tol`` (the
score resolution, 1e-12) of the best admissible score, and both prove it.  When another admissible
support scores within ``tol`` of the winner — a round-off tie — which of the two is returned depends
on the visiting order in either search; otherwise the supports are the same.

Scaling to N machines: start a scheduler (``dask scheduler``) and ``dask worker tcp://host:8786``
on each machine, then ``lsindy identify --scheduler tcp://host:8786`` (``client=`` in Python).  What
travels, once per worker: the Gram matrix and the triangular factor the candidates are fitted on
(p² floats each: 0.7 MB for 209 terms, whatever the number of samples) and the admissibility
rules' state — the kinetic Hessians at ≤ 400 states (s·n²·p floats: 2.7 MB for the double
pendulum) and the balance the jackknife refits (per-sample rows, unless the balance was streamed
into R factors, :mod:`lsindy_cas.identify.stream`).  Per task: its nodes (a few hundred bytes
each) and back its open nodes, its best 2,000 scores and 200 candidates.  The work divides by ~N
while tasks run well above their overhead (benchmarks/bench_dask.py measures it: a round trip of
tens of ms on one machine, a network adds its own) and while there are open nodes for every
worker: the frontier grows with the search, but a search whose proof hangs on a few deep subtrees
goes no faster than the worker holding them, one task-length at a time.  What does not divide: the
warm-up and the final refit (driver), and the order of discovery — a worker may expand a subtree
that one process would have pruned with an incumbent it found first, so the nodes summed over
workers can exceed one process's, more so with more workers and a late incumbent (measured on 2
workers: 0.5–1.6× one process's nodes).  The driver handles every task's result, so with very
many workers it becomes the bottleneck: lengthen ``task_seconds`` to keep it below one result per
few milliseconds.
"""
from __future__ import annotations

import heapq
import time
import uuid

import numpy as np

from .._validate import check_real
from . import findings as F
from .bnb import RUNNERS_UP, SCORE_RESOLUTION, BnbSearch, branch_and_bound, structure_of
from .bnb_drive import EXAMINE_COST, check_inputs, drive, nothing_admissible
from .findings import code_of
from .fitting import coef_on_support
from .search import Candidate, SearchResult

__all__ = ["branch_and_bound_distributed", "WARMUP", "TASK_SECONDS"]

WARMUP = 0.5          # seconds of the ordinary search on the driver before any task
TASK_SECONDS = 1.0    # a task hands its open nodes back after this long (overhead ~1-3 %)
SYNC_EVERY = 0.25     # seconds between a task's reads of the shared incumbent (a read: ~10-30 ms)
FRONTIER = 4          # open nodes per worker in each tree before the first tasks go out
_KEEP = 200           # candidates a task returns (the best-scoring ones: what diagnostics read)
_clock = time.monotonic   # the driver's clock (a test replaces it; the workers keep their own)


def _template(tree: BnbSearch) -> BnbSearch:
    """What the workers need of a started tree: no open nodes, no records, no per-sample data."""
    t = tree.clone()
    t.seen, t.candidates, t.heap, t.counter = set(), [], [], 0
    t.incumbent, t.winner, t.null_dim = np.inf, None, 0
    t.A = None                                   # fitted on Af (the p × p factor) instead
    if t.b is not None:
        t.b = np.zeros(0)                        # only "driven or not" is read once started
    return t


def _run_task(templates, which, entries, incumbent, var_name, seconds):
    """Worker: the ordinary search on ``entries`` (heap entries of tree ``which``) for ``seconds``.

    Returns a dict of the task's winner, records and the entries it left open.
    """
    from distributed import Variable
    s = templates[which].clone()                 # the scattered template stays untouched
    s.seen, s.candidates = set(), []
    s.heap = [(key, i, node) for i, (key, node) in enumerate(entries)]
    heapq.heapify(s.heap)
    s.counter = len(s.heap)
    s.incumbent, s.winner, s.null_dim = incumbent, None, 0
    var = Variable(var_name)
    t0 = time.monotonic()
    end = t0 + seconds
    state = "open"
    while True:
        try:
            shared = float(var.get(timeout=1))
        except Exception:                        # noqa: BLE001 - a slow scheduler only prunes less
            shared = np.inf
        if shared == -np.inf:
            # the driver's stop signal (proven elsewhere, time limit, Ctrl-C), not an incumbent:
            # pruning with it would empty the heap and make a stopped tree look exhausted
            break
        if s.winner is not None and s.winner.score < shared:
            var.set(float(s.winner.score))       # publish (again, if another task overwrote it)
        s.incumbent = min(s.incumbent, shared)
        state = s.advance(min(end, time.monotonic() + SYNC_EVERY))
        if state != "open" or time.monotonic() >= end:
            break
    if s.winner is not None:
        var.set(float(min(s.winner.score, _safe_get(var))))
    if s.pool_S:
        s._trim_pool()
    cands = sorted(s.candidates, key=lambda c: c.score)
    return {"winner": s.winner, "null_dim": s.null_dim,
            "candidates": cands[:_KEEP], "pool": (s.pool_S[0], s.pool_s[0]) if s.pool_S else None,
            "counts": [s.n_leaves, s.n_degenerate, s.nodes, s.n_examined, s.n_reducible],
            "lower_pruned": s.lower_pruned, "open": [(key, node) for key, _, node in s.heap],
            "full": state == "full", "seconds": time.monotonic() - t0}


def _safe_get(var):
    try:
        return float(var.get(timeout=1))
    except Exception:                            # noqa: BLE001
        return np.inf


def _better(cand, best) -> bool:
    """The winner rule: lower score, exact ties by the smaller support (independent of timing)."""
    return best is None or (cand.score, cand.support) < (best.score, best.support)


def branch_and_bound_distributed(client, A, b, k, forced=(), *, admissible=None, D=None,
                                 scale_system=None, time_limit=None, tol=SCORE_RESOLUTION,
                                 n_report=10, progress=None, structure=None, screen="auto",
                                 warmup=None, task_seconds=None, work_limit=None) -> SearchResult:
    """:func:`~lsindy_cas.identify.bnb.branch_and_bound` with the subtrees searched on ``client``.

    Parameters
    ----------
    client : distributed.Client
        A client of a running cluster (:func:`lsindy_cas.identify.distributed.connect`).
    A, b, k, forced, admissible, D, scale_system, time_limit, tol, n_report, progress, structure
        As for :func:`~lsindy_cas.identify.bnb.branch_and_bound`.
    work_limit : float, optional
        As for :func:`~lsindy_cas.identify.bnb.branch_and_bound`, summed over the driver and the
        tasks merged so far (tasks out finish their slice: the stopping point is not exact).
    screen : {"auto", True, False, "l1"}
        The trees, as for :func:`~lsindy_cas.identify.bnb.branch_and_bound` ("auto": the library,
        basis-pursuit and screening orders, sharing the incumbent; otherwise that one order).
    warmup : float, optional
        Seconds of the ordinary search on the driver first (≥ 0; a problem proven within them
        never uses the cluster; default ``WARMUP``).
    task_seconds : float, optional
        How long a task runs before it hands its open nodes back (> 0; default ``TASK_SECONDS``).

    Returns
    -------
    SearchResult
        As :func:`~lsindy_cas.identify.bnb.branch_and_bound`'s (``method="bnb"``, ``proven``,
        ``gap``, ``nodes`` over the driver and all tasks, ``seconds``), plus ``tasks``.
    """
    from .distributed import dask_distributed
    d = dask_distributed()
    m, p = A.shape
    forced, k, time_limit, tol = check_inputs(A, b, D, k, forced, time_limit, tol)
    work_limit = check_real("work_limit", work_limit, positive=True, allow_none=True)
    warmup = WARMUP if warmup is None else check_real("warmup", warmup, nonnegative=True)
    task_seconds = (TASK_SECONDS if task_seconds is None
                    else check_real("task_seconds", task_seconds, positive=True))
    if k == len(forced):
        return branch_and_bound(A, b, k, forced, admissible=admissible, D=D,
                                scale_system=scale_system, n_report=n_report)
    if structure is None:
        structure = structure_of(admissible, p)
    # the trees of branch_and_bound(screen="auto"), built the same way
    s = BnbSearch(A, b, k, forced, admissible, D, scale_system, tol, n_report, structure, False)
    if screen == "auto":
        trees = [s.start(False)] + [t for t in (s.clone().start("l1") if b is not None else None,
                                                s.clone().start(True)) if t is not None]
    else:
        trees = [s.start(screen if screen == "l1" else bool(screen))]
        if trees[0] is None:
            raise ValueError("the basis-pursuit order needs driven data (b) and a solvable "
                             "linear programme")
    t0 = _clock()
    deadline = np.inf if time_limit is None else t0 + time_limit
    run = _Run(client, d, trees, tol, deadline, progress, t0, work_limit)
    try:
        if warmup > 0:
            run.warm(min(warmup, time_limit or np.inf))
        if not run.stopped():
            run.frontier(FRONTIER * max(1, len(client.scheduler_info().get("workers", {}))))
        if not run.stopped():
            run.distribute(task_seconds)
    except KeyboardInterrupt:
        run.interrupted = True
        run.drain()
    return run.result(A, b, k, scale_system, n_report)


class _Run:
    """The driver's state of one distributed search."""

    def __init__(self, client, d, trees, tol, deadline, progress, t0, work_limit=None):
        self.client, self.d, self.trees, self.tol = client, d, trees, tol
        self.work_limit = np.inf if work_limit is None else work_limit
        self.deadline, self.progress, self.t0 = deadline, progress, t0
        self.best, self.null_dim = None, 0
        self.candidates, self.pools = [], []
        self.counts = np.zeros(5, dtype=np.int64)
        self.out = {}                      # future -> (tree index, smallest bound sent)
        self.interrupted = self.full = False
        self.tasks, self.told = 0, False
        self.busy = [0.0] * len(trees)      # worker seconds spent on each tree
        self.var = None                     # the shared incumbent (distributed.Variable)
        # without a warm-up the first round of tasks goes out even past the time limit (one
        # process, too, expands a node before it looks at the clock)
        self.grace = True

    @property
    def incumbent(self) -> float:
        return np.inf if self.best is None else self.best.score

    def _adopt(self, cand, null_dim):
        if cand is not None and _better(cand, self.best):
            self.best, self.null_dim = cand, null_dim
        for t in self.trees:
            t.incumbent, t.winner, t.null_dim = self.incumbent, self.best, self.null_dim

    def work(self) -> float:
        """Work of the driver's trees and the tasks merged (bnb_drive units)."""
        return (float(self.counts[2] + EXAMINE_COST * self.counts[3])
                + sum(t.work for t in self.trees))

    def stopped(self) -> bool:
        """A tree exhausted (proven), interrupted, out of time, work or memory."""
        return (self.interrupted or self.full or (_clock() > self.deadline and not self.grace)
                or self.work() >= self.work_limit
                or any(self._exhausted(i) for i in range(len(self.trees))))

    def _exhausted(self, i) -> bool:
        t = self.trees[i]
        return not t.heap and not t.queue and not any(w == i for w, _ in self.out.values())

    def warm(self, seconds):
        """The ordinary search on the driver (bnb_drive.drive: the trees in turn)."""
        limit = None if not np.isfinite(self.work_limit) else self.work_limit
        *_, interrupted = drive(self.trees, seconds, self.progress, work_limit=limit)
        self.interrupted, self.grace = interrupted, False
        self._adopt(self.trees[0].winner, self.trees[0].null_dim)

    def frontier(self, target):
        """Expand each tree best-first on the driver until it has ``target`` open nodes."""
        for t in self.trees:
            while t.heap and len(t.heap) < target and not self.stopped():
                state = t.advance(-np.inf)          # one node (the clock is always past -inf)
                self._adopt(t.winner, t.null_dim)
                if state == "full":
                    self.full = True

    def distribute(self, task_seconds):
        d, client = self.d, self.client
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        templates = [_template(t) for t in self.trees]
        tmpl, = client.scatter([templates], broadcast=True)     # one object: shared arrays once
        self.var = d.Variable(f"lsindy-bnb-{uuid.uuid4().hex}", client=client)
        self.var.set(float(self.incumbent))
        self.ac = d.as_completed()
        try:
            while True:
                if self.stopped() and self.out and not self.told:
                    self.var.set(-np.inf)     # proven: the tasks out stop at their next read
                    self.told = True
                while len(self.out) < 2 * n_workers and not self.stopped():
                    # the tree with the least worker time so far (tasks out count in full), as
                    # one process gives the trees equal time slices
                    busy = [self.busy[i] + task_seconds * sum(w == i for w, _ in self.out.values())
                            for i in range(len(self.trees))]
                    if not any(self._submit(tmpl, i, n_workers, task_seconds)
                               for i in np.argsort(busy, kind="stable").tolist()):
                        break
                self.grace = False
                if not self.out:
                    break
                fut = next(self.ac)
                self._merge(fut)
                self._report()
        except KeyboardInterrupt:
            self.interrupted = True
            if self.var is not None:
                self.var.set(-np.inf)         # the tasks out stop at their next read
        finally:
            self.drain()
            if self.var is not None:
                self.var.delete()

    def _submit(self, tmpl, i, n_workers, task_seconds) -> bool:
        t = self.trees[i]
        take = max(1, -(-len(t.heap) // (2 * n_workers)))
        entries = []
        while t.heap and len(entries) < take:
            key, _, node = heapq.heappop(t.heap)
            if node.bound >= self.incumbent - self.tol:
                t.lower_pruned = min(t.lower_pruned, node.bound)
                continue
            entries.append((key, node))
        if not entries:
            return False
        seconds = min(task_seconds, max(0.05, self.deadline - _clock()))
        fut = self.client.submit(_run_task, tmpl, i, entries, float(self.incumbent),
                                 self.var.name, seconds, pure=False)
        self.out[fut] = (i, min(n.bound for _, n in entries))
        self.ac.add(fut)
        self.tasks += 1
        return True

    def _merge(self, fut):
        i, _ = self.out.pop(fut)
        r = fut.result()
        t = self.trees[i]
        for key, node in r["open"]:
            heapq.heappush(t.heap, (key, t.counter, node))
            t.counter += 1
        t.lower_pruned = min(t.lower_pruned, r["lower_pruned"])
        self.counts += r["counts"]
        self.candidates += r["candidates"]
        if r["pool"] is not None:
            self.pools.append(r["pool"])
        self.full |= r["full"]
        self.busy[i] += r["seconds"]
        self._adopt(r["winner"], r["null_dim"])

    def drain(self):
        """Wait for the tasks still out (their winners count) and merge them."""
        while self.out:
            fut = next(iter(self.out))
            try:
                fut.result()
            except KeyboardInterrupt:
                self.interrupted = True
                continue
            self._merge(fut)

    def lower(self) -> float:
        """Largest over trees of the smallest bound left in the tree (open, out, or pruned)."""
        out = [min([self.trees[i].lower()] + [bd for w, bd in self.out.values() if w == i])
               for i in range(len(self.trees))]
        return max(out)

    def _report(self):
        if self.progress is None:
            return
        inc, lower = self.incumbent, self.lower()
        gap = max(0.0, inc - lower) if np.isfinite(inc) else float("inf")
        self.progress(int(self.counts[2]) + sum(t.nodes for t in self.trees), 0)
        status = getattr(self.progress, "status", None)
        if status is not None:
            status(f"gap {gap:.2e}, best {inc:.3e}, {_clock() - self.t0:.1f} s, "
                   f"{len(self.out)} tasks out")

    def result(self, A, b, k, scale_system, n_report) -> SearchResult:
        """The SearchResult, assembled as branch_and_bound assembles it."""
        trees, s = self.trees, self.trees[0]
        proven = any(self._exhausted(i) for i in range(len(trees))) and not self.interrupted \
            and not self.full
        seconds = _clock() - self.t0
        counts = self.counts + np.array([sum(getattr(t, n) for t in trees) for n in
                                         ("n_leaves", "n_degenerate", "nodes", "n_examined",
                                          "n_reducible")])
        n_leaves, n_degenerate, nodes, _, n_reducible = (int(x) for x in counts)
        w = self.best
        if w is None and self.interrupted:
            raise KeyboardInterrupt
        if w is None:
            raise nothing_admissible(k, s.candidates + self.candidates, proven, seconds, nodes,
                                     n_leaves, self.work())
        lower = self.lower()
        pool_S = [x for t in trees for x in t.pool_S] + [P[0] for P in self.pools]
        pool_s = [x for t in trees for x in t.pool_s] + [P[1] for P in self.pools]
        sup, sc = np.vstack(pool_S), np.concatenate(pool_s)
        keep = np.argsort(sc, kind="stable")[:RUNNERS_UP]
        sup, sc = sup[keep], sc[keep]
        null_dim = self.null_dim
        coef, nd = coef_on_support(A, b, w.support, scale_system)     # as one process
        if coef is not None:
            w.coef, null_dim = coef, nd
        cands, seen = [], set()
        reducible_kept = 0
        for c in sorted(s.candidates + self.candidates, key=lambda c: c.score):
            if c.support in seen:
                continue
            if code_of(c.reason) == F.REDUCIBLE:
                if reducible_kept >= n_report:
                    continue
                reducible_kept += 1
            seen.add(c.support)
            cands.append(w if c.support == w.support else c)
        runners = [Candidate(tuple(int(j) for j in S), float(v)) for S, v in zip(sup, sc)
                   if tuple(int(j) for j in S) not in seen][:n_report]
        res = SearchResult(w.support, w.coef, w.score, cands + runners, n_leaves, n_degenerate,
                           null_dim, sc, sup, n_reducible)
        res.method, res.proven, res.interrupted = "bnb", proven, self.interrupted
        res.gap = max(0.0, w.score - lower)
        res.nodes, res.seconds, res.tasks, res.work = nodes, seconds, self.tasks, self.work()
        return res
