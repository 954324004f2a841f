"""``lsindy identify``: trajectory files -> model printout and model file."""
from __future__ import annotations

import sys

from ._common import command, library, library_arguments, split

EXIT_UNDETERMINED = 3

IDENTIFY_EXAMPLE = """example:
  lsindy identify run1.csv run2.csv --coords x,theta \\
      --features "cos(theta),sin(theta),theta_dot,x,x_dot" --degree 3 \\
      --terms 4 --prior "theta_dot**2,cos(theta)" --json model.json

Trajectory files: CSV (header row) or NPZ with columns t, <q>, <q>_dot, optional Q_<q>
(generalized force; missing = 0) and optional <q>_ddot (exact accelerations).  t need not be
evenly spaced.  Positions only (no <q>_dot column at all): the velocities are estimated from the
positions and the report and model file say so.

exit codes:
  0  the model is determined by the data (status "ok")
  2  bad input (one line on stderr; nothing is fitted)
  3  the model is not determined by the data (status "undetermined"): one line on stderr
     with the reason; the printout and the --json file are still written, with the status
     (no admissible model at all: the one line only, nothing written)"""


def run(args) -> int:
    from .._io import check_writable
    from ..data.trajectory import load_trajectories
    from ..identify.estimator import LagrangianSINDy

    # Every option is checked before the data are read or the search starts.
    for flag, value in (("--terms", args.terms), ("--max-terms", args.max_terms),
                        ("--window", args.window)):
        if value is not None and value < 1:
            raise ValueError(f"{flag} must be a positive integer, got {value}")
    if args.time_limit is not None and not 0 < args.time_limit < float("inf"):   # and nan
        raise ValueError(f"--time-limit must be positive (seconds), got {args.time_limit}")
    if not 0 < args.effort < float("inf"):                                         # and nan
        raise ValueError(f"--effort must be a positive number, got {args.effort}")
    if args.json:
        check_writable(args.json, "--json")
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be a positive integer, got {args.workers}")
    if args.workers is not None and args.scheduler != "local":
        raise ValueError("--workers sets the size of a local cluster: use it with --scheduler local")
    lib = library(args)
    coords = lib.coords.names
    for flag, value in (("--terms", args.terms), ("--max-terms", args.max_terms)):
        if value is not None and value > len(lib):
            raise ValueError(f"{flag} {value} is larger than the library size ({len(lib)} terms)")
    dissipation = split(args.dissipation) or None
    if dissipation is not None:
        from ..identify.dissipation import dissipation_library
        dissipation_library(lib.coords, dissipation)        # bad terms: one line, before the data
        if args.window is not None:
            raise ValueError("--dissipation needs the all-windows integral form: drop --window")
    trajs = load_trajectories(args.trajectories, coords)
    scale = load_trajectories(args.scale, coords) if args.scale else None
    if args.refine:                 # asked for: uneven runs are bad input (without it, the
        from ..identify.refine import check_uniform     # automatic refinement skips them)
        check_uniform(trajs, "--refine")
    if args.form == "derivative" and any(tr.qdd is None for tr in trajs):
        raise ValueError("--form derivative needs accelerations (<q>_ddot columns) in every "
                         "trajectory file; use --form integral")
    client = None
    if args.scheduler:            # an unreachable address is one line on stderr, after a timeout
        from ..identify.distributed import connect
        try:
            client = connect(args.scheduler, args.workers)
        except ImportError as exc:
            raise ValueError(f"--scheduler: {exc}") from None
    model = LagrangianSINDy(lib, n_terms=args.terms, prior=split(args.prior), form=args.form,
                            window=args.window, smoothing=args.smoothing,
                            max_terms=args.max_terms, hold=args.hold, dissipation=dissipation,
                            time_limit=args.time_limit, effort=args.effort,
                            refinement=("always" if args.refine else "never" if args.no_refine
                                        else "auto"))
    from ..progress import ProgressBar
    from ..identify.selection import UndeterminedError
    try:
        with ProgressBar("searching supports", unit="supports") as bar:
            def notify(message):    # the refinement (seconds to a minute): said before it starts
                bar.close()
                print(message, file=sys.stderr, flush=True)
            model.fit(trajs, scale, passive=True if args.passive else None, progress=bar,
                      client=client, notify=notify)
    except UndeterminedError as exc:    # the search ran: the data, not the options, fall short
        msg = " ".join(str(exc).split())
        print(f"lsindy identify: the data do not determine the model: {msg}", file=sys.stderr)
        return EXIT_UNDETERMINED
    if client is not None:
        client.close()
    res = model.search_
    if res.method == "beam":        # automatic k: the one-term extensions of smaller models
        print("search not proven: support found among the one-term extensions of the best "
              "smaller models", file=sys.stderr)
    elif not res.proven:            # time limit or Ctrl-C in the branch and bound
        print(f"search not proven: best admissible support found in {res.seconds:.1f} s "
              f"({res.nodes:,} nodes), optimality gap {res.gap:.3g}", file=sys.stderr)
    rw = getattr(res, "reweighted", None)
    if rw is not None:              # proven on the unweighted balance, weighted re-check cut short
        print(f"search: support proven best on the unweighted balance; the noise-weighted "
              f"re-check found no better one in {rw['seconds']:.1f} s ({rw['nodes']:,} nodes, "
              "not proven)")
    print(model)
    if model.energy_scale_ == "relative":
        print("(no --scale record: add --scale TRAJ..., a short actuated run, for an absolute energy)")
    print()
    print(model.diagnostics_)
    if args.json:
        model.save(args.json)
        print(f"model written to {args.json}")
    if not model.ok_:
        hint = _refinement_hint(model, args)
        if hint:
            print(f"hint: {hint}")
        print(f"lsindy identify: the data do not determine the model: {model.status_reasons_[0]}",
              file=sys.stderr)
        return EXIT_UNDETERMINED
    return 0


