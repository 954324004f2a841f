"""The ``lsindy swingup`` options: parse them, check every one, then run the experiment.

:func:`run_from_args` checks all options *before* any work (identification takes seconds, a run
minutes), so a typo such as ``--solver foo`` fails at once with a sentence naming the option.
Nothing heavy is imported here until :func:`run_from_args` runs, so building the ``lsindy``
parser stays fast.
"""

from __future__ import annotations

import sys
from pathlib import Path

from .._validate import check_choice, check_int, check_real, relative_energy

__all__ = ["add_swingup_arguments", "plant_note", "run_from_args"]


def plant_note(model, tol=0.05):
    """One line for stderr when ``model`` is not a model of the plant ``lsindy swingup``
    simulates (the paper's cart-pendulum): its accelerations more than ``tol`` off (relative,
    over 20 fixed random states and forces of +-10 N); None otherwise.  The model's coordinates
    must be the plant's, ``x`` and ``theta`` in any order (checked by :func:`run_from_args`)."""
    import numpy as np

    from .systems import cart_pendulum

    plant = cart_pendulum()
    p = plant.params
    what = (f"note: the simulated plant is the paper's cart-pendulum (m_c {p['mc']} kg, "
            f"m_p {p['mp']} kg, L {p['L']} m); ")
    rng = np.random.default_rng(0)
    states = rng.uniform([-1.0, -np.pi, -2.0, -3.0], [1.0, np.pi, 2.0, 3.0], size=(20, 4))
    forces = rng.choice([-10.0, 10.0], size=20)
    coords = list(getattr(model, "coords_", None) or getattr(model, "coords", None))
    order = [plant.coords.index(c) for c in coords]
    order += [2 + i for i in order]                  # the model's state in the plant's order
    f, g = model.ode(), plant.ode()
    diff = ref = 0.0
    for x, u in zip(states, forces):
        push = np.zeros(2)
        push[coords.index("x")] = u
        a = np.empty(4)
        a[order] = np.asarray(f(x[order], push), dtype=float).ravel()
        b = np.asarray(g(x, [u, 0.0]), dtype=float).ravel()
        diff, ref = diff + np.sum((a - b) ** 2), ref + np.sum(b ** 2)
    off = float(np.sqrt(diff / ref))
    if off > tol:
        return what + (f"this model's accelerations differ from it by {100 * off:.0f} %, so the "
                       "episodes test the controller against a plant it does not describe")
    return None


def add_swingup_arguments(parser):
    """Add the ``lsindy swingup`` options to an ``argparse`` parser."""
    parser.add_argument("--model", metavar="MODEL.json",
                        help="saved model (lsindy identify --json); identified afresh if omitted")
    parser.add_argument("--episodes", type=int, default=20, help="random starts (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--scenarios", default=None,
                        help="comma-separated subset of nominal,mismatch,noise (default all)")
    parser.add_argument("--solver", default=None,
                        help="sqp (default), sqp-gn, fatrop or ipopt (warm-started steps)")
    parser.add_argument("--rounding", default=None,
                        help="how the applied force is chosen: lookahead (default), sur or nearest")
    parser.add_argument("--balance", choices=("on", "off"), default=None,
                        help="balancer near the upright (default on: pulse balancer, or the sequence balancer when one push changes the identified pole rate by >= 0.6 rad/s)")
    parser.add_argument("--inexact-tol", type=float, default=None, metavar="TOL",
                        help="largest constraint violation of an iteration-capped solve that is "
                             "still applied (default 1e-6)")
    jit = parser.add_mutually_exclusive_group()
    jit.add_argument("--jit", dest="jit", action="store_const", const=True, default=None,
                     help="compile the controller's NLP derivatives with gcc (the default where "
                          "gcc is on the PATH and $LSINDY_JIT is not 0; an error without gcc): "
                          "5-16 s the first time for a model (two NLPs), cached in "
                          "$LSINDY_CACHE_DIR; step p99 about 30 % shorter")
    jit.add_argument("--no-jit", dest="jit", action="store_const", const=False,
                     help="run the controller's NLP uncompiled (CasADi's virtual machine)")
    parser.add_argument("--json", metavar="OUT.json", help="write the metrics as JSON")
    parser.add_argument("--out", metavar="DIR", help="write the Fig. 5 analogue (PNG) here")
    return parser


