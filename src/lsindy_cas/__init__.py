"""lsindy_cas — Lagrangian-SINDy on CasADi.

Discover a mechanical system's total energy, Lagrangian and equations of motion from trajectory
data (Chu & Hayashibe, IEEE RA-L 2020), then use the equations, e.g. in model-predictive control.

The sub-packages are the pipeline, in order (``docs/architecture.md`` is the map):
``symbolic`` (coordinates, candidate library) → ``data`` (trajectories, smoothing) → ``identify``
(energy balance, support search, selection, the estimator) → ``mechanics`` (Legendre transform,
Euler–Lagrange equations) → ``control`` (MPC with discrete inputs); ``paper`` holds the paper's
benchmark systems and experiments.  The public names below are imported on first use, so that
``import lsindy_cas`` (and the command line) stays cheap.
"""
from ._version import __version__

__all__ = ["Library", "LagrangianSINDy", "Trajectory", "load_trajectories", "systems", "__version__"]

_LAZY = {
    "Library": ("lsindy_cas.symbolic.library", "Library"),
    "LagrangianSINDy": ("lsindy_cas.identify.estimator", "LagrangianSINDy"),
    "Trajectory": ("lsindy_cas.data.trajectory", "Trajectory"),
    "load_trajectories": ("lsindy_cas.data.trajectory", "load_trajectories"),
    "systems": ("lsindy_cas.paper.systems", None),
}


def __getattr__(name):
    if name not in _LAZY:
        raise AttributeError(f"module 'lsindy_cas' has no attribute {name!r}")
    import importlib

    module, attr = _LAZY[name]
    value = importlib.import_module(module)
    value = value if attr is None else getattr(value, attr)
    globals()[name] = value
    return value


def __dir__():
    return sorted(list(globals()) + list(_LAZY))
