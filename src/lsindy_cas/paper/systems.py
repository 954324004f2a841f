"""Benchmark systems with known Lagrangians (paper Fig. 2) and their accurate simulation.

Conventions (DESIGN.md), g = 9.81 m/s²:

- spherical pendulum: q = (θ, φ), θ from the *upward* vertical, V = +mgL cos θ; Q_φ = u;
- double pendulum: q = (θ1, θ2), absolute angles from the downward vertical; Q_θ1 = u;
- cart-pendulum: q = (x, θ), θ from the downward vertical (upright θ = π), point mass at the rod end;
  Q_x = u.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from ..symbolic.coords import Coordinates
from ..data.trajectory import Trajectory
from ..mechanics.euler_lagrange import EulerLagrange, simulate_ode
from ..mechanics.rayleigh import COULOMB_EPS

__all__ = ["MechanicalSystem", "spherical_pendulum", "double_pendulum", "cart_pendulum",
           "mass_spring", "elastic_pendulum", "PAPER_SYSTEMS"]

G = 9.81


@dataclass
class MechanicalSystem:
    """A mechanical system given by its true kinetic and potential energy.

    Parameters
    ----------
    name : str
    coords : list of str
        Generalized coordinates.
    kinetic, potential : str
        T(q, q̇) and V(q) in sympy syntax over the coordinate names.
    actuated : str
        The coordinate a scalar input ``u`` acts on (Q_<actuated> = u).
    x0 : tuple
        The paper's initial state ``[q, q̇]``.
    params : dict
        The physical parameters (for reports).
    rayleigh : str, optional
        True Rayleigh dissipation function R(q̇) (friction forces −∂R/∂q̇); None: no friction.
    coulomb_eps : float
        Simulation only: a Coulomb force's sign(v) is integrated as tanh(v/coulomb_eps)
        (:mod:`lsindy_cas.mechanics.rayleigh`).
    """

    name: str
    coords: list
    kinetic: str
    potential: str
    actuated: str
    x0: tuple
    params: dict = field(default_factory=dict)
    rayleigh: str | None = None
    coulomb_eps: float = COULOMB_EPS

    def __post_init__(self):
        self._c = Coordinates(self.coords)
        if self.actuated not in self._c.names:
            raise ValueError(f"actuated coordinate {self.actuated!r} is not one of {self._c.names}")
        self._T = self._c.parse(self.kinetic, what="kinetic energy")
        self._V = self._c.parse(self.potential, what="potential energy")
        self._R = None if self.rayleigh is None else self._c.parse(self.rayleigh,
                                                                    what="Rayleigh function")
        self._el = EulerLagrange(self._c, self._T - self._V, rayleigh=self._R,
                                 coulomb_eps=self.coulomb_eps)

    @property
    def hamiltonian(self) -> sp.Expr:
        """True total energy H = T + V (sympy, expanded)."""
        return sp.expand(self._T + self._V)

    @property
    def lagrangian(self) -> sp.Expr:
        """True Lagrangian L = T − V (sympy, expanded)."""
        return sp.expand(self._T - self._V)

    def ode(self):
        """True dynamics as ``casadi.Function('ode', [x, u], [xdot])`` (see ``EulerLagrange.ode``)."""
        return self._el.ode()

    def equations(self):
        return self._el.equations()

    def energy(self, X) -> np.ndarray:
        """H evaluated at states X (n_samples, 2n)."""
        from ..symbolic.library import Library
        return Library(self._c, [self.hamiltonian]).theta(X)[:, 0]

    def _forces(self, u):
        """Map a scalar input (or callable returning one) to generalized forces (n,)."""
        n, j = self._c.n, self._c.names.index(self.actuated)

        def lift(v):
            v = np.asarray(v, float)
            if v.size == 1:
                out = np.zeros(n)
                out[j] = float(v)
                return out
            if v.shape != (n,):
                raise ValueError(f"input must be a scalar or {n} generalized forces, got shape {v.shape}")
            return v
        if callable(u):
            return lambda t, x: lift(u(t, x))
        return lift(0.0 if u is None else u)

    def simulate(self, x0=None, t_end: float = 1.0, u=0.0, dt: float = 0.01,
                 t0: float = 0.0) -> Trajectory:
        """Simulate accurately (DOP853, rtol 1e-11) and sample every ``dt`` seconds.

        Parameters
        ----------
        x0 : array (2n,), optional
            Initial state [q, q̇]; defaults to the paper's.
        t_end : float
            Duration in seconds.
        u : float, array (n,) or callable ``u(t, x)``
            Input: a scalar acts on the actuated coordinate; callables are held over each sample.
        dt : float
            Sampling period (0.01 s = the paper's 100 Hz).

        Returns
        -------
        Trajectory
            With exact accelerations ``qdd`` from the true equations of motion.
        """
        if not dt > 0 or not t_end > 0:
            raise ValueError(f"dt and t_end must be positive, got dt={dt}, t_end={t_end}")
        x0 = np.asarray(self.x0 if x0 is None else x0, float)
        t = t0 + np.arange(int(round(t_end / dt)) + 1) * dt
        X, Xdot, U = simulate_ode(self.ode(), x0, t, self._forces(u), self._c.n)
        n = self._c.n
        return Trajectory(t, X[:, :n], X[:, n:], self._c.names, Q=U, qdd=Xdot[:, n:],
                          source=f"{self.name} simulation")


def spherical_pendulum(m=1.0, L=1.0, g=G, names=("theta", "phi")) -> MechanicalSystem:
    th, ph = names
    return MechanicalSystem(
        "spherical pendulum", list(names),
        kinetic=f"{m * L**2 / 2}*({th}_dot**2 + sin({th})**2*{ph}_dot**2)",
        potential=f"{m * g * L}*cos({th})", actuated=ph,
        x0=(np.pi / 2, 0.0, 0.0, 0.5), params=dict(m=m, L=L, g=g))


def double_pendulum(m1=1.0, m2=1.0, L1=1.0, L2=1.0, g=G, names=("theta1", "theta2")) -> MechanicalSystem:
    a, b = names
    return MechanicalSystem(
        "double pendulum", list(names),
        kinetic=(f"{(m1 + m2) * L1**2 / 2}*{a}_dot**2 + {m2 * L2**2 / 2}*{b}_dot**2"
                 f" + {m2 * L1 * L2}*{a}_dot*{b}_dot*cos({a} - {b})"),
        potential=f"-{(m1 + m2) * g * L1}*cos({a}) - {m2 * g * L2}*cos({b})", actuated=a,
        x0=(3 * np.pi / 7, 3 * np.pi / 4, 0.0, 0.0), params=dict(m1=m1, m2=m2, L1=L1, L2=L2, g=g))


def cart_pendulum(mc=1.0, mp=0.1, L=1.0, g=G, names=("x", "theta")) -> MechanicalSystem:
    x, th = names
    return MechanicalSystem(
        "cart-pendulum", list(names),
        kinetic=(f"{(mc + mp) / 2}*{x}_dot**2 + {mp * L**2 / 2}*{th}_dot**2"
                 f" + {mp * L}*{x}_dot*{th}_dot*cos({th})"),
        potential=f"-{mp * g * L}*cos({th})", actuated=x,
        x0=(0.0, np.pi / 4, 0.0, 0.0), params=dict(mc=mc, mp=mp, L=L, g=g))


def elastic_pendulum(m=1.0, k=40.0, L0=1.0, g=G, names=("r", "theta")) -> MechanicalSystem:
    """A point mass on a spring (not in the paper): r the spring length, θ from the downward
    vertical; T = m(ṙ² + r²θ̇²)/2, V = −m g r cos θ + k (r − L0)²/2 (energy terms ṙ², r²θ̇², r cos θ,
    r², r); actuation: a moment about the pivot, Q_θ = u (a constant force along the spring would
    leave the coefficient of r undetermined: E and E − u·r change alike)."""
    r, th = names
    return MechanicalSystem(
        "elastic pendulum", list(names),
        kinetic=f"{m / 2}*({r}_dot**2 + {r}**2*{th}_dot**2)",
        potential=f"-{m * g}*{r}*cos({th}) + {k / 2}*{r}**2 - {k * L0}*{r}", actuated=th,
        x0=(1.2, np.pi / 3, 0.0, 0.0), params=dict(m=m, k=k, L0=L0, g=g))


def mass_spring(m=2.0, k=5.0, name="s") -> MechanicalSystem:
    """A linear oscillator (not in the paper): T = m ṡ²/2, V = k s²/2."""
    return MechanicalSystem("mass-spring", [name], kinetic=f"{m / 2}*{name}_dot**2",
                            potential=f"{k / 2}*{name}**2", actuated=name, x0=(0.5, 0.0),
                            params=dict(m=m, k=k))


PAPER_SYSTEMS = {
    "spherical": spherical_pendulum,
    "double": double_pendulum,
    "cart": cart_pendulum,
}
