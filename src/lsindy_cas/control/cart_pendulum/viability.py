"""Whether a pole can be kept in a band forever with a finite force set: the viability kernel.

On the upright linearisation of a cart-pendulum without cart friction the pole's angle from the
upright ``phi`` and its rate ``omega`` do not depend on the cart's state::

    phi' = omega,    omega' = w2 * phi + c * omega + b * u

(``w2 > 0`` gravity's pull away from the upright, ``c <= 0`` a joint damping if the model has
one, ``b`` the pole's acceleration per newton).  So whether the pole can be held inside the band
``|phi| < angle_band``, ``|omega| < rate_band`` for ever, with the force held at one of
``levels`` over each period ``dt``, is a question about this 2-D system alone, and it has an
exact answer: the min-max value function

    J(s) = max( g(s), min_u max( g_sub(s, u), J(A s + B u) ) ),

with ``g(s) = max(|phi| / angle_band, |omega| / rate_band) - 1`` the normalised band excess and
``g_sub`` its largest value at the ``substeps`` equally spaced instants inside the period (exact,
by the matrix exponential: the success check samples the state every 10 ms, five times per 50 ms
period).  ``J(s) <= 0`` iff some level sequence keeps the pole in the band at every sample for
ever from ``s``; ``{J <= -m}`` is the set held with margin ``m`` (in the band scaled by
``1 - m``).  :class:`ViabilityKernel` computes ``J`` on a grid over the band by value iteration
(bilinear interpolation of ``J``, from ``J_0 = g``: the iterates increase to the limit; stopped
when the largest change is below ``tol`` or after ``max_iter`` sweeps).  Robust variant: with
``gains`` the input matrix is scaled by every gain and the successor must be viable for each
(a max over gains inside the min over levels), the kernel of a plant whose push strength is only
known to lie in a range.

An empty kernel (``J > 0`` everywhere on the grid, :attr:`empty`) says that no controller can
keep this plant's pole in the band: the certificate :func:`pole_kernel` gives for a plant's own
equations.  It is a grid computation: a kernel thinner than the grid spacing may be missed, so
near the boundary (``max_margin`` of a few times ``1 / n_grid``) the verdict is only as fine as
the grid.

A cart friction couples the pole to the cart speed (``omega'`` gains a term in ``x_dot``); that
term is left out here (:attr:`ViabilityKernel.coupling` reports its size).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from scipy.linalg import expm

from ..._validate import check_int, check_real

__all__ = ["BAND", "ViabilityKernel", "kernel_schedule", "pole_kernel", "pole_subsystem"]

#: the success band ``(|phi| <, |theta_dot| <)`` (rad, rad/s) a kernel holds the pole in by default
BAND = (0.1, 0.5)


def check_system(a, b, n, dt, levels, angle_band, rate_band):
    """``(a, b, dt, levels, angle_band, rate_band)`` of an ``n``-state kernel, checked: a finite
    ``(n, n)`` matrix and ``(n,)`` vector, a positive period, a non-empty set of finite levels
    and positive bands (ValueError naming the argument otherwise)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float).ravel()
    if a.shape != (n, n) or b.shape != (n,) or not (np.all(np.isfinite(a))
                                                    and np.all(np.isfinite(b))):
        raise ValueError(f"a must be a finite ({n}, {n}) matrix and b a finite ({n},) vector.")
    levels = np.asarray(levels, dtype=float).ravel()
    if levels.size == 0 or not np.all(np.isfinite(levels)):
        raise ValueError(f"levels must be a non-empty set of finite inputs, got "
                         f"{levels.tolist()}.")
    return (a, b, check_real("dt", dt, positive=True), levels,
            check_real("angle_band", angle_band, positive=True),
            check_real("rate_band", rate_band, positive=True))


def min_max_value(g0, gsub, successors, max_iter, tol):
    """Value iteration ``J <- max(g0, min_u max_d max(gsub, J(successor)))`` from ``J = g0``.

    ``successors(J)`` gives ``J`` at the successors, shape ``(n_disturbances, n_levels, n)``;
    ``gsub`` (broadcast to it) the largest excess inside each period.  Stops when the largest
    change is below ``tol`` or after ``max_iter`` sweeps.  Returns ``(J, converged, sweeps)``.
    """
    J, converged = g0.copy(), False
    for it in range(1, max_iter + 1):
        new = np.maximum(g0, np.maximum(gsub, successors(J)).max(axis=0).min(axis=0))
        change = float(np.max(np.abs(new - J)))
        J = new
        if change < tol:
            converged = True
            break
    return J, converged, it


