"""The Whittaker smoother on arrays: penalised least squares ‖z − y‖² + λ‖D_d z‖² per column, with
λ and the noise chosen by marginal likelihood, penalty rows across force switches dropped, and
long records in overlapping blocks.  :mod:`~lsindy_cas.data.smoothing` applies it to
trajectories and :mod:`~lsindy_cas.data.velocities` differentiates it (the method's notes are in
:mod:`~lsindy_cas.data.smoothing`)."""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .._validate import check_int

__all__ = ["whittaker", "whittaker_block", "smoother_map", "force_switches", "basis", "blocks",
           "robust_noise", "MAX_BLOCK", "NOT_NOISE"]

# Likelihood noise / robust noise above which a column is not smoothed (white noise: 0.9–1.1; the
# passive spherical pendulum at L = 0.3, φ̇ 46, 130, 51 rad/s in three samples: 3e4).
NOT_NOISE = 10.0
MAX_BLOCK = 1500          # longer records are smoothed in overlapping blocks (eigh is O(n³))
_OVERLAP = 150
# λ·s_max from 1e-6 (no smoothing) to 1e12 (a polynomial of degree d − 1), 10 points per decade.
_LOG_GRID = np.arange(-6.0, 12.0001, 0.1)


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


def basis(t: np.ndarray, d: int, breaks=()):
    dt = np.diff(t)
    uniform = np.allclose(dt, dt[0], rtol=1e-6, atol=0)
    steps = None if uniform else np.ascontiguousarray(dt / dt.mean()).tobytes()
    return _eig(len(t), d, steps, np.asarray(breaks, dtype=np.int64).tobytes())


def smoother_map(t: np.ndarray, Q: np.ndarray, lam: float, order: int = 3):
    """The linear map :func:`smooth` applied to one column of a run: ``(U, f)`` with
    H = U diag(f) Uᵀ, from the column's penalty ``lam`` as
    :class:`~lsindy_cas.data.smoothing.Smoothed` stores it.

    Only for a run smoothed as one block (at most ``MAX_BLOCK`` samples); longer runs are smoothed
    in overlapping blocks and have no single such map.
    """
    if len(t) > MAX_BLOCK:
        raise ValueError(f"a run of {len(t)} samples is smoothed in blocks of at most "
                         f"{MAX_BLOCK}: it has no single smoother matrix")
    s, U = basis(t, order, force_switches(Q))
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
    if len(t) <= MAX_BLOCK:
        Z, noise, err, lams = whittaker_block(t, Y, order, lam, undersmooth, breaks)
    else:
        Z, noise, err, lams = _whittaker_blocks(t, Y, order, lam, undersmooth, breaks)
    return (Z[:, 0] if col else Z), noise, (err[:, 0] if col else err), lams


def whittaker_block(t, Y, d, lam, undersmooth, breaks):
    n, m = Y.shape
    if n <= 2 * d + 2:                     # too short to smooth: leave as is
        return Y.copy(), np.zeros(m), np.zeros((n, m)), np.zeros(m)
    s, U = basis(t, d, breaks)
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
    robust = robust_noise(t, Y, d) if lam is None else None
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


def robust_noise(t, Y, d) -> np.ndarray:
    """Noise std per column (m,) from the median |d-th divided difference| (a few large ones do
    not move it); 0 (no information) when most vanish, as for a quantised signal."""
    D = _divided_difference(t, d)
    return np.median(np.abs(D @ Y), axis=0) / (0.6745 * np.median(np.linalg.norm(D, axis=1)))


def blocks(n: int, breaks):
    """Overlapping windows [lo, hi) of at most ``MAX_BLOCK`` samples covering n samples: yields
    (lo, hi, start, stop, the switches inside the window relative to lo); each window's result is
    kept on [start, stop) only, away from its edges (``_OVERLAP``)."""
    step, start = MAX_BLOCK - 2 * _OVERLAP, 0
    while start < n:
        hi = min(n, max(0, start - _OVERLAP) + MAX_BLOCK)
        lo = max(0, hi - MAX_BLOCK)
        stop = min(n, start + step) if hi < n else n
        yield lo, hi, start, stop, breaks[(breaks > lo) & (breaks < hi)] - lo
        start = stop


def _whittaker_blocks(t, Y, d, lam, undersmooth, breaks):
    """Overlapping blocks of ≤ MAX_BLOCK samples; each keeps its central part."""
    Z, err = np.empty_like(Y), np.empty_like(Y)
    stats = []
    for lo, hi, start, stop, br in blocks(len(Y), breaks):
        Zb, noise_b, err_b, lam_b = whittaker_block(t[lo:hi], Y[lo:hi], d, lam, undersmooth, br)
        Z[start:stop] = Zb[start - lo:stop - lo]
        err[start:stop] = err_b[start - lo:stop - lo]
        stats.append((stop - start, noise_b, lam_b))
    w = np.array([c for c, _, _ in stats], float)
    noise = np.sqrt(np.average(np.array([s[1] for s in stats]) ** 2, axis=0, weights=w))
    lams = np.exp(np.average(np.log(np.maximum(np.array([s[2] for s in stats]), 1e-300)), axis=0,
                             weights=w))
    return Z, noise, err, lams
