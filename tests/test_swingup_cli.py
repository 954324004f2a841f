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
