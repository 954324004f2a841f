"""MuJoCo's dry friction (``frictionloss``) against the Coulomb term |ẋ| of our Rayleigh library.

The plant: the damped cart-pendulum of ``tests/test_mujoco.py`` (cart 0.8 kg, pole 0.2 kg at 0.7 m,
joint damping 0.5 / 0.02 N·s) plus MuJoCo ``frictionloss`` μ on the cart, driven by a held
multisine (3 N, changing every sample, 100 Hz, 3 runs × 2 s).  Identified with the energy library
of the tests and the dissipation candidates ẋ², θ̇², |ẋ|, no accelerations (integral form).

MuJoCo solves dry friction as a soft box constraint (``lsindy_cas.plants.mujoco``): sliding, its
force is exactly μ but its sign is that of v + a₀/b (b = 2/(0.95·timeconst)), so it switches a
little before or after the velocity does; sticking, |f| < μ and the cart creeps.  Per case the
table gives, from MuJoCo's own constraint force f at every 1 ms step:

* ``stick``: share of the time with |f| < 0.999 μ;
* ``wrong sign``: share of the time with f·v > 0 (friction pushing along the motion);
* ``work err``: (∫μ|v| dt − ∫(−f v) dt) / ∫(−f v) dt, how far the Coulomb model's dissipated work
  is from MuJoCo's;

and from the identification: status, the largest relative error of the energy coefficients, of
each dissipation coefficient (damping b_x/2, b_θ/2 and μ), and the identified H against MuJoCo's
energy (max deviation / range).  Cases: μ ∈ {0.3, 1, 2} N at MuJoCo's default time constant
(0.02 s) and at 0.005 s and 0.002 s (two timesteps, the sharpest MuJoCo allows).

    python benchmarks/bench_mujoco_friction.py --out DIR [--quick]

``--quick``: μ = 2 only.  Writes ``mujoco_friction.json`` and ``mujoco_friction.md`` to DIR.
"""
from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import json
import time
from pathlib import Path

import numpy as np

from lsindy_cas import LagrangianSINDy, Library

MC, MP, L, G = 0.8, 0.2, 0.7, 9.81
DAMPING = (0.5, 0.02)
FEATURES = ["cos(theta)", "sin(theta)", "theta_dot", "x", "x_dot"]
DISSIPATION = ["x_dot**2", "theta_dot**2", "Abs(x_dot)"]
TRUE_H = {"x_dot**2": (MC + MP) / 2, "theta_dot**2": MP * L ** 2 / 2,
          "theta_dot*x_dot*cos(theta)": MP * L, "cos(theta)": -MP * G * L}


def multisine(n, dt, amp, rng):
    t = np.arange(n) * dt
    f, ph = rng.uniform(0.2, 2.0, 4), rng.uniform(0, 2 * np.pi, 4)
    return amp * sum(np.sin(2 * np.pi * fi * t + p) for fi, p in zip(f, ph)) / 2


def plant_for(mu, timeconst):
    from lsindy_cas.plants import mujoco as pm
    return pm.cart_pendulum(MC, MP, L, cart_damping=DAMPING[0], pivot_damping=DAMPING[1],
                            cart_frictionloss=mu, friction_timeconst=timeconst)


def runs_for(plant, seed=1, n_runs=3, n_samples=200):
    rng = np.random.default_rng(seed)
    return [(x0, multisine(n_samples, 0.01, 3.0, rng))
            for x0 in ([0, rng.uniform(-1, 1), 0, 0] for _ in range(n_runs))]


def friction_trace(plant, x0, u, dt=0.01):
    """MuJoCo's friction force f and the cart velocity v at every MuJoCo step of a run."""
    mj, m, d = plant._mj, plant.model, plant.data
    plant.reset(x0)
    n_sub = int(round(dt / plant.timestep))
    f, v = [], []
    for ui in u:
        d.ctrl[0] = ui
        for _ in range(n_sub):
            mj.mj_forward(m, d)
            f.append(d.qfrc_constraint[0])
            v.append(d.qvel[0])
            mj.mj_step(m, d)
    return np.array(f), np.array(v)


