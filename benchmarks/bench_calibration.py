"""Calibration of the coefficient standard errors: do the ±1σ intervals contain the truth ~68 %?

For each benchmark system (spherical, double, cart-pendulum; libraries and prior terms of
``table1.PAPER_SETUPS``) and ``--seeds`` seeds, rich-protocol data (10 runs × 5 s, random initial
states, random held inputs: ``noise_sweep.rich_runs``) get Gaussian noise of σ on every q and q̇
column and are identified with the defaults (k chosen from the data).  For every coefficient of
the true energy H and Lagrangian L, the fit counts as covered at z when
|ξ̂ − ξ| ≤ z · se(ξ̂).  An honest standard error covers ≈ 68 % at z = 1 (≈ 66 % for a jackknife
over 10 runs, whose error has 9 degrees of freedom), ≈ 95 % at z = 2 and ≈ 99.7 % at z = 3.
Fits with a wrong support are counted apart (their coefficients are not comparable).

Usage::

    python benchmarks/bench_calibration.py --out results/           # 10 seeds, ~3 min on 2 cores
    python benchmarks/bench_calibration.py --out /tmp/c --seeds 2 --systems cart   # quick
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from noise_sweep import clean_data  # noqa: E402

from lsindy_cas import LagrangianSINDy  # noqa: E402
from lsindy_cas.data.smoothing import add_noise  # noqa: E402
from lsindy_cas.paper.table1 import PAPER_SETUPS  # noqa: E402
from lsindy_cas.symbolic.library import Library  # noqa: E402

SYSTEMS = ("spherical", "double", "cart")
Z = (1.0, 2.0, 3.0)
TARGET = (0.60, 0.75)          # coverage of ±1σ aimed for (68 % ideal)


def run_one(job):
    """One (system, seed): the fitted coefficients, their standard errors and the truth."""
    name, seed, sigma = job
    setup = PAPER_SETUPS[name]
    system, clean = clean_data(name, "rich", seed)
    lib = Library.polynomial(system.coords, setup.features, setup.degree)
    rng = np.random.default_rng([seed, int(round(-np.log10(sigma) * 10)) if sigma > 0 else 999])
    noisy = [add_noise(tr, sigma, rng) for tr in clean]
    t0 = time.perf_counter()
    model = LagrangianSINDy(lib, prior=setup.prior).fit(noisy)
    out = {"system": name, "seed": seed, "sigma": sigma, "seconds": time.perf_counter() - t0,
           "method": model.std_method_, "pairs": []}
    for part, truth, coef, std in (
            ("H", lib.coefficients(system.hamiltonian), model.coef_, model.coef_std_),
            ("L", lib.coefficients(system.lagrangian), model.lagrangian_coef_,
             model.lagrangian_coef_std_)):
        out["exact_" + part] = bool(np.array_equal(coef != 0, truth != 0))
        for j in np.flatnonzero(truth):
            out["pairs"].append({"part": part, "term": lib.names[j], "true": float(truth[j]),
                                 "coef": float(coef[j]), "std": float(std[j])})
    return out


def summarise(rows):
    """Per system and part: coverage at each z over exactly-identified fits."""
    table = {}
    for r in rows:
        for part in ("H", "L"):
            key = (r["system"], part)
            t = table.setdefault(key, {"n_fits": 0, "n_exact": 0, "n_pairs": 0,
                                       **{f"z{z:g}": 0 for z in Z}, "z_scores": []})
            t["n_fits"] += 1
            if not r["exact_" + part]:
                continue
            t["n_exact"] += 1
            for p in r["pairs"]:
                if p["part"] != part:
                    continue
                z = abs(p["coef"] - p["true"]) / p["std"] if p["std"] > 0 else np.inf
                t["n_pairs"] += 1
                t["z_scores"].append(float(z))
                for zz in Z:
                    t[f"z{zz:g}"] += bool(z <= zz)
    for t in table.values():
        n = max(t["n_pairs"], 1)
        for zz in Z:
            t[f"coverage_z{zz:g}"] = t[f"z{zz:g}"] / n
        t["median_abs_z"] = float(np.median(t["z_scores"])) if t["z_scores"] else float("nan")
        del t["z_scores"]
    return table


def markdown(table, sigma) -> str:
    lines = [f"Coverage of ±zσ intervals, rich protocol, σ = {sigma:g} (target at z = 1: "
             f"{TARGET[0]:.0%}–{TARGET[1]:.0%}; 68 % ideal, 95 % at z = 2, 99.7 % at z = 3).", "",
             "| system | part | exact fits | pairs | z = 1 | z = 2 | z = 3 | median abs z |",
             "|---|---|---|---|---|---|---|---|"]
    for (name, part), t in table.items():
        lines.append(f"| {name} | {part} | {t['n_exact']}/{t['n_fits']} | {t['n_pairs']} | "
                     f"{t['coverage_z1']:.0%} | {t['coverage_z2']:.0%} | {t['coverage_z3']:.0%} | "
                     f"{t['median_abs_z']:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", required=True, help="output directory (created if missing)")
    p.add_argument("--seeds", type=int, default=10, help="seeds per system (default 10)")
    p.add_argument("--sigma", type=float, default=1e-2, help="noise level (default 1e-2)")
    p.add_argument("--systems", default=",".join(SYSTEMS), help="comma-separated subset")
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    args = p.parse_args(argv)
    names = [s for s in args.systems.split(",") if s]
    bad = [s for s in names if s not in SYSTEMS]
    if bad or args.seeds < 1 or args.jobs < 1 or not args.sigma > 0:
        p.error(f"--systems from {SYSTEMS}, --seeds/--jobs ≥ 1, --sigma > 0 (bad: {bad})")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(name, seed, args.sigma) for name in names for seed in range(args.seeds)]
    t0 = time.perf_counter()
    if args.jobs == 1:
        rows = [run_one(j) for j in jobs]
    else:
        with ProcessPoolExecutor(args.jobs) as ex:
            rows = list(ex.map(run_one, jobs))
    table = summarise(rows)
    text = markdown(table, args.sigma)
    seconds = time.perf_counter() - t0
    print(text)
    print(f"\n{len(jobs)} fits in {seconds:.0f} s")
    (out / "calibration.md").write_text(text + "\n")
    (out / "calibration.json").write_text(json.dumps(
        {"sigma": args.sigma, "seeds": args.seeds, "seconds": seconds, "target_z1": TARGET,
         "summary": {f"{k[0]}/{k[1]}": v for k, v in table.items()}, "rows": rows}, indent=1))
    print(f"written to {out / 'calibration.md'} and {out / 'calibration.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
