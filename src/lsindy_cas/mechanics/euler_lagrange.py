"""Euler–Lagrange equations from a Lagrangian: mass matrix, forcing, CasADi ODE, sympy equations.

For a time-independent L(q, q̇) with applied generalized forces Q,

    d/dt ∂L/∂q̇ − ∂L/∂q = Q   ⇔   M(q, q̇) q̈ = F(q, q̇, Q),
    M = ∂²L/∂q̇²,   F = Q + ∂L/∂q − (∂²L/∂q̇∂q) q̇ − ∂R/∂q̇,

with R(q̇) an optional Rayleigh dissipation function (friction; :mod:`.rayleigh`, which also says how
the ODE smooths a Coulomb sign).

The accelerations are obtained by solving the linear system (``ca.solve``), never by inverting M
symbolically.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..symbolic.coords import Coordinates
from .rayleigh import COULOMB_EPS, check_velocity_only, friction_forces, smooth_sign

__all__ = ["EulerLagrange", "mass_and_force", "simulate_ode"]


def mass_and_force(coords: Coordinates, L):
    """The Euler–Lagrange equations M(q, q̇) q̈ = F of a Lagrangian ``L`` (CasADi SX over
    ``coords``): M = ∂²L/∂q̇², F = Q + ∂L/∂q − (∂²L/∂q̇∂q) q̇.  The one place they are written;
    friction is the caller's to subtract from F."""
    dL_dqd = ca.gradient(L, coords.qd)
    M = ca.jacobian(dL_dqd, coords.qd)
    F = coords.Q + ca.gradient(L, coords.q) - ca.mtimes(ca.jacobian(dL_dqd, coords.q), coords.qd)
    return M, F


class EulerLagrange:
    """Equations of motion of a Lagrangian system.

    Parameters
    ----------
    coords : Coordinates or list of str
        Generalized coordinates.
    lagrangian : str or sympy.Expr
        L(q, q̇) over the coordinate names.
    rayleigh : str or sympy.Expr, optional
        Rayleigh dissipation function R(q̇) (velocities only); friction forces −∂R/∂q̇.
    coulomb_eps : float
        ODE only: ``sign(v)`` of a Coulomb force is smoothed to ``tanh(v/coulomb_eps)``.
    """

    def __init__(self, coords, lagrangian, rayleigh=None, coulomb_eps: float = COULOMB_EPS):
        import sympy as sp
        self.coords = coords if isinstance(coords, Coordinates) else Coordinates(coords)
        self.lagrangian = self.coords.parse(lagrangian, what="Lagrangian")
        c = self.coords
        self.rayleigh = (sp.Integer(0) if rayleigh is None
                         else c.parse(rayleigh, what="Rayleigh function"))
        if self.rayleigh != 0:
            check_velocity_only(c, [self.rayleigh], what="Rayleigh function")
        if not coulomb_eps > 0:
            raise ValueError(f"coulomb_eps must be positive, got {coulomb_eps}")
        self.coulomb_eps = float(coulomb_eps)
        self.M_sx, self.F_sx = mass_and_force(c, c.to_casadi(self.lagrangian))
        if self.rayleigh != 0:
            fr = [c.to_casadi(smooth_sign(f, self.coulomb_eps))
                  for f in friction_forces(c, self.rayleigh)]
            self.F_sx = self.F_sx - ca.vertcat(*fr)

    def mass_matrix(self) -> ca.Function:
        """``M(x)``: (2n,) state -> (n, n) generalized mass matrix ∂²L/∂q̇²."""
        return ca.Function("M", [self.coords.x], [self.M_sx], ["x"], ["M"])

    def ode(self) -> ca.Function:
        """CasADi ``Function('ode', [x, u], [xdot], ['x', 'u'], ['xdot'])``.

        ``x = [q, q̇]`` (2n), ``u = Q`` (n generalized forces), ``xdot = [q̇, q̈]`` with
        ``q̈ = solve(M, F)``.
        """
        c = self.coords
        qdd = ca.solve(self.M_sx, self.F_sx)
        return ca.Function("ode", [c.x, c.Q], [ca.vertcat(c.qd, qdd)], ["x", "u"], ["xdot"])

    def sympy_equations(self) -> tuple:
        """Return ``(M, F)`` as sympy matrices so that ``M q̈ = F`` (with ``Q_<q>`` symbols)."""
        import sympy as sp
        c = self.coords
        L = self.lagrangian
        qd, q = sp.Matrix(c.qd_sym), sp.Matrix(c.q_sym)
        p = sp.Matrix([sp.diff(L, v) for v in c.qd_sym])
        M = p.jacobian(qd)
        F = sp.Matrix(c.Q_sym) + sp.Matrix([sp.diff(L, v) for v in c.q_sym]) - p.jacobian(q) * qd
        if self.rayleigh != 0:                   # exact friction forces (Coulomb: sign(v))
            F = F - sp.Matrix(friction_forces(c, self.rayleigh))
        return M, F

    def equations(self) -> list:
        """Equations of motion as sympy ``Eq(M q̈, F)`` rows over ``<q>_ddot`` symbols."""
        if "_equations" not in self.__dict__:        # derived once (printout, model file, ...)
            self._equations = self._derive_equations()
        return list(self._equations)

    def _derive_equations(self) -> list:
        import sympy as sp
        M, F = self.sympy_equations()
        qdd = sp.Matrix([sp.Symbol(n + "_ddot", real=True) for n in self.coords.names])
        lhs = M * qdd
        # evaluate=False: the rows as derived (deciding whether the two sides are identical,
        # which they never are for a fitted model, cost a third of the derivation)
        return [sp.Eq(sp.expand(lhs[i]), sp.expand(F[i]), evaluate=False)
                for i in range(self.coords.n)]


