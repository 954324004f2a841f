"""A progress bar with an estimate of the time left, for long searches (on stderr).

The subset search reports ``progress(n_done, n_total)`` after each batch of supports.  A
:class:`ProgressBar` is such a callable: it stays silent for searches that finish within
``delay`` seconds, and otherwise redraws one line, at most every ``interval`` seconds::

    searching supports  [#########...........]  45%  1.2M/2.7M  ETA 0:14

Used as a context manager it finishes the line when the work ends, and when the user presses
Ctrl-C it ends the line with how far the search got before letting the ``KeyboardInterrupt``
through (the ``lsindy`` command then exits with status 130)::

    with ProgressBar("searching supports") as bar:
        best_subset(A, b, k, progress=bar)
"""
from __future__ import annotations

import sys
import time

__all__ = ["ProgressBar", "format_seconds", "format_count"]


def format_seconds(seconds: float) -> str:
    """``75.4`` -> ``'1:15'``; ``3725`` -> ``'1:02:05'``."""
    s = int(round(max(seconds, 0.0)))
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def format_count(n: int) -> str:
    """``1234`` -> ``'1234'``, ``1_234_567`` -> ``'1.2M'``."""
    for div, unit in ((1e9, "G"), (1e6, "M"), (1e4, "k")):
        if n >= div:
            return f"{n / div:.1f}{unit}" if unit != "k" else f"{n / 1e3:.0f}k"
    return str(n)


class ProgressBar:
    """Callable ``(n_done, n_total)`` drawing a bar with an ETA on a terminal.

    Parameters
    ----------
    label : str
        What is being done ("searching supports").
    stream : file, optional
        Where to draw (default ``sys.stderr``).  Nothing is drawn unless it is a terminal or
        ``force`` is set, so logs and pipes stay clean.
    delay : float
        Seconds of work before the bar appears (short searches show nothing).
    interval : float
        Minimum seconds between redraws.
    width : int
        Characters in the bar itself.
    force : bool
        Draw even when ``stream`` is not a terminal (tests, notebooks).
    clock : callable, optional
        Returns the time in seconds (default ``time.monotonic``); injectable for tests.
    """

    def __init__(self, label: str = "working", *, stream=None, delay: float = 0.5,
                 interval: float = 0.1, width: int = 24, force: bool = False, clock=None):
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        self.delay = float(delay)
        self.interval = float(interval)
        self.width = int(width)
        self.clock = clock or time.monotonic
        isatty = getattr(self.stream, "isatty", None)
        self.enabled = force or bool(isatty and isatty())
        self.start = self.clock()
        self.n_done = 0
        self.n_total = 0
        self._shown = False
        self._last_draw = -float("inf")
        self._last_len = 0

    # ------------------------------------------------------------------ drawing
    def line(self, n_done: int, n_total: int) -> str:
        """The text of the bar for this state (no carriage return)."""
        frac = min(max(n_done / n_total, 0.0), 1.0) if n_total else 0.0
        filled = int(round(frac * self.width))
        elapsed = self.clock() - self.start
        if n_done >= n_total and n_total:
            eta = f"done in {format_seconds(elapsed)}"
        elif n_done > 0:
            eta = f"ETA {format_seconds(elapsed * (n_total - n_done) / n_done)}"
        else:
            eta = "ETA --:--"
        return (f"{self.label}  [{'#' * filled}{'.' * (self.width - filled)}]  {frac:4.0%}  "
                f"{format_count(n_done)}/{format_count(n_total)}  {eta}")

    def _write(self, text: str):
        pad = " " * max(0, self._last_len - len(text))
        self.stream.write("\r" + text + pad)
        self.stream.flush()
        self._last_len = len(text)

    def __call__(self, n_done: int, n_total: int) -> None:
        self.n_done, self.n_total = int(n_done), int(n_total)
        if not self.enabled:
            return
        now = self.clock()
        finished = self.n_total and self.n_done >= self.n_total
        if now - self.start < self.delay and not self._shown:
            return
        if now - self._last_draw < self.interval and not finished:
            return
        self._shown = True
        self._last_draw = now
        self._write(self.line(self.n_done, self.n_total))

    def close(self, message: str | None = None) -> None:
        """End the bar's line (and print ``message`` on it, if given)."""
        if self._shown:
            if message is not None:
                self._write(message)
            self.stream.write("\n")
            self.stream.flush()
            self._shown = False
        elif message is not None and self.enabled:
            self.stream.write(message + "\n")
            self.stream.flush()

    # ------------------------------------------------------------------ context manager
    def __enter__(self) -> "ProgressBar":
        self.start = self.clock()
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is KeyboardInterrupt:
            done = (f" after {format_count(self.n_done)}/{format_count(self.n_total)}"
                    if self.n_total else "")
            # always say so on an interrupt, terminal or not, so the user knows what stopped
            if self._shown:
                self.close(f"{self.label}: interrupted{done}")
            else:
                self.stream.write(f"{self.label}: interrupted{done}\n")
                self.stream.flush()
        elif exc_type is None and self._shown:
            self.close(self.line(self.n_total or self.n_done, self.n_total or self.n_done))
        else:
            self.close()
        return False
