"""Benchmark of the discrete-force swing-up MPC: solvers and discrete-force strategies.

For each configuration, the controller built from the *identified* cart-pendulum runs the 20
random starts of the swing-up benchmark (seed 0) on the true plant; the table reports success,
time to upright, track used, fallbacks, and the per-step solve time over all episodes (wall
clock and CPU time of the calling thread; the CPU time is not inflated when other processes
share the cores).  The
default configuration is also run with +-10 % plant mismatch and with N(0, 0.01^2) measurement
noise.  Prints a markdown table and writes ``mpc.json`` into ``--out`` (default
``benchmarks/results/``).

    python benchmarks/bench_mpc.py                 # everything (about 8 minutes on 2 cores)
    python benchmarks/bench_mpc.py --episodes 3    # quick look
    python benchmarks/bench_mpc.py --configs sqp+continuous+lookahead+balancer,sqp+nojit,\
sqp+ipopt-recovery --no-robustness --out /tmp/rt  # the real-time comparison

The default compiles the NLP's derivatives with gcc where there is one (about
8 s the first time for a model, cached in ``$LSINDY_CACHE_DIR``, see
``lsindy_cas/control/compiled.py``; ``compiled`` in the JSON says whether it did): run once
before timing, or read ``build_s``.  ``sqp+nojit`` is the default uncompiled (as where
there is no gcc).  ``slow_steps`` in the JSON counts the steps over 20 ms by what
they ran (cold start, recovery, warm SQP, balancer): the p99 of 4,000 steps is the 40th
slowest.  ``force_digests`` fingerprints each episode's forces; the script prints how many
episodes of each configuration applied exactly the forces of the first one.

The configurations given run interleaved (start ``i`` of each before start ``i + 1`` of any), so
that a change of the machine's load affects them alike.

Step times are wall clock (what a real-time loop sees) and CPU time of the calling thread
(``step_cpu_ms``: less inflated when other processes share the cores); measure the wall-clock
p99 on an idle machine.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from lsindy_cas.mpc import SwingUpMPC
from lsindy_cas.paper.swingup import (identify_cart_pendulum, random_starts, run_episode,
                                scenario_plant, scenario_stats)

CONFIGS = {
    # name: (SwingUpMPC options, what it shows); "default" is also run for robustness.
    # The discrete-force strategies are compared as such (balance=False: the rule picks the
    # level everywhere); the solvers with the default pulse balancer near the upright.
    "sqp+continuous+lookahead+balancer": ({"solver": "sqp", "relaxation": "continuous",
                                           "rounding": "lookahead"}, "default"),
    "sqp+solve-balanced": ({"solver": "sqp", "relaxation": "continuous", "rounding": "lookahead",
                            "solve_balanced": True},
                           "relaxed NLP solved on the balancer's steps too (once the default)"),
    "sqp+inexact1e-3": ({"solver": "sqp", "relaxation": "continuous", "rounding": "lookahead",
                         "inexact_tol": 1e-3},
                        "capped SQP iterates applied if within 1e-3 of feasibility"),
    "sqp+inexact1e-3+cap6": ({"solver": "sqp", "relaxation": "continuous",
                              "rounding": "lookahead", "inexact_tol": 1e-3, "max_iter": 6},
                             "as sqp+inexact1e-3, at most 6 SQP iterations per step"),
    "sqp+inexact1e-3+cap8": ({"solver": "sqp", "relaxation": "continuous",
                              "rounding": "lookahead", "inexact_tol": 1e-3, "max_iter": 8},
                             "as sqp+inexact1e-3, at most 8 SQP iterations per step"),
    "sqp+cap10": ({"solver": "sqp", "relaxation": "continuous", "rounding": "lookahead",
                   "max_iter": 10}, "at most 10 warm SQP iterations per step (formerly the "
                  "default; the default is 7)"),
    "sqp+cap8": ({"solver": "sqp", "relaxation": "continuous", "rounding": "lookahead",
                  "max_iter": 8}, "at most 8 warm SQP iterations per step"),
    "sqp+continue": ({"solver": "sqp", "relaxation": "continuous", "rounding": "lookahead",
                      "cold": "warm", "recovery": "continue"},
                     "SQP cold start, failed iterates continued, IPOPT after 3 failures"),
    "sqp+ipopt-recovery": ({"solver": "sqp", "relaxation": "continuous",
                            "rounding": "lookahead", "cold": "ipopt", "recovery": "ipopt"},
                           "cold starts and recoveries by IPOPT (the default before fatrop)"),
    "sqp+jit": ({"solver": "sqp", "relaxation": "continuous", "rounding": "lookahead",
                 "jit": True}, "default with the NLP functions compiled, explicitly (gcc, "
                "cached; the default itself where gcc is)"),
    "sqp+nojit": ({"solver": "sqp", "relaxation": "continuous", "rounding": "lookahead",
                   "jit": False}, "default with the NLP uncompiled (once the default; "
                  "still the default where there is no gcc)"),
    "sqp+no-estimator": ({"solver": "sqp", "relaxation": "continuous", "rounding": "lookahead",
                          "adapt_model": False}, "default without the coefficient estimate "
                         "waiting for a stall (adapt_model=False: once the default)"),
    "sqp+fatrop": ({"solver": "sqp", "relaxation": "continuous", "rounding": "lookahead",
                    "cold": "fatrop", "recovery": "fatrop"},
                   "cold starts and recoveries by fatrop (the default, explicitly)"),
    "sqp+fatrop+jit": ({"solver": "sqp", "relaxation": "continuous", "rounding": "lookahead",
                        "cold": "fatrop", "recovery": "fatrop", "jit": True},
                       "fatrop cold starts and recoveries, NLP functions compiled: the "
                       "default where gcc is, explicitly"),
    "sqp+continuous+lookahead": ({"solver": "sqp", "relaxation": "continuous",
                                  "rounding": "lookahead", "balance": False},
                                 "lookahead everywhere (no balancer)"),
    "sqp+poc+lookahead": ({"solver": "sqp", "relaxation": "poc", "rounding": "lookahead",
                           "balance": False}, "POC weights, lookahead"),
    "sqp+poc+sur": ({"solver": "sqp", "relaxation": "poc", "rounding": "sur", "balance": False},
                    "POC weights, sum-up rounding carried across steps"),
    "sqp+poc+nearest": ({"solver": "sqp", "relaxation": "poc", "rounding": "nearest",
                         "balance": False}, "POC weights, largest weight (no memory)"),
    "sqp+continuous+nearest": ({"solver": "sqp", "relaxation": "continuous",
                                "rounding": "nearest", "balance": False},
                               "plain rounding of a continuous solution"),
    "sqp-gn+continuous+lookahead+balancer": ({"solver": "sqp-gn", "relaxation": "continuous",
                                              "rounding": "lookahead"}, "Gauss-Newton SQP"),
    "fatrop+continuous+lookahead+balancer": ({"solver": "fatrop", "relaxation": "continuous",
                                              "rounding": "lookahead"}, "fatrop"),
    "ipopt+continuous+lookahead+balancer": ({"solver": "ipopt", "relaxation": "continuous",
                                             "rounding": "lookahead"}, "IPOPT"),
}
DEFAULT = "sqp+continuous+lookahead+balancer"
ROBUSTNESS = ("mismatch", "noise")


def run_config(model, options, starts, scenario="nominal", seed=0, noise_std=0.01):
    """Run all starts with one controller; returns a JSON-ready dict of metrics."""
    return run_configs(model, [options], starts, scenario, seed, noise_std)[0]


def run_configs(model, option_list, starts, scenario="nominal", seed=0, noise_std=0.01):
    """Run all starts with one controller per entry of ``option_list``, interleaved: start
    ``i`` of every configuration runs before start ``i + 1`` of any, so that a change of the
    machine's load during the run affects all configurations alike.  Each configuration draws
    its plants and noise from its own generator, as if run alone.  Returns one JSON-ready dict
    of metrics per configuration."""
    ctrls, builds, rngs, eps = [], [], [], []
    for options in option_list:
        t0 = time.perf_counter()
        ctrls.append(SwingUpMPC(model, **options))
        builds.append(time.perf_counter() - t0)
        rngs.append(np.random.default_rng([seed, 7]))
        eps.append([])
    for x0 in starts:
        for ctrl, rng, episodes in zip(ctrls, rngs, eps):
            plant, _ = scenario_plant(scenario, rng, ctrl.dt)
            episodes.append(run_episode(ctrl, plant, x0, noise_std=noise_std
                                        if scenario == "noise" else 0.0, rng=rng))
    return [_metrics(c, o, e, scenario, b)
            for c, o, e, b in zip(ctrls, option_list, eps, builds)]


def _metrics(ctrl, options, eps, scenario, build):
    """JSON-ready metrics of one configuration's episodes."""
    s = ctrl.stats.summary()
    return dict(
        scenario_stats(eps), scenario=scenario, options=options,
        all_forces_in_set=bool(all(np.isin(e.forces, ctrl.levels).all() for e in eps)),
        n_solves=s["n_solves"], n_inexact=s["n_inexact"], n_balanced=s["n_balanced"],
        n_steps=len(ctrl.stats.step_times),
        solve_ms={"median": s["solve_ms_median"], "p99": s["solve_ms_p99"],
                  "max": s["solve_ms_max"]},
        solve_cpu_ms={"median": s["solve_cpu_ms_median"], "p99": s["solve_cpu_ms_p99"]},
        step_ms={"median": s["step_ms_median"], "p99": s["step_ms_p99"]},
        step_cpu_ms={"median": s["step_cpu_ms_median"], "p99": s["step_cpu_ms_p99"]},
        solver={"by_kind": s["by_kind"], "statuses": s["statuses"]},
        slow_steps={"wall": s["slow_steps"], "cpu": s["slow_steps_cpu"]},
        iterations_median=s["iterations_median"], build_s=round(build, 3),
        compiled=bool(ctrl.nlp.jit),
        force_digests=[hashlib.sha1(e.forces.tobytes()).hexdigest()[:12] for e in eps],
        failed_starts=[e.x0.round(4).tolist() for e in eps if not e.success])


