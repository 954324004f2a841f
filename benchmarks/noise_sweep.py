"""Noise sweep: success rate of identification vs. measurement noise, paper-style vs. ours.

For each benchmark system (spherical, double, cart-pendulum; the libraries and prior terms of
``reproduce.PAPER_SETUPS``), each protocol and each noise level σ, ``--seeds`` noisy data sets are
identified and counted as a success when the support is exact AND every coefficient is within 5 %
of the truth (the exact-support rate is reported too).  Noise: additive Gaussian, absolute σ, on
every q and q̇ column.

Protocols
  paper  one 1 s run from the paper's initial state, constant input u = 1 (the paper's data)
  rich   10 runs × 5 s from random initial states, input held piecewise constant at random levels
         for random 0.2–1 s stretches (spherical pendulum: the level is flipped when it would drive
         |p_φ| below 1, keeping the runs away from the coordinate pole)

Methods
  paper  derivative form Γξ = P with accelerations by finite differences of the noisy q̇ (what the
         paper's method has to do without exact accelerations), k given
  raw     ours without denoising: integral form, noise estimated, errors-in-variables correction,
          k chosen automatically
  balance ours with the energy balance alone (``refinement="never"``)
  ours    the default of LagrangianSINDy: denoising (likelihood-chosen smoothing), k chosen
          automatically, and the prediction-error refinement where the balance leaves only a
          coefficient open (``refinement="auto"``; kept when the refined fit is determined)
  ours_k  ours with k given (separates support errors from k-selection errors)
  refined ours, refined by prediction error on every fit (``refinement="always"``)

Usage::

    python benchmarks/noise_sweep.py                          # full: 10 seeds, 8 levels, ~1 h on 2 cores
    python benchmarks/noise_sweep.py --seeds 2 --levels 0,1e-3 --systems cart --protocols paper
"""
from __future__ import annotations

import os

# one BLAS thread per worker process: the parallelism is over runs (set before numpy loads)
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from lsindy_cas import LagrangianSINDy, systems  # noqa: E402
from lsindy_cas.symbolic.library import Library  # noqa: E402
from lsindy_cas.paper.table1 import PAPER_SETUPS, compare  # noqa: E402
from lsindy_cas.data.smoothing import add_noise, finite_difference  # noqa: E402

LEVELS = (0.0, 1e-8, 1e-6, 1e-4, 1e-3, 1e-2, 5e-2, 1e-1)
SYSTEMS = ("spherical", "double", "cart")
PROTOCOLS = ("paper", "rich")
METHODS = ("paper", "raw", "balance", "ours", "ours_k", "refined")
TOL = 0.05
# Rich protocol: input amplitude per system (N or N·m) — an experiment design choice, not a
# method parameter: enough to move each system well without flinging it around.
AMPLITUDE = {"spherical": 0.5, "double": 5.0, "cart": 2.0}
RESULTS = Path(__file__).resolve().parent / "results"              # JSON and Markdown
FIGURES = Path(__file__).resolve().parents[1] / "docs" / "results"  # the images the README shows


def rich_runs(name: str, system, rng: np.random.Generator, n_runs: int = 10, t_end: float = 5.0):
    """Random initial states and random held input levels (see the module notes)."""
    runs = []
    n = len(system.coords)
    for _ in range(n_runs):
        x0 = np.array(system.x0, float)
        x0[:n] += rng.uniform(-0.5, 0.5, n)
        x0[n:] = rng.uniform(-1.0, 1.0, n)
        switch = np.cumsum(rng.uniform(0.2, 1.0, int(t_end / 0.2) + 2))
        level = rng.uniform(-1.0, 1.0, len(switch) + 1) * AMPLITUDE[name]
        if name == "spherical":
            x0[n + 1] = rng.choice([-1.0, 1.0]) * rng.uniform(1.5, 2.5) / np.sin(x0[0]) ** 2

            def u(t, x, switch=switch, level=level):
                v = level[np.searchsorted(switch, t)]
                p_phi = np.sin(x[0]) ** 2 * x[3]
                return -v if abs(p_phi) < 1.0 and v * p_phi < 0 else v
        else:
            def u(t, x, switch=switch, level=level):
                return level[np.searchsorted(switch, t)]
        runs.append(system.simulate(x0=x0, t_end=t_end, u=u))
    return runs


def clean_data(name: str, protocol: str, seed: int):
    system = systems.PAPER_SYSTEMS[name]()
    if protocol == "paper":
        return system, [system.simulate(t_end=1.0, u=1.0)]
    return system, rich_runs(name, system, np.random.default_rng(1000 + seed))


