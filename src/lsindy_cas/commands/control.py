"""``lsindy control``: build a controller from a saved model and a task file, run episodes."""
from __future__ import annotations

from ._common import command

CONTROL_EXAMPLE = """examples:
  lsindy control examples/data/acrobot_model.json --task examples/tasks/acrobot.toml --episodes 5
  lsindy control model.json --task task.toml --plant other_model.json --json runs.json --out figs

Exit codes: 0 every episode met the goal, 1 some did not, 2 bad input."""


def _plant(args, task, model):
    """The plant's one-sample map: the model itself or --plant's (same task, its own ODE)."""
    import numpy as np

    from ..control.system import ControlledSystem
    from ..identify.estimator import LagrangianSINDy

    plant_model = model if args.plant is None else LagrangianSINDy.load(args.plant)
    coords = list(getattr(plant_model, "coords_", []))
    if coords != list(model.coords_):
        raise ValueError(f"--plant {args.plant}: its coordinates {coords} differ from the "
                         f"model's {list(model.coords_)}")
    plant = ControlledSystem(plant_model, task.bind(coords), np.random.default_rng(0))
    return lambda x, u: np.asarray(plant.step(x, u)).ravel()


def _figure(results, ctrl, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    names = ctrl.bound.names
    n = len(names)
    fig, axes = plt.subplots(n + 1, 1, figsize=(8, 1.6 * (n + 1)), sharex=True)
    dt = ctrl.task.dt
    for r in results:
        t = np.arange(len(r.X)) * dt
        for i in range(n):
            axes[i].plot(t, r.X[:, i], lw=0.8, color="C0" if r.success else "C3")
        if len(r.U):
            axes[n].step(t[:-1], r.U[:, 0], where="post", lw=0.6,
                         color="C0" if r.success else "C3")
    for i, name in enumerate(names):
        axes[i].set_ylabel(name)
        if ctrl.bound.target is not None and np.isfinite(ctrl.bound.band[i]):
            lo = ctrl.bound.target[i] - ctrl.bound.band[i]
            axes[i].axhspan(lo, lo + 2 * ctrl.bound.band[i], color="0.85", zorder=0)
    axes[n].set_ylabel(f"u ({list(ctrl.task.inputs)[0]})")
    axes[n].set_xlabel("t (s)")
    ok = sum(r.success for r in results)
    fig.suptitle(f"{ok}/{len(results)} episodes met the goal (blue: met, red: not)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(args) -> int:
    import json

    import numpy as np

    from .._io import atomic_write, check_writable, output_dir
    from ..control.controller import Controller
    from ..control.episodes import run_episode
    from ..control.task import Task
    from ..identify.estimator import LagrangianSINDy
    from ..progress import ProgressBar

    if args.episodes < 1:
        raise ValueError(f"--episodes must be a positive integer, got {args.episodes}")
    if args.seed < 0:
        raise ValueError(f"--seed must be >= 0, got {args.seed}")
    if args.json:
        check_writable(args.json, "--json")
    out = output_dir(args.out, "--out") if args.out else None
    plugin = None
    if args.plugin is not None:
        from ..control.plugins import plugin as make_plugin
        try:                                       # refused before any work
            plugin = make_plugin(args.plugin)
        except ValueError as exc:
            raise ValueError(f"--plugin {args.plugin!r}: {exc}") from None
    task = Task.load(args.task)
    model = LagrangianSINDy.load(args.model)
    task.bind(model.coords_)                       # names checked before anything is built
    ctrl = Controller(model, task, plugin=plugin)
    plant = _plant(args, task, model)
    rng = np.random.default_rng(args.seed)
    results = []
    bar = ProgressBar("episodes", unit="episode")
    for i in range(args.episodes):
        results.append(run_episode(ctrl, plant, ctrl.bound.start(rng)))
        bar(i + 1, args.episodes)
    bar.close()
    ok = [r for r in results if r.success]
    times = [r.time_to_goal for r in ok]
    steps = np.concatenate([r.step_times for r in results]) * 1e3
    print(f"{len(ok)}/{len(results)} episodes met the goal"
          + (f"; time to goal median {np.median(times):.2f} s (min {min(times):.2f}, "
             f"max {max(times):.2f})" if times else ""))
    print(f"controller step: median {np.median(steps):.2f} ms, p99 "
          f"{np.percentile(steps, 99):.2f} ms, max {np.max(steps):.1f} ms "
          f"over {steps.size} steps")
    for i, r in enumerate(results):
        if not r.success:
            why = "left the limits" if not r.within_limits else "goal not met in time"
            print(f"  episode {i}: {why} (start {np.round(r.x0, 3).tolist()})")
    summary = {"model": str(args.model), "task": str(args.task), "plant": args.plant,
               "seed": args.seed, "episodes": [r.summary() for r in results],
               "success": len(ok), "n": len(results),
               "time_to_goal_median": float(np.median(times)) if times else None,
               "step_ms_median": float(np.median(steps)),
               "step_ms_p99": float(np.percentile(steps, 99))}
    if args.json:
        def write(p):
            with open(p, "w") as fh:
                json.dump(summary, fh, indent=1)
        atomic_write(args.json, write)
        print(f"results written to {args.json}")
    if out is not None:
        path = out / "control.png"
        _figure(results, ctrl, path)
        print(f"figure written to {path}")
    return 0 if len(ok) == len(results) else 1


def add_to(sub) -> None:
    """Add the subcommand to the ``lsindy`` parser's subparsers."""
    c = command(sub, "control", "control a saved model's system for a task (episodes on a model)",
                "Build a controller from a saved model (lsindy identify --json) and a task file "
                "(TOML: sample time, inputs with levels or bounds, goal, limits; see "
                "docs/control.md), then run closed-loop episodes from the task's starts on the "
                "model itself or on --plant, another model of the same coordinates. Prints "
                "success, time to goal and controller step times.", CONTROL_EXAMPLE)
    c.add_argument("model", metavar="MODEL.json", help="saved model file")
    c.add_argument("--task", required=True, metavar="TASK.toml", help="task file")
    c.add_argument("--plant", default=None, metavar="PLANT.json",
                   help="simulate the episodes on this model instead (e.g. a mismatched one)")
    c.add_argument("--plugin", default=None, metavar="NAME",
                   help="a system-specific policy in place of the generic one "
                   "(cart_pendulum: the swing-up MPC of lsindy swingup)")
    c.add_argument("--episodes", type=int, default=5, help="episodes to run (default 5)")
    c.add_argument("--seed", type=int, default=0, help="seed of the random starts (default 0)")
    c.add_argument("--json", default=None, metavar="F", help="write the results as JSON")
    c.add_argument("--out", default=None, metavar="DIR", help="write a figure of the episodes")
    c.set_defaults(func=run)
