"""Finite-set lookahead: choose the applied level by enumerating short discrete input sequences.

Rounding only the first relaxed input (nearest level, or sum-up rounding) ignores when a
coarse discrete input can be applied without overshooting: balancing an inverted pendulum with
±10 N held for 50 ms, each push changes its rate by about 0.5 rad/s whatever the relaxed solution wanted.
This strategy enumerates all ``n_levels**depth`` discrete sequences for the first ``depth``
control intervals, simulates each with the model's discrete dynamics (a tree of ``F``
evaluations, one CasADi call), and scores it with the stage costs plus a quadratic model of the
relaxed cost-to-go at stage ``depth``: a Gauss-Newton Riccati recursion along the relaxed plan's
tail, in which intervals whose relaxed input is saturated keep it fixed and the others act as
linear feedback.  The first level of the cheapest sequence is applied.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .._validate import check_int
from .fastcall import NumericFunction

__all__ = ["build_lookahead"]


def _gn(residual, x):
    """Value, gradient and Gauss-Newton Hessian of ``sum(residual(x)**2)``."""
    r = residual(x)
    jac = ca.jacobian(r, x)
    return ca.sumsqr(r), 2 * ca.mtimes(jac.T, r), 2 * ca.mtimes(jac.T, jac)


def build_lookahead(ocp, depth, extra_penalty=None, bound_weight=1e5):
    """Build the scoring function of all discrete sequences of length ``depth``.

    Parameters
    ----------
    ocp : OCP
        The problem (:class:`~lsindy_cas.control.ocp.OCP`): its discrete step, levels, horizon
        ``N``, stage and terminal costs (``dt * |r|^2`` per interval, ``|r_N|^2`` at the end),
        input weight (of ``(u / max|levels|)**2`` per interval, times ``dt``) and state bounds,
        here enforced on the enumerated states by a quadratic penalty.
    depth : int
        Enumeration depth ``K`` in control intervals (``1 <= K < N``).
    extra_penalty : casadi.Function, optional
        ``x -> scalar`` added for every enumerated state (e.g. a band the discrete moves
        should keep a rate in).
    bound_weight : float
        Weight of the state-bound penalty.

    Returns
    -------
    NumericFunction
        A CasADi function called on numbers without conversions
        (:class:`~lsindy_cas.control.fastcall.NumericFunction`; the function itself is its
        ``f``): ``(x0 (n_state,), X (n_state, N) planned x_1..x_N, U (1, N) planned inputs,
        free (1, N) 1 where the planned input is strictly inside the level range,
        gain (n_state,), bias (n_state,) an online correction of the enumerated steps:
        ``x+ = F(x, u) + gain * (F(x, u) - F(x, 0)) + bias``, ref (n_state,) the state the
        costs are measured from) -> cost (n_levels**depth,)``;
        sequence ``j`` starts with level ``j // n_levels**(depth - 1)``.
    """
    step, n_state, levels, horizon = ocp.step, ocp.n_state, ocp.levels, ocp.horizon
    dt, input_weight = ocp.dt, ocp.input_weight
    stage_residual, terminal_residual = ocp.stage_residual, ocp.terminal_residual
    state_lb, state_ub = ocp.state_lb, ocp.state_ub
    depth = check_int("depth", depth, low=1)
    if depth >= horizon:
        raise ValueError(f"depth must be smaller than horizon ({horizon}), got {depth}.")
    scale = ocp.scale
    xs = ca.SX.sym("x", n_state)
    us = ca.SX.sym("u", 1)
    full_u = ocp.full_input(us)
    x_next = step(xs, full_u)
    A, B = ca.jacobian(x_next, xs), ca.jacobian(x_next, us)
    lin = ca.Function("lin", [xs, us], [x_next, A, B])
    l, gl, hl = _gn(stage_residual, xs)
    stage = ca.Function("stage", [xs], [l, gl, hl])
    lN, glN, hlN = _gn(terminal_residual, xs)
    term = ca.Function("term", [xs], [lN, glN, hlN])
    r_u = 2 * dt * input_weight / scale**2  # curvature of the input penalty

    X = ca.SX.sym("X", n_state, horizon)
    U = ca.SX.sym("U", 1, horizon)
    free = ca.SX.sym("free", 1, horizon)
    ref = ca.SX.sym("ref", n_state)  # the costs are those of x - ref
    _, s, P = term(X[:, horizon - 1] - ref)
    # interval k maps x_k -> x_{k+1}; X[:, k-1] is x_k for k >= 1
    for k in range(horizon - 1, depth - 1, -1):
        xk = X[:, k - 1]
        _, Ak, Bk = lin(xk, U[k])
        _, q, Q = stage(xk - ref)
        q, Q = dt * q, dt * Q
        r_lin = 2 * dt * input_weight * U[k] / scale**2
        PA, PB = ca.mtimes(P, Ak), ca.mtimes(P, Bk)
        H = r_u + ca.mtimes(Bk.T, PB) + 1e-9
        g = r_lin + ca.mtimes(Bk.T, s)
        G = ca.mtimes(PB.T, Ak)
        s = q + ca.mtimes(Ak.T, s) - free[k] * G.T * g / H
        P = Q + ca.mtimes(Ak.T, PA) - free[k] * ca.mtimes(G.T, G) / H
        P = (P + P.T) / 2
    x_ref = X[:, depth - 1]

    lb, ub = np.asarray(state_lb, float), np.asarray(state_ub, float)

    def violation(x):
        out = extra_penalty(x) if extra_penalty is not None else 0
        for i in range(n_state):
            if np.isfinite(ub[i]):
                out += bound_weight * ca.fmax(x[i] - ub[i], 0) ** 2
            if np.isfinite(lb[i]):
                out += bound_weight * ca.fmax(lb[i] - x[i], 0) ** 2
        return out

    x0 = ca.SX.sym("x0", n_state)
    gain = ca.SX.sym("gain", n_state)
    bias = ca.SX.sym("bias", n_state)
    frontier, costs = [x0], [ca.SX(0)]
    for _ in range(depth):
        new_frontier, new_costs = [], []
        for x, c in zip(frontier, costs):
            lx = stage(x - ref)[0]
            x_zero = lin(x, 0.0)[0]
            for level in levels:
                xn = lin(x, level)[0]
                # online model correction: input effect scaled by 1 + gain, plus a bias
                xn = xn + gain * (xn - x_zero) + bias
                new_frontier.append(xn)
                new_costs.append(c + dt * (lx + input_weight * (level / scale) ** 2)
                                 + violation(xn))
        frontier, costs = new_frontier, new_costs
    leaf = []
    for x, c in zip(frontier, costs):
        d = x - x_ref
        leaf.append(c + ca.dot(s, d) + 0.5 * ca.bilin(P, d, d))
    return NumericFunction(ca.Function("lookahead", [x0, X, U, free, gain, bias, ref],
                                       [ca.vertcat(*leaf)],
                                       ["x0", "X", "U", "free", "gain", "bias", "ref"],
                                       ["cost"]))
