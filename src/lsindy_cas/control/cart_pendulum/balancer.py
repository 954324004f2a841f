"""Balancing a cart-pendulum at the upright with a coarse force set: enumerated pulse MPC.

Near the upright one push of ``F`` held for ``dt`` changes the pole rate by about
``F * dt / (m_c * L)`` whatever the pole mass: 0.50 rad/s for the nominal cart-pendulum with
10 N and 50 ms, 0.62 rad/s with the cart 10 % lighter and the pole 10 % shorter, i.e. as large
as the success band ``|theta_dot| < 0.5 rad/s`` itself.  A relaxed (continuous-force) plan knows
nothing of this: it asks for a small correction of a nearly still pole, and any admissible level
other than zero then overshoots the band, even when the model is exact.

:class:`PulseBalancer` plans with the pushes themselves.  It enumerates every input sequence over
``horizon`` intervals that contains at most ``max_pushes`` non-zero levels, predicts each with
the model's discrete dynamics linearised at the upright (by superposition: each prediction is
the free response plus at most ``max_pushes`` gathered push responses, with the controller's
online gain/offset correction applied, :mod:`lsindy_cas.control.correction`), and chooses
lexicographically:

1. the least violation of the bands: pole rate ``|theta_dot| <= rate_band``, pole angle
   ``|phi| <= angle_band`` and cart ``|x| <= track_limit - track_margin`` at every predicted
   step (sum of squared excesses, the cart's weighted ``track_weight`` times: leaving the track
   ends an episode, a pole rate outside the band only delays settling);
2. among those, the least cost: ``lean_weight * dt * sum (phi_k - phi_ref)^2`` + ``push_weight``
   per push + ``mode_weight * s_N^2``, where ``s`` is the pole's unstable mode (a left
   eigenvector of the linearised step) and ``phi_ref`` a reference lean of the pole.

A pole leaning by ``phi`` while balanced on average accelerates the cart by ``kappa * phi``
(``kappa`` from the linearised ODE, about ``-g`` for the usual conventions), so the reference
lean is a PD law that returns the cart to the centre:
``phi_ref = -(w^2 x + 2 zeta w x_dot) / kappa``, clipped to ``+-max_lean``.  The result is a
limit cycle about ``phi_ref``: the controller waits while gravity builds the pole rate up, then
one push reverses it inside the band.

The balancer acts only near the upright (``|phi| <= region[0]``, ``|theta_dot| <= region[1]``).
It takes over there only if the cart can still be stopped by leaning,
``|x + x_dot |x_dot| / (2 a)|`` within the track with ``a = brake_fraction * |kappa| * max_lean``
(a fast cart is left to the relaxed MPC, which may swing the pole wider), and it keeps the
decisions until the pole leaves the region.  Elsewhere the caller's own choice applies.
"""

from __future__ import annotations

import itertools
import math

import casadi as ca
import numpy as np

from ..._validate import check_int, check_real
from ..mpc import wrap_angle

__all__ = ["PulseBalancer"]

#: largest number of enumerated sequences before ``max_pushes`` is lowered
MAX_SEQUENCES = 20000


def _sequences(horizon, max_pushes, n_pushes):
    """Level-index matrix of all sequences with at most ``max_pushes`` non-zero entries.

    Entry 0 stands for the zero level, ``1..n_pushes`` for the non-zero ones; shape
    ``(n_sequences, horizon)``, the all-zero sequence first.
    """
    rows = [np.zeros(horizon, dtype=int)]
    for p in range(1, max_pushes + 1):
        for where in itertools.combinations(range(horizon), p):
            for which in itertools.product(range(1, n_pushes + 1), repeat=p):
                row = np.zeros(horizon, dtype=int)
                row[list(where)] = which
                rows.append(row)
    return np.array(rows)


def _count(horizon, max_pushes, n_pushes):
    return sum(math.comb(horizon, p) * n_pushes**p for p in range(max_pushes + 1))


