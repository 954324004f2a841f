"""The staged NLP (``control.staged``): the multiple-shooting NLP assembled from one interval's
functions must be the expanded NLP itself -- the same cost, rows, Jacobian and Hessian of the
Lagrangian at random points, for every kind of stage the controller builds -- and compiled
(``jit=True``) it must solve as the uncompiled controller does."""

import shutil

import casadi as ca
import numpy as np
import pytest

from lsindy_cas.control.ocp import OCP
from lsindy_cas.control.shooting import MultipleShootingNLP
from lsindy_cas.control.staged import staged_nlp

DT = 0.05


def _pendulum(with_coefficients):
    """A pendulum on a cart, ``x = [p, th, v, w]``; its coefficients (gravity term and input
    gain) are parameters or numbers."""
    x, u, c = ca.SX.sym("x", 4), ca.SX.sym("u", 1), ca.SX.sym("c", 2)
    rhs = (lambda k: ca.vertcat(x[2], x[3], k[1] * u[0] - 0.1 * x[3] ** 2 * ca.sin(x[1]),
                                -k[0] * ca.sin(x[1]) + ca.cos(x[1]) * u[0]))
    ode = ca.Function("ode", [x, u], [rhs(ca.DM([9.8, 1.3]))])
    if not with_coefficients:
        return ode, None, None
    return ode, ca.Function("ode_p", [x, u, c], [rhs(c)]), np.array([9.8, 1.3])


def _ocp(horizon, bounded, with_coefficients=False):
    x = ca.SX.sym("x", 4)
    ode, param_ode, values = _pendulum(with_coefficients)
    bounds = dict(state_lb=[-1.5, -np.inf, -np.inf, -np.inf],
                  state_ub=[1.5, np.inf, 8.0, np.inf]) if bounded else {}
    return OCP(ode, (-10.0, 0.0, 10.0), 0,
               ca.Function("r", [x], [ca.vertcat(x[0], 1 - ca.cos(x[1]), 0.1 * x[3])]),
               ca.Function("rN", [x], [ca.vertcat(3 * x[0], ca.sin(x[1]), x[2])]),
               DT, horizon, input_weight=1e-2, param_ode=param_ode, param_values=values,
               **bounds)


@pytest.mark.parametrize("horizon, bounded, relaxation, solver, coefficients", [
    (6, True, "continuous", "sqp", False),    # the controller's default shape
    (6, True, "continuous", "fatrop", False),  # gaps as x_{k+1} - F (not negated)
    (5, False, "poc", "sqp", False),          # no slacks; one weight per level, sum row
    (3, True, "continuous", "sqp", True),     # coefficients as parameters (adapt_model)
    (2, True, "poc", "ipopt", False),         # one middle interval
    (1, True, "continuous", "sqp", False),    # no middle interval at all
])
def test_staged_nlp_is_the_expanded_nlp(horizon, bounded, relaxation, solver, coefficients):
    """Cost, rows, constraint Jacobian and Hessian of the Lagrangian of the staged (MX) NLP
    equal those of the expanded one at random points, to rounding (1e-13 relative: the sums
    are associated differently), and the derivatives have no entry outside its pattern."""
    ocp = _ocp(horizon, bounded, coefficients)
    nlp = MultipleShootingNLP(ocp, relaxation, solver, max_iter=5, tol=1e-6)
    n_coef = 2 if coefficients else 0
    staged = staged_nlp(nlp._terms, nlp.n_var, nlp.n_control, horizon, n_coef,
                        negate_gap=solver.startswith("sqp"))
    rng = np.random.default_rng(horizon)
    for expanded, nl in ((nlp._nlp, ca.SX), (staged, ca.MX)):
        assert isinstance(expanded["x"], nl)
    funcs = []
    for problem in (nlp._nlp, staged):
        z, p = problem["x"], problem["p"]
        lam = type(z).sym("lam", problem["g"].numel())
        lagrangian = problem["f"] + ca.dot(lam, problem["g"])
        funcs.append(ca.Function("d", [z, p, lam], [
            problem["f"], problem["g"], ca.jacobian(problem["g"], z),
            ca.hessian(lagrangian, z)[0]]))
    for _ in range(3):
        z = rng.normal(size=nlp.n_var)
        p = nlp.parameters(rng.normal(size=4), gain=rng.uniform(-0.2, 0.2),
                           ref=rng.normal(size=4) * 0.1,
                           coef=rng.uniform(5, 12, size=2) if coefficients else None)
        lam = rng.normal(size=nlp.lbg.size)
        want, got = funcs[0](z, p, lam), funcs[1](z, p, lam)
        for name, a, b in zip(("f", "g", "jac_g", "hess"), want, got):
            a, b = np.asarray(ca.DM(a).full()), np.asarray(ca.DM(b).full())
            assert a.shape == b.shape, name
            np.testing.assert_allclose(b, a, rtol=1e-13, atol=1e-13 * max(1.0, np.abs(a).max()),
                                       err_msg=name)
    # the same sparsity: no coupling between intervals appears that HPIPM/fatrop would refuse
    for i in (2, 3):
        assert funcs[1].sparsity_out(i) == funcs[0].sparsity_out(i)


needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None,
                               reason="jit=True needs gcc on the PATH")


