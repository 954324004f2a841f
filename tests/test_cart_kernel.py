"""The joint pole/cart viability kernel at the upright (control/cart_pendulum/cart_kernel.py)."""

import numpy as np
import pytest

from lsindy_cas import systems
from lsindy_cas.control.cart_pendulum.cart_kernel import CartPoleKernel, cart_pole_kernel
from lsindy_cas.control.cart_pendulum.viability import pole_kernel

FORCES = (-10.0, 0.0, 10.0)
G = 9.81


def kernel(mc, mp, L, **options):
    ode = systems.cart_pendulum(mc=mc, mp=mp, L=L).ode()
    return cart_pole_kernel(ode, 0, 1, np.pi, 0.05, FORCES, **options)


@pytest.mark.parametrize("mc, mp, L", [(1.0, 0.1, 1.0), (0.5, 0.05, 1.2), (0.7, 0.4, 0.8)])
def test_slow_coordinates_by_hand(mc, mp, L):
    """Point-mass pole, upright linearisation: x'' = (u + m_p g phi) / m_c and
    phi'' = ((m_c + m_p) g phi + u) / (m_c L), so a push moves x_dot and the pole rate in the
    ratio r = L, and v0 = x_dot - r omega obeys v0' = -g phi whatever the masses."""
    k = kernel(mc, mp, L, n_pole=4, n_cart=4, max_iter=1)
    assert abs(k.ratio) == pytest.approx(L, rel=1e-9)
    assert k.kappa == pytest.approx(-G, rel=1e-9)
    # v_max: the speed a full lean (g * 0.1 rad) stops within twice the widest p
    assert k.v_max == pytest.approx(np.sqrt(2 * G * 0.1 * 2 * (2.0 + L * 0.1)), rel=1e-9)


def test_a_far_track_leaves_the_pole_kernel():
    """With the track far away the cart never binds: the centre slice of the 4-D kernel is
    the pole's own kernel (same pole grid; the two differ only by the 2-D kernel's 0.1 %
    disturbance and interpolation, a few grid cells at the boundary)."""
    k4 = kernel(1.0, 0.1, 1.0, n_pole=20, n_cart=6, track=1e3)
    k2 = pole_kernel(systems.cart_pendulum().ode(), 0, 1, np.pi, 0.05, FORCES, n_grid=20)
    share4 = float(np.mean(k4.centre_slice() <= 0))
    assert share4 == pytest.approx(k2.viable_fraction, abs=0.05)


def test_a_shorter_track_never_enlarges_the_kernel():
    """Every sequence that keeps the cart within 1 m keeps it within 3 m: the centre slice's
    viable share can only shrink with the track (same pole grid)."""
    # 12 points per axis (3 s; 16: 10 s): shares 0.91 / 0 / 0 here (16: 0.94 / 0.94 / 0)
    shares = [float(np.mean(kernel(1.0, 0.1, 1.0, n_pole=12, n_cart=12,
                                   track=t).centre_slice() <= 0)) for t in (3.0, 1.0, 0.3)]
    assert shares[0] >= shares[1] >= shares[2]
    assert shares[0] > shares[2]


def test_value_at_maps_error_states():
    """value_at takes (x, phi, x_dot, omega) from the upright; outside the bands it is the
    normalised excess (positive)."""
    k = kernel(1.0, 0.1, 1.0, n_pole=8, n_cart=6, max_iter=3)
    assert k.value_at([0.0, 0.2, 0.0, 0.0])[0] == pytest.approx(1.0)   # twice the angle band
    assert k.value_at([3.0, 0.0, 0.0, 0.0])[0] == pytest.approx(0.5)   # 1.5 x the track


def test_bad_input():
    with pytest.raises(ValueError, match="a must be"):
        CartPoleKernel(np.eye(3), np.ones(4), 0.05, FORCES)
    with pytest.raises(ValueError, match="b must move the pole rate"):
        CartPoleKernel(np.eye(4), np.array([0.0, 0.0, 1.0, 0.0]), 0.05, FORCES)
    with pytest.raises(ValueError, match="levels"):
        CartPoleKernel(np.eye(4), np.ones(4), 0.05, [])
    with pytest.raises(ValueError, match="track"):
        CartPoleKernel(np.eye(4), np.ones(4), 0.05, FORCES, track=0.0)
