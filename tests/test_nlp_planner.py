"""The NLP swing-up planner (``ControllerSettings(planner="nlp")``, control/nlp_planner.py):
settings checks, the tasks it refuses (before anything is built), one step returning an
admissible input, the residuals it minimises, the local policy still taking over at the target,
and (slow) a closed-loop swing-up on the cart-pendulum's true model."""
import casadi as ca
import numpy as np
import pytest

from lsindy_cas import systems
from lsindy_cas.control import controller as controller_module
from lsindy_cas.control.controller import Controller, ControllerSettings
from lsindy_cas.control.episodes import run_episode
from lsindy_cas.control.nlp_planner import NLPSettings, residuals
from lsindy_cas.control.task import Task

UPRIGHT = {"target": {"theta": np.pi}, "band": {"theta": 0.1, "theta_dot": 0.5}, "hold": 3.0}
NLP = ControllerSettings(planner="nlp", jit=False)     # uncompiled: no gcc run in the tests


def upright_task(inputs=None, goal=UPRIGHT):
    return Task(dt=0.05, inputs=inputs or {"x": {"levels": [-10.0, 0.0, 10.0]}}, goal=goal,
                limits={"x": [-2.0, 2.0]}, episode={"duration": 10.0})


# ====================================================================== settings
def test_the_default_planner_is_the_beam_search():
    assert ControllerSettings().planner == "beam"


@pytest.mark.parametrize("kw, error", [
    ({"planner": "milp"}, ValueError),
    ({"planner": "nlp", "nlp": {"horizon": 1.0}}, TypeError),
])
def test_controller_settings_reject_a_bad_planner(kw, error):
    with pytest.raises(error, match="planner|nlp"):
        ControllerSettings(**kw)


@pytest.mark.parametrize("kw", [{"horizon": 0.0}, {"max_intervals": 0}, {"energy_weight": -1.0},
                                {"distance_weight": -0.1}, {"limit_margin": 0.5},
                                {"solver": "bogus"}, {"depth": 0}])
def test_nlp_settings_reject_bad_values(kw):
    with pytest.raises(ValueError, match="nlp."):
        NLPSettings(**kw)


# ====================================================================== refusals
@pytest.fixture
def no_build(monkeypatch):
    """The model's system is never built: a refusal must come before it."""
    def fail(*a, **k):
        raise AssertionError("the controller was built before the refusal")
    monkeypatch.setattr(controller_module, "ControlledSystem", fail)


def test_a_reach_goal_is_refused_before_the_build(no_build):
    task = upright_task(goal={"reach": "-cos(theta) > 0.9"})
    with pytest.raises(ValueError, match="target goal.*planner='beam'"):
        Controller(systems.cart_pendulum(), task, NLP)


def test_two_inputs_are_refused_before_the_build(no_build):
    task = upright_task(inputs={"x": {"levels": [-10.0, 0.0, 10.0]},
                                "theta": {"levels": [-1.0, 0.0, 1.0]}})
    with pytest.raises(ValueError, match="one input, the task has 2.*planner='beam'"):
        Controller(systems.cart_pendulum(), task, NLP)


def test_the_beam_planner_still_serves_a_reach_goal():
    task = upright_task(goal={"reach": "-cos(theta) > 0.9"})
    Controller(systems.cart_pendulum(), task)


# ====================================================================== one step
@pytest.fixture(scope="module")
def nlp_controller():
    return Controller(systems.cart_pendulum(), upright_task(), NLP)


def test_one_nlp_step_returns_an_admissible_level(nlp_controller):
    ctrl = nlp_controller
    ctrl.reset()
    u = ctrl(np.array([0.1, 0.2, 0.0, 0.0]))         # hanging: far outside the LQR region
    assert u.shape == (1,) and float(u[0]) in (-10.0, 0.0, 10.0)
    assert ctrl.search.mpc.stats.n_solves == 1
    assert ctrl.search.mpc.plan_["states"].shape == (ctrl.search.horizon, 4)


