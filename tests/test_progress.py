"""The progress bar: silent when quick, ETA when slow, a clean line on Ctrl-C."""
import io

import numpy as np
import pytest

from lsindy_cas.progress import ProgressBar, format_count, format_seconds
from lsindy_cas.identify.search import best_subset


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_formats():
    assert format_seconds(75.4) == "1:15" and format_seconds(3725) == "1:02:05"
    assert format_count(999) == "999" and format_count(25_000) == "25k"
    assert format_count(1_234_567) == "1.2M"


def test_quick_work_shows_nothing():
    out, clock = io.StringIO(), Clock()
    with ProgressBar("searching", stream=out, force=True, clock=clock, delay=0.5) as bar:
        clock.now = 0.1
        bar(100, 100)
    assert out.getvalue() == ""


def test_slow_work_shows_an_eta_and_finishes_the_line():
    out, clock = io.StringIO(), Clock()
    with ProgressBar("searching", stream=out, force=True, clock=clock, delay=0.5) as bar:
        clock.now = 2.0
        bar(250, 1000)                   # 2 s for a quarter: 6 s to go
        assert "25%" in out.getvalue() and "ETA 0:06" in out.getvalue()
        clock.now = 8.0
        bar(1000, 1000)
    text = out.getvalue()
    assert text.endswith("\n") and "done in 0:08" in text
    assert text.count("\n") == 1         # redrawn in place with carriage returns


def test_not_a_terminal_means_no_bar():
    out = io.StringIO()                  # StringIO.isatty() is False
    bar = ProgressBar(stream=out, delay=0)
    bar(1, 2)
    assert out.getvalue() == "" and not bar.enabled


def test_ctrl_c_ends_the_line_with_a_message():
    out, clock = io.StringIO(), Clock()
    with pytest.raises(KeyboardInterrupt):
        with ProgressBar("searching", stream=out, force=True, clock=clock, delay=0.5) as bar:
            clock.now = 1.0
            bar(300, 1000)
            raise KeyboardInterrupt
    last = out.getvalue().split("\r")[-1]
    assert last.startswith("searching: interrupted after 300/1000") and last.endswith("\n")


def test_ctrl_c_says_so_even_before_the_bar_appears():
    out = io.StringIO()
    with pytest.raises(KeyboardInterrupt):
        with ProgressBar("searching", stream=out):
            raise KeyboardInterrupt
    assert out.getvalue() == "searching: interrupted\n"


def test_drives_the_subset_search(rng):
    A = rng.standard_normal((50, 12))
    b = A[:, [1, 4]] @ [2.0, -1.0]
    calls = []
    bar = ProgressBar(stream=io.StringIO(), force=True, delay=0)
    result = best_subset(A, b, 2, progress=lambda d, n: (calls.append((d, n)), bar(d, n)))
    assert result.support == (1, 4)
    assert calls and calls[-1][0] == calls[-1][1]
    assert bar.n_done == bar.n_total == calls[-1][1]
    np.testing.assert_allclose(result.coef[[1, 4]], [2.0, -1.0], rtol=1e-10)
