"""``lsindy simulate``: integrate a saved model's equations of motion to a trajectory file."""
from __future__ import annotations

import sys

from ._common import command, numbers, split

SIMULATE_EXAMPLE = """examples:
  lsindy simulate model.json --x0 "0,pi/4,0,0" --t-end 5 --out sim.csv
  lsindy simulate model.json --x0 "0,pi/4,0,0" --t-end 1 --u "x=1.0" --dt 0.005 --out pushed.csv
  lsindy simulate model.json --x0 "0,pi/4,0,0" --u-file recorded.csv --out replay.csv"""


def _forces(text: str, coords: list, actuated: list) -> list:
    """Constant generalized forces from ``--u``: one number, n numbers, or ``name=value`` pairs."""
    import numpy as np
    n = len(coords)
    parts = split(text)
    if parts and all("=" in p for p in parts):
        Q = np.zeros(n)
        for p in parts:
            name, value = (s.strip() for s in p.split("=", 1))
            name = name[2:] if name.startswith("Q_") else name
            if name not in coords:
                raise ValueError(f"--u: {name!r} is not a coordinate of the model ({', '.join(coords)})")
            Q[coords.index(name)] = numbers(value, f"--u {name}")[0]
        return list(Q)
    values = numbers(text, "--u")
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

    from ..data.trajectory import read_columns
    from pathlib import Path

    if not Path(path).is_file():
        raise ValueError(f"--u-file {path}: no such file")
    cols = read_columns(Path(path))
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


def run(args) -> int:
    import numpy as np
    from pathlib import Path

    from .._io import check_writable
    from ..data.trajectory import Trajectory
    from ..identify.estimator import LagrangianSINDy
    from ..mechanics.euler_lagrange import simulate_ode

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
    x0 = numbers(args.x0, "--x0")
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


def add_to(sub) -> None:
    """Add the subcommand to the ``lsindy`` parser's subparsers."""
    sim = command(sub, "simulate", "integrate a saved model's equations of motion to CSV",
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
    sim.set_defaults(func=run)
