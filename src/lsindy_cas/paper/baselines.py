"""The methods the paper compares with (Figs. 3 and 4): SINDy with Lasso, and KRONIC.

- **SINDy + Lasso** (Brunton et al. 2016) regresses the accelerations q̈ directly on a library of
  candidate functions, one sparse equation per coordinate.  It runs through **pysindy** (the real
  peer, an optional dependency: ``pip install 'lsindy_cas[bench]'``), with the same measurement
  functions and product degree as our energy library, so the two methods see comparable candidates.
- **KRONIC** (Kaiser et al. 2018) looks for a conserved quantity: on passive data, the coefficient
  vector ξ is the right singular vector of Γ = ∇Θ·ẋ (paper eq. 3) for its smallest singular value.

Both are fitted to the same trajectories as ``LagrangianSINDy``; :func:`rollout` integrates any of
the resulting ODEs and reports where a model diverges.
"""
from __future__ import annotations

import re
import warnings
from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.integrate import solve_ivp

from ..data.trajectory import Trajectory
from ..symbolic.library import Library

__all__ = ["require_pysindy", "SINDyLasso", "Kronic", "Rollout", "rollout"]

_PYSINDY_MISSING = ("the SINDy baseline needs pysindy, an optional dependency; install it with "
                    "pip install 'lsindy_cas[bench]' (or pip install pysindy)")


def require_pysindy():
    """Import pysindy, or raise ``ImportError`` saying how to install it."""
    try:
        import pysindy
    except ImportError:
        raise ImportError(_PYSINDY_MISSING) from None
    return pysindy


def _as_list(trajectories) -> list:
    if isinstance(trajectories, Trajectory):
        return [trajectories]
    out = list(trajectories)
    if not out or not all(isinstance(tr, Trajectory) for tr in out):
        raise TypeError("trajectories must be a Trajectory or a non-empty list of them")
    return out


def _needs_accelerations(trajectories, what: str):
    if any(tr.qdd is None for tr in trajectories):
        raise ValueError(f"{what} needs accelerations (<q>_ddot columns) in every trajectory")


