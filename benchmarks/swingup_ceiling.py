"""Is the swing-up's mismatch shortfall model error, or the coarse force?

On the nominal plant and on each of the 8 sign patterns of a 10 % error in cart mass, pole
mass and pole length, the same random starts are run twice:

* ``identified``: the controller built from the model identified on the nominal plant (the
  ``mismatch`` scenario of ``lsindy swingup``);
* ``exact``: the controller built from the plant's own equations of motion (no model error at
  all): the ceiling of the controller design on that plant.

The table also gives the kick: the change of the pole rate over one 50 ms push of 10 N from
rest at upright, against the success band of +-0.5 rad/s.  Prints a markdown table and writes
``benchmarks/results/swingup_ceiling.json``.

    python benchmarks/swingup_ceiling.py                # 20 starts per plant (~7 min on 2 cores)
    python benchmarks/swingup_ceiling.py --starts 2     # quick look
    python benchmarks/swingup_ceiling.py --balance off  # without the pulse balancer (before it)

``--balance off`` builds the controllers with ``balance=False``: the force is then chosen from
the relaxed plan everywhere, also near the upright (``swingup_ceiling_no_balance.json``).
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import numpy as np

from lsindy_cas.mpc import SwingUpMPC
from lsindy_cas.paper.swingup import (Plant, identify_cart_pendulum, mismatched_cart_pendulum,
                                random_starts, run_episode)

DT = 0.05  # control period (s) of the controller and of the plant's zero-order hold


def kick(plant, force=10.0):
    """Pole-rate change (rad/s) over one control period of ``force`` from rest at upright."""
    return float(abs(plant.step(np.array([0.0, np.pi, 0.0, 0.0]), force)[-1, 3]))


def run(model, plant, starts, balance=True):
    """Success flags and times to upright of one controller on one plant."""
    ctrl = SwingUpMPC(model, dt=DT, balance=balance)
    episodes = [run_episode(ctrl, plant, x0) for x0 in starts]
    return [bool(e.success) for e in episodes], [float(e.time_to_upright) for e in episodes]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", type=int, default=20, help="random starts per plant")
    parser.add_argument("--seed", type=int, default=0, help="seed of the random starts")
    parser.add_argument("--balance", choices=("on", "off"), default="on",
                        help="pulse balancer near the upright (default on)")
    parser.add_argument("--json", help="output (default benchmarks/results/"
                        "swingup_ceiling.json, or swingup_ceiling_no_balance.json)")
    args = parser.parse_args(argv)
    if args.starts < 1:
        parser.error("--starts must be >= 1")
    balance = args.balance == "on"
    if args.json is None:
        args.json = str(Path(__file__).parent / "results" /
                        ("swingup_ceiling.json" if balance else "swingup_ceiling_no_balance.json"))
    identified, _ = identify_cart_pendulum()
    starts = random_starts(args.starts, args.seed)
    rows, t0 = [], time.perf_counter()
    print("| mc | mp | L | kick (rad/s) | identified model | exact model |")
    print("|---|---|---|---|---|---|")
    for signs in [(0.0, 0.0, 0.0), *itertools.product((-1.0, 1.0), repeat=3)]:
        f = 1.0 + 0.1 * np.array(signs)
        true = mismatched_cart_pendulum(f)
        plant = Plant(true, DT)
        row = {"factors": f.tolist(), "kick": kick(plant)}
        for name, model in (("identified", identified), ("exact", true)):
            ok, t_up = run(model, plant, starts, balance)
            row[name] = {"successes": int(sum(ok)), "episodes": len(ok),
                         "failed_starts": [i for i, s in enumerate(ok) if not s],
                         "median_time_to_upright": float(np.median(t_up))}
        rows.append(row)
        print(f"| {f[0]:.1f} | {f[1]:.1f} | {f[2]:.1f} | {row['kick']:.2f} | "
              f"{row['identified']['successes']}/{len(starts)} | "
              f"{row['exact']['successes']}/{len(starts)} |", flush=True)
    mism = rows[1:]  # the 8 mismatched plants
    total = {k: sum(r[k]["successes"] for r in mism) for k in ("identified", "exact")}
    n = len(mism) * len(starts)
    print(f"\nmismatched plants: identified {total['identified']}/{n}, exact {total['exact']}/{n}; "
          f"{time.perf_counter() - t0:.0f} s")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps({"starts": args.starts, "seed": args.seed,
                                           "balance": balance,
                                           "rows": rows, "total": total, "episodes": n},
                                          indent=1))


if __name__ == "__main__":
    main()
