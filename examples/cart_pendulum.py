"""Cart-pendulum (paper Sec. III-C): identify, save the model, load it and use its CasADi ODE.

The cart (1 kg) carries a pendulum (0.1 kg point mass on a 1 m rod); a constant 1 N push for 1 s
gives the data.  The saved JSON model is what ``lsindy simulate`` and ``lsindy swingup --model``
read; its ``ode()`` is a ``casadi.Function`` (x = [x, θ, ẋ, θ̇], u = [Q_x, Q_θ]) -> ẋ, ready for
an optimal-control problem.

Run:  python examples/cart_pendulum.py
"""
import tempfile
from pathlib import Path

import numpy as np

from lsindy_cas import LagrangianSINDy, Library, printing, systems


def main(t_end=1.0, out_dir=None, verbose=True):
    """Identify from ``t_end`` s of pushed motion; save/load the model under ``out_dir``.

    Parameters
    ----------
    t_end : float
        Seconds of training data (the size knob).
    out_dir : str or Path, optional
        Folder for ``cart_model.json``; by default a temporary folder, removed afterwards.
    verbose : bool
        Print the model.

    Returns
    -------
    LagrangianSINDy
        The identified model, as loaded back from its JSON file (``.terms()`` gives H's terms).
    """
    if out_dir is None:
        with tempfile.TemporaryDirectory() as tmp:
            return main(t_end, tmp, verbose)
    system = systems.cart_pendulum()
    data = system.simulate(t_end=t_end, u=1.0)

    library = Library.polynomial(system.coords, "cos(theta),sin(theta),theta_dot,x,x_dot", degree=3)
    model = LagrangianSINDy(library, n_terms=4, prior=["theta_dot**2", "cos(theta)"]).fit(data)
    if verbose:
        print(printing.describe(model, digits=3))

    out_dir = Path(out_dir)
    path = model.save(out_dir / "cart_model.json")
    loaded = LagrangianSINDy.load(path)
    if verbose:
        print(f"\nmodel saved to {path}")

    # the loaded model's ODE gives the true accelerations at an arbitrary state and force
    x, u = np.array([0.3, 2.0, -0.5, 1.5]), np.array([4.0, 0.0])
    xdot = np.asarray(loaded.ode()(x, u)).ravel()
    true = np.asarray(system.ode()(x, u)).ravel()
    if verbose:
        print(f"accelerations at x = {x}, Q_x = {u[0]}: identified {xdot[2:]}, true {true[2:]}")
    # 1e-8: the identified coefficients match the truth to ~1e-12 relative (exact data)
    assert np.allclose(xdot, true, rtol=1e-8, atol=1e-8), (xdot, true)
    return loaded


if __name__ == "__main__":
    main()
