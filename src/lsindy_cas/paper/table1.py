"""Reproduce the paper's Table I: 3 systems × {actuated, passive}, identified H and L vs the truth."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import systems
from ..symbolic.library import Library
from ..identify.estimator import LagrangianSINDy

__all__ = ["PAPER_SETUPS", "Cell", "run_cell", "table_one", "write_table"]


@dataclass(frozen=True)
class Setup:
    """The library and prior knowledge used for one benchmark system."""

    system: str
    features: str
    degree: int
    n_terms: int
    prior: tuple


# Libraries: products of the natural features up to the degree the kinetic terms need; priors:
# the energies of the simple constituents (a pendulum: θ̇², cos θ; each link of the double pendulum).
PAPER_SETUPS = {
    "spherical": Setup("spherical", "cos(theta),sin(theta),theta_dot,phi,phi_dot", 4, 3,
                       ("theta_dot**2", "cos(theta)")),
    "double": Setup("double", "cos(theta1),cos(theta2),sin(theta1),sin(theta2),theta1_dot,theta2_dot",
                    4, 6, ("theta1_dot**2", "cos(theta1)", "theta2_dot**2", "cos(theta2)")),
    "cart": Setup("cart", "cos(theta),sin(theta),theta_dot,x,x_dot", 3, 4, ("theta_dot**2", "cos(theta)")),
}
SCHEMES = ("actuated", "passive")
T_ACTUATED, T_PASSIVE, T_SCALE, U = 1.0, 3.0, 0.1, 1.0


def scheme_data(system, scheme: str):
    """The paper's training data for a scheme: (trajectories, scale_trajectories)."""
    if scheme == "actuated":
        return [system.simulate(t_end=T_ACTUATED, u=U)], None
    if scheme == "passive":
        return [system.simulate(t_end=T_PASSIVE, u=0.0)], [system.simulate(t_end=T_SCALE, u=U)]
    raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")


@dataclass
class Cell:
    """One Table I cell: the identified model and how it compares with the truth."""

    system: str
    scheme: str
    model: LagrangianSINDy
    exact_support: bool
    max_rel_error: float
    lagrangian_exact_support: bool
    lagrangian_max_rel_error: float
    seconds: float
    n_supports: int
    track_error: float


    def to_dict(self) -> dict:
        return {"system": self.system, "scheme": self.scheme,
                "hamiltonian": str(self.model.hamiltonian_), "lagrangian": str(self.model.lagrangian_),
                "hamiltonian_terms": self.model.terms("hamiltonian"),
                "lagrangian_terms": self.model.terms("lagrangian"),
                "exact_support": self.exact_support, "max_rel_error": self.max_rel_error,
                "lagrangian_exact_support": self.lagrangian_exact_support,
                "lagrangian_max_rel_error": self.lagrangian_max_rel_error,
                "seconds": self.seconds, "n_supports": self.n_supports,
                "track_error_6s": self.track_error}


def compare(coef: np.ndarray, truth: np.ndarray) -> tuple[bool, float]:
    """(exact support?, max relative coefficient error on the true support)."""
    true_support = truth != 0
    exact = bool(np.array_equal(coef != 0, true_support))
    err = float(np.max(np.abs(coef[true_support] - truth[true_support]) / np.abs(truth[true_support])))
    return exact, err


def run_cell(name: str, scheme: str, system=None) -> Cell:
    setup = PAPER_SETUPS[name]
    system = system or systems.PAPER_SYSTEMS[name]()
    lib = Library.polynomial(system.coords, setup.features, setup.degree)
    trajs, scale = scheme_data(system, scheme)
    t0 = time.perf_counter()
    model = LagrangianSINDy(lib, n_terms=setup.n_terms, prior=setup.prior).fit(trajs, scale)
    seconds = time.perf_counter() - t0
    exact, err = compare(model.coef_, lib.coefficients(system.hamiltonian))
    exact_l, err_l = compare(model.lagrangian_coef_, lib.coefficients(system.lagrangian))
    return Cell(name, scheme, model, exact, err, exact_l, err_l, seconds, model.search_.n_supports,
                tracking_error(model, system))


T_TRACK = 6.0   # 3 s of the passive training span + 3 s of extrapolation


def tracking_error(model, system, t_end: float = T_TRACK) -> float:
    """Max |x_model − x_true| over ``t_end`` s of unforced motion from the paper's x0."""
    truth = system.simulate(t_end=t_end, u=0.0)
    return float(np.max(np.abs(model.simulate(system.x0, truth.t) - truth.X)))


def table_one(progress=None) -> list:
    """All six cells (3 systems × 2 schemes)."""
    cells = []
    for name in PAPER_SETUPS:
        for scheme in SCHEMES:
            if progress:
                progress(f"identifying {name} ({scheme}) ...")
            cells.append(run_cell(name, scheme))
    return cells


def _short(expr) -> str:
    from ..printing import plain      # 4 significant digits, trig products folded
    return plain(expr, 4).replace("**", "^").replace("*", "·")


def markdown(cells) -> str:
    lines = ["| system | scheme | identified H | identified L | exact support | max rel. error (H / L) "
             "| max state error, 3 s + 3 s | fit time |",
             "|---|---|---|---|---|---|---|---|"]
    for c in cells:
        lines.append(f"| {c.system} | {c.scheme} | {_short(c.model.hamiltonian_)} | "
                     f"{_short(c.model.lagrangian_)} | "
                     f"{'yes' if c.exact_support and c.lagrangian_exact_support else 'NO'} | "
                     f"{c.max_rel_error:.1e} / {c.lagrangian_max_rel_error:.1e} | "
                     f"{c.track_error:.1e} | {c.seconds:.2f} s |")
    return "\n".join(lines)


def write_table(cells, out: Path) -> tuple[Path, Path]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    md, js = out / "table1.md", out / "table1.json"
    md.write_text(markdown(cells) + "\n")
    js.write_text(json.dumps([c.to_dict() for c in cells], indent=2))
    return md, js
