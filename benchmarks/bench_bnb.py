"""Branch and bound without prior terms: found? proven? gap, nodes, time — against the exhaustive
search and the paper-style loop, and what the screening order buys.

Cases (paper actuated data: 1 s at 100 Hz, u = 1, exact accelerations, σ = 0; no prior terms):

- spherical pendulum, 125 terms, k = 3 (C(125,3) = 317,750): bnb vs exhaustive vs paper-style loop
  (itertools + one lstsq per support, then the same admissibility visit), in the same run;
- cart-pendulum, 55 terms, k = 4: bnb vs exhaustive;
- double pendulum, 209 terms, k = 6 (C(209,6) = 1.1e11): bnb under a time limit;
- elastic pendulum (r, θ; 125 terms), k = 5: bnb under a time limit, and automatic k;
- the screening order on/off (spherical, cart).

    python benchmarks/bench_bnb.py --out DIR [--quick] [--time-limit S]
"""
from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from math import comb
from pathlib import Path

import numpy as np


def problem(name):
    from lsindy_cas import Library
    from lsindy_cas.identify.admissibility import Admissibility
    from lsindy_cas.identify.balance import derivative_form
    from lsindy_cas.identify.diagnostics import constant_force_trap
    from lsindy_cas.paper import systems
    from lsindy_cas.paper.table1 import PAPER_SETUPS
    if name == "elastic":
        s, features, degree = systems.elastic_pendulum(), "cos(theta),sin(theta),r,r_dot,theta_dot", 4
        k = 5
    else:
        s = systems.PAPER_SYSTEMS[name]()
        features, degree, k = PAPER_SETUPS[name].features, PAPER_SETUPS[name].degree, PAPER_SETUPS[name].n_terms
    lib = Library.polynomial(s.coords, features, degree)
    tr = s.simulate(t_end=1.0, u=1.0)
    bal = derivative_form(lib, [tr])
    trap = constant_force_trap(lib, [tr], [])
    adm = Admissibility.for_balance(lib, bal, [], None, [] if trap is None else trap.excluded)
    truth = tuple(int(j) for j in np.flatnonzero(lib.coefficients(s.hamiltonian)))
    return s, lib, tr, bal, adm, truth, k


def loop_search(A, b, k, adm):
    """Paper-style: itertools.combinations + one lstsq per support, then the same visit."""
    from lsindy_cas.identify.search import visit
    bb = float(b @ b)
    sup, sc, deg = [], [], []
    for S in itertools.combinations(range(A.shape[1]), k):
        x, _, rank, _ = np.linalg.lstsq(A[:, S], b, rcond=None)
        r = b - A[:, S] @ x
        sup.append(S)
        sc.append(float(r @ r) / bb)
        deg.append(rank < k)
    sup, sc, deg = np.array(sup), np.array(sc), np.array(deg)
    v = visit(A, b, sup, sc, deg, admissible=adm)
    return v.result(sup, sc, deg)


def timed(fn):
    t0 = time.perf_counter()
    try:
        out = fn()
    except ValueError as exc:
        out = exc
    return out, time.perf_counter() - t0


def row(case, method, res, seconds, truth, n_all):
    if isinstance(res, Exception):
        return dict(case=case, method=method, found=False, proven=False, gap=None, nodes=None,
                    supports_scored=None, all_supports=n_all, seconds=round(seconds, 3),
                    note=str(res)[:120])
    return dict(case=case, method=method, found=res.support == truth, proven=bool(res.proven),
                gap=float(res.gap), nodes=int(res.nodes), supports_scored=int(res.n_supports),
                all_supports=n_all, seconds=round(seconds, 3), note="")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="folder for bnb.json (must exist or is created)")
    ap.add_argument("--quick", action="store_true", help="skip the paper-style loop; short limits")
    ap.add_argument("--time-limit", type=float, default=None,
                    help="seconds for the double and elastic pendulum searches (default 60, quick 15)")
    args = ap.parse_args(argv)
    limit = args.time_limit or (15.0 if args.quick else 60.0)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from lsindy_cas import LagrangianSINDy
    from lsindy_cas.identify.bnb import branch_and_bound
    from lsindy_cas.identify.search import best_subset
    rows = []
    for name in ("spherical", "cart"):
        s, lib, tr, bal, adm, truth, k = problem(name)
        n_all = comb(len(lib), k)
        res, sec = timed(lambda: best_subset(bal.A, bal.b, k, admissible=adm))
        rows.append(row(name, "exhaustive", res, sec, truth, n_all))
        for screen in (True, False):
            res, sec = timed(lambda: branch_and_bound(bal.A, bal.b, k, admissible=adm,
                                                      screen=screen, time_limit=limit))
            rows.append(row(name, "bnb, stepwise screening" if screen else "bnb", res, sec, truth, n_all))
        if name == "spherical" and not args.quick:
            res, sec = timed(lambda: loop_search(bal.A, bal.b, k, adm))
            rows.append(row(name, "paper-style loop", res, sec, truth, n_all))
    for name in ("double", "elastic"):
        s, lib, tr, bal, adm, truth, k = problem(name)
        res, sec = timed(lambda: branch_and_bound(bal.A, bal.b, k, admissible=adm, time_limit=limit))
        rows.append(row(name, f"bnb, limit {limit:g} s", res, sec, truth, comb(len(lib), k)))
    s, lib, tr, bal, adm, truth, k = problem("elastic")
    t0 = time.perf_counter()
    try:
        m = LagrangianSINDy(lib, time_limit=limit, max_terms=6).fit(tr)
        rows.append(dict(case="elastic", method=f"automatic k (bnb {limit:g} s per k)",
                         found=set(m.support_) == set(truth), proven=bool(m.search_.proven),
                         gap=float(m.search_.gap), nodes=int(m.search_.nodes),
                         supports_scored=int(m.search_.n_supports), all_supports=None,
                         seconds=round(time.perf_counter() - t0, 3), note=f"k = {m.n_terms_}"))
    except ValueError as exc:
        rows.append(dict(case="elastic", method="automatic k", found=False, proven=False, gap=None,
                         nodes=None, supports_scored=None, all_supports=None,
                         seconds=round(time.perf_counter() - t0, 3), note=str(exc)[:120]))
    cols = ["case", "method", "found", "proven", "gap", "nodes", "supports_scored", "all_supports",
            "seconds", "note"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in rows:
        print("| " + " | ".join("" if r[c] is None else (f"{r[c]:.3g}" if isinstance(r[c], float)
                                                           else str(r[c])) for c in cols) + " |")
    (out / "bnb.json").write_text(json.dumps({"time_limit": limit, "quick": args.quick,
                                             "rows": rows}, indent=2))
    print(f"written {out / 'bnb.json'}", file=sys.stderr)


if __name__ == "__main__":
    main()
