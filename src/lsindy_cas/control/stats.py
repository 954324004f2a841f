"""Counters and solve times of an MPC, accumulated over episodes: :class:`MPCStats`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["MPCStats"]


@dataclass
class MPCStats:
    """Counters of an MPC's solves, accumulated over episodes until :meth:`clear`.

    Attributes
    ----------
    n_solves : int
        NLP solves attempted (one per control step, except the steps a subclass's own rule
        decides without a solve; see ``n_balanced``).
    n_failures : int
        Solves that failed or did not converge to a usable plan; each applied the shifted
        previous plan instead.
    n_inexact : int
        Solves stopped by the iteration cap whose iterate satisfied every constraint (dynamics,
        bounds) to ``inexact_tol``; applied when ``accept_inexact=True``, else counted as
        failures too.
    solve_times : list of float
        Wall-clock seconds per solve (the solver call only).
    solve_cpu_times : list of float
        CPU seconds of the calling thread per solve: unlike the wall-clock time, not inflated
        when other processes compete for the cores.
    step_times : list of float
        Wall-clock seconds per controller call (solve + warm start + rounding + checks).
    step_cpu_times : list of float
        CPU seconds of the calling thread per controller call.
    n_balanced : int
        Steps whose level was chosen by a subclass's own rule instead of from the relaxed plan
        (:class:`~lsindy_cas.mpc.SwingUpMPC`: the pulse balancer near the upright).
    n_resumed : int
        Solves that followed steps decided by the own rule without a solve (the first solve
        after the balancer let go; ``solve_balanced=False``).
    n_escalated : int
        Episodes in which :class:`~lsindy_cas.mpc.SwingUpMPC` switched from the pulse to the
        sequence balancer (the online estimate of the push reached ``SEQUENCE_KICK``).
    n_guard : int
        Steps whose input a plug-in's guard replaced (its prediction of the chosen input
        left the state limits).
    iterations : list of int
        Solver iterations per solve.
    solve_kinds : list of str
        Which solver ran each solve: ``"warm"`` (the warm-started solver), ``"cold"`` (first
        step of an episode) or ``"recover"`` (after a failed step).
    step_kinds : list of str
        What each controller call did, aligned with ``step_times``: the kind of its solve, or
        ``"balanced"`` (a subclass's own rule decided, without a solve).
    statuses : dict
        Count of each solver return status.
    """

    n_solves: int = 0
    n_failures: int = 0
    n_inexact: int = 0
    n_balanced: int = 0
    n_resumed: int = 0
    n_escalated: int = 0
    n_guard: int = 0
    solve_times: list = field(default_factory=list)
    solve_cpu_times: list = field(default_factory=list)
    step_times: list = field(default_factory=list)
    step_cpu_times: list = field(default_factory=list)
    iterations: list = field(default_factory=list)
    solve_kinds: list = field(default_factory=list)
    step_kinds: list = field(default_factory=list)
    statuses: dict = field(default_factory=dict)

    def clear(self):
        """Reset all counters."""
        self.__init__()

    def slow_steps(self, limit_ms=20.0, cpu=False):
        """Number of controller calls longer than ``limit_ms`` milliseconds (wall clock, or
        CPU time of the calling thread with ``cpu=True``) per kind of step
        (:attr:`step_kinds`): what the step-time p99 is made of."""
        t = np.asarray(self.step_cpu_times if cpu else self.step_times) * 1e3
        kinds = np.asarray(self.step_kinds, dtype=object)
        if kinds.size != t.size:  # steps recorded by hand without a kind
            kinds = np.full(t.size, "unknown", dtype=object)
        return {str(k): int(np.sum((kinds == k) & (t > limit_ms))) for k in np.unique(kinds)}

    def summary(self):
        """Dictionary of counts and solve-time percentiles in milliseconds (overall, and count,
        median and maximum per solve kind under ``"by_kind"``), the steps over 20 ms per kind
        (``"slow_steps"``, wall clock and ``"slow_steps_cpu"``) and the solver statuses."""
        t = np.asarray(self.solve_times) * 1e3
        kinds = np.asarray(self.solve_kinds, dtype=object)  # appended with solve_times
        by_kind = {k: {"n": int(np.sum(kinds == k)),
                       "solve_ms_median": float(np.median(t[kinds == k])),
                       "solve_ms_max": float(t[kinds == k].max())}
                   for k in ("warm", "cold", "recover") if np.any(kinds == k)}
        c = np.asarray(self.solve_cpu_times) * 1e3
        s = np.asarray(self.step_times) * 1e3
        sc = np.asarray(self.step_cpu_times) * 1e3
        pct = (lambda a, q: float(np.percentile(a, q)) if a.size else float("nan"))
        return {"n_solves": self.n_solves, "n_failures": self.n_failures,
                "n_inexact": self.n_inexact, "n_balanced": self.n_balanced,
                "n_resumed": self.n_resumed, "n_escalated": self.n_escalated,
                "n_guard": self.n_guard,
                "solve_ms_median": pct(t, 50), "solve_ms_p99": pct(t, 99),
                "solve_ms_max": float(t.max()) if t.size else float("nan"),
                "solve_cpu_ms_median": pct(c, 50), "solve_cpu_ms_p99": pct(c, 99),
                "step_ms_median": pct(s, 50), "step_ms_p99": pct(s, 99),
                "step_cpu_ms_median": pct(sc, 50), "step_cpu_ms_p99": pct(sc, 99),
                "iterations_median": pct(np.asarray(self.iterations), 50), "by_kind": by_kind,
                "slow_steps": self.slow_steps(), "slow_steps_cpu": self.slow_steps(cpu=True),
                "statuses": dict(self.statuses)}
