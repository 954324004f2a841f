"""The exhaustive support search on a Dask cluster (optional extra ``dask[distributed]``).

The support tree of :mod:`lsindy_cas.identify.subset_tree` splits into independent subtrees by the
first free column of a support: subtree i holds every support whose smallest free column is
``free[i]`` — the tree of ``forced + [free[i]]`` over ``free[i+1:]``.  Each task scores a group of
subtrees (groups balanced by their number of supports) on the normalised Gram matrix, which is
scattered to the workers once; the driver concatenates the groups in order, so the supports and
their order are those of the single-process search and their scores agree to round-off (see
:func:`subtree_scores`), and the best-first visit that follows runs on the driver unchanged.  Passive data (scored
by the smallest eigenvalue per support) are split into chunks of supports the same way.

Use it with ``LagrangianSINDy(...).fit(..., client=...)`` or ``lsindy identify --scheduler
ADDRESS|local``; in code, :class:`~lsindy_cas.identify.backend.DaskBackend` is the search
*backend* handed to
:func:`~lsindy_cas.identify.selection.select` (``backend=``), explicitly — there is no ambient
client.  Where the library is too large to score every support, the branch and bound runs on the
same client (:mod:`lsindy_cas.identify.distributed_bnb`: open nodes as tasks, the incumbent shared).

A backend is any object with the two searches of the in-process one:
``score_all(A, b, k, forced, D, progress)`` (as :func:`lsindy_cas.identify.search.score_all`) and
``branch_and_bound(A, b, k, forced, **options)`` (as :func:`lsindy_cas.identify.bnb.branch_and_bound`);
``backend=None`` is in process.

Scaling: the Gram matrix is p² floats (209 terms: 350 kB) whatever the number of samples, so a task
costs its share of the supports and nothing per sample; results travel back as (n, k) int
supports + 2 floats per support (~70 B per support for k = 6), which bounds the useful problem
size by the driver's memory, not the workers'.  With N workers the scoring time divides by ~N
once each task runs well above the per-task overhead (measured in ``benchmarks/bench_dask.py``).
"""
from __future__ import annotations

from math import comb

import numpy as np

from .subset_tree import subtree_scores, subtree_supports

__all__ = ["connect", "score_all_distributed"]

TASKS_PER_WORKER = 4          # subtree groups per worker: enough to balance, few to keep overhead low


def dask_distributed():
    try:
        import distributed
    except ImportError as exc:
        raise ImportError("parallel search needs the optional extra 'dask[distributed]' "
                          "(pip install 'lsindy_cas[dask]')") from exc
    return distributed


def connect(scheduler: str, n_workers: int | None = None, timeout: float = 5.0):
    """A Dask client: ``"local"`` starts a ``LocalCluster`` (``n_workers`` processes, one thread
    each); otherwise ``scheduler`` is the address of a running scheduler (``tcp://host:8786``).

    Raises
    ------
    ValueError
        If the address is not of the form ``tcp://host:port`` / ``local``, or nothing answers
        there within ``timeout`` seconds.
    """
    if not isinstance(scheduler, str) or not scheduler:
        raise TypeError("scheduler must be 'local' or an address such as tcp://127.0.0.1:8786")
    d = dask_distributed()
    if scheduler == "local":
        import os
        n = n_workers or max(1, min(os.cpu_count() or 1, 8))
        cluster = d.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                 dashboard_address=None)
        return d.Client(cluster)
    if "://" not in scheduler:
        raise ValueError(f"scheduler {scheduler!r}: give 'local' or an address such as "
                         f"tcp://127.0.0.1:8786")
    try:
        return d.Client(scheduler, timeout=f"{timeout}s")
    except (OSError, TimeoutError) as exc:
        raise ValueError(f"scheduler {scheduler}: no Dask scheduler answered within {timeout:g} s "
                         f"({type(exc).__name__})") from None


def _groups(sizes: np.ndarray, n_groups: int) -> list:
    """Consecutive runs of subtrees with about equal total size (order kept)."""
    total = sizes.sum()
    if total == 0:
        return []
    cuts = np.searchsorted(np.cumsum(sizes), np.linspace(0, total, n_groups + 1)[1:-1], side="left")
    bounds = np.unique(np.r_[0, cuts + 1, len(sizes)])
    return [np.arange(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


def _passive_chunk(A, b, supports, D):
    from .search import score_supports
    return score_supports(A, b, supports, D)


def score_all_distributed(client, A, b, k, forced=(), D=None, progress=None):
    """:func:`lsindy_cas.identify.search.score_all` with the subtrees scored on ``client``.

    Same returns, in the same order: supports (n, k), scores (n,) (to round-off, see
    :func:`subtree_scores`), degenerate (n,).
    """
    from .fitting import normalise_columns
    from .search import DEGENERACY_TOL
    d = dask_distributed()
    p = A.shape[1]
    forced = sorted(set(int(j) for j in forced))
    free = np.array([j for j in range(p) if j not in set(forced)], dtype=np.int64)
    r = k - len(forced)
    n_tasks = max(1, TASKS_PER_WORKER * len(client.scheduler_info().get("workers", {})))
    supports = subtree_supports(forced, free, k)
    if b is not None:
        if r == 0:
            from .search import score_all
            return score_all(A, b, k, forced, D, progress)
        An, _ = normalise_columns(A)
        G, c, bb = An.T @ An, An.T @ b, float(b @ b)
        sizes = np.array([comb(len(free) - i - 1, r - 1) for i in range(len(free))])
        G_f, c_f = client.scatter([G, c], broadcast=True)
        futures = [client.submit(subtree_scores, G_f, c_f, bb, forced, free, k, grp, pure=False)
                   for grp in _groups(sizes, n_tasks)]
    else:
        A_f = client.scatter(A, broadcast=True)
        D_f = client.scatter(D, broadcast=True) if D is not None else None
        step = max(1, -(-len(supports) // n_tasks))
        futures = [client.submit(_passive_chunk, A_f, b, supports[lo:lo + step], D_f, pure=False)
                   for lo in range(0, len(supports), step)]
    done = 0
    for fut in d.as_completed(futures):
        done += len(fut.result()[0])
        if progress is not None:
            progress(done, len(supports))
    parts = client.gather(futures)                     # in submission order: the global order
    first = np.concatenate([x[0] for x in parts]) if parts else np.zeros(0)
    second = np.concatenate([x[1] for x in parts]) if parts else np.zeros(0)
    if b is not None:
        return supports, first, second < DEGENERACY_TOL
    return supports, first, second
