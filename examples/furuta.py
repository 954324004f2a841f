"""Rotary (Furuta) pendulum in MuJoCo: energy, damping and equations of motion identified from
motor-torque runs, checked against MuJoCo's own inertias and energy.

The plant is ``examples/data/furuta.xml`` (a QUBE-Servo-2-like rig, scaled up ~1.5x): an arm of
0.15 m (0.10 kg) turned by a motor about the vertical (``phi``), a 0.20 m rod (0.05 kg) swinging
about the arm's long axis (``theta``; 0 hanging, pi upright), viscous damping on both joints, motor
torque limited to +-0.03 N m.  Its exact energy, from the rigid-body inertias MuJoCo computed from
the geoms (:func:`true_hamiltonian`; J_arm is the arm's inertia about the shaft, m, l, I_xx, I_yy,
I_zz the rod's mass, centre-of-mass distance and central inertias about the hinge, the horizontal
normal and its own axis, L_r the arm length)::

    H = (J_arm + m L_r² + I_zz)/2 φ̇² + (m l² + I_yy − I_zz)/2 φ̇² sin²θ + (m l² + I_xx)/2 θ̇²
        + m L_r l φ̇ θ̇ cos θ − m g l cos θ

and its Rayleigh function R = b_φ/2 φ̇² + b_θ/2 θ̇² (MuJoCo's joint ``damping``).

The data: runs of a motor torque drawn at random from the controller's level set
``FurutaPlant.LEVELS`` = {−τ, 0, +τ} and held for ``hold`` seconds (each value acts over whole
10 ms samples, as a digital controller's output does), positions and rates recorded at 100 Hz,
no accelerations (the integral form of the energy balance; the engine never sees MuJoCo's
equations).

The library (:func:`library`): all products of cos θ, sin θ, φ, φ̇, θ̇ up to degree 4 with the
products containing cos²θ left out — cos²θ = 1 − sin²θ, and a constant is invisible to the energy
balance, so with them the library would hold exact copies (φ̇² cos²θ = φ̇² − φ̇² sin²θ) and the
support would not be unique.  What is left (104 terms) is a basis.  Priors: the arm's and the
simple pendulum's terms φ̇², θ̇², cos θ; the search finds the two coupling terms among the other
101 (all 5,050 pairs scored).

Run:  python examples/furuta.py          (writes examples/data/furuta_model.json)
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lsindy_cas import LagrangianSINDy, Library, printing

HERE = Path(__file__).resolve().parent
XML = HERE / "data" / "furuta.xml"
MODEL = HERE / "data" / "furuta_model.json"

COORDS = ["phi", "theta"]
FEATURES = ["cos(theta)", "sin(theta)", "phi", "phi_dot", "theta_dot"]
DEGREE = 4
PRIOR = ["phi_dot**2", "theta_dot**2", "cos(theta)"]
DISSIPATION = ["phi_dot**2", "theta_dot**2"]
N_TERMS = 5
TAU = 0.03           # N m: the motor's torque limit (the XML's ctrlrange) and the level set's step
DT = 0.01            # s: the sample time of the data and of a controller


def _mujoco():
    try:
        import mujoco
    except ImportError as exc:                       # pragma: no cover - depends on the machine
        raise ImportError("the Furuta example needs MuJoCo (pip install mujoco)") from exc
    return mujoco


class FurutaPlant:
    """The MuJoCo Furuta pendulum in the model's coordinates.

    State ``x = [phi, theta, phi_dot, theta_dot]`` (rad, rad/s; theta = 0 hanging, pi upright;
    phi and theta are not wrapped), input ``u`` the motor torque on phi (N m) = the generalized
    force Q_phi.  MuJoCo integrates (RK4, 1 ms); ``u`` is held over each ``step``.  MuJoCo clips
    ``u`` to the motor's range [-TAU, TAU] (ctrllimited); ``LEVELS`` is the torque level set for
    control.

    Methods: ``reset(x0) -> x``, ``step(u, dt=0.01) -> x``, ``state() -> x``, ``energy()``
    (MuJoCo's potential + kinetic energy, mjENBL_ENERGY), ``acceleration(x, u)`` (MuJoCo's q̈),
    ``hanging_start(rng) -> x0``,
    ``trajectory(x0, u, dt)`` (a recorded run), ``true_hamiltonian()``, ``true_rayleigh()``.
    """

    LEVELS = (-TAU, 0.0, TAU)
    coords = COORDS
    actuated = "phi"

    def __init__(self, xml_path=XML):
        from lsindy_cas.plants.mujoco import MujocoPlant
        xml = Path(xml_path).read_text()
        identity = (lambda a, b: (np.asarray(a, float), np.asarray(b, float)))
        self.plant = MujocoPlant(xml, list(COORDS), self.actuated, to_project=identity,
                                 to_mujoco=identity)
        self.model, self.data = self.plant.model, self.plant.data
        self.plant.rayleigh = self.true_rayleigh()
        lo, hi = self.model.actuator_ctrlrange[0]
        if not (self.model.actuator_ctrllimited[0] and np.isclose(-lo, TAU) and np.isclose(hi, TAU)):
            raise ValueError(f"{xml_path}: the motor's ctrlrange must be [-{TAU}, {TAU}] (limited)")
        if self.model.opt.timestep != 1e-3:
            raise ValueError(f"{xml_path}: timestep must be 1e-3 s")

    @property
    def timestep(self) -> float:
        return self.plant.timestep

    def reset(self, x0) -> np.ndarray:
        """Set the state (input zeroed); returns it."""
        x0 = np.asarray(x0, float).ravel()
        if x0.shape != (4,) or not np.all(np.isfinite(x0)):
            raise ValueError(f"x0 must be 4 finite numbers [phi, theta, phi_dot, theta_dot], got {x0}")
        self.plant.reset(x0)
        return self.state()

    def state(self) -> np.ndarray:
        return self.plant.state()

    def step(self, u: float, dt: float = DT) -> np.ndarray:
        """Hold the torque ``u`` (N m; clipped to [-TAU, TAU]) for ``dt`` s (a whole number of
        1 ms MuJoCo steps); returns the new state."""
        return self.plant.step(float(u), dt)

    def energy(self) -> float:
        """MuJoCo's total energy at the current state (zero of potential: theta = pi/2 level)."""
        return self.plant.energy()

    def energy_at(self, X) -> np.ndarray:
        """MuJoCo's energy at each state of ``X`` (n, 4), kinematics recomputed (``mj_forward``)
        at each; the plant's state is restored.  (The energy read right after ``mj_step``, as
        ``trajectory`` records it, comes from the kinematics of the step's last RK4 stage, ~1e-6
        of the energy's range off.)"""
        keep, E = self.state(), []
        for x in np.atleast_2d(np.asarray(X, float)):
            self.reset(x)
            E.append(self.energy())
        self.reset(keep)
        return np.array(E)

    def acceleration(self, x, u: float) -> np.ndarray:
        """MuJoCo's [phi_ddot, theta_ddot] at state ``x`` under torque ``u`` (damping included);
        the plant's state is restored."""
        mj, keep = _mujoco(), self.state()
        self.reset(x)
        self.data.ctrl[0] = float(u)
        mj.mj_forward(self.model, self.data)
        qacc = np.array(self.data.qacc)
        self.reset(keep)
        return qacc

    @staticmethod
    def hanging_start(rng, spread: float = 0.05) -> np.ndarray:
        """A start near hanging: each of phi, theta (rad) and their rates (rad/s) uniform in
        [-spread, spread]."""
        return np.asarray(rng.uniform(-spread, spread, 4), float)

    def trajectory(self, x0, u, dt: float = DT, source: str = "mujoco:furuta"):
        """A run from ``x0`` under the torques ``u`` (each held over one sample of ``dt``):
        (Trajectory with Q_phi = u, Q_theta = 0; MuJoCo's energy at each sample)."""
        return self.plant.trajectory(x0, u, dt, source=source)

    # ------------------------------------------------------------------ the truth
    def true_hamiltonian(self) -> dict:
        """H's coefficients {term: value} from MuJoCo's own body masses, inertias and positions."""
        mj, m = _mujoco(), self.model
        arm, pend = (mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, n) for n in ("arm", "pendulum"))

        def inertia(b):                               # central inertia tensor in the body frame
            R = np.empty(9)
            mj.mju_quat2Mat(R, m.body_iquat[b])
            R = R.reshape(3, 3)
            return R @ np.diag(m.body_inertia[b]) @ R.T

        Ia, Ip = inertia(arm), inertia(pend)
        ma, mp = float(m.body_mass[arm]), float(m.body_mass[pend])
        ca, cp = m.body_ipos[arm], m.body_ipos[pend]
        Lr = float(m.body_pos[pend][0])
        g = -float(m.opt.gravity[2])
        # the formula above assumes: pivot on the arm's x axis, rod's centre of mass straight below
        # the pivot, rod's principal axes along the hinge frame (checked, not assumed)
        scale = np.abs(Ip).max()
        if (np.abs(m.body_pos[pend][1:]).max() > 1e-12 or np.abs(cp[:2]).max() > 1e-12
                or np.abs(Ip - np.diag(np.diag(Ip))).max() > 1e-9 * scale
                or np.abs(m.body_quat[pend] - [1, 0, 0, 0]).max() > 1e-12):
            raise ValueError("the pendulum body is not in the layout true_hamiltonian() assumes")
        l = -float(cp[2])
        J_arm = Ia[2, 2] + ma * (ca[0] ** 2 + ca[1] ** 2)
        Ixx, Iyy, Izz = np.diag(Ip)
        return {"phi_dot**2": (J_arm + mp * Lr ** 2 + Izz) / 2,
                "phi_dot**2*sin(theta)**2": (mp * l ** 2 + Iyy - Izz) / 2,
                "theta_dot**2": (mp * l ** 2 + Ixx) / 2,
                "phi_dot*theta_dot*cos(theta)": mp * Lr * l,
                "cos(theta)": -mp * g * l}

    def true_rayleigh(self) -> dict:
        """R's coefficients from MuJoCo's joint damping (R = b/2 q̇² per joint)."""
        b = self.model.dof_damping
        return {f"{c}_dot**2": float(b[i]) / 2 for i, c in enumerate(COORDS) if b[i]}


