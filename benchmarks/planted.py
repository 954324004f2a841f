"""Planted energies: two-link systems whose energy has exactly k terms of a 154-term library.

Each system is H = ½ q̇ᵀ M(θ2) q̇ + V(θ1, θ2) with M built from the kinetic terms below and V a
random combination of trigonometric potential terms; every term is a member of :func:`library`
(all products of cos θ1, sin θ1, cos θ2, sin θ2, θ̇1, θ̇2 up to degree 4, without the products
holding cos²θ1 or cos²θ2 — cos² = 1 − sin² would make exact copies: 154 terms).  The coefficients
are random, with M positive definite for every θ2 (checked on a grid with a margin), so the
system is a mechanical system with a unique energy in that library.  The planted support is
known exactly; the automatic choice of k has to find it.

k = 6 … 10: (kinetic, potential) terms (3, 3), (4, 3), (5, 3), (5, 4), (5, 5).

Data: ``n_runs`` runs of ``t_end`` s sampled every ``dt``, from angles uniform in ±``spread`` rad
(small motion 0.6, large 2.5) and rates in ±0.5 rad/s, under torques on both joints drawn
uniformly in ±``torque`` and held ``hold`` s; the true equations of motion integrated with DOP853
at rtol 1e-11 (:class:`~lsindy_cas.paper.systems.MechanicalSystem`).
"""
from __future__ import annotations

import numpy as np

COORDS = ["theta1", "theta2"]
FEATURES = ["cos(theta1)", "sin(theta1)", "cos(theta2)", "sin(theta2)", "theta1_dot", "theta2_dot"]
DEGREE = 4
# kinetic terms in the order they join: the constant mass matrix, then its θ2 dependence
KINETIC = ["theta1_dot**2", "theta2_dot**2", "theta1_dot*theta2_dot",
           "theta1_dot**2*cos(theta2)", "theta1_dot*theta2_dot*cos(theta2)"]
POTENTIAL = ["cos(theta1)", "cos(theta2)", "cos(theta1)*cos(theta2)", "sin(theta1)*sin(theta2)",
             "sin(theta1)", "sin(theta2)", "sin(theta1)*cos(theta2)", "cos(theta1)*sin(theta2)"]
SPLIT = {6: (3, 3), 7: (4, 3), 8: (5, 3), 9: (5, 4), 10: (5, 5)}
PRIOR = ["theta1_dot**2", "theta2_dot**2"]       # the diagonal of the mass matrix
# smallest eigenvalue of M over θ2, relative to its largest: kept above this so that the
# kinetic part is clearly positive definite (a nearly singular M makes stiff, fast motion)
PD_MARGIN = 0.2


def library():
    """The 154-term library (module notes)."""
    import sympy as sp
    from lsindy_cas import Library
    full = Library.polynomial(COORDS, FEATURES, DEGREE)
    keep = [e for e in full.exprs
            if not any(b.func == sp.cos and p >= 2 for b, p in e.as_powers_dict().items())]
    return Library(COORDS, keep)


def _mass(c, th2):
    """M(θ2) (…, 2, 2) of the kinetic coefficients c (dict term -> coefficient)."""
    g = lambda name: c.get(name, 0.0)
    cos2 = np.cos(th2)
    m11 = 2 * (g(KINETIC[0]) + g(KINETIC[3]) * cos2)
    m22 = 2 * g(KINETIC[1]) * np.ones_like(cos2)
    m12 = g(KINETIC[2]) + g(KINETIC[4]) * cos2
    return np.stack([np.stack([m11, m12], -1), np.stack([m12, m22], -1)], -2)


def planted(k: int, seed: int = 0) -> dict:
    """{term: coefficient} of a random planted energy with ``k`` terms (6 … 10)."""
    if k not in SPLIT:
        raise ValueError(f"k must be one of {sorted(SPLIT)}, got {k}")
    n_kin, n_pot = SPLIT[k]
    rng = np.random.default_rng(1000 * k + seed)
    grid = np.linspace(-np.pi, np.pi, 721)
    while True:
        c = {KINETIC[0]: rng.uniform(1.0, 2.5), KINETIC[1]: rng.uniform(0.4, 1.2),
             KINETIC[2]: rng.choice([-1, 1]) * rng.uniform(0.3, 0.8)}
        if n_kin >= 4:
            c[KINETIC[3]] = rng.choice([-1, 1]) * rng.uniform(0.3, 0.8)
        if n_kin >= 5:
            c[KINETIC[4]] = rng.choice([-1, 1]) * rng.uniform(0.3, 0.8)
        eig = np.linalg.eigvalsh(_mass(c, grid))
        if eig.min() > PD_MARGIN * eig.max():
            break
    for name in rng.permutation(POTENTIAL)[:n_pot]:
        c[str(name)] = float(rng.choice([-1, 1]) * rng.uniform(2.0, 10.0))
    return {name: float(v) for name, v in c.items()}


def system(coef: dict):
    """The planted energy as a :class:`~lsindy_cas.paper.systems.MechanicalSystem`."""
    from lsindy_cas.paper.systems import MechanicalSystem
    kin = " + ".join(f"({v!r})*{n}" for n, v in coef.items() if n in KINETIC)
    pot = " + ".join(f"({v!r})*{n}" for n, v in coef.items() if n not in KINETIC)
    return MechanicalSystem("planted", list(COORDS), kinetic=kin, potential=pot or "0",
                            actuated="theta1", x0=(0.0, 0.0, 0.0, 0.0))


def runs(coef: dict, spread: float, n_runs: int = 6, t_end: float = 5.0, dt: float = 0.01,
         hold: float = 0.25, torque: float = 3.0, seed: int = 0) -> list:
    """Simulated runs of the planted system (module notes)."""
    s = system(coef)
    rng = np.random.default_rng(seed)
    out = []
    n_hold = int(np.ceil(t_end / hold)) + 1
    for _ in range(n_runs):
        x0 = np.concatenate([rng.uniform(-spread, spread, 2), rng.uniform(-0.5, 0.5, 2)])
        levels = rng.uniform(-torque, torque, (n_hold, 2))
        u = (lambda t, x, lv=levels: lv[min(int(t / hold + 1e-9), len(lv) - 1)])
        out.append(s.simulate(x0=x0, t_end=t_end, u=u, dt=dt))
    return out


def strip(trajectories):
    """The runs as a user measures them: positions, rates and forces (no accelerations)."""
    from lsindy_cas.data.trajectory import Trajectory
    return [Trajectory(tr.t, tr.q, tr.qd, tr.coords, Q=tr.Q, source=tr.source)
            for tr in trajectories]
