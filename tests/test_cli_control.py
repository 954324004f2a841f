"""`lsindy control`: a good run on the Acrobot model file (exit 0, the results JSON with its
documented keys, the figure) and the bad-input contract (exit 2, one line on stderr)."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from lsindy_cas.cli import main

ROOT = Path(__file__).resolve().parents[1]
ACROBOT = ROOT / "examples" / "data" / "acrobot_model.json"
ACROBOT_TASK = ROOT / "examples" / "tasks" / "acrobot.toml"
PREFIX = "lsindy control: error:"

# the Acrobot task of examples/tasks, written out so one field at a time can be broken
GOOD = """\
dt = 0.2

[inputs.theta2]
levels = [-1.0, 0.0, 1.0]

[goal]
reach = "-cos(theta1) - cos(theta1 + theta2) > 1.0"

[episode]
duration = 100.0
spread = { theta1 = 0.1, theta2 = 0.1, theta1_dot = 0.1, theta2_dot = 0.1 }
"""


def run_cli(*args):
    """Run the real console entry point in a subprocess (what a user sees)."""
    return subprocess.run([sys.executable, "-m", "lsindy_cas.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


def _one_error_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(PREFIX), err
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture
def negated_model(tmp_path):
    """The Acrobot model file with its θ̇1² coefficient negated: the mass matrix
    [[−3.5 − cos θ2, …], …] is not positive definite."""
    d = json.loads(ACROBOT.read_text())
    d["hamiltonian_terms"] = {k: (-v if k == "theta1_dot**2" else v)
                              for k, v in d["hamiltonian_terms"].items()}
    for key in ("hamiltonian", "lagrangian", "lagrangian_terms", "equations_of_motion"):
        d.pop(key, None)
    path = tmp_path / "negated.json"
    path.write_text(json.dumps(d))
    return path


BAD_TASKS = [
    ("goal names a state the model lacks", 'reach = "-cos(theta1) - cos(theta1 + theta2) > 1.0"',
     'target = { phi = 3.14 }\nband = { phi = 0.1 }', "'phi'"),
    ("episode names a state the model lacks", "theta2_dot = 0.1 }", "x_dot = 0.1 }", "'x_dot'"),
    ("input on a coordinate not in the model", "[inputs.theta2]", "[inputs.x]", "inputs.x"),
    ("empty level set", "levels = [-1.0, 0.0, 1.0]", "levels = []", "inputs.theta2.levels"),
    ("dt zero", "dt = 0.2", "dt = 0.0", "dt"),
    ("dt negative", "dt = 0.2", "dt = -0.2", "dt"),
    ("dt not a number", "dt = 0.2", 'dt = "0.2"', "dt"),
    ("goal expression does not parse", "> 1.0", "> (1.0", "goal.reach"),
    ("goal expression unknown name", "cos(theta1 + theta2)", "cos(theta1 + theta3)", "theta3"),
    ("goal without comparison", "> 1.0", "", "goal.reach"),
    ("unknown key", "dt = 0.2", "dt = 0.2\nspeed = 1", "speed"),
    ("bad TOML", "[goal]", "[goal", "not valid TOML"),
    ("target not a rest state", 'reach = "-cos(theta1) - cos(theta1 + theta2) > 1.0"',
     "target = { theta1 = 1.0 }\nband = { theta1 = 0.1 }", "rest state"),
    ("reach no state satisfies", "> 1.0", "> 2.5", "no state at rest"),   # the tip is <= 2 m up
]


@pytest.mark.parametrize("case, old, new, needle", BAD_TASKS, ids=[c[0] for c in BAD_TASKS])
def test_bad_task_exit_2_one_line(tmp_path, capsys, case, old, new, needle):
    assert old in GOOD, case
    task = tmp_path / "task.toml"
    task.write_text(GOOD.replace(old, new))
    code = main(["control", str(ACROBOT), "--task", str(task), "--episodes", "1"])
    line = _one_error_line(capsys.readouterr().err)
    assert code == 2, case
    assert needle in line, line


def test_model_with_indefinite_kinetic_part_exit_2(negated_model, capsys):
    code = main(["control", str(negated_model), "--task", str(ACROBOT_TASK)])
    line = _one_error_line(capsys.readouterr().err)
    assert code == 2 and "kinetic part is not positive definite" in line, line


BAD_OPTIONS = [
    ("unknown plug-in", ["--plugin", "nope"], "--plugin 'nope'"),
    ("plug-in for another system", ["--plugin", "cart_pendulum"], "cart_pendulum"),
    ("no episodes", ["--episodes", "0"], "--episodes"),
    ("negative episodes", ["--episodes", "-3"], "--episodes"),
    ("negative seed", ["--seed", "-1"], "--seed"),
    ("json in a missing folder", ["--json", "TMP/no/such/dir/r.json"], "--json"),
    ("json is a folder", ["--json", "TMP"], "--json"),
    ("out is a file", ["--out", "TMP/file.txt"], "--out"),
    ("missing task file", ["--task", "TMP/nope.toml"], "cannot read"),
    ("missing model file", ["MODEL", "TMP/nope.json"], "nope.json"),
    ("plant of other coordinates", ["--plant", str(ROOT / "examples" / "data" / "furuta_model.json")],
     "--plant"),
]


@pytest.mark.parametrize("case, extra, needle", BAD_OPTIONS, ids=[c[0] for c in BAD_OPTIONS])
def test_bad_option_exit_2_one_line(tmp_path, capsys, case, extra, needle):
    (tmp_path / "file.txt").write_text("x")
    args = {"model": str(ACROBOT), "--task": str(ACROBOT_TASK), "--episodes": "1"}
    extra = [e.replace("TMP", str(tmp_path)) for e in extra]
    for k, v in zip(extra[::2], extra[1::2]):
        args[k.lower()] = v
    argv = ["control", args.pop("model")] + [a for kv in args.items() for a in kv]
    code = main(argv)
    line = _one_error_line(capsys.readouterr().err)
    assert code == 2, case
    assert needle in line, line


def test_missing_required_task_is_a_usage_error():
    r = run_cli("control", ACROBOT)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines()[-1].startswith(PREFIX), r.stderr
    assert "--task" in r.stderr


def test_bad_input_through_the_real_entry_point(tmp_path):
    """One case end to end in a subprocess: what a user's shell sees."""
    task = tmp_path / "task.toml"
    task.write_text(GOOD.replace("levels = [-1.0, 0.0, 1.0]", "levels = []"))
    r = run_cli("control", ACROBOT, "--task", task)
    assert r.returncode == 2 and r.stdout == ""
    assert "inputs.theta2.levels" in _one_error_line(r.stderr)


