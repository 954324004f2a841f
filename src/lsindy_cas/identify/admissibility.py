"""Every rule a candidate energy must pass: what separates the true energy from spurious fits.

A fit can be perfect and still not be an energy.  With a constant input u on a cyclic coordinate x,
E' = u·x satisfies dE'/dt = u·ẋ = P exactly; with passive data any conserved quantity (e.g. an
angular momentum) lies in the null space.  The rules, in the order a candidate meets them:

Inside the search (cheap, batched over supports, before any coefficient is fitted):

0. **reducible** (:func:`reducible`) — the support's own fitted (or null) vector has a vanishing
   entry: a k-term fit that is a smaller model plus round-off, e.g. E' = u·x + 1e-18·ẋ²;
0'. **scale** (``NO_SCALE_REASON``) — passive data: the actuated record must fix the scale.

Then :class:`Admissibility`, ``(support, coef) -> (ok, reason)``:

1. **excluded terms** — no coordinate whose coefficient a constant input leaves undetermined
   (:func:`lsindy_cas.identify.diagnostics.constant_force_trap`);
2. **no velocity-linear term** — no energy has one (:func:`lsindy_cas.mechanics.legendre.velocity_linear`);
3. **prior terms present** — every prior term has a non-zero coefficient;
4. **every term used** — no support term came out zero (the fit is a smaller model);
5. **positive kinetic part** — M(x) = ∂²E/∂q̇² ≻ 0 at every sample state;
6. **significance** (when a balance is given) — every coefficient has |t| ≥ T_CRIT in a
   delete-a-block jackknife (:class:`lsindy_cas.identify.uncertainty.Jackknife`), a dimensionless
   test that keeps noise-fitting terms out without a threshold in the units of the data.
"""
from __future__ import annotations

import numpy as np

from ..mechanics.legendre import velocity_linear
from ..symbolic.library import Library
from . import findings as F
from .findings import Finding
from .fitting import column_norms
from .uncertainty import T_CRIT, Jackknife

__all__ = ["Admissibility", "reducible", "clearly_not_pd", "REDUCIBLE_TOL", "REDUCIBLE_REASON", "NO_SCALE_REASON",
           "PRIOR_SHARE_TOL", "PD_RTOL"]

# A prior term "is present" when its share of the fitted signal exceeds this fraction of the
# largest term's share; spurious fits put ~1e-12 there (round-off), true terms ≥ 1e-3.
PRIOR_SHARE_TOL = 1e-6
# M(x) counts as positive definite when λ_min > this fraction of λ_max at every sample.
PD_RTOL = 1e-9
# A support is reducible when its smallest normalised coefficient is below this fraction of the
# largest: exact traps put ~1e-12 there, genuine terms ≥ 1e-3 even when small.
REDUCIBLE_TOL = 1e-6
# The batched pre-check of rule 5 (clearly_not_pd) marks a support only when λ_min(M) is below
# −PD_MARGIN·max|λ|: far outside what the normal equations' round-off can move.
PD_MARGIN = 1e-3
# the reasons are findings (identify/findings.py): decisions read their codes, never the words
REDUCIBLE_REASON = Finding("a coefficient came out zero: the support is really a smaller one",
                           F.REDUCIBLE)
NO_SCALE_REASON = Finding("scale trial cannot fix the scale", F.NO_SCALE)
EXCLUDED_REASON = Finding("uses a coordinate whose coefficient a constant input leaves "
                          "undetermined (E and E − u·x fit equally)", F.EXCLUDED_COORDINATE)
LINEAR_REASON = Finding("has a term linear in the velocities, which no energy has (it cancels "
                        "in H = p·q̇ − L): a momentum-like conserved quantity, not the energy",
                        F.VELOCITY_LINEAR)
ADMISSIBLE = Finding("admissible", F.ADMISSIBLE)


