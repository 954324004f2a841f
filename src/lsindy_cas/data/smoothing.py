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
from functools import lru_cache

import numpy as np

from .._validate import check_int
from .trajectory import Trajectory

__all__ = ["Smoothed", "smooth", "whittaker", "force_switches", "finite_difference", "add_noise",
           "VelocityEstimate", "estimate_velocities", "truncation_error", "UNDERSMOOTH",
           "MIN_POSITION_SAMPLES", "MIN_POSITION_STEPS"]

UNDERSMOOTH = 0.1
# Likelihood noise / robust noise above which a column is not smoothed (white noise: 0.9–1.1; the
# passive spherical pendulum at L = 0.3, φ̇ 46, 130, 51 rad/s in three samples: 3e4).
NOT_NOISE = 10.0
_MAX_BLOCK = 1500          # longer records are smoothed in overlapping blocks (eigh is O(n³))
_OVERLAP = 150
# λ·s_max from 1e-6 (no smoothing) to 1e12 (a polynomial of degree d − 1), 10 points per decade.
_LOG_GRID = np.arange(-6.0, 12.0001, 0.1)


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


def _divided_difference(t: np.ndarray, d: int) -> np.ndarray:
    """Dense d-th divided-difference operator (N − d, N), scaled by the mean step to order 1."""
    h = np.mean(np.diff(t))
    D = np.eye(len(t))
    for k in range(1, d + 1):
        span = (t[k:] - t[:-k]) / (k * h)
        D = (D[1:] - D[:-1]) / span[:, None]
    return D


@lru_cache(maxsize=32)
def _eig(n: int, d: int, steps: bytes | None, breaks: bytes):
    t = np.arange(n, dtype=float) if steps is None else np.r_[0.0, np.cumsum(np.frombuffer(steps))]
    D = _divided_difference(t, d)
    cut = np.frombuffer(breaks, dtype=np.int64)
    if cut.size:                       # rows r with r < j < r + d straddle the switch at sample j
        rows = np.arange(n - d)
        keep = ~np.any((rows[:, None] < cut[None, :]) & (cut[None, :] < rows[:, None] + d), axis=1)
        D = D[keep]
    s, U = np.linalg.eigh(D.T @ D)
    return np.maximum(s, 0.0), U


def _basis(t: np.ndarray, d: int, breaks=()):
    dt = np.diff(t)
    uniform = np.allclose(dt, dt[0], rtol=1e-6, atol=0)
    steps = None if uniform else np.ascontiguousarray(dt / dt.mean()).tobytes()
    return _eig(len(t), d, steps, np.asarray(breaks, dtype=np.int64).tobytes())


def smoother_map(t: np.ndarray, Q: np.ndarray, lam: float, order: int = 3):
    """The linear map :func:`smooth` applied to one column of a run: ``(U, f)`` with
    H = U diag(f) Uᵀ, from the column's penalty ``lam`` as :class:`Smoothed` stores it.

    Only for a run smoothed as one block (at most ``_MAX_BLOCK`` samples); longer runs are smoothed
    in overlapping blocks and have no single such map.
    """
    if len(t) > _MAX_BLOCK:
        raise ValueError(f"a run of {len(t)} samples is smoothed in blocks of at most "
                         f"{_MAX_BLOCK}: it has no single smoother matrix")
    s, U = _basis(t, order, force_switches(Q))
    return U, 1.0 / (1.0 + lam / s.max() * s)


def force_switches(Q: np.ndarray) -> np.ndarray:
    """Samples j at which a piecewise-constant (sample-and-hold) force changes, else empty.

    Parameters
    ----------
    Q : array (N, n)
        Applied generalized forces.

    Returns
    -------
    int array
        Indices j (Q[j] ≠ Q[j − 1]) when at most a fifth of the intervals change (a held input);
        an empty array for constant or continuously varying forces.
    """
    change = np.any(np.diff(Q, axis=0) != 0, axis=1)
    if not change.any() or change.mean() > 0.2:
        return np.zeros(0, dtype=np.int64)
    return np.flatnonzero(change) + 1


