"""The generic controller's two swing-up planners, ``planner="beam"`` vs ``planner="nlp"``.

Same model, task, plant and starts for both; only ``ControllerSettings.planner`` differs (the
NLP planner with its defaults, :class:`lsindy_cas.control.nlp_planner.NLPSettings`).  No plug-in.

* **furuta** — the identified model ``examples/data/furuta_model.json`` and
  ``examples/tasks/furuta.toml`` (torque levels {-0.03, 0, 0.03} N m every 10 ms), run in MuJoCo
  (``examples/furuta.py``'s ``FurutaPlant``), starts ``FurutaPlant.hanging_start(default_rng(seed))``;
* **cart** — the cart-pendulum as a plain task: the model identified by
  ``examples/cart_pendulum.py``'s ``main`` (1 s of pushed motion), ``examples/tasks/cart_pendulum.toml``
  (forces {-10, 0, 10} N every 50 ms, track ±2 m), the plant the true system
  (``lsindy_cas.systems.cart_pendulum()``, the controller's RK4 map of it), starts the task's
  ``episode.start`` ± ``spread`` drawn with ``default_rng(seed)``;
* **dpc** (optional) — gymnasium's ``InvertedDoublePendulum-v5`` swung up from hanging with the
  continuous force in [-500, 500] N (``examples/double_pendulum_cart.py``,
  ``examples/tasks/double_pendulum_cart_swingup.toml``), starts ``hanging_start(default_rng(seed))``.

Success: inside the band for the task's hold time (``GoalClock``) within the episode, and every
state inside the task's limits.  Step time: wall clock of each controller call (median, p99,
max over all episodes of a planner; most calls are the local policy's, ~0.03 ms), and of the
calls the planner decided (away from the local policy's region).  Writes ``planner.json``, ``planner.md`` and ``planner.png``
to the output folder; progress on stderr.

    python benchmarks/bench_planner.py OUT                       # furuta, cart; 5 starts each
    python benchmarks/bench_planner.py OUT --systems furuta,cart,dpc --episodes 10
"""
from __future__ import annotations

import argparse
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

SYSTEMS = ("furuta", "cart", "dpc")
PLANNERS = ("beam", "nlp")
GEAR = 500.0                     # N per unit action of InvertedDoublePendulum-v5


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def _settings(planner):
    from lsindy_cas.control.controller import ControllerSettings
    return ControllerSettings(planner=planner)


def _load_task(name):
    from lsindy_cas.control.task import Task
    return Task.load(EXAMPLES / "tasks" / name)


# ---------------------------------------------------------------------------- systems
def furuta():
    """(model, task, make_plant, start(seed)) of the Furuta pendulum in MuJoCo."""
    from furuta import FurutaPlant
    from lsindy_cas import LagrangianSINDy
    model = LagrangianSINDy.load(EXAMPLES / "data" / "furuta_model.json")
    task = _load_task("furuta.toml")

    def make_plant(ctrl):
        plant = FurutaPlant()
        return (lambda x0: plant.reset(x0)), (lambda x, u: plant.step(float(u[0]), task.dt))

    return model, task, make_plant, (lambda seed: FurutaPlant.hanging_start(
        np.random.default_rng(seed)))


def cart():
    """The cart-pendulum: identified model, the true system as the plant."""
    import cart_pendulum
    from lsindy_cas import systems
    from lsindy_cas.control.system import ControlledSystem
    model = cart_pendulum.main(verbose=False)
    task = _load_task("cart_pendulum.toml")
    truth = systems.cart_pendulum()
    bound = task.bind(truth.coords)
    step = ControlledSystem(truth, bound, np.random.default_rng(0)).step

    def make_plant(ctrl):
        return (lambda x0: np.asarray(x0, float)), (lambda x, u: np.asarray(step(x, u)).ravel())

    return model, task, make_plant, (lambda seed: bound.start(np.random.default_rng(seed)))


def dpc():
    """gymnasium's InvertedDoublePendulum-v5 swung up with the continuous force."""
    from double_pendulum_cart import DoublePendulumCartPlant
    from lsindy_cas import LagrangianSINDy
    model = LagrangianSINDy.load(EXAMPLES / "data" / "double_pendulum_cart_model.json")
    task = _load_task("double_pendulum_cart_swingup.toml")
    plant = DoublePendulumCartPlant()
    counter = [0]

    def reset(x0):
        plant.reset(counter[0])          # a fresh env (its step counter) under each episode
        counter[0] += 1
        return plant.reset_to(x0)

    def make_plant(ctrl):
        return reset, (lambda x, u: plant.step(float(u[0]) / GEAR)[0])

    return model, task, make_plant, (lambda seed: DoublePendulumCartPlant.hanging_start(
        np.random.default_rng(seed)))