def reference_ms(model, repeats=5):
    """Median times (ms) of two fixed workloads, to compare runs made on machines (or days) of
    different speed: a pure-Python loop of 10^6 additions, and 10^3 evaluations of the model's
    ODE in CasADi's virtual machine (what the solver's functions run on)."""
    ode = model.ode()
    x, u = np.array([0.1, 3.0, 0.2, -0.3]), np.zeros(2)

    def loop():
        s = 0
        for i in range(10 ** 6):
            s += i

    def casadi_calls():
        for _ in range(10 ** 3):
            ode(x, u)

    out = {}
    for name, f in (("python_loop_1e6", loop), ("casadi_ode_1e3", casadi_calls)):
        t = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            f()
            t.append(1e3 * (time.perf_counter() - t0))
        out[name] = float(np.median(t))
    return out


def table(rows):
    head = ("| configuration | scenario | success | median t_up (s) | max abs x (m) | fallbacks "
            "| solve median (ms) | solve p99 (ms) | CPU p99 (ms) | step median (ms) "
            "| step p99 (ms) | step CPU median (ms) | step CPU p99 (ms) |")
    lines = [head, "|" + "---|" * 13]
    for name, r in rows:
        lines.append(
            f"| {name} | {r['scenario']} | {100 * r['success_rate']:.0f} % | "
            f"{r['median_time_to_upright']:.2f} | {r['max_track_used']:.2f} | "
            f"{r['n_failures']}/{r['n_solves']} | {r['solve_ms']['median']:.2f} | "
            f"{r['solve_ms']['p99']:.1f} | {r['solve_cpu_ms']['p99']:.1f} | "
            f"{r['step_ms']['median']:.2f} | {r['step_ms']['p99']:.1f} | "
            f"{r['step_cpu_ms']['median']:.2f} | {r['step_cpu_ms']['p99']:.1f} |")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--configs", default=",".join(CONFIGS),
                        help="comma-separated subset of " + ", ".join(CONFIGS))
    parser.add_argument("--out", default=str(Path(__file__).parent / "results"),
                        help="folder for mpc.json (created if missing)")
    parser.add_argument("--json", default=None, help="output file (overrides --out)")
    parser.add_argument("--no-robustness", action="store_true",
                        help="skip the mismatch and noise runs of the default")
    args = parser.parse_args(argv)
    if args.json is None:
        args.json = str(Path(args.out) / "mpc.json")
    names = [c for c in args.configs.split(",") if c]
    unknown = set(names) - set(CONFIGS)
    if unknown:
        parser.error(f"unknown configurations {sorted(unknown)}")
    model, _ = identify_cart_pendulum()
    starts = random_starts(args.episodes, args.seed)
    load_before = os.getloadavg()
    reference = reference_ms(model)
    print("machine speed (median ms of fixed workloads; compare runs by these): "
          + ", ".join(f"{k} {v:.0f}" for k, v in reference.items()), flush=True)
    rows = list(zip(names, run_configs(model, [CONFIGS[n][0] for n in names], starts,
                                       seed=args.seed)))
    if DEFAULT in names and not args.no_robustness:
        for scenario in ROBUSTNESS:
            rows.append((DEFAULT, run_config(model, CONFIGS[DEFAULT][0], starts, scenario,
                                             seed=args.seed)))
            print(table(rows[-1:]).splitlines()[-1], flush=True)
    print()
    print(table(rows))
    first = rows[0][1]
    print(f"\nepisodes with the same forces as {rows[0][0]} ({first['scenario']}): " + ", ".join(
        f"{n} {sum(a == b for a, b in zip(r['force_digests'], first['force_digests']))}"
        f"/{len(first['force_digests'])}" for n, r in rows[1:] if r["scenario"] ==
        first["scenario"]))
    print("\nsteps over 20 ms by kind (wall clock | CPU time):")
    for name, r in rows:
        print(f"  {name} ({r['scenario']}): {r['slow_steps']['wall']} | {r['slow_steps']['cpu']}")
    report = {"machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                          "loadavg_before": load_before, "loadavg_after": os.getloadavg(),
                          "reference_ms": reference},
              "episodes": args.episodes, "seed": args.seed,
              "criteria": "success: |wrap(theta - pi)| < 0.1 rad and |theta_dot| < 0.5 rad/s "
                          "over the last 3 s of 10 s, |x| <= 2 m throughout",
              "results": [dict(r, configuration=n, note=CONFIGS[n][1]) for n, r in rows]}
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(report, indent=2))
    print(f"\nwritten to {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
