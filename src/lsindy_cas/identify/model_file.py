"""The model file (DESIGN.md): a fitted ``LagrangianSINDy`` to JSON and back.

Everything a saved model must carry lives here, so new fields (status, uncertainties, friction …)
are added in one place: :func:`model_to_dict` writes them, :func:`load_model` reads them back and
old files (without them) still load.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._io import atomic_write
from .._version import __version__
from ..symbolic.library import Library

__all__ = ["model_to_dict", "save_model", "load_model"]


def model_to_dict(model) -> dict:
    """The DESIGN.md model-file dictionary of a fitted ``LagrangianSINDy``."""
    model._check_fitted()
    prior = model.prior
    out = {
        "coords": model.coords_,
        "hamiltonian": str(model.hamiltonian_),
        "lagrangian": str(model.lagrangian_),
        "hamiltonian_terms": model.terms("hamiltonian"),
        "lagrangian_terms": model.terms("lagrangian"),
        "equations_of_motion": [f"{e.lhs} = {e.rhs}" for e in model.equations_of_motion()],
        "actuated": list(getattr(model, "actuated_", [])),
        "library": model.library.to_dict(),
        "n_terms": int(len(model.support_)),
        "prior": [str(p) for p in ([prior] if isinstance(prior, str) else prior)],
        "lsindy_cas_version": __version__,
    }
    if getattr(model, "hold_", None) is not None:
        out["hold"] = model.hold_
    res = getattr(model, "search_", None)
    if res is not None:            # how the support was found, and whether it is proven best
        out["search"] = {"method": res.method, "proven": bool(res.proven), "gap": float(res.gap),
                         "nodes": int(res.nodes), "supports_scored": int(res.n_supports)}
    elif getattr(model, "_loaded_search", None) is not None:
        out["search"] = model._loaded_search
    diag = getattr(model, "diagnostics_", None)
    diag = diag.to_dict() if diag is not None else getattr(model, "_loaded_diagnostics", None)
    if diag is not None:           # the report of the fit travels with the model file
        out["diagnostics"] = diag
    return out


def save_model(model, path) -> Path:
    """Write the model as JSON, atomically."""
    text = json.dumps(model_to_dict(model), indent=2)
    return atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def load_model(cls, path):
    """Read a model file written by :func:`save_model` (``lsindy identify --json``) into ``cls``."""
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
    model._loaded_diagnostics = d.get("diagnostics")
    model._loaded_search = d.get("search")
    model.hold_ = d.get("hold")
    model._set_coefficients(coef)
    check_kinetic(model, path)
    return model


def check_kinetic(model, path, n_states: int = 64):
    """Refuse a model whose mass matrix ∂²L/∂q̇² has a negative eigenvalue at a random state
    (q ∈ [−π, π], q̇ ∈ [−1, 1]): a negative kinetic energy (e.g. a hand-edited sign) makes the
    equations of motion meaningless.  Singular points (sin²θ at the pole) are allowed."""
    M = model._mechanics.mass_matrix()
    n = len(model.coords_)
    rng = np.random.default_rng(0)
    X = np.hstack([rng.uniform(-np.pi, np.pi, (n_states, n)), rng.uniform(-1, 1, (n_states, n))])
    for x in X:
        eig = np.linalg.eigvalsh(np.asarray(M(x)))
        if eig[0] < -1e-9 * max(1.0, abs(eig[-1])):
            raise ValueError(f"{path}: the kinetic part is not positive definite (mass matrix "
                             f"eigenvalue {eig[0]:.3g} at state {np.round(x, 3).tolist()}); "
                             f"check the signs of the velocity terms")
