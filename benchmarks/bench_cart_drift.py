"""Anatomy of the family plants' balancing failures: hand-over or the balancer's own cart drift?

For each plant of ``bench_family.PLANTS`` (identified from its own simulated run, or its exact
equations) and each random start, one swing-up episode (``run_episode``: 10 s, {-10, 0, 10} N
at 20 Hz), nominal or with the +-10 % mismatch of the family benchmark (same seeds, so the
episodes are the family benchmark's).  Per episode, from the controller's balancer
(:class:`~lsindy_cas.control.cart_pendulum.sequence_balancer.SequenceBalancer`):

* the hand-over: time of the first step the balancer acts, the cart's slow coordinates there
  (``p = x - ratio * phi``, ``v0 = x_dot - ratio * theta_dot``: the pushes do not move them)
  and its :meth:`cart_urgency` (where the cart would stop by leaning, as a share of the
  usable track), the number of hand-overs and the share of the remaining steps the balancer
  acted;
* the cart: when ``|x|`` first passes ``--far`` m (at all, and after the first hand-over)
  and its largest ``|x|``;
* the success band in the last 3 s: how many control samples left it (|phi| >= 0.1 rad or
  |theta_dot| >= 0.5 rad/s) and the state at the first of them.

A failure is ``handover`` when the cart was already past recovery at the first hand-over
(urgency > 1), ``drift`` when it was handed over recoverable and the cart passed ``--far`` m
after the hand-over, ``pole`` otherwise; episodes whose plant has an empty pole kernel are
``unreachable`` (as in the family benchmark).  Prints a table per plant and scenario and
writes ``cart_drift.json`` to ``--out``.

    python benchmarks/bench_cart_drift.py --out DIR --plants 2,11          # ~2 min
    python benchmarks/bench_cart_drift.py --out DIR --quick                # plant 2, 5 starts
    python benchmarks/bench_cart_drift.py --out DIR --plants 2 --models exact \\
        --balance '{"centre_weight": 30}'
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_family import DT, PLANTS, plant_kernel  # noqa: E402

from lsindy_cas import systems  # noqa: E402
from lsindy_cas.mpc import SwingUpMPC  # noqa: E402
from lsindy_cas.paper.swingup import (Plant, identify_cart_pendulum, random_starts,  # noqa: E402
                                      wrap_angle)

STEPS, LAST = 200, 60  # 10 s of 50 ms steps; the last 3 s


def episode(ctrl, plant, x0, far):
    """One episode step by step, recording the balancer's engagement; returns a dict."""
    b = ctrl.balancer
    ctrl.reset()
    x = np.asarray(x0, dtype=float)
    X, eng = [x], []
    for _ in range(STEPS):
        u = ctrl(x)
        eng.append(bool(b.engaged))
        x = plant.step(x, u)[-1]
        X.append(x)
    X, eng = np.array(X), np.array(eng)
    ic, ip = ctrl.cart_index, ctrl.pole_index
    phi = wrap_angle(X[:, ip] - ctrl.upright)
    out = (np.abs(phi) >= 0.1) | (np.abs(X[:, 2 + ip]) >= 0.5)
    last = np.flatnonzero(out[-LAST - 1:]) + X.shape[0] - LAST - 1
    row = {"success": bool(np.abs(X[:, ic]).max() <= ctrl.track_limit and last.size == 0),
           "max_abs_x": float(np.abs(X[:, ic]).max()),
           "handovers": int(np.sum(np.diff(eng.astype(int)) == 1) + eng[0]),
           "last3_out_samples": int(last.size)}
    passed = np.flatnonzero(np.abs(X[:, ic]) > far)
    row["t_far"] = float(passed[0] * DT) if passed.size else None
    on = np.flatnonzero(eng)
    after = passed[passed > on[0]] if on.size else passed[:0]
    row["t_far_after_handover"] = float(after[0] * DT) if after.size else None
    if on.size:
        e = X[on[0]] - b.x_ref
        e[ip] = wrap_angle(e[ip])
        row.update(t_handover=float(on[0] * DT),
                   p=float(e[ic] - b.ratio * e[ip]), v0=float(e[2 + ic] - b.ratio * e[2 + ip]),
                   urgency=float(b.cart_urgency(e)), engaged_share=float(eng[on[0]:].mean()))
    if last.size:
        j = last[0]
        row["first_out"] = {"t": float(j * DT), "x": float(X[j, ic]), "phi": float(phi[j]),
                            "rate": float(X[j, 2 + ip])}
    return row


def cause(row, far_seen):
    """Failure class of a non-unreachable failed episode (module docstring)."""
    if row.get("urgency", 0.0) > 1.0:
        return "handover"
    return "drift" if far_seen else "pole"


