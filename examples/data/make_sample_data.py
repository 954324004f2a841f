"""Write the small sample trajectory files the README's command-line examples use.

Two runs of the paper's cart-pendulum (mc = 1 kg, mp = 0.1 kg, L = 1 m) at 100 Hz, each driven by
a different input held over each 10 ms sample as a digital controller applies it, saved in the
documented CSV format (t, x, theta, x_dot, theta_dot, Q_x, Q_theta) without accelerations, as a
logged run would be, and the same two runs with N(0, 1e-3²) noise on q and q̇
(``cart_noisy*.csv``).  Regenerate with ``python examples/data/make_sample_data.py [FOLDER]``.
"""
from pathlib import Path

import numpy as np


def main(folder=Path(__file__).resolve().parent, t_end=2.0):
    from lsindy_cas import Trajectory, systems
    from lsindy_cas.data.smoothing import add_noise

    rng = np.random.default_rng(2020)

    folder = Path(folder)
    folder.mkdir(exist_ok=True)
    cart = systems.cart_pendulum()
    inputs = [lambda t, x: 2.0 * np.sin(3.0 * t), lambda t, x: 1.5 * np.sign(np.sin(5.0 * t))]
    starts = [(0.0, np.pi / 4, 0.0, 0.0), (0.2, 2.0, 0.0, -0.5)]
    paths = []
    for i, (u, x0) in enumerate(zip(inputs, starts), start=1):
        tr = cart.simulate(x0=x0, t_end=t_end, u=u)
        logged = Trajectory(tr.t, tr.q, tr.qd, tr.coords, Q=tr.Q)      # no exact accelerations
        paths.append(logged.save(folder / f"cart_run{i}.csv"))
        # the same run as a noisy sensor would log it: N(0, 1e-3²) on every q and q̇ column
        noisy = add_noise(logged, 1e-3, rng)
        paths.append(Trajectory(noisy.t, noisy.q, noisy.qd, noisy.coords, Q=noisy.Q)
                     .save(folder / f"cart_noisy{i}.csv"))
    return paths


if __name__ == "__main__":
    import sys

    for p in main(*sys.argv[1:2]):
        print(p)
