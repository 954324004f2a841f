"""Scale-free model selection: the support *and* the number of terms k, with physical admissibility.

For each k the best admissible support comes from :func:`lsindy_cas.identify.search.best_subset` (all
k-supports scored by a scale-free criterion) or, for large libraries, from the branch and bound
of :mod:`lsindy_cas.identify.bnb` (exact, with a certificate) or a beam; all visit their candidates through :func:`lsindy_cas.identify.search.visit`, so a
support gets the same coefficients on either path.  Admissible means passing every rule of
:mod:`lsindy_cas.identify.admissibility` (an energy, no undetermined term, every coefficient
significantly non-zero in a block jackknife).  k itself is chosen on held-out data: whole
trajectories when there are four or more, otherwise contiguous stretches of each run (five folds).
The held-out error of a support is the fraction of the held-out work (driven) — or of the
held-out changes of its terms (passive) — that the fitted energy does not explain, so it has no
units and no threshold in the units of the data.

k grows from the number of prior terms; a larger k replaces the current choice only if it cuts the
held-out error by at least a factor ``IMPROVEMENT`` *and* does so in a paired test over the folds
(one-sided, 5 %).  The factor matters on clean data: there the residual is quadrature error, which a
spurious extra term can fit consistently in every fold — a real missing term cuts the error by
orders of magnitude instead.  The scan stops two k past the last k that lowered the held-out
error significantly at all (the paired test without the factor): a model that leaves most of the
work unexplained often gains less than the factor per term until its last missing terms arrive
(Acrobot without priors: 61 %, 44 %, 34 % unexplained at k = 3, 4, 5; exact at k = 8).

When the noise of the data is known (:class:`~lsindy_cas.identify.uncertainty.NoiseModel`, from the
smoother), two more rules apply, both in units of the noise (χ = RSS / E[noise], ≈ 1 for a model
that fits to within the noise):

- a larger k must also lower χ: a term that cuts the residual less than it cuts the noise the model
  expects is not supported by the data;
- the discrepancy principle caps k: the smallest k with χ ≤ ``CHI_OK`` needs no more terms.

Both matter under a constant input, where functions that imitate u·x over the range of the data
predict the work *better* than the energy does because they avoid the noisy velocities.  Measured
on the paper's 1 s runs at σ = 1e-3: cart-pendulum — the 4-term energy has χ = 0.3–1.2, 5- and
6-term imitations smaller held-out errors; double pendulum — the energy χ = 1.0–1.7, the 7-term
imitation held-out errors 10× smaller but χ = 2.1–3.3.

Where scoring every support is too much (more than ``EXHAUSTIVE`` supports): when k is given,
branch and bound (:mod:`lsindy_cas.identify.bnb`, exact, ``time_limit`` seconds if given).  In the
automatic scan the candidates at k are the one-term extensions of the best ``BEAM`` supports of the
level below (fast, not exact: above the true k every near-perfect support is a smaller one in
disguise, which an exact search of the best *admissible* support would have to rule out one by
one); where there is no smaller model to extend, or none of the extensions is admissible, a branch
and bound *scout* of at most ``SCOUT_WORK`` units of work (:mod:`~lsindy_cas.identify.bnb_drive`:
the same stopping point on every machine; also at most ``time_limit`` seconds if given) searches
that k.  Every k of the range is either scored or listed in :attr:`Selection.unscored` with the
reason and what its search spent — "no admissible model exists" (proven) or "undecided" (the
scout stopped first, or the scan's ``AUTO_WORK`` is spent).  The k chosen is searched again by
branch and bound (``time_limit`` seconds, or ``AUTO_WORK`` units without one) for its certificate,
and the search says whether it was proven.

When no k of the scan fits the data (below) and scouts stopped undecided — up to two k past the
best, or at any k while no model explains the data (χ ≤ ``CHI_MISS``) — their searches go on where
they stopped (:class:`~lsindy_cas.identify.bnb.BnbState`: nothing is searched twice),
smallest k first, each round with twice the work of the one before, until one finds a model that
fits, every k is decided or ``AUTO_WORK`` is spent: a scout's first stretch is a guess, not a
measure of the k.

The scan stops two k past the last k that helped only where it can tell that the best model
explains the data: passive data give no χ, so there the scan goes on to the largest k.

A k whose model fits the data to the noise (χ ≤ ``CHI_OK``) or, without a noise model, to the
held-out floor (the relative held-out error below ``EXACT_CV``) ends the scan: more terms cannot
fit better than exactly.
"""
from __future__ import annotations

import time
from dataclasses import replace
from math import comb
from typing import Callable

import numpy as np