def run(i, model_kind, scen, starts, options, far, seed):
    """Episodes of plant ``i`` in one scenario; returns (summary, rows)."""
    mc, mp, L = PLANTS[i]
    system = systems.cart_pendulum(mc=mc, mp=mp, L=L)
    model = system if model_kind == "exact" else identify_cart_pendulum(system)[0]
    balance = dict(method="sequence", **options) if options else True
    ctrl = SwingUpMPC(model, dt=DT, balance=balance)
    if not hasattr(ctrl.balancer, "cart_urgency"):
        raise SystemExit(f"plant {i} uses the pulse balancer; this benchmark analyses the "
                         f"sequence balancer (pass --balance '{{}}' options to force it).")
    rng = np.random.default_rng([seed, i, scen == "mismatch"])  # as bench_family.run_cell
    rows = []
    for k, x0 in enumerate(starts):
        f = 1.0 + 0.1 * rng.choice([-1.0, 1.0], size=3) if scen == "mismatch" else np.ones(3)
        plant = Plant(systems.cart_pendulum(mc=mc * f[0], mp=mp * f[1], L=L * f[2]), DT)
        row = episode(ctrl, plant, x0, far)
        row["start"], row["factors"] = k, f.tolist()
        if row["success"]:
            row["failure"] = None
        elif plant_kernel(mc * f[0], mp * f[1], L * f[2]).empty:
            row["failure"] = "unreachable"
        else:
            row["failure"] = cause(row, row["t_far_after_handover"] is not None)
        rows.append(row)
    failed = [r for r in rows if r["failure"] not in (None, "unreachable")]
    summary = {"plant": [mc, mp, L], "model": model_kind, "scenario": scen,
               "successes": sum(r["success"] for r in rows), "episodes": len(rows),
               "reachable": sum(r["failure"] != "unreachable" for r in rows),
               "causes": {c: sum(r["failure"] == c for r in rows)
                          for c in ("handover", "drift", "pole", "unreachable")},
               "median_handover_urgency_failed":
                   float(np.median([r.get("urgency", np.nan) for r in failed]))
                   if failed else None,
               "median_max_abs_x_failed":
                   float(np.median([r["max_abs_x"] for r in failed])) if failed else None}
    return summary, rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="output folder (cart_drift.json)")
    ap.add_argument("--quick", action="store_true", help="plant 2, 5 starts, nominal only")
    ap.add_argument("--plants", default="2,11", help="comma-separated indices into PLANTS")
    ap.add_argument("--starts", type=int, default=20, help="random starts (default 20)")
    ap.add_argument("--models", default="identified", help="identified, exact or both")
    ap.add_argument("--scenarios", default="nominal,mismatch")
    ap.add_argument("--balance", default="{}", help="JSON options of the sequence balancer")
    ap.add_argument("--far", type=float, default=1.2, help="cart distance (m) counted as drift")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    try:
        options = json.loads(args.balance)
    except json.JSONDecodeError as err:
        ap.error(f"--balance must be a JSON object: {err}")
    if not isinstance(options, dict):
        ap.error("--balance must be a JSON object")
    plants = [2] if args.quick else [int(i) for i in args.plants.split(",")]
    n = 5 if args.quick else args.starts
    scens = ["nominal"] if args.quick else args.scenarios.split(",")
    models = args.models.split(",")
    if n < 1 or not set(models) <= {"identified", "exact"} or not set(scens) <= {
            "nominal", "mismatch"} or not all(0 <= i < len(PLANTS) for i in plants):
        ap.error("bad --starts, --models, --scenarios or --plants")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    starts = random_starts(n, args.seed)
    report = {"starts": n, "seed": args.seed, "balance": options, "far": args.far,
              "cells": []}
    t0 = time.perf_counter()
    print("| plant | model | scenario | success | reachable | handover | drift | pole | "
          "median urgency at hand-over (failed) | median max abs x (failed) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for i in plants:
        for m in models:
            for scen in scens:
                summary, rows = run(i, m, scen, starts, options, args.far, args.seed)
                c = summary["causes"]
                fmt = (lambda v: "-" if v is None else f"{v:.2f}")
                print(f"| {'/'.join(str(v) for v in summary['plant'])} | {m} | {scen} | "
                      f"{summary['successes']}/{summary['episodes']} | {summary['reachable']} | "
                      f"{c['handover']} | {c['drift']} | {c['pole']} | "
                      f"{fmt(summary['median_handover_urgency_failed'])} | "
                      f"{fmt(summary['median_max_abs_x_failed'])} |", flush=True)
                report["cells"].append({**summary, "episodes_detail": rows})
                (out / "cart_drift.json").write_text(json.dumps(report, indent=1))
    report["seconds"] = time.perf_counter() - t0
    (out / "cart_drift.json").write_text(json.dumps(report, indent=1))
    print(f"\n{report['seconds']:.0f} s; wrote {out / 'cart_drift.json'}")


if __name__ == "__main__":
    main()
