"""MuJoCo plants: the project's benchmark systems simulated by an engine we did not write.

An independent simulator is the judge of the identification (its own energy, ``mjENBL_ENERGY``, and
its own damping parameters) and of the controller (the loop closed on its dynamics).  ``mujoco`` is
an optional extra (``pip install lsindy_cas[mujoco]``), imported when a plant is built.

Conventions are the project's (DESIGN.md), not MuJoCo's:

* cart-pendulum: ``x`` (cart position, m) and ``theta`` from the **downward** vertical, the pole a
  point mass ``mp`` at distance ``L`` (the rod massless), ``Q_x`` the force on the cart;
* double pendulum: **absolute** angles ``theta1``, ``theta2`` from the downward vertical (MuJoCo's
  second hinge is relative: θ2 = q1 + q2), point masses at the rod ends, ``Q_theta1`` the moment on
  the first link.

Point masses are bodies with an explicit ``<inertial>`` of mass m and a rotational inertia of
``POINT_INERTIA`` (MuJoCo needs a positive one): its kinetic energy is ~1e-9 of the system's.
Friction: MuJoCo joint ``damping`` b is viscous, force −b q̇, i.e. a Rayleigh function
R = b q̇²/2 — on the second hinge of the double pendulum it acts on the relative rate θ̇2 − θ̇1.
``frictionloss`` μ (dry friction on the cart) is a soft box constraint |f| ≤ μ, not an exact
Coulomb force: MuJoCo's constraint force is f = −clip((a₀ + b·v)/(A + R), μ) with a₀ the
unconstrained acceleration, A the inverse inertia, b = 2/(d_max·timeconst) from ``solreffriction``
and R = (1 − d)/d times MuJoCo's approximation of A (its inertia at the model's reference pose), d
from ``solimpfriction`` (checked against MuJoCo's ``efc_force`` to 4e-15 at random states).  So
it slides with exactly f = −μ·sign(v + a₀/b) — the sign switches a velocity a₀/b (a time ~1/b)
away from v = 0 — and sticks (|f| < μ) with a creep speed ~(1 − d)a₀/(d b).  The Rayleigh term μ|v| (force μ·sign(v)) is what it tends to as the time
constant goes to 0: ``friction_timeconst`` sets it (MuJoCo's default 0.02 s; it clamps it to two
timesteps), ``friction_impedance`` sets d (default 0.9, rising to 0.95).

Inputs are held over each sample (a digital controller's zero-order hold): the value at t_i acts on
[t_i, t_{i+1}); MuJoCo integrates with RK4 at ``substeps`` steps per sample.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["MujocoPlant", "ClosedLoop", "cart_pendulum", "double_pendulum", "POINT_INERTIA"]

G = 9.81
POINT_INERTIA = 1e-10       # kg m²: the "point" masses' rotational inertia (MuJoCo needs > 0)


def _mujoco():
    try:
        import mujoco
    except ImportError as exc:                       # pragma: no cover - depends on the machine
        raise ImportError("the MuJoCo plants need the optional extra 'mujoco' "
                          "(pip install mujoco)") from exc
    return mujoco


def _point(name: str, mass: float, pos: str) -> str:
    i = POINT_INERTIA
    return (f'<body name="{name}" pos="{pos}"><inertial pos="0 0 0" mass="{mass!r}" '
            f'diaginertia="{i} {i} {i}"/>')


_MASSLESS = (f'<inertial pos="0 0 0" mass="1e-9" '
             f'diaginertia="{POINT_INERTIA} {POINT_INERTIA} {POINT_INERTIA}"/>')


def _model(name: str, g, timestep, bodies: str, actuator: str) -> str:
    """One MJCF model: RK4 at ``timestep``, no contacts, energy computed, the given bodies."""
    return f"""<mujoco model="{name}">
  <option timestep="{timestep!r}" gravity="0 0 {-g!r}" integrator="RK4">
    <flag contact="disable" energy="enable"/>
  </option>
  <worldbody>
    {bodies}
  </worldbody>
  <actuator>{actuator}</actuator>
