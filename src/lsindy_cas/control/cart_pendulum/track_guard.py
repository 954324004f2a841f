"""Track keeping: override a controller's force where the cart could otherwise no longer be
stopped inside its track (:class:`TrackGuard`).

A real cart-pendulum rig has end stops; whatever the controller plans (a stale plan replayed
after failed solves, a balancer holding a pole that cannot be held), the cart must stay in
``|x| <= track_limit``.  Each step the guard predicts, on the controller's own model (its
discrete step ``F(x, u)``), the state after applying the chosen force for one period and then
the *stopping policy* for ``horizon`` seconds: each period the level after which the cart's
speed is nearest a slow retreat towards the centre, i.e. full force against a fast cart, then
whichever level holds it against the pole's pull (always pushing against the velocity, or only
minimising the speed, walked a 0.55 kg cart to the end).  The pole's motion is part of the
prediction, so the bound holds for any pole angle the model covers.  If the cart's predicted
excursion, its distance from the current position enlarged by ``factor`` (room for a model
whose masses are off), leaves ``|x| <= track_limit - margin`` at any of these steps (or the
speed left at the end could not be stopped in time), the guard applies instead the level whose
prediction reaches least far; otherwise it leaves the controller's choice alone.  No force
holds a pole that spins so fast that its pull ``m_p L theta_dot^2`` exceeds the largest one.

Everything comes from the model: no plant parameter is assumed.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..._validate import check_real
from ..fastcall import NumericFunction

__all__ = ["TrackGuard", "check_guard_option"]


def check_guard_option(guard):
    """``SwingUpMPC``'s ``guard``: True, False or a dict of :class:`TrackGuard`'s options."""
    if not isinstance(guard, (bool, dict)):
        raise TypeError(f"guard must be True, False or a dict of options, got "
                        f"{type(guard).__name__}.")
    unknown = set(guard) - {"margin", "factor", "horizon"} if isinstance(guard, dict) else ()
    if unknown:
        raise ValueError(f"guard has unknown keys {sorted(unknown)}; known: "
                         f"['factor', 'horizon', 'margin'].")


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
        Seconds of the stopping policy predicted; the speed left at the end is taken to need
        ``v^2 / (2 decel)`` more (:attr:`decel`: the model's full-force deceleration at rest).

    Attributes
    ----------
    decel : float
        The cart's deceleration (m/s^2) under full force, from the model at rest.
    retreat : float
        The stopping policy's target speed towards the centre (m/s): ``decel * dt / 4``.
    n_fired : int
        Steps whose force the guard replaced, since construction (also counted by the
        controller in ``stats.n_guard``).
    """

    def __init__(self, step, levels, *, cart_index, input_index, track_limit, dt, margin=0.05,
                 factor=1.1, horizon=2.0):
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
        n_input, n_state = step.size1_in(1), step.size1_in(0)

        def held(x, force):
            u = ca.SX.zeros(n_input)
            u[input_index] = force
            return step(x, u)

        # the stopping policy: the level whose next cart speed is nearest a slow retreat
        # towards the centre (full force against a fast cart; near rest whichever level holds
        # it while the pole pulls: a policy that only pushes against the velocity, or only
        # minimises the speed, lets a light cart walk to the end)
        x = ca.SX.sym("x", n_state)
        nexts = [held(x, float(f)) for f in self.levels]
        rest = np.zeros(n_state)
        kicks = [float(ca.Function("h", [x], [n[2 + self.ic]])(rest)) for n in (nexts[0], nexts[-1])]
        #: the cart's deceleration (m/s^2) under full force, from the model at rest
        self.decel = max(abs(kicks[1] - kicks[0]) / (2.0 * float(dt)), 1e-9)
        #: the retreat speed (m/s): a quarter of one full push's speed change
        self.retreat = self.decel * float(dt) / 4
        target = -self.retreat * ca.sign(x[self.ic])

        def miss(nxt):
            return ca.fabs(nxt[2 + self.ic] - target)

        best, err, index = nexts[0], miss(nexts[0]), ca.SX(0)
        for i, nxt in enumerate(nexts[1:], start=1):
            better = miss(nxt) < err
            best = ca.if_else(better, nxt, best)
            err = ca.if_else(better, miss(nxt), err)
            index = ca.if_else(better, i, index)
        self._stop = NumericFunction(ca.Function("stop", [x], [best, index]))
        x0, f = ca.SX.sym("x0", n_state), ca.SX.sym("f")
        rows = [held(x0, f)]
        for _ in range(self.n_steps):
            rows.append(self._stop.f(rows[-1])[0])
        traj = ca.horzcat(*rows)
        self._predict = NumericFunction(
            ca.Function("guard", [x0, f], [traj[self.ic, :], traj[2 + self.ic, :]]))
        self.n_fired = 0

    def brake_level(self, x):
        """Index of the stopping policy's level at state ``x``: the level after which the
        model's cart speed is nearest :attr:`retreat` towards the centre."""
        return int(self._stop(np.asarray(x, dtype=float))[1].item())

    def reach(self, x, force):
        """Largest ``|x|`` (m) the model predicts for ``force`` over one period followed by the
        stopping policy, the excursion from the current position scaled by ``factor`` (inf if
        the prediction is not finite)."""
        pos, vel = (np.asarray(a, dtype=float).ravel() for a in self._predict(x, force))
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
            return np.inf
        # the speed left at the end of the horizon still needs v^2 / (2 decel) to stop
        pos = np.append(pos, pos[-1] + vel[-1] * abs(vel[-1]) / (2 * self.decel))
        return float(np.max(np.abs(x[self.ic] + self.factor * (pos - x[self.ic]))))

    def safe(self, x, force):
        """Whether applying ``force`` for one period and the stopping policy afterwards keeps
        the cart (its excursion scaled by ``factor``) inside ``track_limit - margin``, on the
        model."""
        return self.reach(x, force) <= self.track_limit - self.margin

    def __call__(self, x, index):
        """The level index to apply at state ``x``: ``index`` if it is safe, else the level
        whose predicted reach is smallest (ties: ``index``, then the stopping policy's)."""
        x = np.asarray(x, dtype=float)
        mine = self.reach(x, float(self.levels[index]))
        if mine <= self.track_limit - self.margin:
            return index
        reach = [mine if i == index else self.reach(x, float(f))
                 for i, f in enumerate(self.levels)]
        best = int(np.argmin(reach))
        if reach[best] >= mine - 1e-9:
            return index
        self.n_fired += 1
        return best
