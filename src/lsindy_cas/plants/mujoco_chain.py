"""A chain of capsule links on hinges in MuJoCo (double, triple pendulum), with joint damping, and
the sensors of a real rig: the judge of passive (free-swing) identification with friction.

Convention (MuJoCo's own, unlike :func:`lsindy_cas.plants.mujoco.double_pendulum`): ``theta1`` is
the first link's angle from the downward vertical, ``theta{i}`` (i ≥ 2) the angle of link i
**relative** to link i − 1 — what a joint encoder reads.  Link i is a capsule of mass m_i from its
joint to the next one (length L_i, radius r_i: centre of mass at L_i/2, inertia from MuJoCo's
capsule formula: cylinder plus two hemispheres).  Joint ``damping`` b_i is viscous on the joint's
own rate, torque −b_i θ̇_i, so R = Σ b_i θ̇_i²/2 (no cross terms).

With relative angles the energy of an n-link chain is a polynomial in cos/sin of the angles and
the rates: the kinetic cross terms are ω_i ω_j cos(θ_{i+1} + … + θ_j) with ω_i = θ̇_1 + … + θ̇_i,
and the potential −g Σ m_i z_i has cos(θ_1 + … + θ_i).  :func:`energy_terms` expands both into the
library's monomials (double pendulum: 8 terms of degree ≤ 3; triple: 26 of degree ≤ 4), with the
coefficients from the **compiled** MuJoCo model (``body_mass``, ``body_ipos``, ``body_inertia``).

Sensors (:func:`measure`): angles quantised by an encoder of ``resolution`` rad per count (default
2π/4096, a 12-bit encoder), rates with white noise of std ``rate_noise`` (a rate gyro).
"""
from __future__ import annotations

import numpy as np

from .mujoco import G, MujocoPlant

__all__ = ["pendulum_chain", "energy_terms", "measure", "free_swings", "ENCODER_12BIT"]

ENCODER_12BIT = 2 * np.pi / 4096        # rad per count of a 12-bit absolute encoder


def _chain_xml(masses, lengths, radii, damping, g, timestep) -> str:
    bodies, close = "", ""
    for i, (m, L, r, b) in enumerate(zip(masses, lengths, radii, damping)):
        pos = "0 0 0" if i == 0 else f"0 0 {-lengths[i - 1]!r}"
        bodies += (f'<body name="link{i + 1}" pos="{pos}">'
                   f'<joint name="theta{i + 1}" type="hinge" axis="0 -1 0" damping="{b!r}"/>'
                   f'<geom type="capsule" fromto="0 0 0 0 0 {-L!r}" size="{r!r}" mass="{m!r}"/>')
        close += "</body>"
    return f"""<mujoco model="pendulum_chain_{len(masses)}">
  <option timestep="{timestep!r}" gravity="0 0 {-g!r}" integrator="RK4">
    <flag contact="disable" energy="enable"/>
  </option>
  <worldbody>{bodies}{close}</worldbody>
  <actuator><motor name="moment" joint="theta1" gear="1"/></actuator>
</mujoco>"""


def pendulum_chain(masses=(1.0, 0.6), lengths=(0.5, 0.4), radii=(0.03, 0.03), damping=(0.02, 0.01),
                   g=G, timestep=1e-3) -> MujocoPlant:
    """An n-link chain of capsules (n = len(masses)) on hinges, relative angles, joint damping.

    The single actuator is a moment on the first joint (for scale trials; free swings use u = 0).
    The plant's ``rayleigh`` is {``theta{i}_dot**2``: b_i/2}.
    """
    n = len(masses)
    if n < 1 or not (len(lengths) == len(radii) == len(damping) == n):
        raise ValueError("masses, lengths, radii and damping need one entry per link")
    for name, vals in (("masses", masses), ("lengths", lengths), ("radii", radii)):
        if not all(v > 0 for v in vals):
            raise ValueError(f"{name} must be positive, got {list(vals)}")
    if not all(b >= 0 for b in damping):
        raise ValueError(f"damping must be non-negative, got {list(damping)}")
    coords = [f"theta{i + 1}" for i in range(n)]
    rayleigh = {f"{c}_dot**2": b / 2 for c, b in zip(coords, damping) if b}
    return MujocoPlant(_chain_xml(masses, lengths, radii, damping, g, timestep), coords, coords[0],
                       to_project=lambda qp, qv: (qp, qv), to_mujoco=lambda q, qd: (q, qd),
                       rayleigh=rayleigh,
                       parameters=dict(masses=list(masses), lengths=list(lengths),
                                       radii=list(radii), damping=list(damping), g=g))


