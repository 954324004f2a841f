"""``lsindy export``: a saved model's ODE and RK4 step as C code."""
from __future__ import annotations

import sys

from ._common import command

EXPORT_EXAMPLE = """example:
  mkdir -p model_c && lsindy export model.json --c model_c --dt 0.05
  gcc -O2 -c model_c/lsindy_model.c -o model_c/lsindy_model.o"""


def run(args) -> int:
    from ..export import export_c
    from ..identify.estimator import LagrangianSINDy

    if not args.dt > 0 or args.dt != args.dt or args.dt == float("inf"):
        raise ValueError(f"--dt must be a positive number of seconds, got {args.dt}")
    if args.substeps < 1:
        raise ValueError(f"--substeps must be a positive integer, got {args.substeps}")
    from .._io import existing_dir
    from .._validate import relative_energy
    folder = existing_dir(args.c, "--c")       # checked before the model is read
    model = LagrangianSINDy.load(args.model)
    paths = export_c(model, folder, dt=args.dt, n_substeps=args.substeps, name=args.name,
                     source=str(args.model))
    print("written: " + ", ".join(str(p) for p in paths))
    if relative_energy(model):
        print("note: the energy is relative (passive data without --scale): the response to u "
              "is scaled by an unknown factor (README.md)", file=sys.stderr)
    return 0


def add_to(sub) -> None:
    """Add the subcommand to the ``lsindy`` parser's subparsers."""
    exp = command(sub, "export", "write a saved model's ODE and RK4 step as C code",
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
    exp.set_defaults(func=run)
