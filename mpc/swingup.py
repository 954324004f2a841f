"""Swing up the cart-pendulum with a model identified from data, forces only from {-10, 0, +10} N.

The pipeline end to end, on the public API:

1. simulate training data: the paper's actuated run (1 N on the cart for 1 s, 100 Hz);
2. identify the energy, the Lagrangian and the equations of motion with ``LagrangianSINDy``;
3. build a ``SwingUpMPC`` from the *identified* model (its ``ode()``, no hand-written equations);
4. run closed-loop episodes on the *true* plant (the force held constant over each 50 ms period)
   from random starts, and print whether each one ends upright.

Success: the pole within 0.1 rad of upright and its rate below 0.5 rad/s over the last 3 s, the
cart within 2 m of the centre throughout.

    python mpc/swingup.py

``lsindy swingup`` is the full experiment (20 starts, parameter mismatch and measurement noise,
JSON metrics and the Fig. 5 analogue).
"""

import numpy as np

from lsindy_cas import LagrangianSINDy, Library, systems
from lsindy_cas.mpc import SwingUpMPC

FORCES = (-10.0, 0.0, 10.0)


def identify(plant):
    """Identify the cart-pendulum from one pushed run of ``plant``."""
    data = plant.simulate(x0=[0.0, np.pi / 4, 0.0, 0.0], t_end=1.0, u=1.0)
    library = Library.polynomial(["x", "theta"], "cos(theta),sin(theta),theta_dot,x,x_dot", degree=3)
    return LagrangianSINDy(library, n_terms=4, prior=["theta_dot**2", "cos(theta)"]).fit(data)


def episode(ctrl, plant, x0, t_end):
    """One closed-loop run: the controller sees the plant's state every ``ctrl.dt`` seconds."""
    ctrl.reset()
    run = plant.simulate(x0=x0, t_end=t_end, u=lambda t, x: ctrl(x), dt=ctrl.dt)
    x, theta, theta_dot = run.q[:, 0], run.q[:, 1], run.qd[:, 1]
    off_upright = np.abs((theta - np.pi + np.pi) % (2 * np.pi) - np.pi)
    last = run.t >= t_end - 3.0
    success = bool(np.all(off_upright[last] < 0.1) and np.all(np.abs(theta_dot[last]) < 0.5)
                   and np.all(np.abs(x) <= 2.0))
    return {"x0": np.asarray(x0), "success": success, "forces": run.Q[:-1, 0],
            "max_abs_x": float(np.max(np.abs(x)))}


def main(episodes=5, t_end=10.0, seed=0):
    """Identify, build the controller, run ``episodes`` episodes of ``t_end`` s; return them."""
    plant = systems.cart_pendulum()
    model = identify(plant)
    print(f"identified energy: H = {model.hamiltonian_}")
    ctrl = SwingUpMPC(model, force_set=FORCES, dt=0.05, horizon=40, track_limit=2.0)
    low, high = [-0.5, -np.pi, -1.0, -1.0], [0.5, np.pi, 1.0, 1.0]
    starts = np.random.default_rng(seed).uniform(low, high, size=(episodes, 4))
    results = []
    for i, x0 in enumerate(starts):
        res = episode(ctrl, plant, x0, t_end)
        results.append(res)
        print(f"episode {i}: x0 = {np.round(x0, 2).tolist()}  "
              f"{'upright' if res['success'] else 'FAILED'}  max |x| = {res['max_abs_x']:.2f} m")
    print(f"{sum(r['success'] for r in results)}/{episodes} episodes end upright")
    return results


if __name__ == "__main__":
    main()
