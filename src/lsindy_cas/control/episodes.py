"""Closed-loop episodes of a :class:`~.controller.Controller` on a plant, and the goal's bookkeeping.

A plant is any ``step(x, u) -> x_next`` over one sample of the task (a model's discrete map, a
MuJoCo or gymnasium wrapper).  Success:

* target goal: the state stays inside the band for ``hold`` seconds (every sample), finishing
  within the episode; the time to goal is when that stretch began;
* reach goal: the condition holds at some sample; the time to goal is that sample's time;

and, for both, no sample leaves the task's state limits.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

__all__ = ["EpisodeResult", "run_episode", "GoalClock"]


class GoalClock:
    """Counts samples inside the goal (band held, or reach once) as an episode goes on."""

    def __init__(self, controller):
        self.ctrl = controller
        task = controller.task
        self.need = int(np.ceil(task.goal.hold / task.dt - 1e-9)) if task.goal.target is not None else 0
        self.run, self.done_at = 0, None

    def update(self, x, k):
        """Record sample ``k`` (state after ``k`` samples); True once the goal is met."""
        if self.done_at is not None:
            return True
        if self.ctrl.reached(x):
            self.run += 1
            if self.run > self.need:
                self.done_at = k - self.need
        else:
            self.run = 0
        return self.done_at is not None


@dataclass
class EpisodeResult:
    """One episode.

    Attributes
    ----------
    x0 : ndarray
    X : ndarray (n_steps + 1, n)
        States at the samples.
    U : ndarray (n_steps, m)
        Inputs applied.
    success : bool
    time_to_goal : float or None
        Seconds from the start to the sample where the goal was met (band entered for the
        held stretch, or the reach condition).
    within_limits : bool
    step_times : list of float
        Wall-clock seconds of each controller call.
    """

    x0: np.ndarray
    X: np.ndarray
    U: np.ndarray
    success: bool
    time_to_goal: float | None
    within_limits: bool
    step_times: list = field(default_factory=list)

    def summary(self) -> dict:
        st = np.asarray(self.step_times) * 1e3
        return {"x0": [round(float(v), 6) for v in self.x0], "success": self.success,
                "time_to_goal": None if self.time_to_goal is None else round(self.time_to_goal, 4),
                "within_limits": self.within_limits, "steps": int(len(self.U)),
                "step_ms_median": round(float(np.median(st)), 4) if st.size else None,
                "step_ms_max": round(float(np.max(st)), 4) if st.size else None}


def run_episode(controller, plant_step, x0, duration=None, stop_at_goal=None):
    """Run ``controller`` on ``plant_step`` from ``x0``.

    Parameters
    ----------
    controller : Controller
    plant_step : callable
        ``(x, u) -> x_next`` over one sample ``task.dt``.
    x0 : array_like (n,)
    duration : float, optional
        Seconds (default: the task's ``episode.duration``).
    stop_at_goal : bool, optional
        End at the goal (default: for a reach goal; a target goal runs on, so the hold is seen).

    Returns
    -------
    EpisodeResult
    """
    task = controller.task
    duration = task.episode.duration if duration is None else duration
    stop = (task.goal.reach is not None) if stop_at_goal is None else stop_at_goal
    n_steps = int(round(duration / task.dt))
    b = controller.bound
    controller.reset()
    clock = GoalClock(controller)
    x = np.asarray(x0, float)
    X, U, times = [x], [], []
    inside = bool(np.all((x >= b.lower) & (x <= b.upper)))
    clock.update(x, 0)
    for k in range(1, n_steps + 1):
        t0 = time.perf_counter()
        u = controller(x)
        times.append(time.perf_counter() - t0)
        x = np.asarray(plant_step(x, u), float).ravel()
        X.append(x)
        U.append(np.asarray(u, float))
        if not np.all(np.isfinite(x)):
            inside = False
            break
        inside &= bool(np.all((x >= b.lower) & (x <= b.upper)))
        if clock.update(x, k) and stop:
            break
    done = clock.done_at
    return EpisodeResult(np.asarray(x0, float), np.vstack(X), np.vstack(U) if U else
                         np.zeros((0, len(task.inputs))), bool(done is not None and inside),
                         None if done is None else done * task.dt, inside, times)