def upright_jacobians(ode, pole_index, upright):
    """``(d xdot / dx, d xdot / du)`` of a cart-pendulum ODE ``(x (4,), u (2,)) -> xdot`` at
    rest at the upright (ValueError if not finite there)."""
    xs, us = ca.SX.sym("x", 4), ca.SX.sym("u", 2)
    f = ca.Function("upright", [xs, us], [ca.jacobian(ode(xs, us), xs),
                                          ca.jacobian(ode(xs, us), us)])
    x0 = np.zeros(4)
    x0[pole_index] = upright
    Ac, Bc = (np.asarray(m, dtype=float) for m in f(x0, np.zeros(2)))
    if not (np.all(np.isfinite(Ac)) and np.all(np.isfinite(Bc))):
        raise ValueError("the model's dynamics are not finite at the upright.")
    return Ac, Bc


def pole_subsystem(ode, cart_index, pole_index, upright):
    """The pole's linear dynamics at the upright from a cart-pendulum ODE.

    Parameters
    ----------
    ode : casadi.Function
        ``(x (4,), u (2,)) -> xdot (4,)``, state ``[q, q_dot]``.
    cart_index, pole_index : int
        Positions of the cart and the pole in ``q``.
    upright : float
        Upright pole angle (rad).

    Returns
    -------
    a : ndarray, shape (2, 2)
        ``d(phi, omega)/dt`` per ``(phi, omega)``: ``[[0, 1], [w2, c]]``.
    b : ndarray, shape (2,)
        Per newton of cart force: ``[0, b]``.
    coupling : float
        ``|d omega' / d x_dot|`` (1/s per m/s), the cart-speed term left out (0 without cart
        friction).
    """
    Ac, Bc = upright_jacobians(ode, pole_index, upright)
    ip, ic = pole_index, cart_index
    a = np.array([[Ac[ip, ip], Ac[ip, 2 + ip]], [Ac[2 + ip, ip], Ac[2 + ip, 2 + ip]]])
    b = np.array([Bc[ip, ic], Bc[2 + ip, ic]])
    return a, b, float(abs(Ac[2 + ip, 2 + ic]))


