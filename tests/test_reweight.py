"""The re-selection on the noise-weighted balance (identify/reweight.py): its work budget and how
its outcome is recorded.  ``select`` is replaced by a stub so that each outcome of the weighted
search (proven, cut short on the same support, a different support, nothing admissible) is
produced exactly."""
from types import SimpleNamespace

import numpy as np
import pytest

from lsindy_cas.identify import reweight
from lsindy_cas.identify.search import SearchResult
from lsindy_cas.identify.selection import Selection


def _selection(support, method="bnb", proven=True, seconds=2.0, gap=0.0, nodes=10, work=None):
    res = SearchResult(tuple(support), np.zeros(4), 0.1, [], 1, 0)
    res.method, res.proven, res.seconds, res.gap, res.nodes = method, proven, seconds, gap, nodes
    res.work = float(nodes if work is None else work)
    return Selection(len(support), tuple(support), np.zeros(4), res, [], False, [])


@pytest.mark.parametrize("method, work, expected", [
    ("exhaustive", 0.0, None),           # exhaustive again: no budget needed
    ("bnb", 2.0, reweight.MIN_WORK),
    ("bnb", 3e6, 3e6),                   # as much work as the first search did
])
def test_budget(method, work, expected):
    first = _selection((0, 1), method=method, work=work).search
    assert reweight.budget(first) == expected


def _stub(monkeypatch, outcome):
    calls = []

    def fake_select(bal, forced, **kw):
        calls.append(kw)
        if isinstance(outcome, BaseException):
            raise outcome
        return outcome
    monkeypatch.setattr(reweight, "select", fake_select)
    return calls


def test_cut_short_on_the_same_support_keeps_the_first_certificate(monkeypatch):
    sel = _selection((0, 2), seconds=12.0)
    sel.search.work = 3e5
    weighted = _selection((0, 2), proven=False, seconds=12.0, gap=3e-3, nodes=777, work=3e5)
    calls = _stub(monkeypatch, weighted)
    out, changed = reweight.reselect(None, [], sel, scale_system=None, admissible=None,
                                     time_limit=60.0)
    assert calls[0]["time_limit"] == 60.0 and calls[0]["n_terms"] == 2
    assert calls[0]["work_limit"] == 3e5
    assert changed is False and out is sel and out.search.proven
    assert out.search.reweighted == {"proven": False, "gap": 3e-3, "nodes": 777, "seconds": 12.0,
                                     "work": 3e5}


def _balance(rng, support, noise):
    """A driven balance whose b is made of the columns ``support`` plus noise."""
    A = rng.standard_normal((200, 6))
    b = A[:, list(support)].sum(axis=1) + noise * rng.standard_normal(200)
    return SimpleNamespace(A=A, b=b, D=None, passive=False)


def test_cut_short_with_a_better_weighted_support_takes_it(monkeypatch, rng):
    sel = _selection((0, 2))
    weighted = _selection((0, 3), proven=False, gap=1e-3)
    _stub(monkeypatch, weighted)
    bal_w = _balance(rng, (0, 3), 1e-3)          # (0, 3) explains it, (0, 2) does not
    out, changed = reweight.reselect(bal_w, [], sel, scale_system=None, admissible=None)
    assert changed and out is weighted and not out.search.proven
    assert not hasattr(sel.search, "reweighted")


def test_cut_short_with_a_worse_support_keeps_the_first(monkeypatch, rng):
    # measured on the double pendulum (rich, sigma = 1e-2): a weighted search cut short at 24 s
    # had not reached the true support yet and returned a worse one, gap 0.53
    sel = _selection((0, 2), seconds=8.0)
    weighted = _selection((0, 3), proven=False, gap=0.53, nodes=12669)
    _stub(monkeypatch, weighted)
    bal_w = _balance(rng, (0, 2), 1e-3)
    out, changed = reweight.reselect(bal_w, [], sel, scale_system=None, admissible=None)
    assert not changed and out.support == (0, 2) and out.search is sel.search
    assert out.search.proven and out.search.reweighted["gap"] == 0.53


def test_proven_weighted_search_is_used(monkeypatch):
    sel = _selection((0, 2))
    weighted = _selection((0, 2), proven=True, nodes=5)
    _stub(monkeypatch, weighted)
    out, changed = reweight.reselect(None, [], sel, scale_system=None, admissible=None)
    assert not changed and out is weighted and out.search.nodes == 5


@pytest.mark.parametrize("exc", [ValueError("no physically admissible 2-term model"),
                                 KeyboardInterrupt()])
def test_nothing_admissible_or_interrupted_keeps_the_selection(monkeypatch, exc):
    sel = _selection((0, 2))
    _stub(monkeypatch, exc)
    out, changed = reweight.reselect(None, [], sel, scale_system=None, admissible=None)
    assert out is sel and not changed
