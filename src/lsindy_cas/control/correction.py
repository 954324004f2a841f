"""Online correction of a model's one-step predictions against plant/model mismatch.

:class:`InputGainCorrection` fits, per state component ``i``, the one-step prediction errors of
the measured states as an input-gain error and an offset,

    ``x_i - F_i(x_prev, u) = gain_i * (F_i(x_prev, u) - F_i(x_prev, 0)) + bias_i``,

by recursive least squares with exponential forgetting (offset-free MPC), and predicts with
``F(x, u) + gain * (F(x, u) - F(x, 0)) + bias``.  ``F(x, u) - F(x, 0)`` is the input's effect
over one interval, so ``gain`` scales it (a plant whose push is 20 % stronger has
``gain = 0.2``) and ``bias`` absorbs what does not depend on the input.  The controller owns one
instance and hands it to whatever predicts with it (its lookahead, the balancer).

With ``lean=(index, reference)`` a third term, ``stiffness_i * sin(x_prev[index] -
reference)``, fits what gravity's torque does differently on the plant near an unstable
equilibrium of an angle (a link 10 % shorter turns over 10 % faster): near it the offset cannot
follow, as the lean changes sign with every push.  A plug-in turns it on where it balances.
"""

from __future__ import annotations

import numpy as np

from .._validate import check_int, check_real
from .fastcall import NumericFunction

__all__ = ["InputGainCorrection"]


class InputGainCorrection:
    """Recursive-least-squares estimate of the input gain error and offset (module docstring).

    Parameters
    ----------
    step : casadi.Function
        The model's discrete map ``F(x (n_state,), u (n_input,)) -> x_next`` over one interval.
    input_index : int
        Which entry of ``u`` is actuated (the others are held at zero).
    forgetting : float
        RLS forgetting factor in (0, 1].
    max_gain : float
        Bound on ``|gain|``.
    lean : tuple, optional
        ``(index, reference)``: also fit ``stiffness`` on the sine of that angle's lean from
        the reference (module docstring).  None: gain and offset only.

    Attributes
    ----------
    estimate : ndarray, shape (n_state, p)
        Per state component, the estimate ``[gain, bias]`` (p = 2), with ``lean``
        ``[gain, bias, stiffness]`` (p = 3).
    cov : ndarray, shape (n_state, p, p)
        Per state component, the RLS covariance of ``estimate``.
    """

    #: initial covariance of ``[gain, bias]``: a prior that the model is right
    PRIOR = (1.0, 1e-2)
    #: bound on the entries of the covariance (keeps forgetting from blowing it up)
    COV_BOUND = 1e3

    #: prior variance of the lean's coefficient (``lean=``): per radian of lean, per interval
    LEAN_PRIOR = 1.0

    def __init__(self, step, input_index, *, forgetting=0.95, max_gain=0.5, lean=None):
        self.step = step
        self._step = NumericFunction(step)
        self.n_state, self.n_input = step.size1_in(0), step.size1_in(1)
        self.input_index = check_int("input_index", input_index, low=0, high=self.n_input - 1)
        self.forgetting = check_real("forgetting", forgetting)
        if not 0 < self.forgetting <= 1:
            raise ValueError(f"forgetting must be in (0, 1], got {forgetting!r}.")
        self.max_gain = check_real("max_gain", max_gain, nonnegative=True)
        #: None, or ``(index, reference)``: a third regressor, the sine of that angle's lean
        #: from the reference, fits model error in gravity's torque (e.g. a link's length)
        self.lean = None
        if lean is not None:
            if not isinstance(lean, (tuple, list)) or len(lean) != 2:
                raise TypeError(f"lean must be None or (index, reference), got {lean!r}.")
            self.lean = (check_int("lean[0]", lean[0], low=0, high=self.n_state - 1),
                         check_real("lean[1]", lean[1]))
        self.reset()

    def reset(self):
        """Back to no correction (``gain = bias = 0``) and the prior covariance."""
        prior = self.PRIOR + ((self.LEAN_PRIOR,) if self.lean is not None else ())
        self.estimate = np.zeros((self.n_state, len(prior)))
        self.cov = np.tile(np.diag(prior), (self.n_state, 1, 1))

    @property
    def gain(self):
        """Input-gain error per state component, shape (n_state,)."""
        return self.estimate[:, 0]

    @property
    def bias(self):
        """Offset per state component, shape (n_state,)."""
        return self.estimate[:, 1]

    @property
    def stiffness(self):
        """Per state component, the coefficient of the sine of the lean (zeros without
        ``lean``), shape (n_state,)."""
        return self.estimate[:, 2] if self.lean is not None else np.zeros(self.n_state)

    def _sin_lean(self, x):
        return float(np.sin(x[self.lean[0]] - self.lean[1]))

    def _responses(self, x, force):
        """The model's next state ``F(x, u)`` with ``force`` applied and ``F(x, 0)``."""
        u = np.zeros(self.n_input)
        u[self.input_index] = force
        x_u = self._step(x, u).ravel()
        x_0 = self._step(x, np.zeros(self.n_input)).ravel()
        return x_u, x_0

    def predict(self, x, force):
        """Corrected one-step prediction from state ``x`` (n_state,) under ``force``.

        Returns
        -------
        ndarray, shape (n_state,)
            ``F(x, u) + gain * (F(x, u) - F(x, 0)) + bias`` (``+ stiffness * sin(lean)`` with
            ``lean``).
        """
        x = np.asarray(x, dtype=float)
        x_u, x_0 = self._responses(x, float(force))
        out = x_u + self.gain * (x_u - x_0) + self.bias
        return out + self.stiffness * self._sin_lean(x) if self.lean is not None else out

    def update(self, x_prev, force, x):
        """One RLS step on the transition ``x_prev --force--> x`` (measured states).

        Parameters
        ----------
        x_prev, x : ndarray, shape (n_state,)
            Measured states one interval apart.
        force : float
            The input applied over that interval.
        """
        x_u, x_0 = self._responses(x_prev, force)
        err = x - x_u
        lam = self.forgetting
        # the n_state two- (three-, with lean) parameter RLS problems at once (batched products)
        cols = [x_u - x_0, np.ones(self.n_state)]
        if self.lean is not None:
            cols.append(np.full(self.n_state, self._sin_lean(x_prev)))
        phi = np.stack(cols, axis=1)                                        # (n_state, p)
        Pphi = np.matmul(self.cov, phi[:, :, None])[:, :, 0]
        k = Pphi / (lam + np.matmul(phi[:, None, :], Pphi[:, :, None])[:, 0, 0])[:, None]
        innovation = err - np.matmul(phi[:, None, :], self.estimate[:, :, None])[:, 0, 0]
        self.estimate += k * innovation[:, None]
        self.cov = (self.cov - k[:, :, None] * Pphi[:, None, :]) / lam
        np.clip(self.cov, -self.COV_BOUND, self.COV_BOUND, out=self.cov)
        np.clip(self.estimate[:, 0], -self.max_gain, self.max_gain, out=self.estimate[:, 0])
