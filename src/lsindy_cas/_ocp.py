"""Multiple-shooting transcription of a discrete-input optimal control problem, built once.

Decision variables are ordered stage by stage, ``[c_0, x_1, c_1, x_2, ..., c_{N-1}, x_N]``
(the initial state ``x_0`` is the parameter ``p``), and constraints as
``[gap_0, path_0, gap_1, path_1, ...]`` with ``gap_k = x_{k+1} - F(x_k, c_k)``: the block
structure that fatrop and HPIPM exploit (``nx = [0, n, ..., n]``).  ``c_k`` is either a weight
per admissible level (``relaxation="poc"``, partial outer convexification, one equality
``sum(c_k) = 1`` per stage) or the continuous input itself (``relaxation="continuous"``).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["SOLVERS", "MultipleShootingNLP", "rk4_step"]

SOLVERS = ("fatrop", "ipopt", "sqp-hpipm")


def rk4_step(ode, n_state, n_input, dt, n_substeps):
    """Discrete map ``x_next = F(x, u)``: ``n_substeps`` classical RK4 steps over ``dt``.

    Parameters
    ----------
    ode : casadi.Function
        ``(x (n_state,), u (n_input,)) -> xdot (n_state,)``.
    n_state, n_input : int
        Sizes of ``x`` and ``u``.
    dt : float
        Interval length in seconds.
    n_substeps : int
        RK4 steps per interval.

    Returns
    -------
    casadi.Function
        ``F(x, u) -> x_next``, expanded to SX.
    """
    x = ca.SX.sym("x", n_state)
    u = ca.SX.sym("u", n_input)
    h = dt / n_substeps
    xk = x
    for _ in range(n_substeps):
        k1 = ode(xk, u)
        k2 = ode(xk + h / 2 * k1, u)
        k3 = ode(xk + h / 2 * k2, u)
        k4 = ode(xk + h * k3, u)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("F", [x, u], [xk], ["x", "u"], ["x_next"])


class MultipleShootingNLP:
    """The parametric NLP of one MPC step and its solver (built once, solved every step).

    Parameters
    ----------
    step : casadi.Function
        Discrete dynamics ``F(x, u) -> x_next`` over one control interval.
    n_state, n_input : int
        Sizes of the state and of the model's generalized-force vector ``u``.
    input_index : int
        Index in ``u`` of the actuated coordinate; the other entries are zero.
    levels : ndarray, shape (n_levels,)
        Admissible input levels, increasing.
    horizon : int
        Number of control intervals ``N``.
    dt : float
        Interval length in seconds (weights the stage cost).
    stage_residual, terminal_residual : casadi.Function
        ``x -> r``: running cost ``dt * |r(x_k)|^2`` per interval and terminal cost
        ``|r_N(x_N)|^2``.
    input_weight : float
        Weight ``r`` of the input penalty ``r * dt * sum_i c_i (F_i / F_max)**2`` (POC) or
        ``r * dt * (u / F_max)**2`` (continuous).
    state_lb, state_ub : ndarray, shape (n_state,)
        Bounds on ``x_1 .. x_N``.
    relaxation : {"poc", "continuous"}
    solver : {"fatrop", "ipopt", "sqp-hpipm"}
    max_iter : int
        Iteration cap; a capped solve counts as failed.
    tol : float
        Convergence tolerance.
    """

    def __init__(self, step, n_state, n_input, input_index, levels, horizon, dt,
                 stage_residual, terminal_residual, input_weight, state_lb, state_ub,
                 relaxation, solver, max_iter, tol):
        self.n_state, self.horizon, self.relaxation = n_state, horizon, relaxation
        self.levels = np.asarray(levels, dtype=float)
        n_c = self.levels.size if relaxation == "poc" else 1
        self.n_control = n_c
        scale = float(np.max(np.abs(self.levels))) or 1.0
        level_dm = ca.DM(self.levels)

        p = ca.SX.sym("x0", n_state)
        cs = [ca.SX.sym(f"c{k}", n_c) for k in range(horizon)]
        xs = [p] + [ca.SX.sym(f"x{k}", n_state) for k in range(1, horizon + 1)]
        z, g, f = [], [], 0
        for k in range(horizon):
            c = cs[k]
            if relaxation == "poc":
                force = ca.dot(level_dm, c)
                penalty = ca.dot(c, ca.DM((self.levels / scale) ** 2))
            else:
                force = c[0]
                penalty = (c[0] / scale) ** 2
            u = ca.vertcat(*[force if i == input_index else 0 for i in range(n_input)])
            z += [c, xs[k + 1]]
            gap = xs[k + 1] - step(xs[k], u)  # fatrop wants x_{k+1} - F, HPIPM F - x_{k+1}
            g.append(-gap if solver == "sqp-hpipm" else gap)
            if relaxation == "poc":
                g.append(ca.sum1(c) - 1)
            f += dt * (ca.sumsqr(stage_residual(xs[k])) + input_weight * penalty)
        f += ca.sumsqr(terminal_residual(xs[horizon]))
        nlp = {"x": ca.vertcat(*z), "p": p, "f": f, "g": ca.vertcat(*g)}
        n_g = n_state + (1 if relaxation == "poc" else 0)
        self.n_var = horizon * (n_c + n_state)
        self.lbg = np.zeros(horizon * n_g)
        self.ubg = np.zeros(horizon * n_g)
        c_lb = np.zeros(n_c) if relaxation == "poc" else self.levels[:1]
        c_ub = np.ones(n_c) if relaxation == "poc" else self.levels[-1:]
        self.lbx = np.tile(np.concatenate([c_lb, state_lb]), horizon)
        self.ubx = np.tile(np.concatenate([c_ub, state_ub]), horizon)
        ng_path = [n_g - n_state] * horizon + [0]
        self.solver_name = solver
        self.solver = self._make_solver(nlp, solver, ng_path, max_iter, tol)

    def _make_solver(self, nlp, solver, ng_path, max_iter, tol):
        n, N, m = self.n_state, self.horizon, self.n_control
        common = {"expand": True, "print_time": False, "error_on_fail": False}
        if solver == "ipopt":
            opts = dict(common, ipopt={
                "print_level": 0, "sb": "yes", "max_iter": max_iter, "tol": tol,
                "acceptable_tol": 10 * tol, "warm_start_init_point": "yes",
                "mu_init": 1e-3, "warm_start_bound_push": 1e-6,
                "warm_start_mult_bound_push": 1e-6, "linear_solver": "mumps"})
            return ca.nlpsol("mpc", "ipopt", nlp, opts)
        structure = {"N": N, "nx": [0] + [n] * N, "nu": [m] * N + [0], "ng": ng_path}
        if solver == "fatrop":
            opts = dict(common, structure_detection="manual", **structure,
                        fatrop={"print_level": 0, "max_iter": max_iter, "tolerance": tol,
                                "mu_init": 1e-2})
            return ca.nlpsol("mpc", "fatrop", nlp, opts)
        if solver == "sqp-hpipm":
            qp = dict(structure, nu=[m] * N, hpipm={"iter_max": 100, "warm_start": 1})
            opts = dict(common, qpsol="hpipm", qpsol_options=dict(qp, error_on_fail=False),
                        max_iter=max_iter, tol_pr=tol, tol_du=tol,
                        convexify_strategy="eigen-clip", print_header=False,
                        print_iteration=False, print_status=False)
            return ca.nlpsol("mpc", "sqpmethod", nlp, opts)
        raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}.")

    # --- packing -------------------------------------------------------------------------
    def pack(self, controls, states):
        """Decision vector from controls (N, n_control) and states x_1..x_N (N, n_state)."""
        return np.hstack([controls, states]).ravel()

    def unpack(self, z):
        """Controls (N, n_control) and states x_1..x_N (N, n_state) from a decision vector."""
        block = np.asarray(z, dtype=float).reshape(self.horizon, self.n_control + self.n_state)
        return block[:, : self.n_control], block[:, self.n_control:]

    def shift(self, z, lam_g):
        """Warm start for the next step: drop the first interval, repeat the last one."""
        width = self.n_control + self.n_state
        z = np.asarray(z, dtype=float)
        zs = np.concatenate([z[width:], z[-width:]])
        lam_g = np.asarray(lam_g, dtype=float)
        rows = lam_g.size // self.horizon
        ls = np.concatenate([lam_g[rows:], lam_g[-rows:]])
        return zs, ls

    def solve(self, x_init, z0, lam_g0, lam_x0):
        """Solve from state ``x_init`` with warm start; returns ``(ok, z, lam_g, lam_x, iters)``."""
        res = self.solver(x0=z0, p=x_init, lbx=self.lbx, ubx=self.ubx, lbg=self.lbg,
                          ubg=self.ubg, lam_g0=lam_g0, lam_x0=lam_x0)
        st = self.solver.stats()
        z = np.asarray(res["x"]).ravel()
        ok = bool(st.get("success", False)) or st.get("return_status") in (
            "Solved_To_Acceptable_Level",)
        ok = ok and bool(np.all(np.isfinite(z)))
        self.last_status = str(st.get("return_status", st.get("unified_return_status", "")))
        iters = int(st.get("iter_count", -1))
        return ok, z, np.asarray(res["lam_g"]).ravel(), np.asarray(res["lam_x"]).ravel(), iters
