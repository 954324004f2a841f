"""The linear systems of the energy balance, built from trajectories and a library.

- derivative form (paper eq. 4):  Γ(X, Ẋ) ξ = dE/dt = P,  Γ = ∇Θ·ẋ (needs accelerations);
- integral (weak) form:            [Θ(x(t_b)) − Θ(x(t_a))] ξ = ∫_{t_a}^{t_b} P dt  (no derivatives);
- passive scheme: the same matrices with right-hand side 0 (ξ in the near null space), the scale
  coming from a short actuated record (paper eq. 8).

Windows of the integral form.  Least squares over *every* window [t_a, t_b] of a run, all weighted
alike, is the same problem as  Θ(x(t_i)) ξ − W(t_i) = c  for all samples i with one free constant c
per run, W the cumulative work: Σ_{a<b} (r_b − r_a)² = N Σ_i (r_i − r̄)².  So the default stacks all
windows at the cost of one row per sample — rows are deviations from the run's (weighted) mean.
Compared with short windows this averages the noise of Θ over the whole run instead of taking the
difference of two noisy samples.  Fixed-length windows (``window=w``) remain available.

Work.  W(t) = ∫ Q·q̇ dt, taken as :mod:`~lsindy_cas.identify.work` says (held or smooth forces).

Each form returns an :class:`EnergyBalance`, which also carries the stacked state gradients used to
recognise supports that are identities rather than conserved quantities, and the sample states on
which physical admissibility is checked.
"""
from __future__ import annotations

import numpy as np

from .._validate import check_int
from ..symbolic.library import Library
from .energy_balance import EnergyBalance, is_passive
from .work import HOLDS, cumulative_work, increments_preferred, work, work_error  # noqa: F401

__all__ = ["EnergyBalance", "derivative_form", "integral_form", "cumulative_work", "HOLDS",
           "increments_preferred"]

def _stack_states(library: Library, trajectories):
    X = np.vstack([tr.X for tr in trajectories])
    D = library.grad(X).reshape(-1, len(library))
    return X, D


def _groups(trajectories, lengths=None) -> np.ndarray:
    lengths = [tr.n_samples for tr in trajectories] if lengths is None else lengths
    return np.repeat(np.arange(len(lengths)), lengths)


def derivative_form(library: Library, trajectories, passive: bool | None = None,
                    compress: bool | None = None, chunk: int | None = None) -> EnergyBalance:
    """Γ ξ = P over all samples of all trajectories (paper eq. 4); needs accelerations ``qdd``.

    ``compress``/``chunk``: stream the rows into block-wise R factors (same Gram matrices, bounded
    memory); None (default) does so when the dense rows and gradients would exceed
    :data:`lsindy_cas.identify.stream.STREAM_BUDGET` floats (see :func:`integral_form`).
    """
    passive = is_passive(trajectories) if passive is None else passive
    if _compress(library, trajectories, compress):
        from .stream import compressed_balance
        return compressed_balance(library, trajectories, "derivative", passive=passive,
                                  chunk=chunk)
    A = np.vstack([library.gamma(tr.X, tr.Xdot) for tr in trajectories])
    b = None if passive else np.concatenate([tr.power for tr in trajectories])
    X, D = _stack_states(library, trajectories)
    return EnergyBalance(A, b, D, X, "derivative", groups=_groups(trajectories))


def _compress(library, trajectories, compress) -> bool:
    if compress is not None:
        return bool(compress)
    from .stream import STREAM_BUDGET
    n_state = 2 * len(library.coords.names)         # A (one row per sample) and D (2n per sample)
    return sum(tr.n_samples for tr in trajectories) * len(library) * (1 + n_state) > STREAM_BUDGET


def _weighted_centre(M: np.ndarray, w: np.ndarray) -> np.ndarray:
    return M - (w @ M) / w.sum()


