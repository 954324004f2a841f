"""Tests of the track guard: the cart never leaves the track, and the guard leaves a
controller that keeps the track alone."""

import numpy as np
import pytest

from lsindy_cas import systems
from lsindy_cas.control.ocp import rk4_step
from lsindy_cas.control.cart_pendulum.track_guard import TrackGuard
from lsindy_cas.mpc import SwingUpMPC
from lsindy_cas.paper.swingup import Plant, identify_cart_pendulum, random_starts, run_episode

FORCES = (-10.0, 0.0, 10.0)
DT = 0.05


class _Exact:
    """The exact equations of a cart-pendulum as the controller's model."""

    coords_, actuated_ = ["x", "theta"], ["x"]

    def __init__(self, system):
        self._ode = system.ode()

    def ode(self):
        return self._ode


def _guard(system, **kw):
    step = rk4_step(system.ode(), 4, 2, DT, 1)
    return TrackGuard(step, np.array(FORCES), cart_index=0, input_index=0, track_limit=2.0,
                      dt=DT, **kw)


def _run(system, x0, choose, n_steps=200):
    """Closed loop on the true plant; returns max |x| and the forces applied."""
    plant = Plant(system, DT)
    x, used, forces = np.asarray(x0, float), abs(x0[0]), []
    for _ in range(n_steps):
        forces.append(choose(x))
        fine = plant.step(x, forces[-1])
        used = max(used, float(np.max(np.abs(fine[:, 0]))))
        x = fine[-1]
    return used, np.array(forces)


@pytest.mark.parametrize("push", [10.0, -10.0])
def test_guard_keeps_a_cart_pushed_at_the_end_on_the_track(push):
    # the heavy, short plant of the family benchmark (2.0/0.3/0.3, the one that ran to 10.5 m):
    # a "controller" that always pushes towards one end, the cart moving there, the pole
    # swinging (not spinning: a pole whose centrifugal pull m_p L theta_dot^2 exceeds the force
    # cannot be held by any force in the set; a 12 rad/s spin of this pole pulls with 13 N)
    system = systems.cart_pendulum(mc=2.0, mp=0.3, L=0.3)
    x0 = [0.0, 0.5, np.sign(push) * 1.5, 1.0]
    used_free, _ = _run(system, x0, lambda x: push)
    assert used_free > 2.0  # without the guard the cart leaves the track
    guard = _guard(system)
    used, forces = _run(system, x0, lambda x: FORCES[guard(x, FORCES.index(push))])
    assert used <= 2.0
    # it brakes only near the end: it let the push through at first, then held the cart
    assert forces[0] == push and guard.n_fired > 0
    assert set(np.unique(forces)) <= set(FORCES)


def test_guard_derives_the_braking_distance_from_the_model():
    # a cart at 1 m moving at v towards the end: braking with 10 N on the 2.3 kg cart needs about
    # v^2 / (2 * 10 / 2.3) m (the pole at rest upright) after the step: with factor 1.1 and
    # margin 0.05 the guard lets 10 N act at 2 m/s (stop near 1.7 m, 1.75 with the factor) and
    # brakes at 3 m/s (stop near 2.3 m)
    guard = _guard(systems.cart_pendulum(mc=2.0, mp=0.3, L=0.3))
    assert guard.safe(np.array([1.0, np.pi, 2.0, 0.0]), 10.0)
    assert not guard.safe(np.array([1.0, np.pi, 3.0, 0.0]), 10.0)
    assert guard(np.array([1.0, np.pi, 3.0, 0.0]), 2) == 0  # brake: the lowest level
    assert guard(np.array([-1.0, np.pi, -3.0, 0.0]), 0) == 2
    assert guard(np.array([0.0, np.pi, 0.0, 0.0]), 1) == 1  # at rest in the centre: untouched


@pytest.mark.parametrize("guard, exc, word", [
    ("yes", TypeError, "guard"), ({"speed": 1}, ValueError, "guard"),
    ({"factor": 0.5}, ValueError, "factor"), ({"margin": 3.0}, ValueError, "margin")])
def test_bad_guard_options_raise_naming_them(guard, exc, word):
    with pytest.raises(exc, match=word):
        SwingUpMPC(_Exact(systems.cart_pendulum()), dt=DT, guard=guard)


@pytest.mark.parametrize("guard", [False, True])
def test_failing_solver_replaying_its_plan_keeps_the_track_only_with_the_guard(guard, monkeypatch):
    # the mechanism of the 10.5 m run: every solve fails, so each step replays the shifted
    # previous plan (here the cold-start guess: a short push, then coasting) whatever the cart
    # does; from 1 m at 3.5 m/s the cart coasts off the track unless the guard brakes
    system = systems.cart_pendulum()
    ctrl = SwingUpMPC(_Exact(system), dt=DT, balance=False, guard=guard)

    def fail(*args, **kwargs):
        raise RuntimeError("nlp_hess_l failed: NaN detected")

    monkeypatch.setattr(ctrl.nlp, "solve", fail)
    ep = run_episode(ctrl, Plant(system, DT), [1.0, np.pi, 3.5, 0.0], t_end=3.0)
    assert ctrl.stats.n_failures == ctrl.stats.n_solves == 60
    if guard:
        assert ep.track_used <= 2.0 and ctrl.stats.n_guard > 0
    else:
        assert ep.track_used > 2.0 and ctrl.stats.n_guard == 0


def test_guard_never_fires_in_a_nominal_paper_plant_episode():
    model = identify_cart_pendulum()[0]
    ctrl = SwingUpMPC(model, dt=DT)
    for x0 in ([0.0, 0.0, 0.0, 0.0], random_starts(20, seed=0)[0]):
        ep = run_episode(ctrl, Plant(systems.cart_pendulum(), DT), x0)
        assert ep.success
    assert ctrl.stats.n_guard == 0


def test_brake_level_pushes_against_a_fast_cart_and_holds_a_slow_one():
    """The stopping policy: full force against a cart running outward fast; near rest the level
    whose next speed is nearest a slow retreat towards the centre, a quarter of one push's speed
    change: from rest, waiting (0) is nearer it than a full push (the retreat's 4 times)."""
    guard = _guard(systems.cart_pendulum())
    fast_out = np.array([1.0, 0.0, 1.5, 0.0])
    assert FORCES[guard.brake_level(fast_out)] == -10.0
    assert FORCES[guard.brake_level(-fast_out)] == 10.0
    level = guard.brake_level(np.array([1.0, 0.0, 0.0, 0.0]))
    assert isinstance(level, int) and FORCES[level] == 0.0
