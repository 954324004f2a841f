"""Speed of the support search and of identification end to end, against a paper-style loop.

The paper-style loop scores each support with its own ``np.linalg.lstsq`` call inside
``itertools.combinations`` — the direct reading of the paper's trial-and-error search.  It is
swapped in for our batched scorer (``lsindy_cas.identify.search.score_all``) so that everything else — data,
library, admissibility, Legendre, equations of motion — is identical in both columns.

    python benchmarks/bench_search.py            # full run (~10 min), writes benchmarks/results/search.json
    python benchmarks/bench_search.py --quick    # one repetition of each slow loop
    python benchmarks/bench_search.py --quick --parts search_only   # one part, the others kept

"Search alone" also times the branch and bound (:mod:`lsindy_cas.identify.bnb`) on the same balance
and rules: the ≥ 200× target counts whichever path is faster.
"""
from __future__ import annotations

import argparse
import itertools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SPHERICAL_FEATURES = "cos(theta),sin(theta),theta_dot,phi,phi_dot"


def loop_score_all(A, b, k, forced=(), D=None, progress=None):
    """Paper-style: one least-squares solve per support, in a Python loop (same outputs as ours)."""
    p = A.shape[1]
    forced = sorted(set(int(j) for j in forced))
    free = [j for j in range(p) if j not in forced]
    bb = float(b @ b)
    supports, scores, degenerate = [], [], []
    for combo in itertools.combinations(free, k - len(forced)):
        S = sorted(forced + list(combo))
        x, res, rank, _ = np.linalg.lstsq(A[:, S], b, rcond=None)
        r = b - A[:, S] @ x
        supports.append(S)
        scores.append(float(r @ r) / bb)
        degenerate.append(rank < len(S))
    return np.array(supports), np.array(scores), np.array(degenerate)


def timed(fn, reps):
    times, out = [], None
    for _ in range(reps):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times, out


def spherical_problem():
    from lsindy_cas import Library, systems
    s = systems.spherical_pendulum()
    tr = s.simulate(t_end=1.0, u=1.0)
    lib = Library.polynomial(s.coords, SPHERICAL_FEATURES, 4)
    return s, tr, lib


def bench_full_search(reps_ours, reps_loop):
    """Full C(125, 3) search on the spherical pendulum, no priors, with admissibility."""
    from lsindy_cas import LagrangianSINDy
    from lsindy_cas.identify import search as search_mod
    s, tr, lib = spherical_problem()
    truth = set(np.flatnonzero(lib.coefficients(s.hamiltonian)))

    def fit():
        return LagrangianSINDy(lib, n_terms=3).fit(tr)

    fit()                                                     # warm-up: CasADi functions, caches
    t_ours, all_ours, m_ours = timed(fit, reps_ours)
    original = search_mod.score_all
    search_mod.score_all = loop_score_all
    try:
        t_loop, all_loop, m_loop = timed(fit, reps_loop)
    finally:
        search_mod.score_all = original
    n = m_ours.search_.n_supports
    return {
        "supports": n,
        "ours_s": t_ours, "loop_s": t_loop, "speedup": t_loop / t_ours,
        "ours_all_s": all_ours, "loop_all_s": all_loop,
        "loop_supports_per_s": n / t_loop, "ours_supports_per_s": n / t_ours,
        "ours_exact": set(m_ours.support_) == truth, "loop_exact": set(m_loop.support_) == truth,
    }


