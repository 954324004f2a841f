"""Gymnasium's MuJoCo ``InvertedDoublePendulum-v5`` identified from its own engine's data.

The env is a double pendulum on a cart with its own model file (``inverted_double_pendulum.xml``):
capsule links of distributed mass (density 1000, MuJoCo computes masses and inertias from the
geoms), joint damping 0.05 on every joint, a slider limited to ±1 m (a hard constraint with a 0.01 m
margin), the force on the cart ``gear × action`` (gear 500, action in [-1, 1]), RK4 at 0.01 s and
five MuJoCo steps per env step (0.05 s).  Its gravity is (1e-5, 0, −9.81): a tiny horizontal part
the identification neither needs nor resolves (potential terms of ~1e-4 against 37 for cos θ1).

Coordinates are MuJoCo's ``qpos``: ``x`` (slider, m), ``theta1`` (hinge, from the **upward**
vertical: θ = 0 is upright), ``theta2`` (hinge2, **relative** to link 1).  Hanging is θ1 = π, θ2 = 0.

* :func:`collect` drives the env's own ``MjModel``/``MjData`` with random held actions plus a
  centring feedback (the cart never comes near the slider's limit, so the constraint never acts;
  checked at every MuJoCo step) from random starts with large angles (swinging and tumbling links),
  and records qpos/qvel every ``dt`` and Q_x = ``qfrc_actuator`` (gear × ctrl, held).
* :func:`identify` fits the energy H and a Rayleigh function for the joint damping.
* :func:`true_energy` derives H from the MuJoCo model's body masses, inertias and com positions;
  :func:`mujoco_energy` is MuJoCo's own energy (``mj_energyPos`` + ``mj_energyVel``);
  :func:`acceleration_errors` compares ``model.ode()`` with MuJoCo's ``qacc`` (``mj_forward``).
* :class:`DoublePendulumCartPlant` wraps the real ``gymnasium.make("InvertedDoublePendulum-v5")``
  env for a controller (``reset``, ``reset_to``, ``step``, ``hanging_start``).

Result (8 runs × 4 s, the polynomial library of 329 terms, ~1.5 min): the exact 14-term support,
every energy coefficient within 3.1e-5 of the truth, R's diagonal within 0.64 % (cart), 0.04 %
and 0.009 % (hinges), no coupling terms; ``ode()`` within 1.1e-4 of MuJoCo's qacc.  The verdict
is nevertheless ``undetermined`` ("the residual is 3.9e3× what the estimated noise explains"): the
data are clean, so the noise floor is tiny, and the env's samples are RK4 steps of 10 ms — not the
continuous flow whose energy balance is fitted — with a 1e-5 m/s² horizontal gravity the 14 terms
leave out.  Measured with the physical library: the same runs with 1 ms steps leave 56× (the
horizontal gravity), with 1 ms steps and no horizontal gravity the fit is ``ok`` (coefficients
1.5e-7).  It is the verdict's honest reading of this env, not a wrong model.

Run:  python examples/double_pendulum_cart.py     (writes examples/data/double_pendulum_cart_model.json)
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lsindy_cas import LagrangianSINDy, Library, printing
from lsindy_cas.data.trajectory import Trajectory

ENV_ID = "InvertedDoublePendulum-v5"
COORDS = ["x", "theta1", "theta2"]
DT = 0.05                     # s per env step (frame_skip 5 × timestep 0.01)
GEAR = 500.0                  # N per unit action (the env's <motor gear="500">)
X_LIMIT = 1.0                 # m, the slider's range (a hard constraint)
X_SAFE = 0.8                  # m, what collect() keeps the cart within (limit margin is 0.01 m)
MODEL_FILE = Path(__file__).resolve().parent / "data" / "double_pendulum_cart_model.json"

# Library features: the polynomial library of degree 4 over these features holds every term of H
# in its expanded form (cos(θ1 + θ2) = cos θ1 cos θ2 − sin θ1 sin θ2), see true_energy().
FEATURES = ["cos(theta1)", "sin(theta1)", "cos(theta2)", "sin(theta2)",
            "x_dot", "theta1_dot", "theta2_dot"]
DEGREE = 4
# Terms of the constituent simple systems (cart; pendulum 1; link 2's own rotation): forced in.
PRIOR = ["x_dot**2", "theta1_dot**2", "theta2_dot**2", "cos(theta1)"]
# Rayleigh candidates: viscous on each joint plus couplings (the truth has none of the couplings)
DISSIPATION = ["x_dot**2", "theta1_dot**2", "theta2_dot**2",
               "x_dot*theta1_dot", "x_dot*theta2_dot", "theta1_dot*theta2_dot"]
N_TERMS = 14


def _mujoco():
    import mujoco
    return mujoco


def make_env(**kwargs):
    """``gymnasium.make("InvertedDoublePendulum-v5", **kwargs)``."""
    import gymnasium
    return gymnasium.make(ENV_ID, **kwargs)


# --------------------------------------------------------------------------- the truth
def parameters(mj_model) -> dict:
    """The physical parameters of the env's compiled MuJoCo model.

    Link inertias are about the hinge (y) axis through each link's centre of mass, from MuJoCo's
    principal inertias and their frame (``body_inertia``, ``body_iquat``): the capsules'
    distributed inertia, not a point mass's.
    """
    mj = _mujoco()
    names = ("cart", "pole", "pole2")
    ids = [mj.mj_name2id(mj_model, mj.mjtObj.mjOBJ_BODY, n) for n in names]

    def inertia_y(b):
        R = np.empty(9)
        mj.mju_quat2Mat(R, mj_model.body_iquat[b])
        R = R.reshape(3, 3)
        return float((R @ np.diag(mj_model.body_inertia[b]) @ R.T)[1, 1])

    cart, pole, pole2 = ids
    jid = {n: mj.mj_name2id(mj_model, mj.mjtObj.mjOBJ_JOINT, n) for n in ("slider", "hinge", "hinge2")}
    dof = {n: int(mj_model.jnt_dofadr[j]) for n, j in jid.items()}
    gx, _, gz = (float(v) for v in mj_model.opt.gravity)
    return {
        "mc": float(mj_model.body_mass[cart]), "m1": float(mj_model.body_mass[pole]),
        "m2": float(mj_model.body_mass[pole2]),
        "c1": float(mj_model.body_ipos[pole][2]), "c2": float(mj_model.body_ipos[pole2][2]),
        "L1": float(mj_model.body_pos[pole2][2]),
        "I1": inertia_y(pole), "I2": inertia_y(pole2),
        "g": -gz, "gx": gx,
        "damping": {n: float(mj_model.dof_damping[d]) for n, d in dof.items()},
        "gear": float(mj_model.actuator_gear[0, 0]),
        "ctrlrange": [float(v) for v in mj_model.actuator_ctrlrange[0]],
        "slider_range": [float(v) for v in mj_model.jnt_range[jid["slider"]]],
        "slider_limited": bool(mj_model.jnt_limited[jid["slider"]]),
        "slider_margin": float(mj_model.jnt_margin[jid["slider"]]),
        "timestep": float(mj_model.opt.timestep),
        "integrator": mj.mjtIntegrator(mj_model.opt.integrator).name,
    }


def true_energy(mj_model) -> dict:
    """The true H = T + V in the library's expanded terms {name: coefficient}.

    Link i: mass m_i, com at c_i along the link, inertia I_i about its com; link 2 hinged at L1 on
    link 1; φ = θ1 + θ2 its absolute angle (from the upward vertical).  Then

        T = ½M ẋ² + a ẋθ̇1 cos θ1 + m2c2 ẋφ̇ cos φ + ½J1 θ̇1² + ½J2 φ̇² + m2L1c2 θ̇1φ̇ cos θ2,
        V = g (a cos θ1 + m2c2 cos φ),

    M = mc + m1 + m2, a = m1c1 + m2L1, J1 = I1 + m1c1² + m2L1², J2 = I2 + m2c2².  The horizontal
    gravity gx = 1e-5 adds −gx(M x + a sin θ1 + m2c2 sin φ) to V (coefficients ~1e-4, left out).
    """
    p = parameters(mj_model)
    M = p["mc"] + p["m1"] + p["m2"]
    a = p["m1"] * p["c1"] + p["m2"] * p["L1"]
    b = p["m2"] * p["c2"]
    J1 = p["I1"] + p["m1"] * p["c1"] ** 2 + p["m2"] * p["L1"] ** 2
    J2 = p["I2"] + p["m2"] * p["c2"] ** 2
    k = p["m2"] * p["L1"] * p["c2"]
    g = p["g"]
    terms = {
        "x_dot**2": M / 2,
        "theta1_dot**2": (J1 + J2) / 2, "theta1_dot*theta2_dot": J2, "theta2_dot**2": J2 / 2,
        "theta1_dot**2*cos(theta2)": k, "theta1_dot*theta2_dot*cos(theta2)": k,
        "x_dot*theta1_dot*cos(theta1)": a,
        "x_dot*theta1_dot*cos(theta1)*cos(theta2)": b, "x_dot*theta1_dot*sin(theta1)*sin(theta2)": -b,
        "x_dot*theta2_dot*cos(theta1)*cos(theta2)": b, "x_dot*theta2_dot*sin(theta1)*sin(theta2)": -b,
        "cos(theta1)": g * a, "cos(theta1)*cos(theta2)": g * b, "sin(theta1)*sin(theta2)": -g * b,
    }
    names = Library(COORDS, list(terms)).names          # the library's canonical spelling
    return dict(zip(names, terms.values()))


def true_rayleigh(mj_model) -> dict:
    """MuJoCo's joint damping b (force −b q̇ on each dof) as R = Σ b q̇²/2 {name: coefficient}."""
    d = parameters(mj_model)["damping"]
    return {"x_dot**2": d["slider"] / 2, "theta1_dot**2": d["hinge"] / 2,
            "theta2_dot**2": d["hinge2"] / 2}


