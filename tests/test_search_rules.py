"""The rules applied in batches inside the search (structure, kinetic part) change how many
supports are fitted, never which one wins; and the automatic scan's scouts leave the chosen k's
certificate to a full-length search."""
import numpy as np
import pytest

from lsindy_cas.identify import selection
from lsindy_cas.identify.admissibility import PD_RTOL, clearly_not_pd
from lsindy_cas.identify.fitting import coef_on_support, normal_equations, normalise_columns
from lsindy_cas.identify.search import (best_subset, combinations, score_all,
                                        structurally_inadmissible, visit)
from lsindy_cas.identify.selection import select
from test_selection import _synthetic


def _problem(rng, m=80, p=10, n=2, s=12):
    """Driven data b = A c + noise with a random 'kinetic Hessian' per term: most of the best
    supports fit a mass matrix that is not positive definite somewhere."""
    A = rng.standard_normal((m, p)) * 10.0 ** rng.uniform(-2, 2, p)
    b = A[:, :4] @ rng.uniform(0.5, 2.0, 4) + 0.3 * rng.standard_normal(m)
    h = rng.standard_normal((s, n, n, p))
    hess = h + np.swapaxes(h, 1, 2)
    hess += 2.0 * np.eye(n)[:, :, None]         # a mild bias towards positive definite
    return A, b, hess


def _pd_rule(A, b, hess):
    """The full rule on a least-squares fit: M(x) = Σ c_j H_j(x) ≻ 0 at every state."""
    def admissible(S, coef):
        M = np.einsum("sikp,p->sik", hess, coef)
        lam = np.linalg.eigvalsh(M)
        ok = np.all(lam[:, 0] > PD_RTOL * np.maximum(np.abs(lam[:, -1]), 1e-300))
        return bool(ok), "admissible" if ok else "kinetic part not positive definite"
    return admissible


@pytest.mark.parametrize("seed", range(6))
def test_clearly_not_pd_never_marks_a_support_the_full_rule_passes(seed):
    rng = np.random.default_rng(seed)
    A, b, hess = _problem(rng)
    G, c = normal_equations(A, b)
    _, scales = normalise_columns(A)
    rule = _pd_rule(A, b, hess)
    for k in (2, 3, 4):
        S = combinations(A.shape[1], k)
        marked = clearly_not_pd(hess, G, c, scales, S)
        passed = np.array([rule(tuple(row), coef_on_support(A, b, row)[0])[0] for row in S])
        assert not np.any(marked & passed)
        assert marked.sum() >= 0.5 * (~passed).sum() > 0        # and it catches most failures


def test_batched_rules_keep_the_winner_and_the_stopping_point():
    """visit() with the kinetic rule batched and a structure (term 9 banned, a term of {0, 1}
    required) returns the same winner as judging every support one by one — including winners
    found deep in the order, after supports whose fits it skipped."""
    n_saved = n_deep = 0
    for seed in range(10):
        rng = np.random.default_rng(seed)
        A, b, hess = _problem(rng)
        rule = _pd_rule(A, b, hess)

        def full_rule(S, coef):
            if 9 in S or not ({0, 1} & set(S)):
                return False, "structure"
            return rule(S, coef)

        for k in (3, 4, 5):
            sup, sc, deg = score_all(A, b, k)
            for cap in (3, 20_000):             # stopping early, and searching to the end
                plain = visit(A, b, sup, sc, deg, admissible=full_rule, max_visits=cap,
                              n_report=2)
                fast = visit(A, b, sup, sc, deg, admissible=full_rule, max_visits=cap,
                             n_report=2, structure=([9], [np.array([0, 1])]), kinetic=hess)
                if cap == 20_000:
                    assert (fast.winner is None) == (plain.winner is None)
                if plain.winner is not None and fast.winner is not None:
                    assert fast.winner.support == plain.winner.support
                    np.testing.assert_array_equal(fast.winner.coef, plain.winner.coef)
                fitted = lambda v: sum(cand.coef is not None for cand in v.candidates)
                assert fitted(fast) <= fitted(plain)
                n_saved += fitted(plain) - fitted(fast)
                n_deep += plain.winner is not None and fitted(plain) > fitted(fast)
    assert n_saved > 0 and n_deep >= 3          # not vacuous: fits skipped before real winners


@pytest.mark.parametrize("n_sets", [0, 2, 63, 64, 130])   # the sets go 63 to a bit mask
def test_structurally_inadmissible_matches_the_definition(rng, n_sets):
    S = combinations(30, 3)
    required = [rng.choice(30, 27, replace=False) for _ in range(n_sets)]
    got = structurally_inadmissible(([5], required), S)
    want = [5 in row or any(not (set(r.tolist()) & set(row)) for r in required)
            for row in S.tolist()]
    np.testing.assert_array_equal(got, want)
    assert 0 < got.sum() < len(S)


