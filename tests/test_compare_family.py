"""``benchmarks/compare_family.py``: two family runs compared episode by episode."""

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).parents[1] / "benchmarks" / "compare_family.py"


def _run(tmp_path, episodes, seed=0):
    rows = [{"success": s, "time_to_upright": t, "track_used": 1.0, "reachable": r,
             "model_released_at": rel} for s, t, r, rel in episodes]
    report = {"seed": seed, "plants": [{"mc": 0.6, "mp": 0.2, "L": 1.0, "cells": {
        "identified/auto/mismatch": {"episodes_detail": rows}}}]}
    path = tmp_path / f"run{len(list(tmp_path.glob('run*.json')))}.json"
    path.write_text(json.dumps(report))
    return str(path)


def test_gained_lost_identical_and_the_estimate(tmp_path):
    base = _run(tmp_path, [(True, 2.5, True, None), (False, float("inf"), True, None),
                           (True, 3.0, True, None), (False, float("nan"), False, None)])
    new = _run(tmp_path, [(True, 2.5, True, None), (True, 5.3, True, 3.0),
                          (False, 9.0, True, None), (False, float("nan"), False, None)])
    out = tmp_path / "out"
    res = subprocess.run([sys.executable, str(SCRIPT), "--out", str(out), "--base", base,
                          "--new", new], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    (row,) = json.loads((out / "compare.json").read_text())["rows"]
    assert row["identical"] == 2 and row["reachable"] == 3      # start 3 failed alike (NaN)
    assert (row["base_reachable_successes"], row["new_reachable_successes"]) == (2, 2)
    assert row["released"] == [1] and row["released_at"] == [3.0]
    assert row["gained"] == [1] and row["lost"] == [2]
    assert row["changed_without_estimate"] == [2]
    assert "| 0 | 0.6/0.2/1 | mismatch | 2 -> 2/3 | 2/4 | 1: 3.00 | [1] | [2] | [2] |" in (
        out / "compare.md").read_text()


def test_runs_of_different_seeds_or_unpaired_are_refused(tmp_path):
    a = _run(tmp_path, [(True, 2.5, True, None)], seed=0)
    b = _run(tmp_path, [(True, 2.5, True, None)], seed=1)
    for args in (["--base", a, "--new", b], ["--base", a, a, "--new", a],
                 ["--base", str(tmp_path / "missing.json"), "--new", a]):
        res = subprocess.run([sys.executable, str(SCRIPT), "--out", str(tmp_path / "o"), *args],
                             capture_output=True, text=True)
        assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
        # argparse's usage, then one error line
        assert res.stderr.strip().splitlines()[-1].startswith("compare_family.py: error: ")
        assert res.stderr.count("error") == 1