def bench_search_only(reps_ours, reps_loop):
    """The search alone on the same balance: ``best_subset`` (score every support, then visit them
    best-first through admissibility) with our scorer or the paper-style loop as ``score_all``;
    and the branch and bound (``bnb.branch_and_bound``: the same rules, proven optimal) on it.
    Ours are timed before and after the loop (interleaved with it, under the same load)."""
    from lsindy_cas.identify import search as search_mod
    from lsindy_cas.identify.admissibility import Admissibility
    from lsindy_cas.identify.balance import derivative_form
    from lsindy_cas.identify.bnb import branch_and_bound
    s, tr, lib = spherical_problem()
    bal = derivative_form(lib, [tr])

    def run():
        adm = Admissibility.for_balance(lib, bal, [])         # fresh: its jackknife is built lazily
        return search_mod.best_subset(bal.A, bal.b, 3, admissible=adm)

    def run_bnb():
        adm = Admissibility.for_balance(lib, bal, [])
        return branch_and_bound(bal.A, bal.b, 3, admissible=adm)

    r_ours, r_bnb = run(), run_bnb()
    all_ours, all_bnb, all_loop = [], [], []
    original = search_mod.score_all
    sizes = [len(c) for c in np.array_split(np.arange(reps_ours), reps_loop + 1)]
    for i, n in enumerate(sizes):              # ours | loop | ours | loop ... | ours
        all_ours += timed(run, n)[1] if n else []
        all_bnb += timed(run_bnb, n)[1] if n else []
        if i < reps_loop:
            search_mod.score_all = loop_score_all
            try:
                _, t_l, r_loop = timed(run, 1)
            finally:
                search_mod.score_all = original
            all_loop += t_l
    t_ours, t_bnb, t_loop = (statistics.median(x) for x in (all_ours, all_bnb, all_loop))
    return {"supports": r_ours.n_supports, "ours_s": t_ours, "loop_s": t_loop,
            "speedup": t_loop / t_ours, "ours_all_s": all_ours, "loop_all_s": all_loop,
            "same_support": r_ours.support == r_loop.support,
            "bnb_s": t_bnb, "bnb_all_s": all_bnb, "bnb_speedup": t_loop / t_bnb,
            "bnb_nodes": int(r_bnb.nodes), "bnb_proven": bool(r_bnb.proven),
            "bnb_same_support": r_bnb.support == r_ours.support,
            "best_speedup": t_loop / min(t_ours, t_bnb)}


def bench_table_one(reps):
    from lsindy_cas.paper.table1 import table_one
    t, all_t, cells = timed(table_one, reps)
    return {"seconds": t, "all_s": all_t, "cells": len(cells),
            "all_exact": all(c.exact_support and c.lagrangian_exact_support for c in cells),
            "max_rel_error": max(c.max_rel_error for c in cells)}


CLI_SNIPPET = """
import sys
from lsindy_cas.identify import search
if sys.argv[1] == "loop":
    sys.path.insert(0, {here!r})
    from bench_search import loop_score_all
    search.score_all = loop_score_all
from lsindy_cas.cli import main
sys.exit(main(sys.argv[2:]))
"""


def bench_cli(reps_ours, reps_loop):
    """Wall clock of a whole `lsindy identify` process (start-up, CSV, library, search, output)."""
    _, tr, _ = spherical_problem()
    with tempfile.TemporaryDirectory() as tmp:
        csv = tr.save(Path(tmp) / "spherical.csv")
        args = ["identify", str(csv), "--coords", "theta,phi", "--features", SPHERICAL_FEATURES,
                "--degree", "4", "--terms", "3", "--json", str(Path(tmp) / "m.json")]
        code = CLI_SNIPPET.format(here=str(HERE))

        def run(mode):
            r = subprocess.run([sys.executable, "-c", code, mode, *args], capture_output=True, text=True)
            if r.returncode != 0:
                raise RuntimeError(r.stderr)
            return r.stdout

        t_ours, all_ours, out = timed(lambda: run("ours"), reps_ours)
        t_loop, all_loop, _ = timed(lambda: run("loop"), reps_loop)
    return {"ours_s": t_ours, "loop_s": t_loop, "speedup": t_loop / t_ours,
            "ours_all_s": all_ours, "loop_all_s": all_loop, "hamiltonian": out.splitlines()[0]}


