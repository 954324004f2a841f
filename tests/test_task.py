"""The control task (``control.task``): every bad field is a ``ValueError``/``TypeError`` naming
the field, task files are read with the same checks, every example task loads, and ``bind``
checks the task against a model's coordinates (states, reach expression) and wraps angles."""
from pathlib import Path

import numpy as np
import pytest

from lsindy_cas.control.task import BoundTask, Goal, Input, Task

ROOT = Path(__file__).resolve().parents[1]
TASKS = sorted((ROOT / "examples" / "tasks").glob("*.toml"))

# a reach task on the cart-pendulum's coordinates (x, theta): every case below changes one field
BASE = dict(dt=0.1, inputs={"x": {"levels": [-1.0, 0.0, 1.0]}}, goal={"reach": "cos(theta) < 0"})
TARGET = {"target": {"theta": np.pi}, "band": {"theta": 0.1}}
CART = ["x", "theta"]


def task(**changes):
    return Task(**{**BASE, **changes})


# ---------------------------------------------------------------- the fields, one at a time
@pytest.mark.parametrize("changes, exc, words", [
    # inputs
    ({"inputs": {"x": {"levels": []}}}, ValueError, ["inputs.x.levels", "empty"]),
    ({"inputs": {"x": {"levels": [1.0], "bounds": [0.0, 1.0]}}}, ValueError,
     ["'x'", "levels", "bounds"]),
    ({"inputs": {"x": {}}}, ValueError, ["'x'", "levels", "bounds"]),
    ({"inputs": {"x": {"bounds": [1.0, 1.0]}}}, ValueError, ["inputs.x.bounds", "low < high"]),
    ({"inputs": {"x": {"bounds": [2.0, -2.0]}}}, ValueError, ["inputs.x.bounds", "low < high"]),
    ({"inputs": {"x": {"bounds": [0.0, 1.0, 2.0]}}}, ValueError, ["inputs.x.bounds"]),
    ({"inputs": {"x": {"levels": "abc"}}}, TypeError, ["inputs.x.levels"]),
    ({"inputs": {"x": {"levels": [0.0, "one"]}}}, TypeError, ["inputs.x.levels"]),
    ({"inputs": {"x": {"levels": [0.0, float("nan")]}}}, ValueError, ["inputs.x.levels"]),
    ({"inputs": {"x": 3.0}}, TypeError, ["inputs.x"]),
    ({"inputs": {}}, ValueError, ["inputs"]),
    # dt
    ({"dt": 0.0}, ValueError, ["dt", "> 0"]),
    ({"dt": -0.1}, ValueError, ["dt", "> 0"]),
    ({"dt": float("inf")}, ValueError, ["dt", "finite"]),
    ({"dt": "0.1"}, TypeError, ["dt", "number"]),
    ({"dt": True}, TypeError, ["dt", "number"]),          # a bool is not a sample time
    ({"dt": None}, TypeError, ["dt", "number"]),
    # goal
    ({"goal": {**TARGET, "reach": "cos(theta) < 0"}}, ValueError, ["goal", "target", "reach"]),
    ({"goal": {}}, ValueError, ["goal", "target", "reach"]),
    ({"goal": {"target": {"theta": np.pi}}}, ValueError, ["goal.band", "required"]),
    ({"goal": {"target": {"theta": np.pi}, "band": {}}}, ValueError, ["goal.band"]),
    ({"goal": {"target": {"theta": np.pi}, "band": {"theta": 0.0}}}, ValueError,
     ["goal.band.theta", "> 0"]),
    ({"goal": {"target": {"theta": np.pi}, "band": {"theta": -0.1}}}, ValueError,
     ["goal.band.theta", "> 0"]),
    ({"goal": {**TARGET, "hold": -1.0}}, ValueError, ["goal.hold"]),
    ({"goal": {"target": {"theta": "up"}, "band": {"theta": 0.1}}}, TypeError,
     ["goal.target.theta"]),
    ({"goal": {"reach": "cos(theta)"}}, ValueError, ["goal.reach", "condition"]),
    ({"goal": {"reach": "cos(theta) == 0"}}, ValueError, ["goal.reach", "condition"]),
    ({"goal": {"reach": 1.0}}, ValueError, ["goal.reach"]),
    ({"goal": {"reach": "cos(theta) < 0", "band": {"theta": 0.1}}}, ValueError, ["goal.band"]),
    ({"goal": {"reach": "cos(theta) < 0", "tolerance": 0.1}}, ValueError,
     ["goal", "unknown", "tolerance"]),
    ({"goal": "upright"}, TypeError, ["goal"]),
    # limits
    ({"limits": {"x": [2.0, -2.0]}}, ValueError, ["limits.x", "low < high"]),
    ({"limits": {"x": [1.0, 1.0]}}, ValueError, ["limits.x", "low < high"]),
    ({"limits": {"x": 2.0}}, ValueError, ["limits.x"]),
    ({"limits": {"x": ["a", 1.0]}}, TypeError, ["limits.x"]),
    # weights and episode
    ({"weights": {"theta": -1.0}}, ValueError, ["weights.theta"]),
    ({"episode": {"duration": 0.0}}, ValueError, ["episode.duration"]),
    ({"episode": {"spread": {"x": -0.1}}}, ValueError, ["episode.spread.x"]),
    ({"episode": {"length": 3.0}}, ValueError, ["episode", "unknown", "length"]),
    ({"inputs": {"x": {"levels": [1.0], "step": 0.5}}}, ValueError,
     ["inputs.x", "unknown", "step"]),
])
def test_bad_field_raises_naming_it(changes, exc, words):
    with pytest.raises(exc) as info:
        task(**changes)
    for w in words:
        assert w in str(info.value), (w, str(info.value))


