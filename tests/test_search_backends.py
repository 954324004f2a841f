"""The search backends are interchangeable strategies: the same problem searched exhaustively, by
branch and bound, by the automatic scan's beam, in process or on a Dask cluster, gives the same
support and coefficients.  The Dask cases start a two-worker local cluster (skipped without the
``dask`` extra)."""
import numpy as np
import pytest

from lsindy_cas.identify import selection
from lsindy_cas.identify.bnb import branch_and_bound
from lsindy_cas.identify.search import best_subset, score_all
from lsindy_cas.identify.selection import select
from test_selection import _synthetic


@pytest.fixture(scope="module")
def dask_backend():
    pytest.importorskip("distributed", reason="the dask extra is not installed")
    from lsindy_cas.identify.backend import DaskBackend
    from lsindy_cas.identify.distributed import connect
    client = connect("local", 2)
    yield DaskBackend(client)
    client.close()
    client.cluster.close()


def _strategies(request):
    return request.param


@pytest.fixture(params=["process", "dask"])
def backend(request):
    return None if request.param == "process" else request.getfixturevalue("dask_backend")


@pytest.mark.parametrize("method", ["exhaustive", "bnb", "beam"])
def test_every_search_and_backend_gives_the_same_model(rng, monkeypatch, backend, method):
    """Known answer: b = A[:, :3] (1, -2, 0.5) + noise; the reference is the exhaustive search in
    process.  Coefficients to 1e-10 relative: the same least squares, fitted through different
    Gram matrices (normal equations against QR), round-off ~1e-13."""
    bal = _synthetic(rng)
    ref = select(bal, [], n_terms=3)
    assert ref.support == (0, 1, 2)
    if method == "bnb":
        monkeypatch.setattr(selection, "EXHAUSTIVE", 0)          # branch and bound at fixed k
        got = select(bal, [], n_terms=3, backend=backend)
        assert got.search.method == "bnb" and got.search.proven
    elif method == "beam":
        monkeypatch.setattr(selection, "EXHAUSTIVE", 0)          # the automatic scan's beam
        got = select(bal, [], backend=backend)
        assert got.k == 3
    else:
        got = select(bal, [], n_terms=3, backend=backend)
        assert got.search.method == "exhaustive"
    assert got.support == ref.support
    np.testing.assert_allclose(got.coef, ref.coef, rtol=1e-10, atol=1e-14)


def test_backends_score_the_same_supports(rng, backend):
    """score_all through a backend: the same supports in the same order, scores to round-off."""
    A, b = rng.normal(size=(60, 9)), rng.normal(size=60)
    ref = score_all(A, b, 3, [1])
    got = score_all(A, b, 3, [1]) if backend is None else backend.score_all(A, b, 3, [1])
    np.testing.assert_array_equal(got[0], ref[0])                # supports: integers
    np.testing.assert_allclose(got[1], ref[1], rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(got[2], ref[2])                # degeneracy flags


def test_branch_and_bound_through_a_backend(rng, backend):
    A = rng.normal(size=(80, 12))
    b = A[:, [2, 5, 7]] @ np.array([1.0, -1.0, 2.0]) + 1e-3 * rng.normal(size=80)
    run = branch_and_bound if backend is None else backend.branch_and_bound
    res = run(A, b, 3)
    assert res.support == (2, 5, 7) and res.proven
    assert best_subset(A, b, 3).support == res.support
