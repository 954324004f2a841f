"""Physical admissibility of a candidate energy: what separates the true energy from spurious fits.

A fit can be perfect and still not be an energy.  With a constant input u on a cyclic coordinate x,
E' = u·x satisfies dE'/dt = u·ẋ = P exactly; with passive data any conserved quantity (e.g. an
angular momentum) lies in the null space.  An admissible energy

1. uses every prior term with a non-zero coefficient (prior knowledge says they are there),
2. uses every term of its support (a k-term fit with a vanishing coefficient is a smaller model
   plus round-off, e.g. E' = u·x + 1e-18·ẋ²), and
3. has a positive-definite kinetic part: M(x) = ∂²E/∂q̇² ≻ 0 at every sample state.
"""
from __future__ import annotations

import numpy as np

from ..symbolic.library import Library

__all__ = ["Admissibility"]

# A prior term "is present" when its share of the fitted signal exceeds this fraction of the
# largest term's share; spurious fits put ~1e-12 there (round-off), true terms ≥ 1e-3.
PRIOR_SHARE_TOL = 1e-6
# M(x) counts as positive definite when λ_min > this fraction of λ_max at every sample.
PD_RTOL = 1e-9


class Admissibility:
    """Callable ``(support, coef) -> (ok, reason)`` for :func:`lsindy_cas.identify.search.best_subset`.

    Parameters
    ----------
    library : Library
    X : array (n_samples, 2n)
        States at which the kinetic part must be positive definite.
    forced : sequence of int
        Indices of the prior terms.
    column_norms : array (p,)
        Norms of the design-matrix columns (to compare term contributions scale-free).
    """

    def __init__(self, library: Library, X: np.ndarray, forced, column_norms: np.ndarray):
        self.library = library
        self.forced = list(forced)
        self.norms = np.asarray(column_norms, float)
        # subsample states for the PD check: enough to cover the data, cheap to evaluate
        step = max(1, len(X) // 400)
        self.hess = library.d2theta_dqd2(X[::step])        # (s, n, n, p)

    def __call__(self, support, coef):
        share = np.abs(coef) * self.norms
        top = share.max()
        if top == 0:
            return False, "all coefficients are zero"
        weak = [self.library.names[j] for j in self.forced if share[j] <= PRIOR_SHARE_TOL * top]
        if weak:
            return False, f"prior term(s) {', '.join(weak)} came out zero"
        weak = [self.library.names[j] for j in support if share[j] <= PRIOR_SHARE_TOL * top]
        if weak:
            return False, f"term(s) {', '.join(weak)} came out zero (the fit is a smaller model)"
        M = np.einsum("sikp,p->sik", self.hess, coef)
        eig = np.linalg.eigvalsh(M)
        if not np.all(eig[:, 0] > PD_RTOL * np.maximum(np.abs(eig[:, -1]), 1e-300)):
            return False, "kinetic part not positive definite (∂²E/∂q̇² has a non-positive eigenvalue)"
        return True, "admissible"
