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


REPRODUCE_EXAMPLE = """example:
  lsindy reproduce --out results      # ~1 min: results/table1.md, fig3_complexity.png,
                                      # fig4_extrapolation.png, baselines.md (+ JSON)
Exit status 0 when every Table I model has the exact support and the figures show the paper's
claims (ours sparsest; our extrapolation error below SINDy's)."""

SIMULATE_EXAMPLE = """examples:
  lsindy simulate model.json --x0 "0,pi/4,0,0" --t-end 5 --out sim.csv
  lsindy simulate model.json --x0 "0,pi/4,0,0" --t-end 1 --u "x=1.0" --dt 0.005 --out pushed.csv"""

SWINGUP_EXAMPLE = """examples:
  lsindy swingup --episodes 5 --out results       # identify the cart-pendulum, then swing it up
  lsindy swingup --model model.json --json metrics.json"""

MAIN_EXAMPLES = """examples:
  lsindy reproduce --out results                  # the paper's Table I and Figs. 3-4
  lsindy identify run1.csv --coords x,theta \\
      --features "cos(theta),sin(theta),theta_dot,x,x_dot" --degree 3 \\
      --terms 4 --prior "theta_dot**2,cos(theta)" --json model.json
  lsindy simulate model.json --x0 "0,pi/4,0,0" --t-end 5 --out sim.csv
  lsindy swingup --model model.json --episodes 5  # MPC swing-up of the cart-pendulum

Run "lsindy COMMAND --help" for the options of a command."""


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit code 2)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def _wrap(text: str) -> str:
    import textwrap
    return textwrap.fill(text, 88)


def _split(text: str | None) -> list:
    from .symbolic.library import _split_top_level
    return _split_top_level(text) if text else []


def _identify(args) -> int:
    from .data.trajectory import load_trajectories
    from .symbolic.library import Library
    from .identify.estimator import LagrangianSINDy

    coords = _split(args.coords)
    lib = Library.polynomial(coords, _split(args.features), args.degree)
    trajs = load_trajectories(args.trajectories, coords)
    scale = load_trajectories(args.scale, coords) if args.scale else None
    if args.passive and scale is None:
        raise ValueError("--passive needs --scale TRAJ... (a short actuated record, paper eq. 8)")
    if args.terms is not None and args.terms < 1:
        raise ValueError(f"--terms must be a positive integer, got {args.terms}")
    model = LagrangianSINDy(lib, n_terms=args.terms, prior=_split(args.prior), form=args.form)
    from .progress import ProgressBar
    with ProgressBar("searching supports") as bar:
        model.fit(trajs, scale, passive=True if args.passive else None, progress=bar)
    print(model)
    print()
    print(model.diagnostics_)
    if args.json:
        model.save(args.json)
        print(f"model written to {args.json}")
    return 0


def _reproduce(args) -> int:
    from pathlib import Path

    from .paper.table1 import markdown, table_one, write_table
    say = lambda msg: print(msg, file=sys.stderr)  # noqa: E731
    cells = table_one(progress=say)
    print(markdown(cells))
    md, js = write_table(cells, Path(args.out))
    print(f"\nTable I written to {md} and {js}")
    ok = all(c.exact_support and c.lagrangian_exact_support for c in cells)
    if args.no_figures:
        return 0 if ok else 1
    from .paper.comparison import claims
    from .paper.figures import make_figures
    try:
        paths = make_figures(Path(args.out), cells=cells, progress=say,
                             echo=lambda text: print("\n" + text))
    except ImportError as exc:             # pysindy (the SINDy baseline) is an optional extra
        say(f"lsindy reproduce: figures skipped: {exc}")
        return 0 if ok else 1
    print("\nfigures and numbers written to " + ", ".join(str(p) for p in paths))
    failed = claims(json.loads(paths[-1].read_text()))
    for msg in failed:
        say(f"lsindy reproduce: claim not reproduced: {msg}")
    return 0 if ok and not failed else 1


def _numbers(text: str, what: str) -> list:
    """``"pi/2, 0, -1e-3"`` -> floats (sympy syntax per entry, so ``pi/2`` works)."""
    import sympy as sp
    out = []
    for part in _split(text):
        try:
            out.append(float(sp.sympify(part)))
        except (sp.SympifyError, SyntaxError, TypeError, ValueError):
            raise ValueError(f"{what}: {part!r} is not a number") from None
    if not out:
        raise ValueError(f"{what} is empty")
    return out


def _forces(text: str, coords: list, actuated: list) -> list:
    """Constant generalized forces from ``--u``: one number, n numbers, or ``name=value`` pairs."""
    import numpy as np
    n = len(coords)
    parts = _split(text)
    if parts and all("=" in p for p in parts):
        Q = np.zeros(n)
        for p in parts:
            name, value = (s.strip() for s in p.split("=", 1))
            name = name[2:] if name.startswith("Q_") else name
            if name not in coords:
                raise ValueError(f"--u: {name!r} is not a coordinate of the model ({', '.join(coords)})")
            Q[coords.index(name)] = _numbers(value, f"--u {name}")[0]
        return list(Q)
    values = _numbers(text, "--u")
    if len(values) == n:
        return values
    if len(values) == 1:
        if values[0] == 0:
            return [0.0] * n
        if len(actuated) == 1:
            Q = [0.0] * n
            Q[coords.index(actuated[0])] = values[0]
            return Q
        raise ValueError(f"--u: one number needs a model with exactly one actuated coordinate (this "
                         f"one has {actuated or 'none'}); give {n} numbers or name=value pairs")
    raise ValueError(f"--u: give 1 or {n} numbers (one per coordinate {', '.join(coords)}), "
                     f"got {len(values)}")