def whittaker(t, y, *, order: int = 3, lam: float | None = None, undersmooth: float = 1.0,
              breaks=()):
    """Whittaker smoother of one or more columns, penalty chosen by marginal likelihood (or given).

    Parameters
    ----------
    t : array (N,)
        Sample times (strictly increasing; need not be uniform).
    y : array (N,) or (N, m)
        Column(s) to smooth; each column gets its own λ.
    order : int
        Order d of the penalised divided difference (3: keeps quadratic trends).
    lam : float, optional
        Dimensionless penalty (relative to the largest eigenvalue of D_dᵀD_d); default: maximum
        marginal likelihood.
    undersmooth : float
        Factor in (0, 1] applied to the chosen λ (< 1 keeps more detail).
    breaks : sequence of int
        Samples where the d-th derivative may jump (force switches): not penalised across.

    Returns
    -------
    z : array like ``y``
        Smoothed values.
    noise, lam : arrays (m,)
        Noise estimate σ̂ and the λ used, per column.
    error : array like ``y``
        Standard deviation of the noise left in each smoothed value.
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    col = y.ndim == 1
    Y = y[:, None] if col else y
    if Y.ndim != 2 or Y.shape[0] != len(t):
        raise ValueError(f"y must have {len(t)} rows (one per sample), got shape {y.shape}")
    check_int("order", order, low=1, high=6)
    if not 0 < undersmooth <= 1:
        raise ValueError(f"undersmooth must be in (0, 1], got {undersmooth}")
    if lam is not None and not lam >= 0:
        raise ValueError(f"lam must be ≥ 0, got {lam}")
    breaks = np.asarray(breaks, dtype=np.int64)
    if len(t) <= _MAX_BLOCK:
        Z, noise, err, lams = _whittaker_block(t, Y, order, lam, undersmooth, breaks)
    else:
        Z, noise, err, lams = _whittaker_blocks(t, Y, order, lam, undersmooth, breaks)
    return (Z[:, 0] if col else Z), noise, (err[:, 0] if col else err), lams


def _whittaker_block(t, Y, d, lam, undersmooth, breaks):
    n, m = Y.shape
    if n <= 2 * d + 2:                     # too short to smooth: leave as is
        return Y.copy(), np.zeros(m), np.zeros((n, m)), np.zeros(m)
    s, U = _basis(t, d, breaks)
    C = U.T @ Y                                            # (n, m) spectral coefficients
    scale = s.max()
    pen = s > scale * 1e-12                                # penalised directions (others: polynomials)
    grid = 10.0 ** _LOG_GRID / scale
    # Prior: the penalised coefficients c_k ~ N(0, σ² (1 + 1/(λ s_k))); profile σ² out.
    V = 1.0 + 1.0 / (grid[:, None] * s[None, pen])         # (g, n_pen)
    logdet = np.log(V).sum(axis=1)
    Z = np.empty_like(Y)
    noise, err, lams = np.empty(m), np.empty((n, m)), np.empty(m)
    U2 = U ** 2
    n_pen = int(pen.sum())
    robust = _robust_noise(t, Y, d) if lam is None else None
    for j in range(m):
        if lam is None:
            c2 = C[pen, j] ** 2
            sig2 = (c2[None, :] / V).mean(axis=1)
            nll = n_pen * np.log(np.maximum(sig2, 1e-300)) + logdet
            lam_j = grid[int(np.argmin(nll))]
        else:
            lam_j = float(lam) / scale
        f = 1.0 / (1.0 + lam_j * s)
        resid = (1.0 - f) * C[:, j]
        sig2 = float(resid @ resid) / max(n - f.sum(), 1.0)
        if robust is not None and 0 < robust[j] and sig2 > (NOT_NOISE * robust[j]) ** 2:
            Z[:, j], noise[j], err[:, j], lams[j] = Y[:, j], robust[j], robust[j], 0.0
            continue
        lam_u = lam_j * undersmooth
        fu = 1.0 / (1.0 + lam_u * s)
        Z[:, j] = U @ (fu * C[:, j])
        noise[j] = np.sqrt(sig2)
        err[:, j] = np.sqrt(sig2 * (U2 @ fu ** 2))           # σ̂² diag(H Hᵀ), H = U diag(fu) Uᵀ
        lams[j] = lam_u * scale
    return Z, noise, err, lams


def _robust_noise(t, Y, d) -> np.ndarray:
    """Noise std per column (m,) from the median |d-th divided difference| (a few large ones do
    not move it); 0 (no information) when most vanish, as for a quantised signal."""
    D = _divided_difference(t, d)
    return np.median(np.abs(D @ Y), axis=0) / (0.6745 * np.median(np.linalg.norm(D, axis=1)))


def _blocks(n: int, breaks):
    """Overlapping windows [lo, hi) of at most ``_MAX_BLOCK`` samples covering n samples: yields
    (lo, hi, start, stop, the switches inside the window relative to lo); each window's result is
    kept on [start, stop) only, away from its edges (``_OVERLAP``)."""
    step, start = _MAX_BLOCK - 2 * _OVERLAP, 0
    while start < n:
        hi = min(n, max(0, start - _OVERLAP) + _MAX_BLOCK)
        lo = max(0, hi - _MAX_BLOCK)
        stop = min(n, start + step) if hi < n else n
        yield lo, hi, start, stop, breaks[(breaks > lo) & (breaks < hi)] - lo
        start = stop


def _whittaker_blocks(t, Y, d, lam, undersmooth, breaks):
    """Overlapping blocks of ≤ _MAX_BLOCK samples; each keeps its central part."""
    Z, err = np.empty_like(Y), np.empty_like(Y)
    stats = []
    for lo, hi, start, stop, br in _blocks(len(Y), breaks):
        Zb, noise_b, err_b, lam_b = _whittaker_block(t[lo:hi], Y[lo:hi], d, lam, undersmooth, br)
        Z[start:stop] = Zb[start - lo:stop - lo]
        err[start:stop] = err_b[start - lo:stop - lo]
        stats.append((stop - start, noise_b, lam_b))
    w = np.array([c for c, _, _ in stats], float)
    noise = np.sqrt(np.average(np.array([s[1] for s in stats]) ** 2, axis=0, weights=w))
    lams = np.exp(np.average(np.log(np.maximum(np.array([s[2] for s in stats]), 1e-300)), axis=0,
                             weights=w))
    return Z, noise, err, lams


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


# positions only (kept importable from here): velocities differentiated from the smoothed positions
from .velocities import (MIN_POSITION_SAMPLES, MIN_POSITION_STEPS, VelocityEstimate,  # noqa: E402
                         estimate_velocities, truncation_error)
