"""``LagrangianSINDy``: trajectories -> energy (H) -> Lagrangian (L) -> equations of motion."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import sympy as sp

from .._validate import check_choice, check_int
from .admissibility import Admissibility
from .balance import derivative_form, integral_form
from ..data.trajectory import Trajectory
from .diagnostics import FitRecord, constant_force_trap, diagnose
from ..mechanics.legendre import legendre
from ..symbolic.library import Library
from ..mechanics.euler_lagrange import EulerLagrange, simulate_ode
from .selection import select
from .standard_errors import coefficient_errors
from ..data.smoothing import force_switches, smooth
from .uncertainty import corrected_coef, corrected_null, energy_variance, noise_gram, noise_model, \
    row_gradients, sample_weights

__all__ = ["LagrangianSINDy"]

_FORMS = ("auto", "derivative", "integral")
_SMOOTHING = ("auto", "none")
_HOLDS = ("auto", "zoh", "smooth")
# Errors in variables (``_refine``): the sample weights depend on the coefficients they weight, so
# weights and coefficients are updated in turn, a fixed number of passes (no tolerance in the units
# of the data).  The support may be re-selected on the weighted balance only in the first
# _RESELECT_PASSES passes, so the last pass always re-weights and corrects the coefficients on the
# support they will be reported on.
_REFINE_PASSES = 3
_RESELECT_PASSES = 2


def _check_trajectories(trajectories, coords, what="trajectories") -> list:
    if isinstance(trajectories, Trajectory):
        trajectories = [trajectories]
    try:
        trajectories = list(trajectories)
    except TypeError:
        raise TypeError(f"{what} must be a Trajectory or a list of them") from None
    if not trajectories:
        raise ValueError(f"{what} is empty")
    for tr in trajectories:
        if not isinstance(tr, Trajectory):
            raise TypeError(f"{what} must contain Trajectory objects, got {type(tr).__name__}")
    return [tr.reorder(coords) for tr in trajectories]


class LagrangianSINDy:
    """Lagrangian-SINDy (Chu & Hayashibe 2020): sparse energy, Legendre transform, Euler–Lagrange.

    Parameters
    ----------
    library : Library
        Candidate terms Θ.
    n_terms : int, optional
        Number of terms k in the energy (paper's k).  None (default): chosen from the data on
        held-out trajectories or stretches (:mod:`lsindy_cas.identify.selection`).
    prior : sequence of str
        Terms known to be in the energy (e.g. those of the constituent simple systems); forced into
        every support and required to come out significantly non-zero.
    form : {"auto", "derivative", "integral"}
        Energy-balance form; "auto" uses the derivative form when every trajectory carries exact
        accelerations and the integral (weak) form otherwise.
    window : int, optional
        Integral form: None (default) stacks every window of every run; an integer uses windows of
        that many samples.
    smoothing : {"auto", "none"}
        Integral form: "auto" smooths the measured states with a strength chosen from the data
        (:func:`lsindy_cas.data.smoothing.smooth`); "none" uses them as measured.  Either way the noise
        level is estimated and the coefficients are corrected for noise in the regressors.
    max_terms : int, optional
        Automatic k: the largest k tried.
    hold : {"auto", "zoh", "smooth"}
        Integral form: what a sample ``Q_i`` of the applied force means.  "zoh": it is held over
        [t_i, t_{i+1}) (a digital controller's output; the work is Q_i ∫ q̇ dt per interval);
        "smooth": the force varies smoothly and the power is integrated as a spline.  "auto"
        (default): a force that is constant or changes at few samples is held; one that changes
        at most samples is ambiguous — both work integrals are fitted and the one with the
        smaller held-out error is kept.  ``hold_`` says which was used.

    Attributes (after ``fit``)
    --------------------------
    coords_ : list of str
    coef_ : array (p,)            energy coefficients ξ (H = Θ ξ)
    lagrangian_coef_ : array (p,) Lagrangian coefficients ξ_L (eq. 7)
    coef_std_, lagrangian_coef_std_ : array (p,)
                                  standard errors of ξ and ξ_L (0 off the support; jackknife,
                                  :mod:`lsindy_cas.identify.standard_errors`)
    std_method_ : str             how they were obtained, e.g. "jackknife over 10 runs"
    support_ : tuple of int
    n_terms_ : int                the k used (chosen or given)
    hamiltonian_, lagrangian_ : sympy.Expr
    actuated_ : list of str       coordinates that carried an applied force in the data
    search_ : SearchResult        ranking and diagnostics of the support search
    selection_ : Selection        every k tried and its held-out error
    passive_ : bool               whether the passive (null-space + scale) scheme was used
    smoothing_ : list of Smoothed or None
    diagnostics_ : Diagnostics    near ties, null space, traps, warnings (print it)
    hold_ : str or None           the input hold used by the work integral ("zoh"/"smooth"; None
                                  when no work integral was needed)
    """

    def __init__(self, library: Library, *, n_terms: int | None = None, prior=(), form: str = "auto",
                 window: int | None = None, smoothing: str = "auto", max_terms: int | None = None,
                 hold: str = "auto"):
        self.library = library
        self.n_terms = n_terms
        self.prior = prior
        self.form = form
        self.window = window
        self.smoothing = smoothing
        self.max_terms = max_terms
        self.hold = hold

    # ------------------------------------------------------------------ fitting
    def _validate(self):
        if not isinstance(self.library, Library):
            raise TypeError(f"library must be a Library, got {type(self.library).__name__}")
        prior = [self.prior] if isinstance(self.prior, str) else list(self.prior)
        forced = [self.library.index(t, what="prior term") for t in prior]
        for name, k in (("n_terms", self.n_terms), ("max_terms", self.max_terms)):
            k = check_int(name, k, allow_none=True)
            if k is None:
                continue
            if not 1 <= k <= len(self.library):
                raise ValueError(f"{name} = {k} must be between 1 and the library size "
                                 f"{len(self.library)}")
            if len(set(forced)) > k:
                raise ValueError(f"{len(set(forced))} prior terms do not fit in {name} = {k}")
        check_choice("form", self.form, _FORMS)
        check_choice("hold", self.hold, _HOLDS)
        check_choice("smoothing", self.smoothing, _SMOOTHING)
        check_int("window", self.window, low=1, allow_none=True)
        return sorted(set(forced))

    def _form(self, trajectories) -> str:
        if self.form == "auto":
            return "derivative" if all(tr.qdd is not None for tr in trajectories) else "integral"
        return self.form

    def _balance(self, trajectories, passive=None, weights=None):
        if self._form(trajectories) == "derivative":
            return derivative_form(self.library, trajectories, passive=passive)
        return integral_form(self.library, trajectories, window=self.window, passive=passive,
                             weights=weights, hold=self.hold_ or "auto")

    def _prepare(self, trajectories):
        """States for the balance and their noise variance per row (integral form), or as given."""
        if self._form(trajectories) == "derivative":
            return trajectories, None, None
        smoothed = [smooth(tr) for tr in trajectories]     # also estimates the noise for "none"
        states = [s.trajectory for s in smoothed] if self.smoothing == "auto" else trajectories
        # One variance per column and run: the per-sample ones (larger at the ends) were measured
        # to worsen the coefficients on the paper's 1 s runs (median error 6 % → 8 % at σ = 1e-3).
        var = np.vstack([np.broadcast_to((s.error ** 2).mean(axis=0) if self.smoothing == "auto"
                                         else s.noise ** 2, s.error.shape) for s in smoothed])
        return states, var, smoothed

    def fit(self, trajectories, scale_trajectories=None, passive=None,
            progress=None) -> "LagrangianSINDy":
        """Identify the energy, Lagrangian and equations of motion.

        Parameters
        ----------
        trajectories : Trajectory or list of Trajectory
            Training runs.  If none of them is driven (power ≡ 0) the passive scheme is used.
        scale_trajectories : Trajectory or list, optional
            Passive scheme only: a short actuated record that fixes the energy's scale (eq. 8).
        passive : bool, optional
            Force (True) or forbid (False) the passive scheme; by default it is used when the
            training data carry no power.
        progress : callable ``(n_done, n_total)``, optional
            Progress of the support search (e.g. :class:`lsindy_cas.progress.ProgressBar`).
        """
        self._validate()
        coords = self.library.coords.names
        runs = _check_trajectories(trajectories, coords)
        holds = self._holds(runs)
        if len(holds) == 1:
            return self._fit(runs, scale_trajectories, passive, progress, holds[0])
        # A force that changes at most samples: a smooth force sampled, or a held one changing every
        # sample.  The data decide: the wrong work integral leaves a systematic residual.  The
        # smoothing does not depend on the hold, so both trials share it.
        prepared = self._prepare(runs)
        trials = []
        for hold in holds:
            trial = copy.copy(self)
            trial._fit(runs, scale_trajectories, passive, progress, hold, prepared)
            trials.append(trial)
        best = min(trials, key=lambda m: m.diagnostics_.held_out_error)
        self.__dict__.update(best.__dict__)
        self.hold_errors_ = {m.hold_: m.diagnostics_.held_out_error for m in trials}
        self.diagnostics_.hold_errors = self.hold_errors_
        return self

    def _holds(self, trajectories) -> list:
        """The input holds to try: one when the data or the user settle it, else both."""
        if self.hold != "auto":
            return [self.hold]
        if self._form(trajectories) == "derivative":
            return [None]
        varying = [tr for tr in trajectories if np.any(np.diff(tr.Q, axis=0))]
        if all(force_switches(tr.Q).size for tr in varying):
            return ["zoh"]              # constant, or changing at few samples: a held input
        return ["zoh", "smooth"]

    def _fit(self, trajectories, scale_trajectories, passive, progress, hold, prepared=None):
        """One fit with a given input hold; ``prepared`` = ``_prepare(trajectories)`` if done."""
        self.hold_ = hold
        forced = self._validate()
        lib = self.library
        coords = lib.coords.names
        # 1. inputs: trajectories in the library's coordinate order
        trajectories = _check_trajectories(trajectories, coords)
        scale_list = (None if scale_trajectories is None else
                      _check_trajectories(scale_trajectories, coords, "scale_trajectories"))
        # 2. states: smoothed (integral form) with their noise variance
        states, state_var, smoothing = (self._prepare(trajectories) if prepared is None
                                         else prepared)
        # 3. energy balance (and the passive scheme's scale record)
        bal = self._balance(states, passive=passive)
        scale_system = self._scale_system(scale_list) if bal.passive else None
        # 4. the rules a candidate must pass
        trap = constant_force_trap(lib, trajectories, forced) if not bal.passive else None
        excluded = [] if trap is None else trap.excluded
        admissible = Admissibility.for_balance(lib, bal, forced, scale_system, excluded)
        # 5. support and k
        noise = (noise_model(bal, state_var, smoothing)
                 if state_var is not None and bal.centred else None)
        sel = select(bal, forced, n_terms=self.n_terms, admissible=admissible,
                     scale_system=scale_system, max_terms=self.max_terms, noise=noise,
                     progress=progress)
        coef = sel.coef
        # 6. errors in variables: re-weight, re-select (same k), correct for regressor noise
        if state_var is not None and bal.centred:
            coef, bal, sel, admissible = self._refine(states, passive, sel, forced, state_var,
                                                      scale_system, excluded, row_gradients(bal))
        # 7. the model and its report
        record = FitRecord(lib, bal, trajectories, scale_system, admissible, sel, coef,
                           smoothing, trap, hold)
        self.smoothing_, self.trap_ = smoothing, trap
        self.selection_ = sel
        self.search_ = sel.search
        self.n_terms_ = sel.k
        self.passive_ = bal.passive
        self.form_ = bal.form
        self.actuated_ = [c for c in coords if any(c in tr.actuated for tr in
                                                   trajectories + (scale_list or []))]
        self._set_coefficients(coef, X=bal.X)
        self._set_errors(coefficient_errors(bal, self.coef_, lib, bal.X, scale_system))
        self.diagnostics_ = diagnose(record)
        return self

    def _scale_system(self, scale_list):
        """Passive scheme: the actuated record (A_s, b_s) that fixes the energy's scale (eq. 8)."""
        if scale_list is None:
            raise ValueError("the training data are passive (no power fed in), which fixes the "
                             "energy only up to a factor: pass scale_trajectories, a short "
                             "actuated record (paper eq. 8)")
        scale = self._balance(self._prepare(scale_list)[0], passive=False)
        if not np.any(scale.b):
            raise ValueError("scale_trajectories carry no power (Q·q̇ ≡ 0); they cannot fix the scale")
        return scale.A, scale.b

    def _refine(self, states, passive, sel, forced, state_var, scale_system, excluded, grads):
        """Errors in variables: weight samples by the noise of the fitted energy, re-select on the
        weighted balance (same k), and correct the coefficients for regressor noise."""
        coef, support, sel_w, changed = sel.coef, sel.support, sel, True
        sizes = np.cumsum([tr.n_samples for tr in states])[:-1]
        for it in range(_REFINE_PASSES):
            w = sample_weights(energy_variance(grads, coef, state_var))
            bal_w = self._balance(states, passive=passive, weights=np.split(w, sizes))
            if changed and it < _RESELECT_PASSES:      # re-select on the weighted balance (same k)
                adm = Admissibility.for_balance(self.library, bal_w, forced, scale_system, excluded)
                try:
                    sel_w = select(bal_w, forced, n_terms=sel.k, scale_system=scale_system,
                                   admissible=adm)
                except ValueError:      # nothing passes with these weights: keep the support
                    changed = False
                else:
                    changed, support = sel_w.support != support, sel_w.support
            coef = _corrected(bal_w, grads, w, state_var, support, scale_system)
        sel_w.steps, sel_w.automatic = sel.steps, sel.automatic   # the held-out path of the k choice
        return coef, bal_w, sel_w, adm

    def _set_coefficients(self, coef, X=None):
        lib = self.library
        self.coords_ = list(lib.coords.names)
        self.coef_ = np.asarray(coef, float)
        self.support_ = tuple(int(j) for j in np.flatnonzero(self.coef_))
        self.lagrangian_coef_ = legendre(lib, self.coef_, X)
        self.hamiltonian_ = combine(lib, self.coef_)
        self.lagrangian_ = combine(lib, self.lagrangian_coef_)
        self._mechanics = EulerLagrange(lib.coords, self.lagrangian_)

    def _set_errors(self, errors):
        """Standard errors of H's and L's coefficients (:mod:`.standard_errors`)."""
        self.coef_std_ = np.asarray(errors.hamiltonian, float)
        self.lagrangian_coef_std_ = np.asarray(errors.lagrangian, float)
        self.std_method_ = errors.method

    def _check_fitted(self):
        if not hasattr(self, "coef_"):
            raise ValueError("this LagrangianSINDy is not fitted yet; call fit() or load()")

    # ------------------------------------------------------------------ results
    def terms(self, which: str = "hamiltonian") -> dict:
        """``{term name: coefficient}`` of the identified H or L."""
        self._check_fitted()
        coef = self.coef_ if which == "hamiltonian" else self.lagrangian_coef_
        return {self.library.names[j]: float(coef[j]) for j in np.flatnonzero(coef)}

    def ode(self):
        """``casadi.Function('ode', [x, u], [xdot])``: x = [q, q̇], u = Q (generalized forces)."""
        self._check_fitted()
        return self._mechanics.ode()

    def equations_of_motion(self) -> list:
        """Sympy ``Eq(M q̈, F)`` rows over ``<q>_ddot``, ``<q>``, ``<q>_dot`` and ``Q_<q>``."""
        self._check_fitted()
        return self._mechanics.equations()

    def simulate(self, x0, t, u=None) -> np.ndarray:
        """Integrate the identified equations of motion; returns states (len(t), 2n)."""
        self._check_fitted()
        return simulate_ode(self.ode(), x0, t, u, len(self.coords_))[0]

    def __str__(self) -> str:
        if not hasattr(self, "coef_"):
            return "LagrangianSINDy(unfitted)"
        from ..printing import MAX_DIGITS, coefficient_table, rounded
        H, L, eoms = rounded(self)     # digits from the standard errors
        lines = [f"H = {_fmt(H, MAX_DIGITS)}", f"L = {_fmt(L, MAX_DIGITS)}", "equations of motion:"]
        lines += [f"  {_fmt(e.lhs, MAX_DIGITS)} = {_fmt(e.rhs, MAX_DIGITS)}" for e in eoms]
        table = coefficient_table(self)
        return "\n".join(lines + ([table] if table else []))

    # ------------------------------------------------------------------ persistence
    def to_dict(self) -> dict:
        """The model as the DESIGN.md model-file dictionary (see :mod:`.model_file`)."""
        from .model_file import model_to_dict
        return model_to_dict(self)

    def save(self, path) -> Path:
        """Write the model as JSON (atomically; the DESIGN.md model file)."""
        from .model_file import save_model
        return save_model(self, path)

    @classmethod
    def load(cls, path) -> "LagrangianSINDy":
        """Read a model written by ``save`` or ``lsindy identify --json``."""
        from .model_file import load_model
        return load_model(cls, path)


def _corrected(bal, grads, w, state_var, support, scale_system) -> np.ndarray:
    """Coefficients (p,) on ``support`` with the regressor-noise Gram removed."""
    S = list(support)
    N = noise_gram(grads, state_var, S, w)
    coef = np.zeros(bal.A.shape[1])
    if bal.b is not None:
        coef[S] = corrected_coef(bal.A, bal.b, S, N)
        return coef
    coef[S] = corrected_null(bal.A, S, N, scale_system)
    return coef


def combine(lib: Library, coef) -> sp.Expr:
    """Σ_j coef_j θ_j over the non-zero coefficients (sympy)."""
    return sp.Add(*[sp.Float(float(coef[j]), 15) * lib.exprs[j] for j in np.flatnonzero(coef)])


def _fmt(expr, digits: int = 4) -> str:
    """Readable form with coefficients rounded to ``digits`` significant digits."""
    return str(sp.N(expr, digits))
