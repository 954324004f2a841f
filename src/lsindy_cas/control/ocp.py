"""The optimal control problem of one MPC step, described once: :class:`OCP`.

Dynamics (a CasADi ODE and its RK4 discretisation, :func:`rk4_step`), the finite set of
admissible levels of the one actuated input, the horizon, the least-squares costs and the state
bounds.  The relaxed NLP (:class:`~lsindy_cas.control.shooting.MultipleShootingNLP`) and the
discrete enumeration (:func:`~lsindy_cas.control.lookahead.build_lookahead`) are both built from
one :class:`OCP`, so they solve the same problem.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import numpy as np

from .._validate import check_int, check_real
from ..mechanics.rk4 import rk4_expr, rk4_step  # noqa: F401 (importable here)

__all__ = ["OCP", "check_levels", "rk4_expr", "rk4_step"]


def check_levels(force_set, name="force_set"):
    """Validated, sorted, unique admissible levels as a float array."""
    if isinstance(force_set, (str, bytes)) or not np.iterable(force_set):
        raise TypeError(f"{name} must be a sequence of numbers, e.g. (-10.0, 0.0, 10.0).")
    items = list(force_set)
    if not items:
        raise ValueError(f"{name} is empty; give at least one admissible force.")
    for v in items:
        if isinstance(v, bool) or not isinstance(v, numbers.Real):
            raise TypeError(f"{name} must contain only real numbers, got {v!r}.")
    levels = np.unique(np.asarray(items, dtype=float))
    if not np.all(np.isfinite(levels)):
        raise ValueError(f"{name} must contain only finite numbers.")
    return levels


def _bounds(name, value, n_state, fill):
    """State bound vector (n_state,): ``fill`` everywhere when ``value`` is None."""
    if value is None:
        return np.full(n_state, fill)
    try:
        out = np.asarray(value, dtype=float).ravel()
    except (TypeError, ValueError):
        raise TypeError(f"{name} must be a sequence of {n_state} numbers.") from None
    if out.size != n_state:
        raise ValueError(f"{name} must have {n_state} entries (one per state), got {out.size}.")
    return out


@dataclass(frozen=True, eq=False)
class OCP:
    """The optimal control problem an MPC step solves: dynamics, input set, horizon, costs, bounds.

    Validated once here; :class:`MultipleShootingNLP` (the relaxed NLP) and
    :func:`~lsindy_cas.control.lookahead.build_lookahead` (the discrete enumeration) both read it.
    The objective is ``sum_k dt * (|r(x_k)|^2 + input_weight * (u_k / scale)^2) + |r_N(x_N)|^2``
    with ``scale = max|levels|``.

    Parameters
    ----------
    ode : casadi.Function
        ``(x (n_state,), u (n_input,)) -> xdot (n_state,)``.
    levels : sequence of float
        Admissible values of ``u[input_index]`` (the other inputs are held at zero); stored
        sorted and unique.
    input_index : int
        Which entry of ``u`` is actuated.
    stage_residual, terminal_residual : casadi.Function
        ``x -> r``: running cost ``dt * |r(x_k)|^2`` per interval, terminal cost ``|r_N(x_N)|^2``.
    dt : float
        Control interval in seconds (zero-order hold).
    horizon : int
        Number of control intervals ``N``.
    state_lb, state_ub : array_like, shape (n_state,), optional
        Bounds on the predicted states ``x_1 .. x_{N-1}`` (infinite where omitted).
    input_weight : float
        Weight of the normalised input penalty.
    n_substeps : int
        Classical RK4 steps per control interval (:attr:`step`).
    levels_name : str
        Name of ``levels`` in error messages (the caller's argument name).
    param_ode, param_values : casadi.Function and array_like, optional
        The same ODE as a function of its coefficients, ``(x, u, p) -> xdot``, and their
        values: the relaxed NLP then takes ``p`` as a parameter (:attr:`param_step`;
        ``adapt_model``, :mod:`~lsindy_cas.control.coefficients`).
    """

    ode: ca.Function
    levels: np.ndarray
    input_index: int
    stage_residual: ca.Function
    terminal_residual: ca.Function
    dt: float
    horizon: int
    state_lb: np.ndarray = None
    state_ub: np.ndarray = None
    input_weight: float = 1e-3
    n_substeps: int = 1
    levels_name: str = field(default="levels", repr=False)
    param_ode: ca.Function = None
    param_values: np.ndarray = None

    def __post_init__(self):
        if not isinstance(self.ode, ca.Function):
            raise TypeError(f"ode must be a casadi.Function, got {type(self.ode).__name__}.")
        put = (lambda name, value: object.__setattr__(self, name, value))
        put("levels", check_levels(self.levels, self.levels_name))
        put("dt", check_real("dt", self.dt, positive=True))
        put("horizon", check_int("horizon", self.horizon, low=1))
        put("n_substeps", check_int("n_substeps", self.n_substeps, low=1))
        put("input_weight", check_real("input_weight", self.input_weight, nonnegative=True))
        put("input_index", check_int("input_index", self.input_index, low=0,
                                     high=self.n_input - 1))
        for name in ("stage_residual", "terminal_residual"):
            if not isinstance(getattr(self, name), ca.Function):
                raise TypeError(f"{name} must be a casadi.Function x -> r, got "
                                f"{type(getattr(self, name)).__name__}.")
        put("state_lb", _bounds("state_lb", self.state_lb, self.n_state, -np.inf))
        put("state_ub", _bounds("state_ub", self.state_ub, self.n_state, np.inf))
        if self.param_ode is not None:
            put("param_values", np.asarray(self.param_values, dtype=float).ravel())
            if self.param_ode.size1_in(2) != self.param_values.size:
                raise ValueError("param_values must have one value per coefficient of param_ode.")

    @property
    def n_state(self):
        """Size of the state ``x``."""
        return self.ode.size1_in(0)

    @property
    def n_input(self):
        """Size of the model's generalized-force vector ``u``."""
        return self.ode.size1_in(1)

    @property
    def scale(self):
        """Input normalisation ``max|levels|`` (1 if every level is 0)."""
        return float(np.max(np.abs(self.levels))) or 1.0

    @cached_property
    def step(self):
        """Discrete map ``F(x, u) -> x_next`` over one interval (:func:`rk4_step`)."""
        return rk4_step(self.ode, self.n_state, self.n_input, self.dt, self.n_substeps)

    @cached_property
    def param_step(self):
        """``F(x, u, p) -> x_next`` over one interval (None without :attr:`param_ode`)."""
        if self.param_ode is None:
            return None
        return rk4_step(self.param_ode, self.n_state, self.n_input, self.dt, self.n_substeps)

    def full_input(self, force):
        """Model input ``u`` (n_input,) with ``force`` on the actuated entry, zeros elsewhere."""
        return ca.vertcat(*[force if i == self.input_index else 0 for i in range(self.n_input)])
