"""Branch and bound: every bound against brute force, the same answer as the exhaustive search,
the certificate, the time limit and bad input."""
import itertools

import numpy as np
import pytest

from lsindy_cas.identify.bnb import _Node, BnbSearch, branch_and_bound, screening_order
from lsindy_cas.identify.search import best_subset


def _problem(rng, m, p, passive):
    A = rng.normal(size=(m, p)) * rng.uniform(0.1, 10, p)          # badly scaled columns
    if passive:                                                     # a sparse near-null vector
        A[:, 2] = A[:, 0] * 0.7 - A[:, 4] * 1.3 + 1e-3 * rng.normal(size=m)
        return A, None, A
    return A, rng.normal(size=m), None


def _brute(search: BnbSearch, S):
    """Score of support S from scratch: least-squares relative residual, or λ_min of Ĝ_S."""
    S = list(S)
    if search.b is None:
        return np.linalg.eigvalsh(search.G[np.ix_(S, S)])[0]
    An = search.A[:, S] / np.linalg.norm(search.A[:, S], axis=0)
    x = np.linalg.lstsq(An, search.b, rcond=None)[0]
    return np.sum((An @ x - search.b) ** 2) / search.bb


@pytest.mark.parametrize("screen", [False, True])
@pytest.mark.parametrize("passive", [False, True])
@pytest.mark.parametrize("seed", range(4))
def test_every_child_bound_is_below_every_support_in_its_subtree(passive, seed, screen):
    rng = np.random.default_rng(seed)
    A, b, D = _problem(rng, 30, 9, passive)
    k, forced = 4, [int(rng.integers(9))] if seed % 2 else []
    s = BnbSearch(A, b, k, forced, None, D, None, 0.0, 5).start(screen)
    order = s.order
    # expand the root and one child, and check each child's bound against all of its leaves
    nodes = s.children(_Node((), 0.0, 1.0), batch=False)
    nodes += s.children(nodes[0], batch=False)
    for ch in nodes:
        left = s.r - len(ch.pos)
        allowed = range(ch.pos[-1] + 1, len(order))
        fixed = forced + [int(order[j]) for j in ch.pos]
        best = min(_brute(s, fixed + [int(order[j]) for j in T])
                   for T in itertools.combinations(allowed, left))
        assert ch.bound <= best + 1e-12


@pytest.mark.parametrize("passive", [False, True])
def test_same_support_as_exhaustive_on_random_problems(passive):
    rng = np.random.default_rng(7)
    for _ in range(25):
        m, p = int(rng.integers(10, 40)), int(rng.integers(5, 12))
        k = int(rng.integers(2, min(p, 5) + 1))
        A, b, D = _problem(rng, m, p, passive)
        forced = sorted(rng.choice(p, int(rng.integers(0, 2)), replace=False).tolist())
        ex = best_subset(A, b, k, forced, D=D)
        bb = branch_and_bound(A, b, k, forced, D=D)
        assert bb.support == ex.support
        assert bb.score == pytest.approx(ex.score, rel=1e-8, abs=1e-14)
        np.testing.assert_allclose(bb.coef, ex.coef, rtol=1e-10, atol=1e-12)
        assert bb.proven and bb.method == "bnb" and bb.gap <= 1e-12 and bb.nodes >= 1


def test_admissibility_respected_best_admissible_wins(rng):
    """Reject the exhaustive winner: both searches must agree on the best support that passes."""
    A = rng.normal(size=(50, 10))
    b = A[:, [1, 4, 7]] @ np.array([1.0, -2.0, 0.5]) + 0.01 * rng.normal(size=50)
    banned = {(1, 4, 7)}

    def admissible(S, coef):
        return (S not in banned), "banned"

    ex = best_subset(A, b, 3, admissible=admissible)
    bb = branch_and_bound(A, b, 3, admissible=admissible)
    assert bb.support == ex.support != (1, 4, 7)
    assert any(c.support == (1, 4, 7) and c.reason == "banned" for c in bb.candidates)


