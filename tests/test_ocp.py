"""The optimal control problem (``control.ocp.OCP``) and its multiple-shooting NLP, on problems
with hand-derived answers: RK4 against its closed form, a one-step double-integrator problem with
a known optimum, and constraint satisfaction over a longer horizon."""

import dataclasses

import casadi as ca
import numpy as np
import pytest

from lsindy_cas.control.ocp import OCP, rk4_step
from lsindy_cas.control.shooting import MultipleShootingNLP

DT = 0.1


def _double_integrator():
    """x = [p, v], xdot = [v, u]."""
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    return ca.Function("ode", [x, u], [ca.vertcat(x[1], u[0])])


def _ocp(stage, terminal, horizon, **kwargs):
    x = ca.SX.sym("x", 2)
    return OCP(_double_integrator(), kwargs.pop("levels", (-10.0, 0.0, 10.0)), 0,
               ca.Function("r", [x], [stage(x)]), ca.Function("rN", [x], [terminal(x)]),
               DT, horizon, **kwargs)


def test_rk4_step_is_the_classical_runge_kutta_polynomial():
    """For xdot = a x one RK4 step multiplies by 1 + h a + (h a)^2/2 + (h a)^3/6 + (h a)^4/24
    (hand computation of k1..k4); two substeps apply it twice with h = dt / 2."""
    x, u = ca.SX.sym("x", 1), ca.SX.sym("u", 1)
    a, dt = -1.3, 0.2
    ode = ca.Function("ode", [x, u], [a * x])
    for n_sub in (1, 2):
        z = a * dt / n_sub
        factor = (1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24) ** n_sub
        step = rk4_step(ode, 1, 1, dt, n_sub)
        assert float(step(0.7, 0.0)) == pytest.approx(0.7 * factor, rel=1e-14)


def test_ocp_step_is_exact_for_the_double_integrator():
    """RK4 integrates polynomials of degree <= 4 exactly: p+ = p + v dt + u dt^2 / 2."""
    ocp = _ocp(lambda x: x, lambda x: x, 3)
    p, v, f = 0.3, -0.4, 7.0
    out = np.asarray(ocp.step([p, v], [f])).ravel()
    np.testing.assert_allclose(out, [p + v * DT + f * DT**2 / 2, v + f * DT], rtol=1e-14)


def test_ocp_normalises_and_is_frozen():
    ocp = _ocp(lambda x: x, lambda x: x, 5, levels=[10, -10, 0, 10])
    np.testing.assert_array_equal(ocp.levels, [-10.0, 0.0, 10.0])  # sorted, unique, float
    assert ocp.scale == 10.0 and (ocp.n_state, ocp.n_input) == (2, 1)
    np.testing.assert_array_equal(ocp.state_lb, [-np.inf, -np.inf])
    with pytest.raises(dataclasses.FrozenInstanceError):
        ocp.horizon = 3


@pytest.mark.parametrize("kwargs, exc, word", [
    ({"horizon": 0}, ValueError, "horizon"),
    ({"horizon": 2.5}, TypeError, "horizon"),
    ({"dt": 0.0}, ValueError, "dt"),
    ({"levels": ()}, ValueError, "levels"),
    ({"levels": "abc"}, TypeError, "levels"),
    ({"input_index": 1}, ValueError, "input_index"),
    ({"state_ub": [1.0, 2.0, 3.0]}, ValueError, "state_ub"),
    ({"n_substeps": 0}, ValueError, "n_substeps"),
    ({"input_weight": -1.0}, ValueError, "input_weight"),
])
def test_ocp_bad_arguments_raise_naming_the_argument(kwargs, exc, word):
    x = ca.SX.sym("x", 2)
    r = ca.Function("r", [x], [x])
    args = dict(ode=_double_integrator(), levels=(-1.0, 1.0), input_index=0, stage_residual=r,
                terminal_residual=r, dt=DT, horizon=4)
    args.update(kwargs)
    with pytest.raises(exc, match=word):
        OCP(**args)


@pytest.mark.parametrize("solver", ["ipopt", "sqp"])
@pytest.mark.parametrize("relaxation, optimum", [
    # continuous: min (v0 + u dt)^2 + dt w (u / 10)^2  ->  u = -v0 dt / (dt^2 + dt w / 100)
    ("continuous", -0.2 * DT / (DT**2 + DT / 100)),
    # POC, weight c on -10 N: min (0.2 - 10 dt c)^2 + dt w c  ->  c = 0.15, force -1.5 N
    ("poc", -1.5),
])
def test_one_step_problem_reaches_the_hand_derived_optimum(solver, relaxation, optimum):
    """N = 1, terminal cost v_1^2, input weight w = 1, from v_0 = 0.2 (stage cost on x_0 is a
    constant); the optimum is interior, so both relaxations reach it to solver tolerance."""
    ocp = _ocp(lambda x: ca.DM.zeros(1), lambda x: x[1], 1, input_weight=1.0)
    nlp = MultipleShootingNLP(ocp, relaxation, solver, max_iter=50, tol=1e-10)
    x0 = np.array([0.0, 0.2])
    z0 = np.zeros(nlp.n_var)
    outcome, z, *_ = nlp.solve(x0, z0, np.zeros(nlp.lbg.size), np.zeros(z0.size), kind="warm")
    assert outcome == "converged"
    controls, states, _ = nlp.unpack(z)
    force = controls[0, 0] if relaxation == "continuous" else controls[0] @ ocp.levels
    assert force == pytest.approx(optimum, abs=1e-6)
    if relaxation == "poc":
        assert controls[0].sum() == pytest.approx(1.0, abs=1e-8)
    np.testing.assert_allclose(states[0], np.asarray(ocp.step(x0, [force])).ravel(), atol=1e-8)


