"""The ``lsindy`` command: identify, reproduce, swingup."""
from __future__ import annotations

import argparse
import json
import sys

__all__ = ["main"]

IDENTIFY_EXAMPLE = """example:
  lsindy identify run1.csv run2.csv --coords x,theta \\
      --features "cos(theta),sin(theta),theta_dot,x,x_dot" --degree 3 \\
      --terms 4 --prior "theta_dot**2,cos(theta)" --json model.json

Trajectory files: CSV (header row) or NPZ with columns t, <q>, <q>_dot, optional Q_<q>
(generalized force; missing = 0) and optional <q>_ddot (exact accelerations)."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit code 2)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def _split(text: str | None) -> list:
    from .library import _split_top_level
    return _split_top_level(text) if text else []


def _identify(args) -> int:
    from .data import load_trajectories
    from .library import Library
    from .model import LagrangianSINDy

    coords = _split(args.coords)
    lib = Library.polynomial(coords, _split(args.features), args.degree)
    trajs = load_trajectories(args.trajectories, coords)
    scale = load_trajectories(args.scale, coords) if args.scale else None
    if args.passive and scale is None:
        raise ValueError("--passive needs --scale TRAJ... (a short actuated record, paper eq. 8)")
    model = LagrangianSINDy(lib, n_terms=args.terms, prior=_split(args.prior), form=args.form)
    model.fit(trajs, scale, passive=True if args.passive else None)
    print(model)
    if args.json:
        model.save(args.json)
        print(f"model written to {args.json}")
    return 0


def _reproduce(args) -> int:
    from pathlib import Path

    from .reproduce import markdown, table_one, write_table
    cells = table_one(progress=lambda msg: print(msg, file=sys.stderr))
    print(markdown(cells))
    md, js = write_table(cells, Path(args.out))
    print(f"\nTable I written to {md} and {js}")
    return 0 if all(c.exact_support and c.lagrangian_exact_support for c in cells) else 1


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="lsindy", description="Lagrangian-SINDy: identify energy, Lagrangian and "
                "equations of motion from trajectory data; control with them.",
                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    ident = sub.add_parser("identify", help="identify H, L and the equations of motion from files",
                           epilog=IDENTIFY_EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    ident.add_argument("trajectories", nargs="+", metavar="TRAJ", help="trajectory files (CSV/NPZ)")
    ident.add_argument("--coords", required=True, help="coordinate names, comma-separated (x,theta)")
    ident.add_argument("--features", required=True,
                       help='feature expressions, comma-separated ("cos(theta),theta_dot,x_dot")')
    ident.add_argument("--degree", type=int, default=2, help="highest product degree (default 2)")
    ident.add_argument("--terms", type=int, required=True, help="number of terms k in the energy")
    ident.add_argument("--prior", default="", help='terms forced in ("theta_dot**2,cos(theta)")')
    ident.add_argument("--passive", action="store_true",
                       help="the training data are unforced: use the null-space scheme")
    ident.add_argument("--scale", nargs="+", metavar="TRAJ", help="short actuated record(s) for the scale")
    ident.add_argument("--form", choices=["auto", "derivative", "integral"], default="auto",
                       help="energy-balance form (auto: derivative if files carry <q>_ddot)")
    ident.add_argument("--json", metavar="OUT.json", help="write the model file here")
    ident.set_defaults(func=_identify)

    rep = sub.add_parser("reproduce", help="the paper's Table I (and figures), printed and saved",
                         epilog="example:\n  lsindy reproduce --out results",
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    rep.add_argument("--out", default="results", help="output directory (default: results)")
    rep.set_defaults(func=_reproduce)

    try:
        from .swingup import add_swingup_arguments, run_from_args
    except ImportError:  # the MPC part is optional while it is being built
        pass
    else:
        sw = sub.add_parser("swingup", help="identify the cart-pendulum and swing it up by MPC",
                            formatter_class=argparse.RawDescriptionHelpFormatter)
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
    except KeyboardInterrupt:
        print(f"lsindy {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
