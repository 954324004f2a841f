"""Baselines: KRONIC and SINDy + Lasso (pysindy), the divergence-aware rollout, Figs. 3 and 4."""
import json
import os
import subprocess
import sys
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from lsindy_cas import Library, systems
from lsindy_cas.paper.baselines import Kronic, SINDyLasso, require_pysindy, rollout

needs_pysindy = pytest.mark.needs("pysindy")     # per test: the others run without pysindy


@pytest.fixture(scope="module")
def spring():
    # m = 2 kg, k = 5 N/m: H = s_dot² + 2.5 s², s_ddot = -2.5 s + Q/2
    return systems.mass_spring()


def test_kronic_finds_the_conserved_energy_of_a_spring(spring):
    data = spring.simulate(t_end=2.0, u=0.0)
    lib = Library(["s"], ["s**2", "s_dot**2", "s*s_dot"])
    k = Kronic(lib).fit(data)
    assert k.null_dim_ == 1                      # no identities in this library
    assert k.n_nonzero_ == 2
    np.testing.assert_array_equal(np.abs(k.coef_) > 1e-6, [True, True, False])
    # ξ ∝ (2.5, 1, 0), scaled to max |ξ| = 1; 1e-8 covers the SVD of exact (rtol 1e-11) data
    np.testing.assert_allclose(k.coef_, [1.0, 0.4, 0.0], atol=1e-8)


def test_kronic_is_dense_when_the_library_has_identities():
    # sin² + cos² = 1 and friends make Γ's null space many-dimensional: the smallest singular
    # vector mixes them, which is why KRONIC's bars in Fig. 3 are tall
    system = systems.cart_pendulum()
    lib = Library.polynomial(system.coords, "cos(theta),sin(theta),theta_dot,x,x_dot", 3)
    k = Kronic(lib).fit(system.simulate(t_end=1.0, u=0.0))
    assert k.null_dim_ > 1
    assert k.n_nonzero_ > 4 * 5


def test_kronic_rejects_driven_data(spring):
    lib = Library(["s"], ["s**2", "s_dot**2"])
    with pytest.raises(ValueError, match="passive"):
        Kronic(lib).fit(spring.simulate(t_end=1.0, u=1.0))


@needs_pysindy
def test_sindy_recovers_a_law_its_library_contains(spring):
    # limiting case: the equation of motion is in SINDy's library, so SINDy is exact and sparse
    m = SINDyLasso(["s", "s_dot"], coords=["s"], degree=2).fit(spring.simulate(t_end=2.0, u=1.0))
    assert m.controls_ == ["Q_s"]
    assert m.candidate_names_ == ["s", "s_dot", "s^2", "s s_dot", "s_dot^2", "Q_s"]
    np.testing.assert_array_equal(m.coef_ != 0, [[True, False, False, False, False, True]])
    # pysindy's unbiasing refits the support by least squares: exact up to round-off
    np.testing.assert_allclose(m.coef_[0, [0, 5]], [-2.5, 0.5], rtol=1e-8)
    assert m.n_nonzero_ == 2
    assert m.equations() == ["s_ddot = -2.500 s + 0.500 Q_s"]


@needs_pysindy
def test_sindy_ode_matches_the_accelerations_it_was_fitted_to():
    system = systems.cart_pendulum()
    data = system.simulate(t_end=1.0, u=1.0)
    m = SINDyLasso(["cos(theta)", "sin(theta)", "theta_dot", "x_dot"], coords=system.coords,
                   degree=2).fit(data)
    f = m.ode()
    assert isinstance(f, ca.Function) and f.name_in() == ["x", "u"]
    qdd = m.predict(data.X, data.Q)
    assert qdd.shape == (data.n_samples, 2)
    # the library cannot express the rational true law; a fitted model still tracks the data
    # to a few percent of the acceleration range
    assert np.max(np.abs(qdd - data.qdd)) < 0.05 * np.ptp(data.qdd)


@needs_pysindy
def test_sindy_needs_accelerations(spring):
    data = spring.simulate(t_end=1.0, u=0.0)
    data.qdd = None
    with pytest.raises(ValueError, match="accelerations"):
        SINDyLasso(["s", "s_dot"], coords=["s"], degree=2).fit(data)


@needs_pysindy
def test_sindy_validates_its_arguments(spring):
    data = spring.simulate(t_end=1.0, u=0.0)
    with pytest.raises(ValueError, match="degree"):
        SINDyLasso(["s"], coords=["s"], degree=0).fit(data)
    with pytest.raises(ValueError, match="validation"):
        SINDyLasso(["s"], coords=["s"], degree=1, validation=1.5).fit(data)
    with pytest.raises(ValueError, match="coords"):
        SINDyLasso(["s"], degree=1).fit(data)
    with pytest.raises(ValueError, match="not fitted"):
        SINDyLasso(["s"], coords=["s"]).ode()


def test_missing_pysindy_gives_an_install_hint(monkeypatch):
    monkeypatch.setitem(sys.modules, "pysindy", None)     # makes `import pysindy` fail
    with pytest.raises(ImportError, match=r"pip install 'lsindy_cas\[bench\]'"):
        require_pysindy()