BUILDERS = {"furuta": furuta, "cart": cart, "dpc": dpc}


# ---------------------------------------------------------------------------- runs
class TimedPlanner:
    """The controller's planner (``ctrl.search``) with the wall clock of each of its calls: the
    steps the planner decided, apart from the local policy's."""

    def __init__(self, planner):
        self.planner, self.times = planner, []

    def __call__(self, x):
        t0 = time.perf_counter()
        out = self.planner(x)
        self.times.append(time.perf_counter() - t0)
        return out

    def __getattr__(self, name):
        return getattr(self.planner, name)


def run(system, planner, n, seed0, parts):
    from lsindy_cas.control.controller import Controller
    from lsindy_cas.control.episodes import run_episode

    t_part = time.perf_counter()
    model, task, make_plant, start = parts
    t0 = time.perf_counter()
    ctrl = Controller(model, task, _settings(planner))
    t_build = time.perf_counter() - t0
    ctrl.search = timed = TimedPlanner(ctrl.search)
    reset, step = make_plant(ctrl)
    b = ctrl.bound
    episodes, times, traces = [], [], []
    for i in range(n):
        seed = seed0 + i
        x0 = np.asarray(reset(start(seed)), float)
        r = run_episode(ctrl, step, x0, stop_at_goal=False)
        ep_times, X, inside = r.step_times, r.X, r.within_limits
        held = r.time_to_goal is not None
        times += ep_times
        traces.append(np.array(X))
        ep = {"seed": seed, "x0": [round(float(v), 6) for v in x0], "success": held and inside,
              "held": held, "within_limits": inside,
              "time_to_goal": round(r.time_to_goal, 3) if held else None,
              "step_ms_max": round(1e3 * max(ep_times), 2)}
        episodes.append(ep)
        log(f"{system} {planner} seed {seed}: {'held' if held else 'NOT held'}"
            + (f", goal at {ep['time_to_goal']:.2f} s" if held else "")
            + ("" if inside else ", LEFT the limits")
            + f" ({time.perf_counter() - t_part:.0f} s)")
    s = np.asarray(times) * 1e3
    sp = np.asarray(timed.times) * 1e3
    ok = [e for e in episodes if e["success"]]
    ttg = np.array([e["time_to_goal"] for e in ok], float)
    res = {"system": system, "planner": planner, "task": task_name(system),
           "episodes": n, "seeds": [seed0, seed0 + n - 1], "success": len(ok),
           "time_to_goal_median": round(float(np.median(ttg)), 3) if ttg.size else None,
           "time_to_goal_max": round(float(ttg.max()), 3) if ttg.size else None,
           "build_s": round(t_build, 2),
           "step_ms_median": round(float(np.median(s)), 4),
           "step_ms_p99": round(float(np.percentile(s, 99)), 3),
           "step_ms_max": round(float(s.max()), 2), "controller_calls": int(s.size),
           "planner_calls": int(sp.size),
           "planner_step_ms_median": round(float(np.median(sp)), 3) if sp.size else None,
           "planner_step_ms_p99": round(float(np.percentile(sp, 99)), 2) if sp.size else None,
           "seconds": round(time.perf_counter() - t_part, 1), "per_episode": episodes}
    if planner == "nlp":
        res["nlp_horizon_intervals"] = timed.horizon
        st = timed.mpc.stats
        res["nlp_solves"], res["nlp_failures"] = int(st.n_solves), int(st.n_failures)
    return res, {"times": s, "traces": traces, "dt": task.dt, "angles": ctrl.system.angles,
                 "target": b.target, "band": b.band}


def task_name(system):
    return {"furuta": "furuta.toml", "cart": "cart_pendulum.toml",
            "dpc": "double_pendulum_cart_swingup.toml"}[system]


