"""One controller from a model and a task: :class:`Controller`.

``Controller(model, task)`` builds everything once:

1. :class:`~.system.ControlledSystem` — the model under the task's inputs (discrete map, energy,
   angles, kinetic check);
2. for a target goal, the input that holds the target and a :class:`~.local.LocalPolicy` from the
   model's linearisation there, with the region (a level of its cost-to-go) inside which it takes
   over;
3. a :class:`~.search.BeamSearch` over the task's input levels that drives the state into that
   region (or into the reach condition), guided by the identified energy: the heuristic is the
   energy's distance from the goal's energy plus the distance from the target.

Calling it with a state returns the inputs (one per task input, in task order).  Nothing here
names a coordinate or a system; system-specific know-how can be passed as a ``plugin`` (an
object with ``build(model, task, controller) -> policy``, the policy having ``reset()`` and
``__call__(x)``), see :mod:`~.plugins`.
"""
from __future__ import annotations

from dataclasses import dataclass
import itertools

import numpy as np

from .._validate import check_state
from .compiled import resolve_jit
from .local import LocalPolicy, equilibrium_input
from .nlp_planner import NLPPlanner, NLPSettings, check_nlp_task
from .search import BeamSearch, maybe_compiled
from .system import ControlledSystem
from .task import Task

__all__ = ["Controller", "ControllerSettings"]


@dataclass(frozen=True)
class ControllerSettings:
    """How the controller searches and stabilises (the task says what; these say how).

    Parameters
    ----------
    horizon : float
        Longest plan the swing-up search makes, in seconds (rounded up to whole samples); the
        search stops at the first sample that enters the goal region, so this is only a cap.
    max_depth : int
        Cap on the plan's samples (a search that enters no region runs them all: 400 samples
        take ~0.4 s on the Furuta pendulum).  Plans into the region took 60-73 samples on the
        Acrobot, 270-400 on the Furuta pendulum at 0.01 s and 45-90 on gymnasium's
        InvertedDoublePendulum.
    width : int
        Partial input sequences the search keeps per sample.
    cells : int
        The search keeps at most one sequence per cell of a grid that splits each state's
        spread into ``cells`` (diversity: gymnasium's Acrobot, 30 starts, width 64, took 63.6
        steps to the goal on average with 10 cells and 71.3 with 20; offline plans from 8
        starts at width 256 took 76.5 steps without the grid).
    local_depth : int
        Samples of the discrete sequences the local policy scores (capped at 729 sequences).
    energy_weight : float
        Weight of the energy term in the search heuristic (the distance term has weight 1).
    distance_weight : float
        For a target goal, the heuristic is ``energy_weight ((E − E*)/E_s)² + distance_weight
        log10(max(V/c, 1))`` (E the energy with the actuated rates at zero, V the local
        policy's cost-to-go, c its region level).  0.1: the Furuta pendulum's plans from 3
        hanging starts entered the region in 2.7-2.9 s; 0.02 and 0.46 missed it in 2 of 3
        within 4 s; a quadratic distance in place of the logarithm missed all 3.
    reach_weight : float
        For a reach goal, the heuristic is ``-(energy_weight E/E_s + reach_weight g/g_s)``
        (energy and the condition's margin g, each over its spread): the search pumps energy
        and prefers states nearer the condition.  0.3: Acrobot offline plans 61 steps on
        average vs 77 at 1 and 86 at 10 (8 starts).
    handover : float
        The local policy keeps control until its cost-to-go exceeds ``handover`` × its region
        level (hysteresis: it is not handed back at the region's edge on every sample).
    budget : int or None
        Samples the swing-up search expands per call (anytime search, a bound on the work of
        one control step that does not depend on the machine).  For a reach goal a search
        longer than that goes on over several calls: meanwhile the inputs applied are the
        previous plan's (or, with none, the best partial sequence's) and the search keeps only
        the sequences that begin with them, so its plan, adopted when it ends, starts where
        they leave off.  8: gymnasium's Acrobot, 20 starts, 66.0 steps to the goal on average
        (12: 68.2; unbounded: 62.7 over 100).  None: every search runs to its end in the call
        that starts it.
    replan_budget : int or None
        For a target goal the search restarts from the measured state at every call, with
        this many samples, and applies its best partial sequence's first input until one
        enters the local policy's region (then that plan is kept while it still does): plans
        into the region of gymnasium's InvertedDoublePendulum missed it again after one sample
        (their closest approach 5-100 times the region's level), and finishing them over
        several calls held 15-17 of 20 swing-ups where restarting held 19-20.  24 samples:
        20/20 held (16: 19/20, 12: 8/20).  None: as for ``budget``.
    seed : int
        Seed of the random sample states the build uses (region estimate, checks).
    jit : bool or None
        Compile the search's model map to C (None: where gcc is, or as ``$LSINDY_JIT`` says;
        :func:`~.compiled.resolve_jit`).
    planner : {"beam", "nlp"}
        What drives the state into the local policy's region: the beam search above, or the
        relaxed multiple-shooting NLP with energy shaping (:mod:`~.nlp_planner`; a target goal
        with one input).
    nlp : NLPSettings or None
        The NLP planner's settings (None: its defaults).
    """

    horizon: float = 20.0
    max_depth: int = 400
    width: int = 64
    cells: int = 10
    local_depth: int = 6
    energy_weight: float = 1.0
    reach_weight: float = 0.3
    distance_weight: float = 0.1
    handover: float = 4.0
    budget: int | None = 8
    replan_budget: int | None = 24
    seed: int = 0
    jit: bool | None = None
    planner: str = "beam"
    nlp: NLPSettings | None = None

    def __post_init__(self):
        from .._validate import check_choice, check_int, check_real
        check_choice("planner", self.planner, ("beam", "nlp"))
        if self.nlp is not None and not isinstance(self.nlp, NLPSettings):
            raise TypeError(f"nlp must be NLPSettings or None, got {type(self.nlp).__name__}")
        check_real("horizon", self.horizon, positive=True)
        check_int("width", self.width, low=1)
        check_int("max_depth", self.max_depth, low=1)
        check_int("local_depth", self.local_depth, low=1)
        check_real("energy_weight", self.energy_weight, nonnegative=True)
        check_real("reach_weight", self.reach_weight, nonnegative=True)
        check_real("distance_weight", self.distance_weight, nonnegative=True)
        check_int("cells", self.cells, low=1)
        check_real("handover", self.handover, positive=True)
        for name in ("budget", "replan_budget"):
            if getattr(self, name) is not None:
                check_int(name, getattr(self, name), low=1)
        check_int("seed", self.seed, low=0)


