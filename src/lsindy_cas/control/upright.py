"""The upright of a cart-pendulum model: its angle, one push's kick, and where to reach it.

:func:`handover_side`: on a frictionless track only the cart force changes the horizontal
momentum, by ``F dt`` per push, so the centre of mass's speed ``w = x_dot - k cos(theta -
upright) theta_dot`` (``k = m_p l / (m_c + m_p)``, read off the model's upright linearisation
as ``a_x / omega2``) changes only by multiples of ``dw = F dt / (m_c + m_p)``: its *phase*
``(w / dw) mod 1`` is the start's for the whole episode, whatever the controller does.  Where
the pole cannot turn around inside the success band
(:attr:`~lsindy_cas.control.sequence_balancer.SequenceBalancer.turnaround` False) the balancing
pushes must alternate, so ``w`` takes only two values, ``dw (n + phase)`` and ``dw (n + 1 +
phase)``; the cart can stand still on average only if they straddle zero with shares of time
the band allows (phase near 0.5).  From the other phases it creeps, one way more slowly than
the other, and reversing it takes two pushes of one sign: a touch of the band.  Handing the
pole over on the side the slow creep leaves from gives the cart the longest run before that.
Where gravity turns the pole round inside the band but only beyond the balancer's 0.08 rad angle
band (the family's 0.8/0.2/0.7, 0.6/0.2/1.0 and 0.7/0.4/0.8) the same side measured better too;
below that lean it did not (docs/history/control.md, stop 31).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from .mpc import wrap_angle

__all__ = ["com_speed_step", "find_upright", "handover_side", "reversal_in_band", "step_kick",
           "upright_kick"]


def find_upright(ode, cart_index, pole_index, n_grid=720):
    """Pole angle of the unstable rest equilibrium of a cart-pendulum ODE.

    Scans the pole's angular acceleration at rest with zero input over one revolution;
    equilibria are its zeros, and the upright one is where it increases with the angle
    (a displacement accelerates away).  Works for any angle convention of the model.

    Parameters
    ----------
    ode : casadi.Function
        ``(x (4,), u (2,)) -> xdot (4,)``, state ``[q, q_dot]``.
    cart_index, pole_index : int
        Positions of the cart and pole coordinates in ``q``.
    n_grid : int
        Grid points per revolution.

    Returns
    -------
    float
        Upright angle in ``[-pi, pi)``, radians.

    Raises
    ------
    ValueError
        If there is not exactly one unstable rest equilibrium per revolution.
    """
    grid = np.linspace(-np.pi, np.pi, n_grid, endpoint=False)
    x = np.zeros((4, n_grid))
    x[pole_index] = grid
    acc = np.asarray(ode.map(n_grid)(x, np.zeros((2, n_grid))))[2 + pole_index]
    nxt = np.roll(acc, -1)
    ups = np.flatnonzero((acc < 0) & (nxt >= 0))
    if ups.size != 1 or not np.all(np.isfinite(acc)):
        raise ValueError("could not determine the upright angle from the model (expected one "
                         "unstable rest equilibrium of the pole); pass upright= explicitly.")
    i = ups[0]
    step = 2 * np.pi / n_grid
    angle = grid[i] + step * acc[i] / (acc[i] - nxt[i])
    return float(wrap_angle(angle))


def step_kick(step, cart_index, pole_index, upright, levels):
    """Pole-rate change (rad/s) over one period of the largest of ``levels``, from rest at the
    upright, from the discrete step ``step(x, u)`` linearised there (:meth:`SwingUpMPC.kick`)."""
    x0 = np.zeros(4)
    x0[pole_index] = upright
    u = ca.SX.sym("u", 2)
    jac = ca.Function("kick", [u], [ca.jacobian(step(x0, u), u)])
    b = np.asarray(jac(np.zeros(2)), dtype=float)[2 + pole_index, cart_index]
    return float(abs(b) * np.max(np.abs(np.asarray(levels, dtype=float))))


def upright_kick(ode, cart_index, pole_index, upright, dt, n_substeps, force_set):
    """:meth:`SwingUpMPC.kick` before the controller exists (0.0 if the arguments are bad:
    they are checked, with a clear error, when the controller is built)."""
    from .ocp import rk4_step
    try:
        step = rk4_step(ode, 4, 2, float(dt), int(n_substeps))
        return step_kick(step, cart_index, pole_index, upright, force_set)
    except (TypeError, ValueError, RuntimeError):
        return 0.0


def com_speed_step(A, b, cart_index, pole_index, force):
    """``(k, dw)`` of the centre of mass's speed ``w = x_dot - k cos(theta - upright) theta_dot``
    (module docstring), read off a cart-pendulum's upright linearisation.

    ``A``: the continuous Jacobian in the state ``[q, q_dot]``; ``k = a_x / omega2`` (``m_p l /
    (m_c + m_p)`` for a point-mass pole).  ``b``: the cart force's effect on the state over one
    period (the discrete step's input column, or the continuous one times ``dt``); ``dw`` is the
    change of ``w`` by one push of ``force``."""
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float).reshape(-1)
    k = A[2 + cart_index, pole_index] / A[2 + pole_index, pole_index]
    return k, abs(b[2 + cart_index] - k * b[2 + pole_index]) * force


def handover_side(balancer, x, window=0.25):
    """Side of the track (+1, -1) to hand the pole over on from state ``x``, or 0.

    ``balancer``: a :class:`~lsindy_cas.control.sequence_balancer.SequenceBalancer` (its
    upright linearisation, indices and levels).  0 where the phase of the centre of mass's speed
    is within ``window`` of 0.5 (the cart can stand still); otherwise the side the slower of the
    two creeps leaves from: +1 for phases below 0.5 (the slow creep is towards -x), -1 above.
    """
    ic, ip = balancer.ic, balancer.ip
    x = np.asarray(x, dtype=float)
    k, dw = com_speed_step(balancer.Ac, balancer.B, ic, ip, np.max(np.abs(balancer.levels)))
    w = x[2 + ic] - k * np.cos(x[ip] - balancer.x_ref[ip]) * x[2 + ip]
    phase = float((w / dw) % 1.0)
    if abs(phase - 0.5) <= window:
        return 0
    return 1 if phase < 0.5 else -1


def reversal_in_band(balancer, angle=0.1, rate=0.5, periods=80, n=199):
    """Whether the cart's creep can be reversed with the pole kept in the band ``|phi| < angle``,
    ``|theta_dot| < rate`` (the success band by default) at every sample.

    A reversal changes the pair of levels the centre of mass's speed alternates between, which
    takes two pushes of one sign with only zero forces between them.  Between pushes ``phi'' =
    omega2 phi`` keeps ``theta_dot^2 - omega2 phi^2`` constant, so the rate must turn round and,
    pushes taken as instantaneous, the second comes at ``|phi| >= (kick - rate) / omega``
    (``turn_lean`` for the success band's rate).  Checked here exhaustively on the pole's part of
    ``balancer``'s discrete upright linearisation (a
    :class:`~lsindy_cas.control.sequence_balancer.SequenceBalancer`): every state of an ``n`` x
    ``n`` grid of the band, both signs, 0 to ``periods - 1`` zero periods between the pushes,
    the band required at the samples only.  That is a little more lenient than the bound (a
    push acts over its period, with gravity): with the success band it finds a reversal up to
    ``turn_lean`` ~0.110 rad (none on the family's 0.5/0.05/1.2 at 0.112).
    """
    ip = balancer.ip
    A = balancer.A[np.ix_([ip, 2 + ip], [ip, 2 + ip])]
    push = balancer.B[[ip, 2 + ip], None] * float(np.max(np.abs(balancer.levels)))
    inside = lambda s: (np.abs(s[0]) < angle) & (np.abs(s[1]) < rate)  # noqa: E731
    grid = np.meshgrid(np.linspace(-angle, angle, n + 2)[1:-1],
                       np.linspace(-rate, rate, n + 2)[1:-1])
    for sign in (1.0, -1.0):
        s = A @ np.stack([g.ravel() for g in grid]) + sign * push
        ok = inside(s)
        for _ in range(periods):
            if (ok & inside(A @ s + sign * push)).any():
                return True
            s = A @ s
            ok &= inside(s)
    return False
