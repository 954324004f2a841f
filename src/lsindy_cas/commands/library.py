"""``lsindy library``: list the candidate terms of a library."""
from __future__ import annotations

from ._common import command, library, library_arguments

LIBRARY_EXAMPLE = """example:
  lsindy library --coords x,theta --features "cos(theta),sin(theta),theta_dot,x,x_dot" --degree 3"""


def run(args) -> int:
    lib = library(args)
    width = len(str(len(lib) - 1))
    for j, name in enumerate(lib.names):
        print(f"{j:>{width}}  {name}")
    print(f"{len(lib)} terms ({len(lib.coords.names)} coordinates, degree {args.degree})")
    return 0


def add_to(sub) -> None:
    """Add the subcommand to the ``lsindy`` parser's subparsers."""
    libp = command(sub, "library", "list the candidate terms of a library and their count",
                   "Build the polynomial library that lsindy identify would "
                          "build from the same --coords, --features and --degree, and list its terms "
                          "(index and sympy name) and their count.",
                   LIBRARY_EXAMPLE)
    library_arguments(libp)
    libp.set_defaults(func=run)
