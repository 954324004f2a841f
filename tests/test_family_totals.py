"""``benchmarks/family_totals.py``: family runs of different seeds summed per plant and cell."""

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).parents[1] / "benchmarks" / "family_totals.py"


def _run(tmp_path, seed, cells):
    """A bench_family.py-shaped JSON: ``cells`` maps a cell to (success, reachable) pairs."""
    report = {"seed": seed, "plants": [{"mc": 0.8, "mp": 0.2, "L": 0.7, "cells": {
        f"identified/auto/{c}": {"episodes_detail": [
            {"success": s, "reachable": r, "time_to_upright": 2.0, "track_used": 1.0}
            for s, r in eps]} for c, eps in cells.items()}}]}
    path = tmp_path / f"seed{seed}.json"
    path.write_text(json.dumps(report))
    return str(path)


def _call(tmp_path, *paths):
    return subprocess.run([sys.executable, str(SCRIPT), "--out", str(tmp_path / "out"),
                           "--json", *paths], capture_output=True, text=True)


def test_reachable_successes_are_summed_over_seeds(tmp_path):
    # seed 0: 19 of 20 reachable held (95 %), an unreachable success not counted; seed 1: 18/20
    a = _run(tmp_path, 0, {"mismatch": [(True, True)] * 19 + [(False, True), (True, False)],
                           "nominal": [(True, True)] * 20})
    b = _run(tmp_path, 1, {"mismatch": [(True, True)] * 18 + [(False, True)] * 2,
                           "nominal": [(True, True)] * 19 + [(False, True)]})
    res = _call(tmp_path, a, b)
    assert res.returncode == 0, res.stderr
    rows = {r["cell"]: r for r in json.loads(
        (tmp_path / "out" / "family_totals.json").read_text())["rows"]}
    mis, nom = rows["identified/auto/mismatch"], rows["identified/auto/nominal"]
    assert mis["per_run"] == [[19, 20], [18, 20]] and (mis["successes"], mis["reachable"]) == (37, 40)
    assert mis["share"] == 37 / 40 and not mis["at_target"]          # 92.5 %
    assert (nom["successes"], nom["reachable"], nom["at_target"]) == (39, 40, True)  # 97.5 %
    md = (tmp_path / "out" / "family_totals.md").read_text()
    assert "| 0.8/0.2/0.7 | mismatch | 19/20 / 18/20 | 37/40 (92.5 %) | **no** |" in md
    assert "1 of 2 plant cells at >= 95 %" in md


def test_the_same_seed_twice_or_a_bad_file_is_one_error(tmp_path):
    a = _run(tmp_path, 0, {"nominal": [(True, True)]})
    (tmp_path / "bad.json").write_text("{}")
    for paths in ((a, a), (a, str(tmp_path / "bad.json")), (str(tmp_path / "missing.json"),)):
        res = _call(tmp_path, *paths)
        assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
        assert res.stderr.strip().splitlines()[-1].startswith("family_totals.py: error: ")
