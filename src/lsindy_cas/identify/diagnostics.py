"""What a user should know about an identified energy: ties, null space, traps, in plain words.

:func:`diagnose` builds a :class:`Diagnostics` report after a fit (``model.diagnostics_``; the CLI
prints it).  Every test compares dimensionless quantities — score ratios, held-out error fractions,
t-statistics, singular values of column-normalised matrices — so nothing depends on units.

Known traps, detected from the structure of the data rather than from the fit:

- **constant input** — when every run is driven by the same constant force u on coordinate x,
  E − u·x is conserved, so E + c·(E − u·x) fits the balance for every c: a constant force is
  indistinguishable from a linear potential.  The pure term x (if in the library) is kept out of
  the search, and the report says so;
- **several conserved quantities (passive data)** — E and, e.g., an angular momentum are both
  conserved, so the null space of the passive balance holds both; only the actuated scale trial
  tells them apart.  They are counted among the supports the passive search found (nearly) as
  conserved as the winner (:mod:`~lsindy_cas.identify.conserved`: identities and, with friction,
  quantities the dissipation explains are not conserved quantities).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import findings as F
from .balance import EnergyBalance
from .findings import Finding
from .conserved import conserved_quantities
from .fitting import coef_on_support, normalise_columns

__all__ = ["CONTENDER", "Diagnostics", "ConstantForceTrap", "FitRecord", "constant_force_trap", "diagnose",
           "conserved_quantities", "NEAR_TIE"]

NEAR_TIE = 2.0          # an admissible support within this factor of the winner's score is a near tie
CONTENDER = 10.0        # runners-up listed in the report: within this factor of the winner's score
NEAR_NULL_FACTOR = 10.0     # see _null_dim
_POOR_FIT = 0.5         # unexplained fraction of the work above which the data explain too little
_NUMERICAL_ZERO = 1e-20  # passive scores (squared normalised singular values) this small are exact


@dataclass
class ConstantForceTrap:
    """Every run is driven by the same constant generalized forces ``u`` (n,)."""

    coords: list
    u: np.ndarray
    excluded: list
    in_library: list


def constant_force_trap(library, trajectories, forced=()) -> ConstantForceTrap | None:
    """Detect the constant-input trap; None when the forces vary (or are zero)."""
    Q = np.vstack([tr.Q for tr in trajectories])
    if not np.any(Q) or np.any(np.ptp(Q, axis=0) != 0):
        return None
    u = Q[0].copy()
    names = library.coords.names
    coords = [c for c, v in zip(names, u) if v != 0]
    excluded, in_lib = [], []
    for c in coords:
        try:
            j = library.index(c)
        except ValueError:
            continue
        in_lib.append(c)
        if j not in set(forced):
            excluded.append(j)
    return ConstantForceTrap(coords, u, excluded, in_lib)


@dataclass
class FitRecord:
    """What one fit produced, stage by stage: the input of :func:`diagnose`.

    Attributes
    ----------
    library : Library
    balance : EnergyBalance
        The balance the coefficients were fitted on (the weighted one after refinement).
    trajectories : list of Trajectory
        The training runs as given.
    scale_system : (A_s, b_s) or None
        Passive scheme: the actuated scale record.
    admissibility : Admissibility
        The rules the chosen support passed.
    selection : Selection
        The support search and the choice of k.
    coef : array (p,)
        The energy's coefficients.
    smoothing : list of Smoothed or None
    trap : ConstantForceTrap or None
    hold : str or None
        The input hold of the work integral (None without one).
    state_var : array (n_rows, 2n) or None
        Noise variance of the states behind each row (smoothed integral form): what the status
        needs to judge any support's residual in units of its own noise (χ).
    """

    library: object
    balance: EnergyBalance
    trajectories: list
    scale_system: tuple | None
    admissibility: object
    selection: object
    coef: np.ndarray = field(repr=False)
    smoothing: list | None = None
    trap: ConstantForceTrap | None = None
    hold: str | None = None
    state_var: np.ndarray | None = field(default=None, repr=False)

    @property
    def search(self):
        return self.selection.search

    @property
    def support(self) -> tuple:
        return tuple(int(j) for j in np.flatnonzero(self.coef))


@dataclass
class Diagnostics:
    """Readable report on an identification (``str()`` gives the text the CLI prints).

    Attributes
    ----------
    near_ties : list of (terms, ratio, admissible, reason)
        Runners-up with their score / the winner's score (≥ 1 unless rejected).
    null_dim : int
        Directions on the chosen support that the data do not determine (driven: 0 is right;
        passive: 1 is the energy itself).
    held_out_error : float
        Fraction of the held-out work (or term changes) the model does not explain, pooled over
        the folds; ``held_out_fold_median`` is its median over the folds (robust to one fold that
        extrapolates).
    chi : float
        Residual in units of what the estimated noise explains (≈ 1: fits to within the noise;
        nan without a noise estimate).
    k_path : list of (k, held-out error, χ)
    k_unscored : list of str
        Automatic k: the k of the scan without a model and why (no admissible model, or
        undecided: its search stopped first), with the time spent.
    noise : dict
        Estimated noise std per state column (integral form), from the smoother.
    conserved : list of str
        Passive data: conserved quantities found besides the energy.
    traps : list of Finding
        Known traps, in plain words (a :class:`~.findings.Finding` is its message, with a code).
    warnings : list of Finding
        Everything that makes the result doubtful; empty on well-posed data.
    hold : str or None
        The input hold the work integral used ("zoh", "smooth"; None without a work integral).
    hold_errors : dict
        When the hold was decided from the data: held-out error of the model under each hold.
    velocities : str
        "measured", or "estimated" from the positions (positions-only data), or "mixed".
    status : {"ok", "undetermined"} or None
        The one verdict (:mod:`lsindy_cas.identify.status`); None before it is assessed.
    status_reasons : list of Finding
        Why the fit is undetermined, in plain words (each with its code).
    checks : dict
        The numbers behind the verdict (simulation drift, condition number, ...).
    """

    near_ties: list = field(default_factory=list)
    null_dim: int = 0
    held_out_error: float = 0.0
    held_out_fold_median: float = 0.0
    chi: float = float("nan")
    k_path: list = field(default_factory=list)
    k_unscored: list = field(default_factory=list)
    k_automatic: bool = False
    noise: dict = field(default_factory=dict)
    conserved: list = field(default_factory=list)
    traps: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    hold: str | None = None
    state_var: np.ndarray | None = field(default=None, repr=False)
    hold_errors: dict = field(default_factory=dict)
    velocities: str = "measured"
    status: str | None = None
    status_reasons: list = field(default_factory=list)
    checks: dict = field(default_factory=dict)
    conserved_found: list = field(default_factory=list, repr=False)   # (support, η) per quantity

    @property
    def ok(self) -> bool:
        """True when nothing needs the user's attention."""
        return not self.traps and not self.warnings

    def to_dict(self) -> dict:
        return {"near_ties": [{"terms": t, "score_ratio": r, "admissible": a, "reason": why}
                              for t, r, a, why in self.near_ties],
                "null_dim": self.null_dim, "held_out_error": self.held_out_error,
                "chi": self.chi if np.isfinite(self.chi) else None,
                "k_path": [{"k": k, "held_out_error": e, "chi": c if np.isfinite(c) else None}
                           for k, e, c in self.k_path],
                "k_unscored": list(self.k_unscored),
                "k_automatic": self.k_automatic, "noise": self.noise,
                "conserved": self.conserved, "traps": self.traps, "warnings": self.warnings,
                "hold": self.hold, "hold_errors": self.hold_errors, "velocities": self.velocities,
                "status": self.status, "status_reasons": self.status_reasons,
                "checks": {k: _jsonable(v) for k, v in self.checks.items()}}

    def __str__(self) -> str:
        lines = ["diagnostics:"]
        if self.k_path:
            how = "chosen automatically" if self.k_automatic else "k given"
            path = ", ".join(f"k={k}: {e:.1e}" + (f" (χ {c:.3g})" if np.isfinite(c) else "")
                             for k, e, c in self.k_path)
            lines.append(f"  held-out error by number of terms ({how}): {path}")
        for u in self.k_unscored:
            lines.append(f"  no model at {u}")
        lines.append(f"  held-out error of the model: {self.held_out_error:.2e} "
                     "(fraction not explained)")
        if np.isfinite(self.chi):
            lines.append(f"  residual / expected noise: {self.chi:.3g} "
                         "(≈ 1 means it fits to within the noise)")
        if self.hold is not None:
            how = ("chosen from the data: held-out error " + ", ".join(
                f"{h} {e:.1e}" for h, e in self.hold_errors.items()) if self.hold_errors
                else "held input" if self.hold == "zoh" else "smooth input")
            lines.append(f"  input hold of the work integral: {self.hold} ({how})")
        if self.velocities != "measured":
            lines.append(f"  velocities: {self.velocities} (estimated = the smoother's derivative "
                         "of the positions; its error is in the noise model)")
        lines.append("  undetermined directions on the support (near-null space): "
                     f"{self.null_dim}")
        if self.noise:
            lines.append("  estimated noise std: "
                         + ", ".join(f"{k} {v:.1e}" for k, v in self.noise.items()))
        if self.near_ties:
            lines.append(f"  other supports within {CONTENDER:g}× of the winner's score "
                         "(score / winner's):")
            for terms, r, ok, why in self.near_ties[:3]:
                tag = ("NEAR TIE, admissible" if r <= NEAR_TIE else "admissible") if ok else \
                    f"rejected: {why}" if why else "not examined"
                lines.append(f"    {r:8.3g}×  {' + '.join(terms)}  [{tag}]")
        for t in self.traps:
            lines.append(f"  TRAP: {t}")
        for w in self.warnings:
            lines.append(f"  WARNING: {w}")
        if self.ok:
            lines.append("  no traps or warnings: the data identify this energy")
        if "simulation_drift" in self.checks:
            lines.append(f"  short simulation from measured states: drift "
                         f"{self.checks['simulation_drift']:.1e} of the states' range; condition "
                         f"number of the chosen terms {self.checks.get('condition', np.nan):.2g}")
        if self.status is not None:
            lines.append(f"  status: {self.status.upper()}" + ("" if not self.status_reasons else
                         " — " + "; ".join(self.status_reasons)))
        return "\n".join(lines)