# --------------------------------------------------------------------------- MuJoCo's own views
def mujoco_energy(states, mj_model=None) -> np.ndarray:
    """MuJoCo's total energy (``mj_energyPos`` + ``mj_energyVel``; what ``mjENBL_ENERGY`` reports)
    at states [x, θ1, θ2, ẋ, θ̇1, θ̇2] (n, 6)."""
    mj = _mujoco()
    if mj_model is None:
        env = make_env()
        mj_model = env.unwrapped.model
    data = mj.MjData(mj_model)
    out = []
    for s in np.atleast_2d(np.asarray(states, float)):
        data.qpos[:], data.qvel[:] = s[:3], s[3:]
        mj.mj_forward(mj_model, data)
        mj.mj_energyPos(mj_model, data)
        mj.mj_energyVel(mj_model, data)
        out.append(data.energy[0] + data.energy[1])
    return np.array(out)


def mujoco_qacc(state, ctrl, mj_model) -> np.ndarray:
    """MuJoCo's accelerations (``mj_forward`` qacc) at a state under an action ``ctrl``."""
    mj = _mujoco()
    data = mj.MjData(mj_model)
    data.qpos[:], data.qvel[:] = state[:3], state[3:]
    data.ctrl[0] = ctrl
    mj.mj_forward(mj_model, data)
    if data.nefc:
        raise ValueError("a constraint is active at this state (slider limit)")
    return np.array(data.qacc), float(data.qfrc_actuator[0])


