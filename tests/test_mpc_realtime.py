"""Tests of the MPC's real-time pieces: fatrop cold starts and recoveries,
the per-step record of what each step ran, and the compiled (JIT) NLP functions."""

import shutil
import threading

import casadi as ca
import numpy as np
import pytest

from lsindy_cas.control import compiled
from lsindy_cas.control.shooting import default_robust_solver
from lsindy_cas.control.watchdog import Watchdog
from lsindy_cas.mpc import SwingUpMPC
from lsindy_cas.paper.swingup import identify_cart_pendulum

needs_fatrop = pytest.mark.skipif(not ca.has_nlpsol("fatrop"),
                                  reason="this CasADi has no fatrop plugin")
needs_gcc = pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler (gcc)")


@pytest.fixture(scope="module")
def model():
    return identify_cart_pendulum()[0]


@needs_fatrop
def test_fatrop_recovers_the_sqp_optimum(model):
    """fatrop (the default of cold starts and recoveries where CasADi has it) started from a
    converged SQP plan converges to a plan as cheap, with multipliers of the same sign: the
    shooting gaps' sign convention is translated (fatrop sees x_{k+1} - F, HPIPM F - x_{k+1})."""
    assert default_robust_solver() == "fatrop"
    default = SwingUpMPC(model)
    assert default.cold == "fatrop" and default.recovery == "fatrop"
    ctrl = SwingUpMPC(model, cold="fatrop", recovery="fatrop")
    assert ctrl.cold == "fatrop" and ctrl.recovery == "fatrop"
    nlp = ctrl.nlp
    cost = ca.Function("f", [nlp._nlp["x"], nlp._nlp["p"]], [nlp._nlp["f"]])
    x = np.array([0.1, 2.5, 0.0, 0.5])
    z, lam_g, lam_x = ctrl._cold_start(x)
    outcome, z, lam_g, lam_x, _ = nlp.solve(x, z, lam_g, lam_x, kind="cold")
    assert outcome == "converged"
    outcome, z, lam_g, lam_x, _ = nlp.solve(x, z, lam_g, lam_x, kind="warm")
    assert outcome == "converged"  # the SQP accepts fatrop's optimum (0 iterations here)
    outcome, z2, lam_g2, _, _ = nlp.solve(x, z, lam_g, lam_x, kind="recover")
    assert outcome == "converged"
    # the relaxed optimum is not unique (a bang-bang tail may flip); its cost is: both stop
    # at tolerance 1e-4, fatrop may go on to a slightly lower one (here -0.06 %)
    assert float(cost(z2, nlp.parameters(x))) <= float(cost(z, nlp.parameters(x))) * (1 + 1e-3)
    gaps = nlp._gap_rows  # with the sign wrong the correlation would be about -1
    assert np.corrcoef(lam_g[gaps], lam_g2[gaps])[0, 1] > 0.9


def test_cold_and_recovery_options_and_their_bad_values(model):
    ctrl = SwingUpMPC(model, cold="ipopt", recovery="ipopt")
    assert ctrl.nlp._plugin == {"warm": "sqp", "cold": "ipopt", "recover": "ipopt"}
    for kwargs, word in (({"cold": "snopt"}, "cold"), ({"recovery": "fatropp"}, "recovery"),
                         ({"jit": "yes"}, "jit")):
        with pytest.raises(ValueError, match=word):
            SwingUpMPC(model, **kwargs)


def test_every_step_records_what_it_ran_and_slow_steps_count_them(model):
    ctrl = SwingUpMPC(model)
    x = np.array([0.0, 2.5, 0.0, 0.5])
    ctrl(x)
    ctrl(x)
    ctrl._own_level = lambda state: 1  # the own rule decides: no solve
    ctrl(x)
    stats = ctrl.stats
    assert stats.step_kinds[0] == "cold" and stats.step_kinds[1] in ("warm", "recover")
    assert stats.step_kinds[2] == "balanced"
    assert len(stats.step_kinds) == len(stats.step_times) == 3
    assert sum(stats.slow_steps(limit_ms=0.0).values()) == 3  # every step took > 0 ms
    assert stats.slow_steps(limit_ms=1e9) == {"balanced": 0, "cold": 0,
                                              stats.step_kinds[1]: 0}
    summary = stats.summary()
    assert set(summary["slow_steps"]) == set(stats.step_kinds)
    assert set(summary["slow_steps_cpu"]) == set(stats.step_kinds)


