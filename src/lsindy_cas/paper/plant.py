"""The true plant of the swing-up experiment: a mechanical system integrated under zero-order hold.

:class:`Plant` integrates a system's exact equations of motion with CVODES while the input is held
constant over each control period.  :func:`mismatched_cart_pendulum` and :func:`scenario_plant`
give the plants of the swing-up scenarios (the true cart-pendulum, or one whose cart mass, pole
mass and pole length are off by 10 %).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

#: the swing-up experiment's scenarios: the true plant, ±10 % parameter mismatch, measurement noise
SCENARIOS = ("nominal", "mismatch", "noise")

__all__ = ["Plant", "mismatched_cart_pendulum", "scenario_plant"]


class Plant:
    """A mechanical system integrated under a zero-order-hold input, for closed-loop runs.

    Parameters
    ----------
    system : MechanicalSystem
        The true plant (``ode()``, ``coords``, ``actuated``).
    dt : float
        Control period (s): the input is held constant over each period.
    n_out : int
        States returned per period (at ``dt / n_out`` spacing) so that constraints are
        checked between control instants too.
    tol : float
        CVODES absolute and relative tolerance.
    """

    def __init__(self, system, dt, n_out=5, tol=1e-10):
        self.coords = list(system.coords)
        self.dt, self.n_out = float(dt), int(n_out)
        n = len(self.coords)
        self.input_index = self.coords.index(system.actuated)
        x, u = ca.SX.sym("x", 2 * n), ca.SX.sym("u", n)
        grid = np.linspace(0.0, self.dt, self.n_out + 1)[1:]
        self._integrator = ca.integrator("plant", "cvodes",
                                         {"x": x, "p": u, "ode": system.ode()(x, u)}, 0.0, grid,
                                         {"abstol": tol, "reltol": tol})
        self._u = np.zeros(n)

    def step(self, x, force):
        """States over one period from ``x`` under ``force``: shape (n_out, 2n), last = end."""
        self._u[self.input_index] = force
        return np.asarray(self._integrator(x0=x, p=self._u)["xf"]).T


def mismatched_cart_pendulum(factors):
    """The true cart-pendulum with its cart mass, pole mass and pole length times ``factors``."""
    from . import systems
    p = systems.cart_pendulum().params
    return systems.cart_pendulum(mc=p["mc"] * factors[0], mp=p["mp"] * factors[1],
                                 L=p["L"] * factors[2])


def scenario_plant(name, rng, dt):
    """The true plant of one episode of scenario ``name`` and its parameter factors (or None).

    ``mismatch`` draws the sign of a 10 % error in cart mass, pole mass and pole length from
    ``rng`` (three draws per episode); the other scenarios use the true cart-pendulum.
    """
    from . import systems
    if name == "mismatch":
        f = 1.0 + 0.1 * rng.choice([-1.0, 1.0], size=3)
        return Plant(mismatched_cart_pendulum(f), dt), f.tolist()
    return Plant(systems.cart_pendulum(), dt), None
