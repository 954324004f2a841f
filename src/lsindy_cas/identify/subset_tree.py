"""Least-squares scores of every k-subset of columns, sharing Cholesky factors between prefixes.

Subsets are enumerated in lexicographic order as the leaves of a tree whose nodes are prefixes.
A node P stores R_P = L_P⁻¹ Ĝ[P, :] — the rows of the Cholesky factor of the normalised Gram
matrix Ĝ restricted to P, extended to every column — and y_P = L_P⁻¹ ĉ_P.  Appending a column m is
one rank-one step:

    l = R_P[:, m],   pivot = Ĝ_mm − ‖l‖²,   y_m = (ĉ_m − l·y_P) / √pivot,
    R_{P+m} = [R_P; (Ĝ[m, :] − lᵀ R_P) / √pivot],

so the explained fraction of ‖b‖² of a support is ‖y‖² and its relative residual 1 − ‖y‖²/‖b‖².
``pivot`` is 1 − R² of the new column against the prefix: a tiny pivot means the support is
linearly dependent (e.g. sin²θ·u, cos²θ·u and u together) and is flagged.  The work per leaf is
O(k) instead of the O(k³) of a fresh factorisation, and everything is vectorised over nodes.
For k ≤ 3 the last two levels are computed together from one small square per node
(:func:`_pairs`), without storing the rows of the middle level — the same numbers, a quarter less
time on the spherical pendulum's C(125, 3).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["tree_scores", "combinations", "subtree_scores", "subtree_supports"]

_BUDGET = 4_000_000        # floats held in one batch of prefix rows (~32 MB)


class _Nodes:
    """A batch of prefixes: positions in ``free`` (B, j_free), rows R (B, j, p), y (B, j)."""

    __slots__ = ("pos", "R", "y", "e", "pmin")

    def __init__(self, pos, R, y, e, pmin):
        self.pos, self.R, self.y, self.e, self.pmin = pos, R, y, e, pmin

    def take(self, idx):
        return _Nodes(self.pos[idx], self.R[idx], self.y[idx], self.e[idx], self.pmin[idx])


def _append(G, c, nodes: _Nodes, parent, cols, keep_rows: bool):
    """Children = nodes[parent] + column ``cols`` (one per child).

    Pivots and new y entries are computed densely for every column of each parent (B, p) — one
    contiguous einsum — and then picked out per child by a flat index.
    """
    p = G.shape[0]
    B = len(nodes.e)
    piv_all = np.diag(G)[None, :] - np.einsum("bjp,bjp->bp", nodes.R, nodes.R)
    num_all = c[None, :] - np.einsum("bjp,bj->bp", nodes.R, nodes.y)
    flat = parent * p + cols
    piv = piv_all.reshape(B * p)[flat]
    sq = np.sqrt(np.maximum(piv, 1e-300))
    y_new = num_all.reshape(B * p)[flat] / sq
    e = nodes.e[parent] + y_new ** 2
    pmin = np.minimum(nodes.pmin[parent], piv)
    if keep_rows:
        R = nodes.R[parent]                                  # (B, j, p)
        l = R[np.arange(len(cols)), :, cols]                 # (B, j) = R_P[:, m]
        r_new = (G[cols] - np.einsum("bj,bjp->bp", l, R)) / sq[:, None]
        R = np.concatenate([R, r_new[:, None, :]], axis=1)
        y = np.concatenate([nodes.y[parent], y_new[:, None]], axis=1)
    else:
        R, y = np.zeros((len(cols), 0, 0)), np.zeros((len(cols), 0))
    return R, y, e, pmin


def _leaves(G, c, nodes: _Nodes, free, last):
    """All one-column extensions of ``nodes`` by a free column after each node's last one.

    Returns (parent index, column position in ``free``, explained ‖y‖², smallest pivot), in
    lexicographic order.  Parents are taken in groups with the same last column, so only the
    columns after it are computed (a third of the dense (parent, column) table for k = 3).
    """
    nf = len(free)
    everything = nf == G.shape[0]                             # no forced terms: skip the gather
    dg, cf = (np.diag(G), c) if everything else (np.diag(G)[free], c[free])
    counts = np.maximum(nf - 1 - last, 0)
    begin = np.cumsum(counts) - counts
    total = int(counts.sum())
    parent = np.repeat(np.arange(len(last)), counts)
    col = np.repeat(last + 1, counts) + (np.arange(total) - np.repeat(begin, counts))
    e_out, p_out = np.empty(total), np.empty(total)
    order = np.argsort(last, kind="stable")
    cuts = np.r_[0, np.flatnonzero(np.diff(last[order])) + 1, len(order)]
    for a, z in zip(cuts[:-1], cuts[1:]):
        rows = order[a:z]
        lo = int(last[rows[0]]) + 1
        if lo >= nf:
            continue
        R = nodes.R[rows]
        Rf = R[:, :, lo:] if everything else R[:, :, free[lo:]]      # (b, j, nf − lo)
        piv = dg[None, lo:] - np.einsum("bjf,bjf->bf", Rf, Rf)
        num = cf[None, lo:] - np.einsum("bjf,bj->bf", Rf, nodes.y[rows])
        idx = begin[rows][:, None] + np.arange(nf - lo)[None, :]
        e_out[idx] = nodes.e[rows][:, None] + num ** 2 / np.maximum(piv, 1e-300)
        p_out[idx] = np.minimum(nodes.pmin[rows][:, None], piv)
    return parent, col, e_out, p_out


def _triu(nf: int):
    """``J -> (a, b)``: the pairs a < b < J in lexicographic order, as the tail of those of nf
    (the pairs whose first element is >= nf - J come last), built once per search."""
    iu, ju = np.triu_indices(nf, 1)

    def pairs(J: int):
        n = J * (J - 1) // 2
        return iu[len(iu) - n:] - (nf - J), ju[len(ju) - n:] - (nf - J)
    return pairs


def _pairs(G, c, nodes: _Nodes, free, last, out_e, out_p, offset, triu):
    """Leaves two levels below nodes with at most one row (k ≤ 3): every (a, b) of free columns
    after each node's last one, scores and smallest pivots into ``out_e``/``out_p`` at
    ``offset[n] + ...`` (lexicographic per node n).

    The middle level is never stored: for the nodes with the same last column (so the same
    candidate columns F) the middle node (P, a)'s row at column b, (Ĝ_ab − R_a·R_b) / √pivot_a,
    is formed as a square (|F|, |F|) per node, small enough to stay in cache, and every leaf is
    computed in it with the operations of :func:`_append` then :func:`_leaves`, in the same
    order (with one prefix row the sums have at most two terms), so the numbers are the same
    bit for bit; then the upper triangle is kept.
    """
    nf = len(free)
    everything = nf == G.shape[0]
    dg = np.diag(G)
    order = np.argsort(last, kind="stable")
    cuts = np.r_[0, np.flatnonzero(np.diff(last[order])) + 1, len(order)]
    for a0, z0 in zip(cuts[:-1], cuts[1:]):
        lo = int(last[order[a0]]) + 1
        J = nf - lo
        if J < 2:
            continue
        F = np.arange(lo, nf) if everything else free[lo:]
        iu, ju = triu(J)
        tri = iu * J + ju                                     # flat (a, b) in the square
        GFF, dF, cF = G[np.ix_(F, F)], dg[F], c[F]
        step = max(1, _BUDGET // (4 * J * J))
        for a1 in range(a0, z0, step):
            rows = order[a1:min(z0, a1 + step)]
            R = nodes.R[rows][:, :, F]                        # (b, j, J), j <= 1
            s1 = np.einsum("bjf,bjf->bf", R, R)
            n1 = np.einsum("bjf,bj->bf", R, nodes.y[rows])
            piv1, num1 = dF[None] - s1, cF[None] - n1
            sq1 = np.sqrt(np.maximum(piv1, 1e-300))
            y1 = num1 / sq1                                   # y of the middle node (P, a)
            e1 = nodes.e[rows][:, None] + y1 ** 2
            p1 = np.minimum(nodes.pmin[rows][:, None], piv1)
            r = (GFF[None] - np.einsum("bja,bjf->baf", R, R)) / sq1[:, :, None]   # [n, a, b]
            piv2 = dF[None, None, :] - (s1[:, None, :] + r * r)
            num2 = cF[None, None, :] - (n1[:, None, :] + r * y1[:, :, None])
            e2 = e1[:, :, None] + num2 ** 2 / np.maximum(piv2, 1e-300)
            p2 = np.minimum(p1[:, :, None], piv2)
            idx = offset[rows][:, None] + np.arange(len(tri))[None, :]
            out_e[idx] = e2.reshape(len(rows), J * J)[:, tri]
            out_p[idx] = p2.reshape(len(rows), J * J)[:, tri]


def _pair_positions(pos, last, counts, triu):
    """Positions of the leaves two levels below nodes ``pos`` (B, j): each node's row followed
    by every (a, b), last < a < b, lexicographic (C(counts[n], 2) rows per node n)."""
    n_leaf = counts * (counts - 1) // 2
    out = np.empty((int(n_leaf.sum()), pos.shape[1] + 2), np.int64)
    out[:, :pos.shape[1]] = np.repeat(pos, n_leaf, axis=0)
    offset = np.cumsum(n_leaf) - n_leaf
    for J in np.unique(counts[counts >= 2]):
        iu, ju = triu(int(J))
        nodes = np.flatnonzero(counts == J)
        idx = offset[nodes][:, None] + np.arange(len(iu))[None, :]
        lo = (last[nodes] + 1)[:, None]
        out[idx, -2] = lo + iu
        out[idx, -1] = lo + ju
    return out


def tree_scores(G: np.ndarray, c: np.ndarray, bb: float, forced, free, k: int,
                progress: Callable | None = None):
    """Score all supports = ``forced`` ∪ (k − |forced|)-subsets of ``free``.

    Parameters
    ----------
    G : array (p, p)
        Gram matrix of the column-normalised design matrix (unit diagonal).
    c : array (p,)
        Normalised design matrix transposed times the right-hand side.
    bb : float
        ‖b‖².
    forced, free : int arrays
        Columns in every support / columns to choose from.
    k : int
        Support size.

    Returns
    -------
    supports : int array (n, k), sorted rows, lexicographic over ``free``
    scores : array (n,)   relative residuals in [0, 1]
    pivots : array (n,)   smallest Cholesky pivot of each support (1 − R², degeneracy measure)
    """
    p = G.shape[0]
    forced = np.asarray(forced, dtype=np.int64)
    free = np.asarray(free, dtype=np.int64)
    r = k - len(forced)
    root = _Nodes(np.zeros((1, 0), np.int64), np.zeros((1, 0, p)), np.zeros((1, 0)),
                  np.zeros(1), np.full(1, np.inf))
    for f in forced:
        R, y, e, pmin = _append(G, c, root, np.zeros(1, np.int64), np.array([f]), keep_rows=True)
        root = _Nodes(root.pos, R, y, e, pmin)
    total = _count(len(free), r)
    out_sup, out_e, out_p = [], [], []
    done = [0]

    def walk(nodes: _Nodes, level: int):
        if level == r:
            out_sup.append(nodes.pos)
            out_e.append(nodes.e)
            out_p.append(nodes.pmin)
            done[0] += len(nodes.e)
            if progress is not None:
                progress(done[0], total)
            return
        remaining = r - level - 1
        last = nodes.pos[:, -1] if nodes.pos.shape[1] else np.full(len(nodes.e), -1)
        if remaining == 1 and nodes.R.shape[1] <= 1:    # k <= 3: the last two levels at once
            counts = np.maximum(len(free) - 1 - last, 0)
            n_leaf = counts * (counts - 1) // 2
            e, pmin = np.empty(int(n_leaf.sum())), np.empty(int(n_leaf.sum()))
            triu = _triu(len(free))
            _pairs(G, c, nodes, free, last, e, pmin, np.cumsum(n_leaf) - n_leaf, triu)
            walk(_Nodes(_pair_positions(nodes.pos, last, counts, triu), None, None, e, pmin),
                 level + 2)
            return
        if remaining == 0:          # leaves: dense over (parent, column), then keep column > last
            step = max(1, _BUDGET // (len(free) * (nodes.R.shape[1] + 1)))
            for lo in range(0, len(last), step):
                sub = nodes.take(slice(lo, lo + step))
                parent, col, e, pmin = _leaves(G, c, sub, free, last[lo:lo + step])
                walk(_Nodes(np.hstack([sub.pos[parent], col[:, None]]), None, None, e, pmin),
                     level + 1)
            return
        counts = np.maximum(len(free) - remaining - (last + 1), 0)
        row_cost = (nodes.R.shape[1] + 1) * (p if remaining else 4)
        per_batch = max(1, _BUDGET // row_cost)
        cum = np.cumsum(counts)
        start = 0
        while start < len(counts):
            # largest run of parents whose children fit the budget (at least one parent)
            base = cum[start - 1] if start else 0
            stop = max(start + 1, int(np.searchsorted(cum, base + per_batch, side="right")))
            cnt = counts[start:stop]
            parent = np.repeat(np.arange(start, stop), cnt)
            offs = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
            pos = np.repeat(last[start:stop] + 1, cnt) + offs
            R, y, e, pmin = _append(G, c, nodes, parent, free[pos], keep_rows=remaining > 0)
            child = _Nodes(np.hstack([nodes.pos[parent], pos[:, None]]), R, y, e, pmin)
            walk(child, level + 1)
            start = stop

    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        walk(root, 0)
    pos = np.concatenate(out_sup) if out_sup else np.zeros((0, r), np.int64)
    supports = np.hstack([np.broadcast_to(forced, (len(pos), len(forced))), free[pos]])
    if len(forced):
        supports.sort(axis=1)
    e = np.concatenate(out_e) if out_e else np.zeros(0)
    scores = np.clip(1.0 - e / bb, 0.0, 1.0) if bb > 0 else np.zeros_like(e)
    return supports, scores, np.concatenate(out_p) if out_p else np.zeros(0)


def _count(n: int, r: int) -> int:
    from math import comb
    return comb(n, r) if 0 <= r <= n else 0


def combinations(n: int, r: int) -> np.ndarray:
    """All r-subsets of range(n) in lexicographic order, as an int array (C(n, r), r), vectorised."""
    if r == 0:
        return np.zeros((1, 0), dtype=np.int64)
    if r > n:
        return np.zeros((0, r), dtype=np.int64)
    rows = np.arange(n - r + 1, dtype=np.int64)[:, None]
    for j in range(1, r):
        last = rows[:, -1]
        counts = (n - r + j) - last            # next element ranges over last+1 .. n-r+j
        rep = np.repeat(rows, counts, axis=0)
        starts = np.repeat(last + 1, counts)
        offs = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        rows = np.hstack([rep, (starts + offs)[:, None]])
    return rows


def subtree_scores(G, c, bb, forced, free, k, positions):
    """Scores and smallest pivots of the subtrees ``positions`` (supports whose smallest free column
    is ``free[i]``), concatenated in order: (scores (n,), pivots (n,)).

    The workers score through this function, subtree by subtree, so their numbers do not depend on
    how the subtrees are grouped into tasks; against the in-process search
    (:func:`lsindy_cas.identify.search.score_all`) the supports, their order and the degeneracy
    flags are identical and the scores agree to round-off (bit for bit at k = 3; at k = 4 without
    prior terms, 894,150 of 9.7 M differ in the last bits).  The supports themselves are not returned: they are the
    lexicographic enumeration, rebuilt by the caller (:func:`subtree_supports`).
    """
    rest = k - len(forced) - 1                     # columns still to choose after free[i]
    out = [tree_scores(G, c, bb, list(forced) + [int(free[i])], free[i + 1:], k)[1:]
           for i in positions if len(free) - i - 1 >= rest]
    if not out:
        return np.zeros(0), np.zeros(0)
    return tuple(np.concatenate(parts) for parts in zip(*out))


def subtree_supports(forced, free, k) -> np.ndarray:
    """Every support ``forced`` ∪ (k − |forced|)-subset of ``free``, sorted rows, in the
    lexicographic order of :func:`subtree_scores` (n, k)."""
    forced = np.asarray(sorted(forced), dtype=np.int64)
    free = np.asarray(free, dtype=np.int64)
    combos = combinations(len(free), k - len(forced))
    supports = np.hstack([np.broadcast_to(forced, (len(combos), len(forced))), free[combos]])
    if len(forced):
        supports.sort(axis=1)
    return supports
