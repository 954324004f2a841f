"""The cart-pendulum swing-up behind the controller's plug-in interface (:mod:`..plugins`).

:class:`CartPendulumPlugin` builds :class:`~.swingup.SwingUpMPC` (relaxed MPC with pulse and
sequence balancers, track guard and coefficient estimate) from the task's level set, sample
time, target angle and track.  It is kept because on the paper's cart-pendulum the generic
beam search runs into the ±2 m track (docs/control.md gives the measurement).
"""
from __future__ import annotations

import numpy as np

__all__ = ["CartPendulumPlugin"]


class CartPendulumPlugin:
    """The cart-pendulum swing-up (:class:`~.swingup.SwingUpMPC`) as a plug-in.

    The task must have one discrete input on one of the model's two coordinates (the cart),
    a target on the other (the pole's upright angle) and limits on the cart (the track,
    symmetric about 0).  Extra keyword arguments go to ``SwingUpMPC``.
    """

    name = "cart_pendulum"

    def __init__(self, **options):
        self.options = options

    def build(self, model, task, controller):
        from .swingup import SwingUpMPC
        b = controller.bound
        coords = list(b.coords.names)
        if len(coords) != 2 or len(task.inputs) != 1:
            raise ValueError("the cart_pendulum plug-in needs a model with two coordinates "
                             "(cart, pole) and one input (the force on the cart)")
        (cart, spec), = task.inputs.items()
        if not spec.discrete:
            raise ValueError("the cart_pendulum plug-in needs a level set (levels = [...])")
        pole = coords[1 - coords.index(cart)]
        if b.target is None:
            raise ValueError("the cart_pendulum plug-in needs a target goal (the upright angle)")
        ic = coords.index(cart)
        lo, hi = b.lower[ic], b.upper[ic]
        if not (np.isfinite(lo) and np.isfinite(hi) and np.isclose(lo, -hi)):
            raise ValueError(f"the cart_pendulum plug-in needs a symmetric track: limits.{cart} "
                             "= [-L, L]")
        return _Policy(SwingUpMPC(model, spec.levels, dt=task.dt, track_limit=float(hi),
                                  upright=float(b.target[coords.index(pole)]), actuated=cart,
                                  **self.options))


class _Policy:
    def __init__(self, mpc):
        self.mpc = mpc

    def reset(self):
        self.mpc.reset()

    def __call__(self, x):
        return np.array([float(self.mpc(x))])
