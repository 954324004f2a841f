"""Denoising of measured states, with the strength chosen from the data, and noise estimates.

The energy balance evaluates the library Θ at the measured states, so noise in q and q̇ enters the
regressors (errors in variables).  Two tools deal with it here:

- :func:`smooth` — a Whittaker smoother (penalised least squares ‖z − y‖² + λ‖D_d z‖², D_d the
  d-th divided difference, i.e. a discrete smoothing spline) per state column.  λ and the noise
  variance are chosen by maximum marginal likelihood (the smoother read as a Gaussian prior on the
  d-th differences; Wahba's GML).  Unlike GCV, which was measured to oversmooth noise-free data by
  up to 10⁴ × the noise level (it cannot tell smooth signal from noise when there is none), the
  likelihood leaves clean data essentially untouched and smooths noisy data as much as they need.
  The same fit gives the noise level of each column and the variance of what remains after
  smoothing, which the errors-in-variables correction (:mod:`lsindy_cas.identify.uncertainty`) and the
  sample weights use.
- Piecewise-constant inputs make the accelerations jump where the force jumps: the penalty rows
  whose stencil straddles a force switch are dropped, so the kinks in q̇ there are kept (a
  smoother that rounds them was measured to leave 2e-4 errors in q̇ even on noise-free data).
- Motion the sampling barely resolves (φ̇ near a spherical pendulum's pole) reads as noise: a column
  whose noise exceeds ``NOT_NOISE`` × the median-difference estimate is left as measured.
- :func:`finite_difference` — the paper's route for comparison: accelerations by central finite
  differences of the (noisy) velocities, for the derivative form (eq. 4).

Why undersmooth: the likelihood balances bias against variance for each column, but in the regression the
variance part averages out over thousands of samples and is corrected for (errors in variables),
while the bias part (flattened peaks) is systematic.  The default takes a tenth of that λ
(measured on the rich protocol: the worst coefficient error at σ = 5e-2 drops from 3.6 % to 2.4 % on
the spherical pendulum, unchanged elsewhere; ``benchmarks/noise_sweep.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .trajectory import Trajectory
from .whittaker import NOT_NOISE, force_switches, whittaker  # noqa: F401 (importable here)

__all__ = ["Smoothed", "smooth", "whittaker", "force_switches", "finite_difference", "add_noise",
           "UNDERSMOOTH"]

UNDERSMOOTH = 0.1
@dataclass
class Smoothed:
    """A smoothed trajectory and what the smoother learnt about the noise.

    Attributes
    ----------
    trajectory : Trajectory
        Smoothed positions and velocities (no accelerations), same forces and times.
    raw : Trajectory
        The input.
    noise : array (2n,)
        Estimated standard deviation of the measurement noise of each state column [q, q̇]
        (units of that column), σ̂² = RSS / (N − tr H) at the likelihood-chosen λ.
    error : array (n_samples, 2n)
        Standard deviation of the noise left in each smoothed sample, σ̂ √((H Hᵀ)_ii) (larger
        near the ends of the run, where the smoother has fewer neighbours to average).
    lam : array (2n,)
        Penalty λ used per column (0 = not smoothed).
    """

    trajectory: Trajectory
    raw: Trajectory
    noise: np.ndarray
    error: np.ndarray
    lam: np.ndarray = field(repr=False)


def smooth(trajectory: Trajectory, *, order: int = 3, undersmooth: float = UNDERSMOOTH,
           lam: float | None = None) -> Smoothed:
    """Smooth the positions and velocities of one run, each column with its own penalty.

    Parameters
    ----------
    trajectory : Trajectory
        Measured run; forces ``Q`` are taken as exact (they are commanded, not measured).  Where a
        held (piecewise-constant) force switches, the accelerations may jump.
    order : int
        Penalised difference order (see :func:`whittaker`).
    undersmooth : float
        Factor on the likelihood-chosen penalty (default 0.1, see the module notes).
    lam : float, optional
        Fixed dimensionless penalty instead of the likelihood choice.

    Returns
    -------
    Smoothed
    """
    if not isinstance(trajectory, Trajectory):
        raise TypeError(f"trajectory must be a Trajectory, got {type(trajectory).__name__}")
    tr = trajectory
    n = len(tr.coords)
    if tr.velocities == "estimated":
        # q̇ came from the smoother already (estimate_velocities): keep it and its error; smoothing
        # it again would take the estimate's own smoothness for an absence of noise.
        Zq, nq, eq, lq = whittaker(tr.t, tr.q, order=order, lam=lam, undersmooth=undersmooth,
                                   breaks=force_switches(tr.Q))
        Z, err = np.hstack([Zq, tr.qd]), np.hstack([eq, tr.qd_error])
        noise = np.r_[nq, np.sqrt((tr.qd_error ** 2).mean(axis=0))]
        out = Trajectory(tr.t, Z[:, :n], Z[:, n:], tr.coords, Q=tr.Q,
                         source=f"{tr.source} (smoothed)")
        return Smoothed(out, tr, noise, err, np.r_[lq, np.zeros(n)])
    Z, noise, err, lams = whittaker(tr.t, tr.X, order=order, lam=lam, undersmooth=undersmooth,
                                    breaks=force_switches(tr.Q))
    out = Trajectory(tr.t, Z[:, :n], Z[:, n:], tr.coords, Q=tr.Q, source=f"{tr.source} (smoothed)")
    return Smoothed(out, tr, noise, err, lams)


def finite_difference(trajectory: Trajectory) -> Trajectory:
    """The run with accelerations from second-order central differences of q̇ (paper-style).

    Parameters
    ----------
    trajectory : Trajectory

    Returns
    -------
    Trajectory
        Same data with ``qdd`` (n_samples, n_coords) = d q̇/dt by ``numpy.gradient`` (one-sided,
        second order at the ends).
    """
    if not isinstance(trajectory, Trajectory):
        raise TypeError(f"trajectory must be a Trajectory, got {type(trajectory).__name__}")
    tr = trajectory
    qdd = np.gradient(tr.qd, tr.t, axis=0, edge_order=2)
    return Trajectory(tr.t, tr.q, tr.qd, tr.coords, Q=tr.Q, qdd=qdd,
                      source=f"{tr.source} (finite-difference accelerations)")


def add_noise(trajectory: Trajectory, sigma: float, rng: np.random.Generator) -> Trajectory:
    """Additive Gaussian noise N(0, σ²) on every q and q̇ column (absolute σ); drops ``qdd``.

    Parameters
    ----------
    trajectory : Trajectory
    sigma : float
        Standard deviation (units of each column), ≥ 0.
    rng : numpy.random.Generator
        Seeded generator (so experiments repeat).
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    if not np.isfinite(sigma) or sigma < 0:
        raise ValueError(f"sigma must be a finite number ≥ 0, got {sigma}")
    tr = trajectory
    q = tr.q + sigma * rng.standard_normal(tr.q.shape)
    qd = tr.qd + sigma * rng.standard_normal(tr.qd.shape)
    return Trajectory(tr.t, q, qd, tr.coords, Q=tr.Q, source=f"{tr.source} + N(0, {sigma:g}²)")

