"""Multiple-shooting transcription of a discrete-input optimal control problem, built once.

Decision variables are ordered stage by stage, ``[c_0, x_1, c_1, x_2, ..., c_{N-1}, x_N]``
(the initial state ``x_0`` is the parameter ``p``), and constraints as
``[gap_0, path_0, gap_1, path_1, ...]`` with ``gap_k = x_{k+1} - F(x_k, c_k)`` (negated for
HPIPM): the block structure that fatrop and HPIPM exploit (``nx = [0, n, ..., n]``).  ``c_k``
is either a weight per admissible level (``relaxation="poc"``, partial outer convexification,
one equality ``sum(c_k) = 1`` per stage) or the continuous input itself
(``relaxation="continuous"``).  State bounds are soft: one slack ``s_k >= 0`` per stage with
an exact (L1) plus quadratic penalty, so that no measured state makes a solve infeasible.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .._validate import check_choice
from .compiled import CompileError, check_compiler, compiled_function, compiled_nlpsol
from .fastcall import NumericFunction
from .staged import StageTerms, staged_nlp
from .watchdog import Watchdog

__all__ = ["ROBUST_SOLVERS", "SOLVERS", "MultipleShootingNLP", "check_solver_available",
           "default_robust_solver"]

SOLVERS = ("sqp", "sqp-gn", "fatrop", "ipopt")
#: solvers of cold starts and recoveries (the robust ones: interior-point methods)
ROBUST_SOLVERS = ("fatrop", "ipopt")
#: a solve that reports success counts as converged only if it meets every constraint to
#: this multiple of ``tol`` (or to ``inexact_tol``, if larger; see
#: :meth:`MultipleShootingNLP.solve`)
CONVERGED_VIOLATION = 10.0
#: largest shooting gap (state units) of a guess handed to fatrop (see ``_usable_guess``)
GUESS_GAP = 1e6
#: seconds a fatrop solve may take before it is abandoned (see ``MultipleShootingNLP.solve``);
#: the slowest seen: 0.34 s (300 iterations from a fast spin, not compiled, loaded machine)
WATCHDOG_SECONDS = 5.0


def default_robust_solver():
    """The default solver of cold starts and recoveries: ``"fatrop"`` if this CasADi has it,
    else ``"ipopt"``.

    fatrop exploits the stage structure and reaches IPOPT's optima about three times faster;
    with ``jit=True`` it is the configuration whose step p99 meets 20 ms.  Its past:
    it hung (inside its linear solver, for minutes) on two family-benchmark episodes.  The cause
    was ours -- sqpmethod had reported success for a diverged plan (shooting gaps of 1e82) that
    was shifted into the warm start -- and is fixed: a success claim with the constraints
    violated is a failure, and fatrop is never handed a guess with absurd gaps or NaN
    evaluations.  Since the hang also depends on fatrop's state from earlier solves (the same
    guess handed to a new solver converged), every fatrop solve runs under a
    :class:`~lsindy_cas.control.watchdog.Watchdog` (abandoned after ``WATCHDOG_SECONDS``, IPOPT
    from then on).  It then lost 2 of 60 mismatched paper-plant starts that IPOPT held (the
    swing-up passed the top too fast and spun around); with the top-rate term of
    :class:`~lsindy_cas.mpc.SwingUpMPC`'s cost both hold every start of seeds 0-3 and the
    80 mismatched ones.  ``cold="ipopt", recovery="ipopt"`` chooses IPOPT.
    """
    return "fatrop" if ca.has_nlpsol("fatrop") else "ipopt"


def check_solver_available(name, value):
    """Raise ValueError (naming the argument ``name``) if CasADi lacks the solver ``value``."""
    plugin = "sqpmethod" if value.startswith("sqp") else value
    if plugin in ("fatrop", "ipopt", "sqpmethod") and not ca.has_nlpsol(plugin):
        raise ValueError(f"{name}={value!r} needs CasADi's {plugin} plugin, which this CasADi "
                         f"lacks; choose another {name}.")
    return value


def robust_solvers(recovery, cold):
    """``DiscreteInputMPC``'s ``recovery`` and ``cold`` checked (None: the default robust
    solver), and the NLP's recovery and cold solvers they stand for:
    ``(recovery, cold, recover_solver, cold_solver)``."""
    robust = default_robust_solver()
    recovery = check_solver_available("recovery", check_choice(
        "recovery", robust if recovery is None else recovery, (*ROBUST_SOLVERS, "continue")))
    cold = check_solver_available("cold", check_choice(
        "cold", robust if cold is None else cold, (*ROBUST_SOLVERS, "warm")))
    # "continue" keeps IPOPT for its occasional recovery (as measured when it was added)
    recover_solver = "ipopt" if recovery == "continue" else recovery
    return recovery, cold, recover_solver, recover_solver if cold == "warm" else cold


class MultipleShootingNLP:
    """The parametric NLP of one MPC step and its solver (built once, solved every step).

    Parameters
    ----------
    ocp : OCP
        The problem: dynamics (its :attr:`OCP.step`), levels, horizon, costs and the state
        bounds, which the NLP softens with one slack per stage.  The input penalty is
        ``input_weight * dt * sum_i c_i (F_i / F_max)**2`` (POC) or
        ``input_weight * dt * (u / F_max)**2`` (continuous).
    relaxation : {"poc", "continuous"}
    solver : {"sqp", "sqp-gn", "fatrop", "ipopt"}
        Solver of warm-started steps (:attr:`solver`).
    max_iter : int
        Iteration cap of :attr:`solver`.
    tol : float
        Convergence tolerance.
    slack_weight : float
        Weight of ``s + s^2`` per stage for the soft state bounds.
    inexact_tol : float
        Largest constraint violation of a capped solve's iterate that still counts as
        ``"inexact"`` rather than ``"failed"`` (see :meth:`solve`).
    cold_solver, recover_solver : {"fatrop", "ipopt"}
        The robust (interior-point) solver for cold guesses and for recovery after a failure
        (``solvers["cold"]``, ``["recover"]``), with ``max(10 * max_iter, 300)`` iterations.
        fatrop exploits the stage structure: on the swing-up's recoveries it reached IPOPT's
        optimum (median relative cost difference 2e-6) in about a third of the time
        (``benchmarks/bench_mpc.py``).
    jit : bool
        Compile the NLP's functions to C (:mod:`~lsindy_cas.control.compiled`: several times
        faster iterations; the first build for a model compiles for about a minute, later
        ones load the compiled code from the cache).
    """

    def __init__(self, ocp, relaxation, solver, max_iter, tol, slack_weight=1e5,
                 inexact_tol=1e-6, cold_solver="ipopt", recover_solver="ipopt", jit=False):
        self.ocp = ocp
        self.jit = bool(jit)
        if self.jit:
            check_compiler()
        n_state, horizon = ocp.n_state, ocp.horizon
        levels, state_lb, state_ub = ocp.levels, ocp.state_lb, ocp.state_ub
        self.n_state, self.horizon, self.relaxation = n_state, horizon, relaxation
        self.inexact_tol = float(inexact_tol)
        self.levels = np.asarray(levels, dtype=float)
        n_c = self.levels.size if relaxation == "poc" else 1
        self.n_control = n_c
        bounded = [i for i in range(n_state)
                   if np.isfinite(state_lb[i]) or np.isfinite(state_ub[i])]
        n_s = 1 if bounded else 0  # one slack per stage softens every state bound

        sym = ca.SX  # expanded: the oracle functions run in CasADi's fast SX virtual machine
        x_init = sym.sym("x0", n_state)
        # the online correction's input gain (0: the model as identified): u -> (1 + gain) u
        gain = sym.sym("gain")
        # the state the costs are measured from (0: the residuals as given; e.g. a target position)
        ref = sym.sym("ref", n_state)
        # the model's coefficients (adapt_model: the online estimate), if the OCP has them
        coef = sym.sym("coef", 0 if ocp.param_ode is None else ocp.param_values.size)
        p = ca.vertcat(x_init, gain, ref, *([coef] if coef.numel() else []))
        cs = [sym.sym(f"c{k}", n_c) for k in range(horizon)]
        # x_0 is given, so stage 0 has no slack: ss[k] softens the bounds of x_k, k >= 1
        ss = [sym.sym(f"s{k}", n_s if k > 0 else 0) for k in range(horizon)]
        xs = [x_init] + [sym.sym(f"x{k}", n_state) for k in range(1, horizon + 1)]
        z, g, f = [], [], 0
        lbg, ubg, rows = [], [], []
        residuals = []  # for the Gauss-Newton Hessian

        self._terms = terms = StageTerms(ocp, self.levels, relaxation, tuple(bounded), n_s,
                                         slack_weight)
        for k in range(horizon + 1):
            first = len(lbg)
            kind = "terminal" if k == horizon else "first" if k == 0 else "mid"
            if k < horizon:
                z += [cs[k], ss[k], xs[k + 1]]
            stage = (cs[k], ss[k], xs[k + 1]) if k < horizon else (None, None, None)
            stage_g, lb, ub, costs, res = terms.terms(kind, xs[k], *stage, gain, ref, coef,
                                                      negate_gap=solver.startswith("sqp"))
            for term in costs:
                f += term
            residuals += res
            lbg += lb
            ubg += ub
            g += stage_g
            rows.append(np.arange(first, len(lbg)))
        nlp = {"x": ca.vertcat(*z), "p": p, "f": f, "g": ca.vertcat(*g)}
        # Gauss-Newton Hessian of the Lagrangian: 2 J'J of the stacked residuals, a small
        # regularisation on every variable (the POC weights enter the cost linearly)
        zz, lam_f, lam_g = nlp["x"], sym.sym("lam_f"), sym.sym("lam_g", len(lbg))
        jr = ca.jacobian(ca.vertcat(*residuals), zz)
        hess = lam_f * (2 * ca.mtimes(jr.T, jr) + 1e-6 * ca.DM.eye(zz.numel()))
        self._gn_hessian = ca.Function("nlp_hess_l", [zz, p, lam_f, lam_g], [hess],
                                       ["x", "p", "lam_f", "lam_g"], ["hess_gamma_x_x"])
        self.lbg, self.ubg, self._rows = np.array(lbg), np.array(ubg), rows
        self.n_slack = n_s
        # index tables of the decision vector: stage k = [c_k, s_k, x_{k+1}] (no s_0)
        widths = np.array([n_c + n_state] + [n_c + n_s + n_state] * (horizon - 1))
        base = np.concatenate([[0], np.cumsum(widths)[:-1]])[:, None]
        self._ic = base + np.arange(n_c)
        self._is = base[1:] + n_c + np.arange(n_s)
        self._ix = base + widths[:, None] - n_state + np.arange(n_state)
        self.n_var = int(widths.sum())
        c_lb = np.zeros(n_c) if relaxation == "poc" else self.levels[:1]
        c_ub = np.ones(n_c) if relaxation == "poc" else self.levels[-1:]
        self.lbx = np.full(self.n_var, -np.inf)
        self.ubx = np.full(self.n_var, np.inf)
        self.lbx[self._ic], self.ubx[self._ic] = c_lb, c_ub
        self.lbx[self._is] = 0.0
        ng_path = [len(r) - (n_state if k < horizon else 0) for k, r in enumerate(rows)]
        nu = [n_c] + [n_c + n_s] * (horizon - 1) + [0]
        self.solver_name = solver
        self._nlp, self._nu, self._ng_path, self._tol = nlp, nu, ng_path, tol
        # the sign of each constraint row in the NLP as built: the gaps are negated for HPIPM
        self._gap_rows = np.concatenate([r[:n_state] for r in rows[:-1]])
        # cold starts (first step of an episode) and recoveries after a failed step need many
        # more iterations than warm starts: an interior-point method on the same NLP
        cold = max(10 * max_iter, 300)
        self.max_iters = {"warm": max_iter, "recover": cold, "cold": cold}
        self.watchdog = Watchdog(WATCHDOG_SECONDS)  # for the fatrop solves
        # fatrop loops without end from a guess where a function evaluation fails (NaN) or
        # that is far from dynamically consistent: such a guess is refused (see solve)
        self._fg = NumericFunction(ca.Function("fg", [nlp["x"], p], [nlp["f"], nlp["g"]]))
        try:
            self._build_solvers(solver, cold_solver, recover_solver)
        except CompileError as exc:  # e.g. a compiler that refuses the generated code
            import warnings
            warnings.warn(f"{exc}; this controller runs uncompiled.", RuntimeWarning,
                          stacklevel=3)
            self.jit = False
            self._build_solvers(solver, cold_solver, recover_solver)

    def _build_solvers(self, solver, cold_solver, recover_solver):
        """The warm solver and the robust ones of cold starts and recoveries."""
        nlp, nu, ng_path, tol = self._nlp, self._nu, self._ng_path, self._tol
        sqp = solver.startswith("sqp")
        self.solver = self._make_solver(nlp, solver, nu, ng_path, self.max_iters["warm"], tol,
                                        negate_gap=sqp)
        self.solvers = {"warm": self.solver}
        self._flip = {"warm": False}  # whether a solver sees the gaps with the other sign
        self._plugin = {"warm": solver}
        robust = {}
        for kind, name in (("cold", cold_solver), ("recover", recover_solver)):
            if name not in robust:
                # fatrop wants the gaps as x_{k+1} - F: the HPIPM-signed rows negated
                flip = name == "fatrop" and sqp
                g = nlp["g"]
                if flip:
                    sign = np.ones(self.lbg.size)
                    sign[self._gap_rows] = -1.0
                    g = ca.DM(sign) * g
                robust[name] = (self._make_solver(dict(nlp, g=g), name, nu, ng_path,
                                                  self.max_iters["cold"], tol,
                                                  negate_gap=sqp and not flip), flip)
            self.solvers[kind], self._flip[kind] = robust[name]
            self._plugin[kind] = name

    def _make_solver(self, nlp, solver, nu, ng_path, max_iter, tol, jit=None, negate_gap=True):
        """The solver ``solver`` of ``nlp``; compiled (``jit``) it is generated from the staged
        NLP (:func:`~lsindy_cas.control.staged.staged_nlp`, gaps negated as ``negate_gap``)."""
        n, N = self.n_state, self.horizon
        # a diverged iterate (NaN in the cost) is a failed solve the controller recovers from
        # (recorded in stats.statuses); CasADi's own warning only made the output noisy
        common = {"expand": True, "print_time": False, "error_on_fail": False,
                  "show_eval_warnings": False}
        jit = self.jit if jit is None else jit
        nlpsol, staged = ca.nlpsol, None
        if jit:  # compiled from the staged graph: loops over one interval (see staged.py)
            n_coef = 0 if self.ocp.param_ode is None else self.ocp.param_values.size
            staged = staged_nlp(self._terms, self.n_var, self.n_control, N, n_coef, negate_gap)
            common["expand"] = False
            if solver in ("ipopt", "fatrop"):
                nlp, nlpsol = staged, compiled_nlpsol
        if solver == "ipopt":
            opts = dict(common, ipopt={
                "print_level": 0, "sb": "yes", "max_iter": max_iter, "tol": tol,
                "acceptable_tol": 10 * tol, "warm_start_init_point": "yes",
                "mu_init": 1e-3, "warm_start_bound_push": 1e-6,
                "warm_start_mult_bound_push": 1e-6, "linear_solver": "mumps"})
            return nlpsol("mpc", "ipopt", nlp, opts)
        structure = {"N": N, "nx": [0] + [n] * N, "nu": nu, "ng": ng_path}
        if solver == "fatrop":
            opts = dict(common, structure_detection="manual", **structure,
                        fatrop={"print_level": 0, "max_iter": max_iter, "tolerance": tol,
                                "mu_init": 1e-2})
            return nlpsol("mpc", "fatrop", nlp, opts)
        # SQP with HPIPM (a Riccati-based interior-point QP solver for this stage structure);
        # the exact Hessian is convexified block by block, "sqp-gn" uses Gauss-Newton instead
        qp = dict(structure, hpipm={"iter_max": 100, "warm_start": 1}, error_on_fail=False)
        opts = dict(common, qpsol="hpipm", qpsol_options=qp, max_iter=max_iter, tol_pr=tol,
                    tol_du=10 * tol, print_header=False, print_iteration=False,
                    print_status=False)
        if solver == "sqp":
            opts["convexify_strategy"] = "eigen-clip"
        else:
            opts["hess_lag"] = self._gn_hessian
        if jit:  # HPIPM cannot be serialised: compile the SQP's functions instead
            plain = ca.nlpsol("mpc", "sqpmethod", staged, opts)
            opts["hess_lag"] = compiled_function(opts.get("hess_lag")
                                                 or plain.get_function("nlp_hess_l"))
            opts["jac_fg"] = compiled_function(plain.get_function("nlp_jac_fg"))
            opts["expand"] = True  # the rest (line search) on the SX NLP
        return ca.nlpsol("mpc", "sqpmethod", nlp, opts)

    # --- packing -------------------------------------------------------------------------
    def pack(self, controls, states, slacks=None):
        """Decision vector from controls (N, n_control), states x_1..x_N (N, n_state) and
        slacks of the bounds on x_1..x_{N-1} (N - 1, n_slack; zero if omitted)."""
        z = np.zeros(self.n_var)
        z[self._ic], z[self._ix] = controls, states
        if slacks is not None:
            z[self._is] = slacks
        return z

    def unpack(self, z):
        """Controls (N, n_control), states x_1..x_N (N, n_state), slacks (N - 1, n_slack)."""
        z = np.asarray(z, dtype=float).ravel()
        return z[self._ic], z[self._ix], z[self._is]

    def shift(self, z, lam_g):
        """Warm start for the next step: drop the first interval, repeat the last one."""
        roll = (lambda a: np.concatenate([a[1:], a[-1:]]))
        c, x, s = self.unpack(z)
        zs = self.pack(roll(c), roll(x), roll(s))
        lam_g = np.asarray(lam_g, dtype=float).ravel()
        ls = lam_g.copy()
        for k in range(self.horizon - 1):
            cur, nxt = self._rows[k], self._rows[k + 1]
            if nxt.size >= cur.size:
                ls[cur] = lam_g[nxt[: cur.size]]
        return zs, ls

    def solve(self, x_init, z0, lam_g0, lam_x0, kind="warm", gain=0.0, ref=None, coef=None):
        """Solve from state ``x_init`` with a warm start.

        Parameters
        ----------
        x_init : ndarray, shape (n_state,)
        z0, lam_g0, lam_x0 : ndarray
            Primal and dual initial guesses.
        kind : {"warm", "recover", "cold"}
            Which solver of :attr:`solvers` to use.
        gain : float
            Input-gain error of the model (the plan's dynamics apply ``(1 + gain) * u``; an
            online correction's estimate, 0 for the model as it is).
        ref : ndarray, shape (n_state,), optional
            The costs are those of ``x - ref`` (default zeros: the residuals as given).
        coef : ndarray, optional
            The model's coefficients, where the OCP has them (default its own).

        Returns
        -------
        outcome : {"converged", "inexact", "failed"}
            ``"inexact"``: the iteration cap was hit but the iterate satisfies every constraint
            to ``inexact_tol`` (a nearly dynamically consistent, feasible plan).
        z, lam_g, lam_x : ndarray
            Final iterate.
        iters : int
        """
        solver = self.solvers[kind]
        p = self.parameters(x_init, gain, ref, coef)  # state, gain, ref (, coefficients)
        if self._plugin[kind] == "fatrop" and not self._usable_guess(z0, p):
            self.last_status, self.last_violation = "unusable_guess", np.inf
            return "failed", z0, lam_g0, lam_x0, 0
        flip = self._flip[kind]
        if flip:  # the gap rows' multipliers change sign with the rows
            lam_g0 = self._flip_gaps(lam_g0)
        args = dict(x0=z0, p=p, lbx=self.lbx, ubx=self.ubx, lbg=self.lbg, ubg=self.ubg,
                    lam_g0=lam_g0, lam_x0=lam_x0)
        if self._plugin[kind] == "fatrop":  # under a time limit: it has looped without end
            finished, res = self.watchdog.call(solver, **args)
            if not finished:
                self._abandon_fatrop()
                self.last_status, self.last_violation = "abandoned", np.inf
                return "failed", z0, self._flip_gaps(lam_g0) if flip else lam_g0, lam_x0, -1
        else:
            res = solver(**args)
        st = solver.stats()
        z = np.asarray(res["x"]).ravel()
        g = np.asarray(res["g"]).ravel()
        status = str(st.get("return_status", st.get("unified_return_status", "")))
        self.last_status = status
        finite = bool(np.all(np.isfinite(z)) and np.all(np.isfinite(g)))
        # sqpmethod may report success=False next to a converged "Solve_Succeeded" (when the
        # QP of the final, unneeded iteration reported a problem): trust the status -- but only
        # with the constraints met.  sqpmethod has also reported "Solve_Succeeded" for a
        # diverged iterate (states of 1e8, shooting gaps of 1e82, after NaN Hessians on the
        # family benchmark); applied and shifted into the warm start, such a plan made fatrop
        # hang on the next recovery.  Every genuinely converged solve measured meets the
        # constraints to ``tol`` (2,058 of them in 40 swing-ups), so a claim beyond
        # ``CONVERGED_VIOLATION * tol`` is a failure.
        claimed = bool(st.get("success", False)) or status in (
            "Solve_Succeeded", "Solved_To_Acceptable_Level")
        viol = max(0.0, np.max(self.lbg - g, initial=0.0), np.max(g - self.ubg, initial=0.0),
                   np.max(self.lbx - z, initial=0.0), np.max(z - self.ubx, initial=0.0))
        # (at least inexact_tol: IPOPT relaxes bounds by ~1e-8 however tight its tol)
        converged = claimed and viol <= max(CONVERGED_VIOLATION * self._tol, self.inexact_tol)
        iters = int(st.get("iter_count", -1))
        capped = iters >= self.max_iters[kind]
        self.last_violation = viol
        if claimed and not converged:
            self.last_status = status = f"{status} (constraints violated)"
        if finite and converged:
            outcome = "converged"
        elif finite and capped and viol <= self.inexact_tol:
            outcome = "inexact"
        else:
            outcome = "failed"
        lam_g = np.asarray(res["lam_g"]).ravel()
        if flip:
            lam_g = self._flip_gaps(lam_g)
        return outcome, z, lam_g, np.asarray(res["lam_x"]).ravel(), iters

    @property
    def coef0(self):
        """The model's coefficients the NLP defaults to (None: it has none as parameters)."""
        return self.ocp.param_values if self.ocp.param_ode is not None else None

    def parameters(self, x_init, gain=0.0, ref=None, coef=None):
        """The NLP's parameter vector: the initial state, the input-gain error, the state
        the costs are measured from (``ref``, default zeros) and, if the OCP has them, the
        model's coefficients (``coef``, default the OCP's)."""
        x_init = np.asarray(x_init, dtype=float).ravel()
        ref = np.zeros(x_init.size) if ref is None else np.asarray(ref, dtype=float).ravel()
        if self.coef0 is None:
            return np.concatenate([x_init, [float(gain)], ref])
        coef = self.coef0 if coef is None else np.asarray(coef, dtype=float).ravel()
        return np.concatenate([x_init, [float(gain)], ref, coef])

    def _usable_guess(self, z, p):
        """Whether ``z`` is a guess fatrop can start from: the cost and constraints are finite
        there (the model evaluates) and no shooting gap exceeds ``GUESS_GAP`` state units.

        fatrop loops without end inside its linear solver from either kind of guess (a NaN
        evaluation; a diverged plan whose gaps were 1e82), where IPOPT stops at once.
        """
        f, g = self._fg(z, p)
        g = g.ravel()
        if not (np.isfinite(f.item()) and np.all(np.isfinite(g))):
            return False
        return bool(np.max(np.abs(g[self._gap_rows]), initial=0.0) <= GUESS_GAP)

    def _abandon_fatrop(self):
        """A fatrop solve passed :attr:`watchdog`'s limit (its thread is left behind): every
        later solve of this NLP that would run fatrop runs IPOPT (not compiled, so that it
        builds in a moment), with a warning."""
        import warnings
        ipopt = {}
        for kind, plugin in self._plugin.items():
            if plugin == "fatrop":
                iters = self.max_iters[kind]
                if iters not in ipopt:
                    ipopt[iters] = self._make_solver(self._nlp, "ipopt", self._nu,
                                                     self._ng_path, iters, self._tol, jit=False)
                self.solvers[kind], self._flip[kind] = ipopt[iters], False
                self._plugin[kind] = "ipopt"
        self.solver = self.solvers["warm"]
        warnings.warn(f"a fatrop solve took over {self.watchdog.limit:g} s and was abandoned "
                      "(its thread may keep a core busy); this controller uses IPOPT from now "
                      "on.", RuntimeWarning, stacklevel=5)

    def _flip_gaps(self, lam_g):
        """A copy of ``lam_g`` with the shooting gaps' multipliers negated."""
        lam_g = np.array(lam_g, dtype=float).ravel()
        lam_g[self._gap_rows] *= -1.0
        return lam_g
