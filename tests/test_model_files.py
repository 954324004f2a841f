"""Model files: save/load round trips (JSON: coordinates, library spec, coefficients, version)."""
import json

import numpy as np
import pytest

from lsindy_cas import LagrangianSINDy, Library, __version__, systems


@pytest.fixture(scope="module")
def fitted():
    system = systems.cart_pendulum()
    lib = Library.polynomial(system.coords, "cos(theta),sin(theta),theta_dot,x,x_dot", 3)
    model = LagrangianSINDy(lib, n_terms=4, prior=["theta_dot**2", "cos(theta)"])
    return model.fit(system.simulate(t_end=1.0, u=1.0))


def test_round_trip_keeps_everything(fitted, tmp_path, rng):
    path = fitted.save(tmp_path / "m.json")
    loaded = LagrangianSINDy.load(path)
    assert loaded.coords_ == fitted.coords_
    assert loaded.library.names == fitted.library.names            # rebuilt from its spec
    np.testing.assert_array_equal(loaded.coef_, fitted.coef_)      # JSON floats are exact
    assert loaded.support_ == fitted.support_
    assert loaded.terms("lagrangian") == pytest.approx(fitted.terms("lagrangian"), rel=1e-12)
    assert loaded.actuated_ == ["x"]
    assert [str(e) for e in loaded.equations_of_motion()] == \
        [str(e) for e in fitted.equations_of_motion()]
    X = rng.uniform(-2, 2, size=(20, 4))
    U = rng.uniform(-5, 5, size=(20, 2))
    f, g = fitted.ode(), loaded.ode()
    # exact: the same coefficients (above) and terms build the same expression graph
    np.testing.assert_array_equal(np.asarray(f.map(20)(X.T, U.T)), np.asarray(g.map(20)(X.T, U.T)))


def test_file_contents(fitted, tmp_path):
    d = json.loads(fitted.save(tmp_path / "m.json").read_text())
    assert d["coords"] == ["x", "theta"]
    assert d["library"] == {"coords": ["x", "theta"], "kind": "polynomial",
                            "features": ["cos(theta)", "sin(theta)", "theta_dot", "x", "x_dot"],
                            "degree": 3}
    assert set(d["hamiltonian_terms"]) == {"theta_dot**2", "theta_dot*x_dot*cos(theta)",
                                           "x_dot**2", "cos(theta)"}
    assert d["lsindy_cas_version"] == __version__
    assert len(d["equations_of_motion"]) == 2


def test_save_load_save_is_a_fixed_point(fitted, tmp_path):
    a = fitted.save(tmp_path / "a.json")
    b = LagrangianSINDy.load(a).save(tmp_path / "b.json")
    assert json.loads(a.read_text()) == json.loads(b.read_text())


def test_a_hand_written_model_file(tmp_path):
    # the minimal file: coordinates and energy terms (the library is then those terms)
    path = tmp_path / "spring.json"
    path.write_text(json.dumps({"coords": ["s"], "hamiltonian_terms": {"s_dot**2": 1.0, "s**2": 2.5}}))
    model = LagrangianSINDy.load(path)
    assert model.terms("lagrangian") == pytest.approx({"s_dot**2": 1.0, "s**2": -2.5})
    # M s_ddot = F: 2 s_ddot = Q_s - 5 s
    xdot = np.asarray(model.ode()([0.2, 0.0], [1.0])).ravel()
    np.testing.assert_allclose(xdot, [0.0, (1.0 - 5 * 0.2) / 2], rtol=1e-14)


@pytest.mark.parametrize("content, match", [
    (None, "no such model file"),
    ("{not json", "not a JSON model file"),
    (json.dumps({"coords": ["s"]}), "lacks hamiltonian_terms"),
    (json.dumps({"coords": ["s"], "hamiltonian_terms": {"q**2": 1.0}}), "unknown name"),
])
def test_bad_model_files(tmp_path, content, match):
    path = tmp_path / "m.json"
    if content is not None:
        path.write_text(content)
    with pytest.raises(ValueError, match=match):
        LagrangianSINDy.load(path)


def test_saving_an_unfitted_model_is_an_error(tmp_path):
    with pytest.raises(ValueError, match="not fitted"):
        LagrangianSINDy(Library(["s"], ["s**2"]), n_terms=1).save(tmp_path / "m.json")
