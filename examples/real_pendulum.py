"""A real pendulum: identify energy and friction from free swings, predict unseen swings.

Data: the MultiArm-Pendulum rig (Kaheman et al. 2022, MIT licence), a single arm swinging freely
from 1.6 rad down to 0.25 rad over 55 s, cut by its authors into 4 identification and 2 validation
pieces of ~9.2 s (``examples/data/real_pendulum/``, θ from the upward vertical: hanging is θ = π).
The authors' own grey-box fit, (m a² + I) θ̈ = m a g sin θ − k θ̇, is the model to beat.

Steps:

1. an initial estimate from the energy balance with dissipation, in its integral form over windows:
   Δ(Σ ξ_j H_j) + Σ r_j ∫ q̇·∂R_j/∂q̇ dt = 0 with H = ξ₁ θ̇² + ξ₂ cos θ, R = r₁ θ̇² + r₂ |θ̇|
   (viscous and Coulomb joint friction).  No power is fed in, so the energy is fixed only up to a
   factor: the normalisation here is ξ₁ = 1/2 (H is energy per unit moment of inertia, s⁻²);
2. prediction-error refinement (``lsindy_cas.identify.refine``): the same terms, the coefficients
   that minimise the simulation error over the 4 identification pieces (multiple shooting);
3. each validation piece is predicted from its first sample over its whole length, by our model
   and by the authors'; RMS angle errors at 1 s, 3 s and to the end.

Run:  python examples/real_pendulum.py [--out DIR] [--quick] [--offset]
(``--offset`` adds sin θ to H: a sensor zero that is not exactly at the upright.)
"""
import argparse
import json
import time
from pathlib import Path

import numpy as np

from lsindy_cas import Library, Trajectory, load_trajectories
from lsindy_cas.identify.refine import predict, refine
from lsindy_cas.mechanics.legendre import legendre
from lsindy_cas.mechanics.parametric import ParametricDynamics

DATA = Path(__file__).resolve().parent / "data" / "real_pendulum"
COORDS = ["theta"]
KINETIC = "theta_dot**2"                       # its coefficient in H is fixed to 1/2
DISSIPATION = ["theta_dot**2", "Abs(theta_dot)"]
HORIZONS = (1.0, 3.0, None)                     # RMS over the first 1 s, 3 s, whole piece


def load(quick=False):
    """The 4 identification and 2 validation pieces (``quick``: their first 2 s and 3 s)."""
    ids = load_trajectories([DATA / f"id{i}.csv" for i in range(1, 5)], COORDS)
    vals = load_trajectories([DATA / f"val{i}.csv" for i in range(1, 3)], COORDS)
    if quick:
        ids, vals = [_head(tr, 2.0) for tr in ids], [_head(tr, 3.0) for tr in vals]
    return ids, vals


def _head(tr, seconds):
    keep = tr.t <= tr.t[0] + seconds + 1e-9
    return Trajectory(tr.t[keep], tr.q[keep], tr.qd[keep], tr.coords, source=tr.source)