@needs_gcc
def test_compiled_staged_solvers_solve_like_the_uncompiled_ones(tmp_path, monkeypatch):
    """``jit=True`` (the staged NLP compiled: the SQP's Hessian and Jacobian, the whole IPOPT
    solver of cold starts) reaches the uncompiled solvers' solution from the same guess: the
    same algorithm on functions equal to rounding."""
    monkeypatch.setenv("LSINDY_CACHE_DIR", str(tmp_path))
    ocp = _ocp(4, True)
    plain, fast = (MultipleShootingNLP(ocp, "continuous", "sqp", max_iter=30, tol=1e-8, jit=jit,
                                       cold_solver="ipopt", recover_solver="ipopt")
                   for jit in (False, True))
    x0 = np.array([0.2, 2.5, -0.3, 0.8])
    guess = (np.zeros(plain.n_var), np.zeros(plain.lbg.size), np.zeros(plain.n_var))
    for kind in ("warm", "cold"):
        a = plain.solve(x0, *guess, kind=kind)
        b = fast.solve(x0, *guess, kind=kind)
        assert a[0] == b[0] == "converged"
        np.testing.assert_allclose(b[1], a[1], atol=1e-7)


def test_the_default_compiles_where_gcc_is(monkeypatch):
    """``jit=None`` follows ``$LSINDY_JIT``; unset, it compiles where gcc is on the PATH and
    otherwise runs uncompiled with one warning per process; asking for compiled code without
    gcc, or an unknown value of the variable, is one clear error."""
    from lsindy_cas.control import compiled
    monkeypatch.delenv("LSINDY_JIT", raising=False)
    monkeypatch.setattr(compiled.shutil, "which", lambda name: "/usr/bin/gcc")
    assert compiled.resolve_jit(None) is True and compiled.resolve_jit(False) is False
    for value, want in (("0", False), ("off", False), (" ON ", True), ("1", True)):
        monkeypatch.setenv("LSINDY_JIT", value)
        assert compiled.resolve_jit(None) is want
    monkeypatch.setenv("LSINDY_JIT", "sometimes")
    with pytest.raises(ValueError, match="LSINDY_JIT must be 0/off or 1/on"):
        compiled.resolve_jit(None)
    assert compiled.resolve_jit(True) is True  # the argument wins over the variable
    with pytest.raises(ValueError, match="jit must be one of"):
        compiled.resolve_jit("yes")
    monkeypatch.setattr(compiled.shutil, "which", lambda name: None)  # no gcc
    monkeypatch.delenv("LSINDY_JIT")
    monkeypatch.setattr(compiled, "_warned_no_compiler", False)
    with pytest.warns(RuntimeWarning, match="no C compiler"):
        assert compiled.resolve_jit(None) is False
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per process
        assert compiled.resolve_jit(None) is False
    for how in ("1", None):
        if how:
            monkeypatch.setenv("LSINDY_JIT", how)
        with pytest.raises(ValueError, match="needs a C compiler"):
            compiled.resolve_jit(True if how is None else None)


@needs_gcc
def test_default_controller_is_compiled_and_acts_as_the_uncompiled_one(tmp_path, monkeypatch):
    """The swing-up controller built with the defaults (``$LSINDY_JIT`` unset, gcc present)
    runs compiled code, and over 2 s from a hanging start it applies the same forces as with
    ``jit=False``: its derivatives equal the uncompiled ones to ~1e-15, so the plans agree to
    far below any gap between two levels' costs (a tie that close is not expected in 40
    steps)."""
    from lsindy_cas.mpc import SwingUpMPC
    from lsindy_cas.paper.swingup import identify_cart_pendulum, run_episode, scenario_plant
    monkeypatch.setenv("LSINDY_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("LSINDY_JIT", raising=False)
    model, _ = identify_cart_pendulum()
    fast, plain = SwingUpMPC(model), SwingUpMPC(model, jit=False)
    assert fast.nlp.jit and not plain.nlp.jit
    plant, _ = scenario_plant("nominal", np.random.default_rng(0), fast.dt)
    x0 = np.array([0.1, 0.3, 0.0, 0.2])
    a = run_episode(fast, plant, x0, t_end=2.0)
    b = run_episode(plain, plant, x0, t_end=2.0)
    np.testing.assert_array_equal(a.forces, b.forces)
    assert set(np.unique(a.forces)) <= {-10.0, 0.0, 10.0} and np.any(a.forces != 0)


@needs_gcc
def test_a_compiler_that_fails_leaves_the_controller_uncompiled(tmp_path, monkeypatch):
    """gcc refusing the generated code (here: an option it does not know) is one warning, and
    the NLP is built uncompiled and solves; no scratch folder is left behind."""
    import glob
    import tempfile
    from lsindy_cas.control import compiled
    monkeypatch.setenv("LSINDY_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(compiled, "FLAGS", ["-fno-such-option-lsindy"])
    before = set(glob.glob(f"{tempfile.gettempdir()}/lsindy_jit_*"))
    with pytest.warns(RuntimeWarning, match="C compiler failed.*runs uncompiled"):
        nlp = MultipleShootingNLP(_ocp(3, True), "continuous", "sqp", max_iter=30, tol=1e-8,
                                  jit=True, cold_solver="ipopt", recover_solver="ipopt")
    assert nlp.jit is False
    guess = (np.zeros(nlp.n_var), np.zeros(nlp.lbg.size), np.zeros(nlp.n_var))
    assert nlp.solve(np.array([0.2, 2.5, -0.3, 0.8]), *guess, kind="cold")[0] == "converged"
    assert set(glob.glob(f"{tempfile.gettempdir()}/lsindy_jit_*")) <= before
