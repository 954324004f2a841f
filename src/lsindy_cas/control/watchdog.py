"""A time limit on calls that may never return: the call runs in a worker thread, and the
caller stops waiting after ``limit`` seconds.

CasADi releases the GIL while a solver runs, so the caller keeps running while the worker
solves.  A call past its limit is abandoned, not killed (Python cannot stop a thread): its worker
is dropped and the next call gets a new one.  If the abandoned call does finish later, its
result is discarded and its worker waits, idle, on a queue nobody fills; if it never finishes,
the thread keeps spinning until the process exits (it is a daemon) -- a lost core rather than a
controller that hangs.
:class:`~lsindy_cas.control.shooting.MultipleShootingNLP` uses it for fatrop, whose linear
solver has looped without end from a bad guess.
"""

from __future__ import annotations

import queue
import threading

__all__ = ["Watchdog"]


class Watchdog:
    """Run calls in a worker thread with a time limit.

    Parameters
    ----------
    limit : float
        Seconds to wait for a call before abandoning it.

    Attributes
    ----------
    n_abandoned : int
        Calls abandoned so far.
    """

    def __init__(self, limit):
        self.limit = float(limit)
        if not self.limit > 0:
            raise ValueError(f"limit must be > 0 seconds, got {limit!r}.")
        self.n_abandoned = 0
        self._jobs = None

    def _worker(self, jobs):
        while True:
            fn, kwargs, box, done = jobs.get()
            try:
                box["value"] = fn(**kwargs)
            except BaseException as exc:  # noqa: BLE001 - re-raised in the caller
                box["error"] = exc
            done.set()

    def call(self, fn, **kwargs):
        """``fn(**kwargs)`` in the worker thread.

        Returns
        -------
        finished : bool
            False if the call was abandoned after :attr:`limit` seconds.
        value
            What ``fn`` returned (None if abandoned).

        Raises whatever ``fn`` raised.
        """
        if self._jobs is None:
            self._jobs = queue.SimpleQueue()
            threading.Thread(target=self._worker, args=(self._jobs,), daemon=True,
                             name="lsindy-watchdog").start()
        box, done = {}, threading.Event()
        self._jobs.put((fn, kwargs, box, done))
        if not done.wait(self.limit):
            self._jobs = None  # the next call starts a new worker
            self.n_abandoned += 1
            return False, None
        if "error" in box:
            raise box["error"]
        return True, box["value"]