def test_exact_sparse_support_found_in_a_large_library(rng):
    """p = 60, k = 5: C(60, 5) = 5.5 M supports; the clean exact support is proven best (with the
    stepwise screening, which finds it first on random columns; the library order also proves it)."""
    A = rng.normal(size=(120, 60))
    truth = (3, 17, 29, 41, 58)
    b = A[:, list(truth)] @ np.array([1.0, -2.0, 0.5, 3.0, -1.5])
    res = branch_and_bound(A, b, 5, screen=True)
    assert res.support == truth and res.proven and res.gap <= 1e-12
    assert res.nodes < 1000
    np.testing.assert_allclose(res.coef[list(truth)], [1.0, -2.0, 0.5, 3.0, -1.5], rtol=1e-10)


def test_screening_puts_the_stepwise_terms_first(rng):
    A = rng.normal(size=(80, 12))
    b = 3 * A[:, 5] + A[:, 9]
    from lsindy_cas.identify.fitting import normal_equations
    G, c = normal_equations(A, b)
    order = screening_order(G, c, [], range(12), 2)
    assert set(order[:2].tolist()) == {5, 9}
    assert sorted(order.tolist()) == list(range(12))


def test_time_limit_returns_best_so_far_not_proven(rng, monkeypatch):
    """A clock that jumps past the limit after 12 nodes: the result is marked not proven.  The
    clock is the search's own (bnb and bnb_drive), not time.monotonic itself, so no other thread
    of the test process (a Dask client's event loop) can advance it."""
    import types
    import lsindy_cas.identify.bnb as bnb
    import lsindy_cas.identify.bnb_drive as bnb_drive
    calls = {"n": 0}

    def clock():
        calls["n"] += 1
        return 0.0 if calls["n"] < 14 else 100.0

    fake_time = types.SimpleNamespace(monotonic=clock)
    monkeypatch.setattr(bnb, "time", fake_time)
    monkeypatch.setattr(bnb_drive, "time", fake_time)
    A = rng.normal(size=(40, 14))
    b = rng.normal(size=40)
    res = branch_and_bound(A, b, 4, time_limit=5.0)      # 4 terms: more than 14 nodes
    assert not res.proven and not res.interrupted
    assert res.gap >= 0 and res.nodes >= 1
    ex = best_subset(A, b, 4)
    assert res.score >= ex.score - 1e-12       # never better than the optimum


def test_work_limit_stops_at_the_same_point_every_time(rng):
    """The clock-free limit: a search stopped after 100 units of work is not proven, never
    better than the optimum, and stops where it stopped before (same nodes, support and score,
    whatever the machine's speed); a limit it never reaches changes nothing."""
    A = rng.normal(size=(60, 24))
    b = rng.normal(size=60)                         # pure noise: the proof takes many nodes
    full = branch_and_bound(A, b, 4)
    assert full.proven and full.work > 200
    cut = [branch_and_bound(A, b, 4, work_limit=100) for _ in range(2)]
    for res in cut:
        assert not res.proven and not res.interrupted and res.gap >= 0
        assert 100 <= res.work < full.work
        assert res.score >= full.score - 1e-12      # never better than the optimum
    # the same computation twice in one process: equal, bit for bit
    assert (cut[0].nodes, cut[0].support, cut[0].score) == (cut[1].nodes, cut[1].support,
                                                              cut[1].score)
    same = branch_and_bound(A, b, 4, work_limit=1e9)
    assert same.proven and (same.support, same.nodes) == (full.support, full.nodes)


def test_a_stopped_search_goes_on_where_it_stopped(rng):
    """A search stopped by its work limit hands back its state; resumed, it expands the same nodes
    as one uninterrupted search (nothing repeated, no tree's turn lost) and reaches the same
    proven optimum with the same work in all; a proven search has no state left."""
    A = rng.normal(size=(60, 24))
    b = rng.normal(size=60)
    full = branch_and_bound(A, b, 4)
    res, calls = branch_and_bound(A, b, 4, work_limit=100), 1
    assert not res.proven and res.state is not None
    while res.state is not None:
        before = res.work
        res = branch_and_bound(A, b, 4, resume=res.state, work_limit=100)
        calls += 1
        assert res.work > before                       # totals, not the last call's share
    assert res.proven and calls > 2
    # the same nodes in the same order as the search that never stopped: the same answer and work
    assert (res.support, res.nodes, res.work) == (full.support, full.nodes, full.work)
    assert res.score == full.score


