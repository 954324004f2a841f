"""Swing-up of the cart-pendulum with an identified model (paper Sec. III-C, Fig. 5).

Pipeline: simulate the paper's actuated training run, identify the cart-pendulum with
:class:`~lsindy_cas.LagrangianSINDy` (:func:`identify_cart_pendulum`), build a
:class:`~lsindy_cas.mpc.SwingUpMPC` from the *identified* model, and run closed-loop episodes
(:func:`run_episode`) on the *true* plant (:class:`~lsindy_cas.paper.plant.Plant`: CVODES, force
held constant over each control period).  Scenarios: ``nominal`` (plant = the true system),
``mismatch`` (each of the plant's cart mass, pole mass and pole length off by ±10 % against the
true system the model was identified from, sign drawn per episode) and ``noise`` (the controller
measures the state with additive N(0, sigma^2) noise, sigma = 0.01).

Success (:func:`evaluate`): |wrap(theta - pi)| < 0.1 rad and |theta_dot| < 0.5 rad/s over the
last 3 s of a 10 s episode, checked every 10 ms, and |x| <= 2 m throughout.  The time to upright
is the first time from which these angle and rate bounds hold until the end of the episode.

:func:`run_swingup` runs the whole experiment and reports it; the ``lsindy swingup`` options are
in :mod:`~lsindy_cas.paper.swingup_cli`; ``Plant``, ``mismatched_cart_pendulum``,
``scenario_plant`` and ``SCENARIOS`` (in :mod:`~lsindy_cas.paper.plant`) stay importable from here.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..control.mpc import wrap_angle
from .plant import SCENARIOS, Plant, mismatched_cart_pendulum, scenario_plant  # noqa: F401

__all__ = ["Episode", "evaluate", "identify_cart_pendulum", "in_band", "random_starts",
           "released_at", "run_episode", "run_swingup", "scenario_stats", "summary_table"]

ANGLE_TOL, RATE_TOL, WINDOW, T_END = 0.1, 0.5, 3.0, 10.0
def in_band(X, *, upright=np.pi, pole=1):
    """Per sample of ``X`` (n_samples, 4), whether the pole is in the success band
    (``|angle - upright| < ANGLE_TOL`` and ``|rate| < RATE_TOL``)."""
    return ((np.abs(wrap_angle(X[:, pole] - upright)) < ANGLE_TOL)
            & (np.abs(X[:, 2 + pole]) < RATE_TOL))


def evaluate(t, X, *, upright=np.pi, cart=0, pole=1, track_limit=2.0, t_end=None):
    """Success, time to upright and track used of one trajectory.

    Parameters
    ----------
    t : ndarray, shape (n_samples,)
        Times (s).
    X : ndarray, shape (n_samples, 4)
        States ``[q, q_dot]`` in the plant's coordinate order.
    upright : float
        Upright pole angle (rad).
    cart, pole : int
        Indices of the cart and pole coordinates.
    track_limit : float
        Allowed ``|x|`` (m).
    t_end : float, optional
        Episode length; defaults to ``t[-1]``.

    Returns
    -------
    success : bool
    time_to_upright : float
        ``inf`` if the bounds do not hold at the end.
    track_used : float
        ``max |x|`` (m).
    """
    t_end = t[-1] if t_end is None else t_end
    good = in_band(X, upright=upright, pole=pole)
    track_used = float(np.max(np.abs(X[:, cart])))
    bad = np.flatnonzero(~good)
    if bad.size == 0:
        t_up = float(t[0])
    elif bad[-1] == t.size - 1:
        t_up = math.inf
    else:
        t_up = float(t[bad[-1] + 1])
    success = bool(t_up <= t_end - WINDOW + 1e-9 and track_used <= track_limit)
    return success, t_up, track_used


@dataclass
class Episode:
    """One closed-loop run: fine-grained plant states, applied forces and metrics.

    Attributes
    ----------
    x0 : ndarray, shape (4,)
        Initial state (plant order).
    t : ndarray, shape (n_samples,)
        Times of ``X`` (s), ``dt / n_out`` apart.
    X : ndarray, shape (n_samples, 4)
        True plant states ``[q, q_dot]`` in the order of ``coords``.
    forces : ndarray, shape (n_steps,)
        Applied forces (N), one per control period.
    success, time_to_upright, track_used
        See :func:`evaluate`.
    n_failures : int
        Fallbacks to the previous plan during the episode.
    coords : list of str
        Plant coordinate names.
    solve_times : list of float
        Solver wall-clock seconds per solve (one per step, except the steps the balancer
        decides without a solve).
    """

    x0: np.ndarray
    t: np.ndarray
    X: np.ndarray
    forces: np.ndarray
    success: bool
    time_to_upright: float
    track_used: float
    n_failures: int
    coords: list = field(default_factory=lambda: ["x", "theta"])
    solve_times: list = field(default_factory=list)

    def summary(self):
        """JSON-ready metrics (no time series)."""
        return {"x0": [round(float(v), 6) for v in self.x0], "success": self.success,
                "time_to_upright": None if math.isinf(self.time_to_upright)
                else round(self.time_to_upright, 4),
                "track_used": round(self.track_used, 4), "n_failures": self.n_failures,
                "forces_in_set": None}


def run_episode(ctrl, plant, x0, *, t_end=T_END, noise_std=0.0, rng=None):
    """Run ``ctrl`` on ``plant`` from ``x0`` for ``t_end`` seconds.

    The controller's state order is its own ``coords`` (matched to the plant's by name); the
    measured state is the true one plus N(0, noise_std^2) noise per entry.

    Returns
    -------
    Episode
    """
    perm = [plant.coords.index(c) for c in ctrl.coords]
    perm = perm + [len(perm) + i for i in perm]
    rng = np.random.default_rng(0) if rng is None else rng
    ctrl.reset()
    n_steps = int(round(t_end / plant.dt))
    x = np.asarray(x0, dtype=float)
    states, forces = [x], np.zeros(n_steps)
    n_fail0, n_solve0 = ctrl.stats.n_failures, len(ctrl.stats.solve_times)
    for k in range(n_steps):
        measured = x[perm] + (noise_std * rng.standard_normal(x.size) if noise_std else 0.0)
        forces[k] = ctrl(measured)
        fine = plant.step(x, forces[k])
        states.append(fine)
        x = fine[-1]
        if not np.all(np.isfinite(x)):
            break
    X = np.vstack(states)
    t = np.arange(X.shape[0]) * plant.dt / plant.n_out
    pole = 1 - plant.input_index
    ok, t_up, used = evaluate(t, X, upright=ctrl.upright if ctrl.upright is not None else np.pi,
                              cart=plant.input_index, pole=pole, track_limit=ctrl.track_limit,
                              t_end=t_end)
    return Episode(np.asarray(x0, float), t, X, forces, ok, t_up, used,
                   ctrl.stats.n_failures - n_fail0, list(plant.coords),
                   list(ctrl.stats.solve_times[n_solve0:]))


def released_at(ctrl):
    """Time (s) into the last episode at which ``ctrl``'s plan took up its coefficient estimate
    (``adapt_model``; 0 for ``True``), None if it did not or the controller has no estimator."""
    est = getattr(ctrl, "estimator", None)
    at = None if est is None else est.released_at
    return None if at is None else at * ctrl.dt


def random_starts(n, seed=0):
    """Random initial states ``[x, theta, x_dot, theta_dot]`` of the swing-up episodes.

    theta ~ U[-pi, pi), x ~ U[-0.5, 0.5], both velocities ~ U[-1, 1]; shape (n, 4).
    """
    u = np.random.default_rng(seed).uniform(size=(int(n), 4))  # row i is start i for any n
    low, high = np.array([-0.5, -np.pi, -1.0, -1.0]), np.array([0.5, np.pi, 1.0, 1.0])
    return low + u * (high - low)


def identify_cart_pendulum(system=None):
    """Identify the cart-pendulum from the paper's actuated run (u = 1 N for 1 s, 100 Hz).

    Returns
    -------
    model : LagrangianSINDy
    trajectories : list of Trajectory
        The training data.
    """
    from . import systems
    from ..symbolic.library import Library
    from ..identify.estimator import LagrangianSINDy

    system = systems.cart_pendulum() if system is None else system
    trajs = [system.simulate([0.0, np.pi / 4, 0.0, 0.0], 1.0, u=1.0, dt=0.01)]
    lib = Library.polynomial(coords=["x", "theta"],
                             features=["cos(theta)", "sin(theta)", "theta_dot", "x", "x_dot"],
                             degree=3)
    model = LagrangianSINDy(lib, n_terms=4, prior=["theta_dot**2", "cos(theta)"]).fit(trajs)
    return model, trajs


def scenario_stats(episodes):
    """Success rate, times to upright, track used and fallbacks of a list of episodes."""
    t_up = np.array([e.time_to_upright for e in episodes])
    finite = t_up[np.isfinite(t_up)]
    return {"episodes": len(episodes),
            "success_rate": float(np.mean([e.success for e in episodes])),
            "median_time_to_upright": float(np.median(t_up)) if t_up.size else None,
            "max_time_to_upright": float(finite.max()) if finite.size else None,
            "max_track_used": float(max(e.track_used for e in episodes)),
            "n_failures": int(sum(e.n_failures for e in episodes))}


def run_swingup(model=None, *, episodes=20, seed=0, scenarios=SCENARIOS, noise_std=0.01,
                out=None, json_path=None, controller_options=None, progress=print):
    """Identify (unless ``model`` is given), control, and report (see module docstring).

    Parameters
    ----------
    model : LagrangianSINDy, optional
        A fitted cart-pendulum model; identified from simulated training data if omitted.
    episodes : int
        Random starts per scenario (:func:`random_starts` with ``seed``).
    seed : int
        Seed of the starts, the mismatch signs and the measurement noise.
    scenarios : sequence of {"nominal", "mismatch", "noise"}
    noise_std : float
        Standard deviation of the measurement noise in the ``noise`` scenario.
    out : path, optional
        Directory for the Fig. 5 analogue (PNG).
    json_path : path, optional
        Where to write the metrics.
    controller_options : dict, optional
        Keyword arguments for :class:`~lsindy_cas.mpc.SwingUpMPC`.
    progress : callable or None
        Receives one line per episode.

    Returns
    -------
    dict
        Metrics per scenario, the controller's solve statistics and the model.
    """
    from ..control.cart_pendulum import SwingUpMPC

    episodes = int(episodes)
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}.")
    unknown = set(scenarios) - set(SCENARIOS)
    if unknown:
        raise ValueError(f"scenarios must be among {SCENARIOS}, got {sorted(unknown)}.")
    log = progress or (lambda msg: None)
    trajs = []
    if model is None:
        model, trajs = identify_cart_pendulum()
        log(f"identified model:\n{model}")
    opts = dict(controller_options or {})
    if opts.get("jit") is not False:
        log("building the controller (its two NLPs compiled with gcc where there is one: "
            "5-16 s the first time for a model, later loaded from $LSINDY_CACHE_DIR) ...")
    t0 = time.perf_counter()
    ctrl = SwingUpMPC(model, **opts)
    build_s = time.perf_counter() - t0
    log(f"controller built in {build_s:.1f} s ({'' if ctrl.nlp.jit else 'not '}compiled)")
    starts = random_starts(episodes, seed)
    report = {"controller": {"solver": ctrl.solver, "relaxation": ctrl.relaxation,
                             "rounding": ctrl.rounding, "dt": ctrl.dt, "horizon": ctrl.horizon,
                             "force_set": ctrl.levels.tolist(), "upright": ctrl.upright,
                             "weights": getattr(ctrl, "weights", None),
                             "build_seconds": round(build_s, 3), "compiled": ctrl.nlp.jit,
                             "adapt_model": ctrl.adapt_model},
              "criteria": {"angle_tol": ANGLE_TOL, "rate_tol": RATE_TOL, "window": WINDOW,
                           "t_end": T_END, "track_limit": ctrl.track_limit},
              "noise_std": noise_std, "seed": seed, "scenarios": {}}
    runs = {}
    for name in scenarios:
        rng = np.random.default_rng([seed, SCENARIOS.index(name)])
        eps, rows = [], []
        ctrl.stats.clear()
        for i, x0 in enumerate(starts):
            plant, factors = scenario_plant(name, rng, ctrl.dt)
            ep = run_episode(ctrl, plant, x0, noise_std=noise_std if name == "noise" else 0.0,
                             rng=rng)
            row = ep.summary()
            row["forces_in_set"] = bool(np.all(np.isin(ep.forces, ctrl.levels)))
            if getattr(ctrl, "estimator", None) is not None:  # when the estimate took over
                at = released_at(ctrl)
                row["model_released_at"] = None if at is None else round(at, 4)
            if factors is not None:
                row["plant_factors"] = factors
            eps.append(ep)
            rows.append(row)
            log(f"{name:8s} {i:3d}  x0={np.round(x0, 2).tolist()}  success={ep.success}  "
                f"t_up={ep.time_to_upright:.2f}s  |x|max={ep.track_used:.2f}m  "
                f"fallbacks={ep.n_failures}")
        runs[name] = eps
        report["scenarios"][name] = dict(scenario_stats(eps), solver=ctrl.stats.summary(),
                                         episodes_detail=rows)
    log(summary_table(report))
    if json_path is not None:
        Path(json_path).parent.mkdir(parents=True, exist_ok=True)
        Path(json_path).write_text(json.dumps(report, indent=2))
    if out is not None:
        from .swingup_figures import swingup_figure

        report["figures"] = [str(p) for p in swingup_figure(trajs, runs, ctrl, Path(out))]
    return report


def summary_table(report):
    """Markdown table of the scenarios in a :func:`run_swingup` report."""
    lines = ["| scenario | episodes | success | median t_up (s) | max t_up (s) | max |x| (m) "
             "| fallbacks | solve median (ms) | solve p99 (ms) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, s in report["scenarios"].items():
        fmt = (lambda v: "-" if v is None or not math.isfinite(v) else f"{v:.2f}")
        lines.append(f"| {name} | {s['episodes']} | {100 * s['success_rate']:.0f} % | "
                     f"{fmt(s['median_time_to_upright'])} | {fmt(s['max_time_to_upright'])} | "
                     f"{s['max_track_used']:.2f} | {s['n_failures']} | "
                     f"{s['solver']['solve_ms_median']:.2f} | {s['solver']['solve_ms_p99']:.2f} |")
    return "\n".join(lines)
