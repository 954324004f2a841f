"""Argument checks shared by every layer: one sentence naming the argument and what was expected.

Each raises ``TypeError`` for a value of the wrong kind and ``ValueError`` for one of the right kind
out of range, and returns the value converted (``int`` or ``float``), so callers write
``self.dt = check_real("dt", dt, positive=True)``.
"""
from __future__ import annotations

import math
import numbers

__all__ = ["check_bool", "check_choice", "check_int", "check_real", "check_state",
           "relative_energy"]


def check_int(name: str, value, *, low: int | None = None, high: int | None = None,
              allow_none: bool = False):
    """An integer (not a bool) in ``[low, high]``; ``None`` passes through when ``allow_none``."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer{' or None' if allow_none else ''}, "
                        f"got {value!r}")
    value = int(value)
    if (low is not None and value < low) or (high is not None and value > high):
        if high is None:
            rng = f">= {low}"
        elif low is None:
            rng = f"<= {high}"
        else:
            rng = f"between {low} and {high}"
        raise ValueError(f"{name} must be {rng}, got {value}")
    return value


def check_real(name: str, value, *, positive: bool = False, nonnegative: bool = False,
               allow_none: bool = False):
    """A finite real number (not a bool); optionally > 0 or >= 0."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number{' or None' if allow_none else ''}, "
                        f"got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if positive and not value > 0:
        raise ValueError(f"{name} must be positive, got {value!r}")
    if nonnegative and value < 0:
        raise ValueError(f"{name} must be non-negative, got {value!r}")
    return value


def check_bool(name: str, value):
    """``True`` or ``False`` (not a number standing for one)."""
    if not isinstance(value, bool):
        raise TypeError(f"{name} must be True or False, got {value!r}.")
    return value


def check_choice(name: str, value, options):
    """One of ``options`` (compared with ``==``)."""
    if value not in tuple(options):
        raise ValueError(f"{name} must be one of {tuple(options)}, got {value!r}")
    return value


def check_state(x, n_state: int):
    """A finite state vector ``[q, q_dot]`` of ``n_state`` entries, as a float array."""
    import numpy as np
    try:
        x = np.asarray(x, dtype=float).ravel()
    except (TypeError, ValueError):
        raise TypeError("x must be a sequence of numbers (the state [q, q_dot]).") from None
    if x.size != n_state:
        raise ValueError(f"x must have {n_state} entries [q, q_dot], got {x.size}.")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"x must be finite, got {x.tolist()}.")
    return x


def relative_energy(model) -> bool:
    """Whether ``model`` knows its energy only up to a constant factor: identified from passive
    data without a scale record (``energy_scale_ == "relative"``), so the input's effect is unknown.
    Anything without the attribute (a system, an older model) counts as absolute."""
    return getattr(model, "energy_scale_", "absolute") == "relative"
