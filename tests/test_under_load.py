"""The fast suite's timing-sensitive tests give the same outcomes on a slowed machine.

"Timing-sensitive" here: a test whose code path reads a clock that could decide its outcome
(a time limit, a watchdog, a Dask task's length or its reads of the shared incumbent, a progress
bar's delay).  The list was found with
``grep -rnE "time_limit|monotonic|perf_counter|time\\.time|timeout|Watchdog|task_seconds|_clock|delay" tests/``
and, for clocks the tests reach without naming them, the same grep over ``src/``.
Each of them passes unloaded (the fast suite); here they run in a pytest subprocess while
``os.cpu_count()`` busy loops hold every core, and must all pass again.
"""
import os
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

TIMING_SENSITIVE = [
    # branch and bound: a mocked clock (its own, not time.monotonic) and the clock-free work limit
    "tests/test_bnb.py::test_time_limit_returns_best_so_far_not_proven",
    "tests/test_bnb.py::test_work_limit_stops_at_the_same_point_every_time",
    # Dask: tasks of task_seconds, incumbent reads every SYNC_EVERY s (1 s timeout), a mocked
    # driver clock for the time limit, node counts compared with one process
    "tests/test_distributed_bnb.py",
    # progress bar: the delay before a bar is drawn
    "tests/test_progress.py::test_quick_work_shows_nothing_and_imports_no_tqdm",
    "tests/test_progress.py::test_branch_and_bound_shows_nodes_and_gap",
    # MPC: the watchdog's limit (fatrop solves run under it: WATCHDOG_SECONDS) and step times
    "tests/test_mpc_realtime.py::test_watchdog_returns_raises_and_abandons_a_call_past_its_limit",
    "tests/test_mpc_realtime.py::"
    "test_a_fatrop_solve_that_does_not_return_is_abandoned_and_ipopt_takes_over",
    "tests/test_mpc_realtime.py::test_fatrop_recovers_the_sqp_optimum",
    "tests/test_mpc_realtime.py::test_every_step_records_what_it_ran_and_slow_steps_count_them",
]

BUSY = "while True:\n    pass\n"


@pytest.mark.slow
def test_timing_sensitive_tests_pass_with_every_core_busy(tmp_path):
    report = tmp_path / "report.xml"
    busy = [subprocess.Popen([sys.executable, "-c", BUSY], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL) for _ in range(os.cpu_count() or 1)]
    try:
        t0 = time.monotonic()
        # the timeout only guards against a hang: it decides nothing the list checks
        run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                              "-m", "not slow", f"--junitxml={report}", *TIMING_SENSITIVE],
                             cwd=ROOT, capture_output=True, text=True, timeout=900)
        seconds = time.monotonic() - t0
        still_busy = all(p.poll() is None for p in busy)
    finally:
        for p in busy:
            p.kill()
        for p in busy:
            p.wait()
    assert still_busy, "a busy loop ended early: the run was not under load throughout"
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    outcomes = {}
    for case in ET.parse(report).getroot().iter("testcase"):
        kinds = {child.tag for child in case} & {"failure", "error", "skipped"}
        outcomes[f"{case.get('classname')}.{case.get('name')}"] = kinds.pop() if kinds else "passed"
    # same outcomes as unloaded: everything passes (skips only where an optional package or
    # CasADi plugin is missing, which no load changes)
    assert outcomes and not {k: v for k, v in outcomes.items() if v in ("failure", "error")}
    assert sum(v == "passed" for v in outcomes.values()) >= 1
    print(f"{len(outcomes)} timing-sensitive tests under {len(busy)} busy loops: {seconds:.0f} s")
