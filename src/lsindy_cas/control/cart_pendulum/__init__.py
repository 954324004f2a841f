"""The cart-pendulum swing-up: a plug-in of the generic controller (:mod:`..plugins`).

Everything here knows the system: a force on a cart on a finite track, a pole to bring to its
upright.  ``swingup`` holds :class:`SwingUpMPC` (the relaxed multiple-shooting MPC of the
generic core, :mod:`lsindy_cas.control.mpc`, with this system's rules), ``plugin`` its adapter
to :class:`~lsindy_cas.control.controller.Controller`; ``balancer`` and ``sequence_balancer``
choose the pushes near the upright, ``upright`` holds the pole's geometry and the hand-over,
``viability`` and ``cart_kernel`` the sets from which the pole (and cart) can be held,
``track_guard`` keeps the cart on its track.
"""

__all__ = ["SwingUpMPC", "find_upright", "CartPendulumPlugin", "PLUGIN"]


def __getattr__(name):                      # lazy: importing the package loads no CasADi
    if name in ("SwingUpMPC", "find_upright"):
        from . import swingup
        return getattr(swingup, name)
    if name in ("CartPendulumPlugin", "PLUGIN"):
        from .plugin import CartPendulumPlugin
        return CartPendulumPlugin
    raise AttributeError(name)
