"""The model's own coefficients, re-estimated online from the closed loop (``adapt_model``).

The engine's model is a Lagrangian (and a Rayleigh function) linear in its coefficients,
``L = sum_j a_j L_j``; a plant that differs from it -- a body 10 % lighter, a link 10 % longer --
differs in those coefficients only (mass, inertia, coupling, gravity moment).  The online
correction of :mod:`.correction` fits the one-step prediction errors with a few generic terms
(input gain, offset, the lean's stiffness), which serve the balancer's linearisation near the
upright but not the swing-up's nonlinear plan: re-run with the plant's own equations in the
relaxed NLP only (the balancer and its correction unchanged), the mismatched family episodes
of 0.6/0.2/1.0 and 0.7/0.4/0.8 whose patterns lost most went 5 -> 7 of 8 and 15 -> 17 of 18
(``benchmarks/family_true_model.py --plan-only``).

:func:`parametric_form` rebuilds the model's ODE as a function of its coefficient vector
(:class:`~lsindy_cas.mechanics.parametric.ParametricDynamics`, checked against ``model.ode()``);
:class:`CoefficientEstimator` updates that vector at every control step from the measured
transition, an iterated extended Kalman filter on constant parameters: with the RK4 step
``x+ = F(x, u; p)`` and its exact Jacobian ``J = dF/dp`` (CasADi), from the estimate ``p^``,

    K_i = P J_i' (J_i P J_i' + R)^-1,
    p_i+1 = p^ + K_i (x+_measured - F(x, u; p_i) - J_i (p^ - p_i)),

three times (``J_i`` at ``p_i``, ``p_0 = p^``), then ``P <- (I - K J) P``,

from the prior ``p0`` (the identified coefficients) with standard deviations ``prior * |p0|``,
on the velocities' rows only, ``R`` their squared one-step noise; each coefficient stays within
``max_change * |p0|`` of its prior.  The relaxed NLP takes the estimate as a parameter.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import sympy as sp

from .._validate import check_choice, check_int, check_real
from ..mechanics.parametric import ParametricDynamics
from .fastcall import NumericFunction

__all__ = ["CoefficientEstimator", "parametric_form", "resolve_adapt_model"]


def _terms(expr):
    """``{monomial: coefficient}`` of a sympy expression linear in its numeric coefficients
    (constants dropped: they do not enter the equations of motion)."""
    out = {}
    for arg in sp.Add.make_args(sp.expand(expr)):
        c, m = arg.as_coeff_Mul()
        if m != 1 and m.free_symbols:
            out[m] = out.get(m, 0.0) + float(c)
    return {m: c for m, c in out.items() if c != 0.0}


def parametric_form(model, coords, *, tol=1e-8, seed=0):
    """The model's ODE as ``ode(x, u, p)`` and its coefficients ``p0``.

    Reads the model's Lagrangian (``lagrangian_`` of an identified model, ``lagrangian`` of a
    :class:`~lsindy_cas.paper.systems.MechanicalSystem`) and its Rayleigh function, if any, and
    checks the rebuilt ODE at ``p0`` against ``model.ode()`` at random states.

    Returns
    -------
    ode : casadi.Function
        ``(x, u, p) -> xdot``.
    p0 : ndarray
        The model's coefficients (Lagrangian terms, then Rayleigh terms).
    names : list of str
        The terms, in the order of ``p0``.

    Raises
    ------
    ValueError
        If the model has no Lagrangian to read, or the rebuilt ODE differs from ``model.ode()``.
    """
    lag = getattr(model, "lagrangian_", None)
    if lag is None:
        lag = getattr(model, "lagrangian", None)
    if not isinstance(lag, sp.Expr):
        raise ValueError("the model has no Lagrangian (lagrangian_ or lagrangian) to re-estimate "
                         "its coefficients from.")
    ray = getattr(model, "rayleigh_", None)
    if ray is None:
        ray = getattr(model, "_R", None)
    L, R = _terms(lag), _terms(ray) if isinstance(ray, sp.Expr) else {}
    dyn = ParametricDynamics(list(coords), [str(m) for m in L], [str(m) for m in R])
    p0 = np.array(list(L.values()) + list(R.values()))
    ode, ref = dyn.ode(), model.ode()
    rng = np.random.default_rng(seed)
    n = 2 * len(coords)
    for _ in range(8):
        x, u = rng.uniform(-2, 2, n), rng.uniform(-10, 10, n // 2)
        a = np.asarray(ode(x, u, p0), dtype=float).ravel()
        b = np.asarray(ref(x, u), dtype=float).ravel()
        if not np.allclose(a, b, rtol=tol, atol=tol * (1 + np.abs(b).max())):
            raise ValueError("the model's equations could not be rebuilt from its Lagrangian "
                             "and Rayleigh terms (e.g. friction smoothed differently); its "
                             "coefficients cannot be re-estimated online.")
    return ode, p0, dyn.names


def resolve_adapt_model(value, model, coords):
    """``SwingUpMPC``'s ``adapt_model`` checked and resolved: ``(setting, coefficients)`` with
    ``coefficients`` :func:`parametric_form`'s ``(ode, p0)`` or None.  None (the default) is
    ``"stall"`` where the model's coefficients can be re-estimated and False where they cannot;
    ``True`` or ``"stall"`` on such a model raise its ValueError."""
    check_choice("adapt_model", value, (None, False, True, "stall"))
    if value is False:
        return False, None
    try:
        return ("stall" if value is None else value), parametric_form(model, coords)[:2]
    except (ValueError, TypeError, AttributeError, KeyError, ArithmeticError,
            NotImplementedError):  # the default must not break a controller that builds
        if value is not None:
            raise
        return False, None


class CoefficientEstimator:
    """Extended Kalman filter on the model's constant coefficients (module docstring).

    Parameters
    ----------
    step : casadi.Function
        The one-period map ``(x, u, p) -> x_next`` the plan uses (:attr:`OCP.param_step
        <lsindy_cas.control.ocp.OCP.param_step>`, :func:`~lsindy_cas.control.ocp.rk4_step` of
        :func:`parametric_form`'s ODE).
    p0 : array_like
        Prior coefficients (the identified model's).
    input_index : int
        Which entry of ``u`` the applied force acts on.
    prior : float
        Prior standard deviation of each coefficient as a share of ``|p0|``.
    noise : float
        One-step prediction noise (standard deviation) of the velocities.  Only the velocities'
        errors are used: a position's one-step change is the velocities' integral, which adds
        under dt/2 of their information but its own measurement noise (with noise 0.01 on every
        state, position rows weighted as 1e-3 sent the estimate after the noise).
    max_change : float
        Each coefficient stays within ``max_change * |p0|`` of ``p0``.
    stall : (callable, int), optional
        :attr:`stall`.
    miss : callable, optional
        :attr:`miss` (only with ``stall``).
    """

    #: Gauss-Newton iterations of each measurement update (the iterated EKF): on noise-free
    #: transitions of a plant 10-33 % off, 3 reached the plant's coefficients to 3e-4 after
    #: 20 transitions where the plain EKF (1) was 6e-3 off (its early linearisation lingers)
    ITERATIONS = 3

    def __init__(self, step, p0, *, input_index, prior=0.5, noise=1e-2, max_change=0.5,
                 stall=None, miss=None):
        self.p0 = np.asarray(p0, dtype=float).ravel()
        self.prior = check_real("prior", prior, positive=True)
        self.max_change = check_real("max_change", max_change, positive=True)
        n_state, n_input = step.size1_in(0), step.size1_in(1)
        self._rows = slice(n_state // 2, n_state)  # the velocities
        self._R = check_real("noise", noise, positive=True) ** 2 * np.eye(n_state - n_state // 2)
        x, u = ca.SX.sym("x", n_state), ca.SX.sym("u", n_input)
        p = ca.SX.sym("p", self.p0.size)
        nxt = step(x, u, p)
        self._fj = NumericFunction(ca.Function("FJ", [x, u, p], [nxt, ca.jacobian(nxt, p)]))
        self.input_index, self.n_input = int(input_index), n_input
        if stall is not None:
            far, steps = stall
            if not callable(far):
                raise TypeError(f"stall[0] must be callable (state -> bool), got {far!r}.")
            self.stall = (far, check_int("stall[1]", steps, low=1))
        if miss is not None and (stall is None or not callable(miss)):
            raise TypeError(f"miss must be callable ((state, next state, plan) -> bool) and "
                            f"come with stall, got {miss!r}.")
        self.miss = miss
        self.reset()

    #: ``(far, steps)``: the plan keeps the model as given until ``far(x)`` has held for ``steps``
    #: updates in a row (a stalled swing-up; the shipped swing-up plug-in: the swinging link 2 rad
    #: or more from its target for 3 s), and the estimate after; None: the estimate always
    stall = None
    #: ``miss(x_prev, x, predicted) -> bool``: with :attr:`stall`, the plan takes up the estimate
    #: also at the first transition this calls a missed approach (``predicted``: the states the
    #: plan made at ``x_prev`` predicted, or None; e.g. the plug-in's ``swing_up_gate``); None: only
    #: the stall
    miss = None

    def reset(self):
        """Back to the prior (call between episodes)."""
        self.coef = self.p0.copy()
        self.cov = np.diag((self.prior * np.abs(self.p0)) ** 2)
        self.n_updates = 0
        self.released, self._far = self.stall is None, 0
        self.released_at = 0 if self.released else None

    def plan(self, gain):
        """The plan's parameters (:meth:`MultipleShootingNLP.solve`): the estimate, which carries
        the input gain, or with :attr:`stall` until the swing-up has stalled the online
        correction's ``gain`` and the model's own coefficients, as without an estimator."""
        return {"gain": 0.0, "coef": self.coef} if self.released else {"gain": gain}

    def _watch(self, x_prev, x, predicted):
        """Count the updates in a row that end in a state :attr:`stall` calls far; open at
        ``steps`` of them or at a transition :attr:`miss` calls a missed approach."""
        far, steps = self.stall
        self._far = self._far + 1 if far(x) else 0
        self.released = self._far >= steps or bool(self.miss is not None
                                                   and self.miss(x_prev, x, predicted))
        if self.released:
            self.released_at = self.n_updates + 1  # the updates (steps) until it opened

    @property
    def std(self):
        """Current standard deviation of each coefficient."""
        return np.sqrt(np.diag(self.cov))

    def update(self, x_prev, force, x, predicted=None):
        """One filter step on the measured transition ``x_prev --force--> x`` (the measurement
        update iterated :attr:`ITERATIONS` times, re-linearised at each new estimate); a
        transition the model cannot evaluate (non-finite) is skipped.  ``predicted``: the
        states the plan made at ``x_prev`` predicted (:attr:`miss`), if any."""
        u = np.zeros(self.n_input)
        u[self.input_index] = force
        x = np.asarray(x, dtype=float).ravel()
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(x_prev))):
            return
        if self.stall is not None and not self.released:
            self._watch(np.asarray(x_prev, dtype=float).ravel(), x, predicted)
        p_hat, P, p = self.coef, self.cov, self.coef
        for _ in range(self.ITERATIONS):
            pred, J = self._fj(x_prev, u, p)
            r, J = (x - pred.ravel())[self._rows], J[self._rows]
            if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
                return
            PJ = P @ J.T
            K = np.linalg.solve(J @ PJ + self._R, PJ.T).T
            p = p_hat + K @ (r - J @ (p_hat - p))
        span = self.max_change * np.abs(self.p0)
        self.coef = np.clip(p, self.p0 - span, self.p0 + span)
        cov = P - K @ PJ.T
        self.cov = (cov + cov.T) / 2
        self.n_updates += 1
