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
  lsindy simulate model.json --x0 "0,pi/4,0,0" --t-end 1 --u "x=1.0" --dt 0.005 --out pushed.csv
  lsindy simulate model.json --x0 "0,pi/4,0,0" --u-file recorded.csv --out replay.csv"""

EXPORT_EXAMPLE = """example:
  mkdir -p model_c && lsindy export model.json --c model_c --dt 0.05
  gcc -O2 -c model_c/lsindy_model.c -o model_c/lsindy_model.o"""

LIBRARY_EXAMPLE = """example:
  lsindy library --coords x,theta --features "cos(theta),sin(theta),theta_dot,x,x_dot" --degree 3"""

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


def _library(args):
    from .symbolic.library import Library
    return Library.polynomial(_split(args.coords), _split(args.features), args.degree)


def _identify(args) -> int:
    import numpy as np

    from ._io import check_writable
    from .data.trajectory import load_trajectories
    from .identify.estimator import LagrangianSINDy

    # Every option is checked before the data are read or the search starts.
    for flag, value in (("--terms", args.terms), ("--max-terms", args.max_terms),
                        ("--window", args.window)):
        if value is not None and value < 1:
            raise ValueError(f"{flag} must be a positive integer, got {value}")
    if args.json:
        check_writable(args.json, "--json")
    lib = _library(args)
    coords = lib.coords.names
    for flag, value in (("--terms", args.terms), ("--max-terms", args.max_terms)):
        if value is not None and value > len(lib):
            raise ValueError(f"{flag} {value} is larger than the library size ({len(lib)} terms)")
    trajs = load_trajectories(args.trajectories, coords)
    scale = load_trajectories(args.scale, coords) if args.scale else None
    passive = args.passive or all(not np.any(tr.power) for tr in trajs)
    if passive and scale is None:
        raise ValueError("the training data are passive (no power fed in), which fixes the energy "
                         "only up to a factor: add --scale TRAJ..., a short actuated record "
                         "(paper eq. 8)")
    model = LagrangianSINDy(lib, n_terms=args.terms, prior=_split(args.prior), form=args.form,
                            window=args.window, smoothing=args.smoothing,
                            max_terms=args.max_terms, hold=args.hold)
    from .progress import ProgressBar
    with ProgressBar("searching supports", unit="supports") as bar:
        model.fit(trajs, scale, passive=True if args.passive else None, progress=bar)
    print(model)
    print()
    print(model.diagnostics_)
    if args.json:
        model.save(args.json)
        print(f"model written to {args.json}")
    return 0


def _list_library(args) -> int:
    lib = _library(args)
    width = len(str(len(lib) - 1))
    for j, name in enumerate(lib.names):
        print(f"{j:>{width}}  {name}")
    print(f"{len(lib)} terms ({len(lib.coords.names)} coordinates, degree {args.degree})")
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


def _input_file(path: str, coords: list):
    """Times and held forces (n_samples, n) of a recorded input (``t`` and ``Q_<q>`` columns)."""
    import numpy as np

    from .data.trajectory import _read_columns
    from pathlib import Path

    if not Path(path).is_file():
        raise ValueError(f"--u-file {path}: no such file")
    cols = _read_columns(Path(path))
    if "t" not in cols:
        raise ValueError(f"--u-file {path}: missing column 't'")
    names = [f"Q_{c}" for c in coords]
    unknown = [k for k in cols if k.startswith("Q_") and k not in names]
    if unknown:
        raise ValueError(f"--u-file {path}: {', '.join(unknown)} name no coordinate of the model "
                         f"({', '.join(coords)})")
    if not any(n in cols for n in names):
        raise ValueError(f"--u-file {path}: no force column ({', '.join(names)})")
    t = np.asarray(cols["t"], float)
    if t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError(f"--u-file {path}: 't' must be strictly increasing, with 2 or more samples")
    Q = np.column_stack([cols.get(n, np.zeros_like(t)) for n in names]).astype(float)
    if not np.all(np.isfinite(Q)):
        raise ValueError(f"--u-file {path}: forces contain NaN or inf")
    return t, Q


def _simulate(args) -> int:
    import numpy as np
    from pathlib import Path

    from ._io import check_writable
    from .data.trajectory import Trajectory
    from .identify.estimator import LagrangianSINDy
    from .mechanics.euler_lagrange import simulate_ode

    if Path(args.out).suffix.lower() not in (".csv", ".npz"):
        raise ValueError(f"--out {args.out}: use a .csv or .npz file name")
    check_writable(args.out, "--out")
    if args.u and args.u_file:
        raise ValueError("give either --u (constant forces) or --u-file (a recorded input), not both")
    if args.u_file and (args.t_end is not None or args.dt is not None):
        raise ValueError("--u-file sets the sample times; leave out --t-end and --dt")
    if not args.u_file and args.t_end is None:
        raise ValueError("--t-end is required (or --u-file, whose times are used)")
    if args.max_samples < 1:
        raise ValueError(f"--max-samples must be a positive integer, got {args.max_samples}")
    model = LagrangianSINDy.load(args.model)
    coords = list(model.coords_)
    n = len(coords)
    x0 = _numbers(args.x0, "--x0")
    if len(x0) != 2 * n:
        raise ValueError(f"--x0 needs {2 * n} numbers [{', '.join(coords + [c + '_dot' for c in coords])}], "
                         f"got {len(x0)}")
    if args.u_file:
        t, U_rec = _input_file(args.u_file, coords)
        t = t - t[0]

        def Q(ti, _x):                   # the sample at t_i acts over [t_i, t_{i+1}) (held input)
            return U_rec[min(np.searchsorted(t, ti, side="right") - 1, len(t) - 1)]
    else:
        dt = 0.01 if args.dt is None else args.dt
        if not args.t_end > 0 or not dt > 0 or not np.isfinite(args.t_end) or not np.isfinite(dt):
            raise ValueError(f"--t-end and --dt must be positive, got {args.t_end} and {dt}")
        if dt > args.t_end:
            raise ValueError(f"--dt ({dt}) is longer than --t-end ({args.t_end})")
        n_samples = args.t_end / dt + 1
        if n_samples > args.max_samples:
            raise ValueError(f"--t-end {args.t_end:g} at --dt {dt:g} is {n_samples:.3g} samples, "
                             f"above the limit of {args.max_samples:,}; raise it with --max-samples "
                             f"if you mean it")
        Q = _forces(args.u, coords, list(getattr(model, "actuated_", []))) if args.u else [0.0] * n
        Q = np.asarray(Q)
        t = np.arange(int(round(args.t_end / dt)) + 1) * dt
    if len(t) > args.max_samples:
        raise ValueError(f"--u-file has {len(t):,} samples, above the limit of "
                         f"{args.max_samples:,}; raise it with --max-samples if you mean it")
    try:
        X, Xdot, U = simulate_ode(model.ode(), x0, t, Q, n)
    except RuntimeError as exc:
        print(f"lsindy simulate: {exc}", file=sys.stderr)
        return 1
    traj = Trajectory(t, X[:, :n], X[:, n:], coords, Q=U, qdd=Xdot[:, n:],
                      source=f"simulation of {args.model}")
    path = traj.save(args.out)
    print(f"{len(t)} samples (t = 0 to {t[-1]:g} s) written to {path}")
    return 0


def _export(args) -> int:
    from .export import export_c
    from .identify.estimator import LagrangianSINDy

    if not args.dt > 0 or args.dt != args.dt or args.dt == float("inf"):
        raise ValueError(f"--dt must be a positive number of seconds, got {args.dt}")
    if args.substeps < 1:
        raise ValueError(f"--substeps must be a positive integer, got {args.substeps}")
    from ._io import existing_dir
    folder = existing_dir(args.c, "--c")       # checked before the model is read
    model = LagrangianSINDy.load(args.model)
    paths = export_c(model, folder, dt=args.dt, n_substeps=args.substeps, name=args.name,
                     source=str(args.model))
    print("written: " + ", ".join(str(p) for p in paths))
    return 0


def _command(sub, name: str, help: str, description: str, epilog: str):
    """A subcommand with its one-line help, a described purpose and examples."""
    return sub.add_parser(name, help=help, description=_wrap(description), epilog=epilog,
                          formatter_class=argparse.RawDescriptionHelpFormatter)


def _library_arguments(parser):
    parser.add_argument("--coords", required=True, help="coordinate names, comma-separated (x,theta)")
    parser.add_argument("--features", required=True,
                        help='feature expressions, comma-separated ("cos(theta),theta_dot,x_dot")')
    parser.add_argument("--degree", type=int, default=2, help="highest product degree (default 2)")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="lsindy", description=_wrap("Lagrangian-SINDy: identify energy, Lagrangian and "
                "equations of motion from trajectory data; control with them."),
                epilog=MAIN_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    from ._version import __version__
    p.add_argument("--version", action="version", version=f"lsindy_cas {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    ident = _command(sub, "identify", "identify H, L and the equations of motion from files",
                   "Identify the total energy H, the Lagrangian L and the "
                           "equations of motion of a mechanical system from trajectory files, print "
                           "them with a diagnostics report and optionally save the model (JSON).",
                   IDENTIFY_EXAMPLE)
    ident.add_argument("trajectories", nargs="+", metavar="TRAJ", help="trajectory files (CSV/NPZ)")
    _library_arguments(ident)
    ident.add_argument("--terms", type=int, default=None,
                       help="number of terms k in the energy (default: chosen from the data on "
                       "held-out runs or stretches)")
    ident.add_argument("--prior", default="", help='terms forced in ("theta_dot**2,cos(theta)")')
    ident.add_argument("--passive", action="store_true",
                       help="the training data are unforced: use the null-space scheme")
    ident.add_argument("--scale", nargs="+", metavar="TRAJ", help="short actuated record(s) for the scale")
    ident.add_argument("--form", choices=["auto", "derivative", "integral"], default="auto",
                       help="energy-balance form (auto: derivative if files carry <q>_ddot)")
    ident.add_argument("--smoothing", choices=["auto", "none"], default="auto",
                       help="integral form: smooth the measured states with a strength chosen from "
                       "the data (auto, default) or use them as measured (none)")
    ident.add_argument("--hold", choices=["auto", "zoh", "smooth"], default="auto",
                       help="what a Q_<q> sample means: zoh = held over [t_i, t_i+1) (a digital "
                       "controller's output), smooth = a smoothly varying force sampled; auto "
                       "(default) decides from the data")
    ident.add_argument("--max-terms", type=int, default=None, metavar="K",
                       help="automatic k: the largest k tried")
    ident.add_argument("--window", type=int, default=None, metavar="N",
                       help="integral form: windows of N samples (default: every window of every run)")
    ident.add_argument("--json", metavar="OUT.json",
                       help="write the model file here (its folder must exist)")
    ident.set_defaults(func=_identify)

    libp = _command(sub, "library", "list the candidate terms of a library and their count",
                   "Build the polynomial library that lsindy identify would "
                          "build from the same --coords, --features and --degree, and list its terms "
                          "(index and sympy name) and their count.",
                   LIBRARY_EXAMPLE)
    _library_arguments(libp)
    libp.set_defaults(func=_list_library)

    rep = _command(sub, "reproduce", "the paper's Table I and Figs. 3-4, printed and saved",
                   "Identify the three benchmark systems as in the paper "
                         "(Table I), compare with SINDy (Lasso, via pysindy) and KRONIC (Fig. 3: model "
                         "complexity; Fig. 4: extrapolation), print the numbers and write tables "
                         "and PNG figures.",
                   REPRODUCE_EXAMPLE)
    rep.add_argument("--out", default="results", help="output directory (default: results)")
    rep.add_argument("--no-figures", action="store_true",
                     help="only Table I (skip the baselines and figures, which need pysindy)")
    rep.set_defaults(func=_reproduce)

    sim = _command(sub, "simulate", "integrate a saved model's equations of motion to CSV",
                   "Integrate the equations of motion of a saved model "
                         "(lsindy identify --json) from an initial state, under constant "
                         "generalized forces, and write a trajectory file (t, <q>, <q>_dot, Q_<q>, "
                         "<q>_ddot) that lsindy identify can read back.",
                   SIMULATE_EXAMPLE)
    sim.add_argument("model", metavar="MODEL.json", help="saved model file")
    sim.add_argument("--x0", required=True,
                     help="initial state [q, q_dot], comma-separated; sympy syntax allowed "
                     '("0,pi/4,0,0"); start with --x0= if the first entry is negative')
    sim.add_argument("--t-end", type=float, default=None, help="duration in seconds")
    sim.add_argument("--dt", type=float, default=None, help="sampling period in seconds (default 0.01)")
    sim.add_argument("--u", default=None,
                     help="constant generalized force(s): one number (on the model's actuated "
                     'coordinate), one per coordinate, or name=value pairs ("x=1.0"); default 0')
    sim.add_argument("--u-file", default=None, metavar="FILE",
                     help="replay a recorded input: a trajectory-format file (CSV/NPZ) with 't' and "
                     "'Q_<q>' columns; each sample is held until the next (zero-order hold), and "
                     "its times are the output's")
    sim.add_argument("--max-samples", type=int, default=1_000_000, metavar="N",
                     help="refuse to simulate more than N samples (default 1,000,000)")
    sim.add_argument("--out", required=True, metavar="OUT.csv",
                     help="output trajectory (.csv or .npz; its folder must exist)")
    sim.set_defaults(func=_simulate)

    exp = _command(sub, "export", "write a saved model's ODE and RK4 step as C code",
                   "Generate C code (CasADi) for a saved model's equations "
                         "of motion, (x, u) -> x_dot, and for one integrator step at --dt (the "
                         "MPC's RK4 map), with a header and a README of the calling convention.",
                   EXPORT_EXAMPLE)
    exp.add_argument("model", metavar="MODEL.json", help="saved model file")
    exp.add_argument("--c", required=True, metavar="DIR", help="existing folder for the C files")
    exp.add_argument("--dt", type=float, default=0.05, help="step length in seconds (default 0.05)")
    exp.add_argument("--substeps", type=int, default=1, help="RK4 steps per --dt (default 1)")
    exp.add_argument("--name", default="lsindy_model",
                     help="file base name and C prefix (default lsindy_model)")
    exp.set_defaults(func=_export)

    from .paper.swingup_cli import add_swingup_arguments, run_from_args
    sw = _command(sub, "swingup", "identify the cart-pendulum and swing it up by MPC",
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
    except KeyboardInterrupt:
        print(f"lsindy {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
