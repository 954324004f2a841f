"""``lsindy simulate`` and the command's help texts / error contract."""
import json

import numpy as np
import pytest

from lsindy_cas import Trajectory, systems
from lsindy_cas.cli import main



def test_simulate_reproduces_the_true_motion(cart_model, tmp_path, capsys):
    out = tmp_path / "sim.csv"
    assert main(["simulate", str(cart_model), "--x0", "0,pi/4,0,0", "--t-end", "2",
                 "--out", str(out)]) == 0
    assert "201 samples" in capsys.readouterr().out
    sim = Trajectory.load(out)
    truth = systems.cart_pendulum().simulate(t_end=2.0, u=0.0)
    np.testing.assert_allclose(sim.t, truth.t, atol=1e-12)
    # same equations, same integrator settings (rtol 1e-11): agreement far below 1e-8
    np.testing.assert_allclose(sim.X, truth.X, atol=1e-8)
    np.testing.assert_allclose(sim.qdd, truth.qdd, atol=1e-7)


@pytest.mark.parametrize("u", ["1.5", "x=1.5", "Q_x=1.5", "1.5,0"])
def test_forces_on_the_actuated_coordinate(cart_model, tmp_path, u):
    out = tmp_path / "pushed.npz"
    assert main(["simulate", str(cart_model), "--x0", "0,0.5,0,0", "--t-end", "0.5",
                 "--dt", "0.05", "--u", u, "--out", str(out)]) == 0
    sim = Trajectory.load(out)
    np.testing.assert_array_equal(sim.Q[:, 0], 1.5)
    np.testing.assert_array_equal(sim.Q[:, 1], 0.0)
    truth = systems.cart_pendulum().simulate(x0=(0, 0.5, 0, 0), t_end=0.5, dt=0.05, u=1.5)
    np.testing.assert_allclose(sim.X, truth.X, atol=1e-8)


@pytest.mark.parametrize("args, message", [
    (["--x0", "0,1,0", "--t-end", "1"], "--x0 needs 4 numbers"),
    (["--x0", "0,abc(,0,0", "--t-end", "1"], "is not a number"),
    (["--x0", "0,1,0,0", "--t-end", "-1"], "must be positive"),
    (["--x0", "0,1,0,0", "--t-end", "1", "--u", "y=2"], "'y' is not a coordinate"),
    (["--x0", "0,1,0,0", "--t-end", "1", "--u", "1,2,3"], "give 1 or 2 numbers"),
    (["--x0", "0,1,0,0", "--t-end", "1", "--dt", "2"], "longer than --t-end"),
])
def test_bad_arguments_give_one_line_and_exit_2(cart_model, tmp_path, capsys, args, message):
    code = main(["simulate", str(cart_model), *args, "--out", str(tmp_path / "o.csv")])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and err.count("\n") == 1 and err.startswith("lsindy simulate: error:")
    assert not (tmp_path / "o.csv").exists()


def test_one_number_needs_one_actuated_coordinate(tmp_path, capsys):
    path = tmp_path / "m.json"
    path.write_text(json.dumps({"coords": ["a", "b"],
                                "hamiltonian_terms": {"a_dot**2": 1.0, "b_dot**2": 1.0}}))
    code = main(["simulate", str(path), "--x0", "0,0,0,0", "--t-end", "1", "--u", "2",
                 "--out", str(tmp_path / "o.csv")])
    assert code == 2 and "exactly one actuated coordinate" in capsys.readouterr().err


def test_bad_files(cart_model, tmp_path, capsys):
    assert main(["simulate", str(tmp_path / "none.json"), "--x0", "0,0,0,0", "--t-end", "1",
                 "--out", str(tmp_path / "o.csv")]) == 2
    assert "no such model file" in capsys.readouterr().err
    assert main(["simulate", str(cart_model), "--x0", "0,0,0,0", "--t-end", "1",
                 "--out", str(tmp_path / "o.txt")]) == 2
    assert ".csv or .npz" in capsys.readouterr().err


def test_missing_arguments_exit_2_with_one_line(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["simulate", "m.json"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "required" in err


@pytest.mark.parametrize("command", [[], ["identify"], ["reproduce"], ["simulate"]])
def test_help_has_examples(command, capsys):
    with pytest.raises(SystemExit) as exc:
        main([*command, "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "example" in out and "lsindy " in out.split("example", 1)[1]


def test_unknown_command_exits_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bogus"])
    assert exc.value.code == 2 and capsys.readouterr().err.count("\n") == 1
