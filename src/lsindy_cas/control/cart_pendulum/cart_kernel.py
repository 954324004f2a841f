"""Whether a cart-pendulum can be balanced in the success band *and* kept on its track: a 4-D
viability kernel on the upright linearisation.

:class:`~lsindy_cas.control.cart_pendulum.viability.ViabilityKernel` answers the question for the pole alone,
``(phi, omega)``; it cannot see the cart, and a plant whose pole can be held for ever may still
run its cart off the track: stopping a drifting cart needs a lean, and a lean costs margin in a
band that is barely one push wide.  This module answers the joint question on the model's
upright linearisation, in the coordinates

    phi, omega,   p = x - r * phi,   v0 = x_dot - r * omega

with ``r`` the cart speed per unit pole rate of a push (``r = B_xdot / B_omega``): the pushes
do not move ``p`` and ``v0`` (they obey ``p' = v0``, ``v0' = kappa * phi`` without cart
friction), so their grid is not smeared by every push.  The min-max value

    J(s) = max( g(s), min_u max( g_sub(s, u), J(A s + B u) ) )

with ``g(s) = max(|phi| / angle_band, |omega| / rate_band, |p + r phi| / track,
|v0| / v_max) - 1`` (``g_sub`` its largest value at the ``substeps`` instants of a period) is
computed by value iteration on a grid (multilinear interpolation, from ``J_0 = g``).
``J(s) <= 0`` iff some level sequence keeps the pole in the band and the cart within
``|x| <= track`` at every sample for ever.  ``v_max`` (by default the speed a full lean
``kappa * angle_band`` cannot stop within twice the track) only bounds the grid: no state
beyond it is viable.

The exact upright at rest is a fixed point of the map (waiting there is viable for ever), and
a grid point on it would be trivially viable and lend its value to its neighbours by
interpolation: use even numbers of grid points (the defaults), which put no point on it.

A grid computation: the verdict is only as fine as the grid (``n_pole`` points per pole axis,
``n_cart`` per cart axis).  A period moves ``v0`` by a fraction of a cell, so interpolation
erodes the kernel on coarse grids (it errs towards "not viable"): check a verdict on two
grids.  A build takes tens of seconds to minutes, not one control period: a tool for
benchmarks, not a controller's online term.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.linalg import expm

from ..._validate import check_int, check_real
from .viability import check_system, min_max_value, upright_jacobians

__all__ = ["CartPoleKernel", "cart_pole_kernel"]


class CartPoleKernel:
    """Min-max value of keeping a linear cart-pendulum's pole in a band and its cart on a track.

    Parameters
    ----------
    a : array_like, shape (4, 4)
        Continuous-time upright linearisation in the order ``(x, phi, x_dot, omega)``.
    b : array_like, shape (4,)
        Its input vector per unit of ``levels``.
    dt : float
        Period over which a level is held (s).
    levels : array_like
        Admissible inputs (N).
    angle_band, rate_band : float
        The pole's band (rad, rad/s).
    track : float
        The cart must stay in ``|x| <= track`` (m).
    n_pole, n_cart : int
        Grid points per pole axis and per cart axis.
    v_max : float, optional
        Bound of the ``v0`` grid (m/s); default module docstring.
    substeps : int
        Samples per period at which the bands are checked.
    max_iter : int
        Most value-iteration sweeps.
    tol : float
        Stop when no grid value changes by more than this.

    Attributes
    ----------
    J : ndarray, shape (n_pole, n_pole, n_cart, n_cart)
        The value on the grid over ``(phi, omega, p, v0)``.
    ratio, kappa : float
        ``r`` and the cart acceleration per unit lean (``v0' = kappa * phi``).
    max_margin : float
        ``-min J`` (negative: no state is viable, the plant cannot be balanced on the track).
    empty : bool
        ``max_margin < 0``.
    viable_fraction : float
        Share of the grid's states with ``J <= 0``.
    iterations, converged, seconds
        Sweeps run, whether the change fell below ``tol``, build time (s).
    """

    def __init__(self, a, b, dt, levels, *, angle_band=0.1, rate_band=0.5, track=2.0,
                 n_pole=40, n_cart=20, v_max=None, substeps=5, max_iter=600, tol=1e-4):
        from scipy.sparse import csr_matrix
        t0 = time.perf_counter()
        a, b, self.dt, levels, self.angle_band, self.rate_band = check_system(
            a, b, 4, dt, levels, angle_band, rate_band)
        if abs(b[3]) < 1e-12:
            raise ValueError("b must move the pole rate (b[3] != 0).")
        self.levels = levels
        self.track = check_real("track", track, positive=True)
        self.n_pole = check_int("n_pole", n_pole, low=3)
        self.n_cart = check_int("n_cart", n_cart, low=3)
        substeps = check_int("substeps", substeps, low=1)
        max_iter = check_int("max_iter", max_iter, low=1)
        tol = check_real("tol", tol, positive=True)
        # s = T z: (phi, omega, p, v0) from (x, phi, x_dot, omega)
        r = b[2] / b[3]
        T = np.array([[0, 1, 0, 0], [0, 0, 0, 1], [1, -r, 0, 0], [0, 0, 1, -r]], dtype=float)
        As, bs = T @ a @ np.linalg.inv(T), T @ b
        self.ratio, self.kappa = float(r), float(As[3, 0])
        if v_max is None:
            v_max = np.sqrt(2 * abs(self.kappa) * self.angle_band * 2 * (
                self.track + abs(r) * self.angle_band))
        self.v_max = check_real("v_max", v_max, positive=True)
        M = np.zeros((5, 5))
        M[:4, :4], M[:4, 4] = As, bs
        E = expm(M * self.dt / substeps)
        a_sub, b_sub = E[:4, :4], E[:4, 4]
        self.half = np.array([self.angle_band, self.rate_band,
                              self.track + abs(r) * self.angle_band, self.v_max])
        self.axes = [np.linspace(-h, h, n) for h, n in zip(
            self.half, (self.n_pole, self.n_pole, self.n_cart, self.n_cart))]
        s = np.stack([g.ravel() for g in np.meshgrid(*self.axes, indexing="ij")], axis=1)
        g0 = self.excess(s)
        n = s.shape[0]
        gsub = np.empty((levels.size, n))
        succ = np.empty((levels.size, n))
        maps = []   # per level, the successor's multilinear interpolation as a sparse map
        indptr = np.arange(0, 16 * n + 1, 16, dtype=np.int64)
        for li, u in enumerate(levels):
            z, worst = s, np.full(n, -np.inf)
            for _ in range(substeps):
                z = z @ a_sub.T + u * b_sub
                worst = np.maximum(worst, self.excess(z))
            gsub[li] = worst
            idx, w = self._stencil(z)
            maps.append(csr_matrix((w.ravel(), idx.ravel(), indptr), shape=(n, n)))
            del idx, w, z
        def successors(J):
            for li, W in enumerate(maps):
                succ[li] = W @ J
            return succ[None]                                              # (1, L, n)

        J, self.converged, self.iterations = min_max_value(g0, gsub, successors, max_iter, tol)
        self.J = J.reshape(self.n_pole, self.n_pole, self.n_cart, self.n_cart)
        self.max_margin = float(-J.min())
        self.empty = self.max_margin < 0.0
        self.viable_fraction = float(np.mean(J <= 0.0))
        self.seconds = time.perf_counter() - t0

    def centre_slice(self):
        """``J`` over the pole grid ``(phi, omega)`` with the cart at rest at the centre
        (``p = v0 = 0``, interpolated), shape ``(n_pole, n_pole)``."""
        P, W = np.meshgrid(self.axes[0], self.axes[1], indexing="ij")
        s = np.stack([P.ravel(), W.ravel(), np.zeros(P.size), np.zeros(P.size)], axis=1)
        return self.value(s).reshape(P.shape)

    def excess(self, s):
        """Normalised excess ``g`` (module docstring) of states ``s`` (n, 4) in
        ``(phi, omega, p, v0)``."""
        x = s[:, 2] + self.ratio * s[:, 0]
        return np.maximum.reduce([np.abs(s[:, 0]) / self.angle_band,
                                  np.abs(s[:, 1]) / self.rate_band,
                                  np.abs(x) / self.track, np.abs(s[:, 3]) / self.v_max]) - 1.0

    def _frac(self, s):
        """Fractional grid coordinates of states ``s`` (n, 4), clipped to the grid."""
        sizes = np.array([self.n_pole, self.n_pole, self.n_cart, self.n_cart]) - 1
        f = (s + self.half) * (sizes / (2 * self.half))
        return np.clip(f, 0.0, sizes), sizes

    def _stencil(self, s):
        """Flat indices (n, 16) and multilinear weights (n, 16) of states ``s`` (n, 4)."""
        f, sizes = self._frac(s)
        i0 = np.minimum(f.astype(np.int64), sizes - 1)
        t = f - i0
        dims = sizes + 1
        strides = np.array([dims[1] * dims[2] * dims[3], dims[2] * dims[3], dims[3], 1])
        idx = np.zeros((s.shape[0], 16), dtype=np.int64)
        w = np.ones((s.shape[0], 16))
        for c in range(16):
            bits = np.array([(c >> k) & 1 for k in range(4)])
            idx[:, c] = (i0 + bits) @ strides
            for k in range(4):
                w[:, c] *= t[:, k] if bits[k] else 1.0 - t[:, k]
        return idx, w

    def value(self, s):
        """``J`` at states ``s`` (n, 4) in ``(phi, omega, p, v0)``: multilinear on the grid,
        at least the excess ``g`` (positive outside the grid)."""
        s = np.atleast_2d(np.asarray(s, dtype=float))
        idx, w = self._stencil(s)
        return np.maximum((self.J.ravel()[idx] * w).sum(axis=1), self.excess(s))

    def value_at(self, e):
        """``J`` at error states ``e`` (n, 4) in ``(x, phi, x_dot, omega)`` (from the upright)."""
        e = np.atleast_2d(np.asarray(e, dtype=float))
        s = np.stack([e[:, 1], e[:, 3], e[:, 0] - self.ratio * e[:, 1],
                      e[:, 2] - self.ratio * e[:, 3]], axis=1)
        return self.value(s)


def cart_pole_kernel(ode, cart_index, pole_index, upright, dt, levels, **options):
    """:class:`CartPoleKernel` of a cart-pendulum ODE at the upright.

    The arguments are those of :func:`~lsindy_cas.control.cart_pendulum.viability.pole_kernel` (the ODE
    ``(x (4,), u (2,)) -> xdot``, the cart's and the pole's positions in ``q``, the upright angle,
    the control period and the admissible cart forces); ``options`` go to
    :class:`CartPoleKernel`.
    """
    Ac, Bc = upright_jacobians(ode, pole_index, upright)
    order = [cart_index, pole_index, 2 + cart_index, 2 + pole_index]
    return CartPoleKernel(Ac[np.ix_(order, order)], Bc[order, cart_index], dt, levels,
                          **options)
