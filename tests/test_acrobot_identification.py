"""examples/acrobot.py: gymnasium's Acrobot-v1 identified from its own dynamics.

The hand-derived energy is checked against gymnasium's data (energy balance) and its ``_dsdt``
(through the identified ODE); the fit on a small data set (3 runs x 3 s) must give the exact
8-term support, every coefficient to 1e-6 relative and status "ok".  1e-6: the data are gymnasium's
RK4 at 2 ms, whose energy-balance error leaves the coefficients at 4e-11 relative here (6e-11 on
the example's 6 x 5 s) — 1e-6 is far from that and far below any wrong-but-close model (a missing
or extra term moves coefficients by percents).
"""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "acrobot.py"


@pytest.fixture(scope="module")
def acrobot():
    spec = importlib.util.spec_from_file_location("example_acrobot", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def data(acrobot):
    return acrobot.collect(n_runs=3, t_end=3.0, seed=0)


@pytest.fixture(scope="module")
def model(acrobot, data):
    return acrobot.identify(data, verbose=False)


def test_true_terms_are_the_true_energy(acrobot):
    """TRUE_H (8 library terms, cos(θ1+θ2) expanded) equals the energy written directly."""
    from lsindy_cas import Library
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(-4, 4, (50, 2)), rng.uniform(-5, 5, (50, 2))])
    lib = Library(acrobot.COORDS, list(acrobot.TRUE_H))
    assert lib.names == list(acrobot.TRUE_H)          # the names are the library's own spelling
    H = lib.theta(X) @ np.array(list(acrobot.TRUE_H.values()))
    np.testing.assert_allclose(H, acrobot.true_energy(X), rtol=1e-12, atol=1e-12)


def test_data_balance_the_true_energy(acrobot, data):
    """On gymnasium's runs the true energy changes by the elbow torque's work Q_θ2·Δθ2 (sign and
    coordinates right), the angles are unwrapped, Q_θ1 = 0 and no rate is near gymnasium's clip."""
    for tr in data:
        E = acrobot.true_energy(np.hstack([tr.q, tr.qd]))
        work = tr.Q[:-1, 1] * np.diff(tr.q[:, 1])
        assert np.max(np.abs(np.diff(E) - work)) < 1e-9 * np.ptp(E)
        assert np.all(tr.Q[:, 0] == 0) and set(np.unique(tr.Q[:, 1])) <= {-1.0, 0.0, 1.0}
        assert np.max(np.abs(np.diff(tr.q, axis=0))) < 0.5
        assert np.all(np.abs(tr.qd[:, 0]) < 0.95 * 4 * np.pi)
        assert np.all(np.abs(tr.qd[:, 1]) < 0.95 * 9 * np.pi)
    # the unwrapping mattered: some run leaves [-pi, pi)
    assert any(np.max(np.abs(tr.q)) > np.pi for tr in data)


def test_identified_energy_is_exact(acrobot, model):
    found = model.terms()
    assert set(found) == set(acrobot.TRUE_H)
    names = sorted(acrobot.TRUE_H)
    np.testing.assert_allclose([found[k] for k in names], [acrobot.TRUE_H[k] for k in names],
                               rtol=1e-6)
    assert model.status_ == "ok", model.status_reasons_


def test_identified_ode_is_gymnasiums(acrobot, model, tmp_path):
    """The saved and reloaded model's ODE reproduces gymnasium's _dsdt to 1e-6 relative."""
    from lsindy_cas import LagrangianSINDy
    loaded = LagrangianSINDy.load(model.save(tmp_path / "acrobot.json"))
    assert acrobot.check_ode(loaded, n=50) < 1e-6


def test_plant_is_the_gymnasium_environment(acrobot):
    """AcrobotPlant steps the real env: same states as a raw Acrobot-v1 with the same seed and
    the action index of each torque; wrapped angles; gymnasium's termination flag."""
    plant = acrobot.AcrobotPlant()
    raw = gymnasium.make("Acrobot-v1")
    x = plant.reset(seed=7)
    raw.reset(seed=7)
    assert x.shape == (4,) and np.array_equal(x, np.asarray(raw.unwrapped.state, float))
    rng = np.random.default_rng(0)
    reached = False
    for _ in range(300):
        u = float(rng.choice([-1.0, 0.0, 1.0]))
        x, reached, truncated = plant.step(u)
        _, _, term, trunc, _ = raw.step({-1.0: 0, 0.0: 1, 1.0: 2}[u])
        assert np.array_equal(x, raw.unwrapped.state) and (reached, truncated) == (term, trunc)
        assert np.all(np.abs(x[:2]) <= np.pi)
        if reached:
            break
    with pytest.raises(ValueError):
        plant.step(0.5)
    plant.close()
    raw.close()
