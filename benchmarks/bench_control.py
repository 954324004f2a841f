"""The generic controller (``Controller(model, task)``) from identified models, run in engines.

For each system the controller is built from the IDENTIFIED model file (``examples/data``) and the
task file (``examples/tasks``); the plant is the engine itself, never the model:

* **acrobot** — gymnasium ``Acrobot-v1`` (``examples/acrobot.py``'s ``AcrobotPlant``), gymnasium's
  own random starts (``reset(seed)``, seeds ``seed .. seed+N-1``, default 100), torques
  {-1, 0, +1} every 0.2 s; an episode ends when gymnasium terminates (tip above the bar: success)
  or truncates (500 steps).  The offline reference: from each same start, the plan a much larger
  beam search (``ControllerSettings(width=256, horizon=100, budget=None)``: run to its end in
  one call) finds on the identified model, ``1 + len(plan)`` samples to the goal; reported
  with the ratio closed-loop / offline steps.
  Targets: N/N reach the goal, mean steps <= 70, mean ratio <= 1.15.
* **furuta** — the MuJoCo Furuta pendulum (``examples/furuta.py``'s ``FurutaPlant``), starts
  ``FurutaPlant.hanging_start(default_rng(seed))`` (default 20), torques {-0.03, 0, 0.03} N m
  every 10 ms, 10 s episodes; success: the band held 3 s (``GoalClock``).  Target >= 95 %.
* **double_pendulum_cart** — gymnasium ``InvertedDoublePendulum-v5``
  (``examples/double_pendulum_cart.py``'s ``DoublePendulumCartPlant``):

  - *own task* (``double_pendulum_cart.toml``, force in [-500, 500] N, action = u / 500): the env's
    own starts (``reset(seed)``, default 10), 1000 steps or until it terminates; the env's total
    reward per episode (target >= 9,300 each);
  - *swing-up* (``double_pendulum_cart_swingup.toml``) from ``hanging_start(default_rng(seed))``
    (default 20; the env is ``reset(seed)`` first, so its 1000-step limit counts per episode —
    ``reset_to`` alone does not restart it), 12 s (240 steps); success: the band held 5 s
    (``GoalClock``) and |x| <= 1 m throughout; with the continuous bounds and with the discrete
    levels {-500, 0, 500} N (a ``ValueError`` at build is the variant's result: 0/N with its
    message).  Target >= 90 % each.

Per system: build time, controller step time (median, p99, max), number of states, and the
wall-clock duration of each part.  Writes ``control.json``, ``control.md`` and ``control.png``
to ``--out``; progress on stderr.

    python benchmarks/bench_control.py --out DIR                        # everything, ~2 min
    python benchmarks/bench_control.py --out DIR --systems acrobot --episodes 10
    python benchmarks/bench_control.py --out DIR --systems furuta,double_pendulum_cart --episodes 3

Needs gymnasium with its MuJoCo environments and mujoco (the ``gym`` and ``mujoco`` extras).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
EXAMPLES = ROOT / "examples"
sys.path.insert(0, str(HERE))
from _cli import out_folder  # noqa: E402

SYSTEMS = ("acrobot", "furuta", "double_pendulum_cart")
# default episodes per part (--episodes overrides all of them)
DEFAULT_EPISODES = {"acrobot": 100, "furuta": 20, "dpc_own": 10, "dpc_swingup": 20}
DISCRETE_LEVELS = [-500.0, 0.0, 500.0]
GEAR = 500.0                     # N per unit action of InvertedDoublePendulum-v5
DPC_OWN_STEPS = 1000
X_MAX = 1.0                      # m: the swing-up's |x| bound (the slider's range)
TARGETS = {"acrobot_mean_steps": 70.0, "acrobot_ratio": 1.15, "furuta_share": 0.95,
           "dpc_own_reward": 9300.0, "dpc_swingup_share": 0.9}


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def _ms(seconds):
    """Median, p99 and max of wall-clock seconds, in ms (None when empty)."""
    s = np.asarray(seconds, float) * 1e3
    if not s.size:
        return {"step_ms_median": None, "step_ms_p99": None, "step_ms_max": None,
                "controller_calls": 0}
    return {"step_ms_median": round(float(np.median(s)), 4),
            "step_ms_p99": round(float(np.percentile(s, 99)), 3),
            "step_ms_max": round(float(np.max(s)), 2), "controller_calls": int(s.size)}


def _wrap(a):
    return (np.asarray(a, float) + np.pi) % (2 * np.pi) - np.pi


def _timed(ctrl, x, times):
    t0 = time.perf_counter()
    u = ctrl(x)
    times.append(time.perf_counter() - t0)
    return u


def _load(model_file, task_file):
    from lsindy_cas import LagrangianSINDy
    from lsindy_cas.control.task import Task
    return (LagrangianSINDy.load(EXAMPLES / "data" / model_file),
            Task.load(EXAMPLES / "tasks" / task_file))


def _build(model, task, settings=None):
    from lsindy_cas.control.controller import Controller
    t0 = time.perf_counter()
    ctrl = Controller(model, task, settings)
    return ctrl, time.perf_counter() - t0


# ---------------------------------------------------------------------------- acrobot
def run_acrobot(n, seed0, width, horizon):
    from acrobot import AcrobotPlant
    from lsindy_cas.control.controller import ControllerSettings

    t_part = time.perf_counter()
    model, task = _load("acrobot_model.json", "acrobot.toml")
    ctrl, t_build = _build(model, task)
    # the offline reference: each search runs to its end (no per-call budget)
    big, t_build_big = _build(model, task, ControllerSettings(width=width, horizon=horizon,
                                                              budget=None))
    plant = AcrobotPlant()
    episodes, times, traces = [], [], []
    t_closed = t_offline = 0.0
    for i in range(n):
        seed = seed0 + i
        t0 = time.perf_counter()
        x = plant.reset(seed)
        x0 = x.copy()
        ctrl.reset()
        ep_times, X = [], [x0]
        steps, terminated, truncated = 0, False, False
        while not (terminated or truncated):
            u = _timed(ctrl, x, ep_times)
            x, terminated, truncated = plant.step(float(u[0]))
            X.append(x)
            steps += 1
        t_closed += time.perf_counter() - t0
        # the offline reference: one large search on the model from the same start
        t0 = time.perf_counter()
        big.reset()
        big.search(x0)
        t_search = time.perf_counter() - t0
        t_offline += t_search
        plan = big.search.plan
        offline = (1 + (0 if plan is None else len(plan))) if big.search.captured else None
        times += ep_times
        traces.append(np.array(X))
        ep = {"seed": seed, "x0": [round(float(v), 6) for v in x0], "success": terminated,
              "steps": steps, "truncated": truncated,
              "reached_agrees": ctrl.reached(x) == terminated,
              "offline_steps": offline, "offline_search_s": round(t_search, 3),
              "ratio": (round(steps / offline, 4) if terminated and offline else None),
              "step_ms_max": round(1e3 * max(ep_times), 2)}
        episodes.append(ep)
        log(f"acrobot seed {seed}: {'goal' if terminated else 'TRUNCATED'} in {steps} steps, "
            f"offline plan {offline}, ratio {ep['ratio']} ({time.perf_counter() - t_part:.0f} s)")
    plant.close()
    ok = [e for e in episodes if e["success"]]
    steps = np.array([e["steps"] for e in ok], float)
    offl = np.array([e["offline_steps"] for e in episodes if e["offline_steps"]], float)
    ratios = np.array([e["ratio"] for e in episodes if e["ratio"] is not None], float)
    res = {"system": "acrobot", "variant": "Acrobot-v1", "plant": "gymnasium Acrobot-v1",
           "model": "examples/data/acrobot_model.json", "task": "examples/tasks/acrobot.toml",
           "states": ctrl.system.n, "episodes": n, "seeds": [seed0, seed0 + n - 1],
           "success": len(ok), "failed": [{"seed": e["seed"], "x0": e["x0"]}
                                          for e in episodes if not e["success"]],
           "steps_mean": round(float(steps.mean()), 2) if steps.size else None,
           "steps_median": float(np.median(steps)) if steps.size else None,
           "steps_max": int(steps.max()) if steps.size else None,
           "offline": {"width": width, "horizon": horizon, "build_s": round(t_build_big, 3),
                       "captured": int(offl.size),
                       "steps_mean": round(float(offl.mean()), 2) if offl.size else None,
                       "steps_median": float(np.median(offl)) if offl.size else None,
                       "steps_max": int(offl.max()) if offl.size else None,
                       "seconds": round(t_offline, 1)},
           "ratio_mean": round(float(ratios.mean()), 4) if ratios.size else None,
           "ratio_median": round(float(np.median(ratios)), 4) if ratios.size else None,
           "ratio_max": round(float(ratios.max()), 4) if ratios.size else None,
           "ratio_of_means": (round(float(steps.mean() / offl.mean()), 4)
                              if steps.size and offl.size else None),
           "reached_agrees_with_env": all(e["reached_agrees"] for e in episodes),
           "build_s": round(t_build, 3), **_ms(times),
           "seconds": {"closed_loop": round(t_closed, 1), "offline": round(t_offline, 1),
                       "total": round(time.perf_counter() - t_part, 1)},
           "per_episode": episodes}
    res["targets"] = {
        "all reach": res["success"] == n,
        f"mean steps <= {TARGETS['acrobot_mean_steps']:g}":
            res["steps_mean"] is not None and res["steps_mean"] <= TARGETS["acrobot_mean_steps"],
        f"mean ratio <= {TARGETS['acrobot_ratio']:g}":
            res["ratio_mean"] is not None and res["ratio_mean"] <= TARGETS["acrobot_ratio"]}
    return res, {"traces": traces}


# ---------------------------------------------------------------------------- furuta
def run_furuta(n, seed0):
    from furuta import FurutaPlant
    from lsindy_cas.control.episodes import GoalClock

    t_part = time.perf_counter()
    model, task = _load("furuta_model.json", "furuta.toml")
    ctrl, t_build = _build(model, task)
    plant = FurutaPlant()
    n_steps = int(round(task.episode.duration / task.dt))
    episodes, times, traces = [], [], []
    for i in range(n):
        seed = seed0 + i
        x = plant.reset(FurutaPlant.hanging_start(np.random.default_rng(seed)))
        x0 = x.copy()
        ctrl.reset()
        clock = GoalClock(ctrl)
        clock.update(x, 0)
        ep_times, X = [], [x0]
        for k in range(1, n_steps + 1):
            u = _timed(ctrl, x, ep_times)
            x = plant.step(float(u[0]), task.dt)
            X.append(x)
            clock.update(x, k)
        times += ep_times
        traces.append(np.array(X))
        ok = clock.done_at is not None
        ep = {"seed": seed, "x0": [round(float(v), 6) for v in x0], "success": ok,
              "time_to_goal": None if not ok else round(clock.done_at * task.dt, 3),
              "final": [round(float(v), 4) for v in x],
              "step_ms_max": round(1e3 * max(ep_times), 2)}
        episodes.append(ep)
        log(f"furuta seed {seed}: {'held' if ok else 'NOT held'}"
            + (f", goal at {ep['time_to_goal']:.2f} s" if ok else "")
            + f" ({time.perf_counter() - t_part:.0f} s)")
    ok = [e for e in episodes if e["success"]]
    ttg = np.array([e["time_to_goal"] for e in ok], float)
    res = {"system": "furuta", "variant": "swing-up", "plant": "MuJoCo examples/data/furuta.xml",
           "model": "examples/data/furuta_model.json", "task": "examples/tasks/furuta.toml",
           "states": ctrl.system.n, "episodes": n, "seeds": [seed0, seed0 + n - 1],
           "success": len(ok), "failed": [{"seed": e["seed"], "x0": e["x0"]}
                                          for e in episodes if not e["success"]],
           "time_to_goal_median": round(float(np.median(ttg)), 3) if ttg.size else None,
           "time_to_goal_max": round(float(ttg.max()), 3) if ttg.size else None,
           "build_s": round(t_build, 3), **_ms(times),
           "seconds": {"total": round(time.perf_counter() - t_part, 1)},
           "per_episode": episodes}
    res["targets"] = {f">= {TARGETS['furuta_share']:.0%} held":
                      len(ok) >= TARGETS["furuta_share"] * n - 1e-9}
    return res, {"traces": traces, "dt": task.dt}


# ---------------------------------------------------------------------------- double pendulum
def run_dpc_own(plant, n, seed0):
    t_part = time.perf_counter()
    model, task = _load("double_pendulum_cart_model.json", "double_pendulum_cart.toml")
    ctrl, t_build = _build(model, task)
    episodes, times = [], []
    for i in range(n):
        seed = seed0 + i
        x = plant.reset(seed)
        x0 = x.copy()
        ctrl.reset()
        ep_times, total, steps, terminated, xmax = [], 0.0, 0, False, abs(x[0])
        while steps < DPC_OWN_STEPS and not terminated:
            u = _timed(ctrl, x, ep_times)
            x, r, terminated, _ = plant.step(float(u[0]) / GEAR)
            total += r
            steps += 1
            xmax = max(xmax, abs(x[0]))
        times += ep_times
        ep = {"seed": seed, "x0": [round(float(v), 6) for v in x0], "reward": round(total, 2),
              "steps": steps, "terminated": terminated, "max_abs_x": round(float(xmax), 4),
              "success": bool(total >= TARGETS["dpc_own_reward"]),
              "step_ms_max": round(1e3 * max(ep_times), 2)}
        episodes.append(ep)
        log(f"double_pendulum_cart own task seed {seed}: reward {total:.1f} in {steps} steps"
            f"{' (terminated)' if terminated else ''} ({time.perf_counter() - t_part:.0f} s)")
    rewards = np.array([e["reward"] for e in episodes])
    res = {"system": "double_pendulum_cart", "variant": "own task (balance)",
           "plant": "gymnasium InvertedDoublePendulum-v5",
           "model": "examples/data/double_pendulum_cart_model.json",
           "task": "examples/tasks/double_pendulum_cart.toml", "states": ctrl.system.n,
           "episodes": n, "seeds": [seed0, seed0 + n - 1],
           "success": int(sum(e["success"] for e in episodes)),
           "failed": [{"seed": e["seed"], "x0": e["x0"], "reward": e["reward"]}
                      for e in episodes if not e["success"]],
           "reward_min": round(float(rewards.min()), 2),
           "reward_mean": round(float(rewards.mean()), 2),
           "reward_max": round(float(rewards.max()), 2),
           "build_s": round(t_build, 3), **_ms(times),
           "seconds": {"total": round(time.perf_counter() - t_part, 1)},
           "per_episode": episodes}
    res["targets"] = {f"every reward >= {TARGETS['dpc_own_reward']:,.0f}":
                      res["success"] == n}
    return res, {"rewards": rewards}


def run_dpc_swingup(plant, n, seed0, discrete):
    from lsindy_cas.control.episodes import GoalClock

    t_part = time.perf_counter()
    model, task = _load("double_pendulum_cart_model.json", "double_pendulum_cart_swingup.toml")
    if discrete:
        task = dataclasses.replace(task, inputs={"x": {"levels": list(DISCRETE_LEVELS)}})
    label = ("swing-up, levels {-500, 0, 500} N" if discrete else "swing-up, bounds +-500 N")
    res = {"system": "double_pendulum_cart", "variant": label,
           "plant": "gymnasium InvertedDoublePendulum-v5",
           "model": "examples/data/double_pendulum_cart_model.json",
           "task": "examples/tasks/double_pendulum_cart_swingup.toml"
                   + (f" with inputs.x.levels = {DISCRETE_LEVELS}" if discrete else ""),
           "episodes": n, "seeds": [seed0, seed0 + n - 1]}
    target_name = f">= {TARGETS['dpc_swingup_share']:.0%} held, |x| <= {X_MAX:g} m"
    t0 = time.perf_counter()
    try:
        ctrl, t_build = _build(model, task)
    except ValueError as exc:
        t_build = time.perf_counter() - t0
        log(f"double_pendulum_cart {label}: Controller build raised ValueError: {exc}")
        res.update({"states": 2 * len(model.coords_), "success": 0,
                    "failed": [], "build_error": str(exc), "build_s": round(t_build, 3),
                    **_ms([]), "seconds": {"total": round(time.perf_counter() - t_part, 1)},
                    "per_episode": []})
        res["targets"] = {target_name: False}
        return res, {"traces": [], "error": str(exc)}
    n_steps = int(round(task.episode.duration / task.dt))
    episodes, times, traces = [], [], []
    for i in range(n):
        seed = seed0 + i
        plant.reset(seed)                # a fresh env (its step counter) under each episode
        x = plant.reset_to(plant.hanging_start(np.random.default_rng(seed)))
        x0 = x.copy()
        ctrl.reset()
        clock = GoalClock(ctrl)
        clock.update(x, 0)
        ep_times, X, xmax = [], [x0], abs(x[0])
        for k in range(1, n_steps + 1):
            u = _timed(ctrl, x, ep_times)
            x, _, _, _ = plant.step(float(u[0]) / GEAR)
            X.append(x)
            xmax = max(xmax, abs(x[0]))
            clock.update(x, k)
        times += ep_times
        traces.append(np.array(X))
        held = clock.done_at is not None
        ok = bool(held and xmax <= X_MAX)
        ep = {"seed": seed, "x0": [round(float(v), 6) for v in x0], "success": ok,
              "held": held, "max_abs_x": round(float(xmax), 4),
              "time_to_goal": None if not held else round(clock.done_at * task.dt, 3),
              "step_ms_max": round(1e3 * max(ep_times), 2)}
        episodes.append(ep)
        log(f"double_pendulum_cart {label} seed {seed}: {'held' if held else 'NOT held'}"
            + (f", goal at {ep['time_to_goal']:.2f} s" if held else "")
            + f", max |x| {xmax:.3f} m ({time.perf_counter() - t_part:.0f} s)")
    ok = [e for e in episodes if e["success"]]
    ttg = np.array([e["time_to_goal"] for e in ok], float)
    res.update({"states": ctrl.system.n, "success": len(ok),
                "failed": [{"seed": e["seed"], "x0": e["x0"], "held": e["held"],
                            "max_abs_x": e["max_abs_x"]} for e in episodes if not e["success"]],
                "time_to_goal_median": round(float(np.median(ttg)), 3) if ttg.size else None,
                "time_to_goal_max": round(float(ttg.max()), 3) if ttg.size else None,
                "max_abs_x": round(max(e["max_abs_x"] for e in episodes), 4),
                "build_s": round(t_build, 3), **_ms(times),
                "seconds": {"total": round(time.perf_counter() - t_part, 1)},
                "per_episode": episodes})
    res["targets"] = {target_name: len(ok) >= TARGETS["dpc_swingup_share"] * n - 1e-9}
    return res, {"traces": traces, "dt": task.dt}


# ---------------------------------------------------------------------------- report
def _result_text(r):
    n = r["episodes"]
    if r.get("build_error"):
        return f"0/{n} (build: ValueError)"
    if r["system"] == "acrobot":
        off = r["offline"]
        return (f"{r['success']}/{n} reach; steps mean {r['steps_mean']}, median "
                f"{r['steps_median']:g}, max {r['steps_max']}; offline plan mean "
                f"{off['steps_mean']} ({off['captured']}/{n} captured); ratio mean "
                f"{r['ratio_mean']}, max {r['ratio_max']}")
    if "reward_min" in r:
        return (f"{r['success']}/{n} >= {TARGETS['dpc_own_reward']:,.0f}; reward min "
                f"{r['reward_min']:,.1f}, mean {r['reward_mean']:,.1f}")
    t = (f"; time to goal median {r['time_to_goal_median']} s, max {r['time_to_goal_max']} s"
         if r.get("time_to_goal_median") is not None else "")
    extra = f"; max abs x {r['max_abs_x']} m" if "max_abs_x" in r else ""
    return f"{r['success']}/{n} held{t}{extra}"


def _fmt(v, spec):
    return "-" if v is None else format(v, spec)


def table(results):
    lines = ["| system | variant | result | targets | states | build (s) | step median / p99 / "
             "max (ms) | failed starts (seed) | wall (s) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        targets = "; ".join(f"{k}: {'met' if v else 'MISSED'}" for k, v in r["targets"].items())
        failed = ", ".join(str(f["seed"]) for f in r["failed"]) or "-"
        lines.append(
            f"| {r['system']} | {r['variant']} | {_result_text(r)} | {targets} | {r['states']} | "
            f"{r['build_s']:.2f} | {_fmt(r['step_ms_median'], '.3f')} / "
            f"{_fmt(r['step_ms_p99'], '.1f')} / {_fmt(r['step_ms_max'], '.0f')} | {failed} | "
            f"{r['seconds']['total']:.0f} |")
    return lines


def figure(panels, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k = len(panels)
    cols = min(3, k)
    rows = -(-k // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.0 * cols, 3.6 * rows), squeeze=False)
    for ax in axes.ravel()[k:]:
        ax.set_visible(False)
    for ax, (kind, r, data) in zip(axes.ravel(), panels):
        n = r["episodes"]
        if kind == "acrobot":
            closed = [e["steps"] for e in r["per_episode"] if e["success"]]
            offline = [e["offline_steps"] for e in r["per_episode"] if e["offline_steps"]]
            lo = min(closed + offline, default=0)
            hi = max(closed + offline, default=1)
            bins = np.arange(lo - 0.5, hi + 5.5, max(1, (hi - lo) // 25 + 1))
            ax.hist(offline, bins, alpha=0.6, color="0.5",
                    label=f"offline plan (w {r['offline']['width']}), mean "
                          f"{r['offline']['steps_mean']}")
            ax.hist(closed, bins, alpha=0.6, color="C0",
                    label=f"closed loop in gymnasium, mean {r['steps_mean']}")
            ax.axvline(TARGETS["acrobot_mean_steps"], color="k", ls="--", lw=0.8)
            ax.set_xlabel("steps of 0.2 s to the goal")
            ax.set_ylabel("episodes")
            ax.set_title(f"Acrobot-v1: {r['success']}/{n} reach, ratio mean {r['ratio_mean']}",
                         fontsize=9)
            ax.legend(fontsize=7)
        elif kind == "acrobot_ratio":
            ratio = [e["ratio"] for e in r["per_episode"] if e["ratio"] is not None]
            seeds = [e["seed"] for e in r["per_episode"] if e["ratio"] is not None]
            ax.plot(seeds, ratio, "o", ms=3)
            ax.axhline(1.0, color="0.5", lw=0.8)
            ax.axhline(TARGETS["acrobot_ratio"], color="k", ls="--", lw=0.8)
            ax.set_xlabel("seed")
            ax.set_ylabel("closed-loop / offline steps")
            ax.set_title(f"Acrobot-v1: ratio per episode (mean {r['ratio_mean']})", fontsize=9)
        elif kind == "furuta":
            dt = data["dt"]
            for X, e in zip(data["traces"], r["per_episode"]):
                t = np.arange(len(X)) * dt
                ax.plot(t, np.abs(_wrap(X[:, 1])), lw=0.7, color="C0" if e["success"] else "C3")
            ax.axhspan(np.pi - 0.1, np.pi, color="0.85", zorder=0)
            ax.set_xlabel("t (s)")
            ax.set_ylabel("|theta| wrapped (rad), pi upright")
            ax.set_title(f"Furuta (MuJoCo): {r['success']}/{n} held 3 s (red: not)", fontsize=9)
        elif kind == "dpc_own":
            rewards = data["rewards"]
            seeds = [e["seed"] for e in r["per_episode"]]
            ax.bar(seeds, rewards, color=["C0" if e["success"] else "C3"
                                          for e in r["per_episode"]])
            ax.axhline(TARGETS["dpc_own_reward"], color="k", ls="--", lw=0.8)
            ax.set_ylim(min(TARGETS["dpc_own_reward"] - 200, float(np.min(rewards)) - 50),
                        max(float(np.max(rewards)) + 50, TARGETS["dpc_own_reward"] + 100))
            ax.set_xlabel("seed")
            ax.set_ylabel("total reward (1000 steps)")
            ax.set_title(f"InvertedDoublePendulum-v5 own task: {r['success']}/{n} >= 9,300",
                         fontsize=9)
        elif kind == "dpc_swingup":
            if data.get("error"):
                ax.text(0.5, 0.5, "Controller build: ValueError\n\n" + _wrap_text(data["error"]),
                        ha="center", va="center", fontsize=7, transform=ax.transAxes)
                ax.set_xticks([])
                ax.set_yticks([])
            else:
                dt = data["dt"]
                for X, e in zip(data["traces"], r["per_episode"]):
                    t = np.arange(len(X)) * dt
                    a = 1.0 if e["success"] else 0.9
                    ax.plot(t, np.abs(_wrap(X[:, 1])), lw=0.7, alpha=a,
                            color="C0" if e["success"] else "C3")
                    ax.plot(t, _wrap(X[:, 2]), lw=0.7, alpha=a,
                            color="C1" if e["success"] else "m")
                ax.axhspan(-0.1, 0.1, color="0.85", zorder=0)
                ax.set_xlabel("t (s)")
                ax.set_ylabel("|theta1| (blue), theta2 (orange), rad")
            ax.set_title(f"DPC {r['variant']}: {r['success']}/{n} held 5 s", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON serializable: {type(o).__name__}")


def _wrap_text(text, width=60):
    import textwrap
    return "\n".join(textwrap.wrap(text, width))


# ---------------------------------------------------------------------------- main
def _provenance():
    """The commit the package was run from and the source files modified on top of it."""
    import subprocess

    def git(*cmd):
        try:
            return subprocess.run(["git", *cmd], cwd=ROOT, capture_output=True, text=True,
                                  timeout=30).stdout
        except (OSError, subprocess.SubprocessError):
            return ""
    modified = [line[3:] for line in git("status", "--porcelain", "--", "src", "examples")
                .splitlines() if line.strip()]
    return {"commit": git("rev-parse", "HEAD").strip() or None, "modified": modified}


def _import_all(systems):
    """Import every module the run uses now, so that a source file edited while it runs does
    not mix versions (the package's lazy imports would otherwise load it mid-run)."""
    import lsindy_cas.control.compiled  # noqa: F401
    import lsindy_cas.control.controller  # noqa: F401
    import lsindy_cas.control.episodes  # noqa: F401
    import lsindy_cas.control.task  # noqa: F401
    if "acrobot" in systems:
        import acrobot  # noqa: F401
    if "furuta" in systems:
        import furuta  # noqa: F401
        import lsindy_cas.plants.mujoco  # noqa: F401
    if "double_pendulum_cart" in systems:
        import double_pendulum_cart  # noqa: F401


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="output folder (control.json, .md, .png)")
    ap.add_argument("--systems", default=",".join(SYSTEMS),
                    help=f"comma-separated among {', '.join(SYSTEMS)} (default: all)")
    ap.add_argument("--episodes", type=int, default=None,
                    help="episodes per part (default: acrobot 100, furuta 20, double pendulum "
                         "own task 10, swing-up 20 per variant)")
    ap.add_argument("--seed", type=int, default=0, help="first seed (seeds seed .. seed+N-1)")
    ap.add_argument("--offline-width", type=int, default=256,
                    help="Acrobot offline reference: beam width (default 256)")
    ap.add_argument("--offline-horizon", type=float, default=100.0,
                    help="Acrobot offline reference: horizon in s (default 100)")
    args = ap.parse_args(argv)
    systems = [s.strip() for s in args.systems.split(",") if s.strip()]
    if not systems or set(systems) - set(SYSTEMS):
        ap.error(f"--systems must be among {', '.join(SYSTEMS)}, got {args.systems!r}")
    if args.episodes is not None and args.episodes < 1:
        ap.error(f"--episodes must be a positive integer, got {args.episodes}")
    if args.seed < 0:
        ap.error(f"--seed must be >= 0, got {args.seed}")
    if args.offline_width < 1 or not args.offline_horizon > 0:
        ap.error("--offline-width must be >= 1 and --offline-horizon > 0")
    out = out_folder(ap, args.out)
    sys.path.insert(0, str(EXAMPLES))
    source = _provenance()
    _import_all(systems)
    n = {k: (args.episodes or v) for k, v in DEFAULT_EPISODES.items()}

    t_start = time.perf_counter()
    results, panels = [], []
    if "acrobot" in systems:
        r, d = run_acrobot(n["acrobot"], args.seed, args.offline_width, args.offline_horizon)
        results.append(r)
        panels += [("acrobot", r, d), ("acrobot_ratio", r, d)]
    if "furuta" in systems:
        r, d = run_furuta(n["furuta"], args.seed)
        results.append(r)
        panels.append(("furuta", r, d))
    if "double_pendulum_cart" in systems:
        from double_pendulum_cart import DoublePendulumCartPlant
        plant = DoublePendulumCartPlant()
        try:
            r, d = run_dpc_own(plant, n["dpc_own"], args.seed)
            results.append(r)
            panels.append(("dpc_own", r, d))
            for discrete in (False, True):
                r, d = run_dpc_swingup(plant, n["dpc_swingup"], args.seed, discrete)
                results.append(r)
                panels.append(("dpc_swingup", r, d))
        finally:
            plant.close()
    seconds = time.perf_counter() - t_start

    command = (f"python benchmarks/bench_control.py --out DIR --systems {','.join(systems)}"
               + (f" --episodes {args.episodes}" if args.episodes else "")
               + (f" --seed {args.seed}" if args.seed else "")
               + (f" --offline-width {args.offline_width}" if args.offline_width != 256 else "")
               + (f" --offline-horizon {args.offline_horizon:g}"
                  if args.offline_horizon != 100.0 else ""))
    lines = table(results)
    durations = [f"- {r['system']} / {r['variant']}: "
                 + ", ".join(f"{k} {v:.1f} s" for k, v in r["seconds"].items())
                 for r in results]
    errors = [f"- {r['system']} / {r['variant']}: {r['build_error']}"
              for r in results if r.get("build_error")]
    print("\n" + "\n".join(lines))
    print("\nwall-clock per part:\n" + "\n".join(durations) + f"\n- all: {seconds:.1f} s")
    if errors:
        print("\nbuild errors:\n" + "\n".join(errors))
    (out / "control.md").write_text(
        f"Generic controller (`Controller(model, task)`) built from the identified models and "
        f"the task files, run in the engines; `{command}` ({seconds:.0f} s, one process)\n\n"
        + "\n".join(lines) + "\n\nWall-clock per part:\n\n" + "\n".join(durations)
        + (("\n\nBuild errors:\n\n" + "\n".join(errors)) if errors else "") + "\n")
    (out / "control.json").write_text(json.dumps(
        {"command": command, "seed": args.seed, "episodes_override": args.episodes,
         "source": source, "targets": TARGETS, "seconds": round(seconds, 1),
         "results": results}, indent=1,
        default=_json_default))
    figure(panels, out / "control.png")
    print(f"\nwritten: {out / 'control.json'}, control.md, control.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
