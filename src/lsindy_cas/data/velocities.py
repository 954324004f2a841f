"""Velocities from measured positions (encoders, motion capture): the derivative of the
Whittaker-smoothed positions (:func:`lsindy_cas.data.smoothing.whittaker`), with its error — the
noise part propagated through the smoother and the spline's derivative, and the derivative's own
truncation error (:func:`truncation_error`), which is the whole error on noise-free data.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .whittaker import MAX_BLOCK, basis, blocks, force_switches, whittaker_block

__all__ = ["VelocityEstimate", "estimate_velocities", "truncation_error", "MIN_POSITION_SAMPLES",
           "MIN_POSITION_STEPS"]

# Positions only: the fewest samples a run needs for the likelihood to choose λ and the derivative
# to have neighbours on both sides (the smoother leaves runs of ≤ 2d + 2 = 8 samples untouched)...
MIN_POSITION_SAMPLES = 20
# ... and the fewest distinct quantisation steps the motion of a moving coordinate must span
# (below that the staircase, not the motion, makes the derivative).
MIN_POSITION_STEPS = 20


@dataclass
class VelocityEstimate:
    """Velocities estimated from measured positions (:func:`estimate_velocities`).

    Attributes
    ----------
    q, qd : arrays (n_samples, n_coords)
        Smoothed positions and their time derivative.
    noise : array (n_coords,)
        Estimated noise std of the measured positions (units of each coordinate).
    qd_error : array (n_samples, n_coords)
        Standard deviation of the error in each estimated velocity: the noise part
        σ̂ √((D H Hᵀ Dᵀ)_ii) (D the derivative of the interpolating spline, H the smoother) and
        the truncation error ``truncation`` added in quadrature.
    truncation : array (n_samples, n_coords)
        The derivative's error floor, h²/6 · |q⃛| (q⃛ the third derivative of the
        spline through the smoothed positions, h the local sample step): what the estimate is off
        by on noise-free data, the floor of its error (see :func:`truncation_error`).
    """

    q: np.ndarray
    qd: np.ndarray
    noise: np.ndarray
    qd_error: np.ndarray
    truncation: np.ndarray | None = None


def _check_positions(t, q, source):
    n_samples = len(t)
    if n_samples < MIN_POSITION_SAMPLES:
        raise ValueError(f"{source}: too few samples ({n_samples}) to estimate velocities from "
                         f"positions; need at least {MIN_POSITION_SAMPLES} (or give <q>_dot columns)")
    for j in range(q.shape[1]):
        levels = np.unique(q[:, j])
        if levels.size < 2:
            continue                             # at rest: zero velocity, estimated exactly
        span = levels[-1] - levels[0]
        step = np.diff(levels).min()
        if span / step < MIN_POSITION_STEPS:
            raise ValueError(f"{source}: positions too coarse to estimate velocities: column {j} "
                             f"moves over {span:.3g} in steps of {step:.3g} ({span / step:.0f} "
                             f"steps; need at least {MIN_POSITION_STEPS})")


def _derivative_matrix(t: np.ndarray) -> np.ndarray:
    """(N, N) matrix: values at the samples -> derivative of their quintic interpolating spline."""
    from scipy.interpolate import make_interp_spline
    k = 5 if len(t) > 5 else 3
    return make_interp_spline(t, np.eye(len(t)), k=k, axis=0).derivative()(t)


def truncation_error(t: np.ndarray, Z: np.ndarray) -> np.ndarray:
    """Error floor of the velocities differentiated from positions ``Z`` (n, m): h²/6 · |q⃛|.

    The spline's derivative is exact to O(h⁵) only where the motion is smooth at the scale of the
    sampling.  A force held over each sample interval (a digital controller's output) makes the
    acceleration jump by Δa at every sample; a smooth interpolant of such positions sees a path
    whose velocity is off by about Δa·h/12 (the mean of the sawtooth the jumps leave in q̇), with
    Δa ≈ h·q⃛, and a switch of a square-wave input leaves a ringing of the same order around it.
    h²/6 · |q⃛| is the error of the central difference, the plainest second-order estimate: a
    bound on smooth data, the right scale under held inputs.  Measured on the example files
    (cart-pendulum, held inputs, no noise), RMS over each run: the estimate's error 3.3e-5, 2.1e-5
    (x, θ; run 1, a sine) and 5.5e-4, 4.4e-4 (run 2, a square wave) against this floor's 8.4e-5,
    3.7e-4 and 6.8e-4, 7.0e-4.  On σ = 1e-3 data it is 1–30 % of the noise part, so it matters
    only on clean data, where it is the whole error.

    Parameters
    ----------
    t : array (n,)
    Z : array (n, m)
        Smoothed positions.

    Returns
    -------
    array (n, m)
        Per sample, q⃛ from the quintic spline through ``Z``, h the mean of the adjacent steps.
    """
    from scipy.interpolate import make_interp_spline
    if len(t) < 6:
        return np.zeros_like(Z)
    jerk = make_interp_spline(t, Z, k=5, axis=0).derivative(3)(t)
    dt = np.diff(t)
    h = np.r_[dt[0], 0.5 * (dt[1:] + dt[:-1]), dt[-1]]
    return h[:, None] ** 2 / 6.0 * np.abs(jerk)


def _velocity_block(t, Y, d, undersmooth, breaks):
    Z, noise, _, lams = whittaker_block(t, Y, d, None, undersmooth, breaks)
    s, U = basis(t, d, breaks)
    Dv = _derivative_matrix(t)
    V, err = Dv @ Z, np.empty_like(Z)
    for j in range(Y.shape[1]):
        f = 1.0 / (1.0 + lams[j] / s.max() * s)
        DH = (Dv @ U) * f[None, :]                  # D H = D U diag(f) Uᵀ, and Uᵀ is orthogonal
        err[:, j] = noise[j] * np.sqrt((DH ** 2).sum(axis=1))
    return Z, V, noise, err, truncation_error(t, Z)


def estimate_velocities(t, q, Q=None, *, order: int = 3, undersmooth: float = 1.0,
                        source: str = "positions") -> VelocityEstimate:
    """Velocities from positions: the derivative of the Whittaker-smoothed positions.

    Each position column is smoothed with its penalty chosen by marginal likelihood
    (:func:`whittaker`; not undersmoothed by default: differentiation amplifies what is left of
    the noise), the smoothed samples are interpolated by a quintic spline (any sample times) and
    differentiated.  The noise part of each estimate's error is propagated exactly through the two
    linear maps; the derivative's truncation error (:func:`truncation_error`) is added to it.

    Parameters
    ----------
    t : array (N,)
        Sample times, strictly increasing (need not be uniform).
    q : array (N, n)
        Measured positions.
    Q : array (N, n), optional
        Applied forces: where a held force switches, the acceleration may jump (not penalised).
    order, undersmooth
        As in :func:`whittaker`.
    source : str
        Name of the data for error messages.

    Returns
    -------
    VelocityEstimate

    Raises
    ------
    ValueError
        Fewer than ``MIN_POSITION_SAMPLES`` samples, or a coordinate whose motion spans fewer than
        ``MIN_POSITION_STEPS`` quantisation steps.
    """
    t = np.asarray(t, float)
    q = np.asarray(q, float)
    q2 = q[:, None] if q.ndim == 1 else q
    _check_positions(t, q2, source)
    breaks = force_switches(np.zeros_like(q2) if Q is None else np.asarray(Q, float))
    n = len(t)
    if n <= MAX_BLOCK:
        Z, V, noise, err, trunc = _velocity_block(t, q2, order, undersmooth, breaks)
    else:                                      # overlapping blocks, each keeps its central part
        Z, V, err, trunc = (np.empty_like(q2) for _ in range(4))
        stats = []
        for lo, hi, start, stop, br in blocks(n, breaks):
            Zb, Vb, noise_b, err_b, tr_b = _velocity_block(t[lo:hi], q2[lo:hi], order,
                                                           undersmooth, br)
            Z[start:stop], V[start:stop] = Zb[start - lo:stop - lo], Vb[start - lo:stop - lo]
            err[start:stop], trunc[start:stop] = err_b[start - lo:stop - lo], tr_b[start - lo:stop - lo]
            stats.append((stop - start, noise_b))
        w = np.array([c for c, _ in stats], float)
        noise = np.sqrt(np.average(np.array([s for _, s in stats]) ** 2, axis=0, weights=w))
    return VelocityEstimate(Z, V, noise, np.sqrt(err ** 2 + trunc ** 2), trunc)
