"""What the user wants of a system, apart from how it is achieved: :class:`Task`.

A task names things by the model's coordinates (``theta1``, ``theta1_dot`` …), never by a system:
the sample time, the inputs (a generalized force on a coordinate, with a discrete level set or
bounds), the goal (a target state to reach and hold inside a band, or a condition to reach once),
state limits and optional weights.  ``Task.load("task.toml")`` reads the same fields from a TOML
file (the format is documented in ``docs/control.md``); :meth:`Task.bind` checks the task against
a model's coordinates and returns the arrays a controller needs (:class:`BoundTask`).

Everything is validated when the task is made (``ValueError``/``TypeError`` naming the field),
so a bad file fails before anything is built.
"""
from __future__ import annotations

import math
import numbers
import re
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Task", "Input", "Goal", "BoundTask", "Episode"]

_RELATION = re.compile(r"(>=|<=|>|<)")


def _real(name, value, *, positive=False, nonnegative=False):
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    if positive and value <= 0:
        raise ValueError(f"{name} must be > 0, got {value}")
    if nonnegative and value < 0:
        raise ValueError(f"{name} must be >= 0, got {value}")
    return value


def _numbers(name, values):
    if isinstance(values, (str, bytes)) or not np.iterable(values):
        raise TypeError(f"{name} must be a list of numbers, got {values!r}")
    return [_real(f"{name} entry", v) for v in values]


def _state_dict(name, value, *, positive=False, nonnegative=False):
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise TypeError(f"{name} must be a table of state name -> number, got {value!r}")
    return {str(k): _real(f"{name}.{k}", v, positive=positive, nonnegative=nonnegative)
            for k, v in value.items()}


@dataclass(frozen=True)
class Input:
    """One input: a generalized force on a model coordinate.

    Parameters
    ----------
    coord : str
        The coordinate the force acts on (``Q_<coord>``).
    levels : tuple of float, optional
        The admissible values (a discrete input), stored sorted and unique.
    bounds : (float, float), optional
        ``(low, high)`` for a continuous input.  Exactly one of ``levels`` and ``bounds``.
    """

    coord: str
    levels: tuple | None = None
    bounds: tuple | None = None

    def __post_init__(self):
        if not isinstance(self.coord, str) or not self.coord:
            raise TypeError(f"an input must name a coordinate, got {self.coord!r}")
        if (self.levels is None) == (self.bounds is None):
            raise ValueError(f"input {self.coord!r}: give either levels = [...] (discrete) or "
                             "bounds = [low, high] (continuous)")
        if self.levels is not None:
            levels = sorted(set(_numbers(f"inputs.{self.coord}.levels", self.levels)))
            if not levels:
                raise ValueError(f"inputs.{self.coord}.levels is empty; give at least one level")
            object.__setattr__(self, "levels", tuple(levels))
        else:
            b = _numbers(f"inputs.{self.coord}.bounds", self.bounds)
            if len(b) != 2 or not b[0] < b[1]:
                raise ValueError(f"inputs.{self.coord}.bounds must be [low, high] with low < high, "
                                 f"got {list(self.bounds)}")
            object.__setattr__(self, "bounds", tuple(b))

    @property
    def discrete(self) -> bool:
        return self.levels is not None

    @property
    def low(self) -> float:
        return self.levels[0] if self.discrete else self.bounds[0]

    @property
    def high(self) -> float:
        return self.levels[-1] if self.discrete else self.bounds[1]

    def candidates(self) -> tuple:
        """The values a search over input sequences tries: the levels, or (low, 0, high) clipped
        to the bounds for a continuous input (bang-bang with a coast: the extremes and rest)."""
        if self.discrete:
            return self.levels
        return tuple(sorted({self.low, min(max(0.0, self.low), self.high), self.high}))


@dataclass(frozen=True)
class Goal:
    """Either a target state to reach and hold, or a condition on the state to reach once.

    Parameters
    ----------
    target : dict, optional
        State name -> value (states not named: 0).  With ``band`` and ``hold``.
    band : dict, optional
        State name -> half-width of the success band around the target (states not named are
        not checked).  Required with ``target``.
    hold : float
        Seconds the state must stay inside the band (0: reaching the band is enough).
    reach : str, optional
        A condition in sympy syntax over the state names, e.g.
        ``"-cos(theta1) - cos(theta1 + theta2) > 1.0"`` (one of ``> >= < <=``).
    """

    target: dict | None = None
    band: dict | None = None
    hold: float = 0.0
    reach: str | None = None

    def __post_init__(self):
        if (self.target is None) == (self.reach is None):
            raise ValueError("goal: give either target (with band) or reach, not both or neither")
        put = (lambda k, v: object.__setattr__(self, k, v))
        put("hold", _real("goal.hold", self.hold, nonnegative=True))
        if self.target is not None:
            put("target", _state_dict("goal.target", self.target))
            if not self.band:
                raise ValueError("goal.band is required with goal.target (the success band: "
                                 "state name -> half-width)")
            put("band", _state_dict("goal.band", self.band, positive=True))
        else:
            if not isinstance(self.reach, str) or not _RELATION.search(self.reach):
                raise ValueError(f"goal.reach must be a condition such as 'expr > 1.0', got "
                                 f"{self.reach!r}")
            if self.band:
                raise ValueError("goal.band belongs to a target goal, not to goal.reach")


