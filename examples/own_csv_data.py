"""Your own data: trajectory CSV files in, energy, Lagrangian and equations of motion out.

A trajectory file has a header row and the columns ``t`` (s), one column per generalized
coordinate (here ``x``, ``theta``), ``<q>_dot`` for each, and optionally the applied generalized
forces ``Q_<q>`` (missing = 0).  Measured data rarely come with accelerations, so Lagrangian-SINDy
uses the integral form of the energy balance (the change of energy over a window equals the work
done, ∫ Q·q̇ dt) — no differentiation of noisy signals.

To use your own recordings, replace ``write_example_files`` with your files and set ``COORDS``,
``FEATURES`` and the prior terms for your system.  The same in one command:

    lsindy identify run0.csv run1.csv --coords x,theta \\
        --features "cos(theta),sin(theta),theta_dot,x,x_dot" --degree 3 \\
        --terms 4 --prior "theta_dot**2,cos(theta)" --json model.json

Run:  python examples/own_csv_data.py [OUT_DIR]    (without OUT_DIR the files go to a temporary
folder that is removed at the end)
"""
import sys
import tempfile
from pathlib import Path

import numpy as np

from lsindy_cas import LagrangianSINDy, Library, Trajectory, load_trajectories, systems

COORDS = ["x", "theta"]
FEATURES = ["cos(theta)", "sin(theta)", "theta_dot", "x", "x_dot"]


def write_example_files(out_dir, t_end):
    """Stand-in for your recordings: two cart-pendulum runs with different constant pushes."""
    system = systems.cart_pendulum()
    paths = []
    for i, (x0, force) in enumerate([((0.0, 0.5, 0.0, 0.0), 1.0), ((0.0, -1.0, 0.2, 0.0), -2.0)]):
        run = system.simulate(x0=x0, t_end=t_end, u=force)
        # keep only what a sensor log would have: no accelerations
        measured = Trajectory(run.t, run.q, run.qd, run.coords, Q=run.Q)
        paths.append(measured.save(Path(out_dir) / f"run{i}.csv"))
    return paths


def main(t_end=4.0, out_dir=None, verbose=True):
    """Identify from CSV files of ``t_end`` s each, written to ``out_dir``.

    Parameters
    ----------
    t_end : float
        Seconds per recorded run (the size knob).
    out_dir : str or Path, optional
        Folder for ``run0.csv``, ``run1.csv`` and ``model.json`` (created if missing); by default a
        temporary folder, removed afterwards.
    verbose : bool
        Print the model.

    Returns
    -------
    LagrangianSINDy
        The identified model (``.terms()`` gives H's terms).
    """
    if out_dir is None:
        with tempfile.TemporaryDirectory() as tmp:
            return main(t_end, tmp, verbose)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = write_example_files(out_dir, t_end)

    trajectories = load_trajectories(paths, COORDS)
    library = Library.polynomial(COORDS, FEATURES, degree=3)
    model = LagrangianSINDy(library, n_terms=4, prior=["theta_dot**2", "cos(theta)"])
    model.fit(trajectories)
    if verbose:
        print(f"read {', '.join(str(p) for p in paths)} ({model.form_} form)\n")
        print(model)
        print(f"\nmodel saved to {model.save(out_dir / 'model.json')}")

    truth = library.coefficients(systems.cart_pendulum().hamiltonian)
    assert model.support_ == tuple(np.flatnonzero(truth)), model.terms()
    # 1e-6 relative: the samples are exact and the power is constant per run, so the windowed
    # energy balance holds to integration accuracy (measured: 5e-9 with 4 s runs)
    assert np.allclose(model.coef_, truth, rtol=1e-6, atol=0), model.terms()
    return model


if __name__ == "__main__":
    main(out_dir=sys.argv[1] if len(sys.argv) > 1 else None)
