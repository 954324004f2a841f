"""Every example runs (small), and ends with its own assertion."""
import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

# the size knob of each example, set small: seconds of training data (and of the check)
SMALL = {
    "spherical_pendulum": dict(t_end=0.2, t_check=0.5),
    "double_pendulum": dict(t_end=0.5, t_check=1.0),
    "cart_pendulum": dict(t_end=0.2),
    "own_csv_data": dict(t_end=0.5),
}


def _load(name):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_example_is_listed():
    assert sorted(p.stem for p in EXAMPLES.glob("*.py")) == sorted(SMALL)


@pytest.mark.parametrize("name", sorted(SMALL))
def test_example_runs_small(name, tmp_path, capsys):
    kwargs = dict(SMALL[name])
    if "out_dir" in _load(name).main.__code__.co_varnames:
        kwargs["out_dir"] = tmp_path
    model = _load(name).main(verbose=True, **kwargs)
    assert hasattr(model, "coef_")
    assert "H = " in capsys.readouterr().out


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SMALL))
def test_example_runs_as_a_script(name):
    done = subprocess.run([sys.executable, str(EXAMPLES / f"{name}.py")], capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr
