"""Balancing at the upright with every level sequence: branch and bound over ``levels^N``.

:class:`PulseBalancer` enumerates sequences with at most a few pushes, which cannot express the
alternating pushes in close succession ("chattering") that a plant needs when one push changes
the pole rate by nearly the width of the success band (``F dt / (m_c L)`` up to ~0.9 rad/s
against ``|theta_dot| < 0.5``).  :class:`SequenceBalancer` plans over *all* sequences of the
force levels over ``horizon`` intervals, on the same model linearised at the upright, with the
same online gain/offset correction, reference lean and hand-over rule as the pulse balancer.

Cost of a sequence (every stage cost is non-negative)::

    sum_k  violation_weight * band_excess(z_k)^2 + lean_weight * dt * (phi_k - phi_ref)^2
           + dt * z_k' Q z_k + centre_weight * dt * p_k^2 + push_weight * [u_k != 0]
           + between_weight * (violation_weight * max(0, peak_k - angle_band)^2
                               + success_weight * max(0, peak_k - success_angle) / success_angle)
           + success_weight * sum_c max(0, |c_k| - success_c) / success_c
    + mode_weight * s_N^2 + z_N' P z_N + centre_weight * (p_N, v0_N)' P_c (p_N, v0_N)
    + escape_weight * violation_weight * max(0, phi*_N - angle_band)^2

with the band excess of the pole angle, pole rate and cart position as in :class:`PulseBalancer`
(the cart's excess weighted ``track_weight`` times), ``s`` the unstable mode, ``Q`` the
diagonal ``state_weights`` (plus ``cart_weight`` on the cart), ``P`` its DARE value on the
linearisation, ``p``, ``v0``, ``P_c`` the cart's slow subsystem and its value (below), and
``peak_k`` the pole's lean where its rate turns round between samples k-1 and k (0 if it does
not; :func:`~lsindy_cas.control.cart_pendulum.upright.turn_excess`): success is judged between them too.
The ``success_weight`` terms (on where :attr:`turnaround`) price leaving the success band itself
(``c``: the angle and the rate, ``success`` = (0.1 rad, 0.5 rad/s); and the turn's peak) linearly:
the planning bands' squared excesses alone let a plan keep a rate 0.04 rad/s inside its band at
the price of a turn 0.003 rad outside the success band (docs/swingup.md).

Search: breadth-first branch and bound.  The incumbent is the best of the previous plan shifted
by one interval (warm start) and waiting throughout; at each depth every frontier sequence is
extended by every level, and a partial sequence whose accumulated cost already reaches the
incumbent's is pruned (the remaining costs are non-negative, so it cannot win).  If more than
``max_frontier`` partial sequences survive a depth, the ``max_frontier`` with the least
accumulated cost plus the current unstable-mode term are kept (a beam); the plan is then not
proven optimal and :attr:`proven` is False.  Otherwise the returned first level is that of an
optimal sequence over all ``len(levels)^horizon``.

The cart: its slow subsystem ``(p, v0)``, which the pushes do not move and the pole's lean
drives as a double integrator (:func:`~lsindy_cas.control.cart_pendulum.upright.slow_cart`), has an LQR value
(lean as the input, closed-loop frequency ``centre_frequency``) that, times ``centre_weight``,
is added to the terminal cost, and ``centre_weight * dt * p^2`` to the stage cost: over a horizon
of well under a second this is what makes the plan lean the pole so that the cart drifts back
to the centre (the DARE value of the full linearisation, computed for a continuous force,
does not: it expects the cart to be returned by force).

The escape term (on only where :attr:`turnaround` is False) penalises the lean ``phi*`` where a
push first keeps the rate in the band (:func:`~lsindy_cas.control.cart_pendulum.upright.escape_lean`) beyond
the angle band, so the plan avoids parking the pole at rest on top (the hover) where leaving it
costs a band touch (docs/swingup.md).

Viability: on the upright linearisation without cart friction the pole ``(phi, theta_dot)``
does not depend on the cart, so whether it can be kept in the success band for ever has an exact
answer, the min-max value ``J`` of :class:`~lsindy_cas.control.cart_pendulum.viability.ViabilityKernel` (``J <=
0``: viable) on the model's own linearisation.  With ``viability=True`` the plan's end pays ``w *
max(0, J + viability_margin * m*)^2`` and every predicted state ``viability_stage`` times the same
with ``viability_stage_margin`` (``m*`` the best margin the plant allows, ``w = viability_weight *
violation_weight``): the pole gets an infinite horizon.  Stopping a drifting cart needs a lean
the kernel may forbid, so ``w`` fades as ``(1 - cart_urgency)^2`` (``viability_cart``).  Under
mismatch each plan uses the kernel of the gain factor nearest the online correction's
(``viability_schedule``; one robust over gains 0.9-1.1 is empty for a 0.89 rad/s plant).
Measurements: docs/swingup.md.

The cart's speed ``w = x_dot - (a_x / omega2) theta_dot`` (the centre of mass's, linearised) moves
with the pushes only.  Where gravity cannot turn the pole back inside the success band (``omega *
0.1 < kick - 0.5``), pushes strictly alternate and the cart's mean speed is set by the time spent
between them, not by a lean: the stage cost gets ``speed_weight * dt * (w + x / speed_time)^2``.
"""

