"""The swing-up planner from the relaxed multiple-shooting NLP: :class:`NLPPlanner`.

``ControllerSettings(planner="nlp")`` puts this planner where the beam search (:mod:`~.search`)
is: far from the target every control step solves a :class:`~.mpc.DiscreteInputMPC` built from
the bound task and the model's ODE (one input: its levels, or its bounds relaxed as a
continuous input; the task's limits as soft state bounds; the model's own RK4 substeps), and
applies a level found by the MPC's lookahead over short discrete sequences (for a continuous
input: the relaxed first input).  Inside the local policy's region the controller's LQR takes
over exactly as with the beam planner.

The least-squares residual of every stage (``dt |r|²``) and of the end (``|r_N|²``) is

* energy shaping from the identified H: ``√w_E (E − E*)/E_s``, E the energy with the actuated
  coordinates' rates at zero, E* the target's energy, E_s the energy scale (the quantity the
  beam heuristic uses);
* the distance from the target in bands, saturated: ``√w_d k tanh(e_i / (k band_i))`` for
  every banded state (an angle's error as ``2 sin(e/2)``, wrap-invariant and equal to e near
  0): ``e_i / band_i`` near the target, at most ``k`` bands far from it, where the energy term
  leads; and ``√w_c e_i / half-width`` for a state the task limits but does not band (keeps it
  near the target inside its limits);

with ``r_N = √w_N r`` (``w_N = 0`` by default).  Nothing here names a coordinate or a system.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from .._validate import check_choice, check_int, check_real
from .mpc import DiscreteInputMPC

__all__ = ["NLPSettings", "NLPPlanner", "check_nlp_task"]


@dataclass(frozen=True)
class NLPSettings:
    """How the NLP planner plans (``ControllerSettings(planner="nlp", nlp=NLPSettings(...))``).

    Measurements: 5 starts each, on the model as the plant: the identified Furuta pendulum
    (``examples/data``), the paper's true two-coordinate system and its task (a 2 m track);
    the identified double pendulum swung up with its continuous force (1 start, uncompiled).
    The comparison with the beam search in the engines: ``benchmarks/bench_planner.py``.

    Parameters
    ----------
    horizon : float
        Seconds the NLP predicts (rounded up to whole samples, capped by ``max_intervals``).
        1.5: the paper's system (0.05 s) spun over the top at 0.8 s (0/5), held 5/5 at 1.0-3.0
        (goal at 3.7 s at 1.0, 2.0-3.5 s at 1.5); the double pendulum reached the goal at 5.5 s
        with 1.0, 2.05 s with 1.5, and every solve failed with 2.0 (0/3).
    max_intervals : int
        Cap on the shooting intervals (the solve's cost grows with them).  80: the Furuta
        pendulum (0.01 s) stayed hanging with 60 (0/5), held 5/5 with 80 and 100 (p99 step
        13 vs 17 ms).
    energy_weight : float
        ``w_E``, weight of the energy-shaping residual (-1 hanging at rest, 0 at the target's
        energy); 1: the scale the other weights are relative to.
    distance_weight : float
        ``w_d``, weight of the distance residuals.  0.01: Furuta 5/5 (goal at 2.4-2.8 s); 0:
        4/5 (3.4-6.6 s, the region is found late); 0.1: 0/5 (the plan stays hanging).
    terminal_weight : float
        ``w_N``: the end's residual is ``√w_N`` times the stage residual.  0: with an end cost
        the plan puts a swing's peak at its end and postpones it every step (Furuta, 0.5 s:
        w_N 0.3: 3/5, 1: 1/5, 3: 0/5, the arm spun up instead); 0.8 s with 0: 5/5.
    input_weight : float
        Weight of the normalised input ``(u / max|u|)²`` per stage (the MPC's default).
    saturation : float
        The distance residual of a banded state is ``k tanh(e / (k band))`` with ``k`` this
        (0: plain ``e / band``): it is ``e / band`` near the target and at most ``k`` away from
        it, so the energy term leads the swing-up.  3: Furuta 5/5; 0: 0/5 (the rates'
        residuals, ~40 bands at the bottom of a swing, stop the swing).
    center_weight : float
        Weight of ``e / half-width`` of a state the task limits but does not band.  1: the
        paper's system (2.0 s horizon) 5/5 with the goal at 1.8-2.05 s; 0.1: 5/5 at
        1.75-2.55 s; 0: 2/5 (the LQR took over near the track's end and left it).
    limit_margin : float
        The NLP's state bounds are the task's limits moved inwards by this fraction of their
        width (the bounds are soft, met to a few cm).  0.1: without the centre term the paper's
        system left the track in 3/5 with 0 and 2/5 with 0.05; with it 5/5 with 0 too (a
        reserve).
    depth : int
        Samples of the discrete sequences the lookahead scores (``levels**depth`` sequences;
        the MPC's default).
    solver : {"sqp", "sqp-gn", "fatrop", "ipopt"}
        Solver of the warm-started steps (:class:`~.mpc.DiscreteInputMPC`'s default).
    max_iter : int
        Iterations of a warm-started solve (the MPC's default, its step-time cap).
    """

    horizon: float = 1.5
    max_intervals: int = 80
    energy_weight: float = 1.0
    distance_weight: float = 0.01
    terminal_weight: float = 0.0
    input_weight: float = 1e-3
    saturation: float = 3.0
    center_weight: float = 1.0
    limit_margin: float = 0.1
    depth: int = 4
    solver: str = "sqp"
    max_iter: int = 7

    def __post_init__(self):
        check_real("nlp.horizon", self.horizon, positive=True)
        check_int("nlp.max_intervals", self.max_intervals, low=1)
        for name in ("energy_weight", "distance_weight", "terminal_weight", "input_weight",
                     "center_weight"):
            check_real(f"nlp.{name}", getattr(self, name), nonnegative=True)
        check_real("nlp.saturation", self.saturation, nonnegative=True)
        check_real("nlp.limit_margin", self.limit_margin, nonnegative=True)
        if not self.limit_margin < 0.5:
            raise ValueError(f"nlp.limit_margin must be < 0.5, got {self.limit_margin}")
        check_int("nlp.depth", self.depth, low=1)
        check_choice("nlp.solver", self.solver, ("sqp", "sqp-gn", "fatrop", "ipopt"))
        check_int("nlp.max_iter", self.max_iter, low=1)


def check_nlp_task(bound):
    """Raise ValueError if the NLP planner cannot serve the bound task (cheap: before any build)."""
    if bound.target is None:
        raise ValueError("planner='nlp' needs a target goal (it plans towards the target's "
                         "energy and state); for a reach goal use planner='beam'")
    if bound.B.shape[1] != 1:
        raise ValueError(f"planner='nlp' handles one input, the task has {bound.B.shape[1]}; "
                         "use planner='beam'")


def residuals(system, bound, energy_scale, target_energy, settings):
    """``(stage, terminal)`` residual functions ``x -> r`` (see the module's docstring)."""
    n = system.n
    x = ca.SX.sym("x", n)
    actuated = set(system.actuated_rates.tolist())
    still = ca.vertcat(*[0 if i in actuated else x[i] for i in range(n)])
    r = [np.sqrt(settings.energy_weight) * (system.energy(still) - target_energy) / energy_scale]
    lo, hi = bound.lower, bound.upper
    for i in range(n):
        e = x[i] - bound.target[i]
        if system.angles[i]:
            e = 2 * ca.sin(e / 2)
        if np.isfinite(bound.band[i]):
            k = settings.saturation
            d = k * ca.tanh(e / (k * bound.band[i])) if k > 0 else e / bound.band[i]
            r.append(np.sqrt(settings.distance_weight) * d)
        elif np.isfinite(lo[i]) and np.isfinite(hi[i]):
            r.append(np.sqrt(settings.center_weight) * e / ((hi[i] - lo[i]) / 2))
    r = ca.vertcat(*r)
    return (ca.Function("r", [x], [r]),
            ca.Function("rN", [x], [np.sqrt(settings.terminal_weight) * r]))


class NLPPlanner:
    """One MPC step per call, towards the bound task's target.

    Parameters
    ----------
    system : ControlledSystem
    bound : BoundTask
        A target goal with one input (:func:`check_nlp_task`).
    energy_scale, target_energy : float
        ``E_s`` and ``E*`` (as the controller's heuristic has them).
    settings : NLPSettings
    jit : bool
        Compile the NLP's functions (:func:`~.compiled.resolve_jit`).
    """

    def __init__(self, system, bound, energy_scale, target_energy, settings, jit):
        check_nlp_task(bound)
        self.settings = s = settings
        inp = bound.inputs[0]
        self.discrete, self.low, self.high = inp.discrete, inp.low, inp.high
        dt = bound.task.dt
        horizon = min(s.max_intervals, max(1, int(np.ceil(s.horizon / dt - 1e-9))))
        stage, terminal = residuals(system, bound, energy_scale, target_energy, s)
        # the soft bounds are met only approximately: keep them a margin inside the limits
        width = np.where(np.isfinite(bound.upper - bound.lower), bound.upper - bound.lower, 0.0)
        lower, upper = bound.lower + s.limit_margin * width, bound.upper - s.limit_margin * width
        self.mpc = DiscreteInputMPC(
            system.ode, inp.levels if inp.discrete else (inp.low, inp.high), input_index=0,
            stage_residual=stage, terminal_residual=terminal, dt=dt, horizon=horizon,
            state_lb=lower, state_ub=upper, input_weight=s.input_weight,
            n_substeps=system.n_substeps, solver=s.solver, depth=s.depth, max_iter=s.max_iter,
            rounding="lookahead" if inp.discrete else "nearest", adapt=False, jit=jit)

    @property
    def horizon(self) -> int:
        """Shooting intervals of the NLP."""
        return self.mpc.horizon

    def reset(self):
        """Forget the warm start (a new episode, or the local policy took over)."""
        self.mpc.reset()

    def __call__(self, x) -> np.ndarray:
        """The input (1,) for state ``x``: a level, or the relaxed first input within bounds."""
        level = self.mpc(x)
        if self.discrete:
            return np.array([level])
        return np.array([np.clip(float(self.mpc.plan_["forces"][0]), self.low, self.high)])
