"""The classical RK4 step over a sample, as a CasADi expression or Function: its one home, used by
identification (short simulations from measured states) and control (the discrete map)."""
from __future__ import annotations

import casadi as ca

__all__ = ["rk4_expr", "rk4_step"]


def rk4_step(ode, n_state, n_input, dt, n_substeps):
    """Discrete map ``x_next = F(x, u)``: ``n_substeps`` classical RK4 steps over ``dt``.

    Parameters
    ----------
    ode : casadi.Function
        ``(x (n_state,), u (n_input,)) -> xdot (n_state,)``, or ``(x, u, p) -> xdot`` with
        coefficients ``p`` (then ``F(x, u, p) -> x_next``).
    n_state, n_input : int
        Sizes of ``x`` and ``u``.
    dt : float
        Interval length in seconds.
    n_substeps : int
        RK4 steps per interval.

    Returns
    -------
    casadi.Function
        ``F(x, u) -> x_next`` (``F(x, u, p)``), expanded to SX.
    """
    x = ca.SX.sym("x", n_state)
    u = ca.SX.sym("u", n_input)
    if ode.n_in() == 3:
        p = ca.SX.sym("p", ode.size1_in(2))
        nxt = rk4_expr(lambda xk, uk: ode(xk, uk, p), x, u, dt, n_substeps)
        return ca.Function("Fp", [x, u, p], [nxt], ["x", "u", "p"], ["x_next"])
    return ca.Function("F", [x, u], [rk4_expr(ode, x, u, dt, n_substeps)], ["x", "u"], ["x_next"])


def rk4_expr(ode, x, u, dt, n_substeps):
    """The state after ``n_substeps`` classical RK4 steps over ``dt`` from ``x`` under a held ``u``,
    as a CasADi expression (``dt`` may be a number or a symbol, e.g. for uneven sample times)."""
    h, xk = dt / n_substeps, x
    for _ in range(n_substeps):
        k1 = ode(xk, u)
        k2 = ode(xk + h / 2 * k1, u)
        k3 = ode(xk + h / 2 * k2, u)
        k4 = ode(xk + h * k3, u)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return xk
