"""Conserved quantities besides the energy in passive data, told apart from what only looks null.

The passive search scores how nearly a support conserves something: the smallest singular value
of its column-normalised balance.  Supports (nearly) as null as the winner's are candidates for a
second conserved quantity I — which the energy could be mixed with (E + c·I balances the data
too), so the diagnostics report it and the status asks for a scale trial that separates them.
Three kinds of near-null support are not such quantities:

- **functions of the energy or of a quantity already found** — their state gradients are
  linearly dependent at the samples (:func:`independent`);
- **identities** — terms that are functions of each other (cos²θ + sin²θ = 1,
  cos θ − cos³θ − sin²θ cos θ = 0, φ̇ = φ̇cos²θ + φ̇sin²θ) give a null vector on any data; its
  gradient is round-off, which normalised looks like a new direction.  On each support only the
  terms with independent state gradients are kept (:func:`independent_terms`, the search's own
  ``DEGENERACY_TOL``), and what is left must still score within the floor.  (The exhaustive
  search skips such supports; branch and bound visits and rejects them, so they reach this list.)
- **dissipated quantities** — with Rayleigh dissipation the search scores the balance projected
  off the dissipation columns (:mod:`~lsindy_cas.identify.dissipation`), where *every* quantity
  whose change the friction explains (dI/dt = −Σ ρ_j c_j on the data: the energy itself, or any
  I on a damped coordinate) is null.  Conserved means dI/dt = 0: the quantity must be null in the
  unprojected balance too (:func:`conserved_combination`).  Such a quantity on the chosen support
  is an ambiguity the near-null-space rule reports; it is not a conserved quantity.

A quantity whose velocity-linear terms alone are conserved is reported as that momentum (its
other terms fitted noise), which the status reads: a momentum cannot be mixed into an energy.
"""
from __future__ import annotations

import numpy as np

from .energy_balance import EnergyBalance
from .fitting import normalise_columns, null_vector
from .search import DEGENERACY_TOL

__all__ = ["conserved_quantities", "conserved_combination", "independent_terms", "passive_score",
           "gradient_field", "independent"]

# Gradient fields count as independent when the smallest singular value of the unit-normalised
# fields is above this at the median sample (functions of one quantity give round-off there).
INDEPENDENT_SV = 1e-3


def conserved_quantities(library, bal: EnergyBalance, candidates, energy_coef, floor: float):
    """Conserved quantities besides the energy among the passive search's near-null supports.

    Parameters
    ----------
    library : Library
    bal : EnergyBalance
        The passive balance (projected off the dissipation columns when there are any).
    candidates : list of Candidate
        Supports visited by the search (with their passive scores).
    energy_coef : array (p,)
        The identified energy.
    floor : float
        Candidates scoring at most this are conserved on the data.

    Returns
    -------
    list of (support, eta)
        Quantities Θη functionally independent of the energy and of each other: at the samples
        their state gradients are not linearly dependent on those already found.
    """
    grads = bal.D.reshape(len(bal.X), bal.X.shape[1], -1)
    basis = [gradient_field(grads, np.flatnonzero(energy_coef), energy_coef[energy_coef != 0])]
    raw = bal.raw[0] if bal.dissipation is not None and bal.raw is not None else None
    found, seen = [], set()
    for c in sorted(candidates, key=lambda c: c.score):
        if c.score > floor:
            break
        S = independent_terms(bal.D, list(c.support))
        if not S or tuple(S) in seen:
            continue
        seen.add(tuple(S))
        eta = conserved_combination(bal.A, raw, S, floor)
        if eta is None:
            continue
        linear = [j for j in S if library.velocity_degree(j) == 1]
        if linear and len(linear) < len(S):
            eta_lin = conserved_combination(bal.A, raw, linear, floor)
            if eta_lin is not None:
                S, eta = linear, eta_lin
        g = gradient_field(grads, S, eta)
        if independent(basis + [g]):
            basis.append(g)
            found.append((tuple(S), eta))
    return found


def conserved_combination(A, raw, S, floor: float):
    """The most nearly conserved combination η (data units) of the terms ``S``, or None when it
    is not conserved: its passive score exceeds ``floor`` in the balance ``A`` or — with
    dissipation — in the unprojected balance ``raw`` (where η is then taken from)."""
    A_S = A[:, S] if raw is None else raw[:, S]
    eta = null_vector(A_S)
    if passive_score(A[:, S], eta) > floor or (raw is not None and passive_score(A_S, eta) > floor):
        return None
    return eta


def passive_score(A_S, eta) -> float:
    """‖Â_S η̂‖² with unit-norm columns Â_S and ‖η̂‖ = 1 (η̂ the column-scaled η): the search's
    passive score of the combination η on the balance rows ``A_S``."""
    An, s = normalise_columns(A_S)
    v = np.asarray(eta, float) * s
    v = v / max(np.linalg.norm(v), 1e-300)
    return float(np.sum((An @ v) ** 2))


def independent_terms(D, S) -> list:
    """The terms of ``S`` whose state gradients (``D``'s columns) are independent: column-pivoted
    QR of the column-normalised gradients, a pivot² below the search's ``DEGENERACY_TOL`` marking
    a term that is a function of those before it (sorted)."""
    from scipy.linalg import qr
    R, piv = qr(normalise_columns(D[:, list(S)])[0], mode="r", pivoting=True)
    return sorted(S[j] for j, r in zip(piv, np.abs(np.diag(R))) if r ** 2 >= DEGENERACY_TOL)


def gradient_field(grads, S, eta) -> np.ndarray:
    """∇I at every sample: (N, 2n)."""
    return np.einsum("nkj,j->nk", grads[:, :, list(S)], np.asarray(eta, float))


def independent(fields) -> bool:
    """Are the gradient fields linearly independent at (most) samples?  (N, 2n) each."""
    F = np.stack(fields, axis=2)                                   # (N, 2n, r)
    F = F / np.maximum(np.linalg.norm(F, axis=1, keepdims=True), 1e-300)
    if F.shape[2] > F.shape[1]:
        return False
    sv = np.linalg.svd(F, compute_uv=False)                        # (N, r)
    return bool(np.median(sv[:, -1]) > INDEPENDENT_SV)
