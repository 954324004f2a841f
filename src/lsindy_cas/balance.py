"""The linear systems of the energy balance, built from trajectories and a library.

- derivative form (paper eq. 4):  Γ(X, Ẋ) ξ = dE/dt = P,  Γ = ∇Θ·ẋ (needs accelerations);
- integral form:                   [Θ(x(t_b)) − Θ(x(t_a))] ξ = ∫_{t_a}^{t_b} P dt  (no derivatives);
- passive scheme: the same matrices with right-hand side 0 (ξ in the near null space), the scale
  coming from a short actuated record (paper eq. 8).

Each form returns an :class:`EnergyBalance`, which also carries the stacked state gradients used to
recognise supports that are identities rather than conserved quantities, and the sample states on
which physical admissibility is checked.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .data import Trajectory
from .library import Library

__all__ = ["EnergyBalance", "derivative_form", "integral_form", "cumulative_work"]


@dataclass
class EnergyBalance:
    """``A ξ = b`` (or ``A ξ = 0`` when ``b`` is None), plus what the search needs to judge supports.

    Attributes
    ----------
    A : array (n_rows, p)
    b : array (n_rows,) or None
    D : array (n_samples * 2n, p)
        Stacked state gradients ∇Θ at the samples.
    X : array (n_samples, 2n)
        Sample states.
    form : str
        ``"derivative"`` or ``"integral"``.
    """

    A: np.ndarray
    b: np.ndarray | None
    D: np.ndarray
    X: np.ndarray
    form: str

    @property
    def passive(self) -> bool:
        return self.b is None


def _stack_states(library: Library, trajectories):
    X = np.vstack([tr.X for tr in trajectories])
    D = library.grad(X).reshape(-1, len(library))
    return X, D


def _is_passive(trajectories) -> bool:
    return all(not np.any(tr.power) for tr in trajectories)


def derivative_form(library: Library, trajectories, passive: bool | None = None) -> EnergyBalance:
    """Γ ξ = P over all samples of all trajectories (paper eq. 4); needs exact accelerations."""
    passive = _is_passive(trajectories) if passive is None else passive
    A = np.vstack([library.gamma(tr.X, tr.Xdot) for tr in trajectories])
    b = None if passive else np.concatenate([tr.power for tr in trajectories])
    X, D = _stack_states(library, trajectories)
    return EnergyBalance(A, b, D, X, "derivative")


def cumulative_work(tr: Trajectory) -> np.ndarray:
    """W(t_i) = ∫_{t_0}^{t_i} P dt (n_samples,), by integrating a cubic spline of P (4th order)."""
    from scipy.interpolate import CubicSpline   # lazy: scipy's import costs ~0.5 s per CLI call

    P = tr.power
    if not np.any(P):
        return np.zeros_like(P)
    return CubicSpline(tr.t, P).antiderivative()(tr.t)


def integral_form(library: Library, trajectories, window: int = 10, stride: int = 1,
                  passive: bool | None = None) -> EnergyBalance:
    """Rows Θ(x_{i+w}) − Θ(x_i) = W(t_{i+w}) − W(t_i) for windows of ``window`` samples.

    Parameters
    ----------
    window : int
        Window length in samples (≥ 1).
    stride : int
        Step between window starts (≥ 1).
    """
    if window < 1 or stride < 1:
        raise ValueError(f"window and stride must be at least 1, got {window}, {stride}")
    passive = _is_passive(trajectories) if passive is None else passive
    rows, rhs = [], []
    for tr in trajectories:
        if tr.n_samples <= window:
            raise ValueError(f"{tr.source}: {tr.n_samples} samples is too few for a window of {window}")
        th = library.theta(tr.X)
        W = cumulative_work(tr)
        i = np.arange(0, tr.n_samples - window, stride)
        rows.append(th[i + window] - th[i])
        rhs.append(W[i + window] - W[i])
    X, D = _stack_states(library, trajectories)
    return EnergyBalance(np.vstack(rows), None if passive else np.concatenate(rhs), D, X, "integral")
