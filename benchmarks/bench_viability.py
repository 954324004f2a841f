"""Which cart-pendulums can be balanced with {-10, 0, 10} N at 20 Hz at all.

For every plant of the family benchmark (``bench_family.PLANTS``) and each of the 8 sign
patterns of its +-10 % mismatch (cart mass, pole mass, pole length), the viability kernel of the
pole at the upright (:mod:`lsindy_cas.control.cart_pendulum.viability`, built from the plant's exact
upright linearisation): its largest margin (negative: empty, no controller can hold the pole
in the success band |phi| < 0.1 rad, |theta_dot| < 0.5 rad/s), the share of the band it covers,
whether 8 settled starts (|phi| < 0.03, |theta_dot| < 0.2) are inside, and the build time;
then the sequence balancer's plan time with and without the kernel, closed loop on the
linearised 0.8/0.2/0.7 plant from settled starts.
The expected numbers are the check: kick 0.89 rad/s held from 8/8 settled starts, 1.0 from
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
from lsindy_cas.control.cart_pendulum.viability import pole_kernel  # noqa: E402


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


def plan_times(mc=0.8, mp=0.2, L=0.7, starts=6, steps=60):
    """Per-step plan time (ms) of the sequence balancer with and without the kernel, closed
    loop on the plant's exact upright linearisation from settled starts, and whether the pole
    stayed in the success band (every 10 ms).  Returns one dict per variant."""
    import casadi as ca
    from scipy.linalg import expm

    from lsindy_cas.control.cart_pendulum.sequence_balancer import SequenceBalancer
    ode = systems.cart_pendulum(mc=mc, mp=mp, L=L).ode()
    xs, us = ca.SX.sym("x", 4), ca.SX.sym("u", 2)
    jac = ca.Function("j", [xs, us], [ca.jacobian(ode(xs, us), xs),
                                      ca.jacobian(ode(xs, us), us)])
    ref = np.array([0.0, np.pi, 0.0, 0.0])
    Ac, Bc = (np.asarray(m, dtype=float) for m in jac(ref, np.zeros(2)))
    M = np.zeros((6, 6))
    M[:4, :4], M[:4, 4:] = Ac, Bc
    Ed, Es = expm(M * DT), expm(M * DT / 5)
    lin = ca.Function("lin", [xs, us], [ca.mtimes(Ac, xs - ref) + ca.mtimes(Bc, us)])
    step = ca.Function("step", [xs, us], [ref + ca.mtimes(Ed[:4, :4], xs - ref)
                                          + ca.mtimes(Ed[:4, 4:], us)])
    levels = np.array([-FORCE, 0.0, FORCE])
    rows = []
    for viability in (False, True):
        b = SequenceBalancer(step, lin, levels, cart_index=0, pole_index=1, upright=np.pi,
                             track_limit=2.0, dt=DT, viability=viability)
        held = 0
        for phi, rate in settled(starts, seed=1):
            b.reset()
            e, worst = np.array([0.0, phi, 0.0, rate]), 0.0
            for _ in range(steps):
                u = levels[b(ref + e)]
                for _ in range(5):
                    e = Es[:4, :4] @ e + Es[:4, 4] * u
                    worst = max(worst, abs(e[1]) / 0.1, abs(e[3]) / 0.5)
            held += int(worst < 1.0)
        ms = 1e3 * np.array(b.plan_seconds)
        rows.append({"viability": viability, "held": held, "starts": starts,
                     "plan_ms_median": float(np.median(ms)),
                     "plan_ms_p99": float(np.percentile(ms, 99)), "plans": int(ms.size)})
    return rows


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
    timing = plan_times()
    print("\n| sequence balancer, 0.8/0.2/0.7 linearised, settled starts | held 3 s in the band |"
          " plan median (ms) | plan p99 (ms) |\n|---|---|---|---|")
    for r in timing:
        print(f"| {'with' if r['viability'] else 'without'} the kernel | {r['held']}/{r['starts']}"
              f" | {r['plan_ms_median']:.1f} | {r['plan_ms_p99']:.1f} |")
    report = {"dt": DT, "force": FORCE, "n_grid": args.n_grid, "plants": rows,
              "plan_times": timing, "seconds": time.perf_counter() - t0}
    (out / "viability.json").write_text(json.dumps(report, indent=1))
    print(f"\n{len(rows)} plants, {report['seconds']:.0f} s; wrote {out / 'viability.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
