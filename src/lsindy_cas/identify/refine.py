"""Prediction-error refinement of a model's coefficients by multiple shooting.

The energy balance fixes the support and a first estimate of the coefficients from an *equation*
error.  The standard last step of system identification is to minimise the *simulation*
(prediction) error instead: find the coefficients p (and each run's initial state) for which the
model's motion stays closest to the measured motion over the whole run.  Over many cycles of an
oscillation a fraction of a per cent of frequency error adds up to a large phase error, which an
equation error hardly sees and a simulation error sees at once.

Transcription (direct multiple shooting): each run is cut into shooting intervals of ``interval``
seconds; each interval starts from its own free state s_k and is integrated by RK4 over the
sampling grid (``steps`` RK4 steps per sample, the run's forces held over each sample); the
predicted states are compared with every measured sample, and continuity s_{k+1} = end of interval
k closes the chain, so that at the solution each run is *one* free simulation from a fitted initial
state.  The intervals keep the problem well conditioned and start from the data, which avoids the
local minima of shooting once through many cycles.  IPOPT solves the NLP.

Normalisation: free motion (no forces fed in) fixes L and R only up to a common factor, so one
coefficient (``fixed``) is kept at its starting value.  Admissibility is kept by bounds: a pure
kinetic term q̇_i² keeps a positive coefficient, viscous q̇_i² and Coulomb |q̇_i| friction terms
non-negative ones; after the fit the mass matrix is checked positive definite and the dissipated
power non-negative on every sample, and a fit that breaks either is refused.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
import sympy as sp

from .._validate import check_int, check_real, relative_energy
from ..mechanics.parametric import DEFAULT_EPS, ParametricDynamics
from .prediction import predict, prediction_std, rk4_predictor  # noqa: F401 (importable here)

__all__ = ["RefineResult", "refine", "refine_model", "check_uniform", "current_refinement",
           "refinement_text", "not_applied_reason", "rk4_predictor", "predict", "prediction_std"]


@dataclass
class RefineResult:
    """What ``refine`` found.

    Attributes
    ----------
    names : list of str
        Lagrangian terms, then dissipation terms (the order of ``coef``).
    coef, initial : arrays (n_params,)
        Refined and starting coefficients.
    fixed : list of str
        Terms kept at their starting value (the normalisation).
    x0 : list of arrays (2n,)
        The fitted initial state of each training run.
    rms_initial, rms : float
        RMS position error (coordinate units) of the free simulation of every training run, with
        the starting and with the refined coefficients: from the first measured sample, or
        (``free_start``) from the initial states fitted for each set of coefficients.
    status : str
        IPOPT's return status, or "refused: ..." when the optimum is not a mechanical system on
        the data (mass matrix not positive definite, or friction that creates energy);
        ``success`` whether it converged to an admissible optimum (otherwise nothing is applied).
    std : array (n_params,) or None
        Standard errors of ``coef`` (:func:`prediction_std`; 0 for the fixed terms), None when
        the linearisation is singular.
    """

    names: list
    n_lagrangian: int
    coef: np.ndarray
    initial: np.ndarray
    fixed: list
    x0: list
    rms_initial: float
    rms: float
    status: str
    success: bool
    iterations: int
    seconds: float
    n_intervals: int
    std: np.ndarray | None = None
    report: dict = field(default_factory=dict)

    def lagrangian_terms(self) -> dict:
        """``{term: coefficient}`` of L."""
        return dict(zip(self.names[:self.n_lagrangian], self.coef[:self.n_lagrangian].tolist()))

    def rayleigh_terms(self) -> dict:
        """``{term: coefficient}`` of R."""
        return dict(zip(self.names[self.n_lagrangian:], self.coef[self.n_lagrangian:].tolist()))


def _bounds(dyn: ParametricDynamics, lower, upper):
    lb = np.full(dyn.n_params, -np.inf) if lower is None else np.asarray(lower, float).copy()
    ub = np.full(dyn.n_params, np.inf) if upper is None else np.asarray(upper, float).copy()
    if lb.shape != (dyn.n_params,) or ub.shape != (dyn.n_params,):
        raise ValueError(f"lower and upper must have {dyn.n_params} entries, one per coefficient")
    squares = {v**2 for v in dyn.coords.qd_sym}
    for j, term in enumerate(dyn.lagrangian_terms):
        if term in squares:                      # pure kinetic term: positive mass
            lb[j] = max(lb[j], 0.0)
    for j, term in enumerate(dyn.dissipation_terms, start=dyn.n_lagrangian):
        if term in squares or (isinstance(term, sp.Abs) and term.args[0] in dyn.coords.qd_sym):
            lb[j] = max(lb[j], 0.0)              # viscous or Coulomb friction dissipates
    return lb, ub


def _check_admissible(dyn: ParametricDynamics, p, trajectories) -> str | None:
    """Why the refined coefficients are not a mechanical system on the data, or None."""
    X = np.vstack([tr.X for tr in trajectories])
    M = np.asarray(dyn.mass_matrix().map(len(X))(X.T, p)).T.reshape(len(X), dyn.coords.n, -1)
    low = np.linalg.eigvalsh(0.5 * (M + np.transpose(M, (0, 2, 1))))[:, 0].min()
    if not low > 0:
        return (f"refused: the refined mass matrix is not positive definite on the data "
                f"(smallest eigenvalue {low:.3g})")
    f = np.asarray(dyn.friction().map(len(X))(X.T, p)).T
    n = dyn.coords.n
    power = -np.sum(f * X[:, n:], axis=1)
    if power.min() < -1e-9 * max(1.0, np.abs(power).max()):
        return (f"refused: the refined friction creates energy on the data (dissipated power "
                f"down to {power.min():.3g})")
    return None


def _starts(w, dyn, trajectories, interval) -> list:
    """Each run's initial state (2n,) in the NLP vector ``w``."""
    n, out, offset = dyn.coords.n, [], dyn.n_params
    for tr in trajectories:
        K = max(1, int(round(interval / (tr.t[1] - tr.t[0]))))
        out.append(w[offset:offset + 2 * n])
        offset += 2 * n * (len(range(0, tr.n_samples - 1, K)) + 1)
    return out


