"""Track keeping: override a controller's force with full braking when the cart could otherwise
no longer be stopped inside its track (:class:`TrackGuard`).

A real cart-pendulum rig has end stops; whatever the controller plans (a stale plan replayed
after failed solves, a balancer holding a pole that cannot be held), the cart must stay in
``|x| <= track_limit``.  Each step the guard predicts, on the controller's own model (its
discrete step ``F(x, u)``), the state after applying the chosen force for one period and then
the *braking policy*: full force against the cart's velocity (the lowest level while the cart
moves right, the highest while it moves left) for ``horizon`` seconds, which stops the cart and
then holds it (the force chatters around zero speed).  The pole's motion is part of the
prediction, so the bound holds for any pole angle the model covers.  If the cart's predicted
excursion, its distance from the current position enlarged by ``factor`` (room for a model
whose masses are off), leaves ``|x| <= track_limit - margin`` at any of these steps, or the cart
has not stopped by the end, the guard applies the braking force now instead; otherwise it leaves
the controller's choice alone.  Since braking is then still possible one step later, the cart
stays inside as long as the model's braking distance is right to within ``factor``.

Everything comes from the model: no plant parameter is assumed.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .._validate import check_real

__all__ = ["TrackGuard"]


class TrackGuard:
    """Full braking whenever the cart could otherwise not be stopped inside the track.

    Parameters
    ----------
    step : casadi.Function
        The model's discrete step ``F(x (4,), u (n_input,)) -> x_next`` over one period.
    levels : array_like
        Admissible forces, ascending.
    cart_index : int
        Position of the cart in ``q`` (its velocity is ``x[2 + cart_index]``).
    input_index : int
        Which entry of ``u`` is the cart force.
    track_limit : float
        The cart must stay in ``|x| <= track_limit`` (m).
    dt : float
        Control period (s).
    margin : float
        Distance (m) kept from the track's end in the prediction.
    factor : float
        The predicted excursion from the current position is multiplied by this (>= 1) before
        it is compared with the track: room for a model whose braking distance is too short
        (a 10 % heavier cart brakes about 10 % longer: the default 1.1).
    horizon : float
        Seconds of braking predicted; a cart not stopped by then counts as leaving the track.

    Attributes
    ----------
    n_fired : int
        Steps whose force the guard replaced, since construction (also counted by the
        controller in ``stats.n_guard``).
    """

    def __init__(self, step, levels, *, cart_index, input_index, track_limit, dt, margin=0.05,
                 factor=1.1, horizon=3.0):
        self.levels = np.asarray(levels, dtype=float)
        self.ic, self.track_limit = int(cart_index), float(track_limit)
        self.margin = check_real("guard margin", margin, nonnegative=True)
        if not self.margin < self.track_limit:
            raise ValueError(f"guard margin must be in [0, track_limit), got {margin!r}.")
        self.factor = check_real("guard factor", factor, positive=True)
        if self.factor < 1:
            raise ValueError(f"guard factor must be >= 1, got {factor!r}.")
        horizon = check_real("guard horizon", horizon, positive=True)
        self.n_steps = max(1, int(np.ceil(horizon / float(dt))))
        n_input = step.size1_in(1)
        lo, hi = float(self.levels[0]), float(self.levels[-1])
        x = ca.SX.sym("x", step.size1_in(0))
        v = x[2 + self.ic]
        u = ca.SX.zeros(n_input)
        u[input_index] = ca.if_else(v > 0, lo, hi)
        brake_step = ca.Function("brake", [x], [step(x, u)])
        x0 = ca.SX.sym("x0", step.size1_in(0))
        f = ca.SX.sym("f")
        u0 = ca.SX.zeros(n_input)
        u0[input_index] = f
        rows = [step(x0, u0)]
        for _ in range(self.n_steps):
            rows.append(brake_step(rows[-1]))
        traj = ca.horzcat(*rows)
        self._predict = ca.Function("guard", [x0, f], [traj[self.ic, :], traj[2 + self.ic, :]])
        self.n_fired = 0

    def brake_level(self, x):
        """Index of the braking force at state ``x``: against the cart's velocity (towards the
        centre when the cart is at rest)."""
        v = x[2 + self.ic]
        direction = v if v != 0 else x[self.ic]
        return 0 if direction > 0 else self.levels.size - 1

    def safe(self, x, force):
        """Whether applying ``force`` for one period and braking afterwards keeps the cart
        (with the excursion scaled by ``factor``) inside ``track_limit - margin`` and stops it
        within the horizon, on the model."""
        pos, vel = (np.asarray(a, dtype=float).ravel() for a in self._predict(x, force))
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
            return False
        reach = x[self.ic] + self.factor * (pos - x[self.ic])
        stopped = np.any(np.sign(vel[1:]) != np.sign(vel[:-1])) or abs(vel[-1]) < 1e-3
        return bool(stopped and np.max(np.abs(reach)) <= self.track_limit - self.margin)

    def __call__(self, x, index):
        """The level index to apply at state ``x``: ``index`` if it is safe, else braking."""
        x = np.asarray(x, dtype=float)
        if self.safe(x, float(self.levels[index])):
            return index
        self.n_fired += 1
        return self.brake_level(x)