from .energy_balance import EnergyBalance
from .held_out import CV_FLOOR, chi_of, cv_error, fold_ids  # noqa: F401 (importable here)
from .bnb import SCORE_RESOLUTION, branch_and_bound, structure_of
from .search import NoAdmissibleModel, SearchResult, best_subset, score_supports, visit
from .selection_records import Selection, Step, Unscored
from .k_choice import (CHI_MISS, CHI_OK, EXACT_CV, IMPROVEMENT, better,  # noqa: F401
                       choose, fair, fits_data, gain)
from .findings import UndeterminedError  # noqa: F401 (importable here)

__all__ = ["Step", "Selection", "Unscored", "UndeterminedError", "select", "cv_error", "chi_of",
           "fold_ids", "IMPROVEMENT", "EXACT_CV"]




EXHAUSTIVE = 1_500_000
BEAM = 2000
MAX_VISITS = 2000          # beam: candidates examined for admissibility before giving up
MAX_EXTRA = 8              # automatic k: at most this many terms beyond the prior terms
# Automatic k: work (bnb_drive units) of a branch and bound in the scan — a scout: what the scan
# compares across k is the best model each k offers, which the search finds early (double pendulum,
# rich σ = 1e-2: the k = 4 incumbent of a 60 s search was there at 5 s; proving it best needs far
# more: below k = 6 no bound is above the round-off of a superset fit).  Measured rates 7 k units/s
# (that case: 93 k nodes in 13.5 s) to 31 k units/s (the paper's run), so a scout is ~2–7 s.
SCOUT_WORK = 50_000
# Automatic k: work of all the scouts of one scan together, and of the chosen k's certificate
# without a time limit (~40–170 s at the rates above): a refusal never takes minutes per k.
AUTO_WORK = 1_200_000


class _Columns:
    """Search on a subset of the library columns, reporting supports in full-library indices."""

    def __init__(self, p: int, excluded):
        self.excluded = sorted(set(int(j) for j in excluded))
        self.keep = np.array([j for j in range(p) if j not in set(self.excluded)], dtype=np.int64)
        self.pos = {int(j): i for i, j in enumerate(self.keep)}

    def local(self, S):
        return [self.pos[int(j)] for j in S]

    def full(self, S) -> tuple:
        return tuple(sorted(int(self.keep[i]) for i in S))

    def full_coef(self, coef_local, p) -> np.ndarray:
        out = np.zeros(p)
        out[self.keep] = coef_local
        return out


def _search_k(bal, k, forced, cols, admissible, scale_system, progress, prev: Step | None,
              time_limit=None, automatic=False, work_left=AUTO_WORK, work_limit=None,
              backend=None, scout_work=SCOUT_WORK, resume=None):
    """Best admissible k-support, SearchResult in full indices: exhaustive up to EXHAUSTIVE
    supports; beyond, with ``automatic``, the beam from ``prev`` or else a branch-and-bound scout
    (module notes), otherwise branch and bound — or, with ``resume`` (a scout's ``state``), that
    search for ``work_limit`` more units.  Raises NoAdmissibleModel."""
    p = bal.A.shape[1]
    A, D = bal.A[:, cols.keep], bal.D[:, cols.keep]
    f_loc = cols.local(forced)
    adm = None if admissible is None else (
        lambda S, coef: admissible(cols.full(S), cols.full_coef(coef, p)))
    n_free = len(cols.keep) - len(f_loc)
    beam = comb(n_free, k - len(f_loc)) > EXHAUSTIVE      # too many to score every support
    can_extend = prev is not None and prev.search is not None and prev.search.supports is not None
    structure = _local_structure(admissible, p, cols)     # what the rules exclude before a fit
    kinetic = _local_kinetic(admissible, p, cols) if bal.b is not None else None
    res = None
    if resume is not None:
        res = branch_and_bound(A, bal.b, k, f_loc, resume=resume, time_limit=time_limit,
                               progress=progress, work_limit=work_limit)
    elif beam and automatic and can_extend:
        try:
            res = _beam(A, bal.b, D, k, prev.search, cols, adm, scale_system, structure=structure,
                        kinetic=kinetic)
        except NoAdmissibleModel:
            res = None                   # no extension is admissible: a scout searches this k
    if res is None and beam:
        if automatic:
            if work_left <= 0:
                raise NoAdmissibleModel("the scan's units of branch-and-bound work are spent: "
                                        "give n_terms, prior terms, max_terms or a larger "
                                        "effort", k, False)
            work_limit = min(scout_work, work_left)
        search = branch_and_bound if backend is None else backend.branch_and_bound
        res = search(A, bal.b, k, f_loc, admissible=adm, D=D if bal.passive else None,
                     scale_system=scale_system, time_limit=time_limit, progress=progress,
                     structure=structure, work_limit=work_limit)
    elif res is None:
        res = best_subset(A, bal.b, k, f_loc, admissible=adm, D=D if bal.passive else None,
                          scale_system=scale_system, progress=progress, structure=structure,
                          kinetic=kinetic, backend=backend)
    res.support = cols.full(res.support)
    res.coef = cols.full_coef(res.coef, p)
    # copies: a search kept to go on with (``state``) still holds these in its own indices
    res.candidates = [replace(c, support=cols.full(c.support),
                              coef=None if c.coef is None else cols.full_coef(c.coef, p))
                      for c in res.candidates]
    if res.supports is not None:
        res.supports = cols.keep[res.supports]
    return res, beam