@dataclass(frozen=True)
class Episode:
    """How ``lsindy control`` starts and ends an episode (not used by the controller itself).

    Parameters
    ----------
    duration : float
        Seconds per episode.
    start : dict
        State name -> value of the nominal start (states not named: 0).
    spread : dict
        State name -> half-width of a uniform random offset added to ``start``.
    """

    duration: float = 10.0
    start: dict = field(default_factory=dict)
    spread: dict = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "duration", _real("episode.duration", self.duration,
                                                    positive=True))
        object.__setattr__(self, "start", _state_dict("episode.start", self.start))
        object.__setattr__(self, "spread", _state_dict("episode.spread", self.spread,
                                                        nonnegative=True))


@dataclass(frozen=True)
class Task:
    """A control task over a model's coordinates.

    Parameters
    ----------
    dt : float
        Seconds between control decisions; each input is held over its interval.
    inputs : dict
        Coordinate name -> :class:`Input` (or a table ``{"levels": [...]}`` /
        ``{"bounds": [lo, hi]}``), in the order the controller returns them.
    goal : Goal or dict
    limits : dict, optional
        State name -> ``(low, high)``: bounds the controller keeps the state inside (e.g. a track).
    weights : dict, optional
        State or input name -> weight of its squared deviation in the controller's cost; default:
        ``1 / band²`` for a state with a band (what the user calls close), ``1 / max|input|²``
        for an input.
    episode : Episode or dict, optional
        Start and length of the episodes ``lsindy control`` runs.
    """

    dt: float
    inputs: dict
    goal: Goal
    limits: dict = field(default_factory=dict)
    weights: dict = field(default_factory=dict)
    episode: Episode = field(default_factory=Episode)

    def __post_init__(self):
        put = (lambda k, v: object.__setattr__(self, k, v))
        put("dt", _real("dt", self.dt, positive=True))
        if not isinstance(self.inputs, dict) or not self.inputs:
            raise ValueError("inputs must name at least one coordinate with its levels or bounds")
        inputs = {}
        for name, spec in self.inputs.items():
            if isinstance(spec, Input):
                inputs[name] = spec if spec.coord == name else Input(name, spec.levels, spec.bounds)
            elif isinstance(spec, dict):
                unknown = set(spec) - {"levels", "bounds"}
                if unknown:
                    raise ValueError(f"inputs.{name}: unknown field(s) {sorted(unknown)}; "
                                     "use levels or bounds")
                inputs[name] = Input(name, spec.get("levels"), spec.get("bounds"))
            else:
                raise TypeError(f"inputs.{name} must be a table with levels or bounds")
        put("inputs", inputs)
        if isinstance(self.goal, dict):
            unknown = set(self.goal) - {"target", "band", "hold", "reach"}
            if unknown:
                raise ValueError(f"goal: unknown field(s) {sorted(unknown)}")
            put("goal", Goal(**self.goal))
        elif not isinstance(self.goal, Goal):
            raise TypeError("goal must be a Goal or a table with target/band/hold or reach")
        limits = {}
        for name, lim in (self.limits or {}).items():
            pair = _numbers(f"limits.{name}", lim) if np.iterable(lim) else []
            lo, hi = pair if len(pair) == 2 else (None, None)
            if lo is None or not lo < hi:
                raise ValueError(f"limits.{name} must be [low, high] with low < high, got {lim!r}")
            limits[str(name)] = (lo, hi)
        put("limits", limits)
        put("weights", _state_dict("weights", self.weights, nonnegative=True))
        if isinstance(self.episode, dict):
            unknown = set(self.episode) - {"duration", "start", "spread"}
            if unknown:
                raise ValueError(f"episode: unknown field(s) {sorted(unknown)}")
            put("episode", Episode(**self.episode))

    @classmethod
    def load(cls, path) -> "Task":
        """Read a task from a TOML file (fields as in the class; unknown keys are an error)."""
        try:
            import tomllib
        except ModuleNotFoundError:                  # Python 3.10
            import tomli as tomllib
        try:
            with open(path, "rb") as fh:
                data = tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"task file {path}: not valid TOML ({exc})") from None
        except OSError as exc:
            raise ValueError(f"task file {path}: cannot read ({exc.strerror or exc})") from None
        unknown = set(data) - {"dt", "inputs", "goal", "limits", "weights", "episode"}
        if unknown:
            raise ValueError(f"task file {path}: unknown field(s) {sorted(unknown)}")
        for key in ("dt", "inputs", "goal"):
            if key not in data:
                raise ValueError(f"task file {path}: missing field {key!r}")
        return cls(**data)

    def bind(self, coords) -> "BoundTask":
        """Check the task against a model's coordinate names and return its arrays.

        Raises ``ValueError`` naming the first coordinate or state the model does not have.
        """
        return BoundTask(self, list(coords))