def acceleration_errors(model, n=200, seed=0, mj_model=None) -> np.ndarray:
    """Relative errors |q̈_model − q̈_MuJoCo| / |q̈_MuJoCo| (norm over the 3 dofs) at ``n`` random
    states and actions (|x| < 0.9, all angles, rates up to ~10 rad/s)."""
    if mj_model is None:
        mj_model = make_env().unwrapped.model
    rng = np.random.default_rng(seed)
    ode = model.ode()
    errs = []
    for _ in range(n):
        s = np.concatenate([[rng.uniform(-0.9, 0.9)], rng.uniform(-np.pi, np.pi, 2),
                            [rng.normal(0, 1.0)], rng.normal(0, 4.0, 2)])
        ctrl = rng.uniform(-1, 1)
        qacc, Qx = mujoco_qacc(s, ctrl, mj_model)
        xdot = np.asarray(ode(s, [Qx, 0.0, 0.0])).ravel()
        errs.append(np.linalg.norm(xdot[3:] - qacc) / np.linalg.norm(qacc))
    return np.array(errs)


# --------------------------------------------------------------------------- data
def collect(n_runs, t_end, seed=0, hold=0.05, dt=0.01, env=None, max_tries=50):
    """Runs of the env's own MjModel/MjData under random held actions.

    Each run starts at a random state (|x| ≤ 0.3 m, both angles uniform on the circle, rates
    ~N(0, 2 rad/s), cart ~N(0, 0.3 m/s)), so the links swing, tumble and pass upright.  Every
    ``hold`` seconds an action a ~ U(−0.5, 0.5) plus a centring PD on the cart (acceleration
    −16x − 8ẋ times the total mass, in action units) is clipped to [−1, 1] and held; MuJoCo
    clamps nothing further.  A run whose cart leaves |x| ≤ ``X_SAFE`` (or on which any constraint
    becomes active, ``nefc``) is drawn again, so the slider limit never acts.

    Parameters
    ----------
    n_runs : int
    t_end : float
        Seconds per run.
    seed : int
    hold : float
        Seconds each action is held (a multiple of ``dt``; 0.05 = one env step).
    dt : float
        Sample interval (a multiple of the MuJoCo timestep, 0.01).

    Returns
    -------
    list of Trajectory
        q = qpos, q̇ = qvel at each sample, Q = (qfrc_actuator[0], 0, 0), the value held over
        [t_i, t_{i+1}) (the last repeats).  Damping is not in Q: it is the model's Rayleigh part.
    """
    mj = _mujoco()
    env = make_env() if env is None else env
    m, d = env.unwrapped.model, env.unwrapped.data
    n_sub = int(round(dt / m.opt.timestep))
    n_hold = int(round(hold / dt))
    if n_sub < 1 or abs(n_sub * m.opt.timestep - dt) > 1e-12:
        raise ValueError(f"dt ({dt}) must be a multiple of the MuJoCo timestep {m.opt.timestep}")
    if n_hold < 1 or abs(n_hold * dt - hold) > 1e-12:
        raise ValueError(f"hold ({hold}) must be a multiple of dt ({dt})")
    gear = float(m.actuator_gear[0, 0])
    mass = float(np.sum(m.body_mass))
    n = int(round(t_end / dt))
    rng = np.random.default_rng(seed)
    runs = []
    while len(runs) < n_runs:
        for _ in range(max_tries):
            mj.mj_resetData(m, d)
            d.qpos[:] = [rng.uniform(-0.3, 0.3), *rng.uniform(-np.pi, np.pi, 2)]
            d.qvel[:] = [rng.normal(0, 0.3), *rng.normal(0, 2.0, 2)]
            mj.mj_forward(m, d)
            X = np.empty((n + 1, 6))
            Q = np.zeros((n + 1, 3))
            ok = True
            for i in range(n):
                X[i] = np.concatenate([d.qpos, d.qvel])
                if i % n_hold == 0:
                    x, xd = d.qpos[0], d.qvel[0]
                    d.ctrl[0] = np.clip(rng.uniform(-0.5, 0.5) - mass * (16 * x + 8 * xd) / gear,
                                        -1.0, 1.0)
                for _ in range(n_sub):
                    mj.mj_step(m, d)
                    if d.nefc or abs(d.qpos[0]) > X_SAFE:
                        ok = False
                        break
                if not ok:
                    break
                Q[i, 0] = d.qfrc_actuator[0]                 # gear × ctrl, held over the sample
            if ok:
                break
        else:
            raise RuntimeError(f"no run kept the cart within ±{X_SAFE} m in {max_tries} tries")
        X[n] = np.concatenate([d.qpos, d.qvel])
        Q[n] = Q[n - 1]
        runs.append(Trajectory(np.arange(n + 1) * dt, X[:, :3], X[:, 3:], list(COORDS), Q=Q,
                               source=f"{ENV_ID} run {len(runs)}"))
    return runs