@pytest.mark.parametrize("lim", [[-1.0, 0.0, 1.0], [1.0]])
def test_limits_with_wrong_length_names_the_field(lim):
    with pytest.raises(ValueError, match=r"limits\.x"):
        task(limits={"x": lim})


def test_a_good_task_is_normalised_and_frozen():
    t = task(inputs={"x": {"levels": [1, -1, 0, 1]}, "theta": {"bounds": [-2, 3]}},
             goal={**TARGET, "hold": 2}, limits={"x": [-2, 2]})
    assert t.inputs["x"].levels == (-1.0, 0.0, 1.0)           # sorted, unique, float
    assert t.inputs["x"].discrete and not t.inputs["theta"].discrete
    assert (t.inputs["theta"].low, t.inputs["theta"].high) == (-2.0, 3.0)
    # a continuous input's search candidates: its bounds and rest
    assert t.inputs["theta"].candidates() == (-2.0, 0.0, 3.0)
    assert Input("u", bounds=(1.0, 3.0)).candidates() == (1.0, 3.0)   # 0 clipped to the bounds
    assert t.goal.hold == 2.0 and t.limits == {"x": (-2.0, 2.0)}
    assert t.episode.duration == 10.0                         # the documented default
    with pytest.raises(Exception):                            # frozen dataclass
        t.dt = 0.2


def test_input_and_goal_objects_are_accepted_as_given():
    t = task(inputs={"x": Input("x", levels=[0.5])}, goal=Goal(reach="x > 1"))
    assert t.inputs["x"].levels == (0.5,) and t.goal.reach == "x > 1"
    # an Input stored under another name is renamed to its key (the key names the coordinate)
    assert task(inputs={"x": Input("y", levels=[1.0])}).inputs["x"].coord == "x"


# ---------------------------------------------------------------- task files
GOOD_FILE = """\
dt = 0.1
[inputs.x]
levels = [-1.0, 0.0, 1.0]
[goal]
reach = "cos(theta) < 0"
"""


