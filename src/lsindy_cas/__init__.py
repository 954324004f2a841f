"""lsindy_cas — Lagrangian-SINDy on CasADi.

Discover a mechanical system's total energy, Lagrangian and equations of motion from trajectory
data (Chu & Hayashibe, IEEE RA-L 2020), then use the equations, e.g. in model-predictive control.
"""
__version__ = "0.1.0"

from . import systems  # noqa: E402
from .data import Trajectory, load_trajectories  # noqa: E402
from .library import Library  # noqa: E402
from .model import LagrangianSINDy  # noqa: E402

__all__ = ["Library", "LagrangianSINDy", "Trajectory", "load_trajectories", "systems", "__version__"]