def energy_balance_estimate(trajectories, energy_terms, dissipation, window=0.5):
    """Initial estimate: least squares on the integral energy balance with dissipation.

    A stand-in, marked as such, until the engine's dissipation is merged: swap this function for
    ``LagrangianSINDy(Library(COORDS, energy_terms), dissipation=dissipation).fit(trajectories,
    passive=True)`` and read its H and R coefficients.

    Rows: for windows [a, b] of ``window`` seconds (half overlapping),
    Σ_j ξ_j ΔH_j + Σ_j r_j ∫_a^b q̇·∂R_j/∂q̇ dt = 0, with ξ of ``KINETIC`` fixed to 1/2.

    Returns
    -------
    coef_h : array (len(energy_terms),)
        H's coefficients.
    coef_r : array (len(dissipation),)
        R's coefficients as fitted (a negative one would create energy).
    """
    library = Library(COORDS, energy_terms)
    fixed = library.index(KINETIC)
    unit = ParametricDynamics(COORDS, [KINETIC], dissipation).friction()
    A, b = [], []
    for tr in trajectories:
        n_win = max(1, int(round(window / (tr.t[1] - tr.t[0]))))
        H = library.theta(tr.X)
        power = np.column_stack([                      # q̇·∂R_j/∂q̇ per term (unit coefficient)
            -np.sum(np.asarray(unit.map(tr.n_samples)(tr.X.T, np.eye(1 + len(dissipation))[j + 1])).T
                    * tr.qd, axis=1) for j in range(len(dissipation))])
        work = np.vstack([np.zeros(len(dissipation)), np.cumsum(
            0.5 * (power[1:] + power[:-1]) * np.diff(tr.t)[:, None], axis=0)])
        cols = np.column_stack([H, work])
        start = np.arange(0, tr.n_samples - n_win, max(1, n_win // 2))
        rows = cols[start + n_win] - cols[start]
        A.append(np.delete(rows, fixed, axis=1))
        b.append(-0.5 * rows[:, fixed])
    sol = np.linalg.lstsq(np.vstack(A), np.concatenate(b), rcond=None)[0]
    coef_h = np.insert(sol[:len(energy_terms) - 1], fixed, 0.5)
    return coef_h, sol[len(energy_terms) - 1:]


def authors_model():
    """The authors' grey-box fit as (terms of L, terms of R, coefficients), same normalisation."""
    fit = json.loads((DATA / "authors_fit.json").read_text())["parameters"]
    inertia = fit["m1"] * fit["a1"] ** 2 + fit["I1"]
    # θ̈ = (m a g / J) sin θ − (k / J) θ̇  <=>  L = ½θ̇² − (m a g / J) cos θ, R = (k / 2J) θ̇²
    return (["theta_dot**2", "cos(theta)"], ["theta_dot**2"],
            np.array([0.5, -fit["m1"] * fit["a1"] * fit["g"] / inertia, fit["k1"] / (2 * inertia)]))


def rms_table(dynamics, coef, pieces):
    """RMS angle error (rad) per piece at each horizon, and the predicted angles."""
    table, angles = [], []
    for tr in pieces:
        theta = predict(dynamics, coef, tr.X[0], tr.t, steps=4)[:, 0]
        err = theta - tr.q[:, 0]
        table.append([float(np.sqrt(np.mean(err[tr.t - tr.t[0] <= (h or np.inf) + 1e-9] ** 2)))
                      for h in HORIZONS])
        angles.append(theta)
    return table, angles


def main(out_dir=None, quick=False, offset=False, verbose=True):
    """Identify, refine, validate; return the results dictionary (also written as JSON)."""
    started = time.perf_counter()
    ids, vals = load(quick)
    energy = [KINETIC, "cos(theta)"] + (["sin(theta)"] if offset else [])
    coef_h, coef_r = energy_balance_estimate(ids, energy, DISSIPATION)
    coef_l = legendre(Library(COORDS, energy), coef_h)
    p0 = np.concatenate([coef_l, np.maximum(coef_r, 0.0)])   # start admissible: no friction < 0
    t_init = time.perf_counter() - started
    fit = refine(COORDS, energy, p0, ids, DISSIPATION, fixed=KINETIC, interval=0.25, steps=2)
    ours = ParametricDynamics(COORDS, energy, DISSIPATION)
    a_terms, a_diss, a_coef = authors_model()
    theirs = ParametricDynamics(COORDS, a_terms, a_diss)
    rms_ours, pred_ours = rms_table(ours, fit.coef, vals)
    rms_theirs, pred_theirs = rms_table(theirs, a_coef, vals)
    results = {
        "normalisation": "H = 1/2 theta_dot**2 + ... (energy per unit moment of inertia, 1/s^2)",
        "energy_balance": {"hamiltonian_terms": dict(zip(energy, coef_h.tolist())),
                           "rayleigh_terms": dict(zip(DISSIPATION, coef_r.tolist()))},
        "refined": {"lagrangian_terms": fit.lagrangian_terms(), "rayleigh_terms": fit.rayleigh_terms(),
                    "status": fit.status, "iterations": fit.iterations,
                    "train_rms_before": fit.rms_initial, "train_rms_after": fit.rms},
        "authors": {"lagrangian_terms": dict(zip(a_terms, a_coef[:2].tolist())),
                    "rayleigh_terms": {a_diss[0]: float(a_coef[2])}},
        "rms": {f"val{i + 1}": {"horizons_s": [h or float(tr.t[-1] - tr.t[0]) for h in HORIZONS],
                                "ours": rms_ours[i], "authors": rms_theirs[i]}
                for i, tr in enumerate(vals)},
        "seconds": {"initial_estimate": t_init, "refinement": fit.seconds,
                    "total": time.perf_counter() - started},
        "quick": quick, "offset": offset,
    }
    if verbose:
        _print(results, fit)
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        (out / "real_pendulum.json").write_text(json.dumps(results, indent=2) + "\n")
        _figure(out / "real_pendulum.png", vals, pred_ours, pred_theirs)
    return results


def _print(results, fit):
    print("energy balance (start):", {k: round(v, 5) for k, v in
                                      {**results["energy_balance"]["hamiltonian_terms"],
                                       **{"R:" + k: v for k, v in
                                          results["energy_balance"]["rayleigh_terms"].items()}}.items()})
    print(f"refined ({fit.status}, {fit.iterations} it, {fit.seconds:.1f} s): L =",
          {k: round(v, 5) for k, v in fit.lagrangian_terms().items()},
          " R =", {k: round(v, 6) for k, v in fit.rayleigh_terms().items()})
    print(f"training RMS angle error {fit.rms_initial:.2e} -> {fit.rms:.2e} rad")
    print("\nRMS angle error (rad), prediction from the first sample")
    print(f"{'piece':<6}{'model':<9}{'1 s':>10}{'3 s':>10}{'end':>10}")
    for piece, row in results["rms"].items():
        for who in ("ours", "authors"):
            print(f"{piece:<6}{who:<9}" + "".join(f"{v:>10.2e}" for v in row[who]))


def _figure(path, vals, pred_ours, pred_theirs):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, len(vals), figsize=(6 * len(vals), 6), sharex="col",
                             gridspec_kw={"height_ratios": [2, 1]}, squeeze=False)
    for i, tr in enumerate(vals):
        t = tr.t - tr.t[0]
        top, bottom = axes[0, i], axes[1, i]
        top.plot(t, tr.q[:, 0], "k", lw=2.5, alpha=0.35, label="data")
        top.plot(t, pred_ours[i], "C0", lw=1, label="ours (energy balance + refinement)")
        top.plot(t, pred_theirs[i], "C3--", lw=1, label="authors' grey-box fit")
        top.set_ylabel("θ (rad)")
        top.set_title(f"validation piece {i + 1}: predicted from its first sample")
        bottom.plot(t, pred_ours[i] - tr.q[:, 0], "C0", lw=1, label="ours")
        bottom.plot(t, pred_theirs[i] - tr.q[:, 0], "C3--", lw=1, label="authors'")
        bottom.set_ylabel("error (rad)")
        bottom.set_xlabel("time (s)")
        top.legend(loc="upper right", fontsize=8)
        bottom.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="folder for real_pendulum.json and real_pendulum.png")
    parser.add_argument("--quick", action="store_true", help="first 2 s / 3 s of each piece only")
    parser.add_argument("--offset", action="store_true", help="add sin(theta) to H (sensor zero)")
    args = parser.parse_args()
    main(args.out, quick=args.quick, offset=args.offset)
