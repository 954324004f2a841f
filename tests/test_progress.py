"""The progress bar: silent (and tqdm not imported) when quick, a tqdm bar when slow, a clear
line on Ctrl-C."""
import io
import subprocess
import sys

import numpy as np
import pytest

from lsindy_cas.identify.search import best_subset
from lsindy_cas.progress import ProgressBar


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_quick_work_shows_nothing_and_imports_no_tqdm():
    # "quick" is a clock that does not move (the default delay, 0.5 s, never passes): with the real
    # clock a process descheduled for 0.5 s on a loaded machine would draw the bar
    code = ("import io, sys; from lsindy_cas.progress import ProgressBar\n"
            "out = io.StringIO()\n"
            "with ProgressBar('s', stream=out, force=True, clock=lambda: 0.0) as bar:"
            " bar(100, 100)\n"
            "assert out.getvalue() == '', out.getvalue()\n"
            "assert 'tqdm' not in sys.modules\n")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_slow_work_shows_a_bar_and_finishes_the_line():
    out, clock = io.StringIO(), Clock()
    with ProgressBar("searching", stream=out, force=True, clock=clock, delay=0.5,
                     interval=0, unit="supports") as bar:
        clock.now = 2.0
        bar(250, 1000)
        assert "searching:  25%" in out.getvalue()
        bar(1000, 1000)
    text = out.getvalue()
    assert "100%" in text and "1.00k/1.00k" in text and text.endswith("\n")


def test_not_a_terminal_means_no_bar():
    out = io.StringIO()                  # StringIO.isatty() is False
    bar = ProgressBar(stream=out, delay=0)
    bar(1, 2)
    assert out.getvalue() == "" and not bar.enabled and not bar.shown


def test_ctrl_c_ends_the_line_with_a_message():
    out, clock = io.StringIO(), Clock()
    with pytest.raises(KeyboardInterrupt):
        with ProgressBar("searching", stream=out, force=True, clock=clock, delay=0.5) as bar:
            clock.now = 1.0
            bar(300, 1000)
            raise KeyboardInterrupt
    assert out.getvalue().endswith("searching: interrupted after 300/1,000\n")


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
    bar.close()
    assert result.support == (1, 4)
    assert calls and calls[-1][0] == calls[-1][1]
    assert bar.n_done == bar.n_total == calls[-1][1]
    np.testing.assert_allclose(result.coef[[1, 4]], [2.0, -1.0], rtol=1e-10)


def test_branch_and_bound_shows_nodes_and_gap(rng):
    """Unknown total: the bar counts nodes and shows the gap after them."""
    from lsindy_cas.identify.bnb import branch_and_bound
    out, clock = io.StringIO(), Clock()
    clock.now = 10.0                     # past the delay from the first report on
    A, b = rng.normal(size=(40, 14)), rng.normal(size=40)
    with ProgressBar("branch and bound", stream=out, force=True, clock=clock, delay=0.5,
                     interval=0, unit="nodes") as bar:
        bar.start = 0.0
        res = branch_and_bound(A, b, 3, progress=bar)
    text = out.getvalue()
    assert f"{float(res.nodes):.1f}nodes" in text and "gap 0.00e+00" in text
    assert bar.n_done == res.nodes and bar.text.startswith("gap")
