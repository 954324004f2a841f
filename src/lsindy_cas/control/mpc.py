"""The generic part of :mod:`lsindy_cas.mpc`: a discrete-input MPC on any CasADi ODE.

:class:`DiscreteInputMPC` is a multiple-shooting MPC on any ``casadi.Function``
``ode(x, u) -> xdot`` whose actuated input may only take values from a finite set.  Each step
solves a relaxation (partial outer convexification: one weight per admissible level, the weights
summing to 1; or a continuous input) warm-started from the shifted previous solution, then turns
the first interval's relaxed decision into one admissible level: by enumerating short discrete
sequences against the relaxed plan's cost-to-go (:mod:`lsindy_cas.control.lookahead`, the default), by
sum-up rounding with the rounding error carried across steps, or by plain rounding
(:mod:`lsindy_cas.control.rounding`).  A failed or non-converged solve falls back to the shifted
previous plan, is counted in :attr:`DiscreteInputMPC.stats`, and the next step re-solves with the
robust solver.
"""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from .ocp import SOLVERS, MultipleShootingNLP, rk4_step
from .lookahead import build_lookahead
from .rounding import ROUNDINGS, weights_from_value

__all__ = ["DiscreteInputMPC", "MPCStats", "wrap_angle"]


def wrap_angle(a):
    """Angle(s) in radians mapped to ``[-pi, pi)``."""
    return (np.asarray(a, dtype=float) + np.pi) % (2 * np.pi) - np.pi


@dataclass
class MPCStats:
    """Counters of an MPC's solves, accumulated over episodes until :meth:`clear`.

    Attributes
    ----------
    n_solves : int
        NLP solves attempted (one per control step).
    n_failures : int
        Solves that failed or did not converge to a usable plan; each applied the shifted
        previous plan instead.
    n_inexact : int
        Solves stopped by the iteration cap whose iterate satisfied every constraint (dynamics,
        bounds) to ``inexact_tol``; applied when ``accept_inexact=True``, else counted as
        failures too.
    solve_times : list of float
        Wall-clock seconds per solve (the solver call only).
    solve_cpu_times : list of float
        CPU seconds of the calling thread per solve: unlike the wall-clock time, not inflated
        when other processes compete for the cores.
    step_times : list of float
        Wall-clock seconds per controller call (solve + warm start + rounding + checks).
    n_balanced : int
        Steps whose level was chosen by a subclass's own rule instead of from the relaxed plan
        (:class:`~lsindy_cas.mpc.SwingUpMPC`: the pulse balancer near the upright).
    iterations : list of int
        Solver iterations per solve.
    solve_kinds : list of str
        Which solver ran each solve: ``"warm"`` (the warm-started solver), ``"cold"`` (IPOPT,
        first step of an episode) or ``"recover"`` (IPOPT after a failed step).
    statuses : dict
        Count of each solver return status.
    """

    n_solves: int = 0
    n_failures: int = 0
    n_inexact: int = 0
    n_balanced: int = 0
    solve_times: list = field(default_factory=list)
    solve_cpu_times: list = field(default_factory=list)
    step_times: list = field(default_factory=list)
    iterations: list = field(default_factory=list)
    solve_kinds: list = field(default_factory=list)
    statuses: dict = field(default_factory=dict)

    def clear(self):
        """Reset all counters."""
        self.__init__()

    def summary(self):
        """Dictionary of counts and solve-time percentiles in milliseconds (overall, and count,
        median and maximum per solve kind under ``"by_kind"``) and the solver statuses."""
        t = np.asarray(self.solve_times) * 1e3
        kinds = np.asarray(self.solve_kinds, dtype=object)  # appended with solve_times
        by_kind = {k: {"n": int(np.sum(kinds == k)),
                       "solve_ms_median": float(np.median(t[kinds == k])),
                       "solve_ms_max": float(t[kinds == k].max())}
                   for k in ("warm", "cold", "recover") if np.any(kinds == k)}
        c = np.asarray(self.solve_cpu_times) * 1e3
        s = np.asarray(self.step_times) * 1e3
        pct = (lambda a, q: float(np.percentile(a, q)) if a.size else float("nan"))
        return {"n_solves": self.n_solves, "n_failures": self.n_failures,
                "n_inexact": self.n_inexact, "n_balanced": self.n_balanced,
                "solve_ms_median": pct(t, 50), "solve_ms_p99": pct(t, 99),
                "solve_ms_max": float(t.max()) if t.size else float("nan"),
                "solve_cpu_ms_median": pct(c, 50), "solve_cpu_ms_p99": pct(c, 99),
                "step_ms_median": pct(s, 50), "step_ms_p99": pct(s, 99),
                "iterations_median": pct(np.asarray(self.iterations), 50), "by_kind": by_kind,
                "statuses": dict(self.statuses)}


