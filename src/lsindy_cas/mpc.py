"""Model-predictive control with a discrete input set on a CasADi ODE (paper Sec. III-C, Fig. 5).

:class:`DiscreteInputMPC` is a multiple-shooting MPC on any ``casadi.Function``
``ode(x, u) -> xdot`` whose actuated input may only take values from a finite set.  Each step
solves a relaxation (partial outer convexification: one weight per admissible level, the weights
summing to 1; or a continuous input) warm-started from the shifted previous solution, then rounds
the first interval's relaxed decision to one admissible level, carrying the rounding error across
steps (sum-up rounding, see :mod:`lsindy_cas._rounding`).  A failed or non-converged solve falls
back to the shifted previous plan and is counted in :attr:`DiscreteInputMPC.stats`.

:class:`SwingUpMPC` builds the swing-up cost for an identified (or known) cart-pendulum: the
actuated coordinate is the cart, the other the pole, and the upright angle is the unstable rest
equilibrium of the model's own ODE unless given.
"""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ._ocp import SOLVERS, MultipleShootingNLP, rk4_step
from ._lookahead import build_lookahead
from ._rounding import ROUNDINGS, weights_from_value

__all__ = ["DiscreteInputMPC", "MPCStats", "SwingUpMPC", "find_upright"]


@dataclass
class MPCStats:
    """Counters of an MPC's solves, accumulated over episodes until :meth:`clear`.

    Attributes
    ----------
    n_solves : int
        NLP solves attempted (one per control step).
    n_failures : int
        Solves that failed or did not converge; each used the shifted previous plan instead.
    solve_times : list of float
        Wall-clock seconds per solve (the solver call only).
    step_times : list of float
        Wall-clock seconds per controller call (solve + warm start + rounding + checks).
    iterations : list of int
        Solver iterations per solve.
    statuses : dict
        Count of each solver return status.
    """

    n_solves: int = 0
    n_failures: int = 0
    solve_times: list = field(default_factory=list)
    step_times: list = field(default_factory=list)
    iterations: list = field(default_factory=list)
    statuses: dict = field(default_factory=dict)

    def clear(self):
        """Reset all counters."""
        self.__init__()

    def summary(self):
        """Dictionary of counts and solve-time percentiles in milliseconds."""
        t = np.asarray(self.solve_times) * 1e3
        s = np.asarray(self.step_times) * 1e3
        pct = (lambda a, q: float(np.percentile(a, q)) if a.size else float("nan"))
        return {"n_solves": self.n_solves, "n_failures": self.n_failures,
                "solve_ms_median": pct(t, 50), "solve_ms_p99": pct(t, 99),
                "solve_ms_max": float(t.max()) if t.size else float("nan"),
                "step_ms_median": pct(s, 50), "step_ms_p99": pct(s, 99),
                "iterations_median": pct(np.asarray(self.iterations), 50)}


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
        Bounds imposed on every predicted state after the first.
    input_weight : float
        Weight of the normalised input penalty.
    n_substeps : int
        RK4 steps per control interval.
    solver : {"fatrop", "ipopt", "sqp-hpipm"}
        NLP solver; fatrop (structure-exploiting interior point) was fastest in
        ``benchmarks/bench_mpc.py``.
    relaxation : {"poc", "continuous"}
        Outer-convexified weights per level, or a continuous input in ``[min, max]``.
    rounding : {"sur", "nearest"}
        Sum-up rounding carried across steps, or plain rounding to the largest weight /
        nearest level.
    max_iter : int
        Iteration cap per solve; hitting it counts as a failure (fallback).
    tol : float
        Solver tolerance.
    """

    def __init__(self, ode, levels, *, input_index, stage_residual, terminal_residual, dt,
                 horizon, state_lb=None, state_ub=None, input_weight=1e-3, n_substeps=1,
                 solver="fatrop", relaxation="poc", rounding="lookahead", depth=4,
                 max_iter=60, tol=1e-4):
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
            ub, relaxation, solver, int(max_iter), float(tol))
        self.solver, self.relaxation, self.rounding = solver, relaxation, rounding
        self._lookahead = None
        if rounding == "lookahead":
            self.depth = _check_positive("depth", depth, integer=True)
            if self.depth >= self.horizon:
                raise ValueError(f"depth must be smaller than horizon ({self.horizon}), "
                                 f"got {depth}.")
            self._lookahead = build_lookahead(
                self.step_function, self.n_state, self.n_input, self.input_index,
                self.levels, self.horizon, self.depth, self.dt, stage_residual,
                terminal_residual, float(input_weight), lb, ub)
            self._rounder = ROUNDINGS["nearest"](self.levels.size)
        else:
            self._rounder = ROUNDINGS[rounding](self.levels.size)
        self._rollout = self.step_function.mapaccum(self.horizon)
        self.stats = MPCStats()
        self.reset()

    # --- episode state ---------------------------------------------------------------
    def reset(self):
        """Forget the warm start and the rounding memory (call between episodes).

        :attr:`stats` keeps accumulating; use ``stats.clear()`` to reset it.
        """
        self._warm = None
        self._rounder.reset()
        self.plan_ = None

    def _weights(self, c):
        """Relaxed level weights (n_levels,) of one stage's control vector."""
        if self.relaxation == "poc":
            return np.asarray(c, dtype=float)
        return weights_from_value(float(c[0]), self.levels)

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
        forces = np.array([self._weights(c) @ self.levels for c in controls])
        span = self.levels[-1] - self.levels[0]
        free = ((forces > self.levels[0] + 1e-3 * span)
                & (forces < self.levels[-1] - 1e-3 * span)).astype(float)
        cost = np.asarray(self._lookahead(x, states.T, forces[None, :], free[None, :])).ravel()
        if not np.all(np.isfinite(cost)):
            return self._rounder(self._weights(controls[0]))
        return int(np.argmin(cost)) // self.levels.size ** (self.depth - 1)

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
        z0, lam_g0, lam_x0 = self._warm if self._warm is not None else self._cold_start(x)
        t0 = time.perf_counter()
        try:
            ok, z, lam_g, lam_x, iters = self.nlp.solve(x, z0, lam_g0, lam_x0)
            status = self.nlp.last_status
        except RuntimeError:  # e.g. NaN in a function evaluation of a bad model
            ok, z, lam_g, lam_x, iters = False, z0, lam_g0, lam_x0, -1
            status = "exception"
        self.stats.statuses[status] = self.stats.statuses.get(status, 0) + 1
        self.stats.solve_times.append(time.perf_counter() - t0)
        self.stats.iterations.append(iters)
        self.stats.n_solves += 1
        if not ok:
            self.stats.n_failures += 1
            # fall back to the previous plan, already shifted into the warm start
            z, lam_g, lam_x = z0, lam_g0, lam_x0
        controls, states = self.nlp.unpack(z)
        if self._lookahead is not None:
            index = self._choose_by_lookahead(x, controls, states)
        else:
            index = self._rounder(self._weights(controls[0]))
        force = float(self.levels[index])
        self.plan_ = {"controls": controls, "states": states, "success": ok}
        zs, lgs = self.nlp.shift(z, lam_g)
        self._warm = (zs, lgs, np.zeros_like(lam_x) if not ok else
                      self.nlp.shift(lam_x, lam_g)[0])
        self.stats.step_times.append(time.perf_counter() - t_start)
        return force


