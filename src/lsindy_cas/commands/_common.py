"""What every ``lsindy`` subcommand shares: the parser class, subcommand set-up, list parsing."""
from __future__ import annotations

import argparse

__all__ = ["Parser", "command", "wrap", "split", "library", "library_arguments", "numbers"]


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit code 2)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def wrap(text: str) -> str:
    import textwrap
    return textwrap.fill(text, 88)


def split(text: str | None) -> list:
    from ..symbolic.library import split_top_level
    return split_top_level(text) if text else []


def library(args):
    """The candidate library of ``--candidates`` (explicit terms) or ``--features/--degree``."""
    from ..symbolic.library import Library
    if args.candidates is not None:
        if args.features is not None or args.degree is not None:
            raise ValueError("give either --candidates (an explicit term list) or "
                             "--features/--degree (a polynomial library), not both")
        terms = split(args.candidates)
        if not terms:
            raise ValueError("--candidates is empty; give comma-separated terms "
                             '("theta_dot**2,cos(theta)")')
        return Library(split(args.coords), [_candidate(t, i) for i, t in enumerate(terms)])
    if args.features is None:
        raise ValueError("give --features (with --degree) or --candidates")
    return Library.polynomial(split(args.coords), split(args.features),
                              2 if args.degree is None else args.degree)


def _candidate(term, i):
    """A --candidates entry as text, with its position for error messages."""
    if not term.strip():
        raise ValueError(f"--candidates: term #{i + 1} is empty")
    return term


def command(sub, name: str, help: str, description: str, epilog: str):
    """A subcommand with its one-line help, a described purpose and examples."""
    return sub.add_parser(name, help=help, description=wrap(description), epilog=epilog,
                          formatter_class=argparse.RawDescriptionHelpFormatter)


def library_arguments(parser):
    parser.add_argument("--coords", required=True, help="coordinate names, comma-separated (x,theta)")
    parser.add_argument("--features", default=None,
                        help='feature expressions, comma-separated ("cos(theta),theta_dot,x_dot"); '
                        "the library is their products up to --degree")
    parser.add_argument("--degree", type=int, default=None,
                        help="highest product degree (default 2)")
    parser.add_argument("--candidates", default=None, metavar="TERMS",
                        help="an explicit candidate list instead of --features/--degree: "
                        'comma-separated sympy terms ("theta1_dot**2,theta1_dot*theta2_dot*'
                        'cos(theta1 - theta2),cos(theta1)")')


def numbers(text: str, what: str) -> list:
    """``"pi/2, 0, -1e-3"`` -> floats (sympy syntax per entry, so ``pi/2`` works; plain numbers
    are read without importing sympy)."""
    out = []
    for part in split(text):
        try:
            out.append(float(part))
            continue
        except ValueError:
            pass
        import sympy as sp
        try:
            out.append(float(sp.sympify(part)))
        except (sp.SympifyError, SyntaxError, TypeError, ValueError):
            raise ValueError(f"{what}: {part!r} is not a number") from None
    if not out:
        raise ValueError(f"{what} is empty")
    return out