</mujoco>"""


def _cart_xml(mc, mp, L, g, cart_damping, pivot_damping, cart_frictionloss, timestep,
              friction="") -> str:
    # hinge axis -y: rotating (0, 0, -L) by theta about -y gives (L sin θ, 0, -L cos θ)
    return _model("cart_pendulum", g, timestep, f"""{_point("cart", mc, "0 0 0")}
      <joint name="x" type="slide" axis="1 0 0" damping="{cart_damping!r}"
             frictionloss="{cart_frictionloss!r}"{friction}/>
      <body name="pivot" pos="0 0 0">
        {_MASSLESS}
        <joint name="theta" type="hinge" axis="0 -1 0" damping="{pivot_damping!r}"/>
        {_point("bob", mp, f"0 0 {-L!r}")}</body>
      </body>
    </body>""", '<motor name="force" joint="x" gear="1"/>')


def _double_xml(m1, m2, L1, L2, g, damping1, damping2, timestep) -> str:
    return _model("double_pendulum", g, timestep, f"""<body name="link1" pos="0 0 0">
      {_MASSLESS}
      <joint name="q1" type="hinge" axis="0 -1 0" damping="{damping1!r}"/>
      {_point("bob1", m1, f"0 0 {-L1!r}")}
        <joint name="q2" type="hinge" axis="0 -1 0" damping="{damping2!r}"/>
        {_point("bob2", m2, f"0 0 {-L2!r}")}</body>
      </body>
    </body>""", '<motor name="moment" joint="q1" gear="1"/>')


@dataclass
class MujocoPlant:
    """A MuJoCo model with the project's coordinates.

    Parameters
    ----------
    xml : str
        MJCF text.
    coords : list of str
        The project's coordinate names.
    actuated : str
        The coordinate the single actuator drives.
    to_project : callable
        (qpos, qvel) -> (q, q̇) in the project's coordinates.
    to_mujoco : callable
        (q, q̇) -> (qpos, qvel).
    rayleigh : dict
        The true Rayleigh function's terms {sympy name: coefficient} (R = Σ c·term).
    parameters : dict
        The physical parameters the plant was built from.
    """

    xml: str
    coords: list
    actuated: str
    to_project: object
    to_mujoco: object
    rayleigh: dict = field(default_factory=dict)
    parameters: dict = field(default_factory=dict)

    def __post_init__(self):
        mj = _mujoco()
        self._mj = mj
        self.model = mj.MjModel.from_xml_string(self.xml)
        self.data = mj.MjData(self.model)

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    def reset(self, x) -> None:
        """Set the state x = [q, q̇] (project coordinates) and zero the input."""
        n = len(self.coords)
        x = np.asarray(x, float)
        qpos, qvel = self.to_mujoco(x[:n], x[n:])
        self._mj.mj_resetData(self.model, self.data)
        self.data.qpos[:] = qpos
        self.data.qvel[:] = qvel
        self.data.ctrl[:] = 0.0
        self._mj.mj_forward(self.model, self.data)

    def state(self) -> np.ndarray:
        q, qd = self.to_project(np.array(self.data.qpos), np.array(self.data.qvel))
        return np.concatenate([q, qd])

    def energy(self) -> float:
        """MuJoCo's own total energy (potential + kinetic, ``mjENBL_ENERGY``) at the current state."""
        self._mj.mj_energyPos(self.model, self.data)
        self._mj.mj_energyVel(self.model, self.data)
        return float(self.data.energy[0] + self.data.energy[1])

    def step(self, u: float, dt: float) -> np.ndarray:
        """Hold the input ``u`` for ``dt`` seconds (a whole number of MuJoCo steps); new state."""
        n_sub = int(round(dt / self.timestep))
        if n_sub < 1 or abs(n_sub * self.timestep - dt) > 1e-9 * max(dt, 1.0):
            raise ValueError(f"dt ({dt}) must be a whole multiple of the MuJoCo timestep "
                             f"({self.timestep})")
        self.data.ctrl[0] = float(u)
        for _ in range(n_sub):
            self._mj.mj_step(self.model, self.data)
        return self.state()

    def simulate(self, x0, u, dt: float = 0.01):
        """Record a run: ``u`` (n_samples,) held over each sample of length ``dt``.

        Returns
        -------
        dict with ``t`` (n,), ``X`` (n, 2·n_coords) project states, ``Q`` (n, n_coords) applied
        forces (the held value at each sample; the last one repeats), ``energy`` (n,) MuJoCo's.
        """
        u = np.asarray(u, float).ravel()
        n_c = len(self.coords)
        self.reset(x0)
        X = np.empty((len(u) + 1, 2 * n_c))
        E = np.empty(len(u) + 1)
        X[0], E[0] = self.state(), self.energy()
        for i, ui in enumerate(u):
            X[i + 1] = self.step(ui, dt)
            E[i + 1] = self.energy()
        Q = np.zeros((len(u) + 1, n_c))
        Q[:, self.coords.index(self.actuated)] = np.append(u, u[-1] if len(u) else 0.0)
        return {"t": np.arange(len(u) + 1) * dt, "X": X, "Q": Q, "energy": E}

    def trajectory(self, x0, u, dt: float = 0.01, source: str = "mujoco"):
        """:meth:`simulate` as a project :class:`~lsindy_cas.data.trajectory.Trajectory` (no q̈)."""
        from ..data.trajectory import Trajectory
        run = self.simulate(x0, u, dt)
        n = len(self.coords)
        return Trajectory(run["t"], run["X"][:, :n], run["X"][:, n:], self.coords, Q=run["Q"],
                          source=source), run["energy"]