def test_keyboard_interrupt_returns_best_so_far(rng, monkeypatch):
    import lsindy_cas.identify.bnb as bnb
    calls = {"n": 0}
    original = bnb.BnbSearch.children

    def children(self, node, batch=True):
        calls["n"] += 1
        if calls["n"] > 12:
            raise KeyboardInterrupt
        return original(self, node, batch)

    monkeypatch.setattr(bnb.BnbSearch, "children", children)
    A = rng.normal(size=(40, 14))
    b = rng.normal(size=40)
    res = branch_and_bound(A, b, 4)                       # 4 terms: more than 12 nodes
    assert res.interrupted and not res.proven
    assert res.gap >= 0


@pytest.mark.parametrize("kwargs, exc, match", [
    (dict(k=20), ValueError, "library size 8"),
    (dict(k=0), ValueError, "library size"),
    (dict(k=3, time_limit=0), ValueError, "time_limit must be positive"),
    (dict(k=3, time_limit=-1.0), ValueError, "time_limit must be positive"),
    (dict(k=3, time_limit="10"), TypeError, "time_limit must be a number"),
    (dict(k=3, time_limit=float("nan")), ValueError, "time_limit must be finite"),
    (dict(k=2, forced=(0, 1, 2)), ValueError, "3 prior terms do not fit"),
])
def test_bad_input(rng, kwargs, exc, match):
    A, b = rng.normal(size=(20, 8)), rng.normal(size=20)
    k = kwargs.pop("k")
    with pytest.raises(exc, match=match):
        branch_and_bound(A, b, k, **kwargs)


def test_estimator_rejects_bad_time_limit():
    from lsindy_cas import Library, LagrangianSINDy
    lib = Library.polynomial(["x"], "x,x_dot", 2)
    for bad, exc in ((0, ValueError), (-3, ValueError), ("1", TypeError), (True, TypeError)):
        with pytest.raises(exc, match="time_limit"):
            LagrangianSINDy(lib, time_limit=bad)._validate()


@pytest.mark.parametrize("passive", [False, True])
def test_structure_pruning_agrees_with_brute_force(passive):
    """Banned terms and required sets prune the tree; the answer is the exhaustive search's under
    an admissibility callable that applies the same rules leaf by leaf."""
    rng = np.random.default_rng(11)
    for _ in range(15):
        m, p = int(rng.integers(15, 40)), int(rng.integers(7, 12))
        k = int(rng.integers(2, 5))
        A, b, D = _problem(rng, m, p, passive)
        banned = sorted(rng.choice(p, 2, replace=False).tolist())
        required = [rng.choice(p, 3, replace=False), rng.choice(p, 4, replace=False)]

        def admissible(S, coef):
            ok = not set(S) & set(banned) and all(set(S) & set(r.tolist()) for r in required)
            return ok, "structure"

        try:
            ex = best_subset(A, b, k, D=D, admissible=admissible, max_visits=10**6)
        except ValueError:
            with pytest.raises(ValueError, match="no physically admissible"):
                branch_and_bound(A, b, k, D=D, admissible=admissible,
                                 structure=(banned, required))
            continue
        for screen in ("auto", False, True):
            bb = branch_and_bound(A, b, k, D=D, admissible=admissible, screen=screen,
                                  structure=(banned, required))
            assert bb.support == ex.support and bb.proven
            np.testing.assert_allclose(bb.coef, ex.coef, rtol=1e-9, atol=1e-12)


