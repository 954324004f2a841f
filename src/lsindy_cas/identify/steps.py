"""Small steps of :class:`~lsindy_cas.identify.estimator.LagrangianSINDy` kept apart to keep the
estimator short: input checks, the corrected coefficients, sympy assembly and rounding."""
from __future__ import annotations

import numpy as np

from ..data.trajectory import Trajectory
from .uncertainty import corrected_coef, corrected_null, noise_gram

__all__ = ["drift_simulator", "run_variance"]


def check_trajectories(trajectories, coords, what="trajectories") -> list:
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


def corrected_fit(bal, grads, w, state_var, support, scale_system) -> np.ndarray:
    """Coefficients (p,) on ``support`` with the regressor-noise Gram removed."""
    S = list(support)
    N = noise_gram(grads, state_var, S, w)
    coef = np.zeros(bal.A.shape[1])
    if bal.b is not None:
        coef[S] = corrected_coef(bal.A, bal.b, S, N)
        return coef
    coef[S] = corrected_null(bal.A, S, N, scale_system)
    return coef


def _fmt(expr, digits: int = 4) -> str:
    """Readable form with coefficients rounded to ``digits`` significant digits."""
    import sympy as sp
    return str(sp.N(expr, digits))


def run_variance(smoothed, smoothing: str):
    """Per run, the noise variance left in each state column (2n,) of the balance's states (None
    without smoothing, i.e. the derivative form)."""
    if smoothed is None:
        return None
    return [(s.error ** 2).mean(axis=0) if smoothing == "auto" else s.noise ** 2 for s in smoothed]


def drift_simulator(ode, n_coords: int, substeps: int = 8):
    """``(x0, t, u) -> X`` for the status check's short simulations: classical RK4 with
    ``substeps`` steps per sample interval and the force ``u(t_i, x_i)`` held over it.

    One compiled CasADi step per interval instead of an adaptive SciPy integrator calling back
    into Python for every stage (and importing ``scipy.integrate``, ~0.3 s): at 100 Hz and 8
    substeps the step is 1.25 ms, whose error on the benchmark systems over a 20-sample stretch is
    ~1e-10 of the states' range — far below the check's tolerance (5 %).
    """
    import casadi as ca

    from ..mechanics.rk4 import rk4_expr
    n = 2 * n_coords
    x, u, h = ca.MX.sym("x", n), ca.MX.sym("u", n_coords), ca.MX.sym("h")
    step = ca.Function("rk4_interval", [x, u, h], [rk4_expr(ode, x, u, h, substeps)])

    def simulate(x0, t, u_fn):
        X = np.empty((len(t), n))
        X[0] = x0
        for i in range(len(t) - 1):
            ui = np.broadcast_to(np.asarray(u_fn(t[i], X[i]), float), (n_coords,))
            X[i + 1] = np.asarray(step(X[i], ui, t[i + 1] - t[i])).ravel()
        if not np.all(np.isfinite(X)):
            raise RuntimeError("the simulation diverged")
        return X
    return simulate