def _check_levels(force_set):
    """Validated, sorted, unique admissible levels as a float array."""
    if isinstance(force_set, (str, bytes)) or not np.iterable(force_set):
        raise TypeError("force_set must be a sequence of numbers, e.g. (-10.0, 0.0, 10.0).")
    items = list(force_set)
    if not items:
        raise ValueError("force_set is empty; give at least one admissible force.")
    for v in items:
        if isinstance(v, bool) or not isinstance(v, numbers.Real):
            raise TypeError(f"force_set must contain only real numbers, got {v!r}.")
    levels = np.unique(np.asarray(items, dtype=float))
    if not np.all(np.isfinite(levels)):
        raise ValueError("force_set must contain only finite numbers.")
    return levels


def _check_positive(name, value, integer=False):
    kind = numbers.Integral if integer else numbers.Real
    if isinstance(value, bool) or not isinstance(value, kind):
        raise TypeError(f"{name} must be {'an integer' if integer else 'a number'}, "
                        f"got {value!r}.")
    if not value > 0 or not math.isfinite(value):
        raise ValueError(f"{name} must be {'>= 1' if integer else 'positive and finite'}, "
                         f"got {value!r}.")
    return int(value) if integer else float(value)


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
        ``x -> r`` (least-squares costs); the objective is
        ``sum_k dt * (|r(x_k)|^2 + input penalty) + |r_N(x_N)|^2``.
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
        QPs, SQP with a Gauss-Newton Hessian, fatrop or IPOPT (see ``benchmarks/bench_mpc.py``
        for the comparison that chose the default).
    relaxation : {"continuous", "poc"}
        A continuous input in ``[min, max]`` (default), or partial outer convexification:
        one weight per level, summing to 1.  For an ODE affine in the input both relax to
        the same convex hull; the continuous one has fewer variables and was as successful
        and faster in ``benchmarks/bench_mpc.py``.  The weights of a continuous input are
        those of its two adjacent levels (:func:`~lsindy_cas.control.rounding.weights_from_value`).
    rounding : {"lookahead", "sur", "nearest"}
        How the applied level is chosen: lookahead over all discrete sequences of ``depth``
        intervals (first move among the levels adjacent to the relaxed first input), sum-up
        rounding carried across steps, or plain rounding to the largest weight (= the
        nearest level for the continuous relaxation).
    depth : int
        Lookahead depth in control intervals (``n_levels**depth`` sequences).
    max_iter : int
        Iteration cap per warm-started solve.  The first solve of an episode (from a cold
        guess) and recovery solves (see ``recover_after``) use IPOPT with
        ``max(10 * max_iter, 300)`` iterations.
    tol : float
        Solver tolerance.
    accept_inexact : bool
        Apply a capped solve's iterate if it satisfies every constraint to ``inexact_tol``
        (counted in ``stats.n_inexact``); otherwise such a solve is a failure (fallback).
    inexact_tol : float
        Constraint violation (shooting defects in state units, bounds) up to which a capped
        solve's iterate is applied.  In the swing-up benchmarks every warm SQP failure was
        the iteration cap with violations of 1e-6 to 1.1e-3 (median 5e-5), each followed by
        a ~42 ms IPOPT recovery.  Raising this to 1e-3 cut the fallbacks on 20 nominal
        starts from 45 to 2 and the solve-time p99 from 37 to about 22 ms, with 20/20 in
        each scenario on seeds 0 and 1, but on the larger robustness samples it lost
        starts: 77/80 mismatched starts (79/80 at 1e-6; two new failures at |x| = 2.00 and
        2.02 m) and 157/160 in ``benchmarks/swingup_ceiling.py`` (158/160); 1e-4 gave
        78/80 and 158/160.  So the default stays strict.
    recover_after : int
        After this many failed solves in a row the next solve is a recovery solve (IPOPT)
        from the shifted plan.
    lookahead_penalty : casadi.Function, optional
        ``x -> scalar`` added to the cost of every state the lookahead enumerates.
    adapt : bool
        Correct the lookahead's predictions online (offset-free MPC against plant/model
        mismatch): per state component, recursive least squares fits the one-step prediction
        errors of the measured states as ``gain * (F(x, u) - F(x, 0)) + bias`` and the
        enumerated steps use ``F(x, u) + gain * (F(x, u) - F(x, 0)) + bias``.  With ±10 %
        mass/length mismatch this raised swing-up success on 20 starts from 80 % to 85 %.
    adapt_forgetting : float
        RLS forgetting factor in (0, 1].
    adapt_max_gain : float
        Bound on ``|gain|``.
    """

    def __init__(self, ode, levels, *, input_index, stage_residual, terminal_residual, dt,
                 horizon, state_lb=None, state_ub=None, input_weight=1e-3, n_substeps=1,
                 solver="sqp", relaxation="continuous", rounding="lookahead", depth=4,
                 max_iter=10, tol=1e-4, accept_inexact=True, inexact_tol=1e-6,
                 lookahead_penalty=None,
                 recover_after=1, adapt=True, adapt_forgetting=0.95, adapt_max_gain=0.5):
        if not isinstance(ode, ca.Function):
            raise TypeError(f"ode must be a casadi.Function, got {type(ode).__name__}.")
        self.levels = _check_levels(levels)
        self.dt = _check_positive("dt", dt)
        self.horizon = _check_positive("horizon", horizon, integer=True)
        n_substeps = _check_positive("n_substeps", n_substeps, integer=True)
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {solver!r}.")
        if relaxation not in ("poc", "continuous"):
            raise ValueError(f"relaxation must be 'poc' or 'continuous', got {relaxation!r}.")
        if rounding not in (*ROUNDINGS, "lookahead"):
            raise ValueError(f"rounding must be one of {(*ROUNDINGS, 'lookahead')}, "
                             f"got {rounding!r}.")
        self.n_state, self.n_input = ode.size1_in(0), ode.size1_in(1)
        if not 0 <= input_index < self.n_input:
            raise ValueError(f"input_index must be in [0, {self.n_input}), got {input_index}.")
        self.input_index = int(input_index)
        inf = np.full(self.n_state, np.inf)
        lb = -inf if state_lb is None else np.asarray(state_lb, dtype=float)
        ub = inf if state_ub is None else np.asarray(state_ub, dtype=float)
        self.step_function = rk4_step(ode, self.n_state, self.n_input, self.dt, n_substeps)
        self.nlp = MultipleShootingNLP(
            self.step_function, self.n_state, self.n_input, self.input_index, self.levels,
            self.horizon, self.dt, stage_residual, terminal_residual, float(input_weight), lb,
            ub, relaxation, solver, int(max_iter), float(tol),
            inexact_tol=_check_positive("inexact_tol", inexact_tol))
        self.solver, self.relaxation, self.rounding = solver, relaxation, rounding
        self.accept_inexact = bool(accept_inexact)
        self.recover_after = int(recover_after)
        self._lookahead = None
        if rounding == "lookahead":
            self.depth = _check_positive("depth", depth, integer=True)
            if self.depth >= self.horizon:
                raise ValueError(f"depth must be smaller than horizon ({self.horizon}), "
                                 f"got {depth}.")
            self._lookahead = build_lookahead(
                self.step_function, self.n_state, self.n_input, self.input_index,
                self.levels, self.horizon, self.depth, self.dt, stage_residual,
                terminal_residual, float(input_weight), lb, ub, lookahead_penalty)
            self._rounder = ROUNDINGS["nearest"](self.levels.size)
        else:
            self._rounder = ROUNDINGS[rounding](self.levels.size)
        self._rollout = self.step_function.mapaccum(self.horizon)
        self.adapt = bool(adapt)
        self.adapt_forgetting = float(adapt_forgetting)
        self.adapt_max_gain = float(adapt_max_gain)
        if not 0 < self.adapt_forgetting <= 1:
            raise ValueError(f"adapt_forgetting must be in (0, 1], got {adapt_forgetting!r}.")
        self.stats = MPCStats()
        self.reset()

    # --- episode state ---------------------------------------------------------------
    def reset(self):
        """Forget the warm start and the rounding memory (call between episodes).

        :attr:`stats` keeps accumulating; use ``stats.clear()`` to reset it.
        """
        self._warm = None
        self._failed = 0  # consecutive failed solves
        self._rounder.reset()
        self.plan_ = None
        self._last = None  # (measured state, applied force) of the previous step
        # per state component: RLS estimate of [gain, bias] and its 2x2 covariance
        self._theta = np.zeros((self.n_state, 2))
        self._cov = np.tile(np.diag([1.0, 1e-2]), (self.n_state, 1, 1))

    def _update_correction(self, x):
        """Fit ``x - F(x_prev, u) = gain * (F(x_prev, u) - F(x_prev, 0)) + bias`` per component.

        Recursive least squares with forgetting on the one-step prediction errors of the
        measured states: an online estimate of the input-gain error and an additive offset
        (offset-free MPC against plant/model mismatch), used by the lookahead.
        """
        if self._last is None:
            return
        x_prev, force = self._last
        u = np.zeros(self.n_input)
        u[self.input_index] = force
        x_u = np.asarray(self.step_function(x_prev, u)).ravel()
        x_0 = np.asarray(self.step_function(x_prev, np.zeros(self.n_input))).ravel()
        err = x - x_u
        lam = self.adapt_forgetting
        for i in range(self.n_state):
            phi = np.array([x_u[i] - x_0[i], 1.0])
            P = self._cov[i]
            Pphi = P @ phi
            k = Pphi / (lam + phi @ Pphi)
            self._theta[i] += k * (err[i] - phi @ self._theta[i])
            self._cov[i] = (P - np.outer(k, Pphi)) / lam
            np.clip(self._cov[i], -1e3, 1e3, out=self._cov[i])
        np.clip(self._theta[:, 0], -self.adapt_max_gain, self.adapt_max_gain,
                out=self._theta[:, 0])

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
        # candidates for the first move: the levels adjacent to the relaxed first input
        # (the dynamics are affine in it), or that level alone if it is (almost) one
        w0 = weights_from_value(forces[0], self.levels)
        w0[w0 < 1e-2] = 0.0
        gain, bias = self._correction()
        cost = np.asarray(self._lookahead(x, states.T, forces[None, :], free[None, :],
                                          gain, bias)).ravel()
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
        if self.adapt:
            return self._theta[:, 0], self._theta[:, 1]
        return np.zeros(self.n_state), np.zeros(self.n_state)

    def _check_state(self, x):
        try:
            x = np.asarray(x, dtype=float).ravel()
        except (TypeError, ValueError):
            raise TypeError("x must be a sequence of numbers (the state [q, q_dot]).") from None
        if x.size != self.n_state:
            raise ValueError(f"x must have {self.n_state} entries [q, q_dot], got {x.size}.")
        if not np.all(np.isfinite(x)):
            raise ValueError(f"x must be finite, got {x.tolist()}.")
        return x

    # --- one control step ------------------------------------------------------------
    def __call__(self, x):
        """Solve from state ``x`` (shape (n_state,)) and return the force to apply.

        Returns
        -------
        float
            Exactly one element of the admissible level set.
        """
        t_start = time.perf_counter()
        x = self._check_state(x)
        if self.adapt and self._uses_correction:
            self._update_correction(x)
        # robust solvers for a cold guess, and after failures (so that a run of failures
        # cannot keep replaying an exhausted plan)
        kind = ("cold" if self._warm is None else
                "recover" if self._failed >= self.recover_after else "warm")
        z0, lam_g0, lam_x0 = self._cold_start(x) if self._warm is None else self._warm
        t0, c0 = time.perf_counter(), time.thread_time()
        try:
            outcome, z, lam_g, lam_x, iters = self.nlp.solve(x, z0, lam_g0, lam_x0, kind=kind)
            status = self.nlp.last_status
        except RuntimeError:  # e.g. NaN in a function evaluation of a bad model
            outcome, z, lam_g, lam_x, iters = "failed", z0, lam_g0, lam_x0, -1
            status = "exception"
        if outcome == "inexact":
            self.stats.n_inexact += 1
        ok = outcome == "converged" or (outcome == "inexact" and self.accept_inexact)
        self.stats.solve_times.append(time.perf_counter() - t0)
        self.stats.solve_cpu_times.append(time.thread_time() - c0)
        self.stats.statuses[status] = self.stats.statuses.get(status, 0) + 1
        self.stats.iterations.append(iters)
        self.stats.solve_kinds.append(kind)
        self.stats.n_solves += 1
        self._failed = 0 if ok else self._failed + 1
        if not ok:
            # apply the previous plan (already shifted into z0) and warm-start from it
            self.stats.n_failures += 1
            z, lam_g, lam_x = z0, lam_g0, lam_x0
        controls, states, _ = self.nlp.unpack(z)
        index = self._own_level(x)
        if index is not None:
            self.stats.n_balanced += 1
        elif self._lookahead is not None:
            index = self._choose_by_lookahead(x, controls, states)
        else:
            index = self._rounder(self._weights(controls[0]))
        force = float(self.levels[index])
        self._last = (x, force)
        self.plan_ = {"controls": controls, "forces": self._forces(controls), "states": states,
                      "success": ok}
        zs, lgs = self.nlp.shift(z, lam_g)
        self._warm = (zs, lgs, self.nlp.shift(lam_x, lam_g)[0])
        self.stats.step_times.append(time.perf_counter() - t_start)
        return force