def refine(coords, lagrangian_terms, p0, trajectories, dissipation_terms=(), fixed=(),
           interval: float = 0.25, steps: int = 2, rate_weight: float = 0.1, lower=None,
           upper=None, eps: float = DEFAULT_EPS, free_start: bool = True, max_iter: int = 200,
           verbose: bool = False):
    """Refine L's and R's coefficients by minimising the simulation error over training runs.

    Parameters
    ----------
    coords : Coordinates or list of str
    lagrangian_terms, dissipation_terms : list of str
        The support: terms of L and of the Rayleigh function R (see ``ParametricDynamics``).
    p0 : array (n_params,)
        Starting coefficients, L's then R's (e.g. from the energy-balance fit).
    trajectories : Trajectory or list of Trajectory
        Training runs, each uniformly sampled; their forces ``Q`` are held over each sample.
    fixed : str or list of str
        Lagrangian terms whose coefficient stays at its value in ``p0`` (the normalisation).  Required when no
        run has a force: free motion fixes the coefficients only up to a factor.
    interval : float
        Shooting interval in seconds (rounded to whole samples).
    steps : int
        RK4 steps per sample.
    rate_weight : float
        Weight of velocity errors relative to position errors (time units: 0.1 s counts an error
        of 1 rad/s like one of 0.1 rad).
    lower, upper : array (n_params,), optional
        Extra bounds; the admissibility bounds (module text) are always added.
    eps : float
        Smoothing speed of Coulomb terms (``ParametricDynamics``).
    free_start : bool
        Fit each run's initial state (default); False keeps it at the first measured sample, so
        the fit minimises the error of predicting each run from its first sample.
    max_iter : int
        IPOPT iteration limit.

    Returns
    -------
    RefineResult

    Raises
    ------
    RuntimeError
        If the refined model is not admissible (mass matrix, dissipated power).
    """
    from ..data.trajectory import Trajectory
    dyn = ParametricDynamics(coords, lagrangian_terms, dissipation_terms, eps=eps)
    n = dyn.coords.n
    if isinstance(trajectories, Trajectory):
        trajectories = [trajectories]
    trajectories = list(trajectories)
    if not trajectories or not all(isinstance(tr, Trajectory) for tr in trajectories):
        raise TypeError("trajectories must be a Trajectory or a non-empty list of them")
    trajectories = [tr.reorder(dyn.coords.names) for tr in trajectories]
    p0 = np.asarray(p0, float).ravel()
    if p0.shape != (dyn.n_params,) or not np.all(np.isfinite(p0)):
        raise ValueError(f"p0 must hold {dyn.n_params} finite coefficients ({', '.join(dyn.names)}), "
                         f"got shape {p0.shape}")
    fixed = [fixed] if isinstance(fixed, str) else list(fixed)
    fixed_idx = []
    for name in fixed:
        term = dyn.coords.parse(name, what="fixed term")
        hits = [j for j, t in enumerate(dyn.lagrangian_terms) if sp.expand(t - term) == 0]
        if not hits:
            raise ValueError(f"fixed term {name!r} is not one of the Lagrangian terms "
                             f"{', '.join(dyn.names[:dyn.n_lagrangian])}")
        fixed_idx.append(hits[0])
    if not fixed_idx and all(not np.any(tr.Q) for tr in trajectories):
        raise ValueError("fixed must name a term: free motion (no forces) fixes the coefficients "
                         "only up to a common factor")
    interval = check_real("interval", interval, positive=True)
    rate_weight = check_real("rate_weight", rate_weight, nonnegative=True)
    steps = check_int("steps", steps, low=1)
    max_iter = check_int("max_iter", max_iter, low=1)
    lb, ub = _bounds(dyn, lower, upper)
    lb[fixed_idx] = ub[fixed_idx] = p0[fixed_idx]
    if np.any(p0 < lb) or np.any(p0 > ub):
        raise ValueError("p0 breaks the bounds (a mass or a friction coefficient is negative)")

    step = rk4_predictor(dyn.ode(), n, steps)
    p = ca.MX.sym("p", dyn.n_params)
    w, w0, wlb, wub, g, cost = [p], [p0], [lb], [ub], [], 0
    weight = np.r_[np.ones(n), np.full(n, rate_weight)][:, None]
    n_samples = n_intervals = 0
    rolls = {}                                   # one RK4 chain per interval length
    for r, tr in enumerate(trajectories):
        dt = np.diff(tr.t)
        if not np.allclose(dt, dt[0], rtol=1e-6, atol=0):
            raise ValueError(f"trajectory {r} ({tr.source}) is not uniformly sampled")
        K = max(1, int(round(interval / dt[0])))
        N = tr.n_samples
        nodes = list(range(0, N - 1, K)) + [N - 1]
        S = ca.MX.sym(f"s{r}", 2 * n, len(nodes))
        w.append(ca.vec(S))
        w0.append(tr.X[nodes].T.ravel(order="F"))
        slb, sub = np.full(S.shape, -np.inf), np.full(S.shape, np.inf)
        if not free_start:
            slb[:, 0] = sub[:, 0] = tr.X[0]
        wlb.append(slb.ravel(order="F"))
        wub.append(sub.ravel(order="F"))
        X, U = tr.X, tr.Q
        cost += ca.sumsqr(weight * (S[:, 0] - X[0][:, None]))
        for k in range(len(nodes) - 1):
            a, b = nodes[k], nodes[k + 1]
            if b - a not in rolls:
                rolls[b - a] = step.mapaccum("roll", b - a)
            roll = rolls[b - a]
            pred = roll(S[:, k], U[a:b].T, p, dt[a:b][None, :])
            cost += ca.sumsqr(weight * (pred - X[a + 1:b + 1].T))
            g.append(pred[:, -1] - S[:, k + 1])
        n_samples += N
        n_intervals += len(nodes) - 1
    nlp = {"x": ca.vertcat(*w), "f": cost / n_samples, "g": ca.vertcat(*g)}
    opts = {"ipopt.print_level": 5 if verbose else 0, "print_time": verbose,
            "ipopt.sb": "no" if verbose else "yes",           # no IPOPT banner on stdout
            "ipopt.max_iter": max_iter, "ipopt.tol": 1e-12, "ipopt.acceptable_tol": 1e-10}
    solver = ca.nlpsol("refine", "ipopt", nlp, opts)
    start = time.perf_counter()
    w0, wlb, wub = np.concatenate(w0), np.concatenate(wlb), np.concatenate(wub)
    starts0 = None
    if free_start:
        # the starting coefficients with their own best initial states: the fair "before" of the
        # reported error, and a consistent warm start (states on one simulation per run)
        pre = solver(x0=w0, lbx=np.r_[p0, wlb[dyn.n_params:]], ubx=np.r_[p0, wub[dyn.n_params:]],
                     lbg=0, ubg=0)
        w0 = np.asarray(pre["x"]).ravel()
        starts0 = _starts(w0, dyn, trajectories, interval)
    sol = solver(x0=w0, lbx=wlb, ubx=wub, lbg=0, ubg=0)
    seconds = time.perf_counter() - start
    stats = solver.stats()
    wopt = np.asarray(sol["x"]).ravel()
    coef = np.clip(wopt[:dyn.n_params], lb, ub)    # IPOPT may step outside a bound by its tolerance
    x0s = _starts(wopt, dyn, trajectories, interval)
    refused = _check_admissible(dyn, coef, trajectories)   # then not applied, with the reason

    def rms(c, starts):
        err = [predict(dyn, c, x0, tr.t, tr.Q, steps)[:, :n] - tr.q
               for x0, tr in zip(starts, trajectories)]
        return float(np.sqrt(np.mean(np.concatenate(err) ** 2)))
    first = [tr.X[0] for tr in trajectories]
    free = [j for j in range(dyn.n_params) if j not in fixed_idx]
    std = prediction_std(dyn, coef, x0s if free_start else first, trajectories, steps,
                         rate_weight, free, fit_start=free_start)
    return RefineResult(
        names=dyn.names, n_lagrangian=dyn.n_lagrangian, coef=coef, initial=p0,
        fixed=[dyn.names[j] for j in fixed_idx], x0=x0s,
        rms_initial=rms(p0, starts0 or first), rms=rms(coef, x0s if free_start else first),
        status=refused or stats["return_status"], success=bool(stats["success"]) and not refused,
        iterations=int(stats["iter_count"]), seconds=seconds, n_intervals=n_intervals, std=std,
        report={"cost": float(sol["f"]), "interval": interval, "steps": steps,
                "rate_weight": rate_weight, "eps": eps, "n_samples": n_samples})


