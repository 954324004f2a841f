"""Drawing of the paper's comparison figures (Figs. 3 and 4); matplotlib only.

The numbers come from :mod:`~lsindy_cas.paper.comparison`: :func:`fig3` draws its
:class:`~lsindy_cas.paper.comparison.Complexity` results, :func:`fig4` its
:class:`~lsindy_cas.paper.comparison.Extrapolation` results.  :func:`make_figures` runs the
experiments, writes ``fig3_complexity.png``, ``fig4_extrapolation.png`` and the numbers
(``baselines.md``, ``baselines.json``); ``lsindy reproduce --out DIR`` calls it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..printing import symbol_latex
from .baselines import Rollout
from .comparison import T_TRAIN, TITLES, measure, write_numbers

__all__ = ["fig3", "fig4", "make_figures"]


def fig3(results, path) -> Path:
    """Grouped bars, log scale: library / SINDy / KRONIC / ours for each system."""
    plt = _pyplot()
    methods = [("library", "library (candidates)", "#bbbbbb"), ("sindy", "SINDy (Lasso)", "#4c72b0"),
               ("kronic", "KRONIC", "#55a868"), ("ours", "Lagrangian-SINDy (ours)", "#c44e52")]
    if all(r.sindy is None for r in results):        # SINDy skipped (pysindy missing)
        methods = [m for m in methods if m[0] != "sindy"]
    fig, ax = plt.subplots(figsize=(8.5, 4.8))
    x = np.arange(len(results))
    w = 0.8 / len(methods)
    for i, (key, label, color) in enumerate(methods):
        vals = [getattr(r, key) for r in results]
        bars = ax.bar(x + (i - (len(methods) - 1) / 2) * w, vals, w, label=label, color=color, edgecolor="black",
                      linewidth=0.6)
        for b, v in zip(bars, vals):
            ax.annotate(str(v), (b.get_x() + b.get_width() / 2, v), ha="center", va="bottom",
                        fontsize=9, xytext=(0, 2), textcoords="offset points")
    ax.set_yscale("log")
    ax.set_ylim(1, max(max(r.library, r.sindy or 0, r.kronic) for r in results) * 3)
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
    who_all = ("true", "ours", "sindy") if all(r.sindy is not None for r in results) else ("true", "ours")
    for j, r in enumerate(results):
        n = len(r.coords)
        axes[0, j].set_title(TITLES.get(r.system, r.system), fontsize=12)
        for i, c in enumerate(r.coords):
            ax = axes[i, j]                                         # acceleration vs time
            for who in who_all:
                ax.plot(r.t, getattr(r, who).Xdot[:, n + i], **styles[who])
            ax.set_ylim(*_limits(r.true.Xdot[:, n + i]))
            ax.axvline(t_train, color="gray", ls="-.", lw=1)
            ax.set_ylabel(f"${symbol_latex(c, 2)}$", fontsize=12)
            ax.set_xlabel("time (s)")
            ax.text(t_train - 0.08, 0.97, "training", transform=ax.get_xaxis_transform(),
                    ha="right", va="top", fontsize=8, color="gray")
            ax.text(t_train + 0.08, 0.97, "extrapolation", transform=ax.get_xaxis_transform(),
                    ha="left", va="top", fontsize=8, color="gray")
            if r.sindy is not None:
                _mark_divergence(ax, r.sindy, styles["sindy"]["color"])
            ax = axes[n + i, j]                                     # phase portrait
            for who in who_all:
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
        for who in who_all[1:]:
            d = getattr(r, who).X[:, :n] - r.true.X[:, :n]
            ax.semilogy(r.t, np.maximum(np.sqrt(np.mean(d ** 2, axis=1)), floor), **styles[who])
        ax.axvline(t_train, color="gray", ls="-.", lw=1)
        if r.sindy is not None:
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


def make_figures(out_dir, cells=None, systems=("spherical", "double", "cart"), progress=None,
                 echo=None, sindy=True) -> list:
    """Measure (:func:`~lsindy_cas.paper.comparison.measure`) and draw Figs. 3 and 4; write them
    and their numbers to ``out_dir``.

    Parameters
    ----------
    out_dir : path
        Created if missing.
    cells : list of table1.Cell, optional
        Table I cells whose models to reuse (actuated ones for Fig. 3, passive for Fig. 4); the
        models are fitted here otherwise.
    systems : sequence of {"spherical", "double", "cart"}
    progress : callable(str), optional
        Told what is being computed (e.g. ``print`` to stderr).
    echo : callable(str), optional
        Receives the Markdown tables of the numbers (e.g. ``print``).
    sindy : bool or None
        Include the SINDy baseline (needs pysindy; None: when installed).  Without it the
        figures show the library, KRONIC and our model only.

    Returns
    -------
    list of Path
        ``fig3_complexity.png``, ``fig4_extrapolation.png``, ``baselines.md``, ``baselines.json``.
    """
    comp, extra = measure(systems, cells, progress, sindy=sindy)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [fig3(comp, out / "fig3_complexity.png"), fig4(extra, out / "fig4_extrapolation.png")]
    md, js, text = write_numbers(comp, extra, out)
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