def test_the_horizon_is_seconds_over_dt_capped_by_max_intervals(nlp_controller):
    s = NLPSettings()
    assert nlp_controller.search.horizon == min(s.max_intervals, round(s.horizon / 0.05))


def test_the_local_policy_takes_over_at_the_target(nlp_controller):
    ctrl = nlp_controller
    ctrl.reset()
    solves = ctrl.search.mpc.stats.n_solves
    x = np.array([0.0, np.pi + 0.01, 0.0, 0.0])
    assert np.array_equal(ctrl(x), ctrl.local(x))
    assert ctrl.search.mpc.stats.n_solves == solves      # no NLP solved there


def test_a_continuous_input_returns_the_relaxed_input_within_its_bounds():
    ctrl = Controller(systems.cart_pendulum(), upright_task({"x": {"bounds": [-10.0, 10.0]}}), NLP)
    u = ctrl(np.array([0.1, 0.2, 0.0, 0.0]))
    assert u.shape == (1,) and -10.0 <= u[0] <= 10.0
    assert u[0] == pytest.approx(np.clip(ctrl.search.mpc.plan_["forces"][0], -10, 10))


def test_residuals_energy_shaping_and_wrapped_distance(nlp_controller):
    """Energy term: (E(x with the actuated rates at 0) - E*) / E_s, -1 hanging still, unchanged
    by the actuated rate; distance: an angle 2π off the target is at the target."""
    ctrl = nlp_controller
    s = NLPSettings(energy_weight=1.0, distance_weight=1.0, center_weight=1.0, saturation=0.0)
    stage, terminal = residuals(ctrl.system, ctrl.bound, ctrl.energy_scale, ctrl.target_energy, s)
    r = np.asarray(stage([0.0, 0.0, 0.0, 0.0])).ravel()
    gap = (float(ctrl.system.energy([0, 0, 0, 0])) - ctrl.target_energy) / ctrl.energy_scale
    assert r[0] == pytest.approx(gap) and gap < 0
    moving = np.asarray(stage([0.0, 0.0, 3.0, 0.0])).ravel()
    assert moving[0] == pytest.approx(r[0])           # the input's own rate is not energy
    # residuals in state order after the energy: x / half the track (limited, not banded),
    # theta / 0.1, theta_dot / 0.5
    assert r.size == 4
    assert r[2] == pytest.approx(-2.0 / 0.1)          # 2 sin(-π/2) over the band
    at = np.asarray(stage([0.0, 3 * np.pi, 0.0, 0.0])).ravel()
    assert at[2] == pytest.approx(0.0, abs=1e-12) and at[0] == pytest.approx(0.0, abs=1e-12)
    assert np.asarray(stage([1.0, np.pi, 0, 0])).ravel()[1] == pytest.approx(0.5)
    assert np.asarray(stage([0.0, np.pi, 0, 1.0])).ravel()[3] == pytest.approx(2.0)
    assert float(ca.sumsqr(terminal([0.0, 0.0, 0.0, 0.0]))) == pytest.approx(0.0)


# ====================================================================== closed loop
@pytest.mark.slow
def test_nlp_planner_swings_up_and_holds_on_the_true_model():
    """The paper's cart-pendulum task as a plain task: from hanging, held 3 s inside the band
    and on the track (measured: goal at 2.0 s of 10 s)."""
    ctrl = Controller(systems.cart_pendulum(), upright_task(), NLP)

    def plant(x, u):
        return np.asarray(ctrl.system.step(x, u)).ravel()

    r = run_episode(ctrl, plant, np.array([0.1, 0.2, 0.0, 0.0]))
    assert r.success, r.summary()
    assert set(np.unique(r.U)) <= {-10.0, 0.0, 10.0}
    assert ctrl.search.mpc.stats.n_solves > 0
