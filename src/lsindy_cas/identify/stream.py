"""Streamed energy balances: the rows of A ξ = b compressed block by block, in bounded memory.

Everything the search and the checks after it do with the balance depends on its rows only through
Gram matrices — of all rows (the scores, every least-squares fit, column norms, singular values),
of the rows of one trajectory (held-out folds over whole runs) or of one contiguous stretch of a
trajectory (the jackknife blocks and the held-out stretches of
:func:`~lsindy_cas.identify.uncertainty.block_ids`, :func:`~lsindy_cas.identify.held_out.fold_ids`).
So each such block of rows [A_β b_β] is replaced by its R factor (QR, R ᵀR = [A_β b_β]ᵀ[A_β b_β]):
at most p + 2 rows per block instead of one per sample, built ``chunk`` samples at a time by
updating R with QR of [R; new rows] (TSQR).  R factors rather than Gram matrices: least squares on
them is as accurate as on the rows (the condition number is not squared), so a streamed fit equals
the dense one to round-off.

All-windows integral form: the rows are centred per trajectory, which needs the run's mean before
the first row.  The block factors are built on the uncentred rows [θ_i, W_i, 1] and centred at the
end of the run by a column operation on R (R[:, j] −= R[:, 1] m_j, exact: the rows of R are linear
combinations of the sample rows).  The last column, the intercept, is kept (``intercept``): leaving
a block out re-centres the rest by projecting it off, as the dense jackknife does with its √w column.

What needs one row per sample and is therefore left out or subsampled on a compressed balance:

- ``X``, ``D``: the states and their gradients at a subsample of at most ``MAX_STATES`` samples
  (positive-definite kinetic part, Legendre's non-homogeneous terms, the passive degeneracy test,
  conserved quantities);
- the noise model (χ, the discrepancy cap on k) and the errors-in-variables refinement need per-row
  noise and are skipped (:attr:`EnergyBalance.per_sample` is False);
- dissipation columns (projected per row) are not supported.
"""
from __future__ import annotations

import numpy as np

from .._validate import check_int
from .energy_balance import EnergyBalance, is_passive
from .work import work

__all__ = ["compressed_balance", "block_edges", "STREAM_BUDGET", "MAX_STATES", "CHUNK"]

# Floats of the dense rows A and state gradients D (512 MB) above which balances are streamed:
# e.g. more than ~64,000 samples of the double pendulum's 209-term library.
STREAM_BUDGET = 2 ** 26
MAX_STATES = 5000          # states kept for the per-sample checks
CHUNK = 8192               # samples per QR update
N_BLOCKS = 10              # blocks per trajectory: uncertainty.N_BLOCKS (5 folds nest in them)


def block_edges(n: int, n_blocks: int = N_BLOCKS) -> np.ndarray:
    """Start of each block (and n): sample i is in block (i·n_blocks)//n, as ``block_ids``."""
    return -(-np.arange(n_blocks + 1) * n // n_blocks)          # ceil(β n / n_blocks)


class _TSQR:
    """R factor of a stream of row blocks, padded to a square (width × width) at the end."""

    def __init__(self, width: int):
        self.R = np.zeros((0, width))

    def add(self, rows: np.ndarray) -> None:
        self.R = np.linalg.qr(np.vstack([self.R, rows]), mode="r")

    def square(self) -> np.ndarray:
        w = self.R.shape[1]
        out = np.zeros((w, w))
        out[:len(self.R)] = self.R[:w]
        return out


def _run_blocks(rows, n: int, width: int, chunk: int) -> list:
    """R factors (width × width) of the N_BLOCKS blocks of a run, rows(lo, hi) streamed."""
    edges = block_edges(n)
    out = []
    for a, z in zip(edges[:-1], edges[1:]):
        acc = _TSQR(width)
        for lo in range(a, z, chunk):
            acc.add(rows(lo, min(z, lo + chunk)))
        out.append(acc.square())
    return out


def compressed_balance(library, trajectories, form: str, *, passive: bool | None = None,
                       hold: str = "auto", noise=None, chunk: int | None = None) -> EnergyBalance:
    """The derivative or all-windows integral balance of ``trajectories``, streamed and compressed.

    Parameters
    ----------
    library : Library
    trajectories : list of Trajectory
    form : {"derivative", "integral"}
        Derivative form (needs ``qdd``) or the all-windows integral form (rows centred per run).
    passive : bool, optional
        Right-hand side 0; default: when no power is fed in.
    hold, noise
        Integral form: the work integral's input hold and state noise (see
        :func:`lsindy_cas.identify.work.cumulative_work`).
    chunk : int, optional
        Samples per QR update (default ``CHUNK``); memory ~ chunk × p floats.

    Returns
    -------
    EnergyBalance
        ``compressed``: ``A``, ``b`` (and ``intercept``) hold N_BLOCKS R factors per trajectory,
        ``n_data_rows`` the number of samples, ``X``/``D`` a subsample of the states (module notes).
    """
    if form not in ("derivative", "integral"):
        raise ValueError(f"form must be 'derivative' or 'integral', got {form!r}")
    chunk = CHUNK if chunk is None else check_int("chunk", chunk, low=1)
    passive = is_passive(trajectories) if passive is None else passive
    p = len(library)
    centred = form == "integral"
    width = p + (0 if passive else 1) + (1 if centred else 0)
    M = np.empty((len(trajectories) * N_BLOCKS * width, width))
    groups, rules, n_total = [], [], 0
    for k, tr in enumerate(trajectories):
        n = tr.n_samples
        n_total += n
        if form == "derivative":
            if tr.qdd is None:
                raise ValueError(f"{tr.source}: the derivative form needs accelerations")
            P = tr.power

            def rows(lo, hi, tr=tr, P=P):
                G = library.gamma(tr.X[lo:hi], tr.Xdot[lo:hi])
                return G if passive else np.hstack([G, P[lo:hi, None]])
            R = _run_blocks(rows, n, width, chunk)
        else:
            W, rule = work(tr, hold, None if noise is None else noise[k])
            rules.append(rule)
            total = np.zeros(width - 1)

            def rows(lo, hi, tr=tr, W=W, total=total):
                th = library.theta(tr.X[lo:hi])
                u = th if passive else np.hstack([th, W[lo:hi, None]])
                total += u.sum(axis=0)
                return np.hstack([u, np.ones((hi - lo, 1))])
            R = _run_blocks(rows, n, width, chunk)
            mean = total / n
            for Rb in R:                                   # centre: exact column operation
                Rb[:, :-1] -= Rb[:, -1:] * mean[None, :]
        M[k * N_BLOCKS * width:(k + 1) * N_BLOCKS * width] = np.vstack(R)
        groups.append(np.full(len(R) * width, k))
    stride = max(1, -(-n_total // MAX_STATES))
    X = np.vstack([tr.X[::stride] for tr in trajectories])
    D = library.grad(X).reshape(-1, p)
    return EnergyBalance(M[:, :p], None if passive else M[:, p].copy(), D, X, form,
                         groups=np.concatenate(groups), centred=centred,
                         work_rules=rules if centred else None,
                         intercept=M[:, -1].copy() if centred else None, n_data_rows=n_total)