class ViabilityKernel:
    """Min-max value ``J`` of keeping a linear 2-D pole in a band (module docstring).

    Parameters
    ----------
    a : array_like, shape (2, 2)
        Continuous-time dynamics of ``(phi, omega)``.
    b : array_like, shape (2,)
        Input vector per unit of ``levels``.
    dt : float
        Period over which a level is held (s).
    levels : array_like, shape (n_levels,)
        Admissible inputs (e.g. forces in N).
    angle_band, rate_band : float
        The band ``|phi| < angle_band`` (rad), ``|omega| < rate_band`` (rad/s).
    substeps : int
        Samples inside a period at which the band is checked (the last is the period's end).
    n_grid : int
        Grid points per axis over the band.
    gains : sequence of float
        Factors on ``b``; the successor must be viable for every one (robust kernel).
    max_iter : int
        Most value-iteration sweeps.
    tol : float
        Stop when no grid value changes by more than this.

    Attributes
    ----------
    J : ndarray, shape (n_grid, n_grid)
        The value on the grid, ``J[i, j]`` at ``(phi_i, omega_j)``.
    max_margin : float
        ``-min J``: the largest margin any state is held with (negative: empty kernel).
    empty : bool
        ``max_margin < 0``: no state of the grid is viable.
    iterations : int
        Sweeps run; ``converged`` whether the change fell below ``tol``.
    seconds : float
        Build time.
    coupling : float
        The cart-speed term left out (:func:`pole_subsystem`; 0 when built from ``a``, ``b``).
    """

    coupling = 0.0

    def __init__(self, a, b, dt, levels, *, angle_band=BAND[0], rate_band=BAND[1], substeps=5,
                 n_grid=121, gains=(1.0,), disturbance=1e-3, max_iter=200,
                 tol=1e-4):
        import time
        t0 = time.perf_counter()
        a, b, self.dt, levels, self.angle_band, self.rate_band = check_system(
            a, b, 2, dt, levels, angle_band, rate_band)
        self.levels = levels
        self.substeps = check_int("substeps", substeps, low=1)
        self.n_grid = check_int("n_grid", n_grid, low=3)
        gains = np.asarray(gains, dtype=float).ravel()
        if gains.size == 0 or not np.all(np.isfinite(gains)):
            raise ValueError(f"gains must be a non-empty set of finite factors, got "
                             f"{gains.tolist()}.")
        self.gains = gains
        max_iter = check_int("max_iter", max_iter, low=1)
        tol = check_real("tol", tol, positive=True)
        # exact discretisation over one sub-step: expm of [[a, b], [0, 0]] * tau
        M = np.zeros((3, 3))
        M[:2, :2], M[:2, 2] = a, b
        E = expm(M * self.dt / self.substeps)
        self.a_sub, self.b_sub = E[:2, :2], E[:2, 2]
        A, B = np.eye(2), np.zeros(2)
        for _ in range(self.substeps):
            A, B = self.a_sub @ A, self.a_sub @ B + self.b_sub
        self.A, self.B = A, B
        self.phi = np.linspace(-self.angle_band, self.angle_band, self.n_grid)
        self.omega = np.linspace(-self.rate_band, self.rate_band, self.n_grid)
        P, W = np.meshgrid(self.phi, self.omega, indexing="ij")
        s = np.stack([P.ravel(), W.ravel()], axis=1)                        # (n, 2)
        g0 = self.excess(s)
        frac = check_real("disturbance", disturbance, nonnegative=True)
        d = frac * np.array([self.angle_band, self.rate_band])
        self.disturbance = d
        corners = np.unique(np.array([[sp * d[0], sw * d[1]] for sp in (-1, 1)
                                      for sw in (-1, 1)]), axis=0)
        # per (gain, level): worst sub-step excess and interpolation of the successor
        gsub, idx, wts = [], [], []
        for gain in gains:
            for u in levels:
                z, worst = s, np.full(s.shape[0], -np.inf)
                for _ in range(self.substeps):
                    z = z @ self.a_sub.T + gain * u * self.b_sub
                    worst = np.maximum(worst, self.excess(z))
                gsub.append(worst)
                for corner in corners:
                    i, w = self._stencil(z + corner)
                    idx.append(i)
                    wts.append(w)
        n_c = len(corners)
        gsub = np.repeat(np.array(gsub).reshape(gains.size, 1, levels.size, -1), n_c, axis=1)
        gsub = gsub.reshape(gains.size * n_c, levels.size, -1)
        idx = np.array(idx).reshape(gains.size, levels.size, n_c, -1, 4).transpose(
            0, 2, 1, 3, 4).reshape(gains.size * n_c, levels.size, -1, 4)
        wts = np.array(wts).reshape(gains.size, levels.size, n_c, -1, 4).transpose(
            0, 2, 1, 3, 4).reshape(gains.size * n_c, levels.size, -1, 4)
        # the successor interpolation of every (gain and corner, level) as one sparse map
        from scipy.sparse import csr_matrix
        n = s.shape[0]
        rows = np.repeat(np.arange(idx.shape[0] * idx.shape[1] * n), 4)
        W = csr_matrix((wts.ravel(), (rows, idx.ravel())), shape=(rows.size // 4, n))
        shape = idx.shape[:3]
        J, self.converged, self.iterations = min_max_value(
            g0, gsub, lambda J: (W @ J).reshape(shape), max_iter, tol)    # (G, L, n)
        self.J = J.reshape(self.n_grid, self.n_grid)
        # per cell, the bilinear form J00 + ti (J10 - J00) + tj (J01 - J00 + ti (J11 - J10
        # - J01 + J00)) as one row of four numbers (one gather per evaluated state)
        J00, J01 = self.J[:-1, :-1], self.J[:-1, 1:]
        J10, J11 = self.J[1:, :-1], self.J[1:, 1:]
        self._cells = np.stack([J00, J10 - J00, J01 - J00, J11 - J10 - J01 + J00],
                               axis=-1).reshape(-1, 4)
        self.max_margin = float(-J.min())
        self.viable_fraction = float(np.mean(J <= 0.0))
        self.empty = self.max_margin < 0.0
        self.seconds = time.perf_counter() - t0

    def excess(self, s):
        """Normalised band excess ``max(|phi| / angle_band, |omega| / rate_band) - 1`` of
        states ``s`` (n, 2)."""
        return np.maximum(np.abs(s[:, 0]) / self.angle_band,
                          np.abs(s[:, 1]) / self.rate_band) - 1.0

    def _locate(self, phi, omega):
        """Cell indices and in-cell fractions of states, clipped to the grid."""
        h = self.n_grid - 1
        fi = (phi + self.angle_band) * (h / (2 * self.angle_band))
        fj = (omega + self.rate_band) * (h / (2 * self.rate_band))
        fi = np.minimum(np.maximum(fi, 0.0), h)
        fj = np.minimum(np.maximum(fj, 0.0), h)
        i0 = np.minimum(fi.astype(np.intp), h - 1)
        j0 = np.minimum(fj.astype(np.intp), h - 1)
        return i0, j0, fi - i0, fj - j0

    def _stencil(self, s):
        """Flat grid indices (n, 4) and bilinear weights (n, 4) of states ``s`` (n, 2),
        clipped to the grid."""
        i0, j0, ti, tj = self._locate(s[:, 0], s[:, 1])
        n = self.n_grid
        idx = np.stack([i0 * n + j0, i0 * n + j0 + 1, (i0 + 1) * n + j0,
                        (i0 + 1) * n + j0 + 1], axis=1)
        w = np.stack([(1 - ti) * (1 - tj), (1 - ti) * tj, ti * (1 - tj), ti * tj], axis=1)
        return idx, w

    def value(self, phi, omega):
        """``J`` at states ``(phi, omega)`` (arrays of one shape): bilinear on the grid, the
        band excess outside it (a lower bound there, and positive: not viable)."""
        phi = np.asarray(phi, dtype=float)
        omega = np.asarray(omega, dtype=float)
        i0, j0, ti, tj = self._locate(phi, omega)
        c = self._cells[i0 * (self.n_grid - 1) + j0]                  # (..., 4)
        inside = c[..., 0] + ti * c[..., 1] + tj * (c[..., 2] + ti * c[..., 3])
        out = np.maximum(np.abs(phi) * (1.0 / self.angle_band),
                         np.abs(omega) * (1.0 / self.rate_band))
        out -= 1.0
        return np.maximum(inside, out)

    def viable(self, phi, omega, margin=0.0):
        """Whether states are in the kernel held with ``margin`` (``J <= -margin``)."""
        return self.value(phi, omega) <= -margin


def pole_kernel(ode, cart_index, pole_index, upright, dt, levels, **options):
    """:class:`ViabilityKernel` of a cart-pendulum ODE's pole at the upright.

    Parameters
    ----------
    ode : casadi.Function
        The model's (or the true plant's) ODE ``(x (4,), u (2,)) -> xdot``.
    cart_index, pole_index : int
        Positions of the cart and the pole in ``q``.
    upright : float
        Upright pole angle (rad).
    dt : float
        Control period (s).
    levels : array_like
        Admissible cart forces (N).
    **options
        Passed to :class:`ViabilityKernel` (``angle_band``, ``rate_band``, ``substeps``,
        ``n_grid``, ``gains``, ...).

    Returns
    -------
    ViabilityKernel
        With ``coupling`` set (:func:`pole_subsystem`).
    """
    a, b, coupling = pole_subsystem(ode, cart_index, pole_index, upright)
    kernel = ViabilityKernel(a, b, dt, levels, **options)
    kernel.coupling = coupling
    return kernel


def kernel_schedule(ode, cart_index, pole_index, upright, dt, levels, schedule=None, gains=(1.0,)):
    """One :func:`pole_kernel` per input-gain factor of ``schedule`` (default ``(1.0,)``), each
    robust over ``factor * gains``; a dict ``{factor: kernel}``."""
    gains = np.asarray(gains, dtype=float).ravel()
    try:
        factors = sorted({float(f) for f in ((1.0,) if schedule is None else schedule)})
    except (TypeError, ValueError):
        factors = []
    if not factors or min(factors) <= 0:
        raise ValueError(f"viability_schedule must be positive gain factors, got {schedule!r}.")
    return {f: pole_kernel(ode, cart_index, pole_index, upright, dt, levels, gains=f * gains)
            for f in factors}