def run_one(job):
    """One (system, protocol, σ, seed): every method on the same noisy data."""
    name, protocol, sigma, seed, methods = job
    setup = PAPER_SETUPS[name]
    system, clean = clean_data(name, protocol, seed)
    lib = Library.polynomial(system.coords, setup.features, setup.degree)
    truth = lib.coefficients(system.hamiltonian)
    rng = np.random.default_rng([seed, int(round(-np.log10(sigma) * 10)) if sigma > 0 else 999])
    noisy = [add_noise(tr, sigma, rng) for tr in clean]
    out = []
    for method in methods:
        t0 = time.perf_counter()
        try:
            model = _fit(method, lib, setup, noisy)
            exact, err = compare(model.coef_, truth)
            k, status, reasons = model.n_terms_, model.status_, model.status_reasons_
            checks = getattr(model.diagnostics_, "checks", None) or {}
            rel_std = {key: checks.get(key) for key in ("propagated_relative_std",
                                                        "largest_relative_std")}
            coef_errors = _coef_errors(model, truth) if exact else None
        except ValueError as exc:
            exact, err, k, status, reasons = False, float("inf"), None, "refused", [str(exc)]
            rel_std, coef_errors = {}, None
            print(f"  {name}/{protocol}/σ={sigma:g}/seed {seed}/{method}: {exc}", file=sys.stderr)
        out.append({"system": name, "protocol": protocol, "sigma": sigma, "seed": seed,
                    "method": method, "exact_support": exact, "max_rel_error": err, "k": k,
                    "k_true": setup.n_terms, "status": status, "status_reasons": reasons,
                    "success": bool(exact and err <= TOL), "seconds": time.perf_counter() - t0,
                    # the coefficients are the prediction-error refinement's: automatically
                    # ("auto") or on request ("always"); "tried": automatic refinement did not
                    # settle the fit, the balance's kept; None: not refined
                    "refined": _refined(model) if status != "refused" else None,
                    # the status's relative standard errors: propagated (noise model with the
                    # rows' correlations) and jackknife; None where not computed
                    "relative_std": rel_std,
                    # per true term: relative error and relative standard error of the model's
                    # own coef_std_ (refined: Gauss-Newton; otherwise the jackknife)
                    "coef_errors": coef_errors})
    return out


def _refined(model):
    """"auto"/"always": the coefficients are the refinement's; "tried": automatic refinement
    tried, the balance's fit kept; None: no refinement."""
    from lsindy_cas.identify.refine import current_refinement
    info = current_refinement(model)
    if info is None:
        return None
    if not info["applied"]:
        return "tried" if info.get("auto") else None
    return "auto" if info.get("auto") else "always"


def _coef_errors(model, truth):
    S = np.flatnonzero(truth)
    std = getattr(model, "coef_std_", None)
    rel = (model.coef_[S] - truth[S]) / np.abs(truth[S])
    out = {"error": rel.tolist(), "std": None, "std_method": getattr(model, "std_method_", None)}
    if std is not None:
        out["std"] = (np.asarray(std)[S] / np.abs(truth[S])).tolist()
    return out


def _fit(method, lib, setup, noisy):
    if method == "paper":
        data = [finite_difference(tr) for tr in noisy]
        return LagrangianSINDy(lib, n_terms=setup.n_terms, prior=setup.prior,
                               form="derivative").fit(data)
    refinement = {"balance": "never", "refined": "always"}.get(method, "auto")
    k = setup.n_terms if method == "ours_k" else None
    smoothing = "none" if method == "raw" else "auto"
    return LagrangianSINDy(lib, n_terms=k, prior=setup.prior, smoothing=smoothing,
                           refinement=refinement).fit(noisy)


def summarise(rows):
    """{(system, protocol, method, σ): (successes, exact supports, n)}."""
    table = {}
    for r in rows:
        key = (r["system"], r["protocol"], r["method"], r["sigma"])
        s, e, n = table.get(key, (0, 0, 0))
        table[key] = (s + r["success"], e + r["exact_support"], n + 1)
    return table


TOL_EXACT = 0.01      # a "false alarm" proper: a fit within 1 % that is not "ok"


def status_counts(rows, method=None) -> dict:
    """The fit status against the outcome, over the methods with a status (not "paper"), or one.

    ``false_alarms``: successes (exact support, coefficients within TOL) with status
    "undetermined"; ``false_alarms_1pct``: the same among fits within ``TOL_EXACT``;
    ``silent_failures``: failures with status "ok"; "refused" fits (no model) are neither.
    Refined fits carry the verdict on their own standard errors (``refine``).
    """
    rows = [r for r in rows if r["method"] != "paper" and r.get("status") is not None
            and method in (None, r["method"])]
    passing = [r for r in rows if r["success"]]
    close = [r for r in passing if r["max_rel_error"] <= TOL_EXACT]
    failing = [r for r in rows if not r["success"] and r["status"] != "refused"]
    return {"passing": len(passing),
            "false_alarms": sum(r["status"] != "ok" for r in passing),
            "within_1pct": len(close),
            "false_alarms_1pct": sum(r["status"] != "ok" for r in close),
            "failing": len(failing),
            "silent_failures": sum(r["status"] == "ok" for r in failing),
            "refused": sum(r["status"] == "refused" for r in rows)}