class SINDyLasso:
    """SINDy fitted to the accelerations with the Lasso optimizer, through pysindy.

    The candidate library is every product of ``features`` up to ``degree`` (pysindy's
    ``PolynomialLibrary`` on the feature values, no constant: the same set as
    ``Library.polynomial``), plus each applied generalized force ``Q_<q>`` as a linear term when the
    data are driven (SINDy with control).  Columns are normalised (pysindy ``normalize_columns``)
    and the Lasso weight α is chosen on a grid by the error on a held-out final part of every
    trajectory, then the model is refitted on all data with that α (pysindy's default unbiasing
    step refits the selected terms by least squares).

    Parameters
    ----------
    features : Library or list of str
        Measurement functions, e.g. ``["cos(theta)", "sin(theta)", "theta_dot"]`` (a ``Library``
        of them, whose coordinates are the system's).
    coords : list of str, optional
        Coordinate names; needed when ``features`` is a list of strings.
    degree : int
        Highest product degree.
    alphas : array, optional
        Lasso weights to try; by default 25 values from 1e-6 to 0.3 times the smallest α that
        zeroes every coefficient.
    validation : float
        Fraction of each trajectory (its end) held out to choose α.

    Attributes (after ``fit``)
    --------------------------
    model_ : pysindy.SINDy
    alpha_ : float
    coef_ : array (n_coords, n_candidates)
    candidate_names_ : list of str
    controls_ : list of str         the ``Q_<q>`` inputs in the library
    n_nonzero_ : int                non-zero coefficients over all acceleration equations
    """

    def __init__(self, features, *, coords=None, degree: int = 3, alphas=None,
                 validation: float = 0.2, max_iter: int = 50_000):
        self.features = features
        self.coords = coords
        self.degree = degree
        self.alphas = alphas
        self.validation = validation
        self.max_iter = max_iter

    # ------------------------------------------------------------------ fitting
    def _features(self) -> Library:
        if isinstance(self.features, Library):
            return self.features
        if self.coords is None:
            raise ValueError("coords is required when features is a list of expressions")
        return Library(self.coords, self.features)

    def _pysindy_model(self, ps, alpha: float, n_features: int, n_controls: int):
        from sklearn.linear_model import Lasso
        lasso = Lasso(alpha=alpha, fit_intercept=False, max_iter=self.max_iter)
        poly = ps.PolynomialLibrary(degree=int(self.degree), include_bias=False)
        if n_controls:
            lib = ps.GeneralizedLibrary(
                [poly, ps.PolynomialLibrary(degree=1, include_bias=False)],
                inputs_per_library=[list(range(n_features)),
                                    list(range(n_features, n_features + n_controls))])
        else:
            lib = poly
        return ps.SINDy(optimizer=ps.WrappedOptimizer(lasso, normalize_columns=True),
                        feature_library=lib)

    def _fit_one(self, ps, alpha, Z, Y, U, t):
        model = self._pysindy_model(ps, alpha, Z[0].shape[1], 0 if U is None else U[0].shape[1])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")          # Lasso convergence chatter at tiny α
            model.fit(Z, t=t, x_dot=Y, u=U, feature_names=self._input_names)
        return model

    def fit(self, trajectories) -> "SINDyLasso":
        """Fit q̈ = Ξ θ(q, q̇, Q) to the trajectories (which must carry accelerations).

        Parameters
        ----------
        trajectories : Trajectory or list of Trajectory
        """
        ps = require_pysindy()
        feats = self._features()
        if isinstance(self.degree, bool) or not isinstance(self.degree, (int, np.integer)) \
                or self.degree < 1:
            raise ValueError(f"degree must be a positive integer, got {self.degree!r}")
        if not 0 < self.validation < 1:
            raise ValueError(f"validation must be a fraction in (0, 1), got {self.validation}")
        coords = feats.coords.names
        trajs = [tr.reorder(coords) for tr in _as_list(trajectories)]
        _needs_accelerations(trajs, "SINDy on accelerations")
        actuated = [i for i, c in enumerate(coords) if any(np.any(tr.Q[:, i]) for tr in trajs)]
        self.features_ = feats
        self.controls_ = [f"Q_{coords[i]}" for i in actuated]
        self._actuated = actuated
        self._input_names = [f"z{i}" for i in range(len(feats))] + [f"u{i}" for i in range(len(actuated))]
        Z = [feats.theta(tr.X) for tr in trajs]
        Y = [tr.qdd for tr in trajs]
        U = [tr.Q[:, actuated] for tr in trajs] if actuated else None
        T = [tr.t for tr in trajs]

        # α grid relative to α_max (all coefficients zero) of the normalised problem
        self.alpha_ = self._choose_alpha(ps, Z, Y, U, T)
        self.model_ = self._fit_one(ps, self.alpha_, Z, Y, U, T)
        self.coef_ = np.asarray(self.model_.coefficients(), float)
        self._names = self.model_.get_feature_names()
        self.candidate_names_ = [self._readable(n) for n in self._names]
        self.n_nonzero_ = int(np.count_nonzero(self.coef_))
        self._build_ode()
        check = self.predict(trajs[0].X, trajs[0].Q)
        ref = _pysindy_predict(self.model_, Z[0], None if U is None else U[0])
        if not np.allclose(check, ref, rtol=1e-8, atol=1e-8 * (1 + np.abs(ref).max())):
            raise RuntimeError("internal error: the SINDy ODE disagrees with pysindy's model")
        return self

    def _choose_alpha(self, ps, Z, Y, U, T) -> float:
        A = np.vstack([self._design(z, None if U is None else U[i]) for i, z in enumerate(Z)])
        y = np.vstack(Y)
        An = A / np.maximum(np.linalg.norm(A, axis=0), 1e-300)
        alpha_max = float(np.max(np.abs(An.T @ y)) / len(y))
        alphas = (np.asarray(self.alphas, float) if self.alphas is not None
                  else alpha_max * np.logspace(-6, np.log10(0.3), 25))
        cut = [max(2, int(round(len(z) * (1 - self.validation)))) for z in Z]
        tr = lambda arrs: [a[:c] for a, c in zip(arrs, cut)]        # noqa: E731
        va = lambda arrs: [a[c:] for a, c in zip(arrs, cut)]        # noqa: E731
        scale = np.var(np.vstack(va(Y)), axis=0) + 1e-300
        best = (np.inf, None)
        for alpha in alphas:
            m = self._fit_one(ps, float(alpha), tr(Z), tr(Y), None if U is None else tr(U), tr(T))
            err = 0.0
            for z, yv, uv in zip(va(Z), va(Y), va(U) if U is not None else [None] * len(Z)):
                err += float(np.sum(np.mean((_pysindy_predict(m, z, uv) - yv) ** 2, axis=0) / scale))
            if err < best[0]:
                best = (err, float(alpha))
        return best[1]

    @staticmethod
    def _design(z, u):
        return z if u is None else np.hstack([z, u])

    # ------------------------------------------------------------------ the fitted model
    def _factor(self, token: str):
        """``z3^2`` -> (kind, index, power)."""
        m = re.fullmatch(r"([zu])(\d+)(?:\^(\d+))?", token)
        if m is None:
            raise RuntimeError(f"internal error: unexpected pysindy feature name {token!r}")
        return m.group(1), int(m.group(2)), int(m.group(3) or 1)

    def _readable(self, name: str) -> str:
        out = []
        for tok in name.split():
            kind, i, p = self._factor(tok)
            base = self.features_.names[i] if kind == "z" else self.controls_[i]
            out.append(base + (f"^{p}" if p > 1 else ""))
        return " ".join(out)

    def _build_ode(self):
        c = self.features_.coords
        z = ca.vertsplit(self.features_.sx.T)
        u = [c.Q[i] for i in self._actuated]
        cols = []
        for name in self._names:
            term = ca.SX(1)
            for tok in name.split():
                kind, i, p = self._factor(tok)
                term = term * ca.constpow(z[i] if kind == "z" else u[i], p)
            cols.append(term)
        qdd = ca.mtimes(ca.DM(self.coef_), ca.vertcat(*cols))
        self._ode = ca.Function("sindy_ode", [c.x, c.Q], [ca.vertcat(c.qd, qdd)], ["x", "u"], ["xdot"])

    def _check_fitted(self):
        if not hasattr(self, "coef_"):
            raise ValueError("this SINDyLasso is not fitted yet; call fit()")

    def ode(self) -> ca.Function:
        """``casadi.Function('sindy_ode', [x, u], [xdot])`` with x = [q, q̇], u = Q (like ours)."""
        self._check_fitted()
        return self._ode

    def predict(self, X, Q=None) -> np.ndarray:
        """Accelerations (n_samples, n_coords) at states X (n_samples, 2n) and forces Q."""
        self._check_fitted()
        X = np.atleast_2d(np.asarray(X, float))
        n = self.features_.coords.n
        Q = np.zeros((len(X), n)) if Q is None else np.broadcast_to(np.asarray(Q, float), (len(X), n))
        return np.asarray(self._ode.map(len(X))(X.T, Q.T)).T[:, n:]

    def equations(self, precision: int = 3) -> list:
        """``["theta_ddot = 1.234 cos(theta) + ...", ...]`` (zero terms left out)."""
        self._check_fitted()
        rows = []
        for name, row in zip(self.features_.coords.names, self.coef_):
            text = ""
            for c, term in zip(row, self.candidate_names_):
                if c != 0:
                    sign = ("-" if c < 0 else "") if not text else (" - " if c < 0 else " + ")
                    text += f"{sign}{abs(c):.{precision}f} {term}"
            rows.append(f"{name}_ddot = {text or '0'}")
        return rows