def reducible(G: np.ndarray, c: np.ndarray | None, S: np.ndarray, tol: float = REDUCIBLE_TOL,
              chunk: int = 100_000) -> np.ndarray:
    """Rule 0, batched: does the fitted (or null) vector of each support have a vanishing entry?

    Parameters
    ----------
    G, c : arrays (p, p), (p,) or None
        Normal equations of the column-normalised design matrix
        (:func:`lsindy_cas.identify.fitting.normal_equations`); ``c`` None for passive data.
    S : int array (n, k)
        Supports.

    Returns
    -------
    bool array (n,); a chunk whose Gram matrices are singular is left unmarked.
    """
    out = np.zeros(len(S), dtype=bool)
    for lo in range(0, len(S), chunk):
        Sc = S[lo:lo + chunk]
        GS = G[Sc[:, :, None], Sc[:, None, :]]
        with np.errstate(all="ignore"):
            if c is None:
                v = np.linalg.eigh(GS)[1][:, :, 0]
            else:
                try:
                    v = np.linalg.solve(GS, c[Sc][:, :, None])[:, :, 0]
                except np.linalg.LinAlgError:
                    continue
        a = np.abs(v)
        out[lo:lo + chunk] = ~(a.min(axis=1) > tol * a.max(axis=1))
    return out


