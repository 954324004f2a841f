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
           "VelocityEstimate", "estimate_velocities", "UNDERSMOOTH", "MIN_POSITION_SAMPLES",
           "MIN_POSITION_STEPS"]

UNDERSMOOTH = 0.1
# Likelihood noise / robust noise above which a column is not smoothed (white noise: 0.9–1.1; the
# passive spherical pendulum at L = 0.3, φ̇ 46, 130, 51 rad/s in three samples: 3e4).
NOT_NOISE = 10.0
_MAX_BLOCK = 1500          # longer records are smoothed in overlapping blocks (eigh is O(n³))
_OVERLAP = 150
# λ·s_max from 1e-6 (no smoothing) to 1e12 (a polynomial of degree d − 1), 10 points per decade.
_LOG_GRID = np.arange(-6.0, 12.0001, 0.1)
# Positions only: the fewest samples a run needs for the likelihood to choose λ and the derivative
# to have neighbours on both sides (the smoother leaves runs of ≤ 2d + 2 = 8 samples untouched)...
MIN_POSITION_SAMPLES = 20
# ... and the fewest distinct quantisation steps the motion of a moving coordinate must span
# (below that the staircase, not the motion, makes the derivative).
MIN_POSITION_STEPS = 20


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


def _whittaker_blocks(t, Y, d, lam, undersmooth, breaks):
    """Overlapping blocks of ≤ _MAX_BLOCK samples; each keeps its central part."""
    n, m = Y.shape
    Z, err = np.empty_like(Y), np.empty_like(Y)
    stats = []
    step = _MAX_BLOCK - 2 * _OVERLAP
    start = 0
    while start < n:
        lo = max(0, start - _OVERLAP)
        hi = min(n, lo + _MAX_BLOCK)
        lo = max(0, hi - _MAX_BLOCK)
        br = breaks[(breaks > lo) & (breaks < hi)] - lo
        Zb, noise_b, err_b, lam_b = _whittaker_block(t[lo:hi], Y[lo:hi], d, lam, undersmooth, br)
        stop = min(n, start + step) if hi < n else n
        Z[start:stop] = Zb[start - lo:stop - lo]
        err[start:stop] = err_b[start - lo:stop - lo]
        stats.append((stop - start, noise_b, lam_b))
        start = stop
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
        Standard deviation of the error in each estimated velocity, σ̂ √((D H Hᵀ Dᵀ)_ii), D the
        derivative of the interpolating spline, H the smoother (noise part only, not the bias).
    """

    q: np.ndarray
    qd: np.ndarray
    noise: np.ndarray
    qd_error: np.ndarray


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


def _velocity_block(t, Y, d, undersmooth, breaks):
    Z, noise, _, lams = _whittaker_block(t, Y, d, None, undersmooth, breaks)
    s, U = _basis(t, d, breaks)
    Dv = _derivative_matrix(t)
    V, err = Dv @ Z, np.empty_like(Z)
    for j in range(Y.shape[1]):
        f = 1.0 / (1.0 + lams[j] / s.max() * s)
        DH = (Dv @ U) * f[None, :]                  # D H = D U diag(f) Uᵀ, and Uᵀ is orthogonal
        err[:, j] = noise[j] * np.sqrt((DH ** 2).sum(axis=1))
    return Z, V, noise, err


def estimate_velocities(t, q, Q=None, *, order: int = 3, undersmooth: float = 1.0,
                        source: str = "positions") -> VelocityEstimate:
    """Velocities from positions: the derivative of the Whittaker-smoothed positions.

    Each position column is smoothed with its penalty chosen by marginal likelihood
    (:func:`whittaker`; not undersmoothed by default: differentiation amplifies what is left of
    the noise), the smoothed samples are interpolated by a quintic spline (any sample times) and
    differentiated.  The error of each estimate is propagated exactly through the two linear maps.

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
    if n <= _MAX_BLOCK:
        Z, V, noise, err = _velocity_block(t, q2, order, undersmooth, breaks)
    else:                                      # overlapping blocks, each keeps its central part
        Z, V, err = np.empty_like(q2), np.empty_like(q2), np.empty_like(q2)
        stats, step, start = [], _MAX_BLOCK - 2 * _OVERLAP, 0
        while start < n:
            hi = min(n, max(0, start - _OVERLAP) + _MAX_BLOCK)
            lo = max(0, hi - _MAX_BLOCK)
            br = breaks[(breaks > lo) & (breaks < hi)] - lo
            Zb, Vb, noise_b, err_b = _velocity_block(t[lo:hi], q2[lo:hi], order, undersmooth, br)
            stop = min(n, start + step) if hi < n else n
            Z[start:stop], V[start:stop] = Zb[start - lo:stop - lo], Vb[start - lo:stop - lo]
            err[start:stop] = err_b[start - lo:stop - lo]
            stats.append((stop - start, noise_b))
            start = stop
        w = np.array([c for c, _ in stats], float)
        noise = np.sqrt(np.average(np.array([s for _, s in stats]) ** 2, axis=0, weights=w))
    return VelocityEstimate(Z, V, noise, err)