def test_best_subset_on_the_cart_pendulum_is_unchanged_by_the_batched_rules():
    """Table I cart-pendulum (no priors, k = 4): same support and coefficients, fewer fits."""
    from lsindy_cas import Library
    from lsindy_cas.identify.admissibility import Admissibility
    from lsindy_cas.identify.balance import derivative_form
    from lsindy_cas.identify.screening import structure_of
    from lsindy_cas.paper import systems
    from lsindy_cas.paper.table1 import PAPER_SETUPS
    st = PAPER_SETUPS["cart"]
    s = systems.PAPER_SYSTEMS["cart"]()
    lib = Library.polynomial(s.coords, st.features, st.degree)
    runs = [s.simulate(t_end=1.0, u=1.0)]
    bal = derivative_form(lib, runs)
    adm = Admissibility.for_balance(lib, bal, [])
    plain = best_subset(bal.A, bal.b, 4, admissible=adm)
    fast = best_subset(bal.A, bal.b, 4, admissible=adm, structure=structure_of(adm, len(lib)),
                       kinetic=adm.hess[::8])
    assert fast.support == plain.support
    np.testing.assert_array_equal(fast.coef, plain.coef)
    truth = tuple(np.flatnonzero(lib.coefficients(s.hamiltonian)))
    assert fast.support == truth


def test_scouts_get_the_scout_budget_and_the_chosen_k_the_whole_limit(rng, monkeypatch):
    """Automatic k with no smaller model to extend: each branch and bound of the scan gets at most
    SCOUT_WORK units of work (and the time limit); a chosen k whose search was cut short is
    searched again with the whole time limit and no work limit, and that search's certificate is
    the one reported."""
    bal = _synthetic(rng)
    full = select(bal, [])
    monkeypatch.setattr(selection, "EXHAUSTIVE", 0)
    real, calls = selection.branch_and_bound, []

    def spy(*args, time_limit=None, work_limit=None, **kw):
        calls.append((time_limit, work_limit))
        res = real(*args, time_limit=time_limit, work_limit=work_limit, **kw)
        if work_limit == selection.SCOUT_WORK:       # pretend every scout was cut short
            res.proven, res.gap = False, 1.0
        return res

    monkeypatch.setattr(selection, "branch_and_bound", spy)
    auto = select(bal, [], time_limit=3600.0)          # never binds: a 12-column problem
    assert auto.support == full.support and auto.k == full.k
    assert calls[0] == (3600.0, selection.SCOUT_WORK) and calls[-1] == (3600.0, None)
    assert auto.search.method == "bnb" and auto.search.proven
    assert not auto.steps[0].search.proven or auto.steps[0].k == auto.k


def test_effort_scales_the_scan_budgets(rng, monkeypatch):
    """``effort`` multiplies the scouts' work limit (and the scan's), nothing else; a bad effort
    is refused before any work."""
    bal = _synthetic(rng)
    monkeypatch.setattr(selection, "EXHAUSTIVE", 0)
    real, calls = selection.branch_and_bound, []

    def spy(*args, work_limit=None, **kw):
        calls.append(work_limit)
        return real(*args, work_limit=work_limit, **kw)

    monkeypatch.setattr(selection, "branch_and_bound", spy)
    plain = select(bal, [])
    first = calls[0]
    calls.clear()
    more = select(bal, [], effort=4.0)
    assert first == selection.SCOUT_WORK and calls[0] == 4.0 * selection.SCOUT_WORK
    assert more.support == plain.support and more.k == plain.k


@pytest.mark.parametrize("effort", [0.0, -1.0, float("nan"), "2"])
def test_a_bad_effort_is_refused(effort):
    from lsindy_cas import LagrangianSINDy, Library
    lib = Library(["x"], ["x_dot**2", "x**2"])
    with pytest.raises((ValueError, TypeError), match="effort"):
        LagrangianSINDy(lib, effort=effort)._validate()


def test_a_k_whose_beam_finds_nothing_gets_a_scout_not_a_gap(rng, monkeypatch):
    """Automatic k: when no one-term extension of the smaller models is admissible, that k is
    searched by a branch-and-bound scout instead of being skipped — every k up to the chosen one
    is scored or listed as unscored with its reason."""
    bal = _synthetic(rng)
    full = select(bal, [])
    monkeypatch.setattr(selection, "EXHAUSTIVE", 0)

    def no_extension(*args, **kw):
        raise selection.NoAdmissibleModel("nothing among the extensions", args[3], False)

    monkeypatch.setattr(selection, "_beam", no_extension)
    auto = select(bal, [])
    assert auto.support == full.support and auto.k == full.k
    assert [st.k for st in auto.steps] == list(range(1, auto.steps[-1].k + 1))
    assert all(st.search.method == "bnb" for st in auto.steps) and not auto.unscored