PARTS = ("search_only", "full_search", "table_one", "cli")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="one repetition of each slow loop")
    ap.add_argument("--out", default=str(HERE / "results" / "search.json"))
    ap.add_argument("--parts", default=",".join(PARTS),
                    help="comma-separated parts to run (%s); the others are kept from an existing "
                    "--out file" % ", ".join(PARTS))
    a = ap.parse_args(argv)
    parts = [x.strip() for x in a.parts.split(",") if x.strip()]
    bad = sorted(set(parts) - set(PARTS))
    if bad:
        ap.error(f"--parts: unknown part(s) {', '.join(bad)}; choose from {', '.join(PARTS)}")
    loop_reps = 1 if a.quick else 3
    out = Path(a.out)
    res = json.loads(out.read_text()) if out.exists() else {}
    load = os.getloadavg()
    runs = {"full_search": ("full spherical search (125 terms, k = 3, no priors)",
                            lambda: bench_full_search(7, loop_reps)),
            "search_only": ("search alone (best_subset and branch and bound on the same balance)",
                            lambda: bench_search_only(7, loop_reps)),
            "table_one": ("Table I, six cells end to end", lambda: bench_table_one(3)),
            "cli": ("lsindy identify (spherical, whole process)", lambda: bench_cli(5, loop_reps))}
    for part in PARTS:
        if part in parts:
            print(runs[part][0] + " ...", file=sys.stderr)
            res[part] = runs[part][1]()
            res[part]["load_average"] = load
    if any(part not in res for part in PARTS):
        missing = [part for part in PARTS if part not in res]
        ap.error(f"no results for {', '.join(missing)} in {out}: run them with --parts")
    only, full, table, cli = (res[part] for part in PARTS)
    rows = [
        ("spherical search alone (score + admissible visit), C(125,3)", only["loop_s"],
         only["ours_s"], only["speedup"], "≥ 200×"),
        ("full spherical fit, C(125,3) = %d supports" % full["supports"], full["loop_s"],
         full["ours_s"], full["speedup"], "≥ 200×, < 0.1 s"),
        ("lsindy identify, spherical, whole process", cli["loop_s"], cli["ours_s"], cli["speedup"], "≥ 20×"),
        ("Table I, 6 cells end to end (simulate + fit)", float("nan"), table["seconds"], float("nan"), "≤ 10 s"),
    ]
    if "bnb_s" in only:
        rows.insert(1, ("spherical search alone, branch and bound (%d nodes, proven %s)"
                        % (only["bnb_nodes"], only["bnb_proven"]), only["loop_s"], only["bnb_s"],
                        only["bnb_speedup"], "≥ 200× (whichever path is faster)"))
    print(f"\n| task | paper-style loop | lsindy_cas | speed-up | target |\n|---|---|---|---|---|")
    for name, loop, ours, sp, target in rows:
        loop_s = "—" if np.isnan(loop) else f"{loop:.2f} s"
        sp_s = "—" if np.isnan(sp) else f"{sp:.0f}×"
        print(f"| {name} | {loop_s} | {ours:.3f} s | {sp_s} | {target} |")
    print(f"\nmedians; paper-style loop scores {full['loop_supports_per_s']:,.0f} supports/s, "
          f"ours {full['ours_supports_per_s']:,.0f} supports/s (including admissibility); "
          f"both found the true support: {full['ours_exact'] and full['loop_exact']}; "
          f"Table I all exact: {table['all_exact']} (max rel. error {table['max_rel_error']:.1e})")
    out.parent.mkdir(parents=True, exist_ok=True)
    print("load average at the start of each part: " + ", ".join(
        f"{part} {res[part].get('load_average', res.get('load_average', [float('nan')]))[0]:.2f}"
        for part in PARTS) + " (timings on a loaded machine are provisional)")
    res["load_average"] = load
    out.write_text(json.dumps(res, indent=2))
    print(f"written {out}")


if __name__ == "__main__":
    main()