def calibration(rows, method) -> tuple:
    """(fraction of |error| ≤ 1 std, number of coefficients) over the exact fits of ``method``."""
    hits = [abs(e) <= s for r in rows if r["method"] == method and r.get("coef_errors")
            and r["coef_errors"]["std"] is not None
            for e, s in zip(r["coef_errors"]["error"], r["coef_errors"]["std"])]
    return (float(np.mean(hits)) if hits else float("nan")), len(hits)


def status_lines(rows) -> list:
    """Markdown lines: the status counts per method, then each false alarm and silent failure."""
    lines = ["", "Fit status: 'false alarm' = exact support and every coefficient within 5 % "
             "(within 1 %) but 'undetermined'; 'silent failure' = not within 5 % but 'ok'.", "",
             "| method | ok / fits | false alarms (5 %) | false alarms (1 %) | silent failures | "
             "refused | |error| ≤ 1 std (coef_std_) |", "|---|---|---|---|---|---|---|"]
    for method in METHODS[1:]:
        c = status_counts(rows, method)
        n = sum(r["method"] == method for r in rows)
        if not n:
            continue
        ok = sum(r["method"] == method and r["status"] == "ok" for r in rows)
        frac, m = calibration(rows, method)
        cal = f"{100 * frac:.0f} % of {m}" if m else ""
        lines.append(f"| {method} | {ok}/{n} | {c['false_alarms']} of {c['passing']} | "
                     f"{c['false_alarms_1pct']} of {c['within_1pct']} | {c['silent_failures']} of "
                     f"{c['failing']} | {c['refused']} | {cal} |")
    lines += ["", "Seconds per fit (identification only); 'refined': fits whose coefficients are "
              "the prediction-error refinement's; 'tried': automatic refinement that left the "
              "fit undetermined (the balance's fit kept).", "",
              "| method | median s | max s | refined | tried |", "|---|---|---|---|---|"]
    for method in METHODS:
        mine = [r for r in rows if r["method"] == method]
        if mine:
            sec = [r["seconds"] for r in mine]
            n_ref = sum(r.get("refined") in ("auto", "always") for r in mine)
            n_tried = sum(r.get("refined") == "tried" for r in mine)
            lines.append(f"| {method} | {np.median(sec):.2f} | {max(sec):.2f} | "
                         f"{n_ref}/{len(sec)} | {n_tried} |")
    lines.append("")
    for r in rows:
        if r["method"] == "paper" or r.get("status") in (None, "refused"):
            continue
        if r["success"] == (r["status"] == "ok"):
            continue
        what = "false alarm" if r["success"] else "silent failure"
        why = "; ".join(r.get("status_reasons") or [])[:140]
        lines.append(f"- {what}: {r['system']}/{r['protocol']}/σ={r['sigma']:g}/seed {r['seed']}/"
                     f"{r['method']} (error {r['max_rel_error']:.1e}) {why}")
    return lines


def markdown(rows, levels) -> str:
    table = summarise(rows)
    keys = sorted({k[:3] for k in table}, key=lambda k: (SYSTEMS.index(k[0]), PROTOCOLS.index(k[1]),
                                                        METHODS.index(k[2])))
    head = "| system | protocol | method | " + " | ".join(f"σ={s:g}" for s in levels) + " |"
    lines = ["Success = exact support and every coefficient within 5 % "
             "(in brackets: exact support only), out of the number of seeds.", "",
             head, "|" + "---|" * (3 + len(levels))]
    ks = {}
    for r in rows:
        if r["method"] in ("raw", "balance", "ours"):
            key = (r["system"], r["protocol"], r["method"], r["sigma"])
            hit, n = ks.get(key, (0, 0))
            ks[key] = (hit + (r["k"] == r["k_true"]), n + 1)
    for k in keys:
        cells = []
        for s in levels:
            if (*k, s) in table:
                ok, ex, n = table[(*k, s)]
                cells.append(f"{ok}/{n} ({ex})")
            else:
                cells.append("")
        lines.append(f"| {k[0]} | {k[1]} | {k[2]} | " + " | ".join(cells) + " |")
    lines += ["", "Automatic k (methods raw, balance, ours): runs in which the chosen k is the true "
              "one.", "",
              head, "|" + "---|" * (3 + len(levels))]
    for k in keys:
        if k[2] in ("raw", "balance", "ours"):
            cells = [f"{ks[(*k, s)][0]}/{ks[(*k, s)][1]}" if (*k, s) in ks else "" for s in levels]
            lines.append(f"| {k[0]} | {k[1]} | {k[2]} | " + " | ".join(cells) + " |")
    return "\n".join(lines + status_lines(rows))


