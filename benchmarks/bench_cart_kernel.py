"""Can the pole be held in the success band with the cart on the track for ever? 4-D kernels.

For plants of ``bench_family.PLANTS`` (their exact upright linearisation), the joint pole/cart
viability kernel of :mod:`lsindy_cas.control.cart_pendulum.cart_kernel` (pole band |phi| < 0.1 rad,
|theta_dot| < 0.5 rad/s, cart |x| <= 2 m, {-10, 0, 10} N at 20 Hz) beside the pole-only kernel
of :mod:`lsindy_cas.control.cart_pendulum.viability` on the same pole grid.  Reported: the share of the pole
band that is viable with the cart at rest at the centre (``p = v0 = 0``) in the 4-D kernel and
in the 2-D one, the share of the whole 4-D grid, and the build time and sweeps.  A 4-D share
near 0 where the 2-D share is not says: the pole can be held, but not with the cart on the track
(the failures of ``bench_cart_drift.py`` classed ``drift``), if the grid is fine enough:
coarse grids err towards "not viable" (1.2/0.1/0.5, balanced 20/20 in closed loop: 0.000 on
20x20, 0.868 on 40x40), and on 40x40 (minutes, ~2 GB) 0.7/0.4/0.8 (19/20 nominal) still reads
0.000.  Run two grids (``--grid``) and compare; ``benchmarks/results/cart_kernel.md`` has
the numbers.

    python benchmarks/bench_cart_kernel.py --out DIR              # 4 plants, grid 20x20 (~1 min)
    python benchmarks/bench_cart_kernel.py --out DIR --quick            # 2 plants, grid 12x12
    python benchmarks/bench_cart_kernel.py --out DIR --plants 2 --grid 30,40
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_family import DT, FORCE, PLANTS, kick  # noqa: E402

from lsindy_cas import systems  # noqa: E402
from lsindy_cas.control.cart_pendulum.cart_kernel import cart_pole_kernel  # noqa: E402
from lsindy_cas.control.cart_pendulum.viability import pole_kernel  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="output folder (cart_kernel.json)")
    ap.add_argument("--quick", action="store_true", help="plants 0 and 2, grid 12x12")
    ap.add_argument("--plants", default="0,10,2,11", help="comma-separated indices into PLANTS")
    ap.add_argument("--grid", default="20,20", help="points per pole axis, per cart axis")
    ap.add_argument("--track", type=float, default=2.0, help="cart limit |x| (m)")
    args = ap.parse_args(argv)
    try:
        n_pole, n_cart = (int(v) for v in ("12,12" if args.quick else args.grid).split(","))
        plants = [0, 2] if args.quick else [int(i) for i in args.plants.split(",")]
    except ValueError:
        ap.error("--grid must be two integers and --plants integers")
    if n_pole < 3 or n_cart < 3 or args.track <= 0 or not all(
            0 <= i < len(PLANTS) for i in plants):
        ap.error("bad --grid, --track or --plants")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    levels = (-FORCE, 0.0, FORCE)
    report = {"grid": [n_pole, n_cart], "track": args.track, "plants": []}
    print("| mc | mp | L | kick | 2-D viable share | 4-D viable share, cart centred at rest | "
          "4-D viable share, whole grid | build (s) | sweeps (converged) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for i in plants:
        mc, mp, L = PLANTS[i]
        ode = systems.cart_pendulum(mc=mc, mp=mp, L=L).ode()
        k2 = pole_kernel(ode, 0, 1, np.pi, DT, levels, n_grid=n_pole)
        t0 = time.perf_counter()
        k4 = cart_pole_kernel(ode, 0, 1, np.pi, DT, levels, n_pole=n_pole, n_cart=n_cart,
                              track=args.track)
        seconds = time.perf_counter() - t0
        centre = float(np.mean(k4.centre_slice() <= 0.0))
        row = {"mc": mc, "mp": mp, "L": L, "kick": kick(mc, L),
               "share_2d": k2.viable_fraction, "share_4d_centre": centre,
               "share_4d_grid": k4.viable_fraction, "seconds": seconds,
               "iterations": k4.iterations, "converged": k4.converged,
               "ratio": k4.ratio, "kappa": k4.kappa, "v_max": k4.v_max}
        report["plants"].append(row)
        print(f"| {mc} | {mp} | {L} | {row['kick']:.2f} | {k2.viable_fraction:.3f} | "
              f"{centre:.3f} | {k4.viable_fraction:.4f} | {seconds:.0f} | "
              f"{k4.iterations} ({k4.converged}) |", flush=True)
        (out / "cart_kernel.json").write_text(json.dumps(report, indent=1))
    print(f"\nwrote {out / 'cart_kernel.json'}")


if __name__ == "__main__":
    main()