def test_rollout_stops_where_a_model_diverges():
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    blowup = ca.Function("f", [x, u], [ca.vertcat(x[1], x[1] ** 2)])   # q̇ -> ∞ at t = 1/q̇0
    t = np.linspace(0, 2, 201)
    r = rollout(blowup, [0.0, 1.0], t, bound=1e3)
    assert r.diverged_at == pytest.approx(1.0, abs=0.01)
    assert np.all(np.isfinite(r.X[t < 0.99])) and np.all(np.isnan(r.X[t > 1.0]))
    ok = rollout(blowup, [0.0, 0.0], t)
    assert ok.diverged_at is None and np.all(ok.X == 0)


def test_claims_reads_the_numbers():
    from lsindy_cas.paper.comparison import claims
    good = {"fig3": [{"system": "cart", "library": 55, "sindy": 100, "kronic": 54, "ours": 4}],
            "fig4": [{"system": "cart", "rms_q_extrap_ours": 1e-12, "rms_q_extrap_sindy": None}]}
    assert claims(good) == []
    bad = {"fig3": [{"system": "cart", "library": 55, "sindy": 3, "kronic": 54, "ours": 4}],
           "fig4": [{"system": "cart", "rms_q_extrap_ours": 1e-3, "rms_q_extrap_sindy": 1e-5}]}
    msgs = claims(bad)
    assert len(msgs) == 2 and "SINDy (3)" in msgs[0] and "not below" in msgs[1]


@needs_pysindy
def test_figures_for_the_cart_pendulum(tmp_path):
    from lsindy_cas.paper.comparison import claims
    from lsindy_cas.paper.figures import make_figures
    printed = []
    paths = make_figures(tmp_path, systems=["cart"], echo=printed.append)
    names = [p.name for p in paths]
    assert names == ["fig3_complexity.png", "fig4_extrapolation.png", "baselines.md", "baselines.json"]
    for p in paths[:2]:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 20_000
    numbers = json.loads(paths[-1].read_text())
    fig3 = numbers["fig3"][0]
    assert fig3["ours"] == 4 and fig3["library"] == 55       # the true L has 4 terms
    assert claims(numbers) == []
    assert "Fig. 3" in printed[0] and "cart-pendulum" in printed[0]


@needs_pysindy
def test_make_figures_rejects_unknown_systems(tmp_path):
    from lsindy_cas.paper.figures import make_figures
    with pytest.raises(ValueError, match="systems"):
        make_figures(tmp_path, systems=["triple"])


@pytest.mark.slow
@needs_pysindy
def test_paper_claims_on_all_three_systems(tmp_path):
    from lsindy_cas.paper.comparison import claims
    from lsindy_cas.paper.figures import make_figures
    paths = make_figures(tmp_path)
    numbers = json.loads(paths[-1].read_text())
    assert claims(numbers) == []
    assert [c["ours"] for c in numbers["fig3"]] == [3, 6, 4]


def test_figures_without_pysindy_show_our_model(tmp_path, monkeypatch):
    """Figs. 3-4 need only the project: without pysindy the SINDy columns are left out."""
    from lsindy_cas.paper.comparison import claims
    from lsindy_cas.paper.figures import make_figures
    monkeypatch.setitem(sys.modules, "pysindy", None)          # import pysindy -> ImportError
    paths = make_figures(tmp_path, systems=["cart"], sindy=None)
    pngs = [p for p in paths if p.suffix == ".png"]
    assert [p.name for p in pngs] == ["fig3_complexity.png", "fig4_extrapolation.png"]
    for p in pngs:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 20_000
    numbers = json.loads(paths[-1].read_text())
    assert numbers["fig3"][0]["sindy"] is None and numbers["fig3"][0]["ours"] == 4
    assert "rms_q_extrap_sindy" not in numbers["fig4"][0]
    assert claims(numbers) == []          # ours sparser than the library and KRONIC
    assert "skipped" in (tmp_path / "baselines.md").read_text()


def test_reproduce_without_pysindy_writes_figures(tmp_path, monkeypatch, capsys, table_cell):
    """``lsindy reproduce`` without pysindy: Table I and our figures, and it says what was skipped.

    The experiments are cut to the cart-pendulum (size knob) to keep the test fast.
    """
    import lsindy_cas.paper.figures as figures
    import lsindy_cas.paper.table1 as table1
    from lsindy_cas.cli import main
    monkeypatch.setitem(sys.modules, "pysindy", None)
    real_figures = figures.make_figures
    monkeypatch.setattr(table1, "table_one", lambda progress=None: [   # run_cell, memoised
        table_cell("cart", s) for s in ("actuated", "passive")])
    monkeypatch.setattr(figures, "make_figures",
                        lambda out, **kw: real_figures(out, **kw, systems=["cart"]))
    assert main(["reproduce", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "SINDy (Lasso) baseline columns skipped" in err and "pip install" in err
    assert (tmp_path / "table1.md").exists()
    assert len(list(tmp_path.glob("*.png"))) >= 2
