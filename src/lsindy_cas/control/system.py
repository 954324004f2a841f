"""What a controller needs of a model, read once: :class:`ControlledSystem`.

Any object with the model's coordinate names (``coords_`` of a fitted model, ``coords`` of a
:class:`~lsindy_cas.paper.systems.MechanicalSystem`), an ``ode()`` ``(x, u=Q) -> xdot`` and its
energy ``H`` as sympy (``hamiltonian_`` / ``hamiltonian``) can be controlled.  From these:
the discrete map over one sample (RK4), the energy as a CasADi function, which coordinates are
angles (H is 2π-periodic in them), and the check that the kinetic part is positive definite.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from .._validate import relative_energy
from ..mechanics.rk4 import rk4_step

__all__ = ["ControlledSystem", "MAX_SUBSTEP"]

# RK4's local error is O(h^5): at h = 0.01 s it is ~1e-9 of a swing for pendulum time scales
# >= 0.3 s (every system here), far below the model's own error.
MAX_SUBSTEP = 0.01
# The swing-up search may take longer substeps: the fewest whose map is within SEARCH_TOL of the
# fine one (relative to the sample's largest change of each state).  1e-6: a tenth of the
# identified InvertedDoublePendulum's own one-sample error against MuJoCo (1.3e-5 at most
# along swing-ups, same measure); it keeps that system's 5 substeps and gives the Acrobot 9 of 20.
SEARCH_TOL = 1e-6


class ControlledSystem:
    """A model's dynamics under a task's inputs.

    Parameters
    ----------
    model : object
        A fitted :class:`~lsindy_cas.LagrangianSINDy` or a ``MechanicalSystem``.
    bound : BoundTask
        The task checked against the model's coordinates.
    rng : numpy.random.Generator
        For the sample states of the checks.

    Attributes
    ----------
    n, m : int
        States and inputs.
    step : casadi.Function
        ``(x (n,), u (m,)) -> x_next``: the held inputs over one sample ``dt``.
    energy : casadi.Function
        ``x -> H(x)``.
    actuated_rates : ndarray of int
        The states that are rates of coordinates an input acts on (the energy to shape leaves
        them out: the inputs set them directly).
    angles : ndarray of bool (n,)
        States that are angles (compared modulo 2π): H depends on them, 2π-periodically.
    cyclic : ndarray of bool (n,)
        Positions H does not depend on (the dynamics are the same wherever they are).
    """

    def __init__(self, model, bound, rng):
        if relative_energy(model):
            raise ValueError("the model's energy is known only up to a factor (passive data "
                             "without a scale record), so the inputs' effect is unknown: "
                             "identify it with a scale record or forced data to control it")
        coords = getattr(model, "coords_", None) or getattr(model, "coords", None)
        if not callable(getattr(model, "ode", None)) or not coords:
            raise TypeError("model must be a fitted LagrangianSINDy (or a system with coords, "
                            "ode() and hamiltonian)")
        H = getattr(model, "hamiltonian_", None)
        if H is None:
            H = getattr(model, "hamiltonian", None)
        if H is None:
            raise TypeError("model has no energy (hamiltonian_)")
        c = bound.coords
        self.n, self.m, self.dt = 2 * c.n, bound.B.shape[1], bound.task.dt
        ode = model.ode()
        x, u = ca.SX.sym("x", self.n), ca.SX.sym("u", self.m)
        self.ode = ca.Function("ode_u", [x, u], [ode(x, ca.mtimes(ca.DM(bound.B), u))],
                               ["x", "u"], ["xdot"])
        self.n_substeps = max(1, int(np.ceil(self.dt / MAX_SUBSTEP - 1e-9)))
        self.step = rk4_step(self.ode, self.n, self.m, self.dt, self.n_substeps)
        self.search_substeps, self.search_step = self._search_map(bound)
        Hx = c.to_casadi(H)
        self.energy = ca.Function("H", [c.x], [Hx])
        self.mass = ca.Function("M", [c.x], [ca.hessian(Hx, c.qd)[0]])
        self.actuated_rates = c.n + np.flatnonzero(np.any(bound.B != 0, axis=1))
        self.angles = self._angles(rng, c.n)
        self._check_kinetic(bound, rng)

    def _search_map(self, bound):
        """The search's map: the fewest RK4 substeps whose map stays within ``SEARCH_TOL`` of
        :attr:`step` on sample states (its own seed, so the build's other draws are unchanged)."""
        import itertools
        levels = np.array(list(itertools.product(*[i.candidates() for i in bound.inputs])))
        X = np.random.default_rng(0).uniform(-np.pi, np.pi, size=(64, self.n))
        U = levels[np.arange(len(X)) % len(levels)]
        fine = np.asarray(self.step.map(len(X))(X.T, U.T)).T
        change = np.maximum(np.max(np.abs(fine - X), axis=0), 1e-12)
        for k in range(1, self.n_substeps):
            step = rk4_step(self.ode, self.n, self.m, self.dt, k)
            coarse = np.asarray(step.map(len(X))(X.T, U.T)).T
            if np.all(np.isfinite(coarse)) and np.max(np.abs(coarse - fine) / change) <= SEARCH_TOL:
                return k, step
        return self.n_substeps, self.step

    def _samples(self, rng, k=64):
        """Sample states for the checks: every entry uniform in ±π."""
        return rng.uniform(-np.pi, np.pi, size=(k, self.n))

    def _angles(self, rng, n_coords):
        """Angles: coordinates H depends on and is 2π-periodic in.  Cyclic coordinates: those H
        does not depend on at all (a carriage's position, a Furuta arm's angle): shifting them
        changes nothing in the dynamics."""
        X = self._samples(rng)
        E = self._energy_rows(X)
        scale = 1.0 + np.max(np.abs(E))
        angles, cyclic = np.zeros(self.n, bool), np.zeros(self.n, bool)
        for i in range(n_coords):
            shifted = []
            for shift in (2 * np.pi, 1.0):
                Y = X.copy()
                Y[:, i] += shift
                shifted.append(np.max(np.abs(self._energy_rows(Y) - E)))
            # equal to rounding: 1e-9 of the energy scale (floats carry 1e-16; cos(q + 2π)
            # differs from cos(q) by ~1e-15)
            same = [d <= 1e-9 * scale for d in shifted]
            cyclic[i] = same[1]
            angles[i] = same[0] and not same[1]
        self.cyclic = cyclic
        return angles

    def _energy_rows(self, X):
        return np.asarray(self.energy.map(len(X))(X.T)).ravel()

    def _check_kinetic(self, bound, rng):
        X = self._samples(rng)
        if bound.target is not None:
            X = np.vstack([bound.target, X])
        for x in X:
            M = np.asarray(self.mass(x))
            w = np.linalg.eigvalsh(0.5 * (M + M.T))
            if not w[0] > 1e-9 * max(1.0, abs(w[-1])):
                raise ValueError("the model's kinetic part is not positive definite (mass "
                                 f"matrix eigenvalue {w[0]:.3g} at state "
                                 f"{np.round(x, 3).tolist()}): it cannot be simulated or "
                                 "controlled")

    def wrap(self, E):
        """Errors ``E`` (..., n) with angle entries wrapped into [-π, π)."""
        E = np.array(E, dtype=float, copy=True)
        E[..., self.angles] = (E[..., self.angles] + np.pi) % (2 * np.pi) - np.pi
        return E
