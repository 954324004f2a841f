"""The mechanics of a fitted model, L = Σ_j c_j θ_j over a library (and R = Σ_j ρ_j R_j).

The CasADi side needs no sympy: the library's Θ Function (cached on disk, :mod:`..symbolic.fcache`)
called on the symbolic state gives every term as SX, L is their combination, and the mass matrix
and forcing follow by CasADi's derivatives exactly as in :class:`.euler_lagrange.EulerLagrange`
(M = ∂²L/∂q̇², F = Q + ∂L/∂q − (∂²L/∂q̇∂q) q̇).  The sympy side (L, R and the equations as sympy
objects) is built on first use.  A model with friction takes the sympy route for its ODE too
(the Coulomb ``sign`` is smoothed there, :mod:`.rayleigh`).
"""
from __future__ import annotations

from functools import cached_property

import casadi as ca
import numpy as np

__all__ = ["LinearMechanics", "expression"]


def expression(library, coef):
    """Σ_j coef_j θ_j over the non-zero coefficients, as a sympy expression (floats of 15 digits)."""
    import sympy as sp
    return sp.Add(*[sp.Float(float(coef[j]), 15) * library.exprs[j] for j in np.flatnonzero(coef)])


class LinearMechanics:
    """Equations of motion of L = Θ ξ_L (+ friction −∂R/∂q̇, R = Θ_R ρ).

    Parameters
    ----------
    library : Library
        The terms θ_j of L.
    coef : array (p,)
        The Lagrangian's coefficients ξ_L.
    dissipation : Library, optional
        The Rayleigh function's candidate terms R_j (velocities only).
    rho : array (r,), optional
        Their coefficients; None or all zero: no friction.
    """

    def __init__(self, library, coef, dissipation=None, rho=None):
        self.library, self.coef = library, np.asarray(coef, float)
        self.friction = dissipation is not None and rho is not None and bool(np.any(rho))
        self.dissipation = dissipation if self.friction else None
        self.rho = np.asarray(rho, float) if self.friction else None

    # ------------------------------------------------------------------ sympy, on demand
    @cached_property
    def lagrangian(self):
        """L as a sympy expression."""
        return expression(self.library, self.coef)

    @cached_property
    def rayleigh(self):
        """R as a sympy expression (0 without friction)."""
        if not self.friction:
            import sympy as sp
            return sp.Integer(0)
        return expression(self.dissipation, self.rho)

    @cached_property
    def symbolic(self):
        """The :class:`.euler_lagrange.EulerLagrange` of (L, R) (sympy)."""
        from .euler_lagrange import EulerLagrange
        return EulerLagrange(self.library.coords, self.lagrangian,
                             rayleigh=self.rayleigh if self.friction else None)

    def equations(self) -> list:
        """Sympy ``Eq(M q̈, F)`` rows over ``<q>_ddot`` symbols."""
        return self.symbolic.equations()

    # ------------------------------------------------------------------ CasADi
    @cached_property
    def _sx(self) -> tuple:
        """(M, F) as SX over the coordinates' x and Q, from the library's Θ Function."""
        c = self.library.coords
        theta = self.library.sx_terms()                          # (p, 1) SX, every term
        L = ca.SX(0)
        for j in np.flatnonzero(self.coef):
            L = L + float(self.coef[j]) * theta[int(j)]
        from .euler_lagrange import mass_and_force
        return mass_and_force(c, L)

    def mass_matrix(self) -> ca.Function:
        """``M(x)``: (2n,) state -> (n, n) generalized mass matrix ∂²L/∂q̇²."""
        if self.friction:
            return self.symbolic.mass_matrix()
        return ca.Function("M", [self.library.coords.x], [self._sx[0]], ["x"], ["M"])

    def ode(self) -> ca.Function:
        """``Function('ode', [x, u], [xdot], ['x', 'u'], ['xdot'])``, ``q̈ = solve(M, F)``."""
        if self.friction:
            return self.symbolic.ode()
        c = self.library.coords
        M, F = self._sx
        return ca.Function("ode", [c.x, c.Q], [ca.vertcat(c.qd, ca.solve(M, F))],
                           ["x", "u"], ["xdot"])
