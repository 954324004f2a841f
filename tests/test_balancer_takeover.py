"""When the pulse balancer takes over a fast cart (``SwingUpMPC.PULSE_BRAKE``): only if
leaning by ``brake_fraction`` of its largest lean stops the cart inside the track; 0.45 by default
(the balancer's own default, 0.5, took over a cart it could not stop under a 10 % mismatch)."""

import numpy as np
import pytest

from lsindy_cas import systems
from lsindy_cas.mpc import SwingUpMPC
from lsindy_cas.paper.swingup import Plant, random_starts, run_episode


@pytest.fixture(scope="module")
def nominal():
    return systems.cart_pendulum()


def test_the_pulse_balancer_brakes_on_045_of_its_lean_by_default(nominal):
    ctrl = SwingUpMPC(nominal, jit=False)
    pulse, sequence = ctrl._escalation[:2]
    assert ctrl.PULSE_BRAKE == 0.45 and pulse.brake_fraction == 0.45
    assert sequence.brake_fraction == 0.5  # the sequence balancer keeps its own
    given = SwingUpMPC(nominal, jit=False, balance={"method": "auto", "brake_fraction": 0.5})
    assert given._escalation[0].brake_fraction == 0.5  # balance= still sets it


@pytest.mark.parametrize("fraction, engaged", [(0.5, True), (0.45, False)])
def test_takeover_needs_the_cart_stopped_inside_the_track(nominal, fraction, engaged):
    """The hand-over of held-out seed 2 start 18 (below): cart at +1.06 m running at -1.02 m/s,
    pole upright and still.  Braking at a = fraction |kappa| max_lean stops it at
    x + v |v| / (2 a): about -1.59 m with 0.5 (inside 1.75 m) and -1.89 m with 0.45 (outside)."""
    ctrl = SwingUpMPC(nominal, jit=False, balance={"method": "pulse", "brake_fraction": fraction})
    bal = ctrl.balancer
    a = fraction * abs(bal.kappa) * bal.max_lean
    stop = 1.06 - 1.02 ** 2 / (2 * a)
    assert (abs(stop) <= bal.track_limit - bal.track_margin) is engaged
    bal.reset()
    assert bal.active(np.array([1.06, 0.0, -1.02, 0.0])) is engaged


def _held_out_start_18(ctrl):
    """Family seed 2, start 18 of the paper plant with cart and pole 10 % heavier and the pole
    10 % shorter than the model: the swing-up hands over with the cart at 1 m/s."""
    plant = Plant(systems.cart_pendulum(mc=1.1, mp=0.11, L=0.9), 0.05)
    return run_episode(ctrl, plant, random_starts(60, 2)[18])


def test_a_fast_cart_is_left_to_the_plan_and_the_pole_held(nominal):
    ep = _held_out_start_18(SwingUpMPC(nominal, jit=False))
    assert ep.success and ep.track_used < 1.75


@pytest.mark.slow
def test_taking_it_over_at_05_loses_the_pole_at_the_track_end(nominal):
    ctrl = SwingUpMPC(nominal, jit=False, balance={"method": "auto", "brake_fraction": 0.5})
    ep = _held_out_start_18(ctrl)
    assert not ep.success and ep.track_used > 1.75