def friction_stats(plant, inputs, mu):
    f, v = map(np.concatenate, zip(*(friction_trace(plant, x0, u) for x0, u in inputs)))
    work_mj = -np.sum(f * v)
    return {"stick": float(np.mean(np.abs(f) < 0.999 * mu)),
            "wrong_sign": float(np.mean(f * v > 0)),
            "work_err": float((mu * np.sum(np.abs(v)) - work_mj) / work_mj)}


def energy_of(model, X):
    import sympy as sp
    names = model.coords_ + [c + "_dot" for c in model.coords_]
    f = sp.lambdify([sp.Symbol(s) for s in names], model.hamiltonian_, "numpy")
    return np.asarray(f(*X.T), float)


def run_case(mu, timeconst):
    plant = plant_for(mu, timeconst)
    inputs = runs_for(plant)
    row = {"mu": mu, "timeconst": timeconst, **friction_stats(plant, inputs, mu)}
    runs = [plant.trajectory(x0, u, 0.01) for x0, u in inputs]
    lib = Library.polynomial(["x", "theta"], FEATURES, 3)
    started = time.perf_counter()
    try:
        model = LagrangianSINDy(lib, prior=["theta_dot**2", "cos(theta)"],
                                dissipation=DISSIPATION).fit([tr for tr, _ in runs])
    except ValueError as exc:               # e.g. refused: negative dissipation
        return {**row, "status": f"refused: {exc}", "seconds": time.perf_counter() - started}
    H, R = model.terms(), model.terms("rayleigh")
    energy = max(float(np.ptp((energy_of(model, np.hstack([tr.q, tr.qd])) - E)
                              - np.mean(energy_of(model, np.hstack([tr.q, tr.qd])) - E))
                       / np.ptp(E)) for tr, E in runs)
    return {**row, "status": model.status_, "reasons": model.status_reasons_,
            "support_exact": set(H) == set(TRUE_H) and set(R) == set(plant.rayleigh),
            "energy_coef_err": max(abs(H.get(k, 0.0) / c - 1) for k, c in TRUE_H.items()),
            "rayleigh_err": {k: abs(R.get(k, 0.0) / c - 1) for k, c in plant.rayleigh.items()},
            "energy_vs_mujoco": energy, "seconds": time.perf_counter() - started}


def markdown(rows):
    out = ["| μ (N) | timeconst (s) | stick | wrong sign | work err | status | support | "
           "energy coef | b_x | b_θ | μ | H vs MuJoCo |", "|" + "---|" * 12]
    for r in rows:
        e = r.get("rayleigh_err", {})
        out.append(
            f"| {r['mu']:g} | {r['timeconst'] or 0.02:g} | {r['stick']:.1%} | {r['wrong_sign']:.2%} | "
            f"{r['work_err']:+.1e} | {r['status'].split(':')[0]} | "
            f"{'exact' if r.get('support_exact') else 'no'} | {r.get('energy_coef_err', np.nan):.1e} | "
            f"{e.get('x_dot**2', np.nan):.1e} | {e.get('theta_dot**2', np.nan):.1e} | "
            f"{e.get('Abs(x_dot)', np.nan):.1e} | {r.get('energy_vs_mujoco', np.nan):.1e} |")
    return "\n".join(out)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--quick", action="store_true", help="mu = 2 N only")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    rows = []
    for mu in ([2.0] if args.quick else [0.3, 1.0, 2.0]):
        for tc in (None, 0.005, 0.002):
            rows.append(run_case(mu, tc))
            print(f"mu {mu:g} timeconst {tc or 0.02:g}: {rows[-1]['status']} "
                  f"({rows[-1]['seconds']:.1f} s)", flush=True)
    table = markdown(rows)
    print(table)
    total = time.perf_counter() - started
    print(f"total {total:.0f} s")
    (out / "mujoco_friction.json").write_text(json.dumps(
        {"rows": rows, "seconds": total, "quick": args.quick}, indent=2, default=str) + "\n")
    (out / "mujoco_friction.md").write_text(table + "\n")


if __name__ == "__main__":
    main()