# --------------------------------------------------------------------------- identification
def library() -> Library:
    """The polynomial candidates: every product of degree 1..4 of ``FEATURES`` (329 terms)."""
    return Library.polynomial(COORDS, FEATURES, degree=DEGREE)


_TRIG = ["cos(theta1)", "sin(theta1)", "cos(theta2)", "sin(theta2)", "cos(theta1)*cos(theta2)",
         "sin(theta1)*sin(theta2)", "sin(theta1)*cos(theta2)", "cos(theta1)*sin(theta2)"]
_VELOCITY_PAIRS = ["x_dot**2", "x_dot*theta1_dot", "x_dot*theta2_dot", "theta1_dot**2",
                   "theta1_dot*theta2_dot", "theta2_dot**2"]


def physical_library() -> Library:
    """An explicit, smaller library (64 terms): every velocity pair × {1, cos θi, sin θi, the four
    products cos/sin θ1 · cos/sin θ2} (54 kinetic candidates), the eight angle functions and x, x²
    as potentials.  It holds the same 14 true terms as :func:`library` (which holds all of these)."""
    kinetic = [v if t is None else f"{v}*{t}" for v in _VELOCITY_PAIRS for t in [None, *_TRIG]]
    return Library(COORDS, kinetic + _TRIG + ["x", "x**2"])


