"""Track guard: success and track used with and without it, on the paper's plant.

For each scenario (``nominal``; ``mismatch``: cart mass, pole mass and pole length each off by
+-10 %, signs drawn per episode as in ``lsindy swingup``) the controller built from the
identified model runs the same random starts with ``guard=False`` (no guard) and
``guard=True``; the table gives successes, max |x| and the steps the guard braked.  Writes
``track_guard.json`` to ``--out``.

    python benchmarks/bench_track_guard.py --out /tmp/guard --starts 20
    python benchmarks/bench_track_guard.py --out /tmp/guard --quick   # 3 starts
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from lsindy_cas import systems
from lsindy_cas.mpc import SwingUpMPC
from lsindy_cas.paper.swingup import Plant, identify_cart_pendulum, random_starts, run_episode

DT = 0.05


def run(model, starts, scenario, guard, seed):
    """One cell: episodes of one controller; returns a JSON-ready summary."""
    ctrl = SwingUpMPC(model, dt=DT, guard=guard)
    rng = np.random.default_rng([seed, scenario == "mismatch"])
    p = systems.cart_pendulum().params
    rows = []
    for x0 in starts:
        f = 1.0 + 0.1 * rng.choice([-1.0, 1.0], size=3) if scenario == "mismatch" else np.ones(3)
        true = systems.cart_pendulum(mc=p["mc"] * f[0], mp=p["mp"] * f[1], L=p["L"] * f[2])
        n0 = ctrl.stats.n_guard
        ep = run_episode(ctrl, Plant(true, DT), x0)
        rows.append({"success": bool(ep.success), "track_used": float(ep.track_used),
                     "time_to_upright": float(ep.time_to_upright),
                     "n_guard": ctrl.stats.n_guard - n0, "factors": f.tolist()})
    return {"successes": sum(r["success"] for r in rows), "episodes": len(rows),
            "max_track_used": max(r["track_used"] for r in rows),
            "n_guard": sum(r["n_guard"] for r in rows),
            "median_time_to_upright": float(np.median([r["time_to_upright"] for r in rows])),
            "step_ms_median": ctrl.stats.summary()["step_ms_median"], "episodes_detail": rows}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="output folder (track_guard.json)")
    ap.add_argument("--starts", type=int, default=20, help="random starts per cell")
    ap.add_argument("--quick", action="store_true", help="3 starts")
    ap.add_argument("--scenarios", default="nominal,mismatch")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--variants", default="off,on",
                    help="controllers run: off (guard=False), on (guard=True) or both")
    args = ap.parse_args(argv)
    n = 3 if args.quick else args.starts
    scenarios = args.scenarios.split(",")
    variants = [{"off": False, "on": True}.get(v) for v in args.variants.split(",")]
    if n < 1 or not set(scenarios) <= {"nominal", "mismatch"} or None in variants:
        ap.error("--starts must be >= 1, --scenarios among nominal,mismatch and --variants "
                 "among off,on")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    model, _ = identify_cart_pendulum()
    starts = random_starts(n, args.seed)
    report = {"starts": n, "seed": args.seed, "cells": {}}
    print("| scenario | guard | success | max abs x (m) | guard steps | median t_up (s) |")
    print("|---|---|---|---|---|---|")
    for scen in scenarios:
        for guard in variants:
            c = run(model, starts, scen, guard, args.seed)
            report["cells"][f"{scen}/{'guard' if guard else 'no-guard'}"] = c
            print(f"| {scen} | {guard} | {c['successes']}/{c['episodes']} | "
                  f"{c['max_track_used']:.2f} | {c['n_guard']} | "
                  f"{c['median_time_to_upright']:.2f} |", flush=True)
    report["seconds"] = time.perf_counter() - t0
    (out / "track_guard.json").write_text(json.dumps(report, indent=1))
    print(f"\n{report['seconds']:.0f} s; wrote {out / 'track_guard.json'}")


if __name__ == "__main__":
    main()
