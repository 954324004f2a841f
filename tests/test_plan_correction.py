"""The relaxed plan uses the online correction's input gain (``adapt_plan``)."""

import numpy as np
import pytest

from lsindy_cas import systems
from lsindy_cas.mpc import SwingUpMPC


def _recorded_gains(ctrl, x, steps=2):
    gains, solve = [], ctrl.nlp.solve

    def record(x_init, z0, lam_g0, lam_x0, kind="warm", gain=0.0, ref=None):
        gains.append(gain)
        return solve(x_init, z0, lam_g0, lam_x0, kind=kind, gain=gain, ref=ref)

    ctrl.nlp.solve = record
    for _ in range(steps):
        ctrl.correction.estimate[:] = 0.0
        ctrl.correction.estimate[3, 0] = 0.2  # the pole's push estimated 20 % stronger
        ctrl.correction.estimate[2, 0] = -0.1  # the cart's 10 % weaker
        ctrl._last = None  # no update of the estimate from this made-up state
        ctrl(x)
    return gains


def test_the_plan_uses_the_pole_gain_of_the_correction():
    """SwingUpMPC hands the NLP the correction's gain of the pole rate (state component
    2 + pole); ``adapt_plan=False`` hands it 0 (the model as identified)."""
    x = np.array([0.0, 0.3, 0.0, 0.0])  # hanging nearly still: the NLP decides
    ctrl = SwingUpMPC(systems.cart_pendulum(), balance=False)
    assert ctrl.plan_gain_index == 3
    assert _recorded_gains(ctrl, x) == [pytest.approx(0.2)] * 2
    off = SwingUpMPC(systems.cart_pendulum(), balance=False, adapt_plan=False)
    assert _recorded_gains(off, x) == [0.0, 0.0]


def _family_case(plant, factors, start):
    """The family benchmark's identified model of ``plant`` (mc, mp, L), the mismatched plant
    simulated and its random start ``start`` (of 5, seed 0)."""
    from lsindy_cas.paper.swingup import Plant, identify_cart_pendulum, random_starts

    mc, mp, L = plant
    model = identify_cart_pendulum(systems.cart_pendulum(mc=mc, mp=mp, L=L))[0]
    true = systems.cart_pendulum(mc=mc * factors[0], mp=mp * factors[1], L=L * factors[2])
    return model, Plant(true, 0.05), random_starts(5, 0)[start]


@pytest.mark.slow
def test_a_heavier_plant_is_caught_when_the_plan_knows_its_push():
    """Family plant 1.5/0.3/1.0 (identified), plant cart and pole length +10 %, pole mass
    -10 % (the benchmark's start 2), the top-rate band held at 1.5 rad/s, the energy term off
    and the warm SQP capped at 10 iterations (the settings this was measured with; with the
    energy term on, as by default, this start comes up either way): planning with
    the model's push, the swing-up overshot the top again and again (the pole still spinning
    at 10 s); planning with the online estimate of the push, the pole is up at 2.6 s."""
    from lsindy_cas.paper.swingup import run_episode

    model, plant, x0 = _family_case((1.5, 0.3, 1.0), (1.1, 0.9, 1.1), 2)
    held = {"weights": {"top_rate_band": 1.5, "energy": 0.0}, "max_iter": 10}
    without = run_episode(SwingUpMPC(model, adapt_plan=False, **held), plant, x0)
    with_gain = run_episode(SwingUpMPC(model, **held), plant, x0)
    assert not without.success
    assert with_gain.success and with_gain.time_to_upright < 4.0


@pytest.mark.slow
def test_the_top_rate_band_scales_with_the_plants_kick():
    """Family plant 2.0/0.5/1.5 (kick 0.17 rad/s), every parameter +10 % (start 1): with the
    paper plant's 1.5 rad/s band the pole passed the top too fast to be caught for 7.6 s
    (too late for the last 3 s); with the default band, three kicks (0.5 rad/s), it is
    caught."""
    from lsindy_cas.paper.swingup import run_episode

    model, plant, x0 = _family_case((2.0, 0.5, 1.5), (1.1, 1.1, 1.1), 1)
    fixed = run_episode(SwingUpMPC(model, weights={"top_rate_band": 1.5}), plant, x0)
    scaled = run_episode(SwingUpMPC(model), plant, x0)
    assert not fixed.success
    assert scaled.success
