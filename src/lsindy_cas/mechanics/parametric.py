"""Equations of motion as a CasADi function of the coefficient vector (for fitting coefficients).

A Lagrangian and a Rayleigh dissipation function that are linear in unknown coefficients,

    L(q, q̇; a) = Σ_j a_j L_j(q, q̇),       R(q̇; r) = Σ_j r_j R_j(q̇),

give the Euler–Lagrange equations with friction

    M(q, q̇; a) q̈ = Q + ∂L/∂q − (∂²L/∂q̇∂q) q̇ − ∂R/∂q̇,      M = ∂²L/∂q̇²,

here built once with CasADi symbolic derivatives (no finite differences) over a *symbolic*
coefficient vector ``p = [a, r]``: ``ode(x, u, p)`` can be integrated and differentiated with
respect to the coefficients, as prediction-error refinement (``identify/refine.py``) needs.

Friction terms: ``q̇_i²`` (and products ``q̇_i q̇_j``) are viscous, with R = ½ c q̇² giving the force
−c q̇ for the coefficient c/2; ``Abs(q̇_i)`` is Coulomb friction, whose force −r sign(q̇_i) is
discontinuous at rest.  It is smoothed: |v| is replaced in R by

    |v|_ε = |v| + ε log(1 + exp(−2|v|/ε)) − ε log 2   (= ε log cosh(v/ε), written without overflow),

whose derivative is exactly tanh(v/ε), so the friction force is −r tanh(v/ε).  ε (velocity units,
default 1e-2) is the speed below which the friction fades linearly; the ODE stays smooth, so RK4,
CVODES and the MPC can integrate it.
"""
from __future__ import annotations

import casadi as ca
import sympy as sp

from ..symbolic.coords import Coordinates
from .euler_lagrange import mass_and_force

__all__ = ["ParametricDynamics", "smooth_abs"]

DEFAULT_EPS = 1e-2


def smooth_abs(expr: sp.Expr, eps: float) -> sp.Expr:
    """Replace every ``Abs(v)`` in ``expr`` by ``ε log cosh(v/ε)`` written without overflow.

    Its derivative is ``tanh(v/ε)``, the smooth sign used for Coulomb friction.
    """
    e = sp.Float(eps)
    table = {a: a + e * sp.log(1 + sp.exp(-2 * a / e)) - e * sp.log(2) for a in expr.atoms(sp.Abs)}
    return expr.xreplace(table)


class ParametricDynamics:
    """M q̈ = F with L and R linear in a symbolic coefficient vector.

    Parameters
    ----------
    coords : Coordinates or list of str
        Generalized coordinates.
    lagrangian_terms : list of str
        The terms L_j of the Lagrangian (sympy syntax over ``<q>``, ``<q>_dot``).
    dissipation_terms : list of str, optional
        The terms R_j of the Rayleigh function, functions of the velocities only
        (e.g. ``theta_dot**2``, ``Abs(theta_dot)``).
    eps : float
        Smoothing speed ε of ``Abs`` (Coulomb friction force −r tanh(v/ε)); see the module text.

    Attributes
    ----------
    n_params : int
        ``len(lagrangian_terms) + len(dissipation_terms)``; ``p = [a, r]`` in that order.
    """

    def __init__(self, coords, lagrangian_terms, dissipation_terms=(), eps: float = DEFAULT_EPS):
        self.coords = coords if isinstance(coords, Coordinates) else Coordinates(coords)
        c = self.coords
        if isinstance(lagrangian_terms, str) or isinstance(dissipation_terms, str):
            raise TypeError("lagrangian_terms and dissipation_terms must be lists of strings")
        lagrangian_terms, dissipation_terms = list(lagrangian_terms), list(dissipation_terms)
        if not lagrangian_terms:
            raise ValueError("lagrangian_terms must name at least one term")
        if not (isinstance(eps, (int, float)) and eps > 0):
            raise ValueError(f"eps must be a positive speed, got {eps!r}")
        self.eps = float(eps)
        self.lagrangian_terms = [c.parse(t, what="Lagrangian term") for t in lagrangian_terms]
        self.dissipation_terms = [c.parse(t, what="dissipation term") for t in dissipation_terms]
        positions = set(c.q_sym)
        for t in self.dissipation_terms:
            if t.free_symbols & positions or not t.free_symbols:
                raise ValueError(f"dissipation term {t} must be a function of the velocities only "
                                 f"({', '.join(n + '_dot' for n in c.names)})")
        self.names = [str(t) for t in self.lagrangian_terms + self.dissipation_terms]
        self.n_lagrangian = len(self.lagrangian_terms)
        self.n_params = self.n_lagrangian + len(self.dissipation_terms)
        self.p = ca.SX.sym("p", self.n_params)
        a, r = self.p[:self.n_lagrangian], self.p[self.n_lagrangian:]
        L_j = ca.vertcat(*[c.to_casadi(t) for t in self.lagrangian_terms])
        L = ca.dot(a, L_j)
        R = ca.SX(0)
        if self.dissipation_terms:
            R_j = ca.vertcat(*[c.to_casadi(smooth_abs(t, self.eps)) for t in self.dissipation_terms])
            R = ca.dot(r, R_j)
        self.M_sx, F = mass_and_force(c, L)
        self.friction_sx = -ca.gradient(R, c.qd)
        self.F_sx = F + self.friction_sx

    def ode(self) -> ca.Function:
        """``Function('ode', [x, u, p], [xdot])``: x = [q, q̇] (2n), u = Q (n), p (n_params)."""
        c = self.coords
        qdd = ca.solve(self.M_sx, self.F_sx)
        return ca.Function("ode", [c.x, c.Q, self.p], [ca.vertcat(c.qd, qdd)],
                           ["x", "u", "p"], ["xdot"])

    def bind(self, p) -> ca.Function:
        """The ODE at fixed coefficients: ``Function('ode', [x, u], [xdot])`` as models give it."""
        c = self.coords
        p = ca.DM(p)
        if p.numel() != self.n_params:
            raise ValueError(f"p must have {self.n_params} coefficients ({', '.join(self.names)}), "
                             f"got {p.numel()}")
        xdot = self.ode()(c.x, c.Q, p)
        return ca.Function("ode", [c.x, c.Q], [xdot], ["x", "u"], ["xdot"])

    def mass_matrix(self) -> ca.Function:
        """``Function('M', [x, p], [M])``: the generalized mass matrix ∂²L/∂q̇² (n, n)."""
        return ca.Function("M", [self.coords.x, self.p], [self.M_sx], ["x", "p"], ["M"])

    def friction(self) -> ca.Function:
        """``Function('friction', [x, p], [f])``: the friction forces −∂R/∂q̇ (n,)."""
        return ca.Function("friction", [self.coords.x, self.p], [self.friction_sx], ["x", "p"], ["f"])
