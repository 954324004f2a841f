"""The generic part of :mod:`lsindy_cas.mpc`: a discrete-input MPC on any CasADi ODE.

:class:`DiscreteInputMPC` is a multiple-shooting MPC on any ``casadi.Function``
``ode(x, u) -> xdot`` whose actuated input may only take values from a finite set.  Each step
solves a relaxation (partial outer convexification: one weight per admissible level, the weights
summing to 1; or a continuous input) warm-started from the shifted previous solution, then turns
the first interval's relaxed decision into one admissible level: by enumerating short discrete
sequences against the relaxed plan's cost-to-go (:mod:`lsindy_cas.control.lookahead`, the
default), by sum-up rounding with the rounding error carried across steps, or by plain rounding
(:mod:`lsindy_cas.control.rounding`); where a subclass's own rule decides (the balancer of
:class:`~lsindy_cas.mpc.SwingUpMPC`), the step only shifts the plan.  A failed solve falls back
to the shifted previous plan (counted in :attr:`DiscreteInputMPC.stats`); the next step
re-solves with fatrop or IPOPT, or continues the SQP (``recovery="continue"``).
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from .._validate import check_choice, check_int, check_real, check_state
from .coefficients import CoefficientEstimator
from .compiled import resolve_jit
from .correction import InputGainCorrection
from .lookahead import build_lookahead
from .ocp import OCP
from .rounding import ROUNDINGS, weights_from_value
from .shooting import SOLVERS, MultipleShootingNLP, robust_solvers
from .stats import MPCStats

__all__ = ["DiscreteInputMPC", "MPCStats", "wrap_angle"]


def wrap_angle(a):
    """Angle(s) in radians mapped to ``[-pi, pi)``."""
    return (np.asarray(a, dtype=float) + np.pi) % (2 * np.pi) - np.pi


class DiscreteInputMPC:
    """Multiple-shooting MPC whose single actuated input takes values in a finite set.

    Parameters
    ----------
    ode : casadi.Function
        ``(x (n_state,), u (n_input,)) -> xdot (n_state,)``, e.g. ``model.ode()``.
    levels : sequence of float
        Admissible values of ``u[input_index]`` (the other inputs are held at zero).
    input_index : int
        Which entry of ``u`` is actuated.
    stage_residual, terminal_residual : casadi.Function
        ``x -> r`` (least-squares costs); the objective is ``sum_k dt * (|r(x_k - ref)|^2 +
        input penalty) + |r_N(x_N - ref)|^2`` with ``ref`` the :attr:`reference`.
    dt : float
        Control period in seconds (zero-order hold).
    horizon : int
        Number of control intervals predicted.
    state_lb, state_ub : array_like, shape (n_state,), optional
        Bounds on the predicted states after the first, softened by a slack with an exact
        penalty so that a solve is never infeasible.
    input_weight : float
        Weight of the normalised input penalty.
    n_substeps : int
        RK4 steps per control interval.
    solver : {"sqp", "sqp-gn", "fatrop", "ipopt"}
        Solver of the warm-started steps: SQP with the exact (convexified) Hessian and HPIPM
        QPs, SQP with a Gauss-Newton Hessian, fatrop or IPOPT (compared in
        ``benchmarks/bench_mpc.py``).
    relaxation : {"continuous", "poc"}
        A continuous input in ``[min, max]`` (default), or partial outer convexification:
        one weight per level, summing to 1.  For an ODE affine in the input both relax to
        the same convex hull; the continuous one has fewer variables.  The weights of a
        continuous input are those of its two adjacent levels
        (:func:`~lsindy_cas.control.rounding.weights_from_value`).
    rounding : {"lookahead", "sur", "nearest"}
        How the applied level is chosen: lookahead over all discrete sequences of ``depth``
        intervals (first move among the levels adjacent to the relaxed first input), sum-up
        rounding carried across steps, or plain rounding to the largest weight (= the
        nearest level for the continuous relaxation).
    depth : int
        Lookahead depth in control intervals (``n_levels**depth`` sequences).
    max_iter : int
        Iteration cap per warm-started SQP solve (7: a capped solve then costs under 20 ms,
        and a fatrop recovery from the last plan is mostly faster than the 8th-10th SQP
        iterations; README "Step time").  Recovery solves (see ``recover_after``) and cold
        ones (unless ``cold="warm"``) run fatrop or IPOPT with ``max(10 * max_iter, 300)``
        iterations.
    tol : float
        Solver tolerance.
    accept_inexact : bool
        Apply a capped solve's iterate if it satisfies every constraint to ``inexact_tol``
        (counted in ``stats.n_inexact``); otherwise such a solve is a failure (fallback).
    inexact_tol : float
        Constraint violation (shooting defects in state units, bounds) up to which a capped
        solve's iterate is applied (larger: fewer slow recoveries, less consistent plans).
    recover_after : int, optional
        After this many failed solves in a row the next solve is a recovery solve (fatrop or
        IPOPT) from the shifted plan; by default 1 with ``recovery="fatrop"`` or
        ``"ipopt"``, 3 with ``"continue"``.  After :attr:`RECOVERY_BACKOFF` failed recoveries
        in a row only every ``RECOVERY_BACKOFF``-th step recovers, warm SQP in between.
    recovery : {"fatrop", "ipopt", "continue"}, optional
        After a failure: ``"continue"`` warm-starts the next SQP solve from the failed
        iterate, shifted (an IPOPT recovery from the last applied plan only after
        ``recover_after`` failures in a row); ``"fatrop"`` / ``"ipopt"`` discard it and re-solve
        with that interior-point method from the shifted previous plan.  Default: fatrop where
        CasADi has it (IPOPT's optimum in about a third of the time; under a watchdog,
        :func:`~lsindy_cas.control.shooting.default_robust_solver`), else IPOPT.  A failed step
        applies the shifted previous plan.
    cold : {"fatrop", "ipopt", "warm"}, optional
        Solver of an episode's first step, from a rolled-out guess: the warm solver
        (``"warm"``: at most ``max_iter`` iterations, its iterate applied if finite), or
        fatrop or IPOPT with up to ``max(10 * max_iter, 300)`` iterations (default: as
        ``recovery``).
    lookahead_penalty : casadi.Function, optional
        ``x -> scalar`` added to the cost of every state the lookahead enumerates.
    adapt : bool
        Correct the lookahead's (and a subclass's own rule's) predictions online against
        plant/model mismatch (:attr:`correction`, an :class:`~lsindy_cas.control.correction.
        InputGainCorrection`): ``F(x, u) + gain * (F(x, u) - F(x, 0)) + bias``.
    adapt_forgetting, adapt_max_gain : float
        RLS forgetting factor in (0, 1]; bound on ``|gain|``.
    adapt_plan : bool
        Whether the relaxed plan's dynamics use the correction's input gain as well: the
        NLP applies ``(1 + gain) * u`` with ``gain`` the estimate of the state component
        :attr:`plan_gain_index` (by default the actuated coordinate's velocity).
    solve_balanced : bool
        Whether to solve the relaxed NLP also on steps a subclass's own rule decides (the
        balancer), only to keep the warm start.  By default
        such a step costs only the rule, and the plan is shifted one interval per step
        (``stats.n_resumed`` counts the solves that resume from it).
    coefficients : (casadi.Function, array_like), optional
        The ODE as a function of its coefficients, ``(x, u, p) -> xdot``, and their values:
        the relaxed plan then uses :attr:`estimator`'s online estimate of them (and not
        ``adapt_plan``'s gain; :mod:`~lsindy_cas.control.coefficients`).
    gate : (callable, int) or (callable, int, callable), optional
        With ``coefficients``: the estimate enters the plan only once ``gate[0](x)`` has held
        for ``gate[1]`` steps in a row (:attr:`CoefficientEstimator.stall`) or ``gate[2](x_prev,
        x, predicted)`` held once (``miss``; ``predicted`` the states of the plan made at
        ``x_prev``, None if that step did not solve); until then the step solves the NLP of the
        model as given (built as well): the same forces as without ``coefficients``.
    jit : bool, optional
        Compile the NLP's derivatives to C with gcc (:mod:`~lsindy_cas.control.compiled`): the
        same iterates to rounding, each several times faster (step p99 under 20 ms).  Default
        (None): compiled where gcc is, unless ``$LSINDY_JIT=0``.  The first controller for a model
        (and options) compiles for 3-8 s per NLP (two with a ``gate``); cached on disk
        (``$LSINDY_CACHE_DIR``), later ones build in about 1 s.

    Attributes
    ----------
    ocp : OCP
        The problem each step solves (:class:`~lsindy_cas.control.ocp.OCP`).
    nlp : MultipleShootingNLP
        Its relaxed transcription and solvers (with a ``gate``: those the last step solved).
    correction : InputGainCorrection or None
        The online correction (None when ``adapt=False``).
    stats : MPCStats
        Solve counts and times, accumulated over episodes.
    reference : ndarray, shape (n_state,)
        The state ``ref`` the costs are measured from (zeros); may be set between steps.
    """

    #: failed recoveries in a row after which only every so many steps recover (0: every one)
    RECOVERY_BACKOFF = 3

    def __init__(self, ode, levels, *, input_index, stage_residual, terminal_residual, dt,
                 horizon, state_lb=None, state_ub=None, input_weight=1e-3, n_substeps=1,
                 solver="sqp", relaxation="continuous", rounding="lookahead", depth=4,
                 max_iter=7, tol=1e-4, accept_inexact=True, inexact_tol=1e-6,
                 lookahead_penalty=None, recovery=None, cold=None,
                 recover_after=None, adapt=True, adapt_forgetting=0.95, adapt_max_gain=0.5,
                 adapt_plan=True, solve_balanced=False, jit=None, coefficients=None,
                 gate=None):
        param_ode, p0 = (None, None) if coefficients is None else coefficients
        self.ocp = ocp = OCP(ode, levels, input_index, stage_residual, terminal_residual, dt,
                             horizon, state_lb, state_ub, input_weight, n_substeps, "force_set",
                             param_ode, p0)
        self.solver = check_choice("solver", solver, SOLVERS)
        self.relaxation = check_choice("relaxation", relaxation, ("poc", "continuous"))
        self.rounding = check_choice("rounding", rounding, (*ROUNDINGS, "lookahead"))
        self.recovery, self.cold, recover_solver, cold_solver = robust_solvers(recovery, cold)
        inexact_tol = check_real("inexact_tol", inexact_tol, positive=True)
        forgetting = check_real("adapt_forgetting", adapt_forgetting)
        if not 0 < forgetting <= 1:
            raise ValueError(f"adapt_forgetting must be in (0, 1], got {adapt_forgetting!r}.")
        max_gain = check_real("adapt_max_gain", adapt_max_gain, nonnegative=True)
        self.levels, self.dt, self.horizon = ocp.levels, ocp.dt, ocp.horizon
        self.n_state, self.n_input, self.input_index = ocp.n_state, ocp.n_input, ocp.input_index
        self.step_function, self.reference = ocp.step, np.zeros(ocp.n_state)
        max_iter = check_int("max_iter", max_iter, low=1)
        tol, jit = check_real("tol", tol, positive=True), resolve_jit(jit)
        if recover_after is None:  # continue: 3 (10: seed 0 mismatch start 15 ran 34 stale steps)
            recover_after = 3 if self.recovery == "continue" else 1
        self.recover_after = check_int("recover_after", recover_after, low=0)
        self.adapt, self.adapt_forgetting, self.adapt_max_gain = bool(adapt), forgetting, max_gain
        #: online correction of one-step predictions (None: ``adapt=False``), for every rule
        self.correction = (InputGainCorrection(self.step_function, self.input_index,
                                               forgetting=forgetting, max_gain=max_gain)
                           if self.adapt else None)
        if gate is not None and (coefficients is None or len(gate) not in (2, 3)):
            raise ValueError("gate needs coefficients (the estimate it lets into the plan) and "
                             "is (far, steps) or (far, steps, miss).")
        stall, miss = (None, None) if gate is None else (tuple(gate[:2]), (*gate[2:], None)[0])
        #: online estimate of the model's coefficients for the plan (None: ``coefficients``)
        self.estimator = None if coefficients is None else CoefficientEstimator(
            ocp.param_step, ocp.param_values, input_index=self.input_index, stall=stall, miss=miss)
        self._before_build()  # a subclass's own parts, checked before the heavy build
        self._lookahead = None
        if rounding == "lookahead":
            self._lookahead = build_lookahead(ocp, depth, lookahead_penalty)
            self.depth = int(depth)
            self._rounder = ROUNDINGS["nearest"](self.levels.size)
        else:
            self._rounder = ROUNDINGS[rounding](self.levels.size)
        nlp = (lambda o: MultipleShootingNLP(
            o, self.relaxation, self.solver, max_iter, tol, inexact_tol=inexact_tol,
            cold_solver=cold_solver, recover_solver=recover_solver, jit=jit))
        self.nlp = nlp(ocp)  # with a gate: (the model as given, its coefficients estimated)
        self._nlps = None if gate is None else (
            nlp(replace(ocp, param_ode=None, param_values=None)), self.nlp)
        self.accept_inexact, self.solve_balanced = bool(accept_inexact), bool(solve_balanced)
        self._rollout = self.step_function.mapaccum(self.horizon)
        self.adapt_plan = bool(adapt_plan) and self.adapt
        self.plan_gain_index = self.n_state // 2 + self.input_index
        self.stats = MPCStats()
        self.reset()

    def _before_build(self):
        """Hook: a subclass's own parts, once step and correction exist, before the NLP."""

    def reset(self):
        """Forget the warm start, the rounding memory and the online correction (call between
        episodes).

        :attr:`stats` keeps accumulating; use ``stats.clear()`` to reset it.
        """
        self._warm = None
        self._fallback = None  # shifted last applied plan while continuing a failed iterate
        self._failed = 0  # consecutive failed solves
        self._idle = 0  # steps decided by the own rule since the last solve
        self._rounder.reset()
        self.plan_ = None
        self._last = None  # (measured state, applied force) of the previous step
        if self.correction is not None:
            self.correction.reset()
        if self.estimator is not None:
            self.estimator.reset()
        if self._nlps is not None:
            self.nlp = self._nlps[0]

    def _weights(self, c):
        """Relaxed level weights (n_levels,) of one stage's control vector."""
        if self.relaxation == "poc":
            return np.asarray(c, dtype=float)
        return weights_from_value(float(c[0]), self.levels)

    def _forces(self, controls):
        """Relaxed input values (horizon,) of the stage control vectors (horizon, n_control)."""
        controls = np.asarray(controls, dtype=float)
        return controls @ self.levels if self.relaxation == "poc" else controls[:, 0]

    def _control_of_force(self, force):
        """Stage control vector representing the force ``force`` (an admissible level)."""
        if self.relaxation == "poc":
            return weights_from_value(force, self.levels)
        return np.array([force])

    def _cold_start(self, x):
        """Initial guess: roll the model out under a short push, then the level nearest zero.

        The push breaks the symmetry of rest states where every gradient of the cost vanishes
        (e.g. a pendulum hanging straight down).
        """
        zero = self.levels[np.argmin(np.abs(self.levels))]
        forces = np.full(self.horizon, zero)
        forces[: max(1, self.horizon // 10)] = self.levels[-1]
        u = np.zeros((self.n_input, self.horizon))
        u[self.input_index] = forces
        states = np.asarray(self._rollout(x, u)).T
        if not np.all(np.isfinite(states)):
            states = np.tile(x, (self.horizon, 1))
        controls = np.array([self._control_of_force(f) for f in forces])
        z = self.nlp.pack(controls, states)
        return z, np.zeros(self.nlp.lbg.size), np.zeros(z.size)

    def _choose_by_lookahead(self, x, controls, states):
        """Level index starting the cheapest discrete sequence (see :mod:`._lookahead`)."""
        forces = self._forces(controls)
        span = self.levels[-1] - self.levels[0]
        free = ((forces > self.levels[0] + 1e-3 * span)
                & (forces < self.levels[-1] - 1e-3 * span)).astype(float)
        # first move: the levels adjacent to the relaxed first input (or that level alone)
        w0 = weights_from_value(forces[0], self.levels)
        w0[w0 < 1e-2] = 0.0
        gain, bias = self._correction()
        cost = np.asarray(self._lookahead(x, states.T, forces[None, :], free[None, :],
                                          gain, bias, self.reference)).ravel()
        first = np.repeat(w0 > 0, self.levels.size ** (self.depth - 1))
        cost = np.where(first, cost, np.inf)
        if not np.any(np.isfinite(cost)):
            return self._rounder(w0)
        return int(np.argmin(cost)) // self.levels.size ** (self.depth - 1)

    def _own_level(self, x):
        """Level index chosen by a subclass's own rule at state ``x``, or None (default)."""
        return None

    @property
    def _uses_correction(self):
        """Whether something predicts with the online correction (here: the lookahead)."""
        return self._lookahead is not None

    def _correction(self):
        """Current online correction ``(gain, bias)`` of one-step predictions (zeros if off)."""
        if self.correction is not None:
            return self.correction.gain, self.correction.bias
        return np.zeros(self.n_state), np.zeros(self.n_state)

    def __call__(self, x):
        """Solve from state ``x`` (shape (n_state,)) and return the force to apply (a step
        that a subclass's own rule decides returns its level, without a solve unless
        ``solve_balanced``).

        Returns
        -------
        float
            Exactly one element of the admissible level set.
        """
        t_start, c_start = time.perf_counter(), time.thread_time()
        x = check_state(x, self.n_state)
        if self.correction is not None and self._uses_correction and self._last is not None:
            self.correction.update(*self._last, x)
        if self.estimator is not None and self._last is not None:  # with the plan made there
            plan = None if self._idle or self.plan_ is None else self.plan_["states"]
            self.estimator.update(*self._last, x, plan)
        index = self._own_level(x)
        if index is not None and not self.solve_balanced:
            return self._balanced_step(x, index, t_start, c_start)
        # robust solvers for a cold guess and after failures (not replaying an exhausted plan)
        f, b = self._failed - self.recover_after, self.RECOVERY_BACKOFF
        kind = ("cold" if self._warm is None else "recover"
                if f >= 0 and (not b or f < b or (f - b) % b == b - 1) else "warm")
        if self._idle:
            self._catch_up()
        z0, lam_g0, lam_x0 = self._cold_start(x) if self._warm is None else self._warm
        if self._fallback is not None:  # continuing a failed iterate: fall back on the plan
            zf, lgf, lxf = self._fallback
            if kind == "recover":  # IPOPT restarts from the last good plan
                z0, lam_g0, lam_x0 = zf, lgf, lxf
        else:
            zf, lgf, lxf = z0, lam_g0, lam_x0
        solver_kind = "warm" if kind == "cold" and self.cold == "warm" else kind
        t0, c0 = time.perf_counter(), time.thread_time()
        outcome, z, lam_g, lam_x, iters, status = self._solve(x, z0, lam_g0, lam_x0, solver_kind)
        if status == "unusable_guess" and kind != "cold":  # refused for fatrop: start over
            kind, solver_kind = "cold", "warm" if self.cold == "warm" else "cold"
            z0, lam_g0, lam_x0 = zf, lgf, lxf = self._cold_start(x)
            outcome, z, lam_g, lam_x, iters, status = self._solve(x, z0, lam_g0, lam_x0,
                                                                  solver_kind)
        if outcome == "inexact":
            self.stats.n_inexact += 1
        ok = outcome == "converged" or (outcome == "inexact" and self.accept_inexact)
        # an iterate worth continuing from: finite, gaps and bounds off by <= 1 (not diverged)
        finite = bool(status != "exception" and np.all(np.isfinite(z))
                      and np.all(np.isfinite(lam_g)) and np.all(np.isfinite(lam_x))
                      and self.nlp.last_violation <= 1.0)
        self.stats.solve_times.append(time.perf_counter() - t0)
        self.stats.solve_cpu_times.append(time.thread_time() - c0)
        self.stats.statuses[status] = self.stats.statuses.get(status, 0) + 1
        self.stats.iterations.append(iters)
        self.stats.solve_kinds.append(kind)
        self.stats.n_solves += 1
        self._failed = 0 if ok else self._failed + 1
        self._fallback = None
        if not ok:
            self.stats.n_failures += 1
            continued = finite and (self.recovery == "continue" or solver_kind != kind)
            if kind == "cold" and solver_kind == "warm" and finite:
                # no previous plan: the capped SQP iterate beats the rolled-out guess
                zf, lgf, lxf = z, lam_g, lam_x
            if continued:
                # warm-start the next step from the failed iterate (shifted below), keep
                # the plan applied now as the fallback of the next failure / IPOPT recovery
                self._fallback = self._shifted((zf, lgf, lxf))
                zc, lgc, lxc = z, lam_g, lam_x
            # apply the previous plan (already shifted into z0) and warm-start from it
            z, lam_g, lam_x = zf, lgf, lxf
        else:
            continued = False
        controls, states, _ = self.nlp.unpack(z)
        if index is not None:
            self.stats.n_balanced += 1
        elif self._lookahead is not None:
            index = self._choose_by_lookahead(x, controls, states)
        else:
            index = self._rounder(self._weights(controls[0]))
        self.plan_ = {"controls": controls, "forces": self._forces(controls), "states": states,
                      "success": ok}
        if continued:
            z, lam_g, lam_x = zc, lgc, lxc
        self._warm = self._shifted((z, lam_g, lam_x))
        return self._applied(x, index, t_start, c_start, kind)

    def _solve(self, x, z0, lam_g0, lam_x0, kind):
        """:meth:`MultipleShootingNLP.solve` and its status (``"exception"`` when the solver
        raised, e.g. NaN in a function evaluation of a bad model)."""
        try:
            gain = self.correction.gain[self.plan_gain_index] if self.adapt_plan else 0.0
            plan = {"gain": gain} if self.estimator is None else self.estimator.plan(gain)
            if self._nlps is not None:  # the solve's own NLP (the warm start fits both)
                self.nlp = self._nlps[self.estimator.released]
            return (*self.nlp.solve(x, z0, lam_g0, lam_x0, kind=kind, ref=self.reference, **plan),
                    self.nlp.last_status)
        except RuntimeError:
            return "failed", z0, lam_g0, lam_x0, -1, "exception"

    def _applied(self, x, index, t_start, c_start, kind):
        """Record the step (state and force for the online correction, step times, ``kind``
        of step) and return the force of level ``index``."""
        force = float(self.levels[index])
        self._last = (x, force)
        self.stats.step_kinds.append(kind)
        self.stats.step_times.append(time.perf_counter() - t_start)
        self.stats.step_cpu_times.append(time.thread_time() - c_start)
        return force

    def _shifted(self, plan):
        """A plan ``(z, lam_g, lam_x)`` shifted one interval ahead (the next step's warm start)."""
        z, lam_g, lam_x = plan
        zs, lgs = self.nlp.shift(z, lam_g)
        return zs, lgs, self.nlp.shift(lam_x, lam_g)[0]

    def _catch_up(self):
        """Shift the warm start (and the fallback plan) by the steps decided without a solve:
        at most ``horizon`` shifts, after which the plan repeats its last interval anyway."""
        self.stats.n_resumed += 1
        for _ in range(min(self._idle, self.horizon)):
            if self._warm is not None:
                self._warm = self._shifted(self._warm)
            if self._fallback is not None:
                self._fallback = self._shifted(self._fallback)
        self._idle = 0

    def _balanced_step(self, x, index, t_start, c_start):
        """A step decided by the subclass's own rule without solving the NLP
        (``solve_balanced=False``); the plan is shifted by one interval per such step before
        the next solve (:meth:`_catch_up`), to stay aligned in time."""
        self.stats.n_balanced += 1
        self._idle += 1  # the plan is shifted by as many intervals when the next solve runs
        return self._applied(x, index, t_start, c_start, "balanced")