def check_uniform(trajectories, what: str = "trajectories") -> None:
    """Refinement integrates over the sampling grid: refuse a run whose time steps differ."""
    for r, tr in enumerate(trajectories):
        dt = np.diff(tr.t)
        if dt.size and not np.allclose(dt, dt[0], rtol=1e-6, atol=0):
            raise ValueError(f"{what}: run {r} ({tr.source}) is not uniformly sampled; prediction-"
                             "error refinement needs evenly spaced samples")


def refine_model(model, trajectories, interval: float = 0.25, steps: int = 2,
                 rate_weight: float = 0.1, free_start: bool = True, max_iter: int = 200):
    """Refine a fitted ``LagrangianSINDy``'s coefficients in place by prediction error.

    The support (energy terms and dissipation terms) is the one the energy balance chose; the
    coefficients of L and R are refined by :func:`refine` over ``trajectories``, started from the
    energy-balance estimate.  The normalisation is kept: a relative energy keeps its
    ``normalised_by_`` coefficient; free motion with an absolute energy (scale record) keeps the
    first kinetic term's.  H follows from L term by term (θ ↦ (d − 1) θ, d = degree in the
    velocities).  The model then shows the refined H, L, R and ODE; its energy-balance standard
    errors no longer apply and are replaced by the refined fit's own (:func:`prediction_std`,
    Gauss–Newton), and the verdict's coefficient rule is judged again on them
    (:func:`.status.refined_status`; the balance's verdict stays in
    ``refinement_["balance_status"]``); ``refinement_`` records what was done and
    ``refine_result_`` holds the :class:`RefineResult`.  If IPOPT does not converge or the refined
    coefficients predict worse, the model is left unchanged and ``refinement_["applied"]`` is False.

    Parameters
    ----------
    model : LagrangianSINDy
        A fitted model (energy terms homogeneous in the velocities).
    trajectories : Trajectory or list of Trajectory
        The training runs, evenly sampled; forces are held over each sample.
    interval, steps, rate_weight, max_iter
        As in :func:`refine`.
    free_start : bool
        True (default): each run's initial state is fitted with the coefficients (a noisy first
        sample would otherwise bias them), and the error reported before and after is that of
        each set of coefficients from its own fitted initial states.  False: each run is
        predicted from its first measured sample.

    Returns
    -------
    model
    """
    from ..data.trajectory import as_trajectories
    model._check_fitted()
    lib = model.library
    runs = as_trajectories(trajectories, lib.coords.names)
    check_uniform(runs)
    S = [int(j) for j in np.flatnonzero(model.coef_)]
    degrees = [lib.velocity_degree(j) for j in S]
    bad = [lib.names[j] for j, d in zip(S, degrees) if d is None or d == 1]
    if bad:
        raise ValueError(f"refinement needs energy terms homogeneous of degree 0 or 2 in the "
                         f"velocities; {', '.join(bad)} is not")
    to_l = np.array([1.0 / (d - 1) for d in degrees])        # ξ_L = ξ_H / (d − 1) (Legendre)
    dlib = getattr(model, "_diss_lib", None)
    rho = np.asarray(getattr(model, "rayleigh_coef_", np.zeros(0)), float).copy()
    D = [int(j) for j in np.flatnonzero(rho)]
    fixed = ()
    if relative_energy(model):
        fixed = (lib.exprs[lib.index(model.normalised_by_)],)
    elif all(not np.any(tr.Q) for tr in runs):
        kinetic = [j for j, d in zip(S, degrees) if d == 2]
        if not kinetic:
            raise ValueError("free motion: the energy has no kinetic term to keep its scale by")
        fixed = (lib.exprs[kinetic[0]],)
    p0 = np.r_[model.coef_[S] * to_l, rho[D]]
    res = refine(lib.coords, [lib.exprs[j] for j in S], p0, runs,
                 [dlib.exprs[j] for j in D] if D else (), fixed=fixed, interval=interval,
                 steps=steps, rate_weight=rate_weight, free_start=free_start, max_iter=max_iter)
    applied = res.success and res.rms <= res.rms_initial
    model.refine_result_ = res
    model.refinement_ = {
        "applied": bool(applied), "method": "prediction error, multiple shooting (IPOPT)",
        "status": res.status, "iterations": res.iterations, "seconds": round(res.seconds, 3),
        "runs": len(runs), "fixed": res.fixed, "free_start": bool(free_start),
        "rms_before": res.rms_initial, "rms_after": res.rms if applied else res.rms_initial,
        "rms_refined": res.rms, "interval": res.report["interval"], "rk4_steps": steps,
        "rate_weight": rate_weight,
        "energy_balance_lagrangian": dict(zip(res.names[:len(S)], p0[:len(S)].tolist())),
        "energy_balance_rayleigh": dict(zip(res.names[len(S):], p0[len(S):].tolist())),
    }
    if applied:
        coef = np.zeros(len(lib))
        coef[S] = res.coef[:len(S)] / to_l
        rho[D] = res.coef[len(S):]
        model._set_coefficients(coef, rayleigh=rho if dlib is not None else None)
        _refined_errors(model, res, S, to_l)
    model.refinement_.update(hamiltonian_terms=model.terms(), rayleigh_terms=model.terms("rayleigh"))
    return model


