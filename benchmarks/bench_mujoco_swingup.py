"""Swing-up closed on MuJoCo: identified from MuJoCo data only, controlled in MuJoCo.

For each cart-pendulum below, MuJoCo (an engine we did not write) is the plant throughout:

1. **identify** — three 2 s runs driven by a held multisine (a new value every 10 ms, as a digital
   controller's output), sampled at 100 Hz without accelerations, fed to ``LagrangianSINDy``
   (library: products of cos θ, sin θ, θ̇, x, ẋ up to degree 3; priors θ̇², cos θ; k = 4);
2. **control** — ``SwingUpMPC`` built from the identified model (forces {−10, 0, +10} N at 20 Hz)
   runs episodes of 10 s from random starts, the plant stepped by MuJoCo (RK4, 1 ms) under the held
   force; success as ``lsindy swingup`` (|θ − π| < 0.1 rad and |θ̇| < 0.5 rad/s over the last 3 s,
   |x| ≤ 2 m throughout).

The exact-model ceiling (the controller built from the plant's true equations) runs beside it,
and the plant's viability-kernel margin (``lsindy_cas.control.cart_pendulum.viability``; "empty": no
controller can hold the pole in the success band with these forces) is reported per plant.

    python benchmarks/bench_mujoco_swingup.py --out bench-results            # 10 starts per plant
    python benchmarks/bench_mujoco_swingup.py --out bench-results --starts 20
    python benchmarks/bench_mujoco_swingup.py --out bench-results --starts 2  # quick look
    python benchmarks/bench_mujoco_swingup.py --out bench-results --plants light --models exact

Needs the optional extra ``mujoco`` (``pip install -e '.[mujoco]'``).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

DT = 0.05
# (name, cart mass, pole mass, pole length); the kick of one 10 N push over 50 ms, F·dt/(mc·L)
PLANTS = [("paper", 1.0, 0.1, 1.0), ("light", 0.8, 0.2, 0.7), ("heavy-cart", 2.0, 0.3, 1.2)]


def identify(plant, seed=0):
    from lsindy_cas import LagrangianSINDy, Library
    rng = np.random.default_rng(seed)
    runs = []
    for _ in range(3):
        t = np.arange(200) * 0.01
        f, ph = rng.uniform(0.2, 2.0, 4), rng.uniform(0, 2 * np.pi, 4)
        u = 3.0 * sum(np.sin(2 * np.pi * fi * t + p) for fi, p in zip(f, ph)) / 2
        runs.append(plant.trajectory([0, rng.uniform(-1, 1), 0, 0], u, 0.01)[0])
    lib = Library.polynomial(["x", "theta"], ["cos(theta)", "sin(theta)", "theta_dot", "x", "x_dot"], 3)
    return LagrangianSINDy(lib, n_terms=4, prior=["theta_dot**2", "cos(theta)"]).fit(runs)


class _Exact:
    """The plant's true equations as a model (``ode()`` + ``coords_``) for the ceiling."""

    def __init__(self, system):
        self.system, self.coords_ = system, list(system.coords)
        self.actuated_ = [system.actuated]
        self.hamiltonian_ = system.hamiltonian  # the same controller as the identified model's
        self.lagrangian_ = system.lagrangian  # for adapt_model

    def ode(self):
        return self.system.ode()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True,
                    help="existing folder for mujoco_swingup.json and mujoco_swingup.md")
    ap.add_argument("--starts", type=int, default=10, help="random starts per plant (default 10)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--plants", default=",".join(p[0] for p in PLANTS),
                    help="comma-separated plant names (default: all of "
                         + ", ".join(p[0] for p in PLANTS) + ")")
    ap.add_argument("--models", default="identified,exact",
                    help="comma-separated among identified, exact (default both)")
    ap.add_argument("--adapt-model", action="store_true",
                    help="SwingUpMPC(adapt_model=True): the swing-up plan on an online estimate "
                         "of the model's coefficients")
    args = ap.parse_args(argv)
    names, models = args.plants.split(","), args.models.split(",")
    if not set(names) <= {p[0] for p in PLANTS}:
        ap.error(f"--plants must be among {', '.join(p[0] for p in PLANTS)}, got {args.plants}")
    if not models or not set(models) <= {"identified", "exact"}:
        ap.error(f"--models must be among identified, exact, got {args.models}")
    out = Path(args.out)
    if not out.is_dir():
        ap.error(f"--out {out}: no such folder")
    if args.starts < 1:
        ap.error("--starts must be a positive integer")

    from lsindy_cas.control.cart_pendulum.viability import pole_kernel
    from lsindy_cas.mpc import SwingUpMPC
    from lsindy_cas.paper import systems
    from lsindy_cas.paper.swingup import random_starts, run_episode
    from lsindy_cas.plants import mujoco as pm

    starts = random_starts(args.starts, args.seed)
    t_start = time.perf_counter()
    rows = []
    for name, mc, mp, L in (p for p in PLANTS if p[0] in names):
        plant = pm.cart_pendulum(mc, mp, L)
        t0 = time.perf_counter()
        model = identify(plant, args.seed)
        t_id = time.perf_counter() - t0
        truth = systems.cart_pendulum(mc=mc, mp=mp, L=L)
        true_terms = {"x_dot**2": (mc + mp) / 2, "theta_dot**2": mp * L ** 2 / 2,
                      "theta_dot*x_dot*cos(theta)": mp * L, "cos(theta)": -mp * 9.81 * L}
        got = model.terms()
        coef_err = (max(abs(got.get(k, 0.0) / v - 1) for k, v in true_terms.items())
                    if set(got) == set(true_terms) else float("inf"))
        # the certificate: an empty viability kernel of the plant's own upright linearisation
        # means no controller can hold its pole in the success band (control/cart_pendulum/viability.py)
        kernel = pole_kernel(truth.ode(), 0, 1, np.pi, DT, (-10.0, 0.0, 10.0))
        row = {"plant": name, "mc": mc, "mp": mp, "L": L, "kick_rad_s": 10 * DT / (mc * L),
               "kernel_margin": kernel.max_margin, "proven_unreachable": kernel.empty,
               "identify_s": round(t_id, 2), "support_exact": set(got) == set(true_terms),
               "max_coef_rel_err": coef_err}
        for label, m in (("identified", model), ("exact", _Exact(truth))):
            if label not in models:
                continue
            ctrl = SwingUpMPC(m, force_set=(-10.0, 0.0, 10.0), dt=DT, horizon=40, track_limit=2.0,
                              adapt_model=args.adapt_model or None)
            eps = []
            for i, x0 in enumerate(starts):
                ep = run_episode(ctrl, pm.ClosedLoop(plant, DT), x0)
                eps.append(ep)
                print(f"{name:>10} {label:>10} start {i}: success={ep.success} "
                      f"t_up={ep.time_to_upright:.2f}", file=sys.stderr)
            t_up = [e.time_to_upright for e in eps if np.isfinite(e.time_to_upright)]
            solve = np.concatenate([np.asarray(e.solve_times) for e in eps]) * 1e3
            row[label] = {"success": sum(e.success for e in eps), "episodes": len(eps),
                          "median_time_to_upright": float(np.median(t_up)) if t_up else None,
                          "max_track_used": float(max(e.track_used for e in eps)),
                          "forces_in_set": bool(all(set(np.unique(e.forces)) <= {-10.0, 0.0, 10.0}
                                                    for e in eps)),
                          "failed_starts": [j for j, e in enumerate(eps) if not e.success],
                          "solve_ms_median": float(np.median(solve)),
                          "solve_ms_p99": float(np.percentile(solve, 99))}
        rows.append(row)

    lines = ["| plant | mc, mp, L | kick (rad/s) | kernel margin | support exact | max coef err |"
             " identified: success | t_up median (s) | max abs x (m) | failed starts |"
             " exact model: success | failed starts | solve p99 (ms) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    empty = {"success": "-", "episodes": "-", "median_time_to_upright": None,
             "max_track_used": float("nan"), "failed_starts": [], "solve_ms_p99": float("nan")}
    for r in rows:
        i, e = r.get("identified", empty), r.get("exact", empty)
        t_up = "-" if i["median_time_to_upright"] is None else f"{i['median_time_to_upright']:.2f}"
        lines.append(
            f"| {r['plant']} | {r['mc']}, {r['mp']}, {r['L']} | {r['kick_rad_s']:.2f} | "
            f"{r['kernel_margin']:.3f}{' (empty)' if r['proven_unreachable'] else ''} | "
            f"{r['support_exact']} | {r['max_coef_rel_err']:.1e} | {i['success']}/{i['episodes']} | "
            f"{t_up} | {i['max_track_used']:.2f} | {i['failed_starts'] or '-'} | "
            f"{e['success']}/{e['episodes']} | {e['failed_starts'] or '-'} | {i['solve_ms_p99']:.1f} |")
    print("\n" + "\n".join(lines))
    path = out / "mujoco_swingup.json"
    path.write_text(json.dumps({"starts": args.starts, "seed": args.seed,
                                "adapt_model": args.adapt_model,
                                "seconds": round(time.perf_counter() - t_start, 1),
                                "plants": rows}, indent=2))
    (out / "mujoco_swingup.md").write_text(
        f"MuJoCo swing-up, {args.starts} random starts per plant (seed {args.seed}); identified from "
        "MuJoCo data only, controlled in MuJoCo; `python benchmarks/bench_mujoco_swingup.py "
        f"--out DIR --starts {args.starts}{' --adapt-model' if args.adapt_model else ''}`\n\n"
        + "\n".join(lines) + "\n")
    print(f"\nwritten: {path} and mujoco_swingup.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