def plot(rows, levels, path: Path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    table = summarise(rows)
    systems_ = [s for s in SYSTEMS if any(k[0] == s for k in table)]
    protocols = [p for p in PROTOCOLS if any(k[1] == p for k in table)]
    fig, axes = plt.subplots(len(protocols), len(systems_), figsize=(4 * len(systems_), 3.2 * len(protocols)),
                             squeeze=False, sharey=True)
    x = np.arange(len(levels))
    colours = dict(zip(METHODS, ("tab:gray", "tab:orange", "tab:cyan", "tab:blue", "tab:green",
                                 "tab:purple")))
    for i, prot in enumerate(protocols):
        for j, name in enumerate(systems_):
            ax = axes[i, j]
            for m, method in enumerate(METHODS):
                cells = [table.get((name, prot, method, s)) for s in levels]
                if all(c is None for c in cells):
                    continue
                off = 0.012 * (m - 1.5)          # keep coinciding lines apart
                ok = [np.nan if c is None else c[0] / c[2] + off for c in cells]
                ex = [np.nan if c is None else c[1] / c[2] + off for c in cells]
                ax.plot(x, ok, marker="o", ms=4, color=colours[method], label=f"{method}: success")
                ax.plot(x, ex, ls="--", lw=1, color=colours[method], label=f"{method}: exact support")
            ax.set_xticks(x, [f"{s:g}" for s in levels], rotation=45, fontsize=7)
            ax.set_title(f"{name}, {prot} protocol", fontsize=9)
            ax.set_ylim(-0.05, 1.05)
            if j == 0:
                ax.set_ylabel("success rate")
            if i == len(protocols) - 1:
                ax.set_xlabel("noise σ")
    axes[0, 0].legend(fontsize=6, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=10, help="noisy data sets per cell (default 10)")
    p.add_argument("--levels", default=",".join(f"{s:g}" for s in LEVELS), help="noise σ list")
    p.add_argument("--systems", default=",".join(SYSTEMS))
    p.add_argument("--protocols", default=",".join(PROTOCOLS))
    p.add_argument("--methods", default="paper,raw,ours,ours_k")
    p.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    p.add_argument("--out", default=str(RESULTS), help="output directory")
    p.add_argument("--figures", default=str(FIGURES),
                   help="directory of the PNG (default docs/results, where the README's images are)")
    p.add_argument("--name", default="noise_sweep", help="output file stem")
    args = p.parse_args(argv)
    levels = [float(s) for s in args.levels.split(",")]
    names = args.systems.split(",")
    protocols = args.protocols.split(",")
    methods = args.methods.split(",")
    for v, allowed, what in ((names, SYSTEMS, "systems"), (protocols, PROTOCOLS, "protocols"),
                             (methods, METHODS, "methods")):
        bad = set(v) - set(allowed)
        if bad:
            p.error(f"unknown {what}: {', '.join(sorted(bad))} (choose from {', '.join(allowed)})")
    if args.seeds < 1 or any(s < 0 for s in levels):
        p.error("--seeds must be ≥ 1 and noise levels ≥ 0")
    jobs = [(n, pr, s, seed, methods) for n in names for pr in protocols for s in levels
            for seed in range(args.seeds)]
    jobs.sort(key=lambda j: (j[0] != "double", j[1] != "rich"))      # longest first
    t0 = time.perf_counter()
    rows = []
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for i, res in enumerate(pool.map(run_one, jobs, chunksize=1)):
            rows += res
            if (i + 1) % max(1, len(jobs) // 20) == 0:
                print(f"{i + 1}/{len(jobs)} jobs, {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    md = markdown(rows, levels)
    print(md)
    (out / f"{args.name}.md").write_text(md + "\n")
    (out / f"{args.name}.json").write_text(json.dumps(
        {"levels": levels, "seeds": args.seeds, "tolerance": TOL, "seconds": time.perf_counter() - t0,
         "status": status_counts(rows),
         "status_by_method": {m: status_counts(rows, m) for m in methods if m != "paper"},
         "rows": rows}, indent=1, default=float))
    figures = Path(args.figures)
    figures.mkdir(parents=True, exist_ok=True)
    plot(rows, levels, figures / f"{args.name}.png")
    print(f"\nwritten to {out / args.name}.{{md,json}} and {figures / args.name}.png in "
          f"{time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
