"""Rayleigh dissipation R(q̇): friction forces −∂R/∂q̇ and the dissipated power q̇·∂R/∂q̇.

With friction the energy balance reads dE/dt = P − q̇·∂R/∂q̇ and the equations of motion
M q̈ = Q + ∂L/∂q − (∂²L/∂q̇∂q) q̇ − ∂R/∂q̇.  The candidate terms of R are functions of the
velocities only: quadratic forms for viscous friction (``theta1_dot**2``, ``theta1_dot*theta2_dot``;
a damper between two links is k(θ̇₂ − θ̇₁)², a combination of these) and ``Abs(v)`` for Coulomb
friction, whose force is μ·sign(v).

Sign of a Coulomb force.  The energy balance and the printed/sympy equations use the exact
``sign(v)`` (∂|v|/∂v), so q̇·∂R/∂q̇ = μ|v| exactly on the data.  The CasADi ODE replaces
``sign(v)`` by ``tanh(v/ε)`` with ε = :data:`COULOMB_EPS`, fixed in the velocity's units
(m/s or rad/s): the force is within 0.5 % of μ·sign(v) for |v| > 3ε = 3 cm/s, and its slope
μ/ε near v = 0 stays small enough for the project's adaptive integrator and for the MPC's fixed
RK4 steps (an exact sign would make both chatter at every velocity reversal).  The price: the
smoothed model creeps where a real rig would stick.
"""
from __future__ import annotations

from ..symbolic.coords import Coordinates

__all__ = ["COULOMB_EPS", "check_velocity_only", "friction_forces", "smooth_sign"]

COULOMB_EPS = 1e-2


def check_velocity_only(coords: Coordinates, exprs, what: str = "dissipation term") -> None:
    """Raise ``ValueError`` if an expression of R depends on a position (R = R(q̇) only)."""
    import sympy as sp
    qs = set(coords.q_sym)
    for e in exprs:
        bad = sorted(str(s) for s in sp.sympify(e).free_symbols & qs)
        if bad:
            raise ValueError(f"{what} {e} depends on position(s) {', '.join(bad)}: a Rayleigh "
                             "function may only use the velocities <q>_dot")
        if not sp.sympify(e).free_symbols & set(coords.qd_sym):
            raise ValueError(f"{what} {e} does not depend on any velocity <q>_dot")


def friction_forces(coords: Coordinates, rayleigh) -> list:
    """Exact generalized friction forces ∂R/∂q̇ (sympy, one per coordinate; Coulomb → sign)."""
    import sympy as sp
    R = sp.sympify(rayleigh)
    return [sp.diff(R, v) for v in coords.qd_sym]


def smooth_sign(expr, eps: float = COULOMB_EPS):
    """``expr`` with every ``sign(a)`` replaced by ``tanh(a/eps)`` (the ODE's Coulomb force)."""
    import sympy as sp
    return sp.sympify(expr).replace(sp.sign, lambda a: sp.tanh(a / eps))
