"""mpc/swingup.py, the public-API swing-up script, run with one episode."""
import numpy as np


def test_swingup_script_swings_up_with_three_forces(load_script, capsys):
    results = load_script("mpc/swingup.py").main(episodes=1)
    assert len(results) == 1
    forces = results[0]["forces"]
    assert forces.size == 200                          # 10 s at 20 Hz
    assert set(np.unique(forces)) <= {-10.0, 0.0, 10.0}
    assert {-10.0, 10.0} <= set(np.unique(forces))     # it did push both ways
    assert results[0]["success"] and results[0]["max_abs_x"] <= 2.0
    assert "1/1 episodes end upright" in capsys.readouterr().out
