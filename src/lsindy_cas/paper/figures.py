"""The paper's comparison figures, measured on the paper's setups (``reproduce.PAPER_SETUPS``).

- **Fig. 3 — model complexity**: number of non-zero terms (log scale) of the library, SINDy with
  Lasso (pysindy, fitted to the accelerations of the actuated run), KRONIC (passive run) and
  Lagrangian-SINDy (actuated run), for the three benchmark systems.
- **Fig. 4 — extrapolation**: each model trained on the paper's passive run (0–3 s, no actuation) is
  simulated from the same initial state for 6 s; accelerations and phase portraits of the true
  system, ours and SINDy, with the end of the training window marked, and the RMS errors on the
  training window and on the 3 s of extrapolation.

:func:`make_figures` computes both, writes ``fig3_complexity.png``, ``fig4_extrapolation.png`` and
the numbers (``baselines.md``, ``baselines.json``); ``lsindy reproduce --out DIR`` calls it.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import systems as _systems
from .baselines import Kronic, Rollout, SINDyLasso, require_pysindy, rollout
from ..symbolic.library import Library, _split_top_level
from ..printing import symbol_latex
from .table1 import PAPER_SETUPS, run_cell, scheme_data

__all__ = ["Complexity", "Extrapolation", "claims", "complexity", "extrapolation", "fig3", "fig4",
           "make_figures", "markdown"]

TITLES = {"spherical": "spherical pendulum", "double": "double pendulum", "cart": "cart-pendulum"}
T_TRAIN, T_END, DT = 3.0, 6.0, 0.01          # paper Fig. 4: 3 s training + 3 s extrapolation


def _features(name: str):
    setup = PAPER_SETUPS[name]
    system = _systems.PAPER_SYSTEMS[name]()
    return setup, system, _split_top_level(setup.features)


# ---------------------------------------------------------------------- Fig. 3
@dataclass
class Complexity:
    """Non-zero terms of each method's model for one system (paper Fig. 3)."""

    system: str
    library: int          # candidate terms in the energy library
    sindy: int            # non-zero coefficients over SINDy's acceleration equations
    kronic: int           # non-zero coefficients of KRONIC's conserved quantity
    ours: int             # terms in the identified Lagrangian
    sindy_candidates: int  # SINDy's candidate coefficients (equations × candidates per equation)
    sindy_alpha: float
    kronic_null_dim: int

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def complexity(name: str, ours=None) -> Complexity:
    """Measure Fig. 3 for one system on the paper's data.

    Parameters
    ----------
    name : {"spherical", "double", "cart"}
    ours : LagrangianSINDy, optional
        Our model from the actuated scheme (e.g. a Table I cell's); fitted here if omitted.
    """
    setup, system, features = _features(name)
    lib = Library.polynomial(system.coords, features, setup.degree)
    actuated, _ = scheme_data(system, "actuated")
    passive, _ = scheme_data(system, "passive")
    sindy = SINDyLasso(features, coords=system.coords, degree=setup.degree).fit(actuated)
    kronic = Kronic(lib).fit(passive)
    ours = ours if ours is not None else run_cell(name, "actuated").model
    return Complexity(name, len(lib), sindy.n_nonzero_, kronic.n_nonzero_,
                      int(np.count_nonzero(ours.lagrangian_coef_)), int(sindy.coef_.size),
                      float(sindy.alpha_), kronic.null_dim_)