def test_structure_of_an_admissibility():
    """Velocity-linear terms are banned; each coordinate needs a term with ∂²θ/∂q̇_i² ≠ 0."""
    from lsindy_cas import Library
    from lsindy_cas.identify.admissibility import Admissibility
    from lsindy_cas.identify.bnb import structure_of
    lib = Library.polynomial(["x", "y"], "x,y,x_dot,y_dot", 2)
    X = np.random.default_rng(0).normal(size=(30, 4))
    adm = Admissibility(lib, X, [], np.ones(len(lib)))
    banned, required = structure_of(adm, len(lib))
    names = lib.names
    assert {names[j] for j in banned} == {"x_dot", "y_dot", "x*x_dot", "x*y_dot", "x_dot*y", "y*y_dot"}
    assert {names[j] for j in required[0]} == {"x_dot**2"}
    assert {names[j] for j in required[1]} == {"y_dot**2"}
    assert structure_of(lambda S, c: (True, ""), len(lib)) is None


def test_state_sets_are_exact_consequences_of_the_kinetic_rule():
    """At a state at rest only the q̇_i²·f(q) terms give M_ii ≠ 0: every support missing such a
    set is rejected by the positive-definiteness rule, so pruning with the sets loses nothing."""
    from lsindy_cas import Library
    from lsindy_cas.identify.admissibility import Admissibility
    from lsindy_cas.identify.bnb import structure_of
    lib = Library.polynomial(["x", "y"], "x,y,x_dot,y_dot", 4)
    rng = np.random.default_rng(3)
    X = rng.normal(size=(20, 4))
    X[0, 2:] = 0.0                                    # one state at rest
    adm = Admissibility(lib, X, [], np.ones(len(lib)))
    banned, required = structure_of(adm, len(lib))
    names = lib.names
    at_rest = [set(names[j] for j in r) for r in required[2:]]
    assert len(at_rest) == 2
    assert "x_dot**2*y_dot**2" in {names[j] for j in required[0]}      # per coordinate: allowed
    assert all("x_dot**2*y_dot**2" not in r for r in at_rest)          # at rest: no M_ii from it
    assert {"x_dot**2", "x**2*x_dot**2"} <= at_rest[0] | at_rest[1]
    # brute force: supports (with positive coefficients) missing a set fail the rule
    for _ in range(300):
        S = tuple(sorted(rng.choice([j for j in range(len(lib)) if j not in banned], 3,
                                    replace=False).tolist()))
        coef = np.zeros(len(lib))
        coef[list(S)] = rng.uniform(0.5, 2.0, 3)
        if not all(set(S) & set(r.tolist()) for r in required):
            assert not adm.physical(S, coef)[0]


def test_l1_order_puts_a_sparse_exact_fit_first(rng):
    """Correlated columns, exact 4-term fit: basis pursuit puts the four true terms first (forward
    stepwise does not: a single correlated column fits b better than any true one)."""
    from lsindy_cas.identify.screening import l1_order
    A = rng.normal(size=(200, 30))
    truth = [4, 11, 19, 27]
    b = A[:, truth] @ np.array([1.0, -1.0, 2.0, 1.5])
    A[:, 0] = b / np.linalg.norm(b) + 0.02 * rng.normal(size=200)    # fits b well alone, not exactly
    from lsindy_cas.identify.fitting import normal_equations
    G, c = normal_equations(A, b)
    assert screening_order(G, c, [], range(30), 4)[0] == 0               # stepwise takes the decoy
    order = l1_order(A, b, range(30))
    assert set(order[:4].tolist()) == set(truth)
    assert sorted(order.tolist()) == list(range(30))
    assert l1_order(A, None, range(30)) is None
    forced = l1_order(A, b, [j for j in range(30) if j != 4], forced=[4])
    assert set(forced[:3].tolist()) == {11, 19, 27}


def test_l1_order_gives_up_when_basis_pursuit_finds_no_sparse_fit(rng):
    """Underdetermined (20 rows, 40 monomials t^j: numerically of low rank), 6-term exact fit:
    with max_terms, None when the least-ℓ1 fit is dense (a vertex with a dozen terms, the true
    t^38 among the zeros); an order when it is sparse (incoherent columns: recovered)."""
    from lsindy_cas.identify.screening import l1_order
    t = np.linspace(0, 1, 20)
    A = np.column_stack([t ** j for j in range(40)])
    b = A[:, [0, 7, 15, 22, 30, 38]] @ np.array([1.0, -2.0, 3.0, -1.0, 2.0, 1.0])
    assert l1_order(A, b, range(40), max_terms=12) is None
    assert sorted(l1_order(A, b, range(40)).tolist()) == list(range(40))
    B = rng.normal(size=(20, 40))                                   # incoherent: BP recovers
    b = B[:, [3, 17, 29]] @ np.array([1.0, -1.0, 2.0])
    assert set(l1_order(B, b, range(40), max_terms=6)[:3].tolist()) == {3, 17, 29}


