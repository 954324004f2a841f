"""The ``lsindy`` command: assembles the subcommands of :mod:`lsindy_cas.commands`."""
from __future__ import annotations

import argparse
import sys

from .commands._common import Parser, command, wrap

__all__ = ["main", "build_parser"]

MAIN_EXAMPLES = """examples:
  lsindy reproduce --out results                  # the paper's Table I and Figs. 3-4
  lsindy identify run1.csv --coords x,theta \\
      --features "cos(theta),sin(theta),theta_dot,x,x_dot" --degree 3 \\
      --terms 4 --prior "theta_dot**2,cos(theta)" --json model.json
  lsindy simulate model.json --x0 "0,pi/4,0,0" --t-end 5 --out sim.csv
  lsindy swingup --model model.json --episodes 5  # MPC swing-up of the cart-pendulum
  lsindy control model.json --task task.toml      # any model, any task (docs/control.md)

Run "lsindy COMMAND --help" for the options of a command."""

SWINGUP_EXAMPLE = """examples:
  lsindy swingup --episodes 5 --out results       # identify the cart-pendulum, then swing it up
  lsindy swingup --model model.json --json metrics.json"""


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="lsindy", description=wrap("Lagrangian-SINDy: identify energy, Lagrangian and "
               "equations of motion from trajectory data; control with them."),
               epilog=MAIN_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    from ._version import __version__
    p.add_argument("--version", action="version", version=f"lsindy_cas {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    sub.required = True
    from .commands import control, export, identify, library, reproduce, simulate
    identify.add_to(sub)
    library.add_to(sub)
    reproduce.add_to(sub)
    simulate.add_to(sub)
    export.add_to(sub)
    control.add_to(sub)
    from .paper.swingup_cli import add_swingup_arguments, run_from_args
    sw = command(sub, "swingup", "identify the cart-pendulum and swing it up by MPC",
                   "Identify the paper's cart-pendulum from simulated data "
                        "(or load --model), build the swing-up MPC from the identified equations and "
                        "run closed-loop episodes on the true plant with forces in {-10, 0, +10} N; "
                        "print success, time to upright and solve times per scenario.",
                   SWINGUP_EXAMPLE)
    add_swingup_arguments(sw)
    sw.set_defaults(func=run_from_args)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, TypeError) as exc:
        msg = " ".join(str(exc).split())
        print(f"lsindy {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except BrokenPipeError:       # output piped into e.g. `head`: stop quietly
        sys.stderr.close()
        return 0
    except OSError as exc:        # a file that passed the up-front checks failed to write or read
        print(f"lsindy {args.command}: error: {exc.strerror or exc}"
              + (f": {exc.filename}" if exc.filename else ""), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"lsindy {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