def _jsonable(v):
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    v = float(v)
    return v if np.isfinite(v) else None


def _null_dim(bal: EnergyBalance, S, score: float) -> int:
    """Directions of the normalised coefficients whose standard error exceeds 1/√10 of a unit.

    With column-normalised A_S and ‖b‖ = 1 the residual per row has variance ≈ score/m, so the
    coefficients along singular direction j scatter by √(score/m)/σ_j; undetermined when
    σ_j² ≤ 10·score/m.  Passive: relative to the smallest singular value (the energy itself).
    """
    sv = np.linalg.svd(normalise_columns(bal.A[:, list(S)])[0], compute_uv=False)
    if bal.passive:
        return int(np.sum(sv ** 2 <= NEAR_NULL_FACTOR * max(sv[-1] ** 2, 1e-300)))
    return int(np.sum(sv ** 2 <= NEAR_NULL_FACTOR * max(score, 1e-300) / bal.n_rows))


def _near_ties(fit: FitRecord, n: int = 5) -> list:
    res, lib, bal, admissible = fit.search, fit.library, fit.balance, fit.admissibility
    out, seen = [], {tuple(res.support)}
    base = max(res.score, _NUMERICAL_ZERO)     # exact fits tie at the level of round-off
    for c in res.candidates:
        if tuple(c.support) in seen or len(out) >= n:
            continue
        seen.add(tuple(c.support))
        if c.score > CONTENDER * base:
            continue                   # not a contender
        ok, why = c.admissible, c.reason
        if ok is None and admissible is not None and c.score <= NEAR_TIE * base:
            coef = None if bal.passive else coef_on_support(bal.A, bal.b, c.support, None)[0]
            ok, why = ((False, Finding("no coefficients", F.NO_COEFFICIENTS)) if coef is None
                       else admissible(c.support, coef))
        out.append(([lib.names[j] for j in c.support], float(max(c.score, _NUMERICAL_ZERO) / base),
                    bool(ok), why))
    return out


