"""The MuJoCo Furuta pendulum (examples/furuta.py, examples/data/furuta.xml): identified from
motor-torque runs, judged by MuJoCo's own inertias, damping, energy and accelerations.

Tolerances.  The data are exact up to MuJoCo's RK4 at 1 ms, sampled at 100 Hz; the held torque's
work integral is exact, what is left is the quadrature of the energy differences and of the
dissipation integrals.  Over seeds 0-3 (3 runs x 4 s), 2 runs x 3 s and holds of 0.05-0.2 s the
energy coefficients came out within 4.7e-6 relative and the damping within 2.2e-5 (the pendulum's
b_theta, whose dissipation is the smallest column), H against MuJoCo's energy within 7e-8 of its
range and the equations of motion against MuJoCo's accelerations within 5e-8 of their scale:
the bounds below (1e-4, 1e-3, 1e-6, 1e-5) leave 20-200x room for another machine's BLAS and
MuJoCo build, and are still 100x tighter than the 1 % the example is required to meet.
"""
import numpy as np
import pytest

pytest.importorskip("mujoco")

H_RTOL = 1e-4        # energy coefficients (seen <= 4.7e-6)
R_RTOL = 1e-3        # damping coefficients (seen <= 2.2e-5)
E_TOL = 1e-6         # |H - E_MuJoCo| / range(E_MuJoCo), means removed (seen <= 7e-8)
ACC_TOL = 1e-5       # |q̈_model - q̈_MuJoCo| / max |q̈_MuJoCo| (seen <= 5e-8)


@pytest.fixture(scope="module")
def furuta(load_script):
    return load_script("examples/furuta.py")


@pytest.fixture(scope="module")
def plant(furuta):
    return furuta.FurutaPlant()


@pytest.fixture(scope="module")
def fitted(furuta, plant):
    trajs = furuta.collect(n_runs=2, t_end=3.0, seed=0, hold=0.1, plant=plant)
    return furuta.identify(trajs), trajs


def _check_against_truth(model, plant):
    truth_h, truth_r = plant.true_hamiltonian(), plant.true_rayleigh()
    got_h, got_r = model.terms(), model.terms("rayleigh")
    assert sorted(got_h) == sorted(truth_h)
    for name, c in truth_h.items():
        assert got_h[name] == pytest.approx(c, rel=H_RTOL), name
    assert sorted(got_r) == sorted(truth_r)
    for name, c in truth_r.items():
        assert got_r[name] == pytest.approx(c, rel=R_RTOL), name


def test_true_energy_is_mujocos_energy(furuta, plant):
    """The hand-derived H (from MuJoCo's body masses, inertias, positions) is MuJoCo's energy up to
    a constant, on a driven run: the formula and the conventions are right before anything is
    fitted to them.  MuJoCo's energy is taken at each recorded state after ``mj_forward``
    (``energy_at``): the energy read right after ``mj_step`` comes from the kinematics of the
    step's last RK4 stage, not of the new state, and differs by ~1.5e-6 of the range here."""
    truth = furuta.Library(furuta.COORDS, list(plant.true_hamiltonian()))
    coef = np.array(list(plant.true_hamiltonian().values()))
    rng = np.random.default_rng(5)
    tr, _ = plant.trajectory([0.3, 2.5, -1.0, 3.0], rng.choice(plant.LEVELS, 300))
    X = np.hstack([tr.q, tr.qd])
    H, E = truth.theta(X) @ coef, plant.energy_at(X)
    assert np.ptp(E) > 0.01
    # round-off only (seen 2.8e-15)
    assert np.max(np.abs((H - H.mean()) - (E - E.mean()))) < 1e-12 * np.ptp(E)


def test_furuta_identified_exactly(furuta, plant, fitted):
    """Exact support out of the 104 candidates, H and R against MuJoCo's values, status ok."""
    model, trajs = fitted
    assert len(model.library) == 104
    assert model.hold_ == "zoh"
    _check_against_truth(model, plant)
    assert model.status_ == "ok", model.status_reasons_


def test_identified_model_matches_mujocos_energy_and_accelerations(furuta, plant, fitted):
    model, trajs = fitted
    unseen = furuta.collect(n_runs=1, t_end=3.0, seed=7, hold=0.2, plant=plant)
    assert furuta.energy_error(model, plant, trajs + unseen) < E_TOL
    assert furuta.acceleration_error(model, plant, n=50) < ACC_TOL


def test_saved_model_file_is_the_truth(furuta, plant):
    """examples/data/furuta_model.json (written by ``python examples/furuta.py``) is exact, ok,
    and its ODE is MuJoCo's."""
    model = furuta.LagrangianSINDy.load(furuta.MODEL)
    assert model.coords_ == ["phi", "theta"]
    _check_against_truth(model, plant)
    assert model.status_ == "ok"
    assert furuta.acceleration_error(model, plant, n=50) < ACC_TOL


def test_plant_api(furuta, plant):
    rng = np.random.default_rng(0)
    assert plant.LEVELS == (-furuta.TAU, 0.0, furuta.TAU)
    x0 = plant.hanging_start(rng)
    assert x0.shape == (4,) and np.all(np.abs(x0) <= 0.05)
    assert np.array_equal(plant.reset(x0), x0)
    x = plant.step(furuta.TAU, 0.01)
    assert x.shape == (4,) and x[2] > x0[2]              # the motor torque turns the arm
    # MuJoCo clips the torque to the motor's range
    plant.reset(x0)
    over = plant.step(10 * furuta.TAU, 0.01)
    plant.reset(x0)
    assert np.allclose(over, plant.step(furuta.TAU, 0.01), rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="whole multiple"):
        plant.step(0.0, 0.0105)
    with pytest.raises(ValueError, match="4 finite numbers"):
        plant.reset([0.0, 0.0, 0.0])
    # collect: held levels, Q on phi only, 100 Hz
    tr = furuta.collect(n_runs=1, t_end=1.0, seed=3, hold=0.1, plant=plant)[0]
    assert tr.coords == ["phi", "theta"] and len(tr.t) == 101
    assert np.allclose(np.diff(tr.t), 0.01)
    assert set(np.unique(tr.Q[:, 0])) <= set(plant.LEVELS) and not tr.Q[:, 1].any()
    assert np.all(tr.Q[:100:10, 0][:, None] == tr.Q[:100, 0].reshape(10, 10))