@needs_fatrop
def test_a_guess_where_the_model_does_not_evaluate_is_refused_before_fatrop(model):
    """fatrop loops without end on NaN evaluations: the solve is a failure without calling it."""
    ctrl = SwingUpMPC(model, cold="fatrop", recovery="fatrop")
    nlp = ctrl.nlp
    x = np.array([0.0, 2.5, 0.0, 0.5])
    z, lam_g, lam_x = ctrl._cold_start(x)
    z[nlp._ix[3, 0]] = np.nan
    outcome, z_out, _, _, iters = nlp.solve(x, z, lam_g, lam_x, kind="recover")
    assert (outcome, nlp.last_status, iters) == ("failed", "unusable_guess", 0)
    assert z_out is z


class _ClaimsSuccess:
    """A stand-in solver that reports success and returns ``z`` whatever it is asked."""

    def __init__(self, nlp, z, x):
        self.z, self.g = z, np.asarray(nlp._fg(z, nlp.parameters(x))[1]).ravel()

    def __call__(self, **kw):
        return {"x": self.z, "g": self.g, "lam_g": kw["lam_g0"], "lam_x": kw["lam_x0"]}

    def stats(self):
        return {"return_status": "Solve_Succeeded", "success": True, "iter_count": 0}


def _diverged(ctrl, z):
    """``z`` with the cart speed of every predicted state at 1e8 m/s (shooting gaps ~1e8)."""
    bad = z.copy()
    bad[ctrl.nlp._ix[:, 2]] = 1e8
    return bad


def test_a_claimed_success_that_violates_the_constraints_is_a_failure(model):
    """sqpmethod once reported "Solve_Succeeded" for a diverged plan (gaps of 1e82): the plan
    was applied, shifted into the warm start, and fatrop hung on it at the next recovery."""
    ctrl = SwingUpMPC(model)
    nlp = ctrl.nlp
    x = np.array([0.0, 2.5, 0.0, 0.5])
    z, lam_g, lam_x = ctrl._cold_start(x)
    nlp.solvers["warm"] = _ClaimsSuccess(nlp, _diverged(ctrl, z), x)
    outcome, _, _, _, _ = nlp.solve(x, z, lam_g, lam_x, kind="warm")
    assert outcome == "failed" and nlp.last_status == "Solve_Succeeded (constraints violated)"
    assert nlp.last_violation > 1e7
    # a claim with the constraints met to tol stands (the converged plan itself)
    nlp.solvers["warm"] = _ClaimsSuccess(nlp, *ctrl._cold_start(x)[:1], x)
    nlp.solvers["warm"].g[:] = np.clip(0.0, nlp.lbg, nlp.ubg)
    assert nlp.solve(x, z, lam_g, lam_x, kind="warm")[0] == "converged"
    # in the loop: the step falls back on its plan and the next one is a recovery
    ctrl(x)
    applied = ctrl.plan_["states"].copy()
    ctrl.nlp.solvers["warm"] = _ClaimsSuccess(nlp, _diverged(ctrl, ctrl._warm[0]), x)
    ctrl(x)
    assert ctrl.stats.n_failures == 1 and not ctrl.plan_["success"]
    assert np.abs(ctrl.plan_["states"]).max() < 100 and np.abs(applied).max() < 100
    assert ctrl._failed == 1 and np.abs(ctrl._warm[0]).max() < 100


@needs_fatrop
def test_a_diverged_plan_is_not_handed_to_fatrop_the_step_starts_over(model):
    """fatrop loops without end from a guess whose shooting gaps are absurd (1e82 in the
    family benchmark); such a guess is refused and the step solves from a rolled-out guess."""
    ctrl = SwingUpMPC(model, cold="fatrop", recovery="fatrop")
    nlp = ctrl.nlp
    x = np.array([0.0, 2.5, 0.0, 0.5])
    z, lam_g, lam_x = ctrl._cold_start(x)
    bad = _diverged(ctrl, z)
    outcome, z_out, _, _, iters = nlp.solve(x, bad, lam_g, lam_x, kind="recover")
    assert (outcome, nlp.last_status, iters) == ("failed", "unusable_guess", 0)
    assert z_out is bad
    ctrl(x)
    ctrl._warm, ctrl._failed = (bad, lam_g, lam_x), 1  # a recovery from the diverged plan
    force = ctrl(x)
    assert force in ctrl.levels and ctrl.stats.solve_kinds[-1] == "cold"
    assert ctrl.plan_["success"] and np.abs(ctrl.plan_["states"]).max() < 100


