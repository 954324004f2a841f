"""The pulse balancer's choice against a brute-force reference: every sequence simulated one
interval at a time on the upright linearisation (no superposition, no shared prefixes), its band
violation and cost computed by their definitions (``control/cart_pendulum/balancer.py``), and the lexicographic
rule applied.  The balancer's first level must start one of the reference's best sequences."""

import casadi as ca
import numpy as np
import pytest

from lsindy_cas import systems
from lsindy_cas.control.cart_pendulum.balancer import PulseBalancer, _sequences
from lsindy_cas.control.mpc import wrap_angle
from lsindy_cas.mpc import SwingUpMPC

FORCES = np.array([-10.0, 0.0, 10.0])


class _Correction:
    def __init__(self, gain, bias):
        self.gain, self.bias = gain, bias


def _reference_best_first(b, x, gain, bias):
    """Level indices (into FORCES) that start a best sequence, by direct simulation."""
    e = np.asarray(x, float) - b.x_ref
    e[b.ip] = wrap_angle(e[b.ip])
    bands = np.array([b.angle_band, b.rate_band, b.track_limit - b.track_margin])
    weights = np.array([1.0, 1.0, 100.0])  # track_weight 10, squared
    phi_ref = b.reference_lean(e)
    pushes = FORCES[FORCES != 0.0]
    viol, cost, first = [], [], []
    for row in _sequences(b.horizon, b.max_pushes, pushes.size):
        forces = np.where(row == 0, 0.0, pushes[np.maximum(row - 1, 0)])
        z, v, lean = e.copy(), 0.0, 0.0
        for f in forces:
            z = b.A @ z + (1.0 + gain) * b.B * f + bias
            comps = np.abs(z[[b.ip, 2 + b.ip, b.ic]])
            v += float(np.sum(weights * np.maximum(comps - bands, 0.0) ** 2))
            lean += (z[b.ip] - phi_ref) ** 2
        viol.append(v)
        cost.append(b.lean_weight * b.dt * lean + b.push_weight * np.count_nonzero(forces)
                    + b.mode_weight * float(z @ b.mode) ** 2)
        first.append(int(np.flatnonzero(FORCES == forces[0])[0]))
    viol, cost, first = np.array(viol), np.array(cost), np.array(first)
    ok = viol <= viol.min() + 1e-9
    best = cost[ok].min()
    return set(first[ok & (cost <= best + 1e-9 * max(1.0, abs(best)))].tolist())


@pytest.fixture(scope="module")
def parts():
    system = systems.cart_pendulum(mc=0.9, mp=0.11, L=0.9)
    ctrl = SwingUpMPC(system)
    return ctrl, system


@pytest.mark.parametrize("max_pushes", [1, 2, 3])
def test_choice_matches_brute_force(parts, max_pushes):
    ctrl, system = parts
    rng = np.random.default_rng(max_pushes)
    b = PulseBalancer(ctrl.step_function, system.ode(),
                      FORCES, cart_index=ctrl.cart_index, pole_index=ctrl.pole_index,
                      upright=ctrl.upright, track_limit=ctrl.track_limit, dt=ctrl.dt,
                      horizon=7, max_pushes=max_pushes, track_margin=0.25)
    checked = 0
    for _ in range(25):
        x = np.zeros(4)
        x[ctrl.cart_index] = rng.uniform(-1.5, 1.5)
        x[ctrl.pole_index] = ctrl.upright + rng.uniform(-0.1, 0.1)
        x[2 + ctrl.cart_index] = rng.uniform(-0.5, 0.5)
        x[2 + ctrl.pole_index] = rng.uniform(-0.6, 0.6)
        gain, bias = rng.uniform(-0.2, 0.2, 4), rng.normal(0.0, 1e-3, 4)
        b.correction = _Correction(gain, bias)
        b.engaged = True
        level = b(x)
        assert level in _reference_best_first(b, x, gain, bias)
        checked += 1
    assert checked == 25