@pytest.mark.parametrize("text, words", [
    (GOOD_FILE + "speed = 3\n", ["unknown", "speed"]),                       # top level
    (GOOD_FILE.replace("levels", "step = 1\nlevels"), ["inputs.x", "unknown", "step"]),
    (GOOD_FILE + "tolerance = 0.1\n", ["goal", "unknown", "tolerance"]),     # in [goal]
    (GOOD_FILE + "[episode]\nlength = 2\n", ["episode", "unknown", "length"]),
    (GOOD_FILE.replace("dt = 0.1\n", ""), ["missing", "dt"]),
    (GOOD_FILE.replace("[goal]\nreach = \"cos(theta) < 0\"\n", ""), ["missing", "goal"]),
    ("dt = 0.1\n[inputs.x\nlevels = [1]\n", ["not valid TOML"]),                # syntax
    ("dt = = 0.1\n", ["not valid TOML"]),
    (GOOD_FILE.replace("0.1", "0.0"), ["dt", "> 0"]),
    (GOOD_FILE.replace("-1.0, 0.0, 1.0", ""), ["inputs.x.levels", "empty"]),
    (GOOD_FILE.replace("0.1", '"fast"'), ["dt", "number"]),
])
def test_bad_task_file(tmp_path, text, words):
    path = tmp_path / "task.toml"
    path.write_text(text)
    with pytest.raises((ValueError, TypeError)) as info:
        Task.load(path)
    for w in words:
        assert w in str(info.value), (w, str(info.value))


def test_missing_task_file_is_a_value_error_not_os_error(tmp_path):
    path = tmp_path / "nope.toml"
    with pytest.raises(ValueError, match="cannot read") as info:
        Task.load(path)
    assert str(path) in str(info.value)
    with pytest.raises(ValueError, match="cannot read"):       # a folder is not a task file
        Task.load(tmp_path)


def test_good_task_file_round_trip(tmp_path):
    path = tmp_path / "task.toml"
    path.write_text(GOOD_FILE + "[limits]\nx = [-2.0, 2.0]\n[episode]\nduration = 4.0\n"
                    "spread = { theta = 0.2 }\n")
    t = Task.load(path)
    assert t == task(limits={"x": [-2.0, 2.0]}, episode={"duration": 4.0,
                                                          "spread": {"theta": 0.2}})


# the coordinates each example task is written for (its model file or the paper system)
EXAMPLE_COORDS = {"acrobot": ["theta1", "theta2"], "furuta": ["phi", "theta"],
                  "cart_pendulum": ["x", "theta"],
                  "double_pendulum_cart": ["x", "theta1", "theta2"],
                  "double_pendulum_cart_swingup": ["x", "theta1", "theta2"]}


def test_every_example_task_is_known_here():
    assert {p.stem for p in TASKS} == set(EXAMPLE_COORDS)