class PulseBalancer:
    """Choose the level of a cart-pendulum's cart force near the upright (module docstring).

    Parameters
    ----------
    step : casadi.Function
        The model's discrete map ``F(x (4,), u (2,)) -> x_next`` over one control period.
    ode : casadi.Function
        The model's ODE ``(x (4,), u (2,)) -> xdot``, for the lean-to-acceleration gain.
    levels : ndarray, shape (n_levels,)
        Admissible forces, increasing; must contain 0 (waiting is the balancer's main move).
    cart_index, pole_index : int
        Positions of the cart and the pole in ``q``; ``x = [q, q_dot]``.
    upright : float
        Upright pole angle (rad).
    track_limit : float
        Allowed ``|x|`` of the cart (m).
    dt : float
        Control period (s).
    horizon : int
        Enumerated intervals.
    max_pushes : int
        Most non-zero levels per sequence (lowered if more than ``MAX_SEQUENCES`` sequences).
    rate_band, angle_band : float
        Bands the predicted pole rate (rad/s) and angle from upright (rad) are kept in.
    region : (float, float)
        ``(|phi|, |theta_dot|)`` below which the balancer acts.
    max_lean : float
        Bound on the reference lean (rad).
    cart_frequency, cart_damping : float
        Natural frequency (rad/s) and damping ratio of the cart's return to the centre.
    lean_weight, push_weight, mode_weight : float
        Weights of the cost terms (module docstring).
    track_margin : float
        The cart band is ``|x| <= track_limit - track_margin``.
    track_weight : float
        Weight of the cart band's excess (m) relative to the pole bands' (rad, rad/s).
    brake_fraction : float
        Fraction of the largest lean acceleration assumed available to stop the cart when
        deciding whether to take over.
    correction : InputGainCorrection, optional
        The controller's online correction (:mod:`lsindy_cas.control.correction`); its current
        ``gain`` and ``bias`` correct every prediction.  None: no correction.
    """

    def __init__(self, step, ode, levels, *, cart_index, pole_index, upright, track_limit, dt,
                 horizon=16, max_pushes=3, rate_band=0.42, angle_band=0.08, region=(0.12, 0.7),
                 max_lean=0.04, cart_frequency=1.0, cart_damping=1.0, lean_weight=1e3,
                 push_weight=1e-3, mode_weight=1.0, track_margin=0.25, track_weight=10.0,
                 brake_fraction=0.5, correction=None):
        levels = np.asarray(levels, dtype=float)
        zero = np.flatnonzero(levels == 0.0)
        if zero.size != 1:
            raise ValueError(f"the balancer needs 0 in the force set, got {levels.tolist()}.")
        horizon = check_int("horizon", horizon, low=1)
        max_pushes = check_int("max_pushes", max_pushes, low=1)
        rate_band = check_real("rate_band", rate_band, positive=True)
        angle_band = check_real("angle_band", angle_band, positive=True)
        max_lean = check_real("max_lean", max_lean, positive=True)
        cart_frequency = check_real("cart_frequency", cart_frequency, positive=True)
        cart_damping = check_real("cart_damping", cart_damping, positive=True)
        lean_weight = check_real("lean_weight", lean_weight, positive=True)
        brake_fraction = check_real("brake_fraction", brake_fraction, positive=True)
        track_weight = check_real("track_weight", track_weight, positive=True)
        push_weight = check_real("push_weight", push_weight, nonnegative=True)
        mode_weight = check_real("mode_weight", mode_weight, nonnegative=True)
        track_margin = check_real("track_margin", track_margin, nonnegative=True)
        try:
            region = tuple(float(r) for r in region)
        except (TypeError, ValueError):
            raise ValueError(f"region must be two positive numbers, got {region!r}.") from None
        if len(region) != 2 or not all(math.isfinite(r) and r > 0 for r in region):
            raise ValueError(f"region must be two positive numbers, got {region!r}.")
        if track_margin >= track_limit:
            raise ValueError(f"track_margin must be below track_limit, got {track_margin!r}.")

        self.ic, self.ip, self.dt = int(cart_index), int(pole_index), float(dt)
        self.track_limit = float(track_limit)
        self.rate_band, self.angle_band, self.region = rate_band, angle_band, region
        self.max_lean, self.track_margin = max_lean, track_margin
        self.brake_fraction = brake_fraction
        self.wn, self.zeta = cart_frequency, cart_damping
        self.lean_weight, self.push_weight, self.mode_weight = lean_weight, push_weight, mode_weight
        self.x_ref = np.zeros(4)
        self.x_ref[self.ip] = upright
        self.correction = correction

        # linearisations at the upright: the discrete step (predictions) and the ODE (kappa)
        xs, us = ca.SX.sym("x", 4), ca.SX.sym("u", 2)
        jac = ca.Function("upright_jacobians", [xs, us], [ca.jacobian(step(xs, us), xs),
                                            ca.jacobian(step(xs, us), us),
                                            ca.jacobian(ode(xs, us), xs),
                                            ca.jacobian(ode(xs, us), us)])
        A, B, Ac, Bc = (np.asarray(m, dtype=float) for m in jac(self.x_ref, np.zeros(2)))
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(Ac))):
            raise ValueError("the model's dynamics are not finite at the upright.")
        self.A, self.B, self.Ac, self.Bc = A, B[:, self.ic], Ac, Bc[:, self.ic]
        ic, ip = self.ic, self.ip
        b_pole = Bc[2 + ip, ic]
        if abs(b_pole) < 1e-12:
            raise ValueError("the cart force does not move the pole at the upright.")
        # cart acceleration per unit lean when the force keeps the pole's acceleration at zero
        self.kappa = float(Ac[2 + ic, ip] - Bc[2 + ic, ic] * Ac[2 + ip, ip] / b_pole)
        if abs(self.kappa) < 1e-9:
            raise ValueError("a lean of the pole does not accelerate the cart at the upright.")
        eigval, eigvec = np.linalg.eig(A)
        k = int(np.argmax(np.abs(eigval)))
        left = np.linalg.inv(eigvec)[k].real
        self.mode = left / np.max(np.abs(left))

        pushes = np.delete(levels, zero[0])
        while max_pushes > 1 and _count(horizon, max_pushes, pushes.size) > MAX_SEQUENCES:
            max_pushes -= 1
        self.horizon, self.max_pushes = int(horizon), int(max_pushes)
        index_of = np.concatenate([zero, np.delete(np.arange(levels.size), zero[0])])
        seq = _sequences(self.horizon, self.max_pushes, pushes.size)
        self.first = index_of[seq[:, 0]]             # level index of each first move
        self.n_pushes = (seq != 0).sum(axis=1)
        self._push_values = pushes
        # sequences as at most max_pushes rows of a table indexed 1 + (push - 1) * H + time
        # (row 0: no push), so that a prediction is a sum of a few gathered rows
        self._pushes = np.zeros((seq.shape[0], self.max_pushes), dtype=int)
        for r, row in enumerate(seq):
            when = np.flatnonzero(row)
            self._pushes[r, :when.size] = 1 + (row[when] - 1) * self.horizon + when
        # the sums of all but the last push are shared by many sequences: computed once per
        # call for the distinct prefixes, each sequence then adds its last push to its prefix
        head = self._pushes[:, :-1] if self.max_pushes > 1 else np.zeros((len(seq), 1), int)
        self._prefix, self._prefix_id = np.unique(head, axis=0, return_inverse=True)
        self._prefix_id = self._prefix_id.ravel()
        j, k = np.meshgrid(np.arange(self.horizon), np.arange(self.horizon), indexing="ij")
        self._causal = k >= j                        # input j acts on predicted state k
        self._lag = np.where(self._causal, k - j, 0)
        self._comps = [ip, 2 + ip, ic]               # angle, rate, cart position
        self._bands = np.repeat([angle_band, rate_band, track_limit - track_margin], horizon)
        self._band_weights = np.repeat([1.0, 1.0, track_weight**2], horizon)
        self.reset()

    def reference_lean(self, e):
        """Lean (rad) that returns the cart to the centre, from the error state ``e``."""
        phi = -(self.wn**2 * e[self.ic] + 2 * self.zeta * self.wn * e[2 + self.ic]) / self.kappa
        return float(np.clip(phi, -self.max_lean, self.max_lean))

    def reset(self):
        """Forget whether the balancer was acting (call between episodes)."""
        self.engaged = False

    def active(self, e):
        """Whether the balancer acts at error state ``e``.

        It takes over near the upright if leaning by ``brake_fraction * max_lean`` would stop
        the cart inside the track, and then keeps the decisions until the pole leaves the
        region: its own pushes swing the cart speed by ``F dt / m``, and handing a half-done
        pulse cycle back to the relaxed plan pushes from the wrong state.
        """
        if abs(e[self.ip]) > self.region[0] or abs(e[2 + self.ip]) > self.region[1]:
            self.engaged = False
        elif not self.engaged:
            brake = self.brake_fraction * abs(self.kappa) * self.max_lean
            v = e[2 + self.ic]
            stop = e[self.ic] + v * abs(v) / (2 * brake)
            self.engaged = bool(abs(stop) <= self.track_limit - self.track_margin)
        return self.engaged

    def __call__(self, x):
        """Level index to apply at state ``x`` (4,), or None where the balancer does not act.

        The :attr:`correction`'s current ``gain`` and ``bias`` (4,) correct the predictions
        as in the controller's lookahead: ``x+ = A x + (1 + gain) * B u + bias`` (elementwise).
        """
        e = np.asarray(x, dtype=float) - self.x_ref
        e[self.ip] = wrap_angle(e[self.ip])
        if not self.active(e):
            return None
        if self.correction is None:
            gain, bias = np.zeros(4), np.zeros(4)
        else:
            gain = np.asarray(self.correction.gain, dtype=float)
            bias = np.asarray(self.correction.bias, dtype=float)
        H = self.horizon
        b = self.B * (1.0 + gain)
        free, impulse = np.empty((H, 4)), np.empty((H, 4))
        z = e
        for k in range(H):
            z = self.A @ z + bias
            free[k], impulse[k] = z, b
            b = self.A @ b
        # response of predicted state k to a unit input at interval j: impulse[k - j]
        resp = np.where(self._causal[:, :, None], impulse[self._lag], 0.0)   # (H, H, 4)
        # predicted angle, rate and cart position of every sequence, component-major (n_seq, 3H)
        unit = resp[:, :, self._comps].transpose(0, 2, 1).reshape(H, 3 * H)
        table = np.zeros((1 + self._push_values.size * H, 3 * H))
        table[1:] = (self._push_values[:, None, None] * unit).reshape(-1, 3 * H)
        base = free[:, self._comps].T.reshape(-1)
        prefix = table[self._prefix[:, 0]] + base
        for m in range(1, self._prefix.shape[1]):
            prefix += table[self._prefix[:, m]]
        pred = np.take(prefix, self._prefix_id, axis=0)
        pred += np.take(table, self._pushes[:, -1], axis=0)
        over = np.abs(pred, out=pred)
        over -= self._bands
        np.maximum(over, 0.0, out=over)
        viol = np.square(over, out=over) @ self._band_weights
        # lexicographic: the cost only of the sequences with the least violation
        keep = np.flatnonzero(viol <= viol.min() + 1e-12)
        pushes = self._pushes[keep]
        lean = base[:H] + table[pushes[:, 0], :H]
        for m in range(1, self.max_pushes):
            lean += table[pushes[:, m], :H]
        lean -= self.reference_lean(e)
        unit_mode = resp[:, -1, :] @ self.mode                                # (H,)
        mode_table = np.concatenate([[0.0], (self._push_values[:, None] * unit_mode).ravel()])
        mode = free[-1] @ self.mode + mode_table[pushes].sum(axis=1)         # unstable mode at H
        cost = (self.lean_weight * self.dt * np.einsum("ij,ij->i", lean, lean)
                + self.push_weight * self.n_pushes[keep] + self.mode_weight * mode**2)
        return int(self.first[keep[int(np.argmin(cost))]])
