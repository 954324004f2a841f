"""Search backends: where the support searches run, passed explicitly as ``backend=`` to
:func:`~lsindy_cas.identify.selection.select` (``None``: in this process).

A backend is any object with the two searches of the in-process one —
``score_all(A, b, k, forced, D, progress)`` (as :func:`lsindy_cas.identify.search.score_all`) and
``branch_and_bound(A, b, k, forced, **options)`` (as :func:`lsindy_cas.identify.bnb.branch_and_bound`)
— returning the same results.  :class:`DaskBackend` runs both on a Dask cluster
(:mod:`~lsindy_cas.identify.distributed`, :mod:`~lsindy_cas.identify.distributed_bnb`);
``tests/test_search_backends.py`` holds every backend and search method to the same answers.
"""
from __future__ import annotations

from .distributed import score_all_distributed
from .distributed_bnb import branch_and_bound_distributed

__all__ = ["DaskBackend"]


class DaskBackend:
    """The support searches on a Dask cluster: the backend to pass as ``backend=`` (module notes).
    Same supports and scores as in process (to round-off) and the same winners."""

    name = "dask"

    def __init__(self, client):
        self.client = client

    def score_all(self, A, b, k, forced=(), D=None, progress=None):
        return score_all_distributed(self.client, A, b, k, forced, D, progress)

    def branch_and_bound(self, A, b, k, forced=(), **options):
        return branch_and_bound_distributed(self.client, A, b, k, forced, **options)