@pytest.mark.parametrize("gain", [0.5, -0.3])
def test_input_gain_parameter_scales_the_plans_input(gain):
    """``solve(..., gain=g)`` plans on ``x+ = F(x, (1 + g) u)`` (the online correction's input
    gain, offset-free MPC): the planned state is the model's step under the scaled force, and
    the force that reaches the same terminal speed shrinks by 1 + g."""
    ocp = _ocp(lambda x: ca.DM.zeros(1), lambda x: x[1], 1, input_weight=1e-9)
    nlp = MultipleShootingNLP(ocp, "continuous", "ipopt", max_iter=100, tol=1e-10)
    x0 = np.array([0.0, 0.2])  # v_1 = 0.2 + DT (1 + g) u = 0 at u = -2 / (1 + g)
    outcome, z, *_ = nlp.solve(x0, np.zeros(nlp.n_var), np.zeros(nlp.lbg.size),
                               np.zeros(nlp.n_var), kind="cold", gain=gain)
    assert outcome == "converged"
    controls, states, _ = nlp.unpack(z)
    force = controls[0, 0]
    assert force == pytest.approx(-2.0 / (1.0 + gain), abs=1e-4)
    np.testing.assert_allclose(states[0], np.asarray(ocp.step(x0, [(1 + gain) * force])).ravel(),
                               atol=1e-8)


def test_reference_moves_the_costs_not_the_bounds():
    """``solve(..., ref=r)`` measures the costs from ``x - r``: on the double integrator (its
    dynamics do not depend on the position) the plan from ``x0`` equals the plan from ``x0 - r``
    moved by ``r``; a state bound stays where it is (0.3 m binds with or without ``r``)."""
    N, ref = 15, np.array([-0.6, 0.0])
    costs = (lambda x: ca.vertcat(x[0] - 1.0, 0.1 * x[1]), lambda x: ca.vertcat(x[0] - 1.0, x[1]))
    free = MultipleShootingNLP(_ocp(*costs, N, levels=(-1.0, 0.0, 1.0)), "continuous", "ipopt",
                               max_iter=200, tol=1e-10)
    x0 = np.array([0.1, 0.2])
    plans = []
    for start, r in ((x0, ref), (x0 - ref, None)):
        outcome, z, *_ = free.solve(start, np.zeros(free.n_var), np.zeros(free.lbg.size),
                                    np.zeros(free.n_var), kind="cold", ref=r)
        assert outcome == "converged"
        plans.append(free.unpack(z)[1])
    np.testing.assert_allclose(plans[0], plans[1] + ref, atol=1e-6)
    assert plans[0][-1, 0] == pytest.approx(0.4, abs=0.05)  # towards 1 m + ref
    bounded = MultipleShootingNLP(_ocp(*costs, N, levels=(-1.0, 0.0, 1.0),
                                       state_lb=[-np.inf, -np.inf], state_ub=[0.3, np.inf]),
                                  "continuous", "ipopt", max_iter=200, tol=1e-9)
    outcome, z, *_ = bounded.solve(np.zeros(2), np.zeros(bounded.n_var),
                                   np.zeros(bounded.lbg.size), np.zeros(bounded.n_var),
                                   kind="cold", ref=np.array([-0.5, 0.0]))
    assert outcome == "converged"
    states = bounded.unpack(z)[1]
    assert 0.29 < np.max(states[:-1, 0]) <= 0.3 + 1e-6


def test_plans_satisfy_dynamics_input_and_state_bounds():
    """Drive the position towards 1 m with it bounded by 0.3 m: the soft bound with an exact
    penalty holds (to solver tolerance), every shooting gap closes and the inputs stay in the
    level range."""
    N = 15
    ocp = _ocp(lambda x: ca.vertcat(x[0] - 1.0, 0.1 * x[1]), lambda x: ca.vertcat(x[0] - 1.0, x[1]),
               N, levels=(-1.0, 0.0, 1.0), state_lb=[-np.inf, -np.inf], state_ub=[0.3, np.inf])
    nlp = MultipleShootingNLP(ocp, "continuous", "ipopt", max_iter=200, tol=1e-9)
    x0 = np.array([0.0, 0.0])
    outcome, z, *_ = nlp.solve(x0, np.zeros(nlp.n_var), np.zeros(nlp.lbg.size),
                               np.zeros(nlp.n_var), kind="cold")
    assert outcome == "converged"
    controls, states, slacks = nlp.unpack(z)
    assert np.all(controls >= -1.0 - 1e-9) and np.all(controls <= 1.0 + 1e-9)
    assert np.max(states[:-1, 0]) <= 0.3 + 1e-6  # x_1 .. x_{N-1} bounded
    assert np.max(states[:-1, 0]) > 0.29  # and the bound is active: the cost wants 1 m
    np.testing.assert_allclose(slacks, 0.0, atol=1e-6)
    prev = x0
    for k in range(N):
        np.testing.assert_allclose(states[k], np.asarray(ocp.step(prev, controls[k])).ravel(),
                                   atol=1e-8)
        prev = states[k]