def identify(trajs, lib=None, n_terms=N_TERMS, time_limit=30.0) -> LagrangianSINDy:
    """Fit H (``n_terms`` terms from ``lib``, default :func:`library`; ``PRIOR`` forced in) and R
    (``DISSIPATION`` candidates) on the work of the held force (``hold="zoh"``).

    ``time_limit`` bounds each branch-and-bound search; with the polynomial library the first
    search proves its support in ~12 s, the later re-selection on the noise-weighted balance may
    stop at the limit unproven (the first certificate stands; ``search_.reweighted``)."""
    lib = library() if lib is None else lib
    return LagrangianSINDy(lib, n_terms=n_terms, prior=PRIOR, hold="zoh",
                           dissipation=DISSIPATION, time_limit=time_limit).fit(trajs)


def rayleigh_terms(model) -> dict:
    """The identified R as {``DISSIPATION`` name: coefficient} (zeros included)."""
    lib = Library(COORDS, DISSIPATION)
    return dict(zip(lib.names, (float(c) for c in lib.coefficients(model.rayleigh_))))


def step_errors(model, n=50, seed=1, mj_model=None) -> np.ndarray:
    """One env step (0.05 s, five RK4 steps of MuJoCo) against ``model.simulate`` over the same
    0.05 s under the same held force, from ``n`` random states: max |Δstate| per start."""
    mj = _mujoco()
    if mj_model is None:
        mj_model = make_env().unwrapped.model
    data = mj.MjData(mj_model)
    rng = np.random.default_rng(seed)
    n_sub = int(round(DT / mj_model.opt.timestep))
    out = []
    for _ in range(n):
        s = np.concatenate([[rng.uniform(-0.5, 0.5)], rng.uniform(-np.pi, np.pi, 2),
                            [rng.normal(0, 0.5)], rng.normal(0, 2.0, 2)])
        mj.mj_resetData(mj_model, data)
        data.qpos[:], data.qvel[:] = s[:3], s[3:]
        data.ctrl[0] = rng.uniform(-1, 1)
        for _ in range(n_sub):
            mj.mj_step(mj_model, data)
        Qx = float(data.qfrc_actuator[0])
        X = model.simulate(s, np.array([0.0, DT]), np.array([Qx, 0.0, 0.0]))
        out.append(np.max(np.abs(X[-1] - np.concatenate([data.qpos, data.qvel]))))
    return np.array(out)


