"""From the Hamiltonian (total energy) to the Lagrangian by the linear Legendre transform (eq. 7).

Eq. 7 asks for ξ_L with Θξ = (Σ_i q̇_i Θ_q̇i − Θ) ξ_L.  For a term homogeneous of degree d in the
velocities, Euler's theorem gives Σ_i q̇_i ∂θ/∂q̇_i = d θ, so the map acts term by term as θ ↦ (d − 1) θ:

- d = 0 (potential):  ξ_L = −ξ_H;
- d = 2 (kinetic):    ξ_L = +ξ_H;
- d = 1 (gyroscopic, e.g. A(q)·q̇): the map sends the term to 0.  Such terms never appear in an
  energy (they cancel in H = p·q̇ − L), and the Lagrangian's linear part cannot be recovered from
  H.  A Hamiltonian with a degree-1 term is therefore rejected, and the Lagrangian's degree-1
  part is set to zero (its null-space component) — explicitly, not by the solver's choice.

Terms that are not homogeneous in the velocities fall back to solving eq. 7 by least squares on
sample states, with an error if the transform has no solution in the library.
"""
from __future__ import annotations

import numpy as np

from ..symbolic.library import Library

__all__ = ["legendre", "velocity_linear"]


def velocity_linear(library: Library, indices) -> list:
    """The terms among ``indices`` that are linear in the velocities (degree 1, e.g. A(q)·q̇).

    No energy has such a term: it cancels in H = p·q̇ − L, so eq. 7 cannot map it back.
    """
    return [int(j) for j in indices if library.velocity_degree(int(j)) == 1]


def legendre(library: Library, coef_h: np.ndarray, X: np.ndarray | None = None,
             rtol: float = 1e-9) -> np.ndarray:
    """Lagrangian coefficients ξ_L (p,) from Hamiltonian coefficients ξ_H (p,) (paper eq. 7).

    Parameters
    ----------
    library : Library
    coef_h : array (p,)
        Coefficients of H = Θ ξ_H.
    X : array (n_samples, 2n), optional
        States used only when some active term is not homogeneous in the velocities.
    rtol : float
        Relative size below which a velocity-linear coefficient counts as zero.
    """
    coef_h = np.asarray(coef_h, float)
    if coef_h.shape != (len(library),):
        raise ValueError(f"coef_h must have shape ({len(library)},), got {coef_h.shape}")
    active = np.flatnonzero(coef_h)
    degrees = {j: library.velocity_degree(j) for j in active}
    scale = np.max(np.abs(coef_h)) if active.size else 1.0
    linear = [library.names[j] for j in velocity_linear(library, active)
              if abs(coef_h[j]) > rtol * scale]
    if linear:
        raise ValueError("the energy contains terms linear in the velocities "
                         f"({', '.join(linear)}); no Lagrangian has such an energy (its linear "
                         "part cancels in the Legendre transform)")
    if all(degrees[j] is not None for j in active):
        coef_l = np.zeros_like(coef_h)
        for j in active:
            if degrees[j] != 1:
                coef_l[j] = coef_h[j] / (degrees[j] - 1)
        return coef_l
    if X is None:
        raise ValueError("non-homogeneous terms in the energy: pass sample states X to solve eq. 7")
    theta = library.theta(X)
    lam = np.einsum("si,sip->sp", X[:, library.coords.n:], library.dtheta_dqd(X)) - theta
    target = theta @ coef_h
    coef_l, *_ = np.linalg.lstsq(lam, target, rcond=None)
    if np.linalg.norm(lam @ coef_l - target) > 1e-6 * max(np.linalg.norm(target), 1e-300):
        raise ValueError("the Legendre transform of this energy has no solution in the library")
    return coef_l
