"""Parameter grid: the paper's protocols on the three paper systems with other masses, lengths and
initial states.  Every cell must come out exact (support, coefficients within 1e-3) with status
"ok", or with status "undetermined" and a reason; a wrong model with status "ok" is a failure.

Cells (``--quick``: the first of each system's parameter list, both schemes, the paper's x0):

- spherical pendulum: m ∈ {0.5, 1, 3} × L ∈ {0.3, 1, 2}, x0 ∈ {paper, (π/4, 0 | 0, 1)};
- cart-pendulum: m_c ∈ {0.5, 1, 2} × m_p ∈ {0.05, 0.1, 0.3} × L ∈ {0.3, 1, 2}, paper x0, plus
  x0 = (0, π/2 | 0, 0) at the paper's masses with each L;
- double pendulum (a subset): m1, m2 ∈ {0.5, 1, 2} at L1 = L2 = 1, and L1, L2 ∈ {0.5, 2} at
  m1 = m2 = 1; x0 ∈ {paper, (π/4, π/2 | 0, 0)} at the paper's parameters.

Each cell twice: with the simulator's exact accelerations (derivative form, as Table I) and as
a file gives the data, without accelerations (integral form, smoothed: the CLI's usual case).

Schemes as in Table I (``paper/table1.py``): actuated = u = 1 for 1 s; passive = u = 0 for 3 s
plus a 0.1 s actuated scale trial; 100 Hz; the paper's libraries, priors and k.

Usage::

    python benchmarks/bench_grid.py --out DIR [--quick] [--workers 2]
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

TOL = 1e-3


def cells(quick: bool = False) -> list:
    """(system, params, x0 or None, scheme) for every cell of the grid."""
    out = []
    sph = [dict(m=m, L=L) for m in (0.5, 1.0, 3.0) for L in (0.3, 1.0, 2.0)]
    cart = [dict(mc=mc, mp=mp, L=L) for mc in (0.5, 1.0, 2.0) for mp in (0.05, 0.1, 0.3)
            for L in (0.3, 1.0, 2.0)]
    dbl = ([dict(m1=a, m2=b) for a in (0.5, 1.0, 2.0) for b in (0.5, 1.0, 2.0)]
           + [dict(L1=a, L2=b) for a in (0.5, 2.0) for b in (0.5, 2.0)])
    if quick:
        sph, cart, dbl = [dict(m=3.0, L=0.3)], [dict(mc=0.5, mp=0.3, L=0.3)], [dict(m1=2.0, m2=0.5)]
    for scheme in ("actuated", "passive"):
        for p in sph:
            out.append(("spherical", p, None, scheme))
            if not quick:
                out.append(("spherical", p, (np.pi / 4, 0.0, 0.0, 1.0), scheme))
        for p in cart:
            out.append(("cart", p, None, scheme))
        for p in dbl:
            out.append(("double", p, None, scheme))
        if not quick:
            for L in (0.3, 1.0, 2.0):
                out.append(("cart", dict(L=L), (0.0, np.pi / 2, 0.0, 0.0), scheme))
            out.append(("double", {}, (np.pi / 4, np.pi / 2, 0.0, 0.0), scheme))
    return out


def _strip(tr):
    """The trajectory as a file gives it: no exact accelerations (so the integral form is used)."""
    from lsindy_cas import Trajectory
    return Trajectory(tr.t, tr.q, tr.qd, tr.coords, Q=tr.Q)


def run_cell(cell) -> dict:
    """Identify one cell; classify it as exact / undetermined / wrong-ok / refused."""
    from lsindy_cas import LagrangianSINDy
    from lsindy_cas.paper import systems
    from lsindy_cas.paper.table1 import PAPER_SETUPS, T_ACTUATED, T_PASSIVE, T_SCALE, U, compare
    from lsindy_cas.symbolic.library import Library

    name, params, x0, scheme, form = cell
    factory = {"spherical": systems.spherical_pendulum, "cart": systems.cart_pendulum,
               "double": systems.double_pendulum}[name]
    system = factory(**params)
    setup = PAPER_SETUPS[name]
    lib = Library.polynomial(system.coords, setup.features, setup.degree)
    if scheme == "actuated":
        trajs, scale = [system.simulate(x0=x0, t_end=T_ACTUATED, u=U)], None
    else:
        trajs = [system.simulate(x0=x0, t_end=T_PASSIVE, u=0.0)]
        scale = [system.simulate(x0=x0, t_end=T_SCALE, u=U)]
    if form == "integral":
        trajs = [_strip(tr) for tr in trajs]
        scale = None if scale is None else [_strip(tr) for tr in scale]
    row = {"form": form, "system": name, "params": params, "x0": None if x0 is None else [float(v) for v in x0],
           "scheme": scheme}
    t0 = time.perf_counter()
    try:
        model = LagrangianSINDy(lib, n_terms=setup.n_terms, prior=setup.prior).fit(trajs, scale)
    except ValueError as exc:
        row.update(outcome="refused", reason=str(exc), seconds=time.perf_counter() - t0)
        return row
    exact, err = compare(model.coef_, lib.coefficients(system.hamiltonian))
    right = bool(exact and err <= TOL)
    outcome = ("exact" if model.ok_ else "undetermined-exact") if right else \
        ("WRONG-OK" if model.ok_ else "undetermined")
    row.update(outcome=outcome, exact_support=exact, max_rel_error=err, status=model.status_,
               reasons=model.status_reasons_, terms=model.terms(),
               checks=model.diagnostics_.to_dict()["checks"], seconds=time.perf_counter() - t0)
    return row


def _label(row) -> str:
    p = ",".join(f"{k}={v:g}" for k, v in row["params"].items()) or "paper"
    x0 = "" if row["x0"] is None else " x0=(" + ",".join(f"{v:.2f}" for v in row["x0"]) + ")"
    return f"{row['system']} {row['scheme']} ({row['form']}) {p}{x0}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, type=Path, help="folder for grid.json and grid.md")
    ap.add_argument("--quick", action="store_true", help="one parameter set per system")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--form", choices=["derivative", "integral", "both"], default="both",
                    help="derivative: exact accelerations as the simulator gives them (Table I); "
                    "integral: files without accelerations (the CLI's usual case)")
    args = ap.parse_args(argv)
    if not args.out.is_dir():
        ap.error(f"--out {args.out}: not an existing folder")
    forms = ("derivative", "integral") if args.form == "both" else (args.form,)
    todo = [c + (f,) for f in forms for c in cells(args.quick)]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max(1, args.workers)) as pool:
        rows = list(pool.map(run_cell, todo))
    wall = time.perf_counter() - t0
    counts = {}
    for r in rows:
        counts[r["outcome"]] = counts.get(r["outcome"], 0) + 1
    lines = ["| cell | outcome | max rel. error | reasons |", "|---|---|---|---|"]
    for r in rows:
        err = f"{r['max_rel_error']:.1e}" if "max_rel_error" in r else "—"
        why = "; ".join(r.get("reasons") or ([r["reason"]] if "reason" in r else []))
        lines.append(f"| {_label(r)} | {r['outcome']} | {err} | {why[:160]} |")
    summary = ", ".join(f"{k}: {v}" for k, v in sorted(counts.items()))
    lines += ["", f"{len(rows)} cells — {summary}; wall time {wall:.0f} s"]
    text = "\n".join(lines)
    print(text)
    (args.out / "grid.md").write_text(text + "\n")
    (args.out / "grid.json").write_text(json.dumps({"cells": rows, "counts": counts,
                                                    "wall_seconds": wall, "tolerance": TOL},
                                                   indent=2, default=float))
    return 1 if counts.get("WRONG-OK") else 0


if __name__ == "__main__":
    raise SystemExit(main())
