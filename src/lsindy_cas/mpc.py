"""Public home of the swing-up controller (``from lsindy_cas.mpc import SwingUpMPC``); the code
lives in :mod:`lsindy_cas.control`."""
from .control.cart_pendulum import SwingUpMPC, find_upright
from .control.mpc import DiscreteInputMPC, MPCStats

__all__ = ["DiscreteInputMPC", "MPCStats", "SwingUpMPC", "find_upright"]
