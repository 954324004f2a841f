"""The swing-up with and without the online estimate of the model's coefficients (``adapt_model``).

For each chosen plant of ``bench_family.PLANTS`` (identified from its own simulated run, as in
the family benchmark, or its exact equations), two controllers on the same model --
``SwingUpMPC(model, adapt_model=False)`` and ``adapt_model=True`` -- run the same episodes,
interleaved start by start so that the machine's load affects both alike:

* ``mismatch``: the family benchmark's +-10 % plants (same seeds: the episodes are the family's);
* ``noise``: the nominal plant, every measured state with N(0, ``--noise``^2) added (the same
  noise sequence for both controllers);
* ``nominal``: the nominal plant, exact measurements.

Reports successes (all, and where the simulated plant's pole can be held in the band at all:
``reachable``, as in the family benchmark), the starts one controller holds and the other loses,
the median relative error of the estimated coefficients at the episode's end against the
simulated plant's own (its Lagrangian's, hand-derived), and the step times.  Prints a markdown
table and writes ``adapt_model.json``, ``.md`` and ``.png`` to ``--out``.

    python benchmarks/bench_adapt_model.py --out DIR                          # plants 4, 11
    python benchmarks/bench_adapt_model.py --out DIR --plants 1 --scenarios noise --starts 20
    python benchmarks/bench_adapt_model.py --out DIR --quick                  # 1 plant, 3 starts
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
from bench_family import DT, PLANTS, physical, plant_kernel  # noqa: E402

from lsindy_cas import systems  # noqa: E402
from lsindy_cas.control.coefficients import parametric_form  # noqa: E402
from lsindy_cas.mpc import SwingUpMPC  # noqa: E402
from lsindy_cas.paper.swingup import (Plant, identify_cart_pendulum, random_starts,  # noqa: E402
                                      run_episode)

SCENARIOS = ("nominal", "mismatch", "noise")


def run_cell(i, scenario, n_starts, seed, noise, model_kind):
    """Both controllers on plant ``i`` and one scenario; a JSON-ready summary."""
    mc, mp, L = PLANTS[i]
    system = systems.cart_pendulum(mc=mc, mp=mp, L=L)
    model = identify_cart_pendulum(system)[0] if model_kind == "identified" else system
    ctrls = {"off": SwingUpMPC(model, dt=DT, adapt_model=False),
             "on": SwingUpMPC(model, dt=DT, adapt_model=True)}
    names = parametric_form(model, ["x", "theta"])[2]
    starts = random_starts(n_starts, seed)
    rng = np.random.default_rng([seed, i, scenario == "mismatch"])  # as bench_family.run_cell
    rows = []
    for k, x0 in enumerate(starts):
        f = 1.0 + 0.1 * rng.choice([-1.0, 1.0], size=3) if scenario == "mismatch" else np.ones(3)
        pm = (mc * f[0], mp * f[1], L * f[2])
        true = systems.cart_pendulum(mc=pm[0], mp=pm[1], L=pm[2])
        expected = np.array([physical(*pm)[n] for n in names])
        row = {"start": k, "factors": f.tolist(), "reachable": not plant_kernel(*pm).empty}
        for name, ctrl in ctrls.items():
            ep = run_episode(ctrl, Plant(true, DT), x0,
                             noise_std=noise if scenario == "noise" else 0.0,
                             rng=np.random.default_rng([seed, i, k]))
            row[name] = bool(ep.success)
            row[f"t_up_{name}"] = float(ep.time_to_upright)
            if ctrl.estimator is not None:
                row["coef_error"] = float(np.median(np.abs(ctrl.estimator.coef / expected - 1)))
                row["prior_error"] = float(np.median(np.abs(ctrl.estimator.p0 / expected - 1)))
        rows.append(row)
        print(f"plant {i} {scenario} start {k}: off {'ok' if row['off'] else 'FAILED'}, "
              f"on {'ok' if row['on'] else 'FAILED'}", flush=True)
    cell = {"plant": [mc, mp, L], "index": i, "scenario": scenario, "episodes": rows}
    for name, ctrl in ctrls.items():
        st = ctrl.stats.summary()
        cell[name] = {"successes": sum(r[name] for r in rows),
                      "reachable_successes": sum(r[name] and r["reachable"] for r in rows),
                      "step_ms_median": st["step_ms_median"], "step_ms_p99": st["step_ms_p99"]}
    cell["reachable"] = sum(r["reachable"] for r in rows)
    cell["gained"] = [r["start"] for r in rows if r["on"] and not r["off"]]
    cell["lost"] = [r["start"] for r in rows if r["off"] and not r["on"]]
    cell["coef_error_median"] = float(np.median([r["coef_error"] for r in rows]))
    cell["prior_error_median"] = float(np.median([r["prior_error"] for r in rows]))
    return cell


def figure(cells, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(1.6 + 1.2 * len(cells), 3.6))
    x = np.arange(len(cells))
    for off, (name, color) in enumerate((("off", "0.6"), ("on", "tab:blue"))):
        share = [c[name]["reachable_successes"] / max(c["reachable"], 1) for c in cells]
        ax.bar(x + (off - 0.5) * 0.38, share, 0.38, color=color,
               label=f"adapt_model={name == 'on'}")
    ax.axhline(0.95, color="k", lw=0.8, ls="--")
    ax.set_xticks(x, ["/".join(f"{v:g}" for v in c["plant"]) + "\n" + c["scenario"]
                      for c in cells], fontsize=8)
    ax.set_ylim(0.5, 1.02)
    ax.set_ylabel("success (reachable episodes)")
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="output folder (adapt_model.json, .md, .png)")
    ap.add_argument("--plants", default="4,11", help="indices into bench_family.PLANTS")
    ap.add_argument("--scenarios", default="mismatch,noise",
                    help=f"comma-separated among {', '.join(SCENARIOS)}")
    ap.add_argument("--starts", type=int, default=60)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--noise", type=float, default=0.01, help="measurement noise std (noise)")
    ap.add_argument("--models", default="identified", choices=("identified", "exact"))
    ap.add_argument("--workers", type=int, default=1, help="cells run in parallel processes")
    ap.add_argument("--quick", action="store_true", help="plant 4, mismatch, 3 starts")
    args = ap.parse_args(argv)
    try:
        plants = [int(v) for v in args.plants.split(",")]
        if not all(0 <= p < len(PLANTS) for p in plants):
            raise ValueError
    except ValueError:
        ap.error(f"--plants must be indices in 0..{len(PLANTS) - 1}, got {args.plants!r}")
    scenarios = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    if not scenarios or set(scenarios) - set(SCENARIOS):
        ap.error(f"--scenarios must be among {', '.join(SCENARIOS)}, got {args.scenarios!r}")
    if args.starts < 1 or args.workers < 1:
        ap.error("--starts and --workers must be at least 1")
    if not args.noise >= 0:
        ap.error(f"--noise must be >= 0, got {args.noise}")
    if args.quick:
        plants, scenarios, args.starts = [4], ["mismatch"], 3
    out = out_folder(ap, args.out)
    t0 = time.perf_counter()
    jobs = [(i, s, args.starts, args.seed, args.noise, args.models)
            for i in plants for s in scenarios]
    if args.workers > 1:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(args.workers) as pool:
            cells = list(pool.map(run_cell, *zip(*jobs)))
    else:
        cells = [run_cell(*job) for job in jobs]
    seconds = time.perf_counter() - t0
    lines = [f"`python benchmarks/bench_adapt_model.py --out DIR --plants "
             f"{','.join(map(str, plants))} --scenarios {','.join(scenarios)} "
             f"--starts {args.starts} --models {args.models}`"
             f" ({seconds:.0f} s, {args.workers} worker(s)); noise std {args.noise:g}.", "",
             "| plant mc/mp/L | scenario | adapt_model off | on | reachable: off | on | gained | "
             "lost | coefficient error: prior -> end (median) | step p99 off / on (ms) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for c in cells:
        n = len(c["episodes"])
        lines.append(
            f"| {'/'.join(f'{v:g}' for v in c['plant'])} | {c['scenario']} | "
            f"{c['off']['successes']}/{n} | {c['on']['successes']}/{n} | "
            f"{c['off']['reachable_successes']}/{c['reachable']} | "
            f"{c['on']['reachable_successes']}/{c['reachable']} | {c['gained'] or '-'} | "
            f"{c['lost'] or '-'} | {100 * c['prior_error_median']:.1f} % -> "
            f"{100 * c['coef_error_median']:.2f} % | {c['off']['step_ms_p99']:.1f} / "
            f"{c['on']['step_ms_p99']:.1f} |")
    print("\n".join(lines))
    (out / "adapt_model.md").write_text("\n".join(lines) + "\n")
    (out / "adapt_model.json").write_text(json.dumps(
        {"plants": plants, "scenarios": scenarios, "starts": args.starts, "seed": args.seed,
         "noise": args.noise, "models": args.models, "seconds": seconds, "cells": cells},
        indent=1))
    figure(cells, out / "adapt_model.png")
    print(f"written: {out / 'adapt_model.md'}, adapt_model.json, adapt_model.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