class BoundTask:
    """A :class:`Task` checked against a model's coordinates: index arrays and vectors.

    Attributes
    ----------
    names : list of str
        State names ``[q..., q_dot...]``.
    B : ndarray (n_coords, n_inputs)
        Generalized force of each input (a 1 in its coordinate's row).
    target, band : ndarray (2 n_coords,)
        Target state (0 where not named) and band (inf where not checked); None for a reach goal.
    lower, upper : ndarray (2 n_coords,)
        State limits (±inf where none).
    reach : tuple (str, callable) or None
        The reach condition's text and ``g(X) -> margin`` (>= 0 where it holds), vectorised over
        rows of ``X``.
    """

    def __init__(self, task: Task, coords: list):
        from ..symbolic.coords import Coordinates
        self.task = task
        self.coords = Coordinates(coords)
        self.names = list(self.coords.state_names)
        n = len(coords)
        index = {name: i for i, name in enumerate(self.names)}

        def where(name, what):
            if name not in index:
                raise ValueError(f"{what} names {name!r}, which is not a state of the model "
                                 f"(states: {', '.join(self.names)})")
            return index[name]

        self.B = np.zeros((n, len(task.inputs)))
        for j, (name, spec) in enumerate(task.inputs.items()):
            if name not in coords:
                raise ValueError(f"inputs.{name}: the model has no coordinate {name!r} "
                                 f"(coordinates: {', '.join(coords)})")
            self.B[coords.index(name), j] = 1.0
        self.inputs = list(task.inputs.values())
        self.lower, self.upper = np.full(2 * n, -np.inf), np.full(2 * n, np.inf)
        for name, (lo, hi) in task.limits.items():
            i = where(name, "limits")
            self.lower[i], self.upper[i] = lo, hi
        self.weights = {}
        input_names = set(task.inputs)
        for name, w in task.weights.items():
            if name not in index and name not in input_names:
                raise ValueError(f"weights.{name}: not a state or an input of the task")
            self.weights[name] = w
        goal = task.goal
        self.target = self.band = self.reach = None
        if goal.target is not None:
            self.target, self.band = np.zeros(2 * n), np.full(2 * n, np.inf)
            for name, v in goal.target.items():
                self.target[where(name, "goal.target")] = v
            for name, v in goal.band.items():
                self.band[where(name, "goal.band")] = v
            bad = ~((self.lower <= self.target) & (self.target <= self.upper))
            if np.any(bad):
                raise ValueError(f"goal.target puts {self.names[int(np.flatnonzero(bad)[0])]} "
                                 "outside its limits")
        else:
            self.reach = (goal.reach, self._reach_function(goal.reach))
        for name in list(task.episode.start) + list(task.episode.spread):
            where(name, "episode")

    def _reach_function(self, text):
        import casadi as ca
        parts = _RELATION.split(text)
        if len(parts) != 3:
            raise ValueError(f"goal.reach {text!r}: write one comparison, e.g. 'expr > 1.0'")
        lhs, op, rhs = parts
        left = self.coords.parse(lhs, what="goal.reach (left side)")
        right = self.coords.parse(rhs, what="goal.reach (right side)")
        margin = left - right if op in (">", ">=") else right - left
        f = ca.Function("reach", [self.coords.x], [self.coords.to_casadi(margin)])
        return f

    def start(self, rng) -> np.ndarray:
        """A random start of an episode (``episode.start`` ± ``episode.spread``)."""
        x = np.zeros(len(self.names))
        for name, v in self.task.episode.start.items():
            x[self.names.index(name)] = v
        for name, s in self.task.episode.spread.items():
            x[self.names.index(name)] += rng.uniform(-s, s)
        return x

    def reached_band(self, x, wrap) -> bool:
        """Whether ``x`` is inside the target band (angles in ``wrap`` compared modulo 2π)."""
        e = np.asarray(x, float) - self.target
        e[wrap] = (e[wrap] + np.pi) % (2 * np.pi) - np.pi
        return bool(np.all(np.abs(e) <= self.band))