def _scenarios(text):
    """``"nominal, noise"`` -> ``["nominal", "noise"]``, each checked; ``None``: all scenarios."""
    from .plant import SCENARIOS

    if text is None:
        return list(SCENARIOS)
    names = [s.strip() for s in text.split(",") if s.strip()]
    if not names:
        raise ValueError(f"--scenarios must name at least one of {', '.join(SCENARIOS)}")
    unknown = [s for s in names if s not in SCENARIOS]
    if unknown:
        raise ValueError(f"--scenarios: {', '.join(unknown)} unknown (choose from "
                         f"{', '.join(SCENARIOS)})")
    return names


def _controller_options(args):
    """The :class:`~lsindy_cas.mpc.SwingUpMPC` keyword arguments the options ask for, checked."""
    from ..control.compiled import resolve_jit
    from ..control.rounding import ROUNDINGS
    from ..control.shooting import SOLVERS

    opts = {}
    solver, rounding = getattr(args, "solver", None), getattr(args, "rounding", None)
    if solver:
        opts["solver"] = check_choice("--solver", solver, SOLVERS)
    if rounding:
        opts["rounding"] = check_choice("--rounding", rounding, ("lookahead", *ROUNDINGS))
    if getattr(args, "balance", None):
        opts["balance"] = args.balance == "on"
    tol = getattr(args, "inexact_tol", None)
    if tol is not None:
        opts["inexact_tol"] = check_real("--inexact-tol", tol, positive=True)
    jit = getattr(args, "jit", None)
    resolve_jit(jit)  # $LSINDY_JIT and the compiler checked before any heavy work
    if jit is not None:
        opts["jit"] = jit
    return opts


def _check_paths(args):
    """``--model`` must be a file; ``--json`` must not be a directory, ``--out`` not a file."""
    if args.model and not Path(args.model).is_file():
        raise ValueError(f"--model {args.model}: no such file")
    if args.json and Path(args.json).is_dir():
        raise ValueError(f"--json {args.json}: is a directory; give a file name")
    if args.out and Path(args.out).exists() and not Path(args.out).is_dir():
        raise ValueError(f"--out {args.out}: is a file; give a directory")


def run_from_args(args):
    """Check every option, then run :func:`~lsindy_cas.paper.swingup.run_swingup`.

    Returns
    -------
    int
        0 when every nominal episode succeeded (or none ran), 1 otherwise.

    Raises
    ------
    ValueError
        For a bad option, before the identification or any episode runs.
    """
    from . import swingup   # looked up at call time: the tests replace swingup.run_swingup

    check_int("--episodes", args.episodes, low=1)
    check_int("--seed", args.seed, low=0)
    scenarios = _scenarios(args.scenarios)
    opts = _controller_options(args)
    _check_paths(args)
    model = None
    if args.model:
        from ..identify.estimator import LagrangianSINDy

        model = LagrangianSINDy.load(args.model)
        if relative_energy(model):
            raise ValueError(f"--model {args.model}: the energy is relative (passive data "
                             "without --scale): the force's effect is unknown up to a factor; "
                             "identify with --scale TRAJ")
        coords = list(getattr(model, "coords_", None) or [])
        if sorted(coords) != ["theta", "x"]:
            raise ValueError(f"--model {args.model}: coordinates {coords}, but the simulated "
                             "plant's are ['x', 'theta'] (cart position, pole angle from hanging)")
        note = plant_note(model)
        if note:
            print(note, file=sys.stderr)
    report = swingup.run_swingup(model, episodes=args.episodes, seed=args.seed,
                                 scenarios=scenarios, out=args.out, json_path=args.json,
                                 controller_options=opts)
    if args.json:
        print(f"metrics written to {args.json}")
    for f in report.get("figures", []):
        print(f"figure written to {f}")
    nominal = report["scenarios"].get("nominal")
    return 0 if nominal is None or nominal["success_rate"] == 1.0 else 1