# ---------------------------------------------------------------------- data and identification
def collect(n_runs: int = 3, t_end: float = 4.0, seed: int = 0, hold: float = 0.1,
            dt: float = DT, plant: FurutaPlant | None = None) -> list:
    """``n_runs`` MuJoCo runs of ``t_end`` s: motor torques drawn from ``FurutaPlant.LEVELS``,
    each held for ``hold`` s (rounded to whole samples), sampled at ``dt``.

    Each run starts at phi = 0 with the pendulum at a random angle (uniform over the circle) and
    small random rates (uniform in ±1 rad/s), so the data cover hanging, swinging and whirling.

    Returns
    -------
    list of Trajectory
        coords ``["phi", "theta"]``, measured rates, ``Q = [torque, 0]`` (the held value at each
        sample), no accelerations.
    """
    plant = plant or FurutaPlant()
    rng = np.random.default_rng(seed)
    n = int(round(t_end / dt))
    per = max(1, int(round(hold / dt)))
    runs = []
    for i in range(int(n_runs)):
        x0 = np.array([0.0, rng.uniform(-np.pi, np.pi), *rng.uniform(-1.0, 1.0, 2)])
        u = np.repeat(rng.choice(plant.LEVELS, -(-n // per)), per)[:n]
        runs.append(plant.trajectory(x0, u, dt, source=f"mujoco:furuta:{seed}:{i}")[0])
    return runs


def library() -> Library:
    """Products of cos θ, sin θ, φ, φ̇, θ̇ up to degree 4, without those containing cos²θ
    (exact copies of other terms, see the module docstring)."""
    import sympy as sp
    full = Library.polynomial(COORDS, FEATURES, DEGREE)
    keep = [e for e in full.exprs
            if not any(b.func == sp.cos and p >= 2 for b, p in e.as_powers_dict().items())]
    return Library(COORDS, keep)


def identify(trajs) -> LagrangianSINDy:
    """The fitted model: 5 terms of :func:`library` with the priors φ̇², θ̇², cos θ, and the
    Rayleigh candidates φ̇², θ̇²."""
    return LagrangianSINDy(library(), n_terms=N_TERMS, prior=PRIOR,
                           dissipation=DISSIPATION).fit(trajs)


def hamiltonian_at(model, X) -> np.ndarray:
    """The identified H at the states ``X`` (n, 4)."""
    X = np.atleast_2d(np.asarray(X, float))
    lib = model.library
    cols = lib.theta(X)
    return cols @ np.asarray(model.coef_, float)


def energy_error(model, plant: FurutaPlant, trajs) -> float:
    """Largest |H − E_MuJoCo| (each with its mean removed, the potentials' zeros differ) over the
    runs, relative to the range of MuJoCo's energy."""
    worst = 0.0
    for tr in trajs:
        X = np.hstack([tr.q, tr.qd])
        H, E = hamiltonian_at(model, X), plant.energy_at(X)
        worst = max(worst, float(np.max(np.abs((H - H.mean()) - (E - E.mean()))) / np.ptp(E)))
    return worst


def acceleration_error(model, plant: FurutaPlant, n: int = 200, seed: int = 0) -> float:
    """Largest |q̈_model − q̈_MuJoCo| over ``n`` random states (angles anywhere, rates within
    ±8 rad/s) and torques from the level set, relative to the largest |q̈_MuJoCo|."""
    rng = np.random.default_rng(seed)
    ode = model.ode()
    worst = scale = 0.0
    for _ in range(n):
        x = np.r_[rng.uniform(-np.pi, np.pi, 2), rng.uniform(-8.0, 8.0, 2)]
        u = float(rng.choice(plant.LEVELS))
        a_mj = plant.acceleration(x, u)
        a_id = np.asarray(ode(x, [u, 0.0])).ravel()[2:]
        worst = max(worst, float(np.max(np.abs(a_id - a_mj))))
        scale = max(scale, float(np.max(np.abs(a_mj))))
    return worst / scale


def compare(model, plant: FurutaPlant) -> dict:
    """{term: (identified, true, relative error)} for H and R (a term missing on either side
    gets 0 there)."""
    out = {}
    for which, truth in (("hamiltonian", plant.true_hamiltonian()),
                         ("rayleigh", plant.true_rayleigh())):
        got = model.terms(which)
        for name in sorted(set(got) | set(truth)):
            a, b = got.get(name, 0.0), truth.get(name, 0.0)
            out[(which, name)] = (a, b, abs(a - b) / abs(b) if b else float("inf"))
    return out


def main(model_path=MODEL, n_runs: int = 3, t_end: float = 4.0, seed: int = 0,
         hold: float = 0.1, verbose: bool = True) -> LagrangianSINDy:
    """Collect, identify, compare with MuJoCo's inertias and energy, save the model."""
    plant = FurutaPlant()
    t0 = time.perf_counter()
    trajs = collect(n_runs, t_end, seed, hold, plant=plant)
    t1 = time.perf_counter()
    model = identify(trajs)
    t2 = time.perf_counter()
    table = compare(model, plant)
    check = collect(1, 5.0, seed + 1000, 0.2, plant=plant)     # unseen run: energy vs MuJoCo's
    e_fit, e_check = energy_error(model, plant, trajs), energy_error(model, plant, check)
    if verbose:
        print(f"{len(model.library)} candidate terms; {n_runs} runs x {t_end:g} s, torque levels "
              f"{plant.LEVELS} N m held {hold:g} s (MuJoCo {t1 - t0:.1f} s, fit {t2 - t1:.1f} s)\n")
        print(printing.describe(model, digits=6))
        print("\nterm                              identified      MuJoCo      rel. error")
        for (which, name), (a, b, err) in table.items():
            tag = "R: " if which == "rayleigh" else "H: "
            print(f"{tag}{name:30s} {a:12.6e} {b:12.6e} {err:10.1e}")
        print(f"\nH vs MuJoCo's energy (mjENBL_ENERGY), max deviation / range: training {e_fit:.1e},"
              f" unseen run {e_check:.1e}")
        print(f"status: {model.status_}" + (f" ({'; '.join(model.status_reasons_)})"
                                            if model.status_reasons_ else ""))
    if model_path is not None:
        path = model.save(model_path)
        loaded = LagrangianSINDy.load(path)
        e_acc = acceleration_error(loaded, plant)
        if verbose:
            print(f"model saved to {path}; its ODE against MuJoCo's accelerations (200 random "
                  f"states and level-set torques): max error / max |q̈| {e_acc:.1e}")
    return model


if __name__ == "__main__":
    main()