def clearly_not_pd(hess: np.ndarray, G: np.ndarray, c: np.ndarray, scales: np.ndarray,
                   S: np.ndarray, margin: float = PD_MARGIN) -> np.ndarray:
    """Rule 5, batched, for driven data: is the kinetic part of each support's least-squares fit
    *clearly* not positive definite at one of the given states?

    The coefficients come from the normal equations (``G``, ``c`` of
    :func:`~lsindy_cas.identify.fitting.normal_equations`, ``scales`` the column norms), and a
    support is marked only when ``λ_min(M) < −margin · max|λ(M)|`` at some state, so that the
    normal equations' round-off cannot mark a support that the full rule (on a least-squares fit,
    at these and more states) would pass.  Used to skip fitting such supports one by one.

    Parameters
    ----------
    hess : array (s, n, n, p)
        ∂²θ_j/∂q̇∂q̇ at some of the sample states (a subset of those :class:`Admissibility`
        checks), in the columns of ``G``.
    G, c : arrays (p, p), (p,)
    scales : array (p,)
    S : int array (B, k)

    Returns
    -------
    bool array (B,); a block whose Gram matrices are singular is left unmarked.
    """
    S = np.asarray(S, dtype=np.int64)
    with np.errstate(all="ignore"):
        try:
            v = np.linalg.solve(G[S[:, :, None], S[:, None, :]], c[S][:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            return np.zeros(len(S), dtype=bool)
        coef = v / scales[S]                                   # (B, k), data units
        M = np.einsum("sikbj,bj->bsik", hess[..., S], coef)    # (B, s, n, n)
        lam = np.linalg.eigvalsh(M)
    bad = lam[..., 0] < -margin * np.abs(lam).max(axis=-1)
    return np.nan_to_num(bad, nan=False).any(axis=1) & np.isfinite(lam).all(axis=(1, 2))


class Admissibility:
    """Rules 1–6 as one callable ``(support, coef) -> (ok, reason)`` (full-library indices).

    Parameters
    ----------
    library : Library
    X : array (n_samples, 2n)
        States at which the kinetic part must be positive definite.
    forced : sequence of int
        Indices of the prior terms.
    column_norms : array (p,)
        Norms of the design-matrix columns (to compare term contributions scale-free).
    balance : EnergyBalance, optional
        Enables rule 6 (jackknife significance) on this balance.
    scale_system : (A_s, b_s), optional
        Passive scheme: the scale record the jackknife refits with.
    excluded : sequence of int
        Terms no candidate may use (rule 1).
    """

    def __init__(self, library: Library, X: np.ndarray, forced, column_norms: np.ndarray, *,
                 balance=None, scale_system=None, excluded=()):
        self.library = library
        self.forced = list(forced)
        self.norms = np.asarray(column_norms, float)
        self.balance = balance
        self.scale_system = scale_system
        self.excluded = set(int(j) for j in excluded)
        self._jack = None
        # subsample states for the PD check: enough to cover the data, cheap to evaluate
        step = max(1, len(X) // 400)
        self.hess = library.d2theta_dqd2(X[::step])        # (s, n, n, p)

    @classmethod
    def for_balance(cls, library: Library, bal, forced, scale_system=None, excluded=()):
        """All six rules for candidates fitted on ``bal``.

        Term shares are judged on the driven balance's columns — for passive data on the actuated
        scale record's, where the terms' contributions are not cancelling by construction (without
        a record: on the passive balance's own columns, before any dissipation projection).
        """
        if bal.passive and scale_system is not None:
            A = scale_system[0]
        else:
            A = bal.A if bal.raw is None else bal.raw[0]
        return cls(library, bal.X, forced, column_norms(A), balance=bal,
                   scale_system=scale_system, excluded=excluded)

    def __getstate__(self):
        # pickled for Dask workers (identify/distributed_bnb.py): the library's CasADi expressions
        # do not pickle, and the rules read only its term names and velocity degrees
        state = dict(self.__dict__, _jack=None)
        state["library"] = _TermFacts(self.library)
        return state

    def __call__(self, support, coef):
        if self.excluded & set(support):
            return False, EXCLUDED_REASON
        if velocity_linear(self.library, support):
            return False, LINEAR_REASON
        ok, why = self.physical(support, coef)
        if not ok or self.balance is None:
            return ok, why
        S = list(support)
        if self._jack is None:
            self._jack = Jackknife(self.balance)
        t = self._jack.t(S, coef[S], scale_system=self.scale_system)
        if np.any(t < T_CRIT):
            return False, Finding(f"a term is not significantly non-zero (jackknife |t| < {T_CRIT})",
                                  F.NOT_SIGNIFICANT, {"t_crit": T_CRIT, "t_min": float(np.min(t))})
        return True, ADMISSIBLE

    def physical(self, support, coef):
        """Rules 3–5 only: prior terms present, every term used, kinetic part positive definite."""
        share = np.abs(coef) * self.norms
        top = share.max()
        if top == 0:
            return False, Finding("all coefficients are zero", F.ALL_ZERO)
        weak = [self.library.names[j] for j in self.forced if share[j] <= PRIOR_SHARE_TOL * top]
        if weak:
            return False, Finding(f"prior term(s) {', '.join(weak)} came out zero", F.PRIOR_ZERO,
                                  {"count": len(weak)})
        weak = [self.library.names[j] for j in support if share[j] <= PRIOR_SHARE_TOL * top]
        if weak:
            return False, Finding(f"term(s) {', '.join(weak)} came out zero (the fit is a smaller "
                                  "model)", F.COEFFICIENT_ZERO, {"count": len(weak)})
        M = np.einsum("sikp,p->sik", self.hess, coef)
        if self.balance is not None and self.balance.passive and self.scale_system is None:
            M = M * np.sign(np.trace(M[0]))    # a null vector without a scale: sign is free
        eig = np.linalg.eigvalsh(M)
        if not np.all(eig[:, 0] > PD_RTOL * np.maximum(np.abs(eig[:, -1]), 1e-300)):
            return False, Finding("kinetic part not positive definite (∂²E/∂q̇² has a non-positive "
                                  "eigenvalue)", F.NOT_POSITIVE_DEFINITE)
        return True, ADMISSIBLE


class _TermFacts:
    """What the rules read of a :class:`Library` — term names and velocity degrees — without its
    CasADi expressions: how an :class:`Admissibility` travels to Dask workers."""

    def __init__(self, library):
        self.names = list(library.names)
        self._degrees = [library.velocity_degree(j) for j in range(len(self.names))]

    def __len__(self) -> int:
        return len(self.names)

    def velocity_degree(self, j: int) -> int | None:
        return self._degrees[j]
