"""`lsindy swingup`: a small run writes its metrics and figures; every bad option fails first."""
import pytest

from lsindy_cas import cli
from lsindy_cas.paper import swingup


def test_swingup_runs_small_and_writes_json_and_figures(tmp_path, capsys):
    code = cli.main(["swingup", "--episodes", "1", "--scenarios", "nominal",
                     "--json", str(tmp_path / "m.json"), "--out", str(tmp_path)])
    assert code == 0
    assert (tmp_path / "m.json").exists()
    assert (tmp_path / "swingup_phase.png").exists() and (tmp_path / "swingup_time.png").exists()


@pytest.mark.parametrize("argv, names", [
    (["--episodes", "0"], "--episodes"),
    (["--seed", "-1"], "--seed"),
    (["--scenarios", "nominal,bogus"], "--scenarios"),
    (["--scenarios", ","], "--scenarios"),
    (["--solver", "foo"], "--solver"),
    (["--rounding", "bar"], "--rounding"),
    (["--inexact-tol", "-1"], "--inexact-tol"),
    (["--inexact-tol", "inf"], "--inexact-tol"),
    (["--model", "no_such_model.json"], "--model"),
])
def test_bad_option_is_rejected_before_any_work(argv, names, monkeypatch, capsys):
    def no_work(*args, **kwargs):
        raise AssertionError("the experiment started before the options were checked")

    monkeypatch.setattr(swingup, "identify_cart_pendulum", no_work)
    monkeypatch.setattr(swingup, "run_swingup", no_work)
    assert cli.main(["swingup", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("lsindy swingup: error:") and names in err


def test_json_path_that_is_a_directory_is_rejected(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(swingup, "run_swingup", lambda *a, **k: pytest.fail("ran"))
    assert cli.main(["swingup", "--json", str(tmp_path)]) == 2
    assert "--json" in capsys.readouterr().err


def test_default_scenarios_are_all_three(monkeypatch):
    seen = {}
    monkeypatch.setattr(swingup, "run_swingup",
                        lambda model, **kw: seen.update(kw) or {"scenarios": {}})
    assert cli.main(["swingup"]) == 0
    assert seen["scenarios"] == list(swingup.SCENARIOS) and seen["controller_options"] == {}


def test_jit_option_reaches_the_controller(monkeypatch):
    seen = {}
    monkeypatch.setattr(swingup, "run_swingup",
                        lambda model, **kw: seen.update(kw) or {"scenarios": {}})
    assert cli.main(["swingup", "--jit", "--scenarios", "nominal"]) == 0
    assert seen["controller_options"] == {"jit": True}
    assert cli.main(["swingup", "--no-jit", "--scenarios", "nominal"]) == 0
    assert seen["controller_options"] == {"jit": False}


def test_a_bad_lsindy_jit_is_refused_before_the_identification(monkeypatch, capsys):
    ran = []
    monkeypatch.setattr(swingup, "run_swingup", lambda model, **kw: ran.append(kw))
    monkeypatch.setenv("LSINDY_JIT", "maybe")
    assert cli.main(["swingup", "--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert ran == [] and len(err) == 1 and "LSINDY_JIT must be 0/off or 1/on" in err[0]


def test_jit_and_no_jit_together_are_refused(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["swingup", "--jit", "--no-jit"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "not allowed with argument" in err[-1]


RELATIVE = {"coords": ["x", "theta"], "actuated": ["x"], "energy_scale": "relative",
            "normalised_by": "theta_dot**2",
            "hamiltonian_terms": {"x_dot**2": 11.0, "theta_dot**2": 1.0,
                                  "theta_dot*x_dot*cos(theta)": 2.0, "cos(theta)": -19.62}}


def test_relative_energy_model_is_refused(tmp_path, monkeypatch, capsys):
    """A model from passive data without a scale record knows the force's effect only up to a
    factor: no swing-up is attempted from it (CLI: one line, exit 2; Python: ValueError)."""
    import json

    from lsindy_cas.identify.estimator import LagrangianSINDy
    from lsindy_cas.mpc import SwingUpMPC

    path = tmp_path / "rel.json"
    path.write_text(json.dumps(RELATIVE))
    monkeypatch.setattr(swingup, "run_swingup", lambda *a, **k: pytest.fail("ran"))
    assert cli.main(["swingup", "--model", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "relative" in err and "--scale" in err
    with pytest.raises(ValueError, match="relative"):
        SwingUpMPC(LagrangianSINDy.load(path))
    absolute = dict(RELATIVE, energy_scale="absolute")
    path.write_text(json.dumps(absolute))
    assert SwingUpMPC(LagrangianSINDy.load(path), horizon=10).horizon == 10


def _model_file(tmp_path, name, coords=("x", "theta"), mc=1.0, mp=0.1, L=1.0, g=9.81):
    """A saved absolute model with the hand-derived cart-pendulum energy of (mc, mp, L)."""
    import json
    x, th = coords
    path = tmp_path / name
    path.write_text(json.dumps({
        "coords": list(coords), "actuated": [x], "energy_scale": "absolute",
        "hamiltonian_terms": {f"{x}_dot**2": (mc + mp) / 2, f"{th}_dot**2": mp * L ** 2 / 2,
                              f"{th}_dot*{x}_dot*cos({th})": mp * L,
                              f"cos({th})": -mp * g * L}}))
    return path


def test_a_model_of_another_rig_gets_a_note_about_the_simulated_plant(tmp_path, monkeypatch,
                                                                      capsys):
    """`lsindy swingup` simulates the paper's plant: a model of another cart-pendulum (the
    family's 0.8/0.2/0.7) is run against it, with one line on stderr saying so (it used to fail
    every episode, exit 1, without a word); a model of the paper plant gets no note."""
    monkeypatch.setattr(swingup, "run_swingup", lambda model, **kw: {"scenarios": {}})
    assert cli.main(["swingup", "--model", str(_model_file(tmp_path, "paper.json"))]) == 0
    assert capsys.readouterr().err == ""
    light = _model_file(tmp_path, "light.json", mc=0.8, mp=0.2, L=0.7)
    assert cli.main(["swingup", "--model", str(light)]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "paper's cart-pendulum" in err and "differ" in err


def test_a_model_with_other_coordinate_names_is_refused_before_any_work(tmp_path, monkeypatch,
                                                                          capsys):
    monkeypatch.setattr(swingup, "run_swingup", lambda *a, **k: pytest.fail("ran"))
    other = _model_file(tmp_path, "other.json", coords=("y", "phi"))
    assert cli.main(["swingup", "--model", str(other)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "coordinates" in err and "['x', 'theta']" in err


def test_plant_note_matches_coordinates_by_name():
    """A model of the paper plant with its coordinates in the other order is the same plant."""
    import casadi as ca
    import numpy as np

    from lsindy_cas.paper import systems
    from lsindy_cas.paper.swingup_cli import plant_note

    true = systems.cart_pendulum().ode()
    x, u = ca.SX.sym("x", 4), ca.SX.sym("u", 2)
    swap = [1, 0, 3, 2]
    swapped = ca.Function("ode", [x, u], [true(x[swap], u[[1, 0]])[swap]])

    class Swapped:
        coords_, actuated_ = ["theta", "x"], ["x"]

        def ode(self):
            return swapped

    assert plant_note(Swapped()) is None
    assert np.allclose(np.asarray(swapped([0.0, 0.1, 0.0, 0.0], [0.0, 10.0])).ravel()[[1, 0, 3, 2]],
                       np.asarray(true([0.1, 0.0, 0.0, 0.0], [10.0, 0.0])).ravel())