from __future__ import annotations

import time

import numpy as np

from ..._validate import check_bool, check_int, check_real
from .balancer import PulseBalancer
from ..mpc import wrap_angle
from .upright import cart_urgency, escape_lean, slow_cart, turn_excess
from .viability import BAND, kernel_schedule

__all__ = ["SequenceBalancer"]


class SequenceBalancer(PulseBalancer):
    """Level of the cart force near the upright by branch and bound (module docstring).

    Parameters
    ----------
    step, ode, levels, cart_index, pole_index, upright, track_limit, dt
        As for :class:`~lsindy_cas.control.cart_pendulum.balancer.PulseBalancer`.
    horizon : int
        Planned intervals ``N`` (1.4 s sees a hover's exit; a horizon of 16 lost 9 of 180 more).
    max_frontier : int
        Most partial sequences kept per depth (beyond it the search is a beam, not proven).
    rate_band : float, optional
        Band of the predicted pole rate (rad/s); default ``clip(kick / 2 + 0.02, 0.42, 0.48)``
        (:attr:`kick`): a band narrower than one kick makes every reversing push a violation.
    violation_weight : float
        Weight of the squared band excesses against the other terms.
    cart_weight : float
        Extra weight of the cart position's square in the stage cost.
    state_weights : (float, float, float, float)
        Stage weights of cart position, pole angle, cart speed and pole rate (per second);
        with ``input_weight`` (per N^2 s) they give the DARE value used as terminal cost.
    terminal_weight : float
        Factor on the DARE value at the horizon's end.
    centre_weight : float
        Weight of the cart's return to the centre (module docstring): the LQR value of the
        slow subsystem ``(p, v0)`` is added to the terminal cost, its state cost ``p^2`` to
        the stage cost.
    centre_frequency : float
        Closed-loop natural frequency (rad/s) of that LQR design, i.e. how fast the cart is
        to return (a slower return needs a smaller lean).
    lean_weight : float
        Weight of the lean-reference term (small: the centring value returns the cart).
    escape_weight : float, optional
        Factor on the terminal escape penalty (module docstring); None: ``ESCAPE_WEIGHT`` if
        :attr:`turnaround` is False, else 0 (off).
    viability : bool
        Penalise predicted pole states outside the pole's viability kernel
        (:mod:`lsindy_cas.control.cart_pendulum.viability`, built from the model's upright linearisation),
        held with a margin (module docstring, "viability").
    viability_weight : float
        Factor (times ``violation_weight``) on the squared kernel excess.
    viability_margin : float
        The margin asked for, as a share of the largest margin the kernel allows.
    viability_gains : sequence of float
        Input-gain factors the kernel must hold for (robust kernel); default the model's own.
    viability_stage : float
        Factor on the kernel term at every predicted state (0: the plan's end only).
    viability_stage_margin : float
        The margin asked for at every predicted state, as a share of the largest one.
    viability_cart : bool
        Fade the kernel term as the cart needs the lean to stop (:meth:`cart_urgency`).
    speed_weight, speed_time : float
        Weight of the cart-speed term (module docstring; None: ``SPEED_WEIGHT`` if
        :attr:`turnaround` is False, else 0) and its time (s): target speed ``-x / speed_time``.
    between_weight : float
        Factor on the band excess of the pole's turn between two samples (module docstring;
        0: the samples only).
    success_weight : float, optional
        Cost of leaving the success band, per share of its width (module docstring; None:
        ``SUCCESS_WEIGHT`` if :attr:`turnaround`, else 0, off).
    viability_schedule : sequence of float, optional
        Input-gain factors to build one kernel each for at construction; each plan uses the
        one nearest to the online correction's estimate ``1 + gain`` of the pole rate.
    **options
        ``angle_band``, ``region``, ``max_lean``, ``cart_frequency``, ``cart_damping``,
        ``lean_weight``, ``push_weight``, ``mode_weight``, ``track_margin``, ``track_weight``,
        ``brake_fraction``, ``correction``: as for :class:`PulseBalancer` (a correction with
        a ``lean`` regressor also corrects the lean's effect: :meth:`search`'s ``stiffness``).

    Attributes
    ----------
    kick : float
        The model's pole-rate change (rad/s) over one push of the largest force at the upright.
    turnaround : bool
        Whether gravity can reverse the pole's rate inside the success band between pushes:
        ``turn_lean``, the lean that turns a rate ``kick - 0.5`` round, is at most 0.1 rad.
    kernel : ViabilityKernel or None
        The pole's viability kernel the last plan used (``kernels``: all, by gain factor).
    proven : bool
        Whether the last plan was optimal over all sequences (no beam truncation).
    nodes : int
        Partial sequences evaluated by the last plan.
    plan_seconds : list of float
        Wall-clock time of every plan.
    plan : ndarray of int or None
        Level indices of the last best sequence.
    """

    #: weight of the cart-speed term where the pole cannot turn around inside the band
    #: (0.5/0.05/1.2: 8/20 -> 13/20 nominal starts; docs/swingup.md)
    SPEED_WEIGHT = 300.0
    #: factor on the escape term there (0.5/0.05/1.2, 60 starts: 26 -> 32 nominal)
    ESCAPE_WEIGHT = 1.0
    #: the success band's own term, where the pole turns round inside it (on the
    #: light plant, where it does not, mismatched 36 -> 32/47)
    SUCCESS_WEIGHT = 1e3

    def __init__(self, step, ode, levels, *, cart_index, pole_index, upright, track_limit, dt,
                 horizon=28, max_frontier=500, rate_band=None, violation_weight=1e4,
                 cart_weight=0.0, state_weights=(1.0, 10.0, 0.1, 0.01), input_weight=1e-4,
                 terminal_weight=1.0, lean_weight=1e-6, centre_weight=10.0, centre_frequency=0.5,
                 escape_weight=None, viability=True, viability_weight=1.0,
                 viability_margin=0.25, viability_gains=(1.0,), viability_stage=0.5,
                 viability_schedule=None, viability_stage_margin=0.25, viability_cart=True,
                 speed_weight=None, speed_time=2.0, between_weight=1.0, success_weight=None,
                 **options):
        horizon = check_int("horizon", horizon, low=1)
        self.max_frontier = check_int("max_frontier", max_frontier, low=1)
        self.violation_weight = check_real("violation_weight", violation_weight, positive=True)
        self.cart_weight = check_real("cart_weight", cart_weight, nonnegative=True)
        self.between_weight = check_real("between_weight", between_weight, nonnegative=True)
        if rate_band is not None:
            rate_band = check_real("rate_band", rate_band, positive=True)
        if "max_pushes" in options:
            raise ValueError("max_pushes is the pulse balancer's; this one takes every sequence.")
        super().__init__(step, ode, levels, cart_index=cart_index, pole_index=pole_index,
                         upright=upright, track_limit=track_limit, dt=dt, horizon=horizon,
                         max_pushes=1, rate_band=0.42 if rate_band is None else rate_band,
                         lean_weight=lean_weight, **options)
        self.levels = np.asarray(levels, dtype=float)
        self.zero = int(np.flatnonzero(self.levels == 0.0)[0])
        self.kick = float(abs(self.B[2 + self.ip]) * np.max(np.abs(self.levels)))
        if rate_band is None:
            self.rate_band = float(np.clip(self.kick / 2 + 0.02, 0.42, 0.48))
        self.horizon, self.max_pushes = horizon, None
        self._band = np.array([self.angle_band, self.rate_band,
                               self.track_limit - self.track_margin])
        track_weight = check_real("track_weight", options.get("track_weight", 10.0),
                                  positive=True)
        self._band_w = np.array([1.0, 1.0, track_weight ** 2]) * self.violation_weight
        self.plan_seconds = []
        # the pole alone: phi'' = omega2 phi, E = theta_dot^2 - omega2 phi^2 kept between pushes
        self.omega2 = float(self.Ac[2 + self.ip, self.ip])
        self.turn_lean = (self.kick - BAND[1]) / np.sqrt(max(self.omega2, 1e-12))
        self.turnaround = bool(self.turn_lean <= BAND[0])
        turn = self.turnaround  # the defaults of three terms depend on it (module docstring)
        for name, value, default in (
                ("escape_weight", escape_weight, 0.0 if turn else self.ESCAPE_WEIGHT),
                ("speed_weight", speed_weight, 0.0 if turn else self.SPEED_WEIGHT),
                ("success_weight", success_weight, self.SUCCESS_WEIGHT if turn else 0.0)):
            setattr(self, name, check_real(name, default if value is None else value,
                                           nonnegative=True))
        self._success_w = self.success_weight / np.asarray(BAND)  # per share of the band
        self.escape_rate = max(0.0, self.kick - self.rate_band)
        # cart speed per pole rate of a push: x_dot - ratio * theta_dot moves only by the lean
        self.ratio = float(self.B[2 + self.ic] / self.B[2 + self.ip])
        self._lean_dt = self.lean_weight * self.dt
        self._comps = [self.ip, 2 + self.ip, self.ic]
        from scipy.linalg import solve_discrete_are
        Q, diag = np.zeros((4, 4)), [self.ic, self.ip, 2 + self.ic, 2 + self.ip]
        Q[diag, diag] = np.asarray(state_weights, dtype=float)
        Q[self.ic, self.ic] += self.cart_weight
        self.Q = Q * self.dt
        self.P = terminal_weight * solve_discrete_are(self.A, self.B[:, None], self.Q,
                                                      np.array([[input_weight * self.dt]]))
        # the cart's slow subsystem (p, v0), its LQR value a terminal cost (module docstring)
        self.centre_weight = check_real("centre_weight", centre_weight, nonnegative=True)
        wc = check_real("centre_frequency", centre_frequency, positive=True)
        T, Pc = slow_cart(self.kappa, self.ratio, self.ic, self.ip, wc)
        self.P = self.P + self.centre_weight * T.T @ Pc @ T
        self.Q = self.Q + self.centre_weight * self.dt * T.T @ np.diag([1.0, 0.0]) @ T
        # the cart's speed term (module docstring): w = x_dot - (a_x / omega2) theta_dot
        tw = np.zeros(4)
        tw[self.ic] = 1.0 / check_real("speed_time", speed_time, positive=True)
        tw[2 + self.ic] = 1.0
        tw[2 + self.ip] = -self.Ac[2 + self.ic, self.ip] / max(self.omega2, 1e-12)
        self.Q = self.Q + self.speed_weight * self.dt * np.outer(tw, tw)
        # the pole's viability kernel on the model's upright linearisation (module docstring)
        check_bool("viability", viability)
        for name, v in (("viability_weight", viability_weight),
                        ("viability_margin", viability_margin),
                        ("viability_stage", viability_stage),
                        ("viability_stage_margin", viability_stage_margin)):
            setattr(self, name, check_real(name, v, nonnegative=True))
        self.viability_cart = check_bool("viability_cart", viability_cart)
        self._kernel_w = self.viability_weight * self.violation_weight
        self.kernel, self.kernels = None, {}
        if viability:
            self.kernels = kernel_schedule(ode, self.ic, self.ip, upright, self.dt, self.levels,
                                           viability_schedule, viability_gains)
        self._use_kernel(1.0)

    def reset(self):
        """Forget the balancer's mode and its last plan (call between episodes)."""
        super().reset()
        self.plan = None
        self.proven, self.nodes = True, 0

    def _stage(self, z, phi_ref, kernel=True):
        """Non-negative stage cost of predicted error states ``z`` (n, 4) (``kernel=False``:
        without the viability term, a lower bound the search prunes with first)."""
        mag = np.abs(z[:, self._comps])
        over = mag - self._band
        np.maximum(over, 0.0, out=over)
        lean = z[:, self.ip] - phi_ref
        cost = ((over * over) @ self._band_w + ((z @ self.Q) * z).sum(axis=1)
                + self._lean_dt * lean * lean)
        if self.success_weight:  # beyond the success band itself: linear, per share of it
            out = mag[:, :2] - BAND
            cost += np.maximum(out, 0.0, out=out) @ self._success_w
        if kernel and self.viability_stage > 0.0:
            cost += self.viability_stage * self._viability(z, self._stage_target)
        return cost

    def _between(self, prev, z, reps=1):
        """Band excess cost of the pole's turn inside the interval from each state of ``prev``
        to its ``reps`` successors in ``z`` (:func:`~lsindy_cas.control.cart_pendulum.upright.turn_excess`)."""
        if self.between_weight == 0.0:
            return 0.0
        low = min(self.angle_band, BAND[0])  # the turn's excess over both bands in one call
        over = turn_excess(prev, z, reps, self.ip, self.dt, low)
        cost = np.maximum(over - (self.angle_band - low), 0.0)
        cost = self.violation_weight * cost * cost
        if self.success_weight:
            cost += np.maximum(over - (BAND[0] - low), 0.0) * self._success_w[0]
        return self.between_weight * cost

    def _terminal(self, z):
        """Terminal cost of error states ``z`` (n, 4): unstable mode, DARE value and escape."""
        s = z @ self.mode
        return (self.mode_weight * s * s + ((z @ self.P) * z).sum(axis=1)
                + self._escape(z) + self._viability(z, self._target))

    def _use_kernel(self, factor):
        """Plan with the kernel built for the input-gain factor nearest ``factor``; the plan
        is held with ``viability_margin`` times the best margin that kernel allows."""
        if not self.kernels:
            self.kernel, self._target, self._stage_target = None, 0.0, 0.0
            return
        f = min(self.kernels, key=lambda k: abs(k - factor))
        self.kernel = self.kernels[f]
        best = max(self.kernel.max_margin, 0.0)
        self._target = self.viability_margin * best
        self._stage_target = self.viability_stage_margin * best

    def _viability(self, z, target):
        """``w * max(0, J(phi, theta_dot) + target)^2``, ``J`` the kernel's normalised value
        (module docstring, "Viability"; ``target``: the margin asked for)."""
        if self.kernel is None or self._kernel_w == 0.0:
            return 0.0
        over = self.kernel.value(z[:, self.ip], z[:, 2 + self.ip]) + target
        np.maximum(over, 0.0, out=over)
        return self._kernel_w * over * over

    def cart_urgency(self, e):
        """:func:`~lsindy_cas.control.cart_pendulum.upright.cart_urgency` of error state ``e`` (4,), braking by
        leaning ``brake_fraction * max_lean``."""
        return cart_urgency(e, self.ic, self.ip, self.ratio, self.brake_fraction
                            * abs(self.kappa) * self.max_lean, self.track_limit - self.track_margin)

    def _escape(self, z):
        """``escape_weight`` times a band violation: the squared excess over ``angle_band`` of
        :func:`~lsindy_cas.control.cart_pendulum.upright.escape_lean` (rate ``kick - rate_band``)."""
        if self.escape_weight == 0.0 or self.omega2 <= 0.0:
            return 0.0
        over = escape_lean(z[:, self.ip], z[:, 2 + self.ip], self.escape_rate, self.omega2)
        over = np.maximum(over - self.angle_band, 0.0)
        return self.escape_weight * self.violation_weight * over * over

    def reference_lean(self, e):
        """Lean (rad) that returns the cart to the centre from error state ``e``: as
        :meth:`PulseBalancer.reference_lean`, with the cart speed at zero pole rate ``x_dot -
        ratio * theta_dot`` in place of ``x_dot`` (it does not jump with every push)."""
        v = e[2 + self.ic] - self.ratio * e[2 + self.ip]
        phi = -(self.wn ** 2 * e[self.ic] + 2 * self.zeta * self.wn * v) / self.kappa
        return float(np.clip(phi, -self.max_lean, self.max_lean))

    def _rollout_cost(self, e, seqs, b, bias, phi_ref, A=None):
        """Costs of whole level-index sequences ``seqs`` (n, horizon) from error state ``e``
        (the stage costs of all intervals in one call, summed interval by interval)."""
        n, H = seqs.shape
        z, zs, A = np.tile(e, (n, 1)), np.empty((H, n, 4)), self.A if A is None else A
        u = self.levels[seqs]
        for k in range(H):
            z = zs[k] = z @ A.T + bias + u[:, k, None] * b
        stage = self._stage(zs.reshape(-1, 4), phi_ref).reshape(H, n)
        if self.between_weight:
            prev = np.concatenate([np.tile(e, (1, n, 1)), zs[:-1]]).reshape(-1, 4)
            stage += self._between(prev, zs.reshape(-1, 4)).reshape(H, n)
        push = self.push_weight * (u != 0)
        cost = np.zeros(n)
        for k in range(H):
            cost += stage[k] + push[:, k]
        return cost + self._terminal(z)

    def search(self, e, gain=None, bias=None, stiffness=None):
        """Best level-index sequence from error state ``e`` (4,) and its cost.

        ``gain``, ``bias`` and ``stiffness`` (4,) correct the predictions, ``x+ = A x + (1 +
        gain) B u + bias + stiffness * phi``.  Sets :attr:`proven` and :attr:`nodes`.
        """
        gain = np.zeros(4) if gain is None else np.asarray(gain, dtype=float)
        bias = np.zeros(4) if bias is None else np.asarray(bias, dtype=float)
        b, A = self.B * (1.0 + gain), self.A
        if stiffness is not None:
            A = A.copy()
            A[:, self.ip] += stiffness
        if len(self.kernels) > 1:
            self._use_kernel(1.0 + gain[2 + self.ip])
        H, n_lev = self.horizon, self.levels.size
        phi_ref = self.reference_lean(e)
        # the kernel (pole only) fades as the cart needs the lean: none at the track's margin
        fade = max(0.0, 1.0 - self.cart_urgency(e)) ** 2 if self.viability_cart else 1.0
        self._kernel_w = self.viability_weight * self.violation_weight * fade
        # incumbent: the previous plan shifted by one interval, and waiting throughout
        cands = [np.full(H, self.zero)]
        if self.plan is not None:
            cands.append(np.append(self.plan[1:], self.zero))
        cands = np.array(cands)
        inc_costs = self._rollout_cost(e, cands, b, bias, phi_ref, A)
        best_seq, best = cands[int(np.argmin(inc_costs))], float(inc_costs.min())
        states, costs = e[None, :], np.zeros(1)
        parents, moves = [], []
        push_cost, push_b = self.push_weight * (self.levels != 0), self.levels[:, None] * b
        proven, nodes = True, 0
        for k in range(H):
            nxt = states @ A.T + bias
            child = (nxt[:, None, :] + push_b).reshape(-1, 4)   # (M * L, 4)
            c = ((costs[:, None] + push_cost).ravel()
                 + self._stage(child, phi_ref, kernel=False)
                 + self._between(states, child, n_lev))
            if k == H - 1:
                c += self._terminal(child)
            nodes += c.size
            keep = np.flatnonzero(c < best)
            if self.viability_stage > 0.0 and self._kernel_w > 0.0 and keep.size:
                # the kernel term only for the children the rest of the cost left alive
                c[keep] += self.viability_stage * self._viability(child[keep],
                                                                  self._stage_target)
                keep = keep[c[keep] < best]
            if keep.size == 0:
                break
            if k == H - 1:
                j = keep[int(np.argmin(c[keep]))]
                seq = [j % n_lev]
                p = j // n_lev
                for d in range(H - 2, -1, -1):
                    seq.append(moves[d][p])
                    p = parents[d][p]
                best_seq, best = np.array(seq[::-1]), float(c[j])
                break
            if keep.size > self.max_frontier:
                proven = False
                score = c[keep] + self._terminal(child[keep])
                keep = keep[np.argpartition(score, self.max_frontier)[:self.max_frontier]]
            states, costs = child[keep], c[keep]
            parents.append(keep // n_lev)
            moves.append(keep % n_lev)
        self.proven, self.nodes = proven, nodes
        return best_seq, best

    def __call__(self, x):
        """Level index to apply at state ``x`` (4,), or None where the balancer does not act."""
        e = np.asarray(x, dtype=float) - self.x_ref
        e[self.ip] = wrap_angle(e[self.ip])
        if not self.active(e):
            self.plan = None
            return None
        t0 = time.perf_counter()
        c = self.correction
        lean = c is not None and c.lean is not None
        self.plan, _ = self.search(e, *((None, None) if c is None else (c.gain, c.bias)),
                                   c.stiffness if lean else None)
        self.plan_seconds.append(time.perf_counter() - t0)
        return int(self.plan[0])