def simulate_ode(ode: ca.Function, x0, t_eval, u=None, n_coords: int | None = None,
                 rtol: float = 1e-11, atol: float = 1e-12):
    """Integrate ``xdot = ode(x, u)`` accurately and return states and exact derivatives.

    Parameters
    ----------
    ode : casadi.Function
        ``(x (2n), u (n)) -> xdot (2n)``.
    x0 : array (2n,)
        Initial state ``[q, q̇]``.
    t_eval : array (n_samples,)
        Sample times (the first is the initial time).
    u : None, float, array (n,) or callable
        Generalized forces: constant, or ``u(t, x) -> (n,)`` held constant over each sampling interval
        (zero-order hold, as a digital controller applies it).

    Returns
    -------
    X, Xdot, U : arrays (n_samples, 2n), (n_samples, 2n), (n_samples, n)
    """
    from scipy.integrate import solve_ivp   # imported here: scipy.integrate costs ~0.5 s to import

    t_eval = np.asarray(t_eval, float)
    x0 = np.asarray(x0, float).ravel()
    n = n_coords or x0.size // 2
    if x0.size != 2 * n:
        raise ValueError(f"x0 must have {2 * n} entries [q, q_dot], got {x0.size}")
    f = lambda t, x, uu: np.asarray(ode(x, uu)).ravel()  # noqa: E731
    X = np.empty((len(t_eval), 2 * n))
    U = np.empty((len(t_eval), n))
    X[0] = x0
    if callable(u):
        for i in range(len(t_eval)):
            U[i] = np.broadcast_to(np.asarray(u(t_eval[i], X[i]), float), (n,))
            if i + 1 < len(t_eval):
                sol = solve_ivp(f, (t_eval[i], t_eval[i + 1]), X[i], method="DOP853", rtol=rtol,
                                atol=atol, args=(U[i],))
                if not sol.success:
                    raise RuntimeError(f"integration failed at t = {t_eval[i]}: {sol.message}")
                X[i + 1] = sol.y[:, -1]
    else:
        uu = np.broadcast_to(np.asarray(0.0 if u is None else u, float), (n,)).copy()
        U[:] = uu
        sol = solve_ivp(f, (t_eval[0], t_eval[-1]), x0, method="DOP853", t_eval=t_eval,
                        rtol=rtol, atol=atol, args=(uu,))
        if not sol.success:
            raise RuntimeError(f"integration failed: {sol.message}")
        X = sol.y.T
    Xdot = np.asarray(ode.map(len(t_eval))(X.T, U.T)).T
    return X, Xdot, U
