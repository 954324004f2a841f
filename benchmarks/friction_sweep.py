"""Friction: identification with Rayleigh dissipation on noisy data, rich protocol.

Systems (true friction in ``CASES``): the cart-pendulum with viscous cart and pivot friction and
Coulomb cart friction, and the double pendulum with viscous damping at the first joint and
between the links, k(θ̇₂ − θ̇₁)².  Data: the noise sweep's rich protocol (random initial states,
input held at random levels, 10 runs × 5 s at 100 Hz; ``benchmarks/noise_sweep.py``), positions
and velocities with Gaussian noise σ, no accelerations (integral form, smoothing, errors in
variables).  The candidate dissipation terms are every quadratic form in the velocities plus |q̇ᵢ|.
A seed succeeds when the energy support and the dissipation support are exact and every energy
and dissipation coefficient is within 5 % (target: ≥ 9 of 10 seeds at σ = 1e-2).

    python benchmarks/friction_sweep.py --out benchmarks/results [--jobs 2]   # 10 seeds, both
    python benchmarks/friction_sweep.py --out /tmp/fr --quick                  # 2 seeds, short runs

Prints a table and writes ``friction_sweep.json`` and ``friction_sweep.md`` to DIR.
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import dataclasses
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from lsindy_cas import LagrangianSINDy, systems
from lsindy_cas.data.smoothing import add_noise
from lsindy_cas.paper.table1 import PAPER_SETUPS, compare
from lsindy_cas.symbolic.library import Library

sys.path.insert(0, str(Path(__file__).resolve().parent))
from noise_sweep import rich_runs  # noqa: E402

CASES = {
    "cart": ("0.15*x_dot**2 + 0.005*theta_dot**2 + 0.2*Abs(x_dot)",
             ["x_dot**2", "x_dot*theta_dot", "theta_dot**2", "Abs(x_dot)", "Abs(theta_dot)"]),
    "double": ("0.05*theta1_dot**2 + 0.04*(theta2_dot - theta1_dot)**2",
               ["theta1_dot**2", "theta1_dot*theta2_dot", "theta2_dot**2", "Abs(theta1_dot)",
                "Abs(theta2_dot)"]),
}
TOL = 0.05


def run_one(name: str, sigma: float, seed: int, n_runs: int, t_end: float) -> dict:
    rayleigh, candidates = CASES[name]
    factory = systems.PAPER_SYSTEMS[name]
    system = dataclasses.replace(factory(), rayleigh=rayleigh, coulomb_eps=1e-4)
    setup = PAPER_SETUPS[name]
    lib = Library.polynomial(system.coords, setup.features, setup.degree)
    rlib = Library(system.coords, candidates)
    truth, r_truth = lib.coefficients(system.hamiltonian), rlib.coefficients(rayleigh)
    rng = np.random.default_rng(1000 + seed)
    clean = rich_runs(name, system, rng, n_runs=n_runs, t_end=t_end)
    noisy = [dataclasses.replace(add_noise(tr, sigma, np.random.default_rng([seed, 7])), qdd=None)
             for tr in clean]
    t0 = time.perf_counter()
    row = {"system": name, "sigma": sigma, "seed": seed, "runs": n_runs, "t_end": t_end}
    try:
        model = LagrangianSINDy(lib, prior=setup.prior, dissipation=rlib).fit(noisy)
    except ValueError as exc:
        row.update(exact_energy=False, exact_dissipation=False, err_energy=float("inf"),
                   err_dissipation=float("inf"), success=False, error=str(exc)[:200])
    else:
        exact_e, err_e = compare(model.coef_, truth)
        rho = model.rayleigh_coef_
        exact_r = bool(np.array_equal(rho != 0, r_truth != 0))
        nz = r_truth != 0
        err_r = float(np.max(np.abs(rho[nz] - r_truth[nz]) / np.abs(r_truth[nz])))
        row.update(exact_energy=bool(exact_e), exact_dissipation=exact_r, err_energy=float(err_e),
                   err_dissipation=err_r, rayleigh=model.terms("rayleigh"),
                   success=bool(exact_e and exact_r and err_e <= TOL and err_r <= TOL))
    row["seconds"] = time.perf_counter() - t0
    return row


def _run_job(job):
    return run_one(*job)


def markdown(rows, names, seeds, sigma, n_runs, t_end) -> str:
    """The summary table: per system, seeds with exact supports and every coefficient within TOL."""
    lines = [f"Friction, rich protocol ({n_runs} runs × {t_end:g} s), σ = {sigma:g}: seeds with the "
             f"exact energy and dissipation supports and every coefficient within {TOL:.0%}", "",
             "| system | true R | seeds ok | worst err E (ok seeds) | worst err R (ok seeds) | "
             "failures |", "|---|---|---|---|---|---|"]
    for name in names:
        rs = [r for r in rows if r["system"] == name]
        ok = [r for r in rs if r["success"]]
        bad = "; ".join(f"seed {r['seed']}: " + (r.get("error") or ", ".join(
            f"{k} {v:.2g}" for k, v in r.get("rayleigh", {}).items())) for r in rs
            if not r["success"]) or "-"
        worst_e = max((r["err_energy"] for r in ok), default=float("nan"))
        worst_r = max((r["err_dissipation"] for r in ok), default=float("nan"))
        lines.append(f"| {name} | {CASES[name][0]} | {len(ok)}/{len(rs)} | {worst_e:.2g} | "
                     f"{worst_r:.2g} | {bad} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True, help="output folder (created)")
    ap.add_argument("--quick", action="store_true", help="4 runs × 3 s, 2 seeds (smoke test)")
    ap.add_argument("--seeds", type=int, default=None)
    ap.add_argument("--sigma", type=float, default=1e-2)
    ap.add_argument("--systems", default="cart,double")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    args = ap.parse_args(argv)
    names = [s for s in args.systems.split(",") if s]
    bad = [s for s in names if s not in CASES]
    if bad or not names:
        ap.error(f"--systems must be from {sorted(CASES)}, got {args.systems!r}")
    seeds = args.seeds if args.seeds is not None else (2 if args.quick else 10)
    if seeds < 1 or not args.sigma >= 0:
        ap.error("--seeds must be >= 1 and --sigma >= 0")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    n_runs, t_end = (4, 3.0) if args.quick else (10, 5.0)
    jobs = [(name, args.sigma, seed, n_runs, t_end) for name in names for seed in range(seeds)]
    t0 = time.perf_counter()
    print(f"{'system':8} {'seed':>4} {'E exact':>8} {'R exact':>8} {'err E':>9} {'err R':>9} "
          f"{'ok':>3} {'s':>6}")
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        rows = list(pool.map(_run_job, jobs))
    for r in rows:
        print(f"{r['system']:8} {r['seed']:4d} {str(r['exact_energy']):>8} "
              f"{str(r['exact_dissipation']):>8} {r['err_energy']:9.2e} {r['err_dissipation']:9.2e} "
              f"{'yes' if r['success'] else 'no':>3} {r['seconds']:6.1f}", flush=True)
    md = markdown(rows, names, seeds, args.sigma, n_runs, t_end)
    print(md)
    (out / "friction_sweep.json").write_text(json.dumps(
        {"sigma": args.sigma, "runs": n_runs, "t_end": t_end, "tol": TOL, "rows": rows}, indent=2))
    (out / "friction_sweep.md").write_text(md + "\n")
    print(f"written to {out / 'friction_sweep'}.{{md,json}} in {time.perf_counter() - t0:.0f} s",
          file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
