"""The work the applied forces do, W(t) = ∫ Q·q̇ dt: the right-hand side of the integral form.

A held (sample-and-hold, piecewise-constant) force — what a digital controller and
:meth:`~lsindy_cas.systems.MechanicalSystem.simulate` apply — makes P jump where Q switches; the
integral is then taken as Q_i ∫ q̇ dt per sampling interval, with q̇ integrated by a cubic spline on
each stretch between switches (4th order, no smoothing across a kink).  Smoothly varying forces
use a cubic spline of P.  The trapezoid rule was measured to bias coefficients by ~1e-3 at 100 Hz,
and a spline through a switching P by up to 10 % on small terms.  :func:`work_error` is the
integral's own quadrature error (what χ expects on clean data).
"""
from __future__ import annotations

import numpy as np

from .._validate import check_choice
from ..data.trajectory import Trajectory
from ..data.whittaker import force_switches

__all__ = ["HOLDS", "resolve_hold", "cumulative_work", "work", "held_increments",
           "increments_preferred", "work_error"]

HOLDS = ("auto", "zoh", "smooth")


def resolve_hold(tr: Trajectory, hold: str) -> str:
    check_choice("hold", hold, HOLDS)
    if hold != "auto":
        return hold
    constant = not np.any(np.diff(tr.Q, axis=0))
    return "zoh" if constant or force_switches(tr.Q).size else "smooth"


def cumulative_work(tr: Trajectory, hold: str = "auto", noise=None) -> np.ndarray:
    """W(t_i) = ∫_{t_0}^{t_i} Q·q̇ dt: (n_samples,) in J.

    Parameters
    ----------
    tr : Trajectory
    hold : {"auto", "zoh", "smooth"}
        "zoh": Q_i acts over [t_i, t_{i+1}) (sample-and-hold); "smooth": Q varies smoothly and
        P = Q·q̇ is integrated as a cubic spline (4th order); "auto": "zoh" for constant or
        piecewise-constant forces.
    noise : array (2n,), optional
        Standard deviation of the noise left in the state columns [q, q̇].  Held forces: the work
        over [t_i, t_{i+1}) is Q_i·∫q̇ dt, and ∫q̇ dt has two estimates — the position increment
        q_{i+1} − q_i (exact, no quadrature error, noise √2 σ_q) or the velocities' quadrature
        (trapezoid within an interval, O(dt³ q⃛) error, noise ~dt σ_q̇ /√2).  The one with the
        smaller expected error is used; without ``noise`` the data are taken as exact
        (position increments).
    """
    return work(tr, hold, noise)[0]


def work(tr: Trajectory, hold: str = "auto", noise=None):
    """(W, rule): :func:`cumulative_work` and the rule it used (see ``EnergyBalance.work_rules``)."""
    P = tr.power
    if not np.any(P):
        return np.zeros_like(P), "none"
    if resolve_hold(tr, hold) == "smooth":
        from scipy.interpolate import CubicSpline   # lazy: scipy's import costs ~0.5 s per CLI call
        return CubicSpline(tr.t, P).antiderivative()(tr.t), "spline"
    inc, rule = held_increments(tr, noise)
    return np.r_[0.0, np.cumsum(inc)], rule


def held_increments(tr: Trajectory, noise=None):
    """Work of a held force over each sample interval, Q_i·∫_{t_i}^{t_{i+1}} q̇ dt.

    See :func:`cumulative_work` for the choice between position increments and quadrature.

    Returns
    -------
    increments : array (n_samples − 1,)
    rule : {"increments", "quadrature"}
    """
    Q = tr.Q[:-1]
    dq = np.diff(tr.q, axis=0)
    if increments_preferred(tr, noise, Q):
        return np.einsum("ij,ij->i", Q, dq), "increments"
    trap = 0.5 * (tr.qd[1:] + tr.qd[:-1]) * np.diff(tr.t)[:, None]
    return np.einsum("ij,ij->i", Q, trap), "quadrature"


def increments_preferred(tr: Trajectory, noise=None, Q=None) -> bool:
    """Is ∫q̇ dt over each sample interval better taken from the position increments than from a
    quadrature of the velocities?  (See :func:`cumulative_work`; also the choice of the velocity
    path for the dissipation integrals, :mod:`lsindy_cas.identify.dissipation`.)

    Increments: noise √2 σ_q, no quadrature error; trapezoid: noise ~ h σ_q̇ /√2 and error
    h³/12 · q⃛ (q⃛ from second differences of q̇).  ``Q`` (n_samples − 1, n) weights the coordinates
    (the held force; default all ones); ``noise`` None: the data are taken as exact.
    """
    if noise is None:
        return True
    noise = np.asarray(noise, float)
    n = len(tr.coords)
    Q = np.ones((tr.n_samples - 1, n)) if Q is None else Q
    h = np.diff(tr.t)[:, None]
    # trapezoid error per interval ≈ h³/12 · q⃛, q⃛ from second differences of q̇
    jerk = np.zeros_like(tr.qd)
    if tr.n_samples >= 3:
        hm = np.diff(tr.t)
        slope = np.diff(tr.qd, axis=0) / hm[:, None]
        jerk[1:-1] = 2 * np.diff(slope, axis=0) / (hm[1:] + hm[:-1])[:, None]
        jerk[0], jerk[-1] = jerk[1], jerk[-2]
    quad = h ** 3 / 12 * 0.5 * (np.abs(jerk[1:]) + np.abs(jerk[:-1]))
    var_dq = np.sum(Q ** 2 * 2 * noise[:n] ** 2)
    var_trap = np.sum(Q ** 2 * (0.5 * h ** 2 * noise[n:] ** 2 + quad ** 2))
    return bool(var_dq <= var_trap)


def work_error(tr: Trajectory, rule: str, W: np.ndarray) -> np.ndarray:
    """Estimated error of the cumulative work ``W`` (n_samples,) from its rule's discretisation.

    "increments" and "none": 0 (Q_i·(q_{i+1} − q_i) is exact for a held force); "quadrature": the
    trapezoid's −h³ q⃛/12 per interval (q⃛ from second differences of q̇), summed; "spline": a
    Richardson estimate — the same spline on every other sample (step 2h) differs from it by
    (2⁴ − 1)× its own error at the common samples, interpolated between them.
    """
    if rule == "spline" and tr.n_samples >= 9:
        from scipy.interpolate import CubicSpline
        W2 = CubicSpline(tr.t[::2], tr.power[::2]).antiderivative()(tr.t[::2])
        return np.interp(tr.t, tr.t[::2], (W[::2] - W2) / 15.0)
    if rule != "quadrature" or tr.n_samples < 3:
        return np.zeros_like(W)
    h = np.diff(tr.t)
    slope = np.diff(tr.qd, axis=0) / h[:, None]
    jerk = np.zeros_like(tr.qd)
    jerk[1:-1] = 2 * np.diff(slope, axis=0) / (h[1:] + h[:-1])[:, None]
    jerk[0], jerk[-1] = jerk[1], jerk[-2]
    err = -h[:, None] ** 3 / 12 * 0.5 * (jerk[1:] + jerk[:-1])
    return np.r_[0.0, np.cumsum(np.einsum("ij,ij->i", tr.Q[:-1], err))]
