"""The experiments behind the paper's comparison figures (Figs. 3 and 4), on the paper's setups.

- **Fig. 3 — model complexity** (:func:`complexity`): number of non-zero terms of the library, SINDy
  with Lasso (pysindy, fitted to the accelerations of the actuated run), KRONIC (passive run) and
  Lagrangian-SINDy (actuated run), for the three benchmark systems.
- **Fig. 4 — extrapolation** (:func:`extrapolation`): each model trained on the paper's passive run
  (0–3 s, no actuation) is simulated from the same initial state for 6 s; the RMS errors of ours
  and SINDy against the true system on the training window and on the 3 s of extrapolation.

:func:`measure` runs both for a list of systems; :func:`markdown` and :func:`write_numbers` report
the numbers, :func:`claims` checks them against the paper's claims.  The drawing is in
:mod:`~lsindy_cas.paper.figures`.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import systems as _systems
from .baselines import Kronic, Rollout, SINDyLasso, require_pysindy, rollout
from ..symbolic.library import Library, split_top_level
from .table1 import PAPER_SETUPS, run_cell, scheme_data

__all__ = ["Complexity", "Extrapolation", "claims", "complexity", "extrapolation", "markdown",
           "measure", "sindy_available", "write_numbers"]

TITLES = {"spherical": "spherical pendulum", "double": "double pendulum", "cart": "cart-pendulum"}
T_TRAIN, T_END, DT = 3.0, 6.0, 0.01          # paper Fig. 4: 3 s training + 3 s extrapolation


def _features(name: str):
    setup = PAPER_SETUPS[name]
    system = _systems.PAPER_SYSTEMS[name]()
    return setup, system, split_top_level(setup.features)


# ---------------------------------------------------------------------- Fig. 3
@dataclass
class Complexity:
    """Non-zero terms of each method's model for one system (paper Fig. 3)."""

    system: str
    library: int          # candidate terms in the energy library
    sindy: int | None     # non-zero coefficients over SINDy's acceleration equations (None:
                          # the SINDy baseline was skipped, pysindy missing)
    kronic: int           # non-zero coefficients of KRONIC's conserved quantity
    ours: int             # terms in the identified Lagrangian
    sindy_candidates: int | None  # SINDy's candidate coefficients (equations × candidates)
    sindy_alpha: float | None
    kronic_null_dim: int

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def complexity(name: str, ours=None, sindy: bool = True) -> Complexity:
    """Measure Fig. 3 for one system on the paper's data.

    Parameters
    ----------
    name : {"spherical", "double", "cart"}
    ours : LagrangianSINDy, optional
        Our model from the actuated scheme (e.g. a Table I cell's); fitted here if omitted.
    sindy : bool
        Fit the SINDy baseline (needs pysindy); False leaves its numbers None.
    """
    setup, system, features = _features(name)
    lib = Library.polynomial(system.coords, features, setup.degree)
    actuated, _ = scheme_data(system, "actuated")
    passive, _ = scheme_data(system, "passive")
    kronic = Kronic(lib).fit(passive)
    ours = ours if ours is not None else run_cell(name, "actuated").model
    n_ours = int(np.count_nonzero(ours.lagrangian_coef_))
    if not sindy:
        return Complexity(name, len(lib), None, kronic.n_nonzero_, n_ours, None, None,
                          kronic.null_dim_)
    sindy = SINDyLasso(features, coords=system.coords, degree=setup.degree).fit(actuated)
    return Complexity(name, len(lib), sindy.n_nonzero_, kronic.n_nonzero_, n_ours,
                      int(sindy.coef_.size), float(sindy.alpha_), kronic.null_dim_)