def diagnose(fit: FitRecord) -> Diagnostics:
    """Build the report on a fit (:class:`FitRecord`, made by ``LagrangianSINDy.fit``)."""
    lib, sel, bal = fit.library, fit.selection, fit.balance
    d = Diagnostics(hold=fit.hold)
    S = fit.support
    step = next((s for s in sel.steps if s.k == sel.k), sel.steps[-1])
    d.held_out_error = float(step.cv)
    d.held_out_fold_median = float(np.median(step.cv_folds))
    d.chi = float(step.chi)
    d.k_automatic = bool(sel.automatic)
    d.k_path = [(s.k, float(s.cv), float(s.chi)) for s in sel.steps]
    d.k_unscored = [str(u) for u in getattr(sel, "unscored", [])]
    d.null_dim = _null_dim(bal, S, fit.search.score)
    d.near_ties = _near_ties(fit)
    if fit.smoothing:
        names = list(lib.coords.names) + [c + "_dot" for c in lib.coords.names]
        noise = np.sqrt(np.mean([s.noise ** 2 for s in fit.smoothing], axis=0))
        d.noise = {n: float(v) for n, v in zip(names, noise)}
    if fit.trap is not None:
        d.traps.append(Finding(_constant_force_text(lib, fit.trap, S), F.CONSTANT_INPUT))
    if bal.passive:
        _passive_report(d, fit)
    _warnings(d, fit)
    return d


