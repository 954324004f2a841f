"""Best-subset search: enumeration, batched scores = per-subset least squares, degeneracy."""
import itertools

import numpy as np
import pytest

from lsindy_cas.identify.search import best_subset, combinations, score_all


@pytest.mark.parametrize("n, r", [(5, 0), (5, 1), (7, 3), (9, 4), (6, 6), (3, 4)])
def test_combinations_match_itertools(n, r):
    expected = np.array(list(itertools.combinations(range(n), r)), dtype=np.int64)
    expected = expected.reshape(len(expected), r)
    np.testing.assert_array_equal(combinations(n, r), expected)


@pytest.mark.parametrize("k, forced", [(1, ()), (2, ()), (3, ()), (3, (4,)), (4, (0, 7))])
def test_batched_scores_equal_lstsq(rng, k, forced):
    A = rng.normal(size=(60, 10)) * rng.uniform(0.1, 100, size=10)   # badly scaled columns
    b = rng.normal(size=60)
    supports, scores, degenerate = score_all(A, b, k, forced)
    assert not degenerate.any()
    assert len(supports) == len(list(itertools.combinations(range(10 - len(forced)), k - len(forced))))
    for S, s in zip(supports, scores):
        assert set(forced) <= set(S)
        x, *_ = np.linalg.lstsq(A[:, S], b, rcond=None)
        rel = np.sum((A[:, S] @ x - b) ** 2) / np.sum(b**2)
        assert s == pytest.approx(rel, rel=1e-9, abs=1e-12)


def test_limiting_case_all_columns_is_least_squares(rng):
    """k = p: the only support is everything and its coefficients are the least-squares solution."""
    A = rng.normal(size=(40, 5))
    b = rng.normal(size=40)
    res = best_subset(A, b, 5)
    np.testing.assert_allclose(res.coef, np.linalg.lstsq(A, b, rcond=None)[0], rtol=1e-10)


def test_exact_sparse_support_recovered(rng):
    A = rng.normal(size=(200, 30))
    xi = np.zeros(30)
    xi[[3, 11, 27]] = [1.5, -0.2, 40.0]
    res = best_subset(A, A @ xi, 3)
    np.testing.assert_array_equal(res.support, [3, 11, 27])
    np.testing.assert_allclose(res.coef, xi, rtol=1e-10, atol=1e-12)


def test_collinear_supports_flagged_not_crashing():
    """sin²·u, cos²·u and u are dependent (trig identity); the triple is degenerate, pairs are not."""
    t = np.linspace(0, 3, 300)
    u = np.exp(-t) + t
    A = np.column_stack([np.sin(t) ** 2 * u, np.cos(t) ** 2 * u, u, np.cos(3 * t)])
    b = 2 * u + 0.5 * np.cos(3 * t)
    supports, scores, degenerate = score_all(A, b, 3)
    flagged = {tuple(S) for S, d in zip(supports, degenerate) if d}
    assert flagged == {(0, 1, 2)}
    res = best_subset(A, b, 2)
    np.testing.assert_array_equal(res.support, [2, 3])


def test_validation():
    A = np.ones((10, 3))
    with pytest.raises(ValueError, match="n_terms"):
        best_subset(A, np.ones(10), 4)
    with pytest.raises(ValueError, match="prior"):
        best_subset(A, np.ones(10), 1, forced=(0, 1))