def integral_form(library: Library, trajectories, window: int | None = None, stride: int = 1,
                  passive: bool | None = None, weights=None, hold: str = "auto",
                  noise=None, compress: bool | None = None, chunk: int | None = None
                  ) -> EnergyBalance:
    """The integral (weak) energy balance: no derivatives of the data.

    Parameters
    ----------
    library : Library
    trajectories : list of Trajectory
    window : int, optional
        None (default): all windows of every run, as one centred row per sample (see the module
        notes).  An integer: rows Θ(x_{i+w}) − Θ(x_i) = W(t_{i+w}) − W(t_i), windows of ``w``
        samples.
    stride : int
        Fixed windows only: step between window starts (≥ 1).
    passive : bool, optional
        Right-hand side 0 (passive scheme); default: when no power is fed in.
    weights : list of arrays (n_samples,), optional
        All-windows form only: per-sample weights (e.g. inverse noise variance of the energy).
    hold : {"auto", "zoh", "smooth"}
        How the forces act between samples (see :func:`cumulative_work`).
    noise : list of arrays (2n,), optional
        Per trajectory, the standard deviation of the noise left in each state column (see
        :func:`cumulative_work`); None: the states are taken as exact.
    compress : bool, optional
        All-windows form without weights: stream the rows, ``chunk`` samples at a time, into
        block-wise R factors (:mod:`lsindy_cas.identify.stream`) — the same Gram matrices per
        trajectory and jackknife block, so the same search, held-out errors and jackknife, in
        memory independent of the number of samples.  None (default): when the dense rows and
        state gradients would exceed ``STREAM_BUDGET`` floats (then the noise model and the
        errors-in-variables correction, which need one row per sample, are not applied).

    Returns
    -------
    EnergyBalance
    """
    if window is not None:
        check_int("window", window, low=1)
        check_int("stride", stride, low=1)
        if weights is not None:
            raise ValueError("weights are only supported by the all-windows form (window=None)")
    passive = is_passive(trajectories) if passive is None else passive
    if window is None and weights is None and _compress(library, trajectories, compress):
        from .stream import compressed_balance
        return compressed_balance(library, trajectories, "integral", passive=passive, hold=hold,
                                  noise=noise, chunk=chunk)
    if weights is not None and len(weights) != len(trajectories):
        raise ValueError(f"weights must hold one array per trajectory ({len(trajectories)}), "
                         f"got {len(weights)}")
    rows, rhs, wts, sizes, rules, quad = [], [], [], [], [], 0.0
    for k, tr in enumerate(trajectories):
        th = library.theta(tr.X)
        W, rule = work(tr, hold, None if noise is None else noise[k])
        rules.append(rule)
        E = work_error(tr, rule, W)
        if window is None:
            w = np.ones(tr.n_samples) if weights is None else np.asarray(weights[k], float)
            if w.shape != (tr.n_samples,) or not np.all(np.isfinite(w)) or np.any(w <= 0):
                raise ValueError(f"weights[{k}] must be {tr.n_samples} positive numbers")
            sw = np.sqrt(w)[:, None]
            rows.append(sw * _weighted_centre(th, w))
            rhs.append(sw[:, 0] * _weighted_centre(W, w))
            quad += float(np.sum((sw[:, 0] * _weighted_centre(E, w)) ** 2))
            wts.append(w)
            sizes.append(tr.n_samples)
        else:
            if tr.n_samples <= window:
                raise ValueError(f"{tr.source}: {tr.n_samples} samples is too few for a window "
                                 f"of {window}")
            i = np.arange(0, tr.n_samples - window, stride)
            rows.append(th[i + window] - th[i])
            rhs.append(W[i + window] - W[i])
            quad += float(np.sum((E[i + window] - E[i]) ** 2))
            sizes.append(len(i))
    X, D = _stack_states(library, trajectories)
    return EnergyBalance(np.vstack(rows), None if passive else np.concatenate(rhs), D, X, "integral",
                         groups=_groups(trajectories, sizes),
                         weights=np.concatenate(wts) if window is None else None,
                         centred=window is None, work_rules=rules,
                         quadrature=0.0 if passive else quad)
