"""``lsindy library``: list the candidate terms of a library."""
from __future__ import annotations

from ._common import command, library, library_arguments

LIBRARY_EXAMPLE = """examples:
  lsindy library --coords x,theta --features "cos(theta),sin(theta),theta_dot,x,x_dot" --degree 3
  lsindy library --coords theta1,theta2 --candidates "theta1_dot**2,cos(theta1),cos(theta1 - theta2)"
"""


def run(args) -> int:
    lib = library(args)
    width = len(str(len(lib) - 1))
    for j, name in enumerate(lib.names):
        print(f"{j:>{width}}  {name}")
    how = ("explicit candidates" if args.candidates is not None
           else f"degree {2 if args.degree is None else args.degree}")
    print(f"{len(lib)} terms ({len(lib.coords.names)} coordinates, {how})")
    return 0


def add_to(sub) -> None:
    """Add the subcommand to the ``lsindy`` parser's subparsers."""
    libp = command(sub, "library", "list the candidate terms of a library and their count",
                   "Build the polynomial library that lsindy identify would "
                          "build from the same --coords, --features and --degree (or "
                          "--candidates), and list its terms "
                          "(index and sympy name) and their count.",
                   LIBRARY_EXAMPLE)
    library_arguments(libp)
    libp.set_defaults(func=run)
