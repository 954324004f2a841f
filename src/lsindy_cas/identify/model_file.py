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
from ..mechanics.rayleigh import check_velocity_only
from ..symbolic.library import Library
from .findings import CODES, Finding, code_of

__all__ = ["model_to_dict", "save_model", "load_model"]


def model_to_dict(model) -> dict:
    """The DESIGN.md model-file dictionary of a fitted ``LagrangianSINDy``."""
    model._check_fitted()
    prior = model.prior
    text = model.texts(15)         # sympy syntax, 15 significant digits, built without sympy
    out = {
        "coords": model.coords_,
        "hamiltonian": text["hamiltonian"],
        "lagrangian": text["lagrangian"],
        "hamiltonian_terms": model.terms("hamiltonian"),
        "lagrangian_terms": model.terms("lagrangian"),
        "equations_of_motion": [f"{lhs} = {rhs}" for lhs, rhs in text["equations"]],
        "actuated": list(getattr(model, "actuated_", [])),
        "library": model.library.to_dict(),
        "n_terms": int(len(model.support_)),
        "prior": [str(p) for p in ([prior] if isinstance(prior, str) else prior)],
        "lsindy_cas_version": __version__,
    }
    if getattr(model, "hold_", None) is not None:
        out["hold"] = model.hold_
    out["velocities"] = getattr(model, "velocities_", "measured")   # or "estimated"/"mixed"
    if getattr(model, "status_", None) is not None:
        reasons = list(model.status_reasons_)      # findings: their messages, and their codes
        out["status"] = {"status": model.status_, "reasons": [str(r) for r in reasons],
                         "codes": [code_of(r) for r in reasons]}
    if getattr(model, "coef_std_", None) is not None:      # standard errors, same keys as the terms
        names = model.library.names
        for key, coef, std in (("hamiltonian_std", model.coef_, model.coef_std_),
                               ("lagrangian_std", model.lagrangian_coef_, model.lagrangian_coef_std_)):
            out[key] = {names[j]: float(std[j]) for j in np.flatnonzero(coef)}
        out["std_method"] = model.std_method_
    out["energy_scale"] = getattr(model, "energy_scale_", "absolute")
    if getattr(model, "normalised_by_", None):
        out["normalised_by"] = model.normalised_by_
    if getattr(model, "_diss_lib", None) is not None:      # friction: R and its candidate terms
        out["rayleigh"] = text["rayleigh"]
        out["rayleigh_terms"] = model.terms("rayleigh")
        out["dissipation_library"] = model._diss_lib.to_dict()
    if getattr(model, "refinement_", None) is not None:    # refine.py imports sympy: only then
        from .refine import current_refinement
        if current_refinement(model) is not None:  # prediction-error refinement record
            out["refinement"] = model.refinement_
    res = getattr(model, "search_", None)
    if res is not None:            # how the support was found, and whether it is proven best
        out["search"] = {"method": res.method, "proven": bool(res.proven), "gap": float(res.gap),
                         "nodes": int(res.nodes), "supports_scored": int(res.n_supports)}
        if getattr(res, "reweighted", None) is not None:   # the weighted re-check, cut short
            out["search"]["reweighted"] = dict(res.reweighted)
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
    model.velocities_ = d.get("velocities", "measured")     # files before positions-only: measured
    status = d.get("status")
    if isinstance(status, dict) and status.get("status") in ("ok", "undetermined"):
        model.status_ = status["status"]            # files before the status have none
        model.status_reasons_ = _reasons(status)
    if isinstance(d.get("refinement"), dict):
        model.refinement_ = d["refinement"]
    model.energy_scale_ = d.get("energy_scale", "absolute")
    model.normalised_by_ = d.get("normalised_by")
    rho = None
    if "rayleigh_terms" in d:
        rterms = d["rayleigh_terms"]
        dlib = (Library.from_dict(d["dissipation_library"]) if "dissipation_library" in d
                else Library(d["coords"], list(rterms)) if rterms else None)
        if dlib is not None:
            check_velocity_only(dlib.coords, dlib.exprs, what=f"{path}: dissipation term")
            rho = np.zeros(len(dlib))
            for name, c in rterms.items():
                rho[dlib.index(name, what=f"{path}: dissipation term")] = float(c)
            model.dissipation, model._diss_lib = list(dlib.names), dlib
    model._set_coefficients(coef, rayleigh=rho)
    if "hamiltonian_std" in d:           # files before the standard errors existed have none
        std = {}
        for key in ("hamiltonian_std", "lagrangian_std"):
            std[key] = np.zeros(len(lib))
            for name, se in d.get(key, {}).items():
                std[key][lib.index(name, what=f"{path}: term")] = float(se)
        model.coef_std_, model.lagrangian_coef_std_ = std["hamiltonian_std"], std["lagrangian_std"]
        model.std_method_ = d.get("std_method")
    check_kinetic(model, path)
    return model


def _reasons(status: dict) -> list:
    """The status reasons of a model file: findings when the file records their codes (files
    before the codes, or with an unknown code, give plain strings)."""
    reasons = [str(r) for r in status.get("reasons", [])]
    codes = status.get("codes")
    if not isinstance(codes, list) or len(codes) != len(reasons):
        return reasons
    return [Finding(r, c) if isinstance(c, str) and c in CODES else r
            for r, c in zip(reasons, codes)]


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
