"""Which cart-pendulums can be balanced with {-10, 0, 10} N at 20 Hz at all (issue 16).

For every plant of the family benchmark (``bench_family.PLANTS``) and each of the 8 sign
patterns of its +-10 % mismatch (cart mass, pole mass, pole length), the viability kernel of the
pole at the upright (:mod:`lsindy_cas.control.viability`, built from the plant's exact
upright linearisation): its largest margin (negative: empty, no controller can hold the pole
in the success band |phi| < 0.1 rad, |theta_dot| < 0.5 rad/s), the share of the band it covers,
whether 8 settled starts (|phi| < 0.03, |theta_dot| < 0.2) are inside, and the build time.
The issue's own numbers are the check: kick 0.89 rad/s held from 8/8 settled starts, 1.0 from
none.

    python benchmarks/bench_viability.py --out DIR           # 12 plants x 9 kernels (~1-2 min)
    python benchmarks/bench_viability.py --out DIR --quick   # 3 plants, nominal only
    python benchmarks/bench_viability.py --out DIR --n-grid 241
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_family import DT, FORCE, PLANTS, QUICK, kick  # noqa: E402

from lsindy_cas import systems  # noqa: E402
from lsindy_cas.control.viability import pole_kernel  # noqa: E402


def settled(n=8, seed=0):
    """Settled poles: |phi| < 0.03 rad, |theta_dot| < 0.2 rad/s (seeded)."""
    rng = np.random.default_rng(seed)
    return np.c_[rng.uniform(-0.03, 0.03, n), rng.uniform(-0.2, 0.2, n)]


def kernel_row(mc, mp, L, n_grid):
    """Kernel summary of one plant (JSON-ready)."""
    system = systems.cart_pendulum(mc=mc, mp=mp, L=L)
    K = pole_kernel(system.ode(), 0, 1, np.pi, DT, (-FORCE, 0.0, FORCE), n_grid=n_grid)
    s = settled()
    return {"mc": mc, "mp": mp, "L": L, "kick": kick(mc, L),
            "linear_kick": float(abs(K.B[1]) * FORCE), "max_margin": K.max_margin,
            "empty": K.empty, "viable_fraction": K.viable_fraction,
            "settled_viable": int(K.viable(s[:, 0], s[:, 1]).sum()),
            "iterations": K.iterations, "converged": K.converged, "seconds": K.seconds}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="output folder (viability.json)")
    ap.add_argument("--quick", action="store_true", help="3 plants, nominal only")
    ap.add_argument("--n-grid", type=int, default=121, help="grid points per axis (default 121)")
    args = ap.parse_args(argv)
    if args.n_grid < 3:
        ap.error("--n-grid must be >= 3")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    idx = QUICK if args.quick else range(len(PLANTS))
    patterns = [(1.0, 1.0, 1.0)] + ([] if args.quick else
                                    list(itertools.product((0.9, 1.1), repeat=3)))
    t0 = time.perf_counter()
    rows = []
    print("| mc | mp | L | kick F dt/(m_c L) | kernel margin | band share viable | settled "
          "starts held | mismatch patterns proven unreachable | build (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for i in idx:
        mc, mp, L = PLANTS[i]
        nominal = kernel_row(mc, mp, L, args.n_grid)
        mism = [kernel_row(mc * f[0], mp * f[1], L * f[2], args.n_grid) for f in patterns[1:]]
        for r, f in zip(mism, patterns[1:]):
            r["factors"] = list(f)
        empty = sum(r["empty"] for r in mism)
        rows.append({**nominal, "mismatch": mism, "mismatch_empty": empty})
        share = f"{empty}/{len(mism)}" if mism else "-"
        print(f"| {mc} | {mp} | {L} | {nominal['kick']:.2f} | {nominal['max_margin']:+.3f} | "
              f"{nominal['viable_fraction']:.2f} | {nominal['settled_viable']}/8 | {share} | "
              f"{nominal['seconds']:.2f} |", flush=True)
    report = {"dt": DT, "force": FORCE, "n_grid": args.n_grid, "plants": rows,
              "seconds": time.perf_counter() - t0}
    (out / "viability.json").write_text(json.dumps(report, indent=1))
    print(f"\n{len(rows)} plants, {report['seconds']:.0f} s; wrote {out / 'viability.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