def test_good_run_writes_json_and_figure(tmp_path):
    """The Acrobot's identified model and its task file, one episode on the model itself:
    the goal is met (63 steps from seed 0's start), exit 0, the JSON has the keys the command
    writes and the figure is in --out (a folder it creates)."""
    out_json, out_dir = tmp_path / "runs.json", tmp_path / "figs"
    r = run_cli("control", ACROBOT, "--task", ACROBOT_TASK, "--episodes", 1, "--seed", 0,
                "--json", out_json, "--out", out_dir)
    assert r.returncode == 0, r.stderr
    assert "1/1 episodes met the goal" in r.stdout
    d = json.loads(out_json.read_text())
    assert set(d) == {"model", "task", "plant", "seed", "episodes", "success", "n",
                      "time_to_goal_median", "step_ms_median", "step_ms_p99"}
    assert (d["model"], d["task"], d["plant"], d["seed"]) == (str(ACROBOT), str(ACROBOT_TASK),
                                                             None, 0)
    assert d["n"] == 1 and d["success"] == 1 and len(d["episodes"]) == 1
    ep = d["episodes"][0]
    assert set(ep) == {"x0", "success", "time_to_goal", "within_limits", "steps",
                       "step_ms_median", "step_ms_max"}
    assert ep["success"] is True and ep["within_limits"] is True
    assert len(ep["x0"]) == 4 and all(abs(v) <= 0.1 for v in ep["x0"])   # the task's spread
    # the reach goal ends the episode at the goal: time = steps × dt, at most 100 steps
    assert ep["steps"] <= 100
    assert ep["time_to_goal"] == pytest.approx(ep["steps"] * 0.2, abs=1e-9)
    assert d["time_to_goal_median"] == pytest.approx(ep["time_to_goal"], abs=1e-4)
    png = out_dir / "control.png"
    assert png.is_file() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
