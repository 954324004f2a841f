"""The finite-set lookahead against a brute-force enumeration on a linear-quadratic problem.

On a double integrator with linear residuals the lookahead's Riccati model of the cost-to-go is
exact (up to a constant common to all sequences) when the planned tail is dynamically consistent
and unsaturated; so its costs must equal, up to that constant, the enumerated stage costs plus
the exact optimal continuous cost-to-go, computed here by linear least squares."""

import itertools

import casadi as ca
import numpy as np
import pytest

from lsindy_cas.control.lookahead import build_lookahead
from lsindy_cas.control.ocp import OCP

DT, N, DEPTH, W = 0.1, 5, 2, 0.5
LEVELS = np.array([-1.0, 0.0, 1.0])


@pytest.fixture(scope="module")
def ocp():
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    ode = ca.Function("ode", [x, u], [ca.vertcat(x[1], u[0])])
    r = ca.Function("r", [x], [ca.vertcat(x[0] - 1.0, 0.3 * x[1])])
    rN = ca.Function("rN", [x], [ca.vertcat(3.0 * (x[0] - 1.0), x[1])])
    return OCP(ode, LEVELS, 0, r, rN, DT, N, input_weight=W)


def _step(ocp, x, u, gain=0.0, bias=0.0):
    x_u = np.asarray(ocp.step(x, [u])).ravel()
    x_0 = np.asarray(ocp.step(x, [0.0])).ravel()
    return x_u + gain * (x_u - x_0) + bias


def _stage(ocp, x, u):
    r = np.asarray(ocp.stage_residual(x)).ravel()
    return DT * (r @ r + W * (u / ocp.scale) ** 2)


def _rollout(ocp, x0, plan_u):
    """States x_1..x_N (n_state, N) of the plan's inputs from x0."""
    X, xk = [], x0
    for u in plan_u:
        xk = _step(ocp, xk, u)
        X.append(xk)
    return np.array(X).T


def _tail_cost(ocp, x):
    """Optimal cost over intervals DEPTH..N-1 from x with unbounded continuous inputs: the
    residual vector is affine in the inputs, so evaluate it at 0 and unit inputs and solve."""
    n = N - DEPTH

    def residuals(us):
        out, xk = [], x
        for u in us:
            out += list(np.sqrt(DT) * np.asarray(ocp.stage_residual(xk)).ravel())
            out.append(np.sqrt(DT * W) * u / ocp.scale)
            xk = _step(ocp, xk, u)
        return np.array(out + list(np.asarray(ocp.terminal_residual(xk)).ravel()))

    r0 = residuals(np.zeros(n))
    J = np.column_stack([residuals(np.eye(n)[j]) - r0 for j in range(n)])
    us = np.linalg.lstsq(J, -r0, rcond=None)[0]
    r = r0 + J @ us
    return r @ r


@pytest.mark.parametrize("gain, bias", [(0.0, 0.0),
                                        (np.array([0.1, 0.2]), np.array([0.01, -0.02]))])
def test_lookahead_costs_equal_brute_force_up_to_a_constant(ocp, gain, bias):
    x0 = np.array([0.2, -0.4])
    # a dynamically consistent, unsaturated relaxed plan (what the NLP would hand over)
    plan_u = np.array([0.4, -0.3, 0.2, 0.5, -0.1])
    X = _rollout(ocp, x0, plan_u)
    look = build_lookahead(ocp, DEPTH)
    cost = np.asarray(look(x0, X, plan_u[None, :], np.ones((1, N)), np.broadcast_to(gain, 2),
                           np.broadcast_to(bias, 2), np.zeros(2))).ravel()
    brute = []
    for seq in itertools.product(LEVELS, repeat=DEPTH):  # same order: first level slowest
        c, x = 0.0, x0
        for u in seq:
            c += _stage(ocp, x, u)
            x = _step(ocp, x, u, gain, bias)  # the enumerated steps are corrected
        brute.append(c + _tail_cost(ocp, x))
    brute = np.array(brute)
    assert cost.shape == (LEVELS.size**DEPTH,)
    diff = cost - brute
    # exact up to the constant dropped from the quadratic model and the 1e-9 regularisation
    np.testing.assert_allclose(diff, diff[0], atol=1e-7)
    assert np.argmin(cost) == np.argmin(brute)
    assert np.ptp(brute) > 1e-3  # the sequences really differ


def test_depth_must_be_below_the_horizon(ocp):
    with pytest.raises(ValueError, match="depth"):
        build_lookahead(ocp, N)
    with pytest.raises(ValueError, match="depth"):
        build_lookahead(ocp, 0)


def test_reference_moves_the_costs(ocp):
    """Costs measured from ``x - ref``: the double integrator's step commutes with a shift of
    the position, so scoring from ``x0`` with ``ref`` equals scoring from ``x0 - ref`` with the
    plan moved by ``-ref`` and no reference; and the reference changes the scores."""
    x0, ref = np.array([0.2, -0.4]), np.array([0.7, 0.0])
    plan_u = np.array([0.4, -0.3, 0.2, 0.5, -0.1])
    X = _rollout(ocp, x0, plan_u)
    look = build_lookahead(ocp, DEPTH)
    args = (plan_u[None, :], np.ones((1, N)), np.zeros(2), np.zeros(2))
    with_ref = np.asarray(look(x0, X, *args, ref)).ravel()
    moved = np.asarray(look(x0 - ref, X - ref[:, None], *args, np.zeros(2))).ravel()
    np.testing.assert_allclose(with_ref, moved, rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(with_ref - np.asarray(look(x0, X, *args, np.zeros(2))).ravel())) > 0.1
