"""Swing-up of the cart-pendulum from an identified model, forces only from {-10, 0, +10} N.

The paper's Sec. III-C / Fig. 5 experiment, on the package's public API: simulate the actuated
training run, identify the cart-pendulum with ``LagrangianSINDy``, build a ``SwingUpMPC`` from the
identified model, run closed-loop episodes on the true plant (nominal, +-10 % parameter mismatch,
measurement noise), print a summary table, and optionally write JSON metrics and figures.

    python mpc/swingup.py --episodes 20 --seed 0 --json results/swingup.json --out results/

Same as ``lsindy swingup``.  ``main(["--episodes", "2"])`` runs it small (used by the tests).
"""

from __future__ import annotations

import argparse
import sys

from lsindy_cas.paper.swingup import add_swingup_arguments, run_from_args, run_swingup

__all__ = ["main", "run_swingup"]


def main(argv=None):
    """Parse ``argv`` (default: ``sys.argv[1:]``), run, return the exit code.

    0 = every nominal episode succeeded, 1 = some did not, 2 = bad input.
    """
    parser = argparse.ArgumentParser(prog="swingup", description=__doc__.split("\n\n")[0])
    add_swingup_arguments(parser)
    args = parser.parse_args(argv)
    try:
        return run_from_args(args)
    except (ValueError, TypeError, OSError) as exc:
        print(f"swingup: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