def test_watchdog_returns_raises_and_abandons_a_call_past_its_limit():
    # calls that return get a limit they never reach even on a loaded machine (30 s; a call
    # waiting 0.2 s for its thread to be scheduled would be abandoned); the one that blocks
    # until released is abandoned whatever the limit, so it gets a short one
    dog = Watchdog(30.0)
    assert dog.call(lambda a, b: a + b, a=1, b=2) == (True, 3)
    with pytest.raises(KeyError):
        dog.call(lambda: {}["missing"])
    release = threading.Event()
    dog.limit = 0.2
    assert dog.call(release.wait, timeout=30) == (False, None)  # blocked: abandoned
    dog.limit = 30.0
    assert dog.n_abandoned == 1
    assert dog.call(lambda: "new worker") == (True, "new worker")
    release.set()  # the abandoned call returns; its result is dropped
    with pytest.raises(ValueError, match="limit"):
        Watchdog(0)


@needs_fatrop
def test_a_fatrop_solve_that_does_not_return_is_abandoned_and_ipopt_takes_over(model):
    """fatrop has looped without end inside a solve; a solve past the watchdog's limit is a
    failure, with a warning, and the controller's later cold starts and recoveries run IPOPT."""
    ctrl = SwingUpMPC(model, cold="fatrop", recovery="fatrop")
    nlp = ctrl.nlp
    assert nlp._plugin["recover"] == "fatrop"
    x = np.array([0.0, 2.5, 0.0, 0.5])
    z, lam_g, lam_x = ctrl._cold_start(x)
    release = threading.Event()
    nlp.solvers["recover"] = lambda **kw: release.wait(30)  # a solve that does not return
    nlp.watchdog = Watchdog(0.2)
    with pytest.warns(RuntimeWarning, match="abandoned"):
        outcome, z_out, lam_g_out, _, iters = nlp.solve(x, z, lam_g, lam_x, kind="recover")
    release.set()
    assert (outcome, nlp.last_status, iters) == ("failed", "abandoned", -1)
    assert z_out is z and np.array_equal(lam_g_out, lam_g)
    assert nlp._plugin == {"warm": "sqp", "cold": "ipopt", "recover": "ipopt"}
    assert nlp.solve(x, z, lam_g, lam_x, kind="cold")[0] == "converged"
    assert nlp.last_status == "Solve_Succeeded"  # IPOPT's status


@needs_gcc
def test_compiled_function_matches_and_is_loaded_from_the_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("LSINDY_CACHE_DIR", str(tmp_path))
    x = ca.SX.sym("x", 2)
    f = ca.Function("f", [x], [ca.sin(x[0]) * x[1], ca.exp(x[1])], ["x"], ["a", "b"])
    g = compiled.compiled_function(f)
    files = compiled.cached_files()
    assert len(files) == 1
    point = np.array([0.3, -1.2])
    for out_f, out_g in zip(f(point), g(point)):
        np.testing.assert_allclose(np.asarray(out_g), np.asarray(out_f), rtol=1e-14)
    assert g.name_in() == ["x"] and g.name_out() == ["a", "b"]
    # a second build loads the stored code (no new file); a corrupt file is rebuilt
    h = compiled.compiled_function(f)
    assert compiled.cached_files() == files
    np.testing.assert_allclose(np.asarray(h(point)[0]), np.asarray(f(point)[0]), rtol=1e-14)
    files[0].write_bytes(b"not casadi")
    k = compiled.compiled_function(f)
    np.testing.assert_allclose(np.asarray(k(point)[1]), np.asarray(f(point)[1]), rtol=1e-14)


@needs_gcc
def test_compiled_nlpsol_solves_like_the_plain_one(tmp_path, monkeypatch):
    monkeypatch.setenv("LSINDY_CACHE_DIR", str(tmp_path))
    z, p = ca.SX.sym("z", 2), ca.SX.sym("p")
    nlp = {"x": z, "p": p, "f": (z[0] - p) ** 2 + 10 * (z[1] - z[0] ** 2) ** 2, "g": z[0] + z[1]}
    opts = {"ipopt": {"print_level": 0, "sb": "yes"}, "print_time": False}
    plain = ca.nlpsol("s", "ipopt", nlp, opts)
    fast = compiled.compiled_nlpsol("s", "ipopt", nlp, opts)
    args = {"x0": [0.0, 0.0], "p": 1.5, "lbg": -np.inf, "ubg": 1.0}
    # the same algorithm on the same functions: the same iterates to rounding
    np.testing.assert_allclose(np.asarray(fast(**args)["x"]), np.asarray(plain(**args)["x"]),
                               atol=1e-10)
    assert len(compiled.cached_files()) == 1
