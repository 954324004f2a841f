"""The sequence balancer's plan time with and without its costs of leaving the success band.

Three controllers on the same exact model of a family plant (``bench_family.PLANTS``), the
sequence balancer with ``between_weight`` 0 (samples only), with the pole's turn
between samples priced (``success_weight=0``) and as by default (also the
success band's own term where the pole turns round inside it), run the same nominal episodes, interleaved start by start and repeated ``--repeats`` times so that
the machine's load affects both alike.  Reports, per configuration and repeat, the balancer's
plan time (median, p99, max over every plan) and the step time (everything ``ctrl(x)`` does),
the medians and spreads over the repeats, and the episodes' outcomes (deterministic: equal in
every repeat).  Prints a markdown table and writes ``balancer_time.json`` and ``.md`` to ``--out``.

    python benchmarks/bench_balancer_time.py --out DIR                 # 0.8/0.2/0.7, 4 x 3, ~3 min
    python benchmarks/bench_balancer_time.py --out DIR --plant 4 --starts 6 --repeats 3
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _cli import out_folder  # noqa: E402
from bench_family import DT, PLANTS  # noqa: E402

from lsindy_cas import systems  # noqa: E402
from lsindy_cas.mpc import SwingUpMPC  # noqa: E402
from lsindy_cas.paper.swingup import Plant, random_starts, run_episode  # noqa: E402

CONFIGS = {"samples only (between_weight=0, success_weight=0)": {"between_weight": 0.0,
                                                                  "success_weight": 0.0},
           "the turn between samples (success_weight=0)": {"success_weight": 0.0},
           "default (the success band's own term too)": {}}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="output folder (balancer_time.json, .md)")
    ap.add_argument("--plant", type=int, default=1, help="index into bench_family.PLANTS "
                    "(default 1: 0.8/0.2/0.7)")
    ap.add_argument("--starts", type=int, default=4, help="nominal starts (seed 0), default 4")
    ap.add_argument("--repeats", type=int, default=3, help="repeats of the whole set")
    args = ap.parse_args(argv)
    if not 0 <= args.plant < len(PLANTS):
        ap.error(f"--plant must be in 0..{len(PLANTS) - 1}")
    if args.starts < 1 or args.repeats < 1:
        ap.error("--starts and --repeats must be >= 1")
    out = out_folder(ap, args.out)
    mc, mp, L = PLANTS[args.plant]
    system = systems.cart_pendulum(mc=mc, mp=mp, L=L)
    ctrls = {name: SwingUpMPC(system, dt=DT, balance=dict(method="sequence", **options))
             for name, options in CONFIGS.items()}
    starts = random_starts(args.starts, 0)
    runs = {name: [] for name in CONFIGS}
    t0 = time.perf_counter()
    for rep in range(args.repeats):
        plans = {name: [] for name in CONFIGS}
        steps = {name: [] for name in CONFIGS}
        outcomes = {name: [] for name in CONFIGS}
        for k, x0 in enumerate(starts):
            for name, ctrl in ctrls.items():
                ctrl.balancer.plan_seconds.clear()
                ctrl.stats.clear()
                ep = run_episode(ctrl, Plant(system, DT), x0)
                plans[name] += ctrl.balancer.plan_seconds
                steps[name] += list(ctrl.stats.step_times)
                outcomes[name].append(bool(ep.success))
            print(f"repeat {rep + 1}/{args.repeats}, start {k + 1}/{args.starts} "
                  f"({time.perf_counter() - t0:.0f} s)", flush=True)
        for name in CONFIGS:
            p, s = 1e3 * np.array(plans[name]), 1e3 * np.array(steps[name])
            runs[name].append({"plans": int(p.size), "plan_ms_median": float(np.median(p)),
                               "plan_ms_p99": float(np.percentile(p, 99)),
                               "plan_ms_max": float(p.max()),
                               "step_ms_median": float(np.median(s)),
                               "step_ms_p99": float(np.percentile(s, 99)),
                               "successes": int(sum(outcomes[name]))})
    fmt = lambda rs, k: " / ".join(f"{r[k]:.1f}" for r in rs)  # noqa: E731
    lines = [f"`python benchmarks/bench_balancer_time.py --out DIR --plant {args.plant} --starts "
             f"{args.starts} --repeats {args.repeats}` ({time.perf_counter() - t0:.0f} s): plant "
             f"{mc}/{mp}/{L}, exact model, sequence balancer, {args.starts} nominal starts, "
             "the configurations interleaved start by start; one figure per repeat.", "",
             "| configuration | successes | plans | plan median (ms) | plan p99 (ms) | "
             "plan max (ms) | step median (ms) | step p99 (ms) |",
             "|---|---|---|---|---|---|---|---|"]
    for name, rs in runs.items():
        lines.append(f"| {name} | {rs[0]['successes']}/{args.starts} | {rs[0]['plans']} | "
                     f"{fmt(rs, 'plan_ms_median')} | {fmt(rs, 'plan_ms_p99')} | "
                     f"{fmt(rs, 'plan_ms_max')} | {fmt(rs, 'step_ms_median')} | "
                     f"{fmt(rs, 'step_ms_p99')} |")
    (out / "balancer_time.md").write_text("\n".join(lines) + "\n")
    (out / "balancer_time.json").write_text(json.dumps(
        {"plant": [mc, mp, L], "starts": args.starts, "repeats": args.repeats,
         "configs": CONFIGS, "runs": runs, "seconds": time.perf_counter() - t0}, indent=1))
    print("\n".join(lines))
    print(f"written: {out / 'balancer_time.md'} and balancer_time.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
