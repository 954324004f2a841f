"""Streamed (compressed) balances give the dense path's answers: same support, same numbers."""
import numpy as np
import pytest

from lsindy_cas import LagrangianSINDy, Library
from lsindy_cas.data.trajectory import Trajectory
from lsindy_cas.identify.balance import derivative_form, integral_form
from lsindy_cas.identify.stream import block_edges, compressed_balance
from lsindy_cas.identify.uncertainty import block_ids
from lsindy_cas.paper import systems

SPH = "cos(theta),sin(theta),theta_dot,phi,phi_dot"


@pytest.fixture(scope="module")
def spherical():
    s = systems.spherical_pendulum()
    runs = [s.simulate(t_end=1.0, u=1.0), s.simulate(x0=[1.2, 0, 0.3, 0.2], t_end=0.8, u=0.5)]
    return s, runs, Library.polynomial(s.coords, SPH, 4)


def test_block_edges_match_block_ids():
    for n in (7, 10, 101, 1234):
        e = block_edges(n)
        ids = (np.arange(n) * 10) // n
        assert [int(np.sum(ids == b)) for b in range(10)] == list(np.diff(e))


@pytest.mark.parametrize("form", ["derivative", "integral"])
def test_same_gram_per_block(spherical, form):
    _, runs, lib = spherical
    dense = (derivative_form if form == "derivative" else integral_form)(lib, runs, compress=False)
    comp = (derivative_form if form == "derivative" else integral_form)(lib, runs, compress=True,
                                                                        chunk=17)
    assert comp.compressed and comp.n_rows == len(dense.A)
    Md = np.hstack([dense.A, dense.b[:, None]])
    Mc = np.hstack([comp.A, comp.b[:, None]])
    bd, bc = block_ids(dense), block_ids(comp)
    gd, gc = dense.groups, comp.groups
    for g in range(2):
        for blk in range(10):
            d = Md[(gd == g) & (bd == blk)]
            c = Mc[(gc == g) & (bc == blk)]
            # Gram of one block: TSQR is backward stable, entries agree to ~1e-13 of the largest
            np.testing.assert_allclose(c.T @ c, d.T @ d, rtol=0, atol=1e-12 * np.abs(d.T @ d).max())
    if form == "integral":      # the intercept column: √w = 1 per dense row, block sums kept
        Id, Ic = dense.intercept_column(), comp.intercept
        for g in range(2):
            for blk in range(10):
                d, c = (gd == g) & (bd == blk), (gc == g) & (bc == blk)
                np.testing.assert_allclose(Ic[c] @ Mc[c], Id[d] @ Md[d],
                                           atol=1e-10 * np.abs(Md).max())


@pytest.mark.parametrize("form", ["derivative", "integral"])
def test_streamed_fit_equals_dense(spherical, form, monkeypatch):
    """The whole estimator (search, k on held-out folds, jackknife significance and standard
    errors, diagnostics, status) on the streamed balance: the same support and coefficients."""
    s, runs, lib = spherical
    if form == "integral":      # no accelerations: integral form; smoothing off keeps the
        runs = [Trajectory(r.t, r.q, r.qd, r.coords, Q=r.Q) for r in runs]   # EIV refinement out
    kw = dict(n_terms=None, max_terms=4, smoothing="none", prior=["theta_dot**2"]) if form == "integral" else dict(n_terms=3)
    dense = LagrangianSINDy(lib, **kw).fit(runs)
    import lsindy_cas.identify.stream as stream
    monkeypatch.setattr(stream, "STREAM_BUDGET", 0)         # force the streamed path
    monkeypatch.setattr(stream, "CHUNK", 23)
    comp = LagrangianSINDy(lib, **kw).fit(runs)
    assert comp.support_ == dense.support_
    assert set(comp.support_) == set(np.flatnonzero(lib.coefficients(s.hamiltonian)))
    # least squares on R factors vs on the rows: both backward stable on the same Gram; the
    # coefficients (order 1–10) agree to ~1e-10 relative
    np.testing.assert_allclose(comp.coef_, dense.coef_, rtol=1e-9, atol=1e-12)
    # standard errors: on clean data they are round-off themselves (~1e-11), so they agree to
    # the round-off of the coefficients, not relatively
    np.testing.assert_allclose(comp.coef_std_, dense.coef_std_, rtol=1e-6,
                               atol=1e-9 * np.abs(dense.coef_).max())
    assert comp.n_terms_ == dense.n_terms_
    assert comp.status_ == dense.status_


def test_passive_streamed(spherical):
    s = systems.spherical_pendulum()
    runs = [s.simulate(t_end=1.0, u=0.0), s.simulate(x0=[1.2, 0, 0.3, 0.2], t_end=1.0, u=0.0)]
    lib = Library.polynomial(s.coords, SPH, 2)
    dense = integral_form(lib, runs, compress=False)
    comp = compressed_balance(lib, runs, "integral", chunk=31)
    assert comp.passive and dense.passive
    Gd, Gc = dense.A.T @ dense.A, comp.A.T @ comp.A
    np.testing.assert_allclose(Gc, Gd, atol=1e-12 * np.abs(Gd).max())


def test_dissipation_refuses_compressed(spherical):
    _, runs, lib = spherical
    from lsindy_cas.identify.dissipation import dissipation_columns, dissipation_library
    comp = integral_form(lib, runs, compress=True)
    with pytest.raises(ValueError, match="one balance row per sample"):
        dissipation_columns(dissipation_library(lib.coords, ["theta_dot**2"]), runs, comp)


def test_held_input_simulator_matches_the_adaptive_integrator():
    """The status check's RK4 (8 steps per 10 ms sample) against DOP853 at rtol 1e-11 on the
    double pendulum under a held, changing force: 20 samples, agreement far below the check's
    5 % tolerance (RK4's error at h = 1.25 ms is ~1e-10 here; 1e-7 leaves margin)."""
    from lsindy_cas.mechanics.rk4 import held_input_simulator
    from lsindy_cas.mechanics.euler_lagrange import simulate_ode
    s = systems.double_pendulum()
    t = np.arange(21) * 0.01
    u = lambda tt, x: [np.sin(5 * tt), 0.0]      # noqa: E731
    X_rk4 = held_input_simulator(s.ode(), 2)(np.array(s.x0, float), t, u)
    X_ref = simulate_ode(s.ode(), s.x0, t, u, 2)[0]
    np.testing.assert_allclose(X_rk4, X_ref, atol=1e-7)