def _constant_force_text(lib, trap: ConstantForceTrap, S) -> str:
    parts = []
    for c, u in zip(lib.coords.names, trap.u):
        if u == 0:
            continue
        cyclic = not any(c in lib.positions(k) for k in S)
        if c in trap.in_library:
            where = "cyclic (the energy does not depend on it)" if cyclic else "in the energy"
            left = " — the term was left out of the search" if lib.index(c) in trap.excluded else ""
            parts.append(f"input is constant (Q_{c} = {u:g}) and coordinate {c} is {where}: "
                         f"E and E − u·{c} fit equally{left}; vary the input or drop {c}")
        else:
            parts.append(f"input is constant (Q_{c} = {u:g}): a constant force on {c} acts like a "
                         f"potential −u·{c}, so E and E − u·{c} fit equally; {c} itself is not a "
                         "library term, but over a short run other terms can imitate it — vary "
                         "the input")
    return "; ".join(parts)


def _passive_report(d: Diagnostics, fit: FitRecord):
    lib, res = fit.library, fit.search
    floor = max(NEAR_TIE * res.score, _NUMERICAL_ZERO)
    found = conserved_quantities(lib, fit.balance, res.candidates, fit.coef, floor)
    d.conserved = [_expression(lib, S, eta) for S, eta in found]
    d.conserved_found = found
    if d.conserved:
        d.traps.append(Finding(f"the passive data conserve {1 + len(found)} quantities (energy and "
                               f"{'; '.join(d.conserved)}); a scale trial is needed to tell them "
                               "apart (the actuated record picked the energy)",
                               F.CONSERVED_QUANTITIES, {"count": 1 + len(found)}))


def _expression(lib, S, eta) -> str:
    """Readable I = Σ c_j θ_j, scaled to a largest coefficient of 1, round-off terms dropped."""
    c = np.asarray(eta, float) / np.max(np.abs(eta))
    parts = [f"{v:+.3g}·{lib.names[j]}" for j, v in zip(S, c) if abs(v) > 1e-6]
    return " ".join(parts).lstrip("+")


def _warnings(d: Diagnostics, fit: FitRecord):
    score, bal = fit.search.score, fit.balance
    held_out = d.held_out_fold_median
    if not bal.passive and max(score, held_out) > _POOR_FIT:
        d.warnings.append(Finding(
            f"the data cannot identify the energy: the best model leaves "
            f"{100 * min(max(score, held_out), 1):.0f} % of the "
            f"{'held-out ' if held_out > score else ''}work unexplained — the runs "
            "may barely move, the noise may swamp them, or the library may lack the "
            "energy's terms", F.WORK_UNEXPLAINED,
            {"unexplained": float(min(max(score, held_out), 1)), "held_out": held_out > score}))
    extra = d.null_dim - (1 if bal.passive else 0)
    if extra > 0:
        d.warnings.append(Finding(f"the data cannot identify the energy uniquely: {extra} "
                                  "combination(s) of the chosen terms change the fit less than its "
                                  "residual does", F.NULL_SPACE, {"extra": int(extra)}))
    ties = [t for t in d.near_ties if t[2] and t[1] <= NEAR_TIE]
    if ties:
        d.warnings.append(Finding(f"{len(ties)} other admissible support(s) fit within "
                                  f"{NEAR_TIE:g}× of the chosen one; more varied data would "
                                  "separate them", F.NEAR_TIE, {"count": len(ties),
                                                                "near_tie": NEAR_TIE}))