def _pysindy_predict(model, z, u) -> np.ndarray:
    """q̈ = Θ(z, u) Ξᵀ from a fitted pysindy model's library and ``coefficients()``.

    (Not ``model.predict``: with ``WrappedOptimizer(normalize_columns=True)`` pysindy 2.1 predicts
    through the wrapped scikit-learn estimators, whose coefficients are those of the normalised
    columns before unbiasing, while ``coefficients()`` is the fitted model it reports and prints.)
    """
    x = z if u is None else np.hstack([z, u])
    theta = model.feature_library.transform([x])[0]
    return np.asarray(theta) @ np.asarray(model.coefficients()).T


@dataclass
class Kronic:
    """KRONIC's conserved quantity on passive data: ξ = right singular vector of Γ, smallest σ.

    Parameters
    ----------
    library : Library
        Candidate terms Θ (the same library as ours).
    rel_tol : float
        A coefficient counts as non-zero when ``|ξ_j| > rel_tol · max |ξ|``.  The default 1e-6 is
        far above round-off (1e-15 relative) and far below any term that matters.

    Attributes (after ``fit``)
    --------------------------
    coef_ : array (p,)             ξ scaled so that max |ξ| = 1
    singular_value_ : float        the smallest singular value of Γ
    n_nonzero_ : int
    null_dim_ : int                how many singular values are within round-off of zero (identities
                                   such as sin² + cos² = 1 in the library make this > 1, so the
                                   chosen vector mixes them and is dense)
    """

    library: Library
    rel_tol: float = 1e-6

    def fit(self, trajectories) -> "Kronic":
        trajs = [tr.reorder(self.library.coords.names) for tr in _as_list(trajectories)]
        _needs_accelerations(trajs, "KRONIC (Γ = ∇Θ·ẋ)")
        if any(np.any(tr.power) for tr in trajs):
            raise ValueError("KRONIC looks for a conserved quantity: give it passive data (Q ≡ 0)")
        G = np.vstack([self.library.gamma(tr.X, tr.Xdot) for tr in trajs])
        _, s, Vt = np.linalg.svd(G, full_matrices=False)
        if len(s) < G.shape[1]:
            raise ValueError(f"KRONIC needs at least as many samples ({G.shape[0]}) as library "
                             f"terms ({G.shape[1]})")
        v = Vt[-1]
        self.coef_ = v / v[np.argmax(np.abs(v))]
        self.singular_value_ = float(s[-1])
        self.null_dim_ = int(np.sum(s <= s[0] * 1e-12))
        self.n_nonzero_ = int(np.sum(np.abs(self.coef_) > self.rel_tol))
        return self


