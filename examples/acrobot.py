"""Gymnasium's Acrobot-v1: its energy and equations of motion identified from its own dynamics.

The plant is ``gymnasium.make("Acrobot-v1")`` (Sutton & Barto's "book" dynamics, RK4): two links
hanging from a fixed pivot, a torque of -1, 0 or +1 N m on the elbow.  Coordinates as gymnasium
defines them: ``theta1`` the first link's angle from hanging straight down, ``theta2`` the second
link's angle *relative to the first*; the torque acts on the elbow joint, i.e. it is the
generalized force Q_theta2 (Q_theta1 = 0).  From gymnasium's ``_dsdt`` parameters (m1 = m2 = 1 kg,
l1 = 1 m, lc1 = lc2 = 0.5 m, I1 = I2 = 1 kg m² about each link's centre of mass, g = 9.8 m/s²) the
mass matrix is

    d11 = m1 lc1² + m2 (l1² + lc2² + 2 l1 lc2 cos θ2) + I1 + I2 = 3.5 + cos θ2
    d12 = m2 (lc2² + l1 lc2 cos θ2) + I2                         = 1.25 + 0.5 cos θ2
    d22 = m2 lc2² + I2                                           = 1.25

and the potential V = −(m1 lc1 + m2 l1) g cos θ1 − m2 lc2 g cos(θ1 + θ2) (gymnasium's φ1, φ2 are
∂V/∂θ1, ∂V/∂θ2).  With cos(θ1 + θ2) = cos θ1 cos θ2 − sin θ1 sin θ2, the energy H = ½ q̇ᵀ D q̇ + V
has 8 terms of the library below (:data:`TRUE_H`)::

    H = 1.75 θ̇1² + 0.5 θ̇1² cos θ2 + 1.25 θ̇1 θ̇2 + 0.5 θ̇1 θ̇2 cos θ2 + 0.625 θ̇2²
        − 14.7 cos θ1 − 4.9 cos θ1 cos θ2 + 4.9 sin θ1 sin θ2

(the "book" ddθ2 is exactly the Euler–Lagrange equation of this H with Q = (0, a); checked by
:func:`check_ode` against ``_dsdt`` itself).

The data (:func:`collect`): gymnasium's own ``step``, sampled every ``dt`` = 10 ms, random starts
uniform in ±``spread`` rad, random torques from {−1, 0, +1} each held ``hold`` s.  ``env.dt`` (its
documented time-step knob; the dynamics are unchanged) is set to ``dt / substeps`` = 2 ms: one
gymnasium RK4 step per 10 ms sample gives a discrete map whose energy balance is off by ~1e-7 of
the work per sample, which the fit's status check (rightly) reads as a misfit — exact support and
coefficients to 4e-8, but status "undetermined" (held-out residual 3.4e4× its floor); at 2 ms the
RK4 error is ~1e-4 of that and the status is "ok".  gymnasium wraps the angles to [−π, π) every
step: they are unwrapped before the fit.  It also clips the rates at 4π and 9π rad/s; a run that
comes within 5 % of either bound is drawn again (the clip would break the dynamics; with the
defaults no run comes near it: |θ̇1| ≤ 4.6, |θ̇2| ≤ 10.3 rad/s).

The library (:func:`library`): all products of cos θ1, sin θ1, cos θ2, sin θ2, θ̇1, θ̇2 up to
degree ``DEGREE``, without the products that contain cos²θ1 or cos²θ2 — cos² = 1 − sin², and a
constant is invisible to the energy balance, so with them the library would hold exact copies
(θ̇1² cos²θ1 = θ̇1² − θ̇1² sin²θ1) and the support would not be unique: 154 terms at degree 4.
Priors: θ̇1², cos θ1 (the first link alone is a pendulum); with k = 8 given, the search finds the
other 6 terms (exact support, coefficients ~1e-10 relative, status ok; ~15 s).  Automatic k
(``n_terms=None``) with these two priors scores every 5-term support, then extends the best ones a
term at a time; at degree 4 the best 5-term support is not part of the energy and the scan stops
at k = 5 with a wrong model — flagged "undetermined" (80 % of the held-out work unexplained).  At
degree 3 (69 terms), or at degree 4 with θ̇2² as a third prior, it chooses k = 8 itself and finds
the same exact model (~20–60 s).

:class:`AcrobotPlant` wraps the unmodified environment (dt = 0.2 s, its episode rules) in the
model's coordinates, for a controller.

Run:  python examples/acrobot.py          (writes examples/data/acrobot_model.json)
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lsindy_cas import LagrangianSINDy, Library, printing
from lsindy_cas.data.trajectory import Trajectory

HERE = Path(__file__).resolve().parent
MODEL = HERE / "data" / "acrobot_model.json"

COORDS = ["theta1", "theta2"]
FEATURES = ["cos(theta1)", "sin(theta1)", "cos(theta2)", "sin(theta2)", "theta1_dot", "theta2_dot"]
DEGREE = 4
PRIOR = ["theta1_dot**2", "cos(theta1)"]
N_TERMS = 8
TORQUES = (-1.0, 0.0, 1.0)      # gymnasium's AVAIL_TORQUE, in action-index order
DT = 0.01                       # s: sample time of the identification data
SUBSTEPS = 5                    # gymnasium RK4 steps per sample (env.dt = DT / SUBSTEPS = 2 ms)
CLIP_MARGIN = 0.95              # a run whose rates exceed this fraction of gymnasium's clip is redrawn

# gymnasium's _dsdt parameters
M1 = M2 = 1.0
L1, LC1, LC2 = 1.0, 0.5, 0.5
I1 = I2 = 1.0
G = 9.8


def _true_h() -> dict:
    d11_0 = M1 * LC1**2 + M2 * (L1**2 + LC2**2) + I1 + I2     # 3.5   (+ 2 m2 l1 lc2 cos θ2)
    d12_0 = M2 * LC2**2 + I2                                   # 1.25  (+ m2 l1 lc2 cos θ2)
    d22 = M2 * LC2**2 + I2                                     # 1.25
    c = M2 * L1 * LC2                                          # 0.5
    return {"theta1_dot**2": d11_0 / 2,
            "theta1_dot**2*cos(theta2)": c,                    # ½ · 2 m2 l1 lc2
            "theta1_dot*theta2_dot": d12_0,
            "theta1_dot*theta2_dot*cos(theta2)": c,
            "theta2_dot**2": d22 / 2,
            "cos(theta1)": -(M1 * LC1 + M2 * L1) * G,
            "cos(theta1)*cos(theta2)": -M2 * LC2 * G,
            "sin(theta1)*sin(theta2)": M2 * LC2 * G}


#: the true energy, {library term: coefficient}
TRUE_H = _true_h()


def true_energy(x) -> np.ndarray:
    """The Acrobot's total energy at states ``x`` ([θ1, θ2, θ̇1, θ̇2], one per row), written
    directly (cos(θ1 + θ2), the mass matrix), not from :data:`TRUE_H`."""
    x = np.atleast_2d(np.asarray(x, float))
    t1, t2, w1, w2 = x.T
    d11 = M1 * LC1**2 + M2 * (L1**2 + LC2**2 + 2 * L1 * LC2 * np.cos(t2)) + I1 + I2
    d12 = M2 * (LC2**2 + L1 * LC2 * np.cos(t2)) + I2
    d22 = M2 * LC2**2 + I2
    T = 0.5 * d11 * w1**2 + d12 * w1 * w2 + 0.5 * d22 * w2**2
    V = -(M1 * LC1 + M2 * L1) * G * np.cos(t1) - M2 * LC2 * G * np.cos(t1 + t2)
    return T + V


def _env(dt: float | None = None):
    import gymnasium
    env = gymnasium.make("Acrobot-v1")
    if dt is not None:
        env.unwrapped.dt = float(dt)
    return env


# ---------------------------------------------------------------------- data
def _run(env, x0, actions, substeps: int) -> tuple:
    """Step the unwrapped env from ``x0`` under action indices ``actions`` (one per sample, each
    held for ``substeps`` env steps): (X sampled, gymnasium-wrapped angles; clipped?)."""
    env.state = np.asarray(x0, float).copy()
    X = [env.state.copy()]
    for a in actions[:-1]:
        for _ in range(substeps):
            env.step(int(a))
        X.append(np.asarray(env.state, float).copy())
    X = np.array(X)
    clipped = bool(np.any(np.abs(X[:, 2]) >= CLIP_MARGIN * env.MAX_VEL_1)
                   or np.any(np.abs(X[:, 3]) >= CLIP_MARGIN * env.MAX_VEL_2))
    return X, clipped


def collect(n_runs: int = 6, t_end: float = 5.0, seed: int = 0, spread: float = 2.5,
            hold: float = 0.25, dt: float = DT, substeps: int = SUBSTEPS) -> list:
    """``n_runs`` runs of gymnasium's Acrobot-v1 dynamics, ``t_end`` s each, sampled at ``dt``.

    Each run starts at angles uniform in ±``spread`` rad and rates uniform in ±0.5 rad/s; the
    torque is drawn from {−1, 0, +1} and held for ``hold`` s (rounded to whole samples).  The
    environment's own ``step`` integrates (RK4 over ``dt``; ``env.dt`` is set to ``dt``).  A run
    whose rates come within 5 % of gymnasium's clip (4π, 9π rad/s) is drawn again.

    Returns
    -------
    list of Trajectory
        coords ``["theta1", "theta2"]`` (unwrapped), measured rates, ``Q = [0, torque]`` (the
        torque held over [t_i, t_i+1) at sample i), no accelerations.
    """
    substeps = int(substeps)
    env = _env(dt / substeps).unwrapped
    rng = np.random.default_rng(seed)
    n = int(round(t_end / dt)) + 1
    per = max(1, int(round(hold / dt)))
    runs, redrawn = [], 0
    while len(runs) < int(n_runs):
        x0 = np.concatenate([rng.uniform(-spread, spread, 2), rng.uniform(-0.5, 0.5, 2)])
        actions = np.repeat(rng.integers(0, 3, -(-n // per)), per)[:n]
        X, clipped = _run(env, x0, actions, substeps)
        if clipped:
            redrawn += 1
            if redrawn > 10 * int(n_runs):
                raise RuntimeError("the runs keep reaching gymnasium's rate clip: lower spread")
            continue
        q = np.unwrap(X[:, :2], axis=0)
        Q = np.zeros((n, 2))
        Q[:, 1] = np.asarray(TORQUES)[actions]
        runs.append(Trajectory(np.arange(n) * dt, q, X[:, 2:], COORDS, Q=Q,
                               source=f"gymnasium:Acrobot-v1:{seed}:{len(runs)}"))
    env.close()
    return runs


# ---------------------------------------------------------------------- identification
def library(degree: int = DEGREE) -> Library:
    """Products of cos θ1, sin θ1, cos θ2, sin θ2, θ̇1, θ̇2 up to ``degree``, without those
    containing cos²θ1 or cos²θ2 (exact copies of other terms, see the module docstring)."""
    import sympy as sp
    full = Library.polynomial(COORDS, FEATURES, degree)
    keep = [e for e in full.exprs
            if not any(b.func == sp.cos and p >= 2 for b, p in e.as_powers_dict().items())]
    return Library(COORDS, keep)


def identify(trajectories, verbose: bool = True, n_terms: int | None = N_TERMS,
             degree: int = DEGREE, prior=PRIOR) -> LagrangianSINDy:
    """The fitted model: ``n_terms`` terms of :func:`library` with the priors θ̇1², cos θ1
    (``n_terms=None``: k chosen from the data)."""
    lib = library(degree)
    t0 = time.perf_counter()
    model = LagrangianSINDy(lib, n_terms=n_terms, prior=list(prior)).fit(trajectories)
    if verbose:
        print(f"{len(lib)} candidate terms (degree {degree}), priors {list(prior)}, "
              f"k = {model.n_terms_} ({'given' if n_terms else 'chosen'}); "
              f"fit {time.perf_counter() - t0:.1f} s")
    return model


def compare(model) -> dict:
    """{term: (identified, true, relative error)} (a term missing on either side gets 0)."""
    got, out = model.terms(), {}
    for name in sorted(set(got) | set(TRUE_H)):
        a, b = got.get(name, 0.0), TRUE_H.get(name, 0.0)
        out[name] = (a, b, abs(a - b) / abs(b) if b else float("inf"))
    return out


def check_ode(model, n: int = 200, seed: int = 1) -> float:
    """Largest relative difference between the model's accelerations (``model.ode()``) and
    gymnasium's ``_dsdt`` at ``n`` random states and torques."""
    env = _env().unwrapped
    ode = model.ode()
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(n):
        x = np.concatenate([rng.uniform(-np.pi, np.pi, 2), rng.uniform(-6, 6, 2)])
        a = float(rng.choice(TORQUES))
        ours = np.asarray(ode(x, [0.0, a])).ravel()
        true = np.asarray(env._dsdt(np.append(x, a))[:4], float)
        worst = max(worst, float(np.max(np.abs(ours - true)) / np.max(np.abs(true))))
    env.close()
    return worst