def cart_pendulum(mc=1.0, mp=0.1, L=1.0, g=G, cart_damping=0.0, pivot_damping=0.0,
                  cart_frictionloss=0.0, timestep=1e-3, friction_timeconst=None,
                  friction_impedance=None) -> MujocoPlant:
    """The cart-pendulum (DESIGN.md convention) in MuJoCo, with optional friction.

    ``cart_damping`` b_x and ``pivot_damping`` b_θ give R = b_x ẋ²/2 + b_θ θ̇²/2;
    ``cart_frictionloss`` μ adds MuJoCo's dry friction on the cart, nominally μ|ẋ| in R (the plant's
    ``rayleigh``), in fact a soft constraint (module docstring).  ``friction_timeconst`` (s) and
    ``friction_impedance`` (d in (0, 1)) set that constraint's ``solreffriction`` time constant
    (damping ratio 1) and ``solimpfriction`` impedance (d at both ends); None keeps MuJoCo's
    defaults (0.02 s; 0.9 to 0.95).
    """
    for name, v in (("mc", mc), ("mp", mp), ("L", L), ("timestep", timestep)):
        if not v > 0:
            raise ValueError(f"{name} must be positive, got {v}")
    for name, v in (("cart_damping", cart_damping), ("pivot_damping", pivot_damping),
                    ("cart_frictionloss", cart_frictionloss)):
        if not v >= 0:
            raise ValueError(f"{name} must be non-negative, got {v}")
    friction = ""
    if friction_timeconst is not None:
        if not friction_timeconst >= 2 * timestep:
            raise ValueError(f"friction_timeconst must be at least two timesteps "
                             f"({2 * timestep!r} s; MuJoCo clamps it), got {friction_timeconst}")
        friction += f' solreffriction="{friction_timeconst!r} 1"'
    if friction_impedance is not None:
        if not 0 < friction_impedance < 1:
            raise ValueError(f"friction_impedance must be in (0, 1), got {friction_impedance}")
        d = friction_impedance
        friction += f' solimpfriction="{d!r} {d!r} 0.001 0.5 2"'
    rayleigh = {k: v / 2 for k, v in (("x_dot**2", cart_damping), ("theta_dot**2", pivot_damping)) if v}
    if cart_frictionloss:
        rayleigh["Abs(x_dot)"] = cart_frictionloss
    return MujocoPlant(
        _cart_xml(mc, mp, L, g, cart_damping, pivot_damping, cart_frictionloss, timestep, friction),
        ["x", "theta"], "x", to_project=lambda qp, qv: (qp, qv), to_mujoco=lambda q, qd: (q, qd),
        rayleigh=rayleigh, parameters=dict(mc=mc, mp=mp, L=L, g=g, cart_damping=cart_damping,
                                           pivot_damping=pivot_damping,
                                           cart_frictionloss=cart_frictionloss,
                                           friction_timeconst=friction_timeconst,
                                           friction_impedance=friction_impedance))


