"""The classical RK4 step over a sample, as a CasADi expression or Function: its one home, used by
identification (short simulations from measured states) and control (the discrete map)."""
from __future__ import annotations

import casadi as ca

__all__ = ["rk4_expr", "rk4_step", "held_input_simulator"]


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


def held_input_simulator(ode, n_coords: int, substeps: int = 8):
    """``(x0, t, u) -> X`` (e.g. the status check's short simulations): classical RK4 with
    ``substeps`` steps per sample interval and the force ``u(t_i, x_i)`` held over it.

    One compiled CasADi step per interval instead of an adaptive SciPy integrator calling back
    into Python for every stage (and importing ``scipy.integrate``, ~0.3 s): at 100 Hz and 8
    substeps the step is 1.25 ms, whose error on the benchmark systems over a 20-sample stretch is
    ~1e-10 of the states' range — far below the check's tolerance (5 %).
    """
    import numpy as np

    n = 2 * n_coords
    x, u, h = ca.MX.sym("x", n), ca.MX.sym("u", n_coords), ca.MX.sym("h")
    step = ca.Function("rk4_interval", [x, u, h], [rk4_expr(ode, x, u, h, substeps)])

    def simulate(x0, t, u_fn):
        X = np.empty((len(t), n))
        X[0] = x0
        for i in range(len(t) - 1):
            ui = np.broadcast_to(np.asarray(u_fn(t[i], X[i]), float), (n_coords,))
            X[i + 1] = np.asarray(step(X[i], ui, t[i + 1] - t[i])).ravel()
        if not np.all(np.isfinite(X)):
            raise RuntimeError("the simulation diverged")
        return X
    return simulate