def energy_deviation(model, traj, mj_model=None) -> float:
    """max |H_model − E_MuJoCo − mean| along ``traj``, relative to E_MuJoCo's range (H is defined up
    to a constant)."""
    X = np.hstack([traj.q, traj.qd])
    E = mujoco_energy(X, mj_model)
    H = model.library.theta(X) @ model.coef_
    diff = (H - H.mean()) - (E - E.mean())
    return float(np.max(np.abs(diff)) / np.ptp(E))


# --------------------------------------------------------------------------- the plant
class DoublePendulumCartPlant:
    """The real ``gymnasium.make("InvertedDoublePendulum-v5")`` env, with a state vector.

    State x = [x, θ1, θ2, ẋ, θ̇1, θ̇2] (MuJoCo's qpos, qvel: θ = 0 upright, θ2 relative to link 1).
    Actions are in [−1, 1] (force ``GEAR`` × action on the cart), each held for ``DT`` = 0.05 s.
    ``terminated`` is the env's own (tip height ≤ 1 m), so it is True whenever the links hang; the
    env does not stop stepping then — a swing-up controller keeps going (``TimeLimit`` truncates
    after 1000 steps).
    """

    GEAR = GEAR
    DT = DT
    X_LIMIT = X_LIMIT

    def __init__(self, **make_kwargs):
        self.env = make_env(**make_kwargs)
        self._reset_done = False

    @property
    def mj_model(self):
        return self.env.unwrapped.model

    @property
    def mj_data(self):
        return self.env.unwrapped.data

    def state(self) -> np.ndarray:
        d = self.mj_data
        return np.concatenate([d.qpos, d.qvel]).astype(float)

    def reset(self, seed=None) -> np.ndarray:
        """The env's own random start (near upright, ±0.1 noise); returns the state."""
        self.env.reset(seed=seed)
        self._reset_done = True
        return self.state()

    def reset_to(self, x0) -> np.ndarray:
        """Set the state to ``x0`` (e.g. :meth:`hanging_start`); returns it as MuJoCo holds it."""
        x0 = np.asarray(x0, float)
        if x0.shape != (6,):
            raise ValueError(f"x0 must be [x, theta1, theta2, x_dot, theta1_dot, theta2_dot], "
                             f"got shape {x0.shape}")
        if not self._reset_done:
            self.reset()
        self.env.unwrapped.set_state(x0[:3], x0[3:])
        return self.state()

    def step(self, action):
        """``env.step`` with ``action`` in [−1, 1] (clipped); returns (x, reward, terminated,
        truncated)."""
        a = np.clip(np.asarray(action, dtype=np.float32).reshape(1), -1.0, 1.0)
        _, reward, terminated, truncated, _ = self.env.step(a)
        return self.state(), float(reward), bool(terminated), bool(truncated)

    def energy(self) -> float:
        """MuJoCo's total energy at the current state."""
        return float(mujoco_energy(self.state(), self.mj_model)[0])

    @staticmethod
    def hanging_start(rng=None, scale=0.05) -> np.ndarray:
        """Both links down (θ1 = π, θ2 = 0), at rest, with offsets ~U(−scale, scale) on the
        positions and ~N(0, scale) on the rates."""
        rng = np.random.default_rng(rng)
        return np.array([rng.uniform(-scale, scale), np.pi + rng.uniform(-scale, scale),
                         rng.uniform(-scale, scale), *rng.normal(0, scale, 3)])

    def close(self):
        self.env.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


hanging_start = DoublePendulumCartPlant.hanging_start