def fig3(results, path) -> Path:
    """Grouped bars, log scale: library / SINDy / KRONIC / ours for each system."""
    plt = _pyplot()
    methods = [("library", "library (candidates)", "#bbbbbb"), ("sindy", "SINDy (Lasso)", "#4c72b0"),
               ("kronic", "KRONIC", "#55a868"), ("ours", "Lagrangian-SINDy (ours)", "#c44e52")]
    fig, ax = plt.subplots(figsize=(8.5, 4.8))
    x = np.arange(len(results))
    w = 0.2
    for i, (key, label, color) in enumerate(methods):
        vals = [getattr(r, key) for r in results]
        bars = ax.bar(x + (i - 1.5) * w, vals, w, label=label, color=color, edgecolor="black",
                      linewidth=0.6)
        for b, v in zip(bars, vals):
            ax.annotate(str(v), (b.get_x() + b.get_width() / 2, v), ha="center", va="bottom",
                        fontsize=9, xytext=(0, 2), textcoords="offset points")
    ax.set_yscale("log")
    ax.set_ylim(1, max(max(r.library, r.sindy, r.kronic) for r in results) * 3)
    ax.set_xticks(x, [TITLES.get(r.system, r.system) for r in results], fontsize=11)
    ax.set_ylabel("number of non-zero terms (log scale)", fontsize=11)
    ax.set_title("Model complexity (paper Fig. 3) — lower is sparser", fontsize=12)
    ax.legend(fontsize=9, ncol=2, loc="upper left", frameon=False)
    ax.grid(axis="y", which="major", alpha=0.3)
    fig.text(0.01, 0.01, "SINDy: terms summed over its acceleration equations (actuated run); "
             "KRONIC: passive run; ours: terms of the identified L (actuated run).",
             fontsize=7.5, color="#444444")
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    return _save(fig, path)


# ---------------------------------------------------------------------- Fig. 4
@dataclass
class Extrapolation:
    """Simulations of the true system, ours and SINDy from the training run's initial state."""

    system: str
    coords: list
    t: np.ndarray
    true: Rollout
    ours: Rollout
    sindy: Rollout
    sindy_terms: int
    errors: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        """JSON-able numbers; an error of ``null`` means the model diverged in that window."""
        errors = {k: (v if np.isfinite(v) else None) for k, v in self.errors.items()}
        return {"system": self.system, "sindy_terms": self.sindy_terms, **errors,
                "sindy_diverged_at": self.sindy.diverged_at, "ours_diverged_at": self.ours.diverged_at}


def _rms(d: np.ndarray) -> float:
    """RMS of a difference; ``inf`` when the model diverged inside the window (NaN samples)."""
    if not np.all(np.isfinite(d)):
        return float("inf")
    return float(np.sqrt(np.mean(d ** 2)))


def extrapolation(name: str, ours=None, t_train: float = T_TRAIN, t_end: float = T_END) -> Extrapolation:
    """Measure Fig. 4 for one system.

    Both models learn from the paper's passive run (``t_train`` s, no actuation; ours also from the
    0.1 s scale trial), then every model is simulated without actuation for ``t_end`` s.

    Parameters
    ----------
    ours : LagrangianSINDy, optional
        Our passive-scheme model (e.g. a Table I cell's); fitted here if omitted.
    """
    setup, system, features = _features(name)
    passive, _ = scheme_data(system, "passive")
    if abs(passive[0].t[-1] - t_train) > 1e-9:
        raise ValueError(f"the passive run lasts {passive[0].t[-1]} s, not t_train = {t_train} s")
    sindy = SINDyLasso(features, coords=system.coords, degree=setup.degree).fit(passive)
    ours = ours if ours is not None else run_cell(name, "passive").model
    t = np.arange(int(round(t_end / DT)) + 1) * DT
    x0 = np.asarray(system.x0, float)
    res = Extrapolation(name, list(system.coords), t, rollout(system.ode(), x0, t),
                        rollout(ours.ode(), x0, t), rollout(sindy.ode(), x0, t), sindy.n_nonzero_)
    n = len(system.coords)
    windows = {"train": t <= t_train + 1e-9, "extrap": t > t_train + 1e-9}
    for w, mask in windows.items():
        for who in ("ours", "sindy"):
            r = getattr(res, who)
            res.errors[f"rms_q_{w}_{who}"] = _rms(r.X[mask, :n] - res.true.X[mask, :n])
            res.errors[f"rms_qdd_{w}_{who}"] = _rms(r.Xdot[mask, n:] - res.true.Xdot[mask, n:])
    return res