def find_upright(ode, cart_index, pole_index, n_grid=720):
    """Pole angle of the unstable rest equilibrium of a cart-pendulum ODE.

    Scans the pole's angular acceleration at rest with zero input over one revolution;
    equilibria are its zeros, and the upright one is where it increases with the angle
    (a displacement accelerates away).  Works for any angle convention of the model.

    Parameters
    ----------
    ode : casadi.Function
        ``(x (4,), u (2,)) -> xdot (4,)``, state ``[q, q_dot]``.
    cart_index, pole_index : int
        Positions of the cart and pole coordinates in ``q``.
    n_grid : int
        Grid points per revolution.

    Returns
    -------
    float
        Upright angle in ``[-pi, pi)``, radians.

    Raises
    ------
    ValueError
        If there is not exactly one unstable rest equilibrium per revolution.
    """
    grid = np.linspace(-np.pi, np.pi, n_grid, endpoint=False)
    x = np.zeros((4, n_grid))
    x[pole_index] = grid
    acc = np.asarray(ode.map(n_grid)(x, np.zeros((2, n_grid))))[2 + pole_index]
    nxt = np.roll(acc, -1)
    ups = np.flatnonzero((acc < 0) & (nxt >= 0))
    if ups.size != 1 or not np.all(np.isfinite(acc)):
        raise ValueError("could not determine the upright angle from the model (expected one "
                         "unstable rest equilibrium of the pole); pass upright= explicitly.")
    i = ups[0]
    step = 2 * np.pi / n_grid
    angle = grid[i] + step * acc[i] / (acc[i] - nxt[i])
    return float((angle + np.pi) % (2 * np.pi) - np.pi)