# --------------------------------------------------------------------------- main
def compare(model, mj_model) -> dict:
    """Identified vs true H and R: {"H": {name: (identified, true)}, "R": {...}}."""
    found, truth = model.terms(), true_energy(mj_model)
    h = {k: (found.get(k, 0.0), truth.get(k, 0.0)) for k in sorted(set(found) | set(truth))}
    rho, r_true = rayleigh_terms(model), true_rayleigh(mj_model)
    r = {k: (rho.get(k, 0.0), r_true.get(k, 0.0)) for k in sorted(set(rho) | set(r_true))}
    return {"H": h, "R": r}


def worst_relative_error(pairs) -> float:
    """max |identified − true| / |true| over the true terms of {name: (identified, true)}."""
    return max(abs(f - t) / abs(t) for f, t in pairs.values() if t)


def main(model_path=MODEL_FILE, n_runs=8, t_end=4.0, seed=0, lib="polynomial", verbose=True):
    """Collect ``n_runs`` × ``t_end`` s, identify (``lib``: "polynomial" — 329 terms, ~1.5–3 min —
    or "physical" — 64 terms, ~7 s), compare with the truth and with MuJoCo, save to
    ``model_path`` (None: not saved).  Returns the fitted model."""
    env = make_env()
    mj_model = env.unwrapped.model
    p = parameters(mj_model)
    t0 = time.perf_counter()
    trajs = collect(n_runs, t_end, seed=seed, env=env)
    t1 = time.perf_counter()
    model = identify(trajs, {"polynomial": library, "physical": physical_library}[lib]())
    t2 = time.perf_counter()
    if verbose:
        print(f"{ENV_ID}: cart {p['mc']:.4f} kg; links {p['m1']:.4f} kg, com {p['c1']} m, "
              f"I_com {p['I1']:.5f} kg m^2, hinge2 at {p['L1']} m; damping {p['damping']}; "
              f"gear {p['gear']}; ctrlrange {p['ctrlrange']}; slider {p['slider_range']} "
              f"(limited {p['slider_limited']}, margin {p['slider_margin']}); "
              f"{p['integrator']} at {p['timestep']} s; gravity ({p['gx']}, 0, -{p['g']})")
        print(f"data: {n_runs} runs x {t_end} s at 100 Hz ({t1 - t0:.1f} s); {lib} library of "
              f"{len(model.library)} terms; fit {t2 - t1:.1f} s")
        print(printing.describe(model, digits=5))
        cmp = compare(model, mj_model)
        print("\nterm: identified, true, relative error")
        for part in ("H", "R"):
            for k, (f, t) in cmp[part].items():
                rel = f"{abs(f - t) / abs(t):.1e}" if t else "(true 0)"
                print(f"  {part}  {k:42s} {f:+.6f} {t:+.6f} {rel}")
        print(f"worst relative error: H {worst_relative_error(cmp['H']):.1e}, "
              f"R {worst_relative_error(cmp['R']):.1e}")
        acc = acceleration_errors(model, mj_model=mj_model)
        print(f"ode() vs MuJoCo qacc (mj_forward) at {acc.size} random states: max relative "
              f"error {acc.max():.1e}")
        print(f"one env step (0.05 s) from 50 random states: max state error "
              f"{step_errors(model, mj_model=mj_model).max():.1e}")
        print(f"H vs MuJoCo's energy along run 0: max deviation "
              f"{energy_deviation(model, trajs[0], mj_model):.1e} of its range")
        print(f"support search: proven {model.search_.proven}, {model.search_.nodes} nodes; "
              f"status {model.status_}" + "".join(f"\n  - {r}" for r in model.status_reasons_))
        if not model.ok_:
            print("  (expected: the env's RK4 steps of 10 ms and its 1e-5 m/s^2 horizontal gravity "
                  "leave a residual far above this clean data's noise floor; see the module "
                  "docstring)")
    if model_path is not None:
        path = model.save(model_path)
        if verbose:
            print(f"model saved to {path}")
    env.close()
    return model


if __name__ == "__main__":
    main()