# ---------------------------------------------------------------------- the plant, for control
class AcrobotPlant:
    """The unmodified ``gymnasium.make("Acrobot-v1")`` environment in the model's coordinates.

    State ``x = [theta1, theta2, theta1_dot, theta2_dot]`` (rad, rad/s), read from
    ``env.unwrapped.state``; the angles are gymnasium's, wrapped to [−π, π).  Input ``u`` the elbow
    torque in {−1, 0, +1} N m = Q_theta2 (``LEVELS``), held over one gymnasium step of ``dt`` =
    0.2 s (RK4).  ``reached`` is gymnasium's termination (tip above the bar:
    −cos θ1 − cos(θ1 + θ2) > 1); ``truncated`` its 500-step time limit.

    Methods: ``reset(seed=None) -> x`` (gymnasium's random start, uniform in ±0.1),
    ``step(u) -> (x, reached, truncated)``, ``state() -> x``, ``close()``.
    """

    LEVELS = TORQUES
    coords = COORDS
    actuated = "theta2"

    def __init__(self, render_mode: str | None = None):
        import gymnasium
        self.env = gymnasium.make("Acrobot-v1", render_mode=render_mode)
        self.dt = float(self.env.unwrapped.dt)

    def state(self) -> np.ndarray:
        return np.asarray(self.env.unwrapped.state, float).copy()

    def reset(self, seed: int | None = None) -> np.ndarray:
        self.env.reset(seed=seed)
        return self.state()

    def step(self, u: float) -> tuple:
        """Apply torque ``u`` (one of ``LEVELS``) for one step: (x, reached, truncated)."""
        levels = list(self.env.unwrapped.AVAIL_TORQUE)
        match = [i for i, lv in enumerate(levels) if np.isclose(float(u), lv)]
        if not match:
            raise ValueError(f"u = {u} is not one of Acrobot's torques {tuple(levels)}")
        _, _, terminated, truncated, _ = self.env.step(match[0])
        return self.state(), bool(terminated), bool(truncated)

    def close(self):
        self.env.close()


