"""Rounding relaxed discrete-input decisions to one admissible level per control step.

The MPC solves a relaxation in which every control interval carries a weight per admissible
input level (partial outer convexification: weights in [0, 1] summing to 1).  Only the first
interval's weights are applied, once per MPC step, so the rounding has to be carried *across*
steps: :class:`SumUpRounding` keeps the accumulated deviation between the relaxed weights and the
levels actually applied (combinatorial integral approximation by sum-up rounding, S. Sager,
"Numerical methods for mixed-integer optimal control problems", 2005, ch. 5).
:class:`NearestRounding` is the plain alternative: pick the level with the largest weight, i.e.
round a continuous force to the nearest admissible one.
"""

from __future__ import annotations

import numpy as np

__all__ = ["NearestRounding", "SumUpRounding", "weights_from_value"]


def weights_from_value(value, levels):
    """Convex weights on the two levels adjacent to a continuous value.

    Parameters
    ----------
    value : float
        Continuous input; clipped to ``[min(levels), max(levels)]``.
    levels : array_like, shape (n_levels,)
        Admissible input levels, strictly increasing.

    Returns
    -------
    weights : ndarray, shape (n_levels,)
        Non-negative, summing to 1, with ``weights @ levels == clip(value)``; at most two
        neighbouring entries are non-zero (the cheapest convex representation).
    """
    levels = np.asarray(levels, dtype=float)
    weights = np.zeros(levels.size)
    if levels.size == 1:
        weights[0] = 1.0
        return weights
    v = float(np.clip(value, levels[0], levels[-1]))
    j = int(np.clip(np.searchsorted(levels, v, side="right") - 1, 0, levels.size - 2))
    frac = (v - levels[j]) / (levels[j + 1] - levels[j])
    weights[j], weights[j + 1] = 1.0 - frac, frac
    return weights


class SumUpRounding:
    """Sum-up rounding with the deviation carried across control steps.

    At step ``j`` the accumulated deficit is ``D_j = sum_{l<=j} w_l - sum_{l<j} e_{i_l}``
    (relaxed weights minus the one-hot levels applied so far); the level with the largest
    deficit is applied and its deficit reduced by one.  The running deviation between applied
    and relaxed inputs therefore stays bounded (``max |D| <= 1`` for any weights, see
    ``tests/test_mpc.py``) instead of growing with the number of steps, which is what makes
    the applied piecewise-constant discrete input approximate the relaxed one in the integral
    sense.

    Parameters
    ----------
    n_levels : int
        Number of admissible levels.
    """

    name = "sur"

    def __init__(self, n_levels):
        self.n_levels = int(n_levels)
        self.deficit = np.zeros(self.n_levels)

    def reset(self):
        """Forget the accumulated deviation (start of an episode)."""
        self.deficit[:] = 0.0

    def __call__(self, weights):
        """Choose the level to apply for relaxed weights ``weights`` (shape (n_levels,)).

        Returns
        -------
        index : int
            Index of the level to apply.
        """
        w = np.clip(np.asarray(weights, dtype=float), 0.0, 1.0)
        total = w.sum()
        w = w / total if total > 0 else np.full(self.n_levels, 1.0 / self.n_levels)
        self.deficit += w
        # ties go to the level the relaxation itself prefers most
        index = int(np.lexsort((-w, -self.deficit))[0])
        self.deficit[index] -= 1.0
        return index


class NearestRounding:
    """Plain rounding: apply the level with the largest relaxed weight (no memory).

    With the weights of :func:`weights_from_value` this is rounding a continuous input to the
    nearest admissible level.

    Parameters
    ----------
    n_levels : int
        Number of admissible levels.
    """

    name = "nearest"

    def __init__(self, n_levels):
        self.n_levels = int(n_levels)

    def reset(self):
        """Nothing to forget; present for symmetry with :class:`SumUpRounding`."""

    def __call__(self, weights):
        """Index of the largest weight."""
        return int(np.argmax(np.asarray(weights, dtype=float)))


ROUNDINGS = {"sur": SumUpRounding, "nearest": NearestRounding}