def double_pendulum(m1=1.0, m2=1.0, L1=1.0, L2=1.0, g=G, damping1=0.0, damping2=0.0,
                    timestep=1e-3) -> MujocoPlant:
    """The double pendulum (absolute angles, DESIGN.md) in MuJoCo, with optional joint damping.

    ``damping1`` acts on θ̇1 (joint to the world), ``damping2`` on the relative rate θ̇2 − θ̇1:
    R = b1 θ̇1²/2 + b2 (θ̇2 − θ̇1)²/2.
    """
    for name, v in (("m1", m1), ("m2", m2), ("L1", L1), ("L2", L2), ("timestep", timestep)):
        if not v > 0:
            raise ValueError(f"{name} must be positive, got {v}")
    for name, v in (("damping1", damping1), ("damping2", damping2)):
        if not v >= 0:
            raise ValueError(f"{name} must be non-negative, got {v}")
    rayleigh = {}
    if damping1:
        rayleigh["theta1_dot**2"] = damping1 / 2
    if damping2:   # b2/2 (θ̇2 − θ̇1)² expanded
        rayleigh["theta1_dot**2"] = rayleigh.get("theta1_dot**2", 0.0) + damping2 / 2
        rayleigh["theta1_dot*theta2_dot"] = -damping2
        rayleigh["theta2_dot**2"] = damping2 / 2

    def to_project(qp, qv):
        return np.array([qp[0], qp[0] + qp[1]]), np.array([qv[0], qv[0] + qv[1]])

    def to_mujoco(q, qd):
        return np.array([q[0], q[1] - q[0]]), np.array([qd[0], qd[1] - qd[0]])

    return MujocoPlant(_double_xml(m1, m2, L1, L2, g, damping1, damping2, timestep),
                       ["theta1", "theta2"], "theta1", to_project=to_project, to_mujoco=to_mujoco,
                       rayleigh=rayleigh, parameters=dict(m1=m1, m2=m2, L1=L1, L2=L2, g=g,
                                                          damping1=damping1, damping2=damping2))


class ClosedLoop:
    """A :class:`MujocoPlant` as the plant of closed-loop episodes (the ``Plant`` interface of
    :func:`lsindy_cas.paper.swingup.run_episode`): ``step(x, force)`` holds ``force`` for ``dt``
    from state ``x`` and returns ``n_out`` states over the period, the last at its end.

    The state is set from ``x`` at every step, so MuJoCo integrates exactly the episode's states
    (its warm-start data are cleared; no contacts are modelled, so nothing else is lost).
    """

    def __init__(self, plant: MujocoPlant, dt: float, n_out: int = 5):
        self.plant, self.dt, self.n_out = plant, float(dt), int(n_out)
        self.coords = list(plant.coords)
        self.input_index = self.coords.index(plant.actuated)
        n_sub = dt / plant.timestep
        if abs(n_sub - round(n_sub)) > 1e-9 or round(n_sub) % self.n_out:
            raise ValueError(f"dt ({dt}) must be a multiple of n_out ({n_out}) MuJoCo steps "
                             f"({plant.timestep} s)")

    def step(self, x, force):
        self.plant.reset(x)
        sub = self.dt / self.n_out
        return np.array([self.plant.step(force, sub) for _ in range(self.n_out)])
