"""``LagrangianSINDy``: trajectories -> energy (H) -> Lagrangian (L) -> equations of motion."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from .._validate import check_choice, check_int, check_real
from .admissibility import Admissibility
from .balance import derivative_form, integral_form
from .diagnostics import FitRecord, constant_force_trap, diagnose
from .fitting import coef_on_support
from .dissipation import dissipation_columns, dissipation_library, fold_scale, full_rayleigh, \
    norm_term, project, prune
from ..symbolic.library import Library
from ..mechanics.euler_lagrange import simulate_ode
from .fitted import FittedModel
from .reweight import reselect
from .selection import select
from .status import assess, open_coefficient
from .standard_errors import coefficient_errors
from ..data.smoothing import force_switches, smooth
from .uncertainty import energy_variance, noise_model, row_gradients, sample_weights
from ..data.trajectory import as_trajectories
from ..mechanics.rk4 import held_input_simulator
from .uncertainty import corrected_fit, run_variance

__all__ = ["LagrangianSINDy"]

_FORMS = ("auto", "derivative", "integral")
_SMOOTHING = ("auto", "none")
_HOLDS = ("auto", "zoh", "smooth")
_REFINEMENTS = ("auto", "always", "never")
# Errors in variables (``_refine``): the sample weights depend on the coefficients they weight, so
# weights and coefficients are updated in turn, a fixed number of passes (no tolerance in the units
# of the data).  The support may be re-selected on the weighted balance only in the first
# _RESELECT_PASSES passes, so the last pass always re-weights and corrects the coefficients on the
# support they will be reported on.
_REFINE_PASSES = 3
_RESELECT_PASSES = 2


class LagrangianSINDy(FittedModel):
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
    dissipation : sequence of str or Library, optional
        Candidate terms of a Rayleigh dissipation function R(q̇) over ``<q>_dot`` (viscous
        ``theta_dot**2``, ``theta1_dot*theta2_dot``; Coulomb ``Abs(x_dot)``): the balance becomes
        dE/dt = P − q̇·∂R/∂q̇ and the equations of motion gain the friction forces −∂R/∂q̇
        (:mod:`lsindy_cas.identify.dissipation`).  Terms the data do not support come out zero.
    time_limit : float, optional
        Seconds allowed to each branch-and-bound search (libraries too large to score every
        support); when it runs out the best admissible support found is kept, marked not proven
        with its gap (``search_``).  The limit applies to every branch and bound: the scouts of
        automatic k, which also stop after a fixed amount of work (the same on every machine),
        the k chosen, and the re-selection on the noise-weighted balance
        (:mod:`lsindy_cas.identify.selection`, :mod:`lsindy_cas.identify.reweight`).
    effort : float
        Automatic k: a factor on the work the scan may spend (per scout and in all): default 1
        (a refusal within about a minute per k); more for a large library whose scouts stop
        undecided (the refusal says so).  The same stopping points on every machine.
    refinement : {"auto", "always", "never"}
        Prediction-error refinement of the coefficients on the chosen support
        (:meth:`refine`, :func:`lsindy_cas.identify.refine.refine_model`) after the verdict.
        "auto" (default): only when the one finding against the fit is that the energy balance
        leaves a coefficient open (its standard error too large, rule 7 of
        :mod:`lsindy_cas.identify.status`); the refined fit is kept when its verdict on its own
        standard errors is "ok", else the balance's fit stays as it was.  Runs that cannot be
        refined (not evenly sampled, …) are left to the balance.  Either way ``refinement_``
        records what was tried (``"auto": True``).  "always": refine every fit, as ``refine``
        does (runs must be evenly sampled).  "never": the energy balance alone.

    Attributes (after ``fit``)
    --------------------------
    coords_ : list of str
    coef_ : array (p,)            energy coefficients ξ (H = Θ ξ)
    lagrangian_coef_ : array (p,) Lagrangian coefficients ξ_L (eq. 7)
    coef_std_, lagrangian_coef_std_ : standard errors of ξ, ξ_L (jackknife, see std_method_)
    support_ : tuple of int
    n_terms_ : int                the k used (chosen or given)
    hamiltonian_, lagrangian_ : sympy.Expr (built on first access; ``texts()``: the strings)
    actuated_ : list of str       coordinates that carried an applied force in the data
    search_ : SearchResult        ranking and diagnostics of the support search
    selection_ : Selection        every k tried and its held-out error
    passive_ : bool               whether the passive (null-space + scale) scheme was used
    smoothing_ : list of Smoothed or None
    diagnostics_ : Diagnostics    near ties, null space, traps, warnings, status (print it)
    status_ : str                 "ok" or "undetermined" (:mod:`lsindy_cas.identify.status`)
    status_reasons_ : list of str why it is undetermined, in plain words
    ok_ : bool                    ``status_ == "ok"``: one check that the data determine the model
    hold_ : str or None           the input hold used by the work integral ("zoh"/"smooth"; None
                                  when no work integral was needed)
    velocities_ : str             "measured", "estimated" (positions only: q̇ from the smoothed
                                  positions, its error carried into the noise model) or "mixed"
    rayleigh_coef_ : array (r,)   dissipation coefficients ρ (R = Σ ρ_j R_j; zeros when absent)
    rayleigh_ : sympy.Expr        the identified R(q̇) (0 without friction)
    energy_scale_ : str           "absolute", or "relative" (passive data without a scale record:
                                  H, L and R up to one common factor, fixed by ``normalised_by_``)
    normalised_by_ : str or None  relative energy: the term whose coefficient is set to 1 (the
                                  first kinetic prior term, else the first kinetic support term)
    refinement_ : dict            present when a prediction-error refinement was applied or tried:
                                  what was done (``"applied"``; ``"auto"`` when automatic, with
                                  ``"balance_open"``, and ``"outcome"`` when not applied)
    """

    def __init__(self, library: Library, *, n_terms: int | None = None, prior=(), form: str = "auto",
                 window: int | None = None, smoothing: str = "auto", max_terms: int | None = None,
                 hold: str = "auto", dissipation=None, time_limit: float | None = None,
                 effort: float = 1.0, refinement: str = "auto"):
        self.library, self.n_terms, self.prior, self.form = library, n_terms, prior, form
        self.window, self.smoothing, self.max_terms = window, smoothing, max_terms
        self.hold, self.dissipation, self.time_limit = hold, dissipation, time_limit
        self.effort, self.refinement = effort, refinement

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
        self._diss_lib = dissipation_library(self.library.coords, self.dissipation)
        if self._diss_lib is not None and self.window is not None:
            raise ValueError("dissipation needs the all-windows integral form: leave window unset")
        check_real("time_limit", self.time_limit, positive=True, allow_none=True)
        check_real("effort", self.effort, positive=True)
        check_choice("refinement", self.refinement, _REFINEMENTS)
        return sorted(set(forced))

    def _form(self, trajectories) -> str:
        if self.form == "auto":
            return "derivative" if all(tr.qdd is not None for tr in trajectories) else "integral"
        return self.form

    def _balance(self, trajectories, passive=None, weights=None, dissipation=True, noise=None):
        """The energy balance of ``trajectories`` (with the dissipation columns projected out);
        ``noise``: per run, the noise left in each state column (picks the held-force work
        rule, see ``work.cumulative_work``)."""
        if self._form(trajectories) == "derivative":
            if not all(tr.qdd is not None for tr in trajectories):
                raise ValueError("form='derivative' needs accelerations <q>_ddot in every "
                                 "trajectory; use form='integral' (or 'auto')")
            bal = derivative_form(self.library, trajectories, passive=passive)
        else:
            bal = integral_form(self.library, trajectories, window=self.window, passive=passive,
                                weights=weights, hold=self.hold_ or "auto", noise=noise)
        lib = self._active_dissipation() if dissipation else None
        if lib is None:
            return bal
        return project(bal, *dissipation_columns(lib, trajectories, bal, noise, True), lib.names)

    def _active_dissipation(self):
        """The dissipation terms still in the model (a Library), or None."""
        lib = getattr(self, "_diss_lib", None)
        active = getattr(self, "_diss_active", None)
        if lib is None or not active:
            return None
        return lib if len(active) == len(lib) else type(lib)(lib.coords,
                                                            [lib.exprs[j] for j in active])

    def _prepare(self, trajectories):
        """States for the balance and their noise variance per row (integral form), or as given."""
        if self._form(trajectories) == "derivative":
            return trajectories, None, None
        smoothed = [smooth(tr) for tr in trajectories]     # also estimates the noise for "none"
        states = [s.trajectory for s in smoothed] if self.smoothing == "auto" else trajectories
        # One variance per column and run: the per-sample ones (larger at the ends) were measured
        # to worsen the coefficients on the paper's 1 s runs (median error 6 % → 8 % at σ = 1e-3).
        var = np.vstack([np.broadcast_to(v, s.error.shape)
                         for v, s in zip(run_variance(smoothed, self.smoothing), smoothed)])
        return states, var, smoothed

    def _run_noise(self, smoothed):
        var = run_variance(smoothed, self.smoothing)
        return None if var is None else [np.sqrt(v) for v in var]

    def fit(self, trajectories, scale_trajectories=None, passive=None,
            progress=None, client=None, notify=None) -> "LagrangianSINDy":
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
        client : dask.distributed.Client, optional
            Search the supports on this Dask cluster (:mod:`~lsindy_cas.identify.distributed`,
            :mod:`~lsindy_cas.identify.distributed_bnb`); the same answer as in process.
        notify : callable ``(message)``, optional
            Told in one line before a step that ``progress`` does not cover starts: the
            prediction-error refinement (``refinement``), e.g. to print it.
        """
        backend = None
        if client is not None:
            from .backend import DaskBackend
            backend = DaskBackend(client)
        self._validate()
        for name in ("refinement_", "refine_result_"):     # a refit's own refinement, if any
            self.__dict__.pop(name, None)
        self._diss_active = None if self._diss_lib is None else list(range(len(self._diss_lib)))
        coords = self.library.coords.names
        runs = as_trajectories(trajectories, coords)
        if self.refinement == "always":                     # bad input before the search
            from .refine import check_uniform
            check_uniform(runs)
        holds = self._holds(runs)
        if len(holds) == 1:
            self._fit(runs, scale_trajectories, passive, progress, holds[0], backend=backend)
            return self._assess()._refinement(runs, notify)
        # A force that changes at most samples: a smooth force sampled, or a held one changing every
        # sample.  The data decide: the wrong work integral leaves a systematic residual.  The
        # smoothing does not depend on the hold, so both trials share it.
        prepared = self._prepare(runs)
        trials, failed = [], {}
        for hold in holds:
            trial = copy.copy(self)
            try:
                trial._fit(runs, scale_trajectories, passive, progress, hold, prepared, backend)
            except ValueError as exc:   # e.g. no admissible model under the wrong work integral
                failed[hold] = exc
                continue
            trials.append(trial)
        if not trials:
            raise failed[holds[0]]
        best = min(trials, key=lambda m: m.diagnostics_.held_out_error)
        self.__dict__.update(best.__dict__)
        self.hold_errors_ = {m.hold_: m.diagnostics_.held_out_error for m in trials}
        self.hold_errors_.update({h: float("inf") for h in failed})
        self.diagnostics_.hold_errors = self.hold_errors_
        return self._assess()._refinement(runs, notify)

    def _assess(self) -> "LagrangianSINDy":
        """The one verdict on the fit (:func:`.status.assess`): ``status_``, ``status_reasons_``,
        ``ok_``, also in ``diagnostics_``.  Never raises: an undetermined fit is data."""
        d = self.diagnostics_
        simulate = (held_input_simulator(self.ode(), len(self.coords_)) if not self.has_friction_ else
                    lambda x0, t, u: simulate_ode(self.ode(), x0, t, u, len(self.coords_),  # noqa
                                                  rtol=1e-9, atol=1e-10)[0])
        d.status, d.status_reasons, d.checks = assess(self._record, d, simulate, self.coef_std_)
        self.status_, self.status_reasons_ = d.status, list(d.status_reasons)
        del self._record
        return self

    def _refinement(self, runs, notify=None) -> "LagrangianSINDy":
        """The prediction-error refinement after the verdict, as ``refinement`` says."""
        if self.refinement == "never":
            return self
        if self.refinement == "always":
            if notify is not None:
                notify("refining the coefficients by prediction error ...")
            return self.refine(runs)
        open_ = _open_coefficient(self)
        if open_ is None:
            return self
        term, rel = open_
        auto = {"applied": False, "auto": True,
                "balance_open": {"term": term, "relative_std": rel}}
        if notify is not None:
            notify(f"the energy balance leaves the coefficient of {term} open (±{100 * rel:.2g} %): "
                   "refining the coefficients by prediction error ...")
        trial = copy.copy(self)        # refine_model changes the model and its report in place
        trial.diagnostics_ = copy.copy(self.diagnostics_)
        try:
            trial.refine(runs)
        except (ValueError, RuntimeError) as exc:   # the balance's fit stands, with the reason
            why = " ".join(str(exc).split())
            # ValueError: data it cannot refine (runs not evenly sampled, terms not homogeneous
            # in the velocities, free motion without a kinetic term); RuntimeError: the solver
            auto["outcome"] = (f"skipped: {why}" if isinstance(exc, ValueError)
                               else f"failed: {why}")
            self.refinement_ = self._current(auto)
            return self
        info = trial.refinement_
        if info["applied"] and trial.status_ == "ok":
            info.update(auto, applied=True)
            self.__dict__.clear()
            self.__dict__.update(trial.__dict__)
            return self
        if not info["applied"]:
            from .refine import not_applied_reason
            auto["outcome"] = f"not applied ({not_applied_reason(info)})"
        elif trial.coef_std_ is None:
            auto["outcome"] = "the refined fit has no standard errors (singular linearisation)"
        else:
            left = _open_coefficient(trial)
            auto["outcome"] = (f"the refined fit left the coefficient of {left[0]} open too "
                               f"(±{100 * left[1]:.2g} %)" if left is not None else
                               "the refined fit is undetermined: "
                               + "; ".join(map(str, trial.status_reasons_)))
            # what the refined fit was, apart from what describes the model (the balance's fit)
            auto["refined_terms"] = trial.terms()
            auto["refined_std"] = info.pop("hamiltonian_std", None)
            info.pop("balance_status", None)
        self.refinement_ = self._current({**info, **auto})
        self.refine_result_ = trial.refine_result_
        return self

    def _current(self, info: dict) -> dict:
        """``info`` marked as describing this model's present coefficients, those of the balance
        (:func:`.refine.current_refinement`)."""
        info.update(hamiltonian_terms=self.terms(), rayleigh_terms=self.terms("rayleigh"))
        if "rms_before" in info:
            info["rms_after"] = info["rms_before"]
        return info

    @property
    def ok_(self) -> bool:
        """True when the fit's status is "ok": the data determine this model."""
        self._check_fitted()
        return getattr(self, "status_", None) == "ok"

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

    def _fit(self, trajectories, scale_trajectories, passive, progress, hold, prepared=None,
             backend=None, previous=None):
        """One fit with a given input hold; ``prepared`` = ``_prepare(trajectories)`` if done;
        ``previous``: the selection of the fit before with more dissipation terms (step 7)."""
        self.hold_ = hold
        forced = self._validate()
        lib = self.library
        coords = lib.coords.names
        # 1. inputs: trajectories in the library's coordinate order
        trajectories = as_trajectories(trajectories, coords)
        scale_list = (None if scale_trajectories is None else
                      as_trajectories(scale_trajectories, coords, "scale_trajectories"))
        # 2. states: smoothed (integral form) with their noise variance
        states, state_var, smoothing = (self._prepare(trajectories) if prepared is None
                                         else prepared)
        # 3. energy balance (and the passive scheme's scale record)
        self._state_noise = self._run_noise(smoothing)
        bal = self._balance(states, passive=passive, noise=self._state_noise)
        scale_system = self._scale_system(scale_list, bal) if bal.passive else None
        # 4. the rules a candidate must pass
        trap = constant_force_trap(lib, trajectories, forced) if not bal.passive else None
        excluded = [] if trap is None else trap.excluded
        admissible = Admissibility.for_balance(lib, bal, forced, scale_system, excluded)
        # 5. support and k
        noise = (noise_model(bal, state_var, smoothing)
                 if state_var is not None and bal.per_sample else None)
        if previous is None:
            sel = select(bal, forced, n_terms=self.n_terms, admissible=admissible,
                         scale_system=scale_system, max_terms=self.max_terms, noise=noise,
                         progress=progress, time_limit=self.time_limit, backend=backend,
                         effort=self.effort)
        else:   # friction terms dropped: k stays, the support is searched again (reweight.py)
            sel, _ = reselect(bal, forced, previous, scale_system=scale_system,
                              admissible=admissible, time_limit=self.time_limit,
                              progress=progress, backend=backend)
            kept, sel = sel is previous, copy.copy(sel)
            sel.steps, sel.automatic, sel.unscored = (previous.steps, previous.automatic,
                                                      previous.unscored)
            refit = coef_on_support(bal.A, bal.b, sel.support, scale_system)[0] if kept else None
            if refit is not None:                   # the kept support, fitted on this balance
                sel.coef = refit
        coef = sel.coef
        # 6. errors in variables: re-weight, re-select (same k), correct for regressor noise
        if state_var is not None and bal.per_sample:
            coef, bal, sel, admissible = self._refine(states, passive, sel, forced, state_var,
                                                      scale_system, excluded, row_gradients(bal),
                                                      progress, backend)
        # 7. dissipation: drop the terms the data do not support and fit again without them
        if bal.dissipation is not None:
            keep = prune(bal, coef)
            if len(keep) < len(self._diss_active):
                self._diss_active = [self._diss_active[j] for j in keep]
                return self._fit(trajectories, scale_trajectories, passive, progress, hold,
                                 prepared, backend, previous=sel)
        # 8. relative energy (passive, no scale record): the stated normalisation
        self.energy_scale_, self.normalised_by_ = "absolute", None
        if bal.passive and scale_system is None:
            j = norm_term(lib, coef, forced)
            coef = coef / coef[j]
            self.energy_scale_, self.normalised_by_ = "relative", lib.names[j]
        rho = full_rayleigh(self._diss_lib, self._diss_active, bal, coef)
        # 9. the model and its report
        record = FitRecord(lib, bal, trajectories, scale_system, admissible, sel, coef, smoothing,
                           trap, hold, state_var if bal.per_sample else None)
        self.smoothing_, self.trap_, self.selection_, self.n_terms_ = smoothing, trap, sel, sel.k
        self.search_, self.passive_, self.form_ = sel.search, bal.passive, bal.form
        self.actuated_ = [c for c in coords if any(c in tr.actuated for tr in
                                                   trajectories + (scale_list or []))]
        kinds = {tr.velocities for tr in trajectories + (scale_list or [])}
        self.velocities_ = kinds.pop() if len(kinds) == 1 else "mixed"
        self._set_coefficients(coef, X=bal.X, rayleigh=rho)
        self._set_errors(coefficient_errors(bal, self.coef_, lib, bal.X, scale_system))
        self.diagnostics_ = diagnose(record)
        self.diagnostics_.velocities = self.velocities_
        self._record = record
        return self

    def _scale_system(self, scale_list, bal):
        """Passive scheme: the actuated record (A_s, b_s) that fixes the energy's scale (eq. 8);
        None without one (the energy is then relative).  With dissipation, the record's friction
        work is that of ρ(ξ) = −pinv(D) A ξ of the passive balance, folded into A_s."""
        if scale_list is None:
            return None
        states, _, smoothed = self._prepare(scale_list)
        noise = self._run_noise(smoothed)
        scale = self._balance(states, passive=False, dissipation=False, noise=noise)
        if not np.any(scale.b):
            raise ValueError("scale_trajectories carry no power (Q·q̇ ≡ 0); they cannot fix the scale")
        if bal.dissipation is None:
            return scale.A, scale.b
        lib = self._active_dissipation()
        return fold_scale(bal, scale, dissipation_columns(lib, states, scale, noise))

    def _refine(self, states, passive, sel, forced, state_var, scale_system, excluded, grads,
                progress=None, backend=None):
        """Errors in variables: weight samples by the noise of the fitted energy, re-select on the
        weighted balance (same k), and correct the coefficients for regressor noise."""
        coef, support, sel_w, changed = sel.coef, sel.support, sel, True
        sizes = np.cumsum([tr.n_samples for tr in states])[:-1]
        for it in range(_REFINE_PASSES):
            w = sample_weights(energy_variance(grads, coef, state_var))
            bal_w = self._balance(states, passive=passive, weights=np.split(w, sizes),
                                  noise=self._state_noise)
            if changed and it < _RESELECT_PASSES:      # re-select on the weighted balance (same k)
                adm = Admissibility.for_balance(self.library, bal_w, forced, scale_system, excluded)
                sel_w, changed = reselect(bal_w, forced, sel_w, scale_system=scale_system,
                                          admissible=adm, time_limit=self.time_limit,
                                          progress=progress, backend=backend)
                support = sel_w.support
            coef = corrected_fit(bal_w, grads, w, state_var, support, scale_system)
        sel_w.steps, sel_w.automatic = sel.steps, sel.automatic   # the held-out path of the k choice
        sel_w.unscored = sel.unscored
        return coef, bal_w, sel_w, adm

    def refine(self, trajectories, **options) -> "LagrangianSINDy":
        """Refine the coefficients in place by prediction error (:func:`.refine.refine_model`)."""
        from .refine import refine_model
        return refine_model(self, trajectories, **options)

    def __str__(self) -> str:
        from ..printing import model_text
        return model_text(self)

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


def _open_coefficient(model):
    """(term, relative standard error) when the one finding against ``model`` is that a
    coefficient is open (:func:`.status.open_coefficient`), else None."""
    worst = open_coefficient(getattr(model, "status_", None), getattr(model, "status_reasons_", ()))
    if worst is None:
        return None
    j = worst.numbers.get("term")
    term = model.library.names[j] if j is not None else "a term"
    return term, float(worst.numbers.get("relative_std", float("nan")))