# ---------------------------------------------------------------------------- report
def table(results):
    lines = ["| system | planner | success | time to goal median / max (s) | build (s) | "
             "step median / p99 / max (ms) | planner steps: calls, median / p99 (ms) | wall (s) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in results:
        ttg = ("-" if r["time_to_goal_median"] is None
               else f"{r['time_to_goal_median']:.2f} / {r['time_to_goal_max']:.2f}")
        lines.append(f"| {r['system']} | {r['planner']} | {r['success']}/{r['episodes']} | {ttg} "
                     f"| {r['build_s']:.1f} | {r['step_ms_median']:.2f} / {r['step_ms_p99']:.1f} / "
                     f"{r['step_ms_max']:.0f} | {r['planner_calls']}, "
                     f"{r['planner_step_ms_median']:.1f} / {r['planner_step_ms_p99']:.1f} | "
                     f"{r['seconds']:.0f} |")
    return lines


def figure(results, data, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    systems = list(dict.fromkeys(r["system"] for r in results))
    fig, axes = plt.subplots(len(systems), 2, figsize=(11, 3.4 * len(systems)), squeeze=False)
    colors = {"beam": "C0", "nlp": "C3"}
    for row, system in zip(axes, systems):
        for r in (r for r in results if r["system"] == system):
            d = data[(system, r["planner"])]
            # distance from the target in bands: the largest |error| / band over banded states
            banded = np.isfinite(d["band"])
            for k, X in enumerate(d["traces"]):
                E = X - d["target"]
                E[:, d["angles"]] = (E[:, d["angles"]] + np.pi) % (2 * np.pi) - np.pi
                dist = np.max(np.abs(E[:, banded]) / d["band"][banded], axis=1)
                row[0].semilogy(np.arange(len(X)) * d["dt"], dist, color=colors[r["planner"]],
                                lw=0.8, alpha=0.7,
                                label=f"{r['planner']} ({r['success']}/{r['episodes']})"
                                if k == 0 else None)
            row[1].hist(np.maximum(d["times"], 1e-3), bins=np.logspace(-3, 3, 60), alpha=0.6,
                        color=colors[r["planner"]],
                        label=f"{r['planner']}: median {r['step_ms_median']:.2f}, "
                              f"p99 {r['step_ms_p99']:.1f} ms")
        row[0].axhline(1.0, color="k", lw=0.8, ls="--")
        row[0].set(title=f"{system}: distance from the target", xlabel="t (s)",
                   ylabel="max |error| / band")
        row[0].legend(fontsize=8)
        row[1].set(xscale="log", yscale="log", title=f"{system}: controller step time",
                   xlabel="ms", ylabel="calls")
        row[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", help="output folder (planner.json, planner.md, planner.png)")
    ap.add_argument("--systems", default="furuta,cart",
                    help=f"comma-separated among {', '.join(SYSTEMS)} (default: furuta,cart)")
    ap.add_argument("--planners", default="beam,nlp", help="comma-separated among beam, nlp")
    ap.add_argument("--episodes", type=int, default=5, help="starts per system (default 5)")
    ap.add_argument("--seed", type=int, default=0, help="first seed (seeds seed .. seed+N-1)")
    args = ap.parse_args(argv)
    systems = [s.strip() for s in args.systems.split(",") if s.strip()]
    planners = [s.strip() for s in args.planners.split(",") if s.strip()]
    if not systems or set(systems) - set(SYSTEMS):
        ap.error(f"--systems must be among {', '.join(SYSTEMS)}, got {args.systems!r}")
    if not planners or set(planners) - set(PLANNERS):
        ap.error(f"--planners must be among {', '.join(PLANNERS)}, got {args.planners!r}")
    if args.episodes < 1 or args.seed < 0:
        ap.error("--episodes must be >= 1 and --seed >= 0")
    out = out_folder(ap, args.out)
    sys.path.insert(0, str(EXAMPLES))
    t_start = time.perf_counter()
    results, data = [], {}
    for system in systems:
        parts = BUILDERS[system]()
        for planner in planners:
            r, d = run(system, planner, args.episodes, args.seed, parts)
            results.append(r)
            data[(system, planner)] = d
    total = round(time.perf_counter() - t_start, 1)
    lines = table(results)
    print("\n".join(lines))
    print(f"\nrun duration {total:.0f} s")
    doc = {"command": "python benchmarks/bench_planner.py " + " ".join(argv or sys.argv[1:]),
           "seconds": total, "results": results}
    (out / "planner.json").write_text(json.dumps(doc, indent=1))
    (out / "planner.md").write_text("\n".join(lines) + f"\n\nrun duration {total:.0f} s\n")
    figure(results, data, out / "planner.png")
    log(f"wrote {out / 'planner.json'}, planner.md, planner.png")


if __name__ == "__main__":
    main()
