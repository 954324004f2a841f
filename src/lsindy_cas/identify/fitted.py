"""What a fitted :class:`~lsindy_cas.identify.estimator.LagrangianSINDy` offers: its coefficients,
expressions, equations of motion and ODE (a base class, kept apart from the fitting steps).

Everything printed or written is linear in the coefficients, so it is assembled from the
library's per-term templates (:mod:`lsindy_cas.symbolic.template`) without sympy;
``hamiltonian_``, ``lagrangian_``, ``rayleigh_`` and ``equations_of_motion()`` are sympy objects
built on first access, and ``ode()`` is CasADi from the library's cached Θ Function
(:mod:`lsindy_cas.mechanics.linear`).
"""
from __future__ import annotations

from functools import cached_property

import numpy as np

from ..mechanics.euler_lagrange import simulate_ode
from ..mechanics.legendre import legendre
from ..mechanics.linear import LinearMechanics, expression
from ..symbolic.template import text

__all__ = ["FittedModel"]

_LAZY = ("hamiltonian_", "lagrangian_", "rayleigh_")


class FittedModel:
    """Base of the estimator: results of a fit (attributes are documented on the estimator)."""

    def _set_coefficients(self, coef, X=None, rayleigh=None):
        lib = self.library
        self.coords_ = list(lib.coords.names)
        self.coef_ = np.asarray(coef, float)
        self.support_ = tuple(int(j) for j in np.flatnonzero(self.coef_))
        self.lagrangian_coef_ = legendre(lib, self.coef_, X)
        dlib = getattr(self, "_diss_lib", None)
        self.rayleigh_coef_ = (np.zeros(0) if rayleigh is None or dlib is None
                               else np.asarray(rayleigh, float))
        for name in _LAZY:                      # the sympy expressions: rebuilt when asked for
            self.__dict__.pop(name, None)
        self._mechanics = LinearMechanics(lib, self.lagrangian_coef_, dlib,
                                          self.rayleigh_coef_ if self.rayleigh_coef_.size
                                          else None)

    def _set_errors(self, errors):
        """Standard errors of H's and L's coefficients (:mod:`.standard_errors`)."""
        self.coef_std_ = np.asarray(errors.hamiltonian, float)
        self.lagrangian_coef_std_ = np.asarray(errors.lagrangian, float)
        self.std_method_ = errors.method

    def _check_fitted(self):
        if not hasattr(self, "coef_"):
            raise ValueError("this LagrangianSINDy is not fitted yet; call fit() or load()")

    def _fitted_mechanics(self) -> LinearMechanics:
        if "_mechanics" not in self.__dict__:        # unfitted: no expressions (hasattr False)
            raise AttributeError("the model is not fitted yet")
        return self._mechanics

    # ------------------------------------------------------------------ sympy, on first access
    @cached_property
    def hamiltonian_(self):
        """H = Σ ξ_j θ_j (sympy)."""
        return expression(self._fitted_mechanics().library, self.coef_)

    @cached_property
    def lagrangian_(self):
        """L = Σ ξ_L,j θ_j (sympy)."""
        return self._fitted_mechanics().lagrangian

    @cached_property
    def rayleigh_(self):
        """R(q̇) (sympy; 0 without friction)."""
        return self._fitted_mechanics().rayleigh

    @property
    def has_friction_(self) -> bool:
        """Whether the model has a non-zero Rayleigh function."""
        return self._fitted_mechanics().friction

    # ------------------------------------------------------------------ results
    def terms(self, which: str = "hamiltonian") -> dict:
        """``{term name: coefficient}`` of the identified H or L."""
        self._check_fitted()
        if which == "rayleigh":
            if getattr(self, "_diss_lib", None) is None:
                return {}
            return {self._diss_lib.names[j]: float(c) for j, c in enumerate(self.rayleigh_coef_)
                    if c != 0}
        coef = self.coef_ if which == "hamiltonian" else self.lagrangian_coef_
        return {self.library.names[j]: float(coef[j]) for j in np.flatnonzero(coef)}

    def texts(self, dps: int = 15, coef_h=None, coef_l=None) -> dict:
        """H, L, R and the equations of motion as sympy-syntax strings (no sympy needed).

        Parameters
        ----------
        dps : int
            Significant digits of every printed coefficient.
        coef_h, coef_l : array (p,), optional
            Coefficients of H and L to print instead of the fitted ones (e.g. rounded); the
            equations follow ``coef_l``.

        Returns
        -------
        dict
            ``{"hamiltonian", "lagrangian", "rayleigh" (None without a dissipation library),
            "equations": [(lhs, rhs), ...]}``; lhs holds the ``<q>_ddot`` monomials, rhs is
            ``Q_<q>`` minus the rest (and minus the friction force ∂R/∂q̇).
        """
        self._check_fitted()
        t = self.library.template
        coef_h = self.coef_ if coef_h is None else coef_h
        coef_l = self.lagrangian_coef_ if coef_l is None else coef_l
        mech = self._mechanics
        friction = (mech.dissipation.template, mech.rho) if mech.friction else None
        dlib = getattr(self, "_diss_lib", None)
        return {"hamiltonian": text(t.combine(coef_h), dps),
                "lagrangian": text(t.combine(coef_l), dps),
                "rayleigh": (None if dlib is None else
                             text(friction[0].combine(friction[1]), dps) if friction else "0"),
                "equations": t.equations(coef_l, dps, friction)}

    def ode(self):
        """``casadi.Function('ode', [x, u], [xdot])``: x = [q, q̇], u = Q (generalized forces)."""
        self._check_fitted()
        return self._mechanics.ode()

    def equations_of_motion(self) -> list:
        """Sympy ``Eq(M q̈, F)`` rows over ``<q>_ddot``, ``<q>``, ``<q>_dot`` and ``Q_<q>``."""
        self._check_fitted()
        return self._mechanics.equations()

    def simulate(self, x0, t, u=None) -> np.ndarray:
        """Integrate the identified equations of motion; returns states (len(t), 2n)."""
        self._check_fitted()
        return simulate_ode(self.ode(), x0, t, u, len(self.coords_))[0]
