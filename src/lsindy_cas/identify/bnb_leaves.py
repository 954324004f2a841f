"""Helpers of :mod:`lsindy_cas.identify.bnb`: the children's bounds (driven: the suffix sweep;
passive: nested suffixes), the pairs of a node's children scored in one batch, and the trimming of
the queue of scored leaves."""
from __future__ import annotations

import numpy as np

__all__ = ["SKIP_TOL", "suffix_explained", "passive_bounds", "pair_positions", "trim_queue"]

# Pivots of a unit-diagonal Gram matrix below this are exact linear dependence (round-off of n·eps):
# such a column adds nothing to the span of a superset (its contribution is < 1e-18 of ‖b‖²).
SKIP_TOL = 1e-13


def suffix_explained(Gd, cd, stop_at: float) -> np.ndarray:
    """Driven: explained ‖y‖² of every suffix of the columns of ``Gd`` (index i: columns i..n−1).

    A Cholesky sweep from the last column backwards; exactly dependent columns (pivot < SKIP_TOL)
    add nothing.  Stops once the explained part reaches ``stop_at`` or the span is exhausted; the
    suffixes not reached get NaN (or, when the span is exhausted, the final value).
    """
    n = len(cd)
    S, v = Gd.copy(), cd.copy()
    out = np.full(n, np.nan)
    E = 0.0
    for t in range(n - 1, -1, -1):
        d = S[t, t]
        if d > SKIP_TOL:
            sd = np.sqrt(d)
            yt = v[t] / sd
            E += yt * yt
            if t:
                l = S[:t, t] / sd
                S[:t, :t] -= np.outer(l, l)
                v[:t] -= l * yt
        out[t] = E
        if t and (E >= stop_at or np.diag(S)[:t].max() <= SKIP_TOL):
            if np.diag(S)[:t].max() <= SKIP_TOL:
                out[:t] = E
            break
    return out


def passive_bounds(G, U, terms, rest, left: int, node_bound: float):
    """Passive: bounds and partial scores (λ_min of Ĝ over U + term) of the children adding
    ``terms`` (the first ones of ``rest``, in order).  The smallest eigenvalue of a few nested
    suffixes U + rest[-length:] bounds every child whose allowed terms lie inside (interlacing)."""
    n = len(terms)
    bounds = np.full(n, node_bound)
    idx = np.hstack([np.broadcast_to(np.array(U, np.int64), (n, len(U))), np.asarray(terms)[:, None]])
    partial = np.linalg.eigvalsh(G[idx[:, :, None], idx[:, None, :]])[:, 0]
    length, done = left, np.zeros(n, dtype=bool)
    while True:                       # nested suffixes of growing length bound the children
        idx = list(U) + [int(j) for j in rest[len(rest) - length:]]
        lam = np.linalg.eigvalsh(G[np.ix_(idx, idx)])[0]
        new = (np.arange(n) + length >= len(rest)) & ~done     # child's suffix inside this one
        bounds[new] = np.maximum(bounds[new], lam)
        done |= new
        if length >= len(rest):
            break
        length = min(len(rest), 2 * length)
    return bounds, partial


def pair_positions(js: np.ndarray, n: int):
    """Every pair of positions (j, j2) with j in ``js`` and j < j2 < n: two arrays (J1, J2)."""
    J1, J2 = np.nonzero(np.arange(n)[None, :] > np.asarray(js)[:, None])
    return np.asarray(js)[J1], J2


def trim_queue(queue: list, keep: int, counter: int):
    """Keep the ``keep`` best leaves of a queue of batches ``(score, counter, i, supports, scores)``
    (entries from position i on pending).  Returns (new queue, smallest score dropped or inf,
    leaves kept): a dropped leaf is never examined, so its score stays a lower bound."""
    S = np.vstack([SS[i:] for _, _, i, SS, _ in queue])
    s = np.concatenate([ss[i:] for _, _, i, _, ss in queue])
    order = np.argsort(s, kind="stable")
    kept, drop = order[:keep], order[keep:]
    dropped = float(s[drop[0]]) if len(drop) else np.inf
    new = [(float(s[kept[0]]), counter, 0, S[kept], s[kept])] if len(kept) else []
    return new, dropped, len(kept)
