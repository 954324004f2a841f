"""Dask: the support searches on a LocalCluster against one process, on this machine.

Exhaustive scoring: every support of the spherical pendulum's 125-term library without priors —
C(125, 3) = 317,750 and C(125, 4) = 9,691,375 supports — in process and on a ``--workers``-worker
``LocalCluster`` (processes, one thread each); the answers must be identical (supports, order,
scores bit for bit).

Branch and bound (:mod:`lsindy_cas.identify.distributed_bnb`): searches whose proof takes seconds —
the cart-pendulum's paper run (55 terms, no priors) at k = 5, one past its true k (the proof walks
~13,000 nodes), and pure noise (200 × 40 Gaussian, k = 5, and 300 × 60, k = 6: every support
scores alike; the smaller one is now proven within the warm-up on the driver) — in process
and on the cluster (defaults: 0.5 s warm-up on the driver, tasks of 1 s); the same support is
required, and the nodes over all tasks are reported next to one process's.

Reported: the speed-up (median of ``--reps`` runs, with min–max), the overhead of one task (round
trip of an empty task, and of an empty branch-and-bound task, which also reads the shared
incumbent; median of 100).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_dask.py --out bench-results   # ~3-5 min
    python benchmarks/bench_dask.py --out bench-results --quick     # k = 3, noise case only
    python benchmarks/bench_dask.py --out bench-results --bnb-only  # the branch and bound only

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
    ap.add_argument("--quick", action="store_true", help="k = 3 and the noise case only")
    ap.add_argument("--bnb-only", action="store_true", help="skip the exhaustive scoring")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if not out.is_dir():
        ap.error(f"--out {out}: no such folder")

    from lsindy_cas import Library, systems
    from lsindy_cas.identify import balance
    from lsindy_cas.identify.backend import DaskBackend
    from lsindy_cas.identify.distributed import connect
    from lsindy_cas.identify.search import score_all

    s = systems.spherical_pendulum()
    tr = s.simulate(t_end=1.0, u=1.0)
    lib = Library.polynomial(s.coords, ["cos(theta)", "sin(theta)", "theta_dot", "phi", "phi_dot"], 4)
    bal = balance.derivative_form(lib, [tr])
    client = connect("local", args.workers)
    client.run(lambda: None)                              # workers up before timing
    rows = []
    try:
        for k in ([] if args.bnb_only else [3] if args.quick else [3, 4]):
            local, dist = [], []
            for _ in range(args.reps):
                t0 = time.perf_counter()
                a = score_all(bal.A, bal.b, k)
                local.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                b = DaskBackend(client).score_all(bal.A, bal.b, k)
                dist.append(time.perf_counter() - t0)
            same = all(np.array_equal(x, y) for x, y in zip(a, b))
            rows.append({"k": k, "supports": int(len(a[1])), "one_process": _median_spread(local),
                         "dask": _median_spread(dist), "speedup": float(np.median(local) / np.median(dist)),
                         "identical": bool(same)})
            del a, b
            print(f"k={k}: one process {np.median(local):.2f} s, dask {np.median(dist):.2f} s",
                  file=sys.stderr)
        bnb_rows = bnb_section(client, args)
        overhead = task_overheads(client)
    finally:
        client.close()

    print(f"\n| supports (k) | one process (s) | {args.workers}-worker LocalCluster (s) | speed-up | identical |")
    print("|---|---|---|---|---|")
    for r in rows:
        o, d = r["one_process"], r["dask"]
        print(f"| {r['supports']:,} ({r['k']}) | {o['median_s']:.2f} ({o['min_s']:.2f}–{o['max_s']:.2f}) | "
              f"{d['median_s']:.2f} ({d['min_s']:.2f}–{d['max_s']:.2f}) | {r['speedup']:.2f}× | {r['identical']} |")
    print(f"\n| branch and bound | one process (s) | {args.workers}-worker LocalCluster (s) | speed-up "
          "| nodes one / cluster | tasks | same support | proven |")
    print("|---|---|---|---|---|---|---|---|")
    for r in bnb_rows:
        o, d = r["one_process"], r["dask"]
        print(f"| {r['case']} | {o['median_s']:.2f} ({o['min_s']:.2f}–{o['max_s']:.2f}) | "
              f"{d['median_s']:.2f} ({d['min_s']:.2f}–{d['max_s']:.2f}) | {r['speedup']:.2f}× | "
              f"{r['nodes_one']:,} / {r['nodes_dask']:,} | {r['tasks']} | {r['same_support']} | "
              f"{r['proven']} |")
    print(f"\noverhead of one task (round trip): median {overhead['median_ms']:.2f} ms, "
          f"p90 {overhead['p90_ms']:.2f} ms; an empty branch-and-bound task (reads the shared "
          f"incumbent): median {overhead['bnb_median_ms']:.2f} ms, p90 {overhead['bnb_p90_ms']:.2f} ms")
    path = out / "dask.json"
    path.write_text(json.dumps({"workers": args.workers, "reps": args.reps, "rows": rows,
                                "bnb_rows": bnb_rows, "task_overhead": overhead}, indent=2))
    print(f"written: {path}")
    return 0


def bnb_cases(quick):
    """(name, A, b, k, admissible) of the branch-and-bound section."""
    from lsindy_cas import Library
    from lsindy_cas.identify.admissibility import Admissibility
    from lsindy_cas.identify.balance import derivative_form
    from lsindy_cas.paper import systems
    from lsindy_cas.paper.table1 import PAPER_SETUPS
    rng = np.random.default_rng(1)
    cases = [("noise 200x40, k = 5", rng.normal(size=(200, 40)), rng.normal(size=200), 5, None)]
    if not quick:            # a noise search long enough to leave the driver (~16,000 nodes)
        cases.append(("noise 300x60, k = 6", rng.normal(size=(300, 60)), rng.normal(size=300), 6,
                      None))
        s, st = systems.cart_pendulum(), PAPER_SETUPS["cart"]
        lib = Library.polynomial(s.coords, st.features, st.degree)
        bal = derivative_form(lib, [s.simulate(t_end=1.0, u=1.0)])
        adm = Admissibility.for_balance(lib, bal, [])
        cases.append(("cart paper run, 55 terms, k = 5", bal.A, bal.b, 5, adm))
    return cases


def bnb_section(client, args):
    from lsindy_cas.identify.bnb import branch_and_bound
    from lsindy_cas.identify.distributed_bnb import branch_and_bound_distributed
    rows = []
    for name, A, b, k, adm in bnb_cases(args.quick):
        local, dist = [], []
        for _ in range(args.reps):
            t0 = time.perf_counter()
            one = branch_and_bound(A, b, k, admissible=adm)
            local.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            many = branch_and_bound_distributed(client, A, b, k, admissible=adm)
            dist.append(time.perf_counter() - t0)
        rows.append({"case": name, "one_process": _median_spread(local), "dask": _median_spread(dist),
                     "speedup": float(np.median(local) / np.median(dist)),
                     "nodes_one": int(one.nodes), "nodes_dask": int(many.nodes),
                     "tasks": int(many.tasks), "same_support": many.support == one.support,
                     "coef_max_diff": float(np.max(np.abs(many.coef - one.coef))),
                     "proven": bool(one.proven and many.proven)})
        print(f"{name}: one process {np.median(local):.2f} s ({one.nodes} nodes), dask "
              f"{np.median(dist):.2f} s ({many.nodes} nodes, {many.tasks} tasks)", file=sys.stderr)
    return rows


def task_overheads(client, n=100):
    """Round trip of an empty task, and of an empty branch-and-bound task (ms)."""
    import uuid
    from distributed import Variable
    from lsindy_cas.identify.bnb import BnbSearch
    from lsindy_cas.identify.distributed_bnb import _run_task, _template
    rt = []
    for _ in range(n):
        t0 = time.perf_counter()
        client.submit(int, 1, pure=False).result()
        rt.append(time.perf_counter() - t0)
    rng = np.random.default_rng(0)
    s = BnbSearch(rng.normal(size=(50, 10)), rng.normal(size=50), 3, [], None, None, None, 1e-12,
                10).start(False)
    tmpl, = client.scatter([[_template(s)]], broadcast=True)
    var = Variable(f"bench-{uuid.uuid4().hex}", client=client)
    var.set(float("inf"))
    rb = []
    for _ in range(n):
        t0 = time.perf_counter()
        client.submit(_run_task, tmpl, 0, [], np.inf, var.name, 1.0, pure=False).result()
        rb.append(time.perf_counter() - t0)
    var.delete()
    return {"median_ms": float(np.median(rt) * 1e3), "p90_ms": float(np.percentile(rt, 90) * 1e3),
            "bnb_median_ms": float(np.median(rb) * 1e3),
            "bnb_p90_ms": float(np.percentile(rb, 90) * 1e3)}


if __name__ == "__main__":
    sys.exit(main())
