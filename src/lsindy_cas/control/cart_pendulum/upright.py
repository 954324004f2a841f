"""The upright of a cart-pendulum model: its angle, one push's kick, and where to reach it.

:func:`handover_side`: on a frictionless track only the cart force changes the horizontal
momentum, by ``F dt`` per push, so the centre of mass's speed ``w = x_dot - k cos(theta -
upright) theta_dot`` (``k = m_p l / (m_c + m_p)``, read off the model's upright linearisation
as ``a_x / omega2``) changes only by multiples of ``dw = F dt / (m_c + m_p)``: its *phase*
``(w / dw) mod 1`` is the start's for the whole episode, whatever the controller does.  Where
the pole cannot turn around inside the success band
(:attr:`~lsindy_cas.control.cart_pendulum.sequence_balancer.SequenceBalancer.turnaround` False) the balancing
pushes must alternate, so ``w`` takes only two values, ``dw (n + phase)`` and ``dw (n + 1 +
phase)``; the cart can stand still on average only if they straddle zero with shares of time
the band allows (phase near 0.5).  From the other phases it creeps, one way more slowly than
the other, and reversing it takes two pushes of one sign: a touch of the band.  Handing the
pole over on the side the slow creep leaves from gives the cart the longest run before that.
Where gravity turns the pole round inside the band but only beyond the balancer's 0.08 rad angle
band (the family's 0.8/0.2/0.7, 0.6/0.2/1.0 and 0.7/0.4/0.8) the same side measured better too;
below that lean it did not (docs/swingup.md).

Also here, on the upright linearisation's pole: the sequence balancer's pole terms
(:func:`escape_lean`, :func:`peak_between` / :func:`turn_excess` for the pole's turn between two
samples, :func:`slow_cart` for the cart's slow subsystem) and :func:`reversal_margin`, an exact
check of whether the cart's creep can be reversed with the pole inside the success band.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from ..mpc import wrap_angle

__all__ = ["cart_urgency", "com_speed_step", "escape_lean", "find_upright", "handover_side",
           "peak_between", "reversal_in_band", "reversal_margin", "slow_cart", "step_kick",
           "swing_up_gate", "turn_excess", "upright_kick"]


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
    from ...mechanics.rk4 import rk4_step
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

    ``balancer``: a :class:`~lsindy_cas.control.cart_pendulum.sequence_balancer.SequenceBalancer` (its
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


def slow_cart(kappa, ratio, cart_index, pole_index, frequency):
    """The cart's slow subsystem at the upright and the value of its LQR design.

    Pushes move the cart speed and the pole rate in the ratio ``ratio``, so ``p = x - ratio *
    phi`` and ``v0 = x_dot - ratio * theta_dot`` are not moved by them; ``p' = v0``, ``v0' =
    kappa * phi``: a double integrator driven by the lean.  Returns ``T`` (2, 4), the map from
    the error state to ``(p, v0)``, and ``Pc`` (2, 2), the value of the LQR design with state
    cost ``p^2`` whose closed loop has natural frequency ``frequency`` (rad/s).
    """
    from scipy.linalg import solve_continuous_are
    Pc = solve_continuous_are(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [kappa]]),
                              np.diag([1.0, 0.0]), np.array([[kappa ** 2 / frequency ** 4]]))
    T = np.zeros((2, 4))
    T[0, cart_index], T[0, pole_index] = 1.0, -ratio
    T[1, 2 + cart_index], T[1, 2 + pole_index] = 1.0, -ratio
    return T, Pc


def escape_lean(phi, rate, escape_rate, omega2):
    """The lean at which a pole at ``(phi, rate)`` (n,) first reaches ``|theta_dot| =
    escape_rate``: between pushes ``E = theta_dot^2 - omega2 * phi^2`` is conserved, so
    ``phi*^2 = (escape_rate^2 - E) / omega2`` (0 where it is already there).  With
    ``escape_rate = kick - rate_band`` it is where a push first keeps the rate in the band."""
    need = (escape_rate ** 2 - rate * rate) / omega2 + phi * phi
    return np.sqrt(np.maximum(need, 0.0))


def peak_between(phi0, rate0, phi1, rate1, dt):
    """``|phi|`` at the pole's turn inside a period from its ends' leans and rates (n,), where
    the rate changes sign inside and the turn lies beyond both ends; 0 elsewhere.  The
    acceleration is taken constant over the period (``(rate1 - rate0) / dt``): the turn is at
    ``phi0 - rate0^2 / (2 a)``."""
    phi0, rate0 = np.asarray(phi0, dtype=float), np.asarray(rate0, dtype=float)
    a = (np.asarray(rate1, dtype=float) - rate0) / dt
    turns = rate0 * rate1 < 0.0
    peak = np.zeros_like(phi0)
    peak[turns] = np.abs(phi0[turns] - rate0[turns] ** 2 / (2.0 * a[turns]))
    peak[peak <= np.maximum(np.abs(phi0), np.abs(phi1))] = 0.0
    return peak


def cart_urgency(e, cart_index, pole_index, ratio, brake, usable):
    """Where the cart would stop braking at ``brake`` (m/s^2) from error state ``e`` (4,), as a
    share of the ``usable`` track (m; 0: at the centre and still, 1: at the track's margin).

    Uses the cart's slow subsystem ``p = x - ratio * phi``, ``v0 = x_dot - ratio * theta_dot``
    (the pushes do not move it, :func:`slow_cart`): ``|p + v0 |v0| / (2 brake)| / usable``.
    """
    p = e[cart_index] - ratio * e[pole_index]
    v0 = e[2 + cart_index] - ratio * e[2 + pole_index]
    return abs(p + v0 * abs(v0) / (2 * brake)) / usable


def turn_excess(prev, z, reps, pole_index, dt, band):
    """How far the pole's turn inside each interval leaves ``|phi| <= band``: for each state of
    ``prev`` (n, 4) and each of its ``reps`` successors, rows ``reps * i ... reps * i + reps - 1``
    of ``z`` (n * reps, 4), ``max(0, peak - band)`` with ``peak`` from :func:`peak_between`.

    The rate turns inside the interval only if ``|rate1 - rate0| > |rate0|``, so a turn reaches
    at most ``|phi0| + |rate0| dt / 2``; only the states of ``prev`` from which that exceeds
    ``band`` are evaluated.
    """
    over, phi0, rate0 = np.zeros(len(z)), prev[:, pole_index], prev[:, 2 + pole_index]
    near = np.flatnonzero(np.abs(phi0) + np.abs(rate0) * (0.5 * dt) > band - 1e-12)
    if near.size:
        rows = (near[:, None] * reps + np.arange(reps)).ravel()
        peak = peak_between(np.repeat(phi0[near], reps), np.repeat(rate0[near], reps),
                            z[rows, pole_index], z[rows, 2 + pole_index], dt)
        peak -= band
        over[rows] = np.maximum(peak, 0.0)
    return over


def reversal_margin(balancer, angle=0.1, rate=0.5, periods=20, substeps=5, full=False):
    """The largest share ``t`` by which the band ``|phi| <= angle``, ``|theta_dot| <= rate`` can
    shrink (to ``(1 - t)`` times both) with a reversal of the cart's creep still inside it at
    ``substeps`` evenly spaced instants of every period (the swing-up benchmarks judge success at
    5 per period), the pushes at most ``periods`` periods apart; negative where no such reversal
    stays inside the band itself.  ``full=True`` returns ``(t, idle periods between the pushes,
    start (phi, theta_dot))`` of the best one.

    A reversal changes the pair of levels the centre of mass's speed alternates between, which
    takes two pushes of one sign with only zero forces between them.  Between pushes ``phi'' =
    omega2 phi`` keeps ``theta_dot^2 - omega2 phi^2`` constant, so the rate must turn round and,
    pushes taken as instantaneous, the second comes at ``|phi| >= (kick - rate) / omega``
    (``turn_lean`` for the success band's rate); a push held over its period, with gravity,
    moves that line a little.  Computed exactly on the pole's part of ``balancer``'s upright
    linearisation (a :class:`~lsindy_cas.control.cart_pendulum.sequence_balancer.SequenceBalancer`; its
    continuous pole block, the push held over each period as on the plant): for each number of
    idle periods between the pushes every state on the way is linear in the start, so the best
    start is a linear program in three unknowns (HiGHS).

    ``periods`` bounds the idle time: the longer the pole coasts between the pushes, the closer
    it must pass the unstable equilibrium, and a start error grows as ``exp(omega t)`` (about 20
    times in 1 s on the family's thin plants); with no bound the program finds knife-edge
    reversals that rest on the top for seconds.
    """
    from scipy.linalg import expm
    from scipy.optimize import linprog
    substeps, periods = int(substeps), int(periods)
    if substeps < 1 or periods < 1:
        raise ValueError("substeps and periods must be positive integers.")
    ip, dt = balancer.ip, balancer.dt
    idx = [ip, 2 + ip]
    aug = np.zeros((3, 3))   # the pole's part, a push of the largest level held over a period
    aug[:2, :2] = balancer.Ac[np.ix_(idx, idx)]
    aug[:2, 2] = balancer.Bc[idx] * float(np.max(np.abs(balancer.levels)))
    maps = [expm(aug * dt * (j + 1) / substeps) for j in range(substeps)]  # [[Phi, Gamma bc]]
    scale = np.array([1.0 / angle, 1.0 / rate])

    def period(M, push):
        """Affine maps of the start (2 x 3: [linear | constant]) at each instant of a period
        that begins at the affine map ``M``, under ``push`` (0 or 1)."""
        return [m[:2, :2] @ M + push * np.outer(m[:2, 2], [0.0, 0.0, 1.0]) for m in maps]

    # the pole's linearisation is odd, so two negative pushes mirror two positive ones
    best = (-np.inf, None, None)
    rows = [np.hstack([np.eye(2), np.zeros((2, 1))])]
    rows += period(rows[0], 1.0)
    for idle in range(periods):
        G = np.vstack(rows + period(rows[-1], 1.0))
        G = G * np.tile(scale, len(G) // 2)[:, None]
        # |G[:, :2] s + G[:, 2]| <= 1 - t at every instant; maximise t
        ones = np.ones((len(G), 1))
        res = linprog([0.0, 0.0, -1.0], A_ub=np.vstack([np.hstack([G[:, :2], ones]),
                                                        np.hstack([-G[:, :2], ones])]),
                      b_ub=np.concatenate([1.0 - G[:, 2], 1.0 + G[:, 2]]),
                      bounds=[(None, None), (None, None), (-1.0, 1.0)], method="highs")
        if res.status == 0 and res.x[2] > best[0]:
            best = (float(res.x[2]), idle, res.x[:2].copy())
        rows += period(rows[-1], 0.0)
    return best if full else best[0]


def reversal_in_band(balancer, angle=0.1, rate=0.5, periods=20, substeps=5):
    """Whether the cart's creep can be reversed with the pole kept strictly inside the band
    ``|phi| < angle``, ``|theta_dot| < rate`` (the success band by default) at ``substeps``
    instants of every period, the two pushes at most ``periods`` periods apart:
    :func:`reversal_margin` > 0."""
    return reversal_margin(balancer, angle, rate, periods, substeps) > 0.0


def swing_up_gate(pole_index, upright, dt, stall, missed):
    """``DiscreteInputMPC``'s ``gate`` for a cart-pendulum's swing-up: ``(far, steps, miss)``.

    ``stall = (angle, seconds)``: the pole stayed ``angle`` rad or more from the upright for
    ``seconds``.  ``missed = (low, high)``: a missed approach -- the plan made at the previous
    state had the pole rise on to within ``low`` rad of the upright without turning round, and
    the plant's pole turned round (its rate changed sign) between ``low`` and ``high`` rad from
    it: the model said this swing reaches the top and it fell short (None: only the stall).
    """
    ip, up = int(pole_index), float(upright)
    lean = (lambda s: abs(wrap_angle(s[ip] - up)))
    far = (lambda s: lean(s) >= stall[0])
    if missed is None:
        return far, round(stall[1] / dt), None
    low, high = missed

    def miss(s0, s, predicted):
        rate = s0[2 + ip]
        if predicted is None or not (rate * s[2 + ip] < 0 and low < lean(s) < high):
            return False
        for p in predicted:  # the plan's own swing: to the top, or turning round first
            if p[2 + ip] * rate <= 0:
                return False
            if lean(p) < low:
                return True
        return False

    return far, round(stall[1] / dt), miss
