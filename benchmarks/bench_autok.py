"""Automatic k on planted energies: does the scan find the planted support, at which k, how fast?

Planted two-link energies with k = 6 … 10 terms in a 154-term library (``planted.py``), two priors
(θ̇1², θ̇2²), six clean runs of 5 s at 100 Hz under random held torques, small motion (starts in
±0.6 rad) and large motion (±2.5 rad); ``--seeds`` energies per (k, motion).  For each fit:
exact support?, the k chosen, largest relative coefficient error, status, the k scored and the
k left unscored (with why), seconds.

    python benchmarks/bench_autok.py --out DIR [--seeds N] [--ks 6,7,8,9,10] [--spreads 0.6,2.5]

writes DIR/autok.json and DIR/autok.md; prints the table as it goes.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import planted  # noqa: E402


def run_one(k: int, spread: float, seed: int, lib) -> dict:
    from lsindy_cas import LagrangianSINDy
    coef = planted.planted(k, seed)
    truth = lib.coefficients(planted.system(coef).hamiltonian)
    data = planted.strip(planted.runs(coef, spread, seed=seed))
    t0 = time.perf_counter()
    row = {"k_true": k, "spread": spread, "seed": seed}
    try:
        m = LagrangianSINDy(lib, prior=planted.PRIOR).fit(data)
    except ValueError as exc:
        row.update(k=None, exact=False, max_rel_error=None, status="refused", reasons=[str(exc)],
                   scored=[], unscored=[], seconds=time.perf_counter() - t0)
        return row
    S = np.flatnonzero(truth)
    exact = set(np.flatnonzero(m.coef_)) == set(S)
    err = float(np.max(np.abs(m.coef_[S] - truth[S]) / np.abs(truth[S]))) if exact else None
    row.update(k=int(m.n_terms_), exact=bool(exact), max_rel_error=err, status=m.status_,
               reasons=[str(r) for r in m.status_reasons_],
               scored=[st.k for st in m.selection_.steps],
               unscored=[{"k": u.k, "proven": u.proven, "seconds": u.seconds, "reason": u.reason}
                         for u in m.selection_.unscored],
               seconds=time.perf_counter() - t0)
    return row


def markdown(rows, header) -> str:
    lines = [header, "", "| k true | motion (rad) | seed | k chosen | exact support | max rel. error "
             "| status | k scored | k unscored | seconds |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        err = "" if r["max_rel_error"] is None else f"{r['max_rel_error']:.1e}"
        uns = ", ".join(f"{u['k']} ({'none' if u['proven'] else 'undecided'})" for u in r["unscored"])
        lines.append(f"| {r['k_true']} | ±{r['spread']:g} | {r['seed']} | {r['k']} | {r['exact']} | "
                     f"{err} | {r['status']} | {','.join(map(str, r['scored']))} | {uns} | "
                     f"{r['seconds']:.1f} |")
    ok = [r for r in rows if r["exact"]]
    wrong_ok = [r for r in rows if not r["exact"] and r["status"] == "ok"]
    secs = np.array([r["seconds"] for r in rows])
    lines += ["", f"exact support: {len(ok)}/{len(rows)}; wrong and status ok: {len(wrong_ok)}; "
              f"seconds per fit: median {np.median(secs):.1f}, min {secs.min():.1f}, "
              f"max {secs.max():.1f}"]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path, help="output folder")
    ap.add_argument("--seeds", type=int, default=2, help="planted energies per (k, motion)")
    ap.add_argument("--ks", default="6,7,8,9,10")
    ap.add_argument("--spreads", default="0.6,2.5", help="start-angle spreads (rad)")
    args = ap.parse_args(argv)
    try:
        ks = [int(x) for x in args.ks.split(",")]
        spreads = [float(x) for x in args.spreads.split(",")]
        bad = [k for k in ks if k not in planted.SPLIT]
        if bad or args.seeds < 1 or not all(s > 0 for s in spreads):
            raise ValueError
    except ValueError:
        print(f"bench_autok: --ks must be among {sorted(planted.SPLIT)}, --spreads positive, "
              "--seeds ≥ 1", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    lib = planted.library()
    t0 = time.perf_counter()
    rows = []
    for k in ks:
        for spread in spreads:
            for seed in range(args.seeds):
                r = run_one(k, spread, seed, lib)
                rows.append(r)
                print(f"k={k} ±{spread:g} seed {seed}: chose {r['k']}, exact {r['exact']}, "
                      f"status {r['status']}, {r['seconds']:.1f} s", flush=True)
    total = time.perf_counter() - t0
    header = (f"Automatic k on planted energies ({len(lib)}-term library, priors "
              f"{', '.join(planted.PRIOR)}; {total:.0f} s in all)")
    md = markdown(rows, header)
    (args.out / "autok.md").write_text(md)
    (args.out / "autok.json").write_text(json.dumps({"rows": rows, "seconds": total}, indent=1))
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
