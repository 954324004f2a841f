"""Small steps of :class:`~lsindy_cas.identify.estimator.LagrangianSINDy` kept apart to keep the
estimator short: input checks, the corrected coefficients, sympy assembly and rounding."""
from __future__ import annotations

import numpy as np
import sympy as sp

from ..data.trajectory import Trajectory
from ..symbolic.library import Library
from .uncertainty import corrected_coef, corrected_null, noise_gram

__all__ = ["combine"]


def _check_trajectories(trajectories, coords, what="trajectories") -> list:
    if isinstance(trajectories, Trajectory):
        trajectories = [trajectories]
    try:
        trajectories = list(trajectories)
    except TypeError:
        raise TypeError(f"{what} must be a Trajectory or a list of them") from None
    if not trajectories:
        raise ValueError(f"{what} is empty")
    for tr in trajectories:
        if not isinstance(tr, Trajectory):
            raise TypeError(f"{what} must contain Trajectory objects, got {type(tr).__name__}")
    return [tr.reorder(coords) for tr in trajectories]


def _corrected(bal, grads, w, state_var, support, scale_system) -> np.ndarray:
    """Coefficients (p,) on ``support`` with the regressor-noise Gram removed."""
    S = list(support)
    N = noise_gram(grads, state_var, S, w)
    coef = np.zeros(bal.A.shape[1])
    if bal.b is not None:
        coef[S] = corrected_coef(bal.A, bal.b, S, N)
        return coef
    coef[S] = corrected_null(bal.A, S, N, scale_system)
    return coef


def combine(lib: Library, coef) -> sp.Expr:
    """Σ_j coef_j θ_j over the non-zero coefficients (sympy)."""
    return sp.Add(*[sp.Float(float(coef[j]), 15) * lib.exprs[j] for j in np.flatnonzero(coef)])


def _fmt(expr, digits: int = 4) -> str:
    """Readable form with coefficients rounded to ``digits`` significant digits."""
    return str(sp.N(expr, digits))


def run_variance(smoothed, smoothing: str):
    """Per run, the noise variance left in each state column (2n,) of the balance's states (None
    without smoothing, i.e. the derivative form)."""
    if smoothed is None:
        return None
    return [(s.error ** 2).mean(axis=0) if smoothing == "auto" else s.noise ** 2 for s in smoothed]