def _refinement_hint(model, args) -> str | None:
    """What the user can learn about the prediction-error refinement of an undetermined fit."""
    info = getattr(model, "refinement_", None)
    if isinstance(info, dict) and info.get("auto") and not info.get("applied"):
        return ("the energy balance leaves a coefficient undetermined and the automatic "
                f"prediction-error refinement did not settle it: {info.get('outcome')}")
    if args.no_refine:
        from ..identify.status import open_coefficient
        if open_coefficient(model.status_, model.status_reasons_) is not None:
            # measured: benchmarks/results/noise_refined.md (the paper's run, sigma = 1e-3)
            return ("the energy balance leaves a coefficient undetermined; without --no-refine "
                    "the coefficients are then refined by prediction error and judged by its "
                    "own standard errors")
    return None


def add_to(sub) -> None:
    """Add the subcommand to the ``lsindy`` parser's subparsers."""
    ident = command(sub, "identify", "identify H, L and the equations of motion from files",
                   "Identify the total energy H, the Lagrangian L and the "
                           "equations of motion of a mechanical system from trajectory files, print "
                           "them with a diagnostics report and optionally save the model (JSON).",
                   IDENTIFY_EXAMPLE)
    ident.add_argument("trajectories", nargs="+", metavar="TRAJ", help="trajectory files (CSV/NPZ)")
    library_arguments(ident)
    ident.add_argument("--terms", type=int, default=None,
                       help="number of terms k in the energy (default: chosen from the data on "
                       "held-out runs or stretches)")
    ident.add_argument("--prior", default="", help='terms forced in ("theta_dot**2,cos(theta)")')
    ident.add_argument("--passive", action="store_true",
                       help="the training data are unforced: use the null-space scheme")
    ident.add_argument("--scale", nargs="+", metavar="TRAJ",
                       help="short actuated record(s) for the scale; without one, passive data "
                       "give the energy up to a constant factor (stated in the output)")
    ident.add_argument("--dissipation", default="", metavar="TERMS",
                       help='candidate terms of the Rayleigh dissipation function R over <q>_dot, '
                       'e.g. "theta_dot**2,Abs(x_dot)" (friction forces -dR/dq_dot; terms the '
                       "data do not support come out zero)")
    refine = ident.add_mutually_exclusive_group()
    refine.add_argument("--refine", action="store_true",
                        help="always refine the coefficients of H and R on the chosen support by "
                        "prediction error over the training runs (multiple shooting; evenly "
                        "sampled runs; the normalisation kept).  Default: only when the energy "
                        "balance leaves a coefficient open (its standard error too large), and "
                        "kept when the refined coefficients are determined")
    refine.add_argument("--no-refine", action="store_true",
                        help="the energy balance alone: no prediction-error refinement")
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
    ident.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="search the supports on a Dask cluster (exhaustive scoring or branch and "
                       "bound): 'local' (a LocalCluster on this machine) or a running scheduler's "
                       "address, tcp://host:8786 (needs the optional extra dask[distributed]; the "
                       "same answer as without)")
    ident.add_argument("--workers", type=int, default=None, metavar="N",
                       help="with --scheduler local: number of worker processes (default: cores)")
    ident.add_argument("--time-limit", type=float, default=None, metavar="SECONDS",
                       help="branch and bound (libraries too large to score every support): stop "
                       "each search after SECONDS with the best admissible support found, marked "
                       "not proven with its optimality gap (Ctrl-C does the same); with automatic "
                       "k, every search of the scan")
    ident.add_argument("--effort", type=float, default=1.0, metavar="X",
                       help="automatic k: X times the branch-and-bound work the scan may spend "
                       "(default 1; a fixed amount of work, the same on every machine); more "
                       "for a large library whose searches stop undecided")
    ident.add_argument("--json", metavar="OUT.json",
                       help="write the model file here (its folder must exist)")
    ident.set_defaults(func=run)