@dataclass
class Rollout:
    """A simulated trajectory that may have diverged.

    Attributes
    ----------
    t : array (n_samples,)
    X : array (n_samples, 2n)       states; NaN after ``diverged_at``
    Xdot : array (n_samples, 2n)    state derivatives from the model (NaN after divergence)
    diverged_at : float or None     time at which the state left the bound or the integrator failed
    """

    t: np.ndarray
    X: np.ndarray
    Xdot: np.ndarray
    diverged_at: float | None


def rollout(ode: ca.Function, x0, t, u=None, bound: float = 1e3,
            rtol: float = 1e-10, atol: float = 1e-10) -> Rollout:
    """Integrate ``ode(x, u)`` from ``x0`` over the sample times ``t``, stopping if it diverges.

    Parameters
    ----------
    ode : casadi.Function
        ``(x (2n), u (n)) -> xdot (2n)``.
    x0 : array (2n,)
    t : array (n_samples,)
    u : array (n,), optional
        Constant generalized forces (default zero).
    bound : float
        The model has diverged when any |state| exceeds this (or the integrator fails).
    """
    t = np.asarray(t, float)
    x0 = np.asarray(x0, float).ravel()
    n = x0.size // 2
    uu = np.zeros(n) if u is None else np.broadcast_to(np.asarray(u, float), (n,)).copy()
    f = lambda _t, x: np.asarray(ode(x, uu)).ravel()          # noqa: E731
    escape = lambda _t, x: bound - np.max(np.abs(x))            # noqa: E731
    escape.terminal = True
    with np.errstate(all="ignore"):
        sol = solve_ivp(f, (t[0], t[-1]), x0, method="DOP853", t_eval=t, rtol=rtol, atol=atol,
                        events=escape)
    X = np.full((len(t), 2 * n), np.nan)
    X[:sol.y.shape[1]] = sol.y.T
    good = np.all(np.isfinite(X), axis=1)
    k = len(t) if good.all() else int(np.argmin(good))     # rows before the first bad one
    X[k:] = np.nan
    diverged = None
    if sol.status != 0 or k < len(t):
        hit = sol.t_events[0] if sol.t_events else []
        diverged = float(hit[0]) if len(hit) else float(t[min(k, len(t) - 1)])
    Xdot = np.full_like(X, np.nan)
    if k:
        Xdot[:k] = np.asarray(ode.map(k)(X[:k].T, np.tile(uu[:, None], (1, k)))).T
    return Rollout(t, X, Xdot, diverged)