def _refined_errors(model, res, S, to_l) -> None:
    """The refined coefficients' own standard errors (:func:`prediction_std`) in place of the
    balance's, and the verdict on them (:func:`.status.refined_status`)."""
    from .status import refined_status
    model.coef_std_ = model.lagrangian_coef_std_ = model.std_method_ = None
    std = None
    if res.std is not None:
        std_l = np.zeros(len(model.coef_))
        std_l[S] = res.std[:len(S)]
        std = std_l.copy()
        std[S] *= np.abs(1.0 / to_l)                 # ξ_H = (d − 1) ξ_L, term by term
        model.coef_std_, model.lagrangian_coef_std_ = std, std_l
        model.std_method_ = "Gauss-Newton, prediction error over the runs"
        model.refinement_["hamiltonian_std"] = {model.library.names[j]: float(std[j]) for j in S}
    if getattr(model, "status_", None) is None:
        return
    status, reasons = refined_status(model.status_reasons_, model.coef_, std, model.library.names,
                                     "standard error of the prediction-error fit")
    model.refinement_["balance_status"] = model.status_
    model.status_, model.status_reasons_ = status, reasons
    d = getattr(model, "diagnostics_", None)
    if d is not None and getattr(d, "status", None) is not None:
        d.status, d.status_reasons = status, list(reasons)


