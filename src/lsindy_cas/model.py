"""``LagrangianSINDy``: trajectories -> energy (H) -> Lagrangian (L) -> equations of motion."""
from __future__ import annotations

import json
import os
import tempfile
from pathlib import Path

import numpy as np
import sympy as sp

from . import __version__
from .admissibility import Admissibility
from .balance import derivative_form, integral_form
from .data import Trajectory
from .legendre import legendre
from .library import Library
from .mechanics import EulerLagrange, simulate_ode
from .search import _normalise, best_subset

__all__ = ["LagrangianSINDy"]

_FORMS = ("auto", "derivative", "integral")


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
    n_terms : int
        Number of terms k in the energy (paper's k).
    prior : sequence of str
        Terms known to be in the energy (e.g. those of the constituent simple systems); forced into
        every support and required to come out non-zero.
    form : {"auto", "derivative", "integral"}
        Energy-balance form; "auto" uses the derivative form when every trajectory carries exact
        accelerations and the integral form otherwise.
    window : int
        Integral form: window length in samples.

    Attributes (after ``fit``)
    --------------------------
    coords_ : list of str
    coef_ : array (p,)            energy coefficients ξ (H = Θ ξ)
    lagrangian_coef_ : array (p,) Lagrangian coefficients ξ_L (eq. 7)
    support_ : tuple of int
    hamiltonian_, lagrangian_ : sympy.Expr
    actuated_ : list of str       coordinates that carried an applied force in the data
    search_ : SearchResult        ranking and diagnostics of the support search
    passive_ : bool               whether the passive (null-space + scale) scheme was used
    """

    def __init__(self, library: Library, *, n_terms: int, prior=(), form: str = "auto",
                 window: int = 10):
        self.library = library
        self.n_terms = n_terms
        self.prior = prior
        self.form = form
        self.window = window

    # ------------------------------------------------------------------ fitting
    def _validate(self):
        if not isinstance(self.library, Library):
            raise TypeError(f"library must be a Library, got {type(self.library).__name__}")
        k = self.n_terms
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)):
            raise TypeError(f"n_terms must be an integer, got {type(k).__name__}")
        if not 1 <= k <= len(self.library):
            raise ValueError(f"n_terms = {k} must be between 1 and the library size {len(self.library)}")
        prior = [self.prior] if isinstance(self.prior, str) else list(self.prior)
        forced = [self.library.index(t, what="prior term") for t in prior]
        if len(set(forced)) > k:
            raise ValueError(f"{len(set(forced))} prior terms do not fit in n_terms = {k}")
        if self.form not in _FORMS:
            raise ValueError(f"form must be one of {_FORMS}, got {self.form!r}")
        return forced

    def _balance(self, trajectories, passive=None):
        form = self.form
        if form == "auto":
            form = "derivative" if all(tr.qdd is not None for tr in trajectories) else "integral"
        if form == "derivative":
            return derivative_form(self.library, trajectories, passive=passive)
        return integral_form(self.library, trajectories, window=self.window, passive=passive)

    def fit(self, trajectories, scale_trajectories=None, passive=None) -> "LagrangianSINDy":
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
        """
        forced = self._validate()
        coords = self.library.coords.names
        trajectories = _check_trajectories(trajectories, coords)
        bal = self._balance(trajectories, passive=passive)
        scale_system = None
        if bal.passive:
            if scale_trajectories is None:
                raise ValueError("the training data are passive (no power fed in), which fixes the "
                                 "energy only up to a factor: pass scale_trajectories, a short "
                                 "actuated record (paper eq. 8)")
            scale = self._balance(_check_trajectories(scale_trajectories, coords,
                                                      "scale_trajectories"), passive=False)
            if not np.any(scale.b):
                raise ValueError("scale_trajectories carry no power (Q·q̇ ≡ 0); they cannot fix the scale")
            scale_system = (scale.A, scale.b)
        _, norms = _normalise(bal.A)
        if bal.passive:       # judge term shares on the actuated record, where they are non-zero
            norms = _normalise(scale_system[0])[1]
        admissible = Admissibility(self.library, bal.X, forced, norms)
        self.search_ = best_subset(bal.A, bal.b, int(self.n_terms), forced, admissible=admissible,
                                   D=bal.D if bal.passive else None, scale_system=scale_system)
        self.passive_ = bal.passive
        self.form_ = bal.form
        self.actuated_ = [c for c in coords if any(c in tr.actuated for tr in
                                                   trajectories + _maybe_list(scale_trajectories))]
        self._set_coefficients(self.search_.coef, X=bal.X)
        return self

    def _set_coefficients(self, coef, X=None):
        lib = self.library
        self.coords_ = list(lib.coords.names)
        self.coef_ = np.asarray(coef, float)
        self.support_ = tuple(int(j) for j in np.flatnonzero(self.coef_))
        self.lagrangian_coef_ = legendre(lib, self.coef_, X)
        self.hamiltonian_ = _combine(lib, self.coef_)
        self.lagrangian_ = _combine(lib, self.lagrangian_coef_)
        self._mechanics = EulerLagrange(lib.coords, self.lagrangian_)

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
        lines = [f"H = {_fmt(self.hamiltonian_)}", f"L = {_fmt(self.lagrangian_)}",
                 "equations of motion:"]
        lines += [f"  {_fmt(e.lhs)} = {_fmt(e.rhs)}" for e in self.equations_of_motion()]
        return "\n".join(lines)

    # ------------------------------------------------------------------ persistence
    def to_dict(self) -> dict:
        self._check_fitted()
        return {
            "coords": self.coords_,
            "hamiltonian": str(self.hamiltonian_),
            "lagrangian": str(self.lagrangian_),
            "hamiltonian_terms": self.terms("hamiltonian"),
            "lagrangian_terms": self.terms("lagrangian"),
            "equations_of_motion": [f"{e.lhs} = {e.rhs}" for e in self.equations_of_motion()],
            "actuated": list(getattr(self, "actuated_", [])),
            "library": self.library.to_dict(),
            "n_terms": int(len(self.support_)),
            "prior": [str(p) for p in ([self.prior] if isinstance(self.prior, str) else self.prior)],
            "lsindy_cas_version": __version__,
        }

    def save(self, path) -> Path:
        """Write the model as JSON (atomically; the DESIGN.md model file)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".json")
        try:
            with os.fdopen(fd, "w") as fh:
                json.dump(self.to_dict(), fh, indent=2)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        return path

    @classmethod
    def load(cls, path) -> "LagrangianSINDy":
        """Read a model written by ``save`` or ``lsindy identify --json``."""
        path = Path(path)
        if not path.is_file():
            raise ValueError(f"{path}: no such model file")
        try:
            d = json.loads(path.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise ValueError(f"{path}: not a JSON model file ({exc})") from None
        missing = [k for k in ("coords", "hamiltonian_terms") if k not in d]
        if missing:
            raise ValueError(f"{path}: model file lacks {', '.join(missing)}")
        terms = d["hamiltonian_terms"]
        lib = Library.from_dict(d["library"]) if "library" in d else Library(d["coords"], list(terms))
        coef = np.zeros(len(lib))
        for name, c in terms.items():
            coef[lib.index(name, what=f"{path}: term")] = float(c)
        model = cls(lib, n_terms=max(1, len(terms)), prior=d.get("prior", ()))
        model.actuated_ = list(d.get("actuated", []))
        model._set_coefficients(coef)
        return model


def _maybe_list(x) -> list:
    if x is None:
        return []
    return [x] if isinstance(x, Trajectory) else list(x)


def _combine(lib: Library, coef) -> sp.Expr:
    return sp.Add(*[sp.Float(float(coef[j]), 15) * lib.exprs[j] for j in np.flatnonzero(coef)])


def _fmt(expr, digits: int = 4) -> str:
    """Readable form with coefficients rounded to ``digits`` significant digits."""
    return str(sp.N(expr, digits))