# ---------------------------------------------------------------------- main
def main(model_path=MODEL, n_runs: int = 6, t_end: float = 5.0, seed: int = 0,
         spread: float = 2.5, hold: float = 0.25, n_terms: int | None = N_TERMS,
         verbose: bool = True) -> LagrangianSINDy:
    """Collect, identify, compare with the true energy and ``_dsdt``, save the model."""
    t0 = time.perf_counter()
    trajs = collect(n_runs, t_end, seed, spread, hold)
    t1 = time.perf_counter()
    model = identify(trajs, verbose=verbose, n_terms=n_terms)
    t2 = time.perf_counter()
    table = compare(model)
    ode_err = check_ode(model)
    if verbose:
        print(f"{n_runs} runs x {t_end:g} s at {DT:g} s, torques {TORQUES} held {hold:g} s "
              f"(gymnasium {t1 - t0:.1f} s, fit {t2 - t1:.1f} s)\n")
        print(printing.describe(model, digits=6))
        print("\nterm                                       identified         true   rel. error")
        for name, (a, b, err) in table.items():
            print(f"{name:36s} {a:16.12g} {b:12.6g} {err:10.1e}")
        print(f"\nODE vs gymnasium's _dsdt at 200 random states/torques: max rel. error {ode_err:.1e}")
        print(f"status: {model.status_}" + (f" ({'; '.join(model.status_reasons_)})"
                                            if model.status_reasons_ else ""))
    assert set(model.terms()) == set(TRUE_H), sorted(model.terms())
    assert max(err for _, _, err in table.values()) < 1e-3, table
    assert ode_err < 1e-6, ode_err
    if model_path is not None:
        path = model.save(model_path)
        if verbose:
            print(f"model saved to {path}")
    return model


if __name__ == "__main__":
    main()