def _simulate(args) -> int:
    import numpy as np

    from .data.trajectory import Trajectory
    from .mechanics.euler_lagrange import simulate_ode
    from .identify.estimator import LagrangianSINDy

    from pathlib import Path
    if Path(args.out).suffix.lower() not in (".csv", ".npz"):
        raise ValueError(f"--out {args.out}: use a .csv or .npz file name")
    model = LagrangianSINDy.load(args.model)
    coords = list(model.coords_)
    n = len(coords)
    x0 = _numbers(args.x0, "--x0")
    if len(x0) != 2 * n:
        raise ValueError(f"--x0 needs {2 * n} numbers [{', '.join(coords + [c + '_dot' for c in coords])}], "
                         f"got {len(x0)}")
    if not args.t_end > 0 or not args.dt > 0:
        raise ValueError(f"--t-end and --dt must be positive, got {args.t_end} and {args.dt}")
    if args.dt > args.t_end:
        raise ValueError(f"--dt ({args.dt}) is longer than --t-end ({args.t_end})")
    Q = _forces(args.u, coords, list(getattr(model, "actuated_", []))) if args.u else [0.0] * n
    t = np.arange(int(round(args.t_end / args.dt)) + 1) * args.dt
    try:
        X, Xdot, U = simulate_ode(model.ode(), x0, t, np.asarray(Q), n)
    except RuntimeError as exc:
        print(f"lsindy simulate: {exc}", file=sys.stderr)
        return 1
    traj = Trajectory(t, X[:, :n], X[:, n:], coords, Q=U, qdd=Xdot[:, n:],
                      source=f"simulation of {args.model}")
    path = traj.save(args.out)
    print(f"{len(t)} samples (t = 0 to {t[-1]:g} s) written to {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="lsindy", description=_wrap("Lagrangian-SINDy: identify energy, Lagrangian and "
                "equations of motion from trajectory data; control with them."),
                epilog=MAIN_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    ident = sub.add_parser("identify", help="identify H, L and the equations of motion from files",
                           epilog=IDENTIFY_EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    ident.add_argument("trajectories", nargs="+", metavar="TRAJ", help="trajectory files (CSV/NPZ)")
    ident.add_argument("--coords", required=True, help="coordinate names, comma-separated (x,theta)")
    ident.add_argument("--features", required=True,
                       help='feature expressions, comma-separated ("cos(theta),theta_dot,x_dot")')
    ident.add_argument("--degree", type=int, default=2, help="highest product degree (default 2)")
    ident.add_argument("--terms", type=int, default=None,
                       help="number of terms k in the energy (default: chosen from the data on "
                       "held-out runs or stretches)")
    ident.add_argument("--prior", default="", help='terms forced in ("theta_dot**2,cos(theta)")')
    ident.add_argument("--passive", action="store_true",
                       help="the training data are unforced: use the null-space scheme")
    ident.add_argument("--scale", nargs="+", metavar="TRAJ", help="short actuated record(s) for the scale")
    ident.add_argument("--form", choices=["auto", "derivative", "integral"], default="auto",
                       help="energy-balance form (auto: derivative if files carry <q>_ddot)")
    ident.add_argument("--json", metavar="OUT.json", help="write the model file here")
    ident.set_defaults(func=_identify)

    rep = sub.add_parser("reproduce", help="the paper's Table I and Figs. 3-4, printed and saved",
                         description=_wrap("Identify the three benchmark systems as in the paper "
                         "(Table I), compare with SINDy (Lasso, via pysindy) and KRONIC (Fig. 3: model "
                         "complexity; Fig. 4: extrapolation), print the numbers and write tables "
                         "and PNG figures."),
                         epilog=REPRODUCE_EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    rep.add_argument("--out", default="results", help="output directory (default: results)")
    rep.add_argument("--no-figures", action="store_true",
                     help="only Table I (skip the baselines and figures, which need pysindy)")
    rep.set_defaults(func=_reproduce)

    sim = sub.add_parser("simulate", help="integrate a saved model's equations of motion to CSV",
                         description=_wrap("Integrate the equations of motion of a saved model "
                         "(lsindy identify --json) from an initial state, under constant "
                         "generalized forces, and write a trajectory file (t, <q>, <q>_dot, Q_<q>, "
                         "<q>_ddot) that lsindy identify can read back."),
                         epilog=SIMULATE_EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    sim.add_argument("model", metavar="MODEL.json", help="saved model file")
    sim.add_argument("--x0", required=True,
                     help="initial state [q, q_dot], comma-separated; sympy syntax allowed "
                     '("0,pi/4,0,0"); start with --x0= if the first entry is negative')
    sim.add_argument("--t-end", type=float, required=True, help="duration in seconds")
    sim.add_argument("--dt", type=float, default=0.01, help="sampling period in seconds (default 0.01)")
    sim.add_argument("--u", default=None,
                     help="constant generalized force(s): one number (on the model's actuated "
                     'coordinate), one per coordinate, or name=value pairs ("x=1.0"); default 0')
    sim.add_argument("--out", required=True, metavar="OUT.csv", help="output trajectory (.csv or .npz)")
    sim.set_defaults(func=_simulate)

    from .paper.swingup_cli import add_swingup_arguments, run_from_args
    sw = sub.add_parser("swingup", help="identify the cart-pendulum and swing it up by MPC",
                        epilog=SWINGUP_EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
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