@pytest.mark.parametrize("best_first", [False, True])
def test_exact_fit_on_rank_deficient_data_found_and_proven(best_first):
    """Fewer rows than terms (every superset bound is 0 until deep), a planted exact 5-term fit:
    found and proven (gap at round-off), the exhaustive search's answer, in both visit modes."""
    rng = np.random.default_rng(5)
    A = rng.normal(size=(14, 22))
    truth = (2, 6, 11, 15, 20)
    b = A[:, truth] @ np.array([1.0, 2.0, -1.5, 0.7, 3.0])
    ex = best_subset(A, b, 5)
    bb = branch_and_bound(A, b, 5, best_first=best_first, screen=False)
    assert ex.support == bb.support == truth
    assert bb.proven and bb.gap <= 1e-12 and bb.score <= 1e-12


def test_full_queue_drops_leaves_honestly(rng, monkeypatch):
    """A queue capped at 4 leaves: dropped leaves are never examined, so a search that dropped
    one scoring below its answer is not proven and its gap covers it; the exhaustive answer is
    never beaten."""
    import lsindy_cas.identify.bnb as bnb
    monkeypatch.setattr(bnb, "_MAX_QUEUED", 4)
    for seed in range(6):
        r = np.random.default_rng(seed)
        A, b = r.normal(size=(30, 10)), r.normal(size=30)
        ex = best_subset(A, b, 3)
        for best_first in (False, True):
            res = branch_and_bound(A, b, 3, best_first=best_first, screen=False)
            assert res.score >= ex.score - 1e-12
            if res.proven:
                assert res.support == ex.support
            else:
                assert res.gap >= res.score - ex.score - 1e-12


@pytest.mark.parametrize("best_first", [False, True])
def test_visit_modes_agree_with_exhaustive_under_admissibility(best_first):
    """Leaves queued per batch (best of each examined at once or none): the best admissible
    support is the exhaustive search's, with the rule rejecting the best few supports."""
    rng = np.random.default_rng(21)
    for _ in range(12):
        m, p, k = int(rng.integers(12, 30)), int(rng.integers(8, 13)), int(rng.integers(2, 5))
        A, b = rng.normal(size=(m, p)), rng.normal(size=m)
        top = best_subset(A, b, k).supports[:3]
        worse = {tuple(int(j) for j in S) for S in top}

        def admissible(S, coef):
            return S not in worse, "rejected"

        ex = best_subset(A, b, k, admissible=admissible, max_visits=10**6)
        bb = branch_and_bound(A, b, k, admissible=admissible, best_first=best_first)
        assert bb.support == ex.support and bb.proven
        np.testing.assert_allclose(bb.coef, ex.coef, rtol=1e-9, atol=1e-12)


def test_window_visit_order_agrees_with_exhaustive():
    """The library tree visited window-first (every prefix over the first N terms before one using
    term N+1) exhausts to the exhaustive search's support, rank-deficient or not."""
    from lsindy_cas.identify.bnb_drive import drive
    rng = np.random.default_rng(8)
    for m in (9, 40):                                # fewer rows than terms, and more
        for _ in range(6):
            p, k = 14, int(rng.integers(3, 6))
            A, b = rng.normal(size=(m, p)), rng.normal(size=m)
            ex = best_subset(A, b, k)
            s = BnbSearch(A, b, k, [], None, None, None, 1e-12, 5).start(False, window=True)
            lower, proven, _, _ = drive([s], None, None)
            assert proven and s.winner.support == ex.support
            assert s.winner.score == pytest.approx(ex.score, rel=1e-8, abs=1e-12)