def _limits(values, pad=0.25):
    lo, hi = float(np.nanmin(values)), float(np.nanmax(values))
    span = hi - lo or max(abs(hi), 1.0)
    return lo - pad * span, hi + pad * span


def fig4(results, path, t_train: float = T_TRAIN) -> Path:
    """Rows: accelerations of each coordinate, then phase portraits; one column per system."""
    plt = _pyplot()
    n_max = max(len(r.coords) for r in results)
    n_rows = 2 * n_max + 1
    fig, axes = plt.subplots(n_rows, len(results), figsize=(4.6 * len(results), 2.5 * n_rows + 0.6),
                             squeeze=False)
    styles = {"true": dict(color="black", lw=2.4, label="true"),
              "ours": dict(color="#c44e52", lw=1.5, ls="--", label="Lagrangian-SINDy (ours)"),
              "sindy": dict(color="#4c72b0", lw=1.3, ls=":", label="SINDy (Lasso)")}
    k_train = int(np.argmin(np.abs(results[0].t - t_train)))
    for j, r in enumerate(results):
        n = len(r.coords)
        axes[0, j].set_title(TITLES.get(r.system, r.system), fontsize=12)
        for i, c in enumerate(r.coords):
            ax = axes[i, j]                                         # acceleration vs time
            for who in ("true", "ours", "sindy"):
                ax.plot(r.t, getattr(r, who).Xdot[:, n + i], **styles[who])
            ax.set_ylim(*_limits(r.true.Xdot[:, n + i]))
            ax.axvline(t_train, color="gray", ls="-.", lw=1)
            ax.set_ylabel(f"${symbol_latex(c, 2)}$", fontsize=12)
            ax.set_xlabel("time (s)")
            ax.text(t_train - 0.08, 0.97, "training", transform=ax.get_xaxis_transform(),
                    ha="right", va="top", fontsize=8, color="gray")
            ax.text(t_train + 0.08, 0.97, "extrapolation", transform=ax.get_xaxis_transform(),
                    ha="left", va="top", fontsize=8, color="gray")
            _mark_divergence(ax, r.sindy, styles["sindy"]["color"])
            ax = axes[n + i, j]                                     # phase portrait
            for who in ("true", "ours", "sindy"):
                X = getattr(r, who).X
                ax.plot(X[:, i], X[:, n + i], **styles[who])
                if k_train < len(X) and np.isfinite(X[k_train, i]):
                    ax.plot(X[k_train, i], X[k_train, n + i], "o", ms=5, mfc="white",
                            mec=styles[who]["color"], mew=1.5)
            ax.set_xlim(*_limits(r.true.X[:, i], 0.1))
            ax.set_ylim(*_limits(r.true.X[:, n + i], 0.15))
            ax.set_xlabel(f"${symbol_latex(c)}$", fontsize=12)
            ax.set_ylabel(f"${symbol_latex(c, 1)}$", fontsize=12)
        for i in range(2 * n, 2 * n_max):
            axes[i, j].axis("off")
        ax = axes[-1, j]                                            # error of q over time
        floor = 1e-16
        for who in ("ours", "sindy"):
            d = getattr(r, who).X[:, :n] - r.true.X[:, :n]
            ax.semilogy(r.t, np.maximum(np.sqrt(np.mean(d ** 2, axis=1)), floor), **styles[who])
        ax.axvline(t_train, color="gray", ls="-.", lw=1)
        _mark_divergence(ax, r.sindy, styles["sindy"]["color"])
        ax.set_ylim(floor / 3, 1e2)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("RMS error of q", fontsize=10)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    handles.append(plt.Line2D([], [], color="gray", ls="-.", lw=1))
    labels.append(f"end of training (t = {t_train:g} s; ○ on phase portraits)")
    fig.suptitle("Simulation from the training run's initial state, no actuation (paper Fig. 4)",
                 fontsize=13)
    fig.tight_layout(rect=(0, 0, 1, 0.955))
    top = axes[0, 0].get_position().y1
    fig.legend(handles, labels, loc="lower center", bbox_to_anchor=(0.5, top + 0.012), ncol=4,
               fontsize=10, frameon=False)
    return _save(fig, path)


