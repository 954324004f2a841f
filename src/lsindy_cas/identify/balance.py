"""The linear systems of the energy balance, built from trajectories and a library.

- derivative form (paper eq. 4):  Γ(X, Ẋ) ξ = dE/dt = P,  Γ = ∇Θ·ẋ (needs accelerations);
- integral (weak) form:            [Θ(x(t_b)) − Θ(x(t_a))] ξ = ∫_{t_a}^{t_b} P dt  (no derivatives);
- passive scheme: the same matrices with right-hand side 0 (ξ in the near null space), the scale
  coming from a short actuated record (paper eq. 8).

Windows of the integral form.  Least squares over *every* window [t_a, t_b] of a run, all weighted
alike, is the same problem as  Θ(x(t_i)) ξ − W(t_i) = c  for all samples i with one free constant c
per run, W the cumulative work: Σ_{a<b} (r_b − r_a)² = N Σ_i (r_i − r̄)².  So the default stacks all
windows at the cost of one row per sample — rows are deviations from the run's (weighted) mean.
Compared with short windows this averages the noise of Θ over the whole run instead of taking the
difference of two noisy samples.  Fixed-length windows (``window=w``) remain available.

Work.  W(t) = ∫ Q·q̇ dt.  A held (sample-and-hold, piecewise-constant) force — what a digital
controller and :meth:`~lsindy_cas.systems.MechanicalSystem.simulate` apply — makes P jump where
Q switches; the integral is then taken as Q_i ∫ q̇ dt per sampling interval, with q̇ integrated by a
cubic spline on each stretch between switches (4th order, no smoothing across a kink).  Smoothly
varying forces use a cubic spline of P.  The trapezoid rule was measured to bias coefficients by
~1e-3 at 100 Hz, and a spline through a switching P by up to 10 % on small terms.

Each form returns an :class:`EnergyBalance`, which also carries the stacked state gradients used to
recognise supports that are identities rather than conserved quantities, and the sample states on
which physical admissibility is checked.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._validate import check_choice, check_int
from ..data.trajectory import Trajectory
from ..symbolic.library import Library
from ..data.smoothing import force_switches

__all__ = ["EnergyBalance", "derivative_form", "integral_form", "cumulative_work", "HOLDS",
           "increments_preferred"]

HOLDS = ("auto", "zoh", "smooth")


@dataclass
class EnergyBalance:
    """``A ξ = b`` (or ``A ξ = 0`` when ``b`` is None), plus what the search needs to judge supports.

    Attributes
    ----------
    A : array (n_rows, p)
    b : array (n_rows,) or None
    D : array (n_samples * 2n, p)
        Stacked state gradients ∇Θ at the samples.
    X : array (n_samples, 2n)
        Sample states.
    form : str
        ``"derivative"`` or ``"integral"``.
    groups : int array (n_rows,), optional
        Index of the trajectory each row comes from (rows of one trajectory are in time order).
    weights : array (n_rows,), optional
        Row weights already applied (rows are scaled by √w); None means all ones.
    centred : bool
        Rows are deviations from their trajectory's weighted mean (the all-windows integral form);
        then row i belongs to sample i, so ``X``, ``D`` and the rows line up.
    work_rules : list of str, optional
        Integral form, per trajectory: how its work integral was computed — "increments"
        (held force × position increments), "quadrature" (held force × trapezoid of q̇),
        "spline" (smooth force) or "none" (no power) — which the noise model needs.
    dissipation : array (n_rows, r), optional
        Rayleigh dissipation columns (:mod:`lsindy_cas.identify.dissipation`), rows as ``A``'s.
        When set, ``A`` and ``b`` are projected off their span and ``raw`` holds the unprojected
        ``(A, b)``.
    intercept : array (n_rows,), optional
        Compressed (streamed) balance: the rows' entries of the per-trajectory intercept column
        that centred rows are orthogonal to (dense centred rows: √w, see ``intercept_column``).
    n_data_rows : int, optional
        Compressed (streamed) balance (:mod:`lsindy_cas.identify.stream`): the number of rows
        of the uncompressed balance; ``A``, ``b`` then hold block-wise R factors with the same
        Gram matrices, and ``X``, ``D`` a subsample of the states.
    quadrature : float
        Integral form: the squared error of ``b`` expected from the work integral's own
        discretisation (J², rows weighted and centred as ``b``; :func:`work_error`).  On
        noise-free data it is what a correct model leaves; 0 for position increments.
    dissipation_error : array (n_rows, r), optional
        Estimated quadrature error of each entry of ``dissipation`` (integral form).
    """

    A: np.ndarray
    b: np.ndarray | None
    D: np.ndarray
    X: np.ndarray
    form: str
    groups: np.ndarray | None = None
    weights: np.ndarray | None = None
    centred: bool = False
    work_rules: list | None = None
    dissipation: np.ndarray | None = None
    raw: tuple | None = None
    intercept: np.ndarray | None = None
    n_data_rows: int | None = None
    quadrature: float = 0.0
    dissipation_error: np.ndarray | None = None

    @property
    def passive(self) -> bool:
        return self.b is None

    @property
    def compressed(self) -> bool:
        """Rows are block-wise R factors of the balance (streamed), not one row per sample."""
        return self.n_data_rows is not None

    @property
    def n_rows(self) -> int:
        """Rows of the (uncompressed) balance: windows or samples."""
        return len(self.A) if self.n_data_rows is None else int(self.n_data_rows)

    @property
    def per_sample(self) -> bool:
        """Row i belongs to sample i (dense all-windows form): per-sample noise model and EIV."""
        return self.centred and not self.compressed

    def intercept_column(self) -> np.ndarray:
        """(n_rows,): the per-trajectory constant column of centred rows (√w per dense row)."""
        if self.intercept is not None:
            return self.intercept
        return np.sqrt(np.ones(len(self.A)) if self.weights is None else self.weights)

    @property
    def n_groups(self) -> int:
        return 1 if self.groups is None else int(self.groups.max()) + 1


def _stack_states(library: Library, trajectories):
    X = np.vstack([tr.X for tr in trajectories])
    D = library.grad(X).reshape(-1, len(library))
    return X, D


def _is_passive(trajectories) -> bool:
    return all(not np.any(tr.power) for tr in trajectories)


def _groups(trajectories, lengths=None) -> np.ndarray:
    lengths = [tr.n_samples for tr in trajectories] if lengths is None else lengths
    return np.repeat(np.arange(len(lengths)), lengths)


def derivative_form(library: Library, trajectories, passive: bool | None = None,
                    compress: bool | None = None, chunk: int | None = None) -> EnergyBalance:
    """Γ ξ = P over all samples of all trajectories (paper eq. 4); needs accelerations ``qdd``.

    ``compress``/``chunk``: stream the rows into block-wise R factors (same Gram matrices, bounded
    memory); None (default) does so when the dense rows and gradients would exceed
    :data:`lsindy_cas.identify.stream.STREAM_BUDGET` floats (see :func:`integral_form`).
    """
    passive = _is_passive(trajectories) if passive is None else passive
    if _compress(library, trajectories, compress):
        from .stream import compressed_balance
        return compressed_balance(library, trajectories, "derivative", passive=passive,
                                  chunk=chunk)
    A = np.vstack([library.gamma(tr.X, tr.Xdot) for tr in trajectories])
    b = None if passive else np.concatenate([tr.power for tr in trajectories])
    X, D = _stack_states(library, trajectories)
    return EnergyBalance(A, b, D, X, "derivative", groups=_groups(trajectories))


def _compress(library, trajectories, compress) -> bool:
    if compress is not None:
        return bool(compress)
    from .stream import STREAM_BUDGET
    n_state = 2 * len(library.coords.names)         # A (one row per sample) and D (2n per sample)
    return sum(tr.n_samples for tr in trajectories) * len(library) * (1 + n_state) > STREAM_BUDGET


def _resolve_hold(tr: Trajectory, hold: str) -> str:
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
    return _work(tr, hold, noise)[0]


def _work(tr: Trajectory, hold: str = "auto", noise=None):
    """(W, rule): :func:`cumulative_work` and the rule it used (see ``EnergyBalance.work_rules``)."""
    P = tr.power
    if not np.any(P):
        return np.zeros_like(P), "none"
    if _resolve_hold(tr, hold) == "smooth":
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


def _weighted_centre(M: np.ndarray, w: np.ndarray) -> np.ndarray:
    return M - (w @ M) / w.sum()


def integral_form(library: Library, trajectories, window: int | None = None, stride: int = 1,
                  passive: bool | None = None, weights=None, hold: str = "auto",
                  noise=None, compress: bool | None = None, chunk: int | None = None
                  ) -> EnergyBalance:
    """The integral (weak) energy balance: no derivatives of the data.

    Parameters
    ----------
    library : Library
    trajectories : list of Trajectory
    window : int, optional
        None (default): all windows of every run, as one centred row per sample (see the module
        notes).  An integer: rows Θ(x_{i+w}) − Θ(x_i) = W(t_{i+w}) − W(t_i), windows of ``w``
        samples.
    stride : int
        Fixed windows only: step between window starts (≥ 1).
    passive : bool, optional
        Right-hand side 0 (passive scheme); default: when no power is fed in.
    weights : list of arrays (n_samples,), optional
        All-windows form only: per-sample weights (e.g. inverse noise variance of the energy).
    hold : {"auto", "zoh", "smooth"}
        How the forces act between samples (see :func:`cumulative_work`).
    noise : list of arrays (2n,), optional
        Per trajectory, the standard deviation of the noise left in each state column (see
        :func:`cumulative_work`); None: the states are taken as exact.
    compress : bool, optional
        All-windows form without weights: stream the rows, ``chunk`` samples at a time, into
        block-wise R factors (:mod:`lsindy_cas.identify.stream`) — the same Gram matrices per
        trajectory and jackknife block, so the same search, held-out errors and jackknife, in
        memory independent of the number of samples.  None (default): when the dense rows and
        state gradients would exceed ``STREAM_BUDGET`` floats (then the noise model and the
        errors-in-variables correction, which need one row per sample, are not applied).

    Returns
    -------
    EnergyBalance
    """
    if window is not None:
        check_int("window", window, low=1)
        check_int("stride", stride, low=1)
        if weights is not None:
            raise ValueError("weights are only supported by the all-windows form (window=None)")
    passive = _is_passive(trajectories) if passive is None else passive
    if window is None and weights is None and _compress(library, trajectories, compress):
        from .stream import compressed_balance
        return compressed_balance(library, trajectories, "integral", passive=passive, hold=hold,
                                  noise=noise, chunk=chunk)
    if weights is not None and len(weights) != len(trajectories):
        raise ValueError(f"weights must hold one array per trajectory ({len(trajectories)}), "
                         f"got {len(weights)}")
    rows, rhs, wts, sizes, rules, quad = [], [], [], [], [], 0.0
    for k, tr in enumerate(trajectories):
        th = library.theta(tr.X)
        W, rule = _work(tr, hold, None if noise is None else noise[k])
        rules.append(rule)
        E = work_error(tr, rule, W)
        if window is None:
            w = np.ones(tr.n_samples) if weights is None else np.asarray(weights[k], float)
            if w.shape != (tr.n_samples,) or not np.all(np.isfinite(w)) or np.any(w <= 0):
                raise ValueError(f"weights[{k}] must be {tr.n_samples} positive numbers")
            sw = np.sqrt(w)[:, None]
            rows.append(sw * _weighted_centre(th, w))
            rhs.append(sw[:, 0] * _weighted_centre(W, w))
            quad += float(np.sum((sw[:, 0] * _weighted_centre(E, w)) ** 2))
            wts.append(w)
            sizes.append(tr.n_samples)
        else:
            if tr.n_samples <= window:
                raise ValueError(f"{tr.source}: {tr.n_samples} samples is too few for a window "
                                 f"of {window}")
            i = np.arange(0, tr.n_samples - window, stride)
            rows.append(th[i + window] - th[i])
            rhs.append(W[i + window] - W[i])
            quad += float(np.sum((E[i + window] - E[i]) ** 2))
            sizes.append(len(i))
    X, D = _stack_states(library, trajectories)
    return EnergyBalance(np.vstack(rows), None if passive else np.concatenate(rhs), D, X, "integral",
                         groups=_groups(trajectories, sizes),
                         weights=np.concatenate(wts) if window is None else None,
                         centred=window is None, work_rules=rules,
                         quadrature=0.0 if passive else quad)