def _local_structure(admissible, p, cols):
    """:func:`~lsindy_cas.identify.bnb.structure_of` in the searched columns' indices (or None)."""
    st = structure_of(admissible, p)
    if st is None:
        return None
    banned = [cols.pos[j] for j in st[0] if j in cols.pos]
    required = [np.array([cols.pos[int(j)] for j in r if int(j) in cols.pos], dtype=np.int64)
                for r in st[1]]
    return banned, required


def _local_kinetic(admissible, p, cols, n_states=50):
    """∂²θ/∂q̇∂q̇ at up to ``n_states`` of the states the kinetic rule checks, in the searched
    columns (for the batched rule in :func:`~lsindy_cas.identify.search.visit`), or None."""
    hess = getattr(admissible, "hess", None)
    if hess is None or hess.shape[-1] != p:
        return None
    return hess[::max(1, len(hess) // n_states)][..., cols.keep]


def _beam(A, b, D, k, prev: SearchResult, cols, admissible, scale_system, n_report=10,
          max_visits=MAX_VISITS, structure=None, kinetic=None):
    """Score the one-term extensions of the best BEAM supports of size k − 1 (local indices)."""
    order = np.argsort(prev.scores, kind="stable")[:BEAM]
    base = np.array([cols.local(S) for S in prev.supports[order]], dtype=np.int64)
    p = A.shape[1]
    ext = np.repeat(base, p, axis=0)
    add = np.tile(np.arange(p), len(base))
    ok = ~np.any(ext == add[:, None], axis=1)
    S = np.sort(np.hstack([ext[ok], add[ok, None]]), axis=1)
    S = np.unique(S, axis=0)
    scores, degenerate = score_supports(A, b, S, D if b is None else None)
    v = visit(A, b, S, scores, degenerate, admissible=admissible, scale_system=scale_system,
              max_visits=max_visits, n_report=n_report, structure=structure, kinetic=kinetic)
    if v.winner is None:
        raise NoAdmissibleModel(f"no physically admissible {k}-term model among the one-term "
                                "extensions of the best smaller models", k, False)
    res = v.result(S, scores, degenerate)
    res.method, res.proven = "beam", False      # not every support scored: no certificate
    return res


def select(bal: EnergyBalance, forced, *, n_terms: int | None = None, admissible: Callable | None = None,
           scale_system=None, exclude=(), max_terms: int | None = None, noise=None,
           progress: Callable | None = None, time_limit: float | None = None,
           work_limit: float | None = None, backend=None, effort: float = 1.0) -> Selection:
    """Choose the support (and k when ``n_terms`` is None) of the energy.

    Parameters
    ----------
    bal : EnergyBalance
    forced : sequence of int
        Prior terms (in every support).
    n_terms : int, optional
        Fixed k; None chooses k on held-out data (module notes).
    admissible : callable ``(support, coef) -> (bool, reason)``, optional
        Physical admissibility and significance of a candidate (full-library indices).
    scale_system : (A_s, b_s), optional
        Passive scheme: the actuated record fixing the scale (eq. 8).
    exclude : sequence of int
        Library terms kept out of the search (e.g. a coordinate that a constant force makes
        indistinguishable from a potential).
    max_terms : int, optional
        Automatic k: largest k tried (default: prior terms + MAX_EXTRA).
    noise : NoiseModel, optional
        Expected noise of the rows (driven data): enables the discrepancy cap on k.
    progress : callable ``(n_done, n_total)``, optional
    time_limit : float, optional
        Seconds allowed to each branch-and-bound search (:mod:`lsindy_cas.identify.bnb`): the
        search at the given k, or each scout of the automatic scan and the chosen k's certificate.
    work_limit : float, optional
        With ``n_terms``: the branch and bound's work limit (:mod:`~lsindy_cas.identify.bnb`).
    backend : object, optional
        Where the searches run (:mod:`~lsindy_cas.identify.distributed`: ``score_all`` and
        ``branch_and_bound``); None: in this process.
    effort : float
        Automatic k: multiplies the scan's work budgets (``SCOUT_WORK`` per scout, ``AUTO_WORK``
        for the scan): more for a large library whose scouts stop undecided.

    Returns
    -------
    Selection
    """
    p = bal.A.shape[1]
    forced = sorted(set(int(j) for j in forced))
    if set(forced) & set(int(j) for j in exclude):
        raise ValueError("a prior term cannot be excluded from the search")
    cols = _Columns(p, exclude)
    folds = fold_ids(bal)
    if n_terms is not None:
        res, _ = _search_k(bal, int(n_terms), forced, cols, admissible, scale_system, progress, None,
                           time_limit, work_limit=work_limit, backend=backend)
        cv, per = cv_error(bal, res.support, folds)
        step = Step(int(n_terms), res.support, res.coef, res.score, cv, per, res,
                    chi=_chi(bal, res, noise))
        _drop_states([step])
        return Selection(step.k, res.support, res.coef, res, [step], False, cols.excluded)
    scout_work, auto_work = SCOUT_WORK * effort, AUTO_WORK * effort
    k_lo = max(len(forced), 2 if bal.passive else 1)
    k_hi = min(len(cols.keep), len(forced) + MAX_EXTRA if max_terms is None else int(max_terms))
    if k_hi < k_lo:
        raise ValueError(f"max_terms = {max_terms} is smaller than the {k_lo} terms every model needs")
    steps, unscored, best, prev, fits, lowest = [], [], None, None, None, None
    work = 0.0                           # branch-and-bound work of the whole scan (AUTO_WORK)
    stopped = {}                         # k -> the state of its scout that stopped undecided
    for k in range(k_lo, k_hi + 1):
        t0 = time.monotonic()
        try:
            res, beam = _search_k(bal, k, forced, cols, admissible, scale_system, progress, prev,
                                  time_limit, automatic=True, work_left=auto_work - work,
                                  backend=backend, scout_work=scout_work)
        except NoAdmissibleModel as exc:  # no admissible k-term model found: say so, try k + 1
            work += exc.work
            unscored.append(Unscored(k, str(exc), exc.proven, time.monotonic() - t0, exc.work))
            if getattr(exc, "state", None) is not None:
                stopped[k] = exc.state
            prev = None
            continue
        work += res.work
        step = _step(bal, k, res, beam, folds, noise)
        if res.method == "beam" and not fair(step):
            # the beam only extends the best smaller models: a poor fit may be its blind spot
            try:
                scout, _ = _search_k(bal, k, forced, cols, admissible, scale_system, progress,
                                     None, time_limit, automatic=True,
                                     work_left=auto_work - work, backend=backend,
                                     scout_work=scout_work)
                work += scout.work
                if scout.score < res.score - SCORE_RESOLUTION:
                    step = _step(bal, k, scout, True, folds, noise)
            except NoAdmissibleModel as exc:
                work += exc.work
        steps.append(step)
        prev = step
        if fits is None and fits_data(step):
            fits = step                  # the discrepancy principle: enough terms for the noise
        if best is None or better(step, best):
            best = step
        if lowest is None or gain(step, lowest):
            lowest = step                # the scan goes on while more terms still help at all
        if step.search.interrupted or fits is not None:   # Ctrl-C, or a fit
            break
        # passive data give no χ: nothing tells a model that explains them from one that misses a
        # detail, so the scan goes on to k_hi (damped double pendulum, 83 terms: 0.4 % of the
        # held-out changes unexplained at k = 5 … 7, 2e-8 at k = 8)
        if k - max(best.k, lowest.k) >= 2 and fair(best) and (np.isfinite(best.chi)
                                                              or not bal.passive):
            break
    # more work for the undecided k up to two past the best (where a driven scan looks), or for
    # all of them while no model explains the data (passive double pendulum, 83 terms, exact at
    # k = 8: k = 10 and 11 took 2 of 4 minutes and found nothing better)
    if best is not None and fair(best):
        top = max(best.k, lowest.k) + 2
        stopped = {k: st for k, st in stopped.items() if k <= top}
    if fits is None and stopped and not any(st.search.interrupted for st in steps):
        work = _deepen(bal, stopped, steps, unscored, forced, cols, admissible, scale_system,
                       progress, noise, folds, time_limit, auto_work, work, scout_work)
        best, fits = choose(steps)
    if best is None:
        open_k = [u.k for u in unscored if not u.proven]
        if open_k:                       # not a proof: the scouts stopped before finding one
            raise UndeterminedError(
                f"no model found for any number of terms {k_lo}..{k_hi}: the searches of k = "
                + ", ".join(map(str, open_k)) + f" stopped undecided ({work:,.0f} units of work, "
                f"{auto_work:,.0f} for the scan) — give the number of terms "
                "(n_terms / --terms), prior terms, a smaller library or a larger search effort "
                f"(effort / --effort, now {effort:g}) ("
                + "; ".join(str(u) for u in unscored[:3]) + ")")
        raise UndeterminedError("the data cannot identify the energy: no physically admissible model "
                         f"with significant terms for any number of terms {k_lo}..{k_hi} — vary "
                         "the input, add runs or check the library ("
                         + "; ".join(str(u) for u in unscored[:3]) + ")")
    if fits is not None and fits.k < best.k:
        best = fits
    if best.search is not None and (best.search.method == "beam" or not best.search.proven):
        best = _certify(bal, best, steps, forced, cols, admissible, scale_system, progress, noise,
                        folds, time_limit, auto_work - work, backend, scout_work)
    _drop_states(steps)
    return Selection(best.k, best.support, best.coef, best.search, steps, True, cols.excluded,
                     unscored)


def _drop_states(steps) -> None:
    """The fitted model keeps the searches' results, not their trees (up to ~0.5 GB each)."""
    for st in steps:
        if st.search is not None:
            st.search.state = None


def _certify(bal, step, steps, forced, cols, admissible, scale_system, progress, noise, folds,
             time_limit, work_left, backend=None, scout_work=SCOUT_WORK) -> Step:
    """The chosen k came from the beam or a scout (no certificate): search it again by branch and
    bound (``time_limit`` seconds, or without one what is left of AUTO_WORK) and keep its answer —
    the same support, now with a certificate, or a better-scoring admissible one the first search
    missed; the first search's when it finds none."""
    if time_limit is None and work_left < scout_work:
        return step                      # the scan spent its budget: no certificate
    try:                                 # a scout's search goes on where it stopped
        res, _ = _search_k(bal, step.k, forced, cols, admissible, scale_system, progress, None,
                           time_limit, work_limit=None if time_limit is not None else work_left,
                           backend=backend, resume=getattr(step.search, "state", None))
    except (NoAdmissibleModel, KeyboardInterrupt):
        return step
    if res.score > step.score + SCORE_RESOLUTION:
        return step
    cv, per = cv_error(bal, res.support, folds)
    new = Step(step.k, res.support, res.coef, res.score, cv, per, res, True, _chi(bal, res, noise))
    steps[steps.index(step)] = new
    return new


def _deepen(bal, stopped, steps, unscored, forced, cols, admissible, scale_system, progress,
            noise, folds, time_limit, auto_work, work, scout_work) -> float:
    """No k of the scan fits the data and some scouts stopped undecided: go on with their
    searches, smallest k first, each round with twice the work of the round before, until one
    finds a model that fits (the scan's answer), every one is decided or the scan's work is
    spent.  ``steps`` and ``unscored`` are updated in place; returns the scan's work."""
    chunk = scout_work
    while stopped and work < auto_work:
        for k in sorted(stopped):
            if work >= auto_work:
                break
            state, u = stopped.pop(k), next(u for u in unscored if u.k == k)
            before, t0 = state.work, time.monotonic()
            try:
                res, _ = _search_k(bal, k, forced, cols, admissible, scale_system, progress,
                                   None, time_limit, work_limit=min(chunk, auto_work - work),
                                   resume=state)
            except NoAdmissibleModel as exc:
                work += exc.work - before
                unscored[unscored.index(u)] = Unscored(
                    k, str(exc), exc.proven, u.seconds + time.monotonic() - t0, exc.work)
                if getattr(exc, "state", None) is not None:
                    stopped[k] = exc.state
                continue
            work += res.work - before
            unscored.remove(u)
            step = _step(bal, k, res, False, folds, noise)
            steps.append(step)
            steps.sort(key=lambda st: st.k)
            if fits_data(step) or res.interrupted:
                return work
        chunk *= 2
    return work


def _step(bal, k, res, beam, folds, noise) -> Step:
    cv, per = cv_error(bal, res.support, folds)
    return Step(k, res.support, res.coef, res.score, cv, per, res, beam, _chi(bal, res, noise))


def _chi(bal, res, noise) -> float:
    """Residual of the search's model in units of its expected noise (nan without a noise model)."""
    if noise is None or bal.b is None:
        return float("nan")
    return chi_of(bal, res.coef, noise)
