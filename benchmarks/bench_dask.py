"""Dask: the support scoring on a LocalCluster against one process, on this machine (issue 15).

Scores every support of the spherical pendulum's 125-term library without priors — C(125, 3) =
317,750 and C(125, 4) = 9,691,375 supports — in process and on a 2-worker ``LocalCluster``
(processes, one thread each), checks the answers are identical (supports, order, scores bit for
bit), and reports the speed-up (median of ``--reps`` runs, with min–max) and the overhead of one
task (round trip of an empty task, median of 200).

    python benchmarks/bench_dask.py --out bench-results            # ~1-2 min
    python benchmarks/bench_dask.py --out bench-results --quick     # k = 3 only

Needs the optional extra ``dask[distributed]``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def _median_spread(times):
    return {"median_s": float(np.median(times)), "min_s": float(np.min(times)),
            "max_s": float(np.max(times))}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="existing folder for dask.json")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="k = 3 only")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if not out.is_dir():
        ap.error(f"--out {out}: no such folder")

    from lsindy_cas import Library, systems
    from lsindy_cas.identify import balance
    from lsindy_cas.identify.distributed import connect, using
    from lsindy_cas.identify.search import score_all

    s = systems.spherical_pendulum()
    tr = s.simulate(t_end=1.0, u=1.0)
    lib = Library.polynomial(s.coords, ["cos(theta)", "sin(theta)", "theta_dot", "phi", "phi_dot"], 4)
    bal = balance.derivative_form(lib, [tr])
    client = connect("local", args.workers)
    client.run(lambda: None)                              # workers up before timing
    rows = []
    try:
        for k in ([3] if args.quick else [3, 4]):
            local, dist = [], []
            for _ in range(args.reps):
                t0 = time.perf_counter()
                a = score_all(bal.A, bal.b, k)
                local.append(time.perf_counter() - t0)
                with using(client):
                    t0 = time.perf_counter()
                    b = score_all(bal.A, bal.b, k)
                    dist.append(time.perf_counter() - t0)
            same = all(np.array_equal(x, y) for x, y in zip(a, b))
            rows.append({"k": k, "supports": int(len(a[1])), "one_process": _median_spread(local),
                         "dask": _median_spread(dist), "speedup": float(np.median(local) / np.median(dist)),
                         "identical": bool(same)})
            del a, b
            print(f"k={k}: one process {np.median(local):.2f} s, dask {np.median(dist):.2f} s",
                  file=sys.stderr)
        rt = []
        for _ in range(200):
            t0 = time.perf_counter()
            client.submit(int, 1, pure=False).result()
            rt.append(time.perf_counter() - t0)
        overhead = {"median_ms": float(np.median(rt) * 1e3), "p90_ms": float(np.percentile(rt, 90) * 1e3)}
    finally:
        client.close()

    print(f"\n| supports (k) | one process (s) | {args.workers}-worker LocalCluster (s) | speed-up | identical |")
    print("|---|---|---|---|---|")
    for r in rows:
        o, d = r["one_process"], r["dask"]
        print(f"| {r['supports']:,} ({r['k']}) | {o['median_s']:.2f} ({o['min_s']:.2f}–{o['max_s']:.2f}) | "
              f"{d['median_s']:.2f} ({d['min_s']:.2f}–{d['max_s']:.2f}) | {r['speedup']:.2f}× | {r['identical']} |")
    print(f"\noverhead of one task (round trip): median {overhead['median_ms']:.2f} ms, "
          f"p90 {overhead['p90_ms']:.2f} ms")
    path = out / "dask.json"
    path.write_text(json.dumps({"workers": args.workers, "reps": args.reps, "rows": rows,
                                "task_overhead": overhead}, indent=2))
    print(f"written: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