def current_refinement(model):
    """``model.refinement_`` if it describes the model's present coefficients, else None (a model
    fitted again after ``refine`` no longer carries the refined coefficients)."""
    info = getattr(model, "refinement_", None)
    if not isinstance(info, dict) or not hasattr(model, "coef_"):
        return None
    same = (info.get("hamiltonian_terms") == model.terms()
            and info.get("rayleigh_terms", {}) == model.terms("rayleigh"))
    return info if same else None


def not_applied_reason(info: dict) -> str:
    """Why a refinement (``model.refinement_``) was not applied, in a few words."""
    if info["status"].startswith("refused"):
        return info["status"]
    if info["status"] != "Solve_Succeeded":
        return f"IPOPT: {info['status']}"
    return f"prediction error {info['rms_before']:.3g} -> {info['rms_refined']:.3g} did not drop"


def refinement_text(info: dict) -> str:
    """One line on a model's refinement (``model.refinement_``) for the printout."""
    why = ""
    if info.get("auto"):
        open_ = info.get("balance_open") or {}
        why = (f"automatic: the energy balance left {open_.get('term', 'a coefficient')} open to "
               f"±{100 * open_.get('relative_std', float('nan')):.2g} %")
        if not info["applied"]:
            return (f"prediction-error refinement ({why}): {info.get('outcome', 'not applied')}; "
                    "coefficients from the energy balance")
    if not info["applied"]:
        return (f"refinement not applied ({not_applied_reason(info)}): coefficients from the "
                "energy balance")
    before, after = info["rms_before"], info["rms_refined"]
    drop = 100 * (1 - after / before) if before > 0 else 0.0
    return (f"coefficients refined by prediction error over {info['runs']} run(s) "
            f"({why + '; ' if why else ''}{info['iterations']} IPOPT iterations, "
            f"{info['seconds']:.1f} s): RMS position error {before:.3g} -> {after:.3g} "
            f"({drop:.1f} % lower)")
