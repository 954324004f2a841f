"""Branch and bound without prior terms: found? proven? gap, nodes, time — against the exhaustive
search and the paper-style loop, and what the order of the library does.

Data (no prior terms anywhere):

- paper  the paper's actuated run: 1 s at 100 Hz, u = 1, exact accelerations (derivative form,
         101 rows), σ = 0;
- rich   runs from random initial states under random held inputs (``noise_sweep.rich_runs``; the
         elastic pendulum: the same design, moments up to 3 N·m), exact accelerations, σ = 0;
- rich σ = 1e-2: the rich runs with Gaussian noise on q, q̇ and no accelerations, through the
         whole estimator (integral form, smoothing, noise model, re-selection).

Systems and k: spherical (125 terms, k = 3), cart-pendulum (55, 4), double pendulum (209, 6),
elastic pendulum (r, θ; features cos θ, sin θ, r, ṙ, θ̇, degree 4: 125 terms, k = 5; also with
automatic k).  Orders: the library's ("library"), the stepwise screening order ("screen"), the
basis-pursuit order ("l1"), all searched in turn sharing the incumbent ("auto", the default).

    python benchmarks/bench_bnb.py --out DIR [--quick] [--time-limit S] [--only CASES]
                                   [--no-estimator] [--no-loop] [--merge]

writes DIR/bnb.json and DIR/bnb.md (``--only double:paper,elastic:paper`` runs those exact-data
cases only; ``--merge`` keeps the rows of an existing DIR/bnb.json that were not re-run).  BLAS threads: run with OPENBLAS_NUM_THREADS=1 on a loaded
machine (measured here under load: a 5010×6 least squares 24 ms with 2 threads, 1.4 ms with one).
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

sys.path.insert(0, str(Path(__file__).resolve().parent))

ELASTIC = ("cos(theta),sin(theta),r,r_dot,theta_dot", 4, 5)


def system_setup(name):
    from lsindy_cas.paper import systems
    from lsindy_cas.paper.table1 import PAPER_SETUPS
    if name == "elastic":
        return systems.elastic_pendulum(), *ELASTIC
    st = PAPER_SETUPS[name]
    return systems.PAPER_SYSTEMS[name](), st.features, st.degree, st.n_terms


def runs_for(name, s, protocol, n_runs, seed=1000):
    if protocol == "paper":
        return [s.simulate(t_end=1.0, u=1.0)]
    rng = np.random.default_rng(seed)
    if name != "elastic":
        from noise_sweep import rich_runs
        return rich_runs(name, s, rng, n_runs=n_runs)
    runs = []
    for _ in range(n_runs):
        x0 = np.array(s.x0, float)
        x0[:2] += rng.uniform(-0.2, 0.2, 2)
        x0[2:] = rng.uniform(-1.0, 1.0, 2)
        sw = np.cumsum(rng.uniform(0.2, 1.0, 27))
        lv = rng.uniform(-1.0, 1.0, len(sw) + 1) * 3.0
        runs.append(s.simulate(x0=x0, t_end=5.0, u=lambda t, x, sw=sw, lv=lv: lv[np.searchsorted(sw, t)]))
    return runs


def problem(name, protocol="paper", n_runs=10):
    """(system, library, runs, balance, admissibility, true support, k) for exact-data cases."""
    from lsindy_cas import Library
    from lsindy_cas.identify.admissibility import Admissibility
    from lsindy_cas.identify.balance import derivative_form
    from lsindy_cas.identify.diagnostics import constant_force_trap
    s, features, degree, k = system_setup(name)
    lib = Library.polynomial(s.coords, features, degree)
    runs = runs_for(name, s, protocol, n_runs)
    bal = derivative_form(lib, runs)
    trap = constant_force_trap(lib, runs, [])
    adm = Admissibility.for_balance(lib, bal, [], None, [] if trap is None else trap.excluded)
    truth = tuple(int(j) for j in np.flatnonzero(lib.coefficients(s.hamiltonian)))
    return s, lib, runs, bal, adm, truth, k


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
    global LAST_CPU
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        out = fn()
    except ValueError as exc:
        out = exc
    LAST_CPU = time.process_time() - c0          # CPU seconds: what a loaded machine hides
    return out, time.perf_counter() - t0


LAST_CPU = None


def row(case, data, method, res, seconds, truth, n_all, rows_cols, note=""):
    global LAST_CPU
    base = dict(case=case, data=data, method=method, rows_cols=rows_cols, all_supports=n_all,
                seconds=round(seconds, 2),
                cpu_seconds=None if LAST_CPU is None else round(LAST_CPU, 2))
    LAST_CPU = None                               # the next row's own timed() call, or none
    if isinstance(res, Exception):
        return dict(base, found=False, proven=False, gap=None, nodes=None, supports_scored=None,
                    note=str(res)[:110])
    return dict(base, found=tuple(res.support) == tuple(truth), proven=bool(res.proven),
                gap=float(res.gap), nodes=int(res.nodes), supports_scored=int(res.n_supports),
                note=note)


def exact_cases(args, limit, rows):
    from lsindy_cas.identify.bnb import branch_and_bound
    from lsindy_cas.identify.search import best_subset
    plan = [("spherical", "paper"), ("cart", "paper"), ("double", "paper"), ("elastic", "paper"),
            ("elastic", "rich"), ("double", "rich")]
    if args.only:
        wanted = set(args.only.split(","))
        plan = [c for c in plan if f"{c[0]}:{c[1]}" in wanted]
    for name, protocol in plan:
        s, lib, runs, bal, adm, truth, k = problem(name, protocol, 4 if args.quick else 10)
        n_all, rc = comb(len(lib), k), f"{bal.A.shape[0]}x{bal.A.shape[1]}"
        data = f"{protocol}, σ = 0"
        small = n_all <= 2_000_000
        if small:
            res, sec = timed(lambda: best_subset(bal.A, bal.b, k, admissible=adm))
            rows.append(row(name, data, "exhaustive", res, sec, truth, n_all, rc))
        for screen in ("auto", False, True, "l1") if small or protocol == "rich" else ("auto",):
            label = {"auto": "bnb auto", False: "bnb library order", True: "bnb screen order",
                     "l1": "bnb l1 order"}[screen]
            res, sec = timed(lambda: branch_and_bound(bal.A, bal.b, k, admissible=adm, screen=screen,
                                                      time_limit=limit))
            rows.append(row(name, data, f"{label} ({limit:g} s)", res, sec, truth, n_all, rc))
            print(rows[-1], file=sys.stderr)
        if name == "spherical" and not (args.quick or args.no_loop):
            res, sec = timed(lambda: loop_search(bal.A, bal.b, k, adm))
            rows.append(row(name, data, "paper-style loop", res, sec, truth, n_all, rc))


def estimator_cases(args, limit, rows):
    from lsindy_cas import LagrangianSINDy, Library
    from lsindy_cas.data.smoothing import add_noise
    n_runs = 4 if args.quick else 10
    # automatic k on the elastic pendulum's rich runs (exact data)
    s, features, degree, k = system_setup("elastic")
    lib = Library.polynomial(s.coords, features, degree)
    runs = runs_for("elastic", s, "rich", n_runs)
    truth = tuple(int(j) for j in np.flatnonzero(lib.coefficients(s.hamiltonian)))
    t0 = time.perf_counter()
    try:
        m = LagrangianSINDy(lib, time_limit=limit).fit(runs)
        steps = ", ".join(f"k={st.k}: {st.score:.1e}" for st in m.selection_.steps)
        rows.append(row("elastic", "rich, σ = 0", f"automatic k ({limit:g} s per bnb)", m.search_,
                        time.perf_counter() - t0, truth, None, "", f"k = {m.n_terms_}; {steps}"))
    except ValueError as exc:
        rows.append(row("elastic", "rich, σ = 0", "automatic k", exc, time.perf_counter() - t0,
                        truth, None, ""))
    print(rows[-1], file=sys.stderr)
    # the double pendulum, rich protocol at σ = 1e-2, k = 6, whole estimator
    s, features, degree, k = system_setup("double")
    lib = Library.polynomial(s.coords, features, degree)
    rng = np.random.default_rng([0, 20])
    noisy = [add_noise(tr, 1e-2, rng) for tr in runs_for("double", s, "rich", n_runs)]
    truth = tuple(int(j) for j in np.flatnonzero(lib.coefficients(s.hamiltonian)))
    t0 = time.perf_counter()
    try:
        m = LagrangianSINDy(lib, n_terms=k, time_limit=limit).fit(noisy)
        rows.append(row("double", "rich, σ = 1e-2", f"estimator k = 6 ({limit:g} s per bnb)",
                        m.search_, time.perf_counter() - t0, truth, comb(len(lib), k), ""))
    except ValueError as exc:
        rows.append(row("double", "rich, σ = 1e-2", "estimator k = 6", exc,
                        time.perf_counter() - t0, truth, comb(len(lib), k), ""))
    print(rows[-1], file=sys.stderr)
    # the same data with automatic k (no priors): the scan's scouts, then the chosen k certified
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        m = LagrangianSINDy(lib, time_limit=limit).fit(noisy)
        steps = ", ".join(f"k={st.k}: {st.score:.1e}" + ("" if st.search is None or
                                                         st.search.proven else " (scout)")
                          for st in m.selection_.steps)
        rows.append(row("double", "rich, σ = 1e-2", f"automatic k ({limit:g} s per bnb)",
                        m.search_, time.perf_counter() - t0, truth, None, "",
                        f"k = {m.n_terms_}; {steps}"))
        rows[-1]["cpu_seconds"] = round(time.process_time() - c0, 2)
    except ValueError as exc:
        rows.append(row("double", "rich, σ = 1e-2", "automatic k", exc,
                        time.perf_counter() - t0, truth, None, ""))
    print(rows[-1], file=sys.stderr)


def key_of(r):
    return f"{r['case']} | {r['data']} | {r['method']}"


COLS = ["case", "data", "method", "rows_cols", "found", "proven", "gap", "nodes", "supports_scored",
        "all_supports", "seconds", "cpu_seconds", "note"]


def markdown(rows, limit, kept=()):
    def cell(v):
        if v is None:
            return ""
        return f"{v:.3g}" if isinstance(v, float) else str(v)
    lines = ["Branch and bound without prior terms (wall-clock time limit per search in the method "
             "column; cpu_seconds: process CPU time, what a loaded machine hides)", "",
             "| " + " | ".join(COLS) + " |", "|" + "---|" * len(COLS)]
    lines += ["| " + " | ".join(cell(r.get(c)) for c in COLS) + " |" for r in rows]
    if kept:
        lines += ["", "Kept from the previous run (not re-run): "
                  + "; ".join(f"{r['case']}, {r['data']}, {r['method']}" for r in kept) + "."]
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="folder for bnb.json and bnb.md (created)")
    ap.add_argument("--quick", action="store_true",
                    help="no paper-style loop, 4 rich runs instead of 10, 15 s limits")
    ap.add_argument("--time-limit", type=float, default=None,
                    help="seconds per branch and bound (default 60, quick 15)")
    ap.add_argument("--only", default="",
                    help="comma-separated exact-data cases name:protocol, e.g. double:paper")
    ap.add_argument("--no-estimator", action="store_true",
                    help="skip the estimator rows (automatic k, rich σ = 1e-2: ~30 min)")
    ap.add_argument("--no-loop", action="store_true", help="skip the paper-style loop (60 s)")
    ap.add_argument("--merge", action="store_true",
                    help="keep the rows of an existing DIR/bnb.json that were not re-run")
    args = ap.parse_args(argv)
    if args.time_limit is not None and not 0 < args.time_limit < float("inf"):
        ap.error(f"--time-limit must be positive, got {args.time_limit}")
    limit = args.time_limit or (15.0 if args.quick else 60.0)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows, kept, t0 = [], [], time.perf_counter()
    exact_cases(args, limit, rows)
    if not args.no_estimator:
        estimator_cases(args, limit, rows)
    if args.merge and (out / "bnb.json").exists():
        key = lambda r: (r["case"], r["data"], r["method"])           # noqa: E731
        new = {key(r): r for r in rows}
        old = json.loads((out / "bnb.json").read_text())["rows"]
        kept = [r for r in old if key(r) not in new]
        rows = [new.pop(key(r), r) for r in old] + list(new.values())
    md = markdown(rows, limit, kept)
    print(md)
    (out / "bnb.json").write_text(json.dumps({"time_limit": limit, "quick": args.quick, "rows": rows,
                                              "total_seconds": round(time.perf_counter() - t0, 1),
                                              "kept_not_rerun": [key_of(r) for r in kept]},
                                             indent=2))
    (out / "bnb.md").write_text(md)
    print(f"written {out / 'bnb.json'}, {out / 'bnb.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()