@pytest.mark.parametrize("path", TASKS, ids=lambda p: p.stem)
def test_every_example_task_loads_and_binds_to_its_model(path):
    t = Task.load(path)
    b = t.bind(EXAMPLE_COORDS[path.stem])
    n = 2 * len(EXAMPLE_COORDS[path.stem])
    assert b.B.shape == (n // 2, len(t.inputs)) and np.all(b.B.sum(axis=0) == 1.0)
    assert len(b.names) == n and b.lower.shape == b.upper.shape == (n,)
    assert (b.target is None) != (b.reach is None)


# ---------------------------------------------------------------- bind
@pytest.mark.parametrize("changes, words", [
    ({"inputs": {"y": {"levels": [1.0]}}}, ["inputs.y", "no coordinate 'y'"]),
    ({"inputs": {"x_dot": {"levels": [1.0]}}}, ["inputs.x_dot"]),     # a rate is no coordinate
    ({"goal": {"target": {"phi": 0.0}, "band": {"theta": 0.1}}}, ["goal.target", "'phi'"]),
    ({"goal": {"target": {"theta": 0.0}, "band": {"phi_dot": 0.1}}}, ["goal.band", "'phi_dot'"]),
    ({"limits": {"y": [-1.0, 1.0]}}, ["limits", "'y'"]),
    ({"episode": {"start": {"phi": 1.0}}}, ["episode", "'phi'"]),
    ({"episode": {"spread": {"phi": 1.0}}}, ["episode", "'phi'"]),
    ({"weights": {"phi": 1.0}}, ["weights.phi"]),
    ({"goal": {"target": {"x": 3.0}, "band": {"x": 0.1}}, "limits": {"x": [-2.0, 2.0]}},
     ["goal.target", "outside its limits"]),
    # reach expressions: not parsable, unknown names, unknown functions, two comparisons
    ({"goal": {"reach": "cos(theta < 0"}}, ["goal.reach", "parse"]),
    ({"goal": {"reach": "cos(phi) < 0"}}, ["goal.reach", "phi"]),
    ({"goal": {"reach": "theta_ddot > 1"}}, ["goal.reach", "theta_ddot"]),
    ({"goal": {"reach": "foo(theta) > 1"}}, ["goal.reach", "foo"]),
    ({"goal": {"reach": "theta >"}}, ["goal.reach", "empty"]),
    ({"goal": {"reach": "0 < theta < 1"}}, ["goal.reach", "one comparison"]),
    ({"goal": {"reach": "__import__('os') > 1"}}, ["goal.reach"]),
])
def test_bind_rejects_what_the_model_lacks(changes, words):
    t = task(**changes)                     # valid on its own ...
    with pytest.raises(ValueError) as info:
        t.bind(CART)                        # ... but not for this model
    for w in words:
        assert w in str(info.value), (w, str(info.value))


def test_bind_arrays_known_answers():
    t = task(inputs={"theta": {"bounds": [-1.0, 1.0]}, "x": {"levels": [0.0, 2.0]}},
             goal={"target": {"theta": np.pi, "x_dot": 0.5}, "band": {"theta": 0.1}},
             limits={"x": [-2.0, 2.0], "theta_dot": [-9.0, 9.0]})
    b = t.bind(CART)
    assert isinstance(b, BoundTask) and b.names == ["x", "theta", "x_dot", "theta_dot"]
    # inputs in task order: column 0 acts on theta (row 1), column 1 on x (row 0)
    np.testing.assert_array_equal(b.B, [[0.0, 1.0], [1.0, 0.0]])
    np.testing.assert_array_equal(b.target, [0.0, np.pi, 0.5, 0.0])
    np.testing.assert_array_equal(b.band, [np.inf, 0.1, np.inf, np.inf])
    np.testing.assert_array_equal(b.lower, [-2.0, -np.inf, -np.inf, -9.0])
    np.testing.assert_array_equal(b.upper, [2.0, np.inf, np.inf, 9.0])
    assert b.reach is None


def test_reach_margin_known_values():
    """'a > b' has margin a − b, 'a < b' has b − a (>= 0 where the condition holds)."""
    b = task(goal={"reach": "-cos(theta) + x_dot >= 0.5"}).bind(CART)
    X = np.array([[0.0, np.pi, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [5.0, np.pi / 2, -1.0, 3.0]])
    g = np.asarray(b.reach[1].map(3)(X.T)).ravel()
    np.testing.assert_allclose(g, [0.5, -0.5, -1.5], atol=1e-15)   # cos(π/2) = 6e-17
    b = task(goal={"reach": "theta < 1"}).bind(CART)
    assert float(b.reach[1]([0.0, 0.25, 0.0, 0.0])) == 0.75


def test_reached_band_wraps_angles():
    """Target θ = π with band 0.1: θ = −π + 0.05 is 0.05 from it modulo 2π (inside); without
    the wrap it is 2π − 0.05 away (outside).  Unchecked states (band inf) never matter."""
    b = task(goal={"target": {"theta": np.pi}, "band": {"theta": 0.1}}).bind(CART)
    wrap = np.array([False, True, False, False])
    x = np.array([123.0, -np.pi + 0.05, -7.0, 0.0])
    assert b.reached_band(x, wrap)
    assert not b.reached_band(x, np.zeros(4, bool))
    assert b.reached_band([0.0, 3 * np.pi - 0.09, 0.0, 0.0], wrap)      # a turn further
    assert not b.reached_band([0.0, -np.pi + 0.11, 0.0, 0.0], wrap)     # just outside
    assert not b.reached_band([0.0, np.pi, 0.0, 0.0] + np.array([0, 0.2, 0, 0]), wrap)


def test_start_is_seeded_nominal_plus_uniform_spread():
    b = task(episode={"start": {"theta": 1.0}, "spread": {"x": 0.5}}).bind(CART)
    x = b.start(np.random.default_rng(3))
    u = np.random.default_rng(3).uniform(-0.5, 0.5)
    np.testing.assert_array_equal(x, [u, 1.0, 0.0, 0.0])