def test_an_undecided_k_is_reported_with_its_reason(rng, monkeypatch):
    """A k whose scout stops before finding any admissible model is listed as undecided (not
    proven absent), with the time and work it spent; the scan goes on past it."""
    bal = _synthetic(rng)
    full = select(bal, [])
    monkeypatch.setattr(selection, "EXHAUSTIVE", 0)
    real = selection.branch_and_bound

    def blind_at_two(A, b, k, *args, **kw):
        if k == 2:
            raise selection.NoAdmissibleModel("no physically admissible 2-term model found in "
                                              "0.1 s", 2, False, 0.1, 123.0)
        return real(A, b, k, *args, **kw)

    monkeypatch.setattr(selection, "branch_and_bound", blind_at_two)
    monkeypatch.setattr(selection, "_beam", lambda *a, **kw: (_ for _ in ()).throw(
        selection.NoAdmissibleModel("no extension", a[3], False)))
    auto = select(bal, [])
    assert auto.k == full.k and auto.support == full.support and full.k > 2
    (u,) = auto.unscored
    assert (u.k, u.proven, u.work) == (2, False, 123.0) and "undecided" in str(u)
    assert auto.undecided == [u]


def test_the_refusal_counts_the_supports_the_structure_rules_out(rng):
    """When every support is ruled out before any fit, the error says how many were, not only
    the few fitted for their reasons."""
    A, b, hess = _problem(rng)
    with pytest.raises(ValueError, match=r"among the \d+ best supports \(and [\d,]+ more that "
                                         r"the rules exclude before any fit\)"):
        best_subset(A, b, 3, admissible=lambda S, c: (False, "structure"),
                    structure=([], [np.array([], dtype=np.int64)]))


def test_a_scan_with_only_undecided_ks_says_so(rng, monkeypatch):
    """When no k yields a model and some searches stopped before deciding, the refusal names
    those k and how to get a model (give k), instead of claiming that none exists."""
    bal = _synthetic(rng)
    monkeypatch.setattr(selection, "EXHAUSTIVE", 0)

    def blind(A, b, k, *args, **kw):
        raise selection.NoAdmissibleModel(f"no {k}-term model found in 0.1 s", k, False, 0.1, 5.0)

    monkeypatch.setattr(selection, "branch_and_bound", blind)
    with pytest.raises(selection.UndeterminedError, match=r"k = 1, 2, .* stopped undecided"
                                                          r".*--terms"):
        select(bal, [], max_terms=4)


def test_undecided_scouts_go_on_until_a_model_fits(monkeypatch):
    """While no model explains the data and scouts stopped undecided, their searches go on where
    they stopped (smallest k first, doubling the work) until one finds the model that fits
    exactly: here every scout gets one unit of work, and the exact 3-term model still comes out."""
    bal = _synthetic(np.random.default_rng(0), sigma=0.0)
    full = select(bal, [])
    monkeypatch.setattr(selection, "EXHAUSTIVE", 0)
    monkeypatch.setattr(selection, "fair", lambda step: step.cv < 1e-6)   # 2-term model: a miss
    monkeypatch.setattr(selection, "SCOUT_WORK", 1)
    monkeypatch.setattr(selection, "_beam", lambda *a, **kw: (_ for _ in ()).throw(
        selection.NoAdmissibleModel("no extension", a[3], False)))
    real, resumed = selection.branch_and_bound, []

    def spy(*args, resume=None, **kw):
        resumed.append(resume is not None)
        return real(*args, resume=resume, **kw)

    monkeypatch.setattr(selection, "branch_and_bound", spy)
    auto = select(bal, [])
    assert (auto.k, auto.support) == (full.k, full.support) == (3, (0, 1, 2))
    assert any(resumed) and auto.steps[-1].k == 3 and auto.steps[-1].cv <= selection.EXACT_CV
    assert all(u.k > 3 and not u.proven for u in auto.unscored)    # above the fit: left open
    assert all(getattr(st.search, "state", None) is None for st in auto.steps)  # trees dropped


def test_undecided_k_far_above_a_model_that_explains_the_data_get_no_more_work(monkeypatch):
    """Above a model that explains the data, only the undecided k up to two past it (where the
    scan looks) get more work; the others stay listed as undecided.  Here the 1-term model counts
    as fair (no noise model), so k = 2, 3 go on and the exact 3-term model comes out, while
    k = 4 … 8 are left."""
    bal = _synthetic(np.random.default_rng(0), sigma=0.0)
    monkeypatch.setattr(selection, "EXHAUSTIVE", 0)
    monkeypatch.setattr(selection, "SCOUT_WORK", 1)
    monkeypatch.setattr(selection, "_beam", lambda *a, **kw: (_ for _ in ()).throw(
        selection.NoAdmissibleModel("no extension", a[3], False)))
    real, resumed = selection.branch_and_bound, []

    def spy(*args, resume=None, work_limit=None, **kw):
        if resume is not None and work_limit is not None and work_limit < 1000:
            resumed.append(args[2])                # a round of the scan, not the certificate
        return real(*args, resume=resume, work_limit=work_limit, **kw)

    monkeypatch.setattr(selection, "branch_and_bound", spy)
    auto = select(bal, [])
    assert (auto.k, auto.support) == (3, (0, 1, 2))
    assert resumed and max(resumed) <= 3
    assert [u.k for u in auto.unscored] == [4, 5, 6, 7, 8]