# ---------------------------------------------------------------------- Fig. 4
@dataclass
class Extrapolation:
    """Simulations of the true system, ours and SINDy from the training run's initial state."""

    system: str
    coords: list
    t: np.ndarray
    true: Rollout
    ours: Rollout
    sindy: Rollout | None          # None: the SINDy baseline was skipped (pysindy missing)
    sindy_terms: int | None
    errors: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-able numbers; an error of ``null`` means the model diverged in that window."""
        errors = {k: (v if np.isfinite(v) else None) for k, v in self.errors.items()}
        return {"system": self.system, "sindy_terms": self.sindy_terms, **errors,
                "sindy_diverged_at": None if self.sindy is None else self.sindy.diverged_at,
                "ours_diverged_at": self.ours.diverged_at}


def _rms(d: np.ndarray) -> float:
    """RMS of a difference; ``inf`` when the model diverged inside the window (NaN samples)."""
    if not np.all(np.isfinite(d)):
        return float("inf")
    return float(np.sqrt(np.mean(d ** 2)))


def extrapolation(name: str, ours=None, t_train: float = T_TRAIN, t_end: float = T_END,
                  sindy: bool = True) -> Extrapolation:
    """Measure Fig. 4 for one system.

    Both models learn from the paper's passive run (``t_train`` s, no actuation; ours also from the
    0.1 s scale trial), then every model is simulated without actuation for ``t_end`` s.

    Parameters
    ----------
    ours : LagrangianSINDy, optional
        Our passive-scheme model (e.g. a Table I cell's); fitted here if omitted.
    sindy : bool
        Fit and simulate the SINDy baseline (needs pysindy); False leaves it None.
    """
    setup, system, features = _features(name)
    passive, _ = scheme_data(system, "passive")
    if abs(passive[0].t[-1] - t_train) > 1e-9:
        raise ValueError(f"the passive run lasts {passive[0].t[-1]} s, not t_train = {t_train} s")
    sindy = (SINDyLasso(features, coords=system.coords, degree=setup.degree).fit(passive)
             if sindy else None)
    ours = ours if ours is not None else run_cell(name, "passive").model
    t = np.arange(int(round(t_end / DT)) + 1) * DT
    x0 = np.asarray(system.x0, float)
    res = Extrapolation(name, list(system.coords), t, rollout(system.ode(), x0, t),
                        rollout(ours.ode(), x0, t),
                        None if sindy is None else rollout(sindy.ode(), x0, t),
                        None if sindy is None else sindy.n_nonzero_)
    n = len(system.coords)
    windows = {"train": t <= t_train + 1e-9, "extrap": t > t_train + 1e-9}
    for w, mask in windows.items():
        for who in ("ours", "sindy"):
            r = getattr(res, who)
            if r is None:
                continue
            res.errors[f"rms_q_{w}_{who}"] = _rms(r.X[mask, :n] - res.true.X[mask, :n])
            res.errors[f"rms_qdd_{w}_{who}"] = _rms(r.Xdot[mask, n:] - res.true.Xdot[mask, n:])
    return res


# ---------------------------------------------------------------------- report
def _fmt(v) -> str:
    return "skipped" if v is None else "diverged" if v == float("inf") else f"{v:.2e}"


def markdown(complexities, extrapolations) -> str:
    """The numbers behind Figs. 3 and 4 as Markdown tables."""
    lines = []
    if complexities:
        lines += ["Fig. 3 — number of non-zero terms (lower is sparser)", "",
                  "| system | library | SINDy (Lasso) | KRONIC | Lagrangian-SINDy |",
                  "|---|---|---|---|---|"]
        lines += [f"| {TITLES[c.system]} | {c.library} | "
                  + ("skipped" if c.sindy is None else f"{c.sindy} (of {c.sindy_candidates})")
                  + f" | {c.kronic} | {c.ours} |" for c in complexities]
    if extrapolations:
        lines += ["", "Fig. 4 — RMS error of the simulated coordinates q (rad or m) and accelerations "
                  "q̈, ours vs SINDy", "",
                  "| system | q, training 0–3 s | q, extrapolation 3–6 s | q̈, extrapolation 3–6 s "
                  "| SINDy diverges at |", "|---|---|---|---|---|"]
        for e in extrapolations:
            er = {k: e.errors.get(k) for k in ("rms_q_train_ours", "rms_q_train_sindy",
                                               "rms_q_extrap_ours", "rms_q_extrap_sindy",
                                               "rms_qdd_extrap_ours", "rms_qdd_extrap_sindy")}
            div = ("skipped" if e.sindy is None else "—" if e.sindy.diverged_at is None
                   else f"{e.sindy.diverged_at:.2f} s")
            lines.append(f"| {TITLES[e.system]} | {_fmt(er['rms_q_train_ours'])} vs "
                         f"{_fmt(er['rms_q_train_sindy'])} | {_fmt(er['rms_q_extrap_ours'])} vs "
                         f"{_fmt(er['rms_q_extrap_sindy'])} | {_fmt(er['rms_qdd_extrap_ours'])} vs "
                         f"{_fmt(er['rms_qdd_extrap_sindy'])} | {div} |")
    return "\n".join(lines)


def claims(numbers: dict) -> list:
    """What in ``baselines.json`` contradicts the paper's claims (an empty list: all reproduced).

    Claims: ours has the fewest non-zero terms on every system (Fig. 3), and our extrapolation
    error (RMS of q over 3–6 s) is below SINDy's on every system (Fig. 4).
    """
    failed = []
    for c in numbers.get("fig3", []):
        rivals = {"SINDy": c["sindy"], "KRONIC": c["kronic"], "library": c["library"]}
        worse = [k for k, v in rivals.items() if v is not None and v <= c["ours"]]
        if worse:
            failed.append(f"{c['system']}: ours ({c['ours']} terms) is not sparser than "
                          + ", ".join(f"{k} ({rivals[k]})" for k in worse))
    for e in numbers.get("fig4", []):
        ours, sindy = e["rms_q_extrap_ours"], e.get("rms_q_extrap_sindy")
        if "rms_q_extrap_sindy" not in e:           # SINDy skipped (pysindy missing)
            if ours is None:
                failed.append(f"{e['system']}: our extrapolation diverged")
            continue
        if ours is None or (sindy is not None and ours >= sindy):
            failed.append(f"{e['system']}: our extrapolation error ({ours}) is not below "
                          f"SINDy's ({'diverged' if sindy is None else sindy})")
    return failed


def measure(systems=("spherical", "double", "cart"), cells=None, progress=None, sindy=True):
    """Run the Fig. 3 and Fig. 4 experiments for ``systems``.

    Parameters
    ----------
    systems : sequence of {"spherical", "double", "cart"}
    cells : list of table1.Cell, optional
        Table I cells whose models to reuse (actuated ones for Fig. 3, passive for Fig. 4); the
        models are fitted here otherwise.
    progress : callable(str), optional
        Told what is being computed (e.g. ``print`` to stderr).
    sindy : bool or None
        Include the SINDy baseline (True: pysindy required, ``ImportError`` without it; False:
        skipped; None: included when pysindy is installed).

    Returns
    -------
    complexities : list of Complexity
    extrapolations : list of Extrapolation
    """
    if sindy is None:
        sindy = sindy_available()
    if sindy:
        require_pysindy()
    systems = [systems] if isinstance(systems, str) else list(systems)
    unknown = [s for s in systems if s not in PAPER_SETUPS]
    if unknown or not systems:
        raise ValueError(f"systems must be a non-empty subset of {list(PAPER_SETUPS)}, got {systems}")
    by_key = {(c.system, c.scheme): c.model for c in (cells or [])}
    say = progress or (lambda _msg: None)
    comp, extra = [], []
    for name in systems:
        say(f"Fig. 3: SINDy and KRONIC on the {TITLES[name]} ...")
        comp.append(complexity(name, by_key.get((name, "actuated")), sindy=sindy))
    for name in systems:
        say(f"Fig. 4: training and extrapolating the {TITLES[name]} ...")
        extra.append(extrapolation(name, by_key.get((name, "passive")), sindy=sindy))
    return comp, extra


def sindy_available() -> bool:
    """Whether the SINDy baseline can run (pysindy importable)."""
    try:
        require_pysindy()
    except ImportError:
        return False
    return True


def write_numbers(complexities, extrapolations, out_dir):
    """Write ``baselines.md`` and ``baselines.json`` to ``out_dir`` (created).

    Returns
    -------
    md, js : Path
    text : str
        The Markdown tables.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    text = markdown(complexities, extrapolations)
    md = out / "baselines.md"
    md.write_text(text + "\n")
    js = out / "baselines.json"
    js.write_text(json.dumps({"fig3": [c.to_dict() for c in complexities],
                              "fig4": [e.to_dict() for e in extrapolations]}, indent=2))
    return md, js, text
