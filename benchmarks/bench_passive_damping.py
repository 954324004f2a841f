"""Free swings with joint damping: energy and friction from passive data, MuJoCo as the judge.

The plants (:mod:`lsindy_cas.plants.mujoco_chain`): double pendulum (links 1.0 / 0.6 kg, 0.5 /
0.4 m) and triple pendulum (+ 0.4 kg, 0.3 m), capsule links of radius 3 cm on hinges, relative
angles, viscous joint damping 0.02 / 0.01 / 0.005 N·m·s.  Per seed: runs released from rest at
angles uniform in ±2 rad (double: 3 runs of 3 s, 2 s with the full library; triple: 5 runs of
4 s — with 3 of 3 s one seed in three missed 1 % on a small coupling term, 1.5 %), RK4 at 1 ms,
sampled at 1 kHz, angles read by a 12-bit encoder (2π/4096 rad per count), rates with white
noise 1e-3 rad/s.

Identified passively (no input, no scale trial: relative energy) with the dissipation candidates
θ̇_i θ̇_j (all i ≤ j: 3 for the double, 6 for the triple), the priors θ̇1², θ̇2², cos θ1 and the
number of terms given (8 / 26).  Libraries:

* ``double``: the 8 energy terms and 12 distractors (sin θ1, cos θ2, …, cos²θ2 and sin²θ2, whose
  sum is an identity);
* ``double-full``: every product of degree ≤ 3 of cos/sin of the angles and the rates (83 terms),
  the reported case (branch and bound; minutes per fit);
* ``triple``: the 26 energy terms (degree ≤ 4) and 5 distractors.

Columns: support exact (energy and dissipation), largest relative error of the energy
coefficients, of the damping coefficients (b_i/2), the status, the number of "conserved"
quantities the diagnostics report, the identified H against MuJoCo's ``mjData.energy`` (largest
deviation after removing the mean, over its range) and the seconds of the fit.  The truth is
:func:`~lsindy_cas.plants.mujoco_chain.energy_terms` (from the compiled model; the tests derive it
by hand too).  ``--auto-k``: also double seed 0 with the number of terms chosen automatically
(the 20-term library, and the 83-term one unless ``--no-full``: with the three damping
candidates and, ``double-full-diag``, with θ̇1² and θ̇2² only).

    python benchmarks/bench_passive_damping.py [OUT] [--quick] [--seeds N] [--no-full] [--auto-k]

Writes ``passive_damping.json`` and ``passive_damping.md`` to OUT (default
benchmarks/results/passive_damping/).
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import json
import time
from pathlib import Path

import numpy as np

from lsindy_cas import LagrangianSINDy, Library

DOUBLE = dict(masses=(1.0, 0.6), lengths=(0.5, 0.4), radii=(0.03, 0.03), damping=(0.02, 0.01))
TRIPLE = dict(masses=(1.0, 0.6, 0.4), lengths=(0.5, 0.4, 0.3), radii=(0.03, 0.03, 0.03),
              damping=(0.02, 0.01, 0.005))
DOUBLE_EXTRA = ["sin(theta1)", "cos(theta2)", "sin(theta2)", "theta1_dot**2*cos(theta1)",
                "theta2_dot**2*cos(theta2)", "theta1_dot*theta2_dot*sin(theta2)",
                "theta1_dot**2*sin(theta2)", "theta2_dot**2*cos(theta1)", "cos(theta1)*sin(theta2)",
                "cos(theta2)**2", "sin(theta2)**2", "theta1_dot*theta2_dot*cos(theta1)"]
TRIPLE_EXTRA = ["sin(theta1)", "cos(theta2)", "cos(theta3)", "theta3_dot**2*cos(theta3)",
                "theta1_dot**2*cos(theta1)"]
PRIOR = ["theta1_dot**2", "theta2_dot**2", "cos(theta1)"]
# (plant, distractors or None for the full library, runs, seconds per run)
CASES = {"double": (DOUBLE, DOUBLE_EXTRA, 3, 3.0), "double-full": (DOUBLE, None, 3, 2.0),
         "triple": (TRIPLE, TRIPLE_EXTRA, 5, 4.0)}


def dissipation_terms(n, diagonal=False):
    return [f"theta{i + 1}_dot**2" if i == j else f"theta{i + 1}_dot*theta{j + 1}_dot"
            for i in range(n) for j in range(i, n) if i == j or not diagonal]


def energy_of(terms, coords, X):
    import sympy as sp
    names = list(coords) + [c + "_dot" for c in coords]
    expr = sum(v * sp.sympify(k) for k, v in terms.items())
    return np.asarray(sp.lambdify([sp.Symbol(s) for s in names], expr, "numpy")(*X.T), float)


def run_case(case, seed, auto_k=False):
    from lsindy_cas.plants import mujoco_chain as chain
    diagonal = case.endswith("-diag")          # damping candidates θ̇_i² only (no cross terms)
    params, extra, n_runs, seconds = CASES[case.removesuffix("-diag")]
    plant = chain.pendulum_chain(**params)
    truth = chain.energy_terms(plant)
    runs = chain.free_swings(plant, np.random.default_rng(seed), n_runs=n_runs, seconds=seconds)
    if extra is None:
        feats = [f"{f}({c})" for c in plant.coords for f in ("cos", "sin")] + \
            [c + "_dot" for c in plant.coords]
        lib = Library.polynomial(plant.coords, feats, 3)
    else:
        lib = Library(plant.coords, list(truth) + extra)
    row = {"case": case + (" auto-k" if auto_k else ""), "seed": seed, "library": len(lib),
           "true_terms": len(truth)}
    started = time.perf_counter()
    try:
        model = LagrangianSINDy(lib, n_terms=None if auto_k else len(truth), prior=PRIOR,
                                dissipation=dissipation_terms(len(plant.coords), diagonal)).fit(
            [tr for tr, _, _ in runs], passive=True)
    except ValueError as exc:
        return {**row, "status": f"refused: {exc}", "seconds": time.perf_counter() - started}
    row["seconds"] = time.perf_counter() - started
    scale = truth.get(model.normalised_by_, np.nan)
    H, R = model.terms(), model.terms("rayleigh")
    d = model.diagnostics_
    dev = []
    for _, E, X in runs:                       # on MuJoCo's own states, not the readings
        Hm = energy_of(H, plant.coords, X) * scale
        dev.append(float(np.max(np.abs((Hm - Hm.mean()) - (E - E.mean()))) / np.ptp(E)))
    return {**row, "k": model.n_terms_, "status": model.status_,
            "reasons": [str(r) for r in model.status_reasons_],
            "support_exact": set(H) == set(truth) and set(R) == set(plant.rayleigh),
            "energy_coef_err": max(abs(H.get(k, 0.0) * scale / v - 1) for k, v in truth.items()),
            "worst_term": max(truth, key=lambda k: abs(H.get(k, 0.0) * scale / truth[k] - 1)),
            "damping_err": max(abs(R.get(k, 0.0) * scale / v - 1) for k, v in plant.rayleigh.items()),
            "conserved": len(d.conserved), "held_out_error": d.held_out_error,
            "k_path": [[k, e] for k, e, _ in d.k_path], "H_vs_mujoco": max(dev)}


def markdown(rows):
    out = ["| case | seed | library | k | support exact | energy coef err | damping err | status | "
           "conserved | held-out err | H vs MuJoCo | seconds |", "|" + "---|" * 12]
    for r in rows:
        out.append(f"| {r['case']} | {r['seed']} | {r['library']} | {r.get('k', '-')} | "
                   f"{'yes' if r.get('support_exact') else 'no'} | "
                   f"{r.get('energy_coef_err', np.nan):.2%} | {r.get('damping_err', np.nan):.2%} | "
                   f"{r['status'].split(':')[0]} | {r.get('conserved', '-')} | "
                   f"{r.get('held_out_error', np.nan):.1e} | {r.get('H_vs_mujoco', np.nan):.1e} | "
                   f"{r['seconds']:.0f} |")
    return "\n".join(out)


def main(argv=None):
    from _cli import out_folder
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default="benchmarks/results/passive_damping",
                        help="output folder (default: %(default)s)")
    parser.add_argument("--seeds", type=int, default=3, help="seeds per case (default 3)")
    parser.add_argument("--quick", action="store_true", help="one seed, no full library")
    parser.add_argument("--no-full", action="store_true", help="skip the 83-term library (minutes)")
    parser.add_argument("--auto-k", action="store_true",
                        help="also the double, seed 0, with the number of terms chosen automatically "
                        "(both libraries unless --no-full)")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be >= 1, got {args.seeds}")
    out = out_folder(parser, args.out)
    seeds = range(1 if args.quick else args.seeds)
    jobs = [("double", s, False) for s in seeds] + [("triple", s, False) for s in seeds]
    if not (args.quick or args.no_full):
        jobs.append(("double-full", 0, False))
    if args.auto_k:
        jobs.append(("double", 0, True))
        if not (args.quick or args.no_full):
            jobs += [("double-full", 0, True), ("double-full-diag", 0, True)]
    started = time.perf_counter()
    rows = []
    for case, seed, auto in jobs:
        rows.append(run_case(case, seed, auto))
        r = rows[-1]
        print(f"{r['case']} seed {seed}: {r['status']} ({r['seconds']:.0f} s)", flush=True)
    table = markdown(rows)
    print(table)
    total = time.perf_counter() - started
    print(f"total {total:.0f} s")
    settings = {"rate_hz": 1000, "encoder_rad_per_count": 2 * np.pi / 4096, "rate_noise": 1e-3,
                "runs_seconds": {k: v[2:] for k, v in CASES.items()}, "max_angle": 2.0, "double": DOUBLE, "triple": TRIPLE, "prior": PRIOR}
    (out / "passive_damping.json").write_text(json.dumps(
        {"rows": rows, "settings": settings, "seconds": total}, indent=2, default=str) + "\n")
    (out / "passive_damping.md").write_text(
        "Free swings with joint damping, MuJoCo judge (benchmarks/bench_passive_damping.py): 1 kHz, "
        "12-bit encoder, rate noise 1e-3 rad/s, 3 runs per seed.\n\n" + table + "\n")


if __name__ == "__main__":
    main()