class Controller:
    """Discrete- or bounded-input controller for any identified mechanical system.

    Parameters
    ----------
    model : LagrangianSINDy or MechanicalSystem
        Anything with coordinate names, ``ode()`` and its energy (see :mod:`~.system`).
    task : Task
    settings : ControllerSettings, optional
    plugin : object, optional
        System-specific policy maker (``build(model, task, controller)``); the controller then
        only validates states and answers :meth:`reached`.

    Raises
    ------
    ValueError
        The task names a coordinate or state the model lacks, the kinetic part is not positive
        definite, the target cannot be held or stabilised by the inputs, or no state satisfies
        the reach condition.
    """

    def __init__(self, model, task: Task, settings: ControllerSettings | None = None,
                 plugin=None):
        if not isinstance(task, Task):
            raise TypeError(f"task must be a Task, got {type(task).__name__}")
        self.settings = settings or ControllerSettings()
        self.task = task
        coords = getattr(model, "coords_", None) or getattr(model, "coords", None)
        if not coords:
            raise TypeError("model must be a fitted LagrangianSINDy (or a system with coords)")
        self.bound = task.bind(coords)
        if self.settings.planner == "nlp" and plugin is None:
            check_nlp_task(self.bound)             # before anything heavy is built
        rng = np.random.default_rng(self.settings.seed)
        self.system = sys_ = ControlledSystem(model, self.bound, rng)
        self.candidates = np.array(list(itertools.product(
            *[i.candidates() for i in self.bound.inputs])), float)
        self.policy, self._margin_maps = None, {}
        self._last_value = self._last_margin = (None, None)
        if plugin is not None:                 # the plug-in decides: nothing generic to build
            self.policy = plugin.build(model, task, self)
            self.reset()
            return
        jit = resolve_jit(self.settings.jit)
        # the search's heuristic evaluates H on every child: compiled like the model's map
        self._energy_map = maybe_compiled(
            sys_.energy.map(max(1, self.settings.width * len(self.candidates))), jit)
        self.energy_scale = self._energy_scale(rng)
        self.local, self.region = None, 0.0
        if self.bound.target is not None:
            self._build_target(rng)
        else:
            self._build_reach(rng)
        if self.settings.planner == "nlp":
            self.search = NLPPlanner(sys_, self.bound, self.energy_scale, self.target_energy,
                                     self.settings.nlp or NLPSettings(), jit)
            self.reset()
            return
        depth = min(self.settings.max_depth,
                    max(1, int(np.ceil(self.settings.horizon / task.dt - 1e-9))))
        self.search = BeamSearch(sys_.search_step, self.candidates, depth, self.settings.width,
                                 self._cost, self._capture, self.bound.lower, self.bound.upper,
                                 cells=self.settings.cells, jit=jit,
                                 budget=(self.settings.replan_budget if self.local is not None
                                         else self.settings.budget),
                                 restart=self.local is not None)
        self.reset()

    # ------------------------------------------------------------------ build
    def _energies(self, X):
        X = np.atleast_2d(X)
        out = np.empty(len(X))
        size = self._energy_map.f.size2_in(0)
        for s in range(0, len(X), size):
            chunk = X[s:s + size]
            pad = np.zeros((size, X.shape[1]))
            pad[:len(chunk)] = chunk
            out[s:s + len(chunk)] = self._energy_map(pad.T).ravel()[:len(chunk)]
        return out

    def _sample_positions(self, rng, k):
        """Random positions (angles over a turn, others inside their limits or ±1) at rest."""
        n = self.system.n // 2
        X = np.zeros((k, 2 * n))
        for i in range(n):
            if self.system.angles[i]:
                X[:, i] = rng.uniform(-np.pi, np.pi, k)
            else:
                lo, hi = self.bound.lower[i], self.bound.upper[i]
                lo, hi = (lo if np.isfinite(lo) else -1.0), (hi if np.isfinite(hi) else 1.0)
                X[:, i] = rng.uniform(lo, hi, k)
        return X

    def _energy_scale(self, rng):
        """The system's energy scale: the spread of H over positions at rest (a swing's worth)."""
        E = self._energies(self._sample_positions(rng, 512))
        return float(max(np.ptp(E), 1e-12))

    def _build_target(self, rng):
        b, sys_ = self.bound, self.system
        x_star = b.target.copy()
        u_star, residual, inside = equilibrium_input(sys_, x_star, b.inputs)
        acc = float(np.linalg.norm(np.asarray(sys_.ode(x_star, np.zeros(sys_.m))).ravel()))
        # an equilibrium to 1e-6 of the unforced acceleration (or 1e-9 absolute): rounding of
        # the linear solve, not a force the inputs lack
        if residual > 1e-6 * max(acc, 1e-3):
            raise ValueError(f"the goal's target is not a rest state the inputs can hold in the "
                             f"model (residual acceleration {residual:.3g} after the best input)")
        if not inside:
            raise ValueError(f"holding the goal's target needs the input(s) "
                             f"{np.round(u_star, 4).tolist()}, outside their levels/bounds")
        self.x_star, self.u_star = x_star, u_star
        band = b.band
        banded = np.isfinite(band)
        q = np.where(banded, 1.0 / np.where(banded, band, 1.0) ** 2, 0.0)
        # states without a band: a weight 1e-3 of the smallest banded one keeps the LQR cost
        # positive definite without steering by them
        q[~banded] = 1e-3 * np.min(q[banded])
        umax = np.maximum(np.abs([i.low for i in b.inputs]), np.abs([i.high for i in b.inputs]))
        r = 1.0 / np.maximum(umax, 1e-12) ** 2
        for name, w in b.weights.items():
            if name in b.names:
                q[b.names.index(name)] = w
            else:
                r[list(self.task.inputs).index(name)] = w
        limited = np.isfinite(b.lower) | np.isfinite(b.upper)
        self.local = LocalPolicy(sys_, x_star, u_star, b.inputs, q, r,
                                 depth=self.settings.local_depth,
                                 ignore=sys_.cyclic & ~banded & ~limited)
        hold_steps = int(np.ceil(self.task.goal.hold / self.task.dt))
        self.region = self.local.region(np.where(banded, band, np.inf), hold_steps, rng,
                                        limits=(b.lower, b.upper))
        if self.region <= 0:
            raise ValueError("the inputs cannot hold the goal's band in the model: from states "
                             "next to the target, the local policy on these levels/bounds "
                             "leaves the band (a wider band, finer levels or a shorter dt "
                             "may help)")
        self.target_energy = float(self._energies(x_star)[0])

    def _build_reach(self, rng):
        g = self.bound.reach[1]
        X = self._sample_positions(rng, 20000)
        margin = np.asarray(g.map(len(X))(X.T)).ravel()
        ok = margin >= 0
        if not np.any(ok):
            raise ValueError(f"no state at rest satisfies goal.reach {self.bound.reach[0]!r} "
                             "(searched 20000 positions): the goal cannot be reached")
        # the least energy with which the condition can hold: the search pumps at least this
        self.target_energy = float(np.min(self._energies(X[ok])))
        self._margin_scale = float(max(np.ptp(margin), 1e-12))

    # ------------------------------------------------------------------ heuristic
    def _cost(self, X):
        if self.local is not None:
            # the energy to shape is the part the inputs do not set directly: H with the
            # actuated coordinates' rates at zero (their kinetic energy is the inputs' to give
            # or take; on a Furuta pendulum the full H rewards spinning the arm)
            X0 = np.array(X, dtype=float, copy=True)
            X0[:, self.system.actuated_rates] = 0.0
            E = self._energies(X0)
            # distance: the local policy's cost-to-go in decades above its region
            dist = np.log10(np.maximum(self._value(X) / self.region, 1.0))
            return (self.settings.energy_weight * ((E - self.target_energy)
                                                   / self.energy_scale) ** 2
                    + self.settings.distance_weight * dist)
        E = self._energies(X)
        return -(self.settings.energy_weight * E / self.energy_scale
                 + self.settings.reach_weight * self._margins(X) / self._margin_scale)

    def _margins(self, X):
        X = np.atleast_2d(X)
        if self._last_margin[0] is X:      # the search's capture and heuristic: same children
            return self._last_margin[1]
        f = self._margin_maps.get(len(X))
        if f is None:                  # one mapped function per row count, not one per call
            f = self._margin_maps[len(X)] = self.bound.reach[1].map(len(X))
        g = np.asarray(f(X.T)).ravel()
        self._last_margin = (X, g)
        return g

    def _value(self, X):
        """The local policy's cost-to-go of rows of ``X``; the search asks for the capture
        and the heuristic of the same children, so the last array's values are kept."""
        if self._last_value[0] is not X:
            self._last_value = (X, self.local.value(X))
        return self._last_value[1]

    def _capture(self, X):
        if self.local is not None:
            return self._value(X) <= self.region
        return self._margins(X) >= 0

    # ------------------------------------------------------------------ use
    def reset(self):
        """Forget the previous episode's plan and mode (call before each episode)."""
        self._local_mode = False
        if self.policy is not None:
            self.policy.reset()
        else:
            self.search.reset()

    def __call__(self, x) -> np.ndarray:
        """The inputs for state ``x`` ([q..., q_dot...] in the model's coordinate order),
        one per task input (a level where levels are given)."""
        x = check_state(x, self.system.n)
        if self.policy is not None:
            return np.atleast_1d(np.asarray(self.policy(x), float))
        if self.local is not None and self.region > 0:
            v = float(self.local.value(x)[0])
            limit = self.region * (self.settings.handover if self._local_mode else 1.0)
            self._local_mode = v <= limit
            if self._local_mode:
                self.search.reset()
                return self.local(x)
        if self.settings.planner == "nlp":
            return self.search(x)
        i = self.search(x)
        if i is None:
            return self._least_violation(x)
        return self.candidates[i].copy()

    def _least_violation(self, x):
        """Every sequence leaves the limits: the input whose next state violates them least."""
        X = np.asarray(self.system.step.map(len(self.candidates))(
            np.tile(x, (len(self.candidates), 1)).T, self.candidates.T)).T
        over = np.maximum(X - self.bound.upper, 0) + np.maximum(self.bound.lower - X, 0)
        return self.candidates[int(np.argmin(np.nan_to_num(over, nan=np.inf).sum(1)))].copy()

    def reached(self, x) -> bool:
        """The task's goal test at state ``x`` (the band for a target goal; hold time is the
        caller's bookkeeping, see :func:`~.episodes.run_episode`)."""
        x = check_state(x, self.system.n)
        if self.bound.target is not None:
            return self.bound.reached_band(x, self.system.angles)
        return bool(self._margins(x)[0] >= 0)