class SwingUpMPC(DiscreteInputMPC):
    """Swing-up MPC for a cart-pendulum model, the force restricted to ``force_set``.

    Parameters
    ----------
    model : object
        An identified :class:`~lsindy_cas.LagrangianSINDy` (or any object with ``coords_`` or
        ``coords``, ``actuated_`` or ``actuated``, and ``ode()``) with exactly two coordinates:
        the actuated one is the cart position (m), the other the pole angle (rad).
    force_set : sequence of float
        Admissible cart forces in newtons.
    dt : float
        Control period in seconds.
    horizon : int
        Prediction horizon in control periods.
    track_limit : float
        The cart must stay in ``|x| <= track_limit`` (m), imposed on all predicted states.
    upright : float, optional
        Upright pole angle; by default the unstable rest equilibrium of the model's ODE
        (:func:`find_upright`), which is pi for the downward-zero convention.
    actuated : str, optional
        Name of the cart coordinate, overriding the model's ``actuated_``.
    weights : dict, optional
        Cost weights ``{"angle", "position", "velocity", "rate", "terminal", "input"}``.
    **options
        Passed to :class:`DiscreteInputMPC` (``solver``, ``relaxation``, ``rounding``,
        ``n_substeps``, ``max_iter``, ``tol``).
    """

    default_weights = {"angle": 10.0, "position": 1.0, "velocity": 0.1, "rate": 0.1,
                       "terminal": 10.0, "input": 1e-2}

    def __init__(self, model, force_set=(-10.0, 0.0, 10.0), *, dt=0.05, horizon=40,
                 track_limit=2.0, upright=None, actuated=None, weights=None, **options):
        coords = getattr(model, "coords_", None) or getattr(model, "coords", None)
        if coords is None or not hasattr(model, "ode"):
            raise TypeError("model must be a fitted cart-pendulum model with coords_ and ode().")
        coords = list(coords)
        if len(coords) != 2:
            raise ValueError(f"model must have exactly two coordinates (cart, pole), got "
                             f"{coords}.")
        if actuated is None:
            act = getattr(model, "actuated_", None) or getattr(model, "actuated", None) or []
            act = [a for a in act if a in coords]
            if len(act) != 1:
                raise ValueError(f"model must have exactly one actuated coordinate (the cart), "
                                 f"got {act}; pass actuated= to choose one.")
            actuated = act[0]
        if actuated not in coords:
            raise ValueError(f"actuated must be one of {coords}, got {actuated!r}.")
        self.track_limit = _check_positive("track_limit", track_limit)
        self.coords, self.cart = coords, actuated
        ic = coords.index(actuated)
        ip = 1 - ic
        ode = model.ode()
        if not isinstance(ode, ca.Function) or ode.size1_in(0) != 4 or ode.size1_in(1) != 2:
            raise ValueError("model.ode() must be a casadi.Function (x (4,), u (2,)) -> xdot.")
        if upright is None:
            upright = find_upright(ode, ic, ip)
        self.upright = float(upright)
        w = dict(self.default_weights, **(weights or {}))
        x = ca.SX.sym("x", 4)
        # 1 - cos(a) = 2 sin(a/2)^2: a residual whose square is wrap-invariant
        r = ca.vertcat(ca.sqrt(2 * w["angle"]) * ca.sin((x[ip] - self.upright) / 2),
                       ca.sqrt(w["position"]) * x[ic] / self.track_limit,
                       ca.sqrt(w["velocity"]) * x[2 + ic], ca.sqrt(w["rate"]) * x[2 + ip])
        lb = np.full(4, -np.inf)
        ub = np.full(4, np.inf)
        lb[ic], ub[ic] = -self.track_limit, self.track_limit
        super().__init__(ode, force_set, input_index=ic,
                         stage_residual=ca.Function("r", [x], [r]),
                         terminal_residual=ca.Function("rN", [x], [ca.sqrt(w["terminal"]) * r]),
                         dt=dt, horizon=horizon, state_lb=lb, state_ub=ub,
                         input_weight=w["input"], **options)
        self.cart_index, self.pole_index = ic, ip