def energy_terms(plant: MujocoPlant) -> dict:
    """The chain's total energy H = T + V as {library term name: coefficient}, expanded into
    products of cos/sin of the (relative) angles and the rates, from the compiled model.

    T = Σ_i ½ m_i |v_i|² + ½ I_i ω_i² with v_i the velocity of link i's centre of mass and I_i its
    inertia about the hinge direction through the centre of mass; V = Σ_i m_i g z_i (MuJoCo's zero:
    the first joint).  Terms whose coefficient is below 1e-12 of the largest are dropped (what the
    expansion leaves of cancelled terms).
    """
    import sympy as sp
    from ..symbolic.coords import Coordinates
    m, d = plant.model, plant.data
    n = len(plant.coords)
    q = sp.symbols(plant.coords)
    qd = sp.symbols([c + "_dot" for c in plant.coords])
    g = -float(m.opt.gravity[2])
    mass = [float(m.body_mass[i + 1]) for i in range(n)]
    com = [float(-m.body_ipos[i + 1][2]) for i in range(n)]       # along the link, from its joint
    # link axis along z: the hinge (y) is a principal direction with the transverse inertia
    inertia = [float(np.sort(m.body_inertia[i + 1])[-1]) for i in range(n)]
    lengths = plant.parameters["lengths"]
    phi = [sum(q[:i + 1]) for i in range(n)]                        # absolute angles
    omega = [sum(qd[:i + 1]) for i in range(n)]
    x = z = 0
    T = V = 0
    for i in range(n):
        xc = x + com[i] * sp.sin(phi[i])
        zc = z - com[i] * sp.cos(phi[i])
        vx = sum(sp.diff(xc, q[j]) * qd[j] for j in range(n))
        vz = sum(sp.diff(zc, q[j]) * qd[j] for j in range(n))
        T += sp.Rational(1, 2) * mass[i] * (vx ** 2 + vz ** 2) + sp.Rational(1, 2) * inertia[i] * omega[i] ** 2
        V += mass[i] * g * zc
        x, z = x + lengths[i] * sp.sin(phi[i]), z - lengths[i] * sp.cos(phi[i])
    H = sp.expand(sp.expand_trig(T + V))
    H = sp.expand(H.subs({sp.sin(qi) ** 2: 1 - sp.cos(qi) ** 2 for qi in q}))
    coords = Coordinates(plant.coords)
    out = {}
    for term, c in H.as_coefficients_dict().items():
        if term.is_number:
            continue                                   # energy is defined up to a constant
        name = str(coords.parse(str(term)))
        out[name] = out.get(name, 0.0) + float(c)
    top = max(abs(v) for v in out.values())
    return {k: v for k, v in out.items() if abs(v) > 1e-12 * top}


def measure(t, X, coords, rng, resolution=ENCODER_12BIT, rate_noise=1e-3, source="mujoco"):
    """The rig's readings of states ``X`` (n, 2·n_coords) as a passive
    :class:`~lsindy_cas.data.trajectory.Trajectory`: angles rounded to whole encoder counts of
    ``resolution`` rad (0: exact), rates plus white noise of std ``rate_noise`` rad/s."""
    from ..data.trajectory import Trajectory
    X = np.asarray(X, float)
    n = len(coords)
    q = X[:, :n] if not resolution else np.round(X[:, :n] / resolution) * resolution
    qd = X[:, n:] + (rng.normal(0.0, rate_noise, X[:, n:].shape) if rate_noise else 0.0)
    return Trajectory(np.asarray(t, float), q, qd, list(coords), source=source)


def free_swings(plant: MujocoPlant, rng, n_runs=3, seconds=2.0, rate=1000.0, max_angle=2.0,
                resolution=ENCODER_12BIT, rate_noise=1e-3):
    """Free swings released from rest at random angles (uniform in ±``max_angle`` rad per joint),
    no input, sampled at ``rate`` Hz and read by :func:`measure`.

    Returns a list of (Trajectory, MuJoCo's energy at every sample, the true states)."""
    n = len(plant.coords)
    dt = 1.0 / rate
    out = []
    for _ in range(n_runs):
        x0 = np.r_[rng.uniform(-max_angle, max_angle, n), np.zeros(n)]
        run = plant.simulate(x0, np.zeros(int(round(seconds * rate))), dt)
        out.append((measure(run["t"], run["X"], plant.coords, rng, resolution, rate_noise),
                    run["energy"], run["X"]))
    return out