def _mark_divergence(ax, r: Rollout, color):
    if r.diverged_at is not None:
        ax.axvline(r.diverged_at, color=color, lw=0.8, alpha=0.6)
        ax.text(r.diverged_at, 0.05, f" SINDy diverges\n t = {r.diverged_at:.2f} s",
                transform=ax.get_xaxis_transform(), fontsize=8, color=color)


# ---------------------------------------------------------------------- report
def _fmt(v) -> str:
    return "diverged" if v == float("inf") else f"{v:.2e}"


def markdown(complexities, extrapolations) -> str:
    """The numbers behind Figs. 3 and 4 as Markdown tables."""
    lines = []
    if complexities:
        lines += ["Fig. 3 — number of non-zero terms (lower is sparser)", "",
                  "| system | library | SINDy (Lasso) | KRONIC | Lagrangian-SINDy |",
                  "|---|---|---|---|---|"]
        lines += [f"| {TITLES[c.system]} | {c.library} | {c.sindy} (of {c.sindy_candidates}) | "
                  f"{c.kronic} | {c.ours} |" for c in complexities]
    if extrapolations:
        lines += ["", "Fig. 4 — RMS error of the simulated coordinates q (rad or m) and accelerations "
                  "q̈, ours vs SINDy", "",
                  "| system | q, training 0–3 s | q, extrapolation 3–6 s | q̈, extrapolation 3–6 s "
                  "| SINDy diverges at |", "|---|---|---|---|---|"]
        for e in extrapolations:
            er = e.errors
            div = "—" if e.sindy.diverged_at is None else f"{e.sindy.diverged_at:.2f} s"
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
        worse = [k for k, v in rivals.items() if v <= c["ours"]]
        if worse:
            failed.append(f"{c['system']}: ours ({c['ours']} terms) is not sparser than "
                          + ", ".join(f"{k} ({rivals[k]})" for k in worse))
    for e in numbers.get("fig4", []):
        ours, sindy = e["rms_q_extrap_ours"], e["rms_q_extrap_sindy"]
        if ours is None or (sindy is not None and ours >= sindy):
            failed.append(f"{e['system']}: our extrapolation error ({ours}) is not below "
                          f"SINDy's ({'diverged' if sindy is None else sindy})")
    return failed


def make_figures(out_dir, cells=None, systems=("spherical", "double", "cart"), progress=None,
                 echo=None) -> list:
    """Measure and draw Figs. 3 and 4; write them and their numbers to ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Created if missing.
    cells : list of reproduce.Cell, optional
        Table I cells whose models to reuse (actuated ones for Fig. 3, passive for Fig. 4); the
        models are fitted here otherwise.
    systems : sequence of {"spherical", "double", "cart"}
    progress : callable(str), optional
        Told what is being computed (e.g. ``print`` to stderr).
    echo : callable(str), optional
        Receives the Markdown tables of the numbers (e.g. ``print``).

    Returns
    -------
    list of Path
        ``fig3_complexity.png``, ``fig4_extrapolation.png``, ``baselines.md``, ``baselines.json``.
    """
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
        comp.append(complexity(name, by_key.get((name, "actuated"))))
    for name in systems:
        say(f"Fig. 4: training and extrapolating the {TITLES[name]} ...")
        extra.append(extrapolation(name, by_key.get((name, "passive"))))
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [fig3(comp, out / "fig3_complexity.png"), fig4(extra, out / "fig4_extrapolation.png")]
    text = markdown(comp, extra)
    md = out / "baselines.md"
    md.write_text(text + "\n")
    js = out / "baselines.json"
    js.write_text(json.dumps({"fig3": [c.to_dict() for c in comp],
                              "fig4": [e.to_dict() for e in extra]}, indent=2))
    if echo:
        echo(text)
    return paths + [md, js]


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130)
    import matplotlib.pyplot as plt
    plt.close(fig)
    return path
