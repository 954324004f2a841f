"""`lsindy identify` end to end (process start to JSON) against the paper-style loop, same run.

The data are the spherical pendulum's paper run (1 s, u = 1 N·m on φ, 100 Hz) saved **without**
accelerations, so the command takes the common path: integral form, smoothing, noise model,
errors in variables, standard errors, diagnostics and status, library of 125 terms, k = 3, no
prior terms (C(125, 3) = 317,750 supports).

- ours: ``python -m lsindy_cas.cli identify FILE ... --json OUT`` as a subprocess, N times;
- paper-style loop: a subprocess that reads the same file, builds the same library and balance
  (integral form, every window, as ours) and scores every support with its own
  ``np.linalg.lstsq`` inside ``itertools.combinations`` — the direct reading of the paper's
  trial-and-error search — then prints the best support.  It does no smoothing, no noise model and
  no diagnostics, so the comparison favours the loop.

Also: the import time of the CLI (``python -X importtime``) and the time of each stage of one
``lsindy identify`` run (cProfile, in process).

    python benchmarks/bench_cli.py --out results          # 5 runs of ours, 3 of the loop
    python benchmarks/bench_cli.py --out results --quick  # 3 runs of ours, 1 of the loop
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
FEATURES = "cos(theta),sin(theta),theta_dot,phi,phi_dot"
STAGES = {    # cProfile cumulative time of these functions = the stages of `lsindy identify`
    "load files": "load_trajectories",
    "library (CasADi terms)": "library",
    "smoothing": "smooth",
    "energy balance": "_balance",
    "noise model": "noise_model",
    "support search + k": "select",
    "errors in variables": "_refine",
    "Legendre + Euler-Lagrange": "_set_coefficients",
    "standard errors": "coefficient_errors",
    "diagnostics": "diagnose",
    "status (incl. simulation)": "_assess",
    "printout": "model_text",
    "model file": "save_model",
}

LOOP = r"""
import itertools, sys, time
import numpy as np
from lsindy_cas.data.trajectory import load_trajectories
from lsindy_cas.symbolic.library import Library
from lsindy_cas.identify.balance import integral_form
path, features, k = sys.argv[1], sys.argv[2], int(sys.argv[3])
trs = load_trajectories([path], ["theta", "phi"])
lib = Library.polynomial(["theta", "phi"], features, 4)
bal = integral_form(lib, trs)
A, b = bal.A, bal.b
best, best_S = np.inf, None
for S in itertools.combinations(range(A.shape[1]), k):
    S = list(S)
    x = np.linalg.lstsq(A[:, S], b, rcond=None)[0]
    r = b - A[:, S] @ x
    if r @ r < best:
        best, best_S = r @ r, S
print([lib.names[j] for j in best_S])
"""


def spherical_file(folder: Path) -> Path:
    """The paper's spherical-pendulum run, saved without the accelerations."""
    from lsindy_cas.data.trajectory import Trajectory
    from lsindy_cas.paper import systems
    tr = systems.spherical_pendulum().simulate(t_end=1.0, u=1.0)
    tr = Trajectory(tr.t, tr.q, tr.qd, tr.coords, Q=tr.Q, source=tr.source)
    return tr.save(folder / "spherical.csv")


def cli_args(csv: Path, out: Path) -> list:
    return ["identify", str(csv), "--coords", "theta,phi", "--features", FEATURES, "--degree",
            "4", "--terms", "3", "--json", str(out)]


def run(cmd, env) -> float:
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    dt = time.perf_counter() - t0
    if r.returncode not in (0, 3):
        raise RuntimeError(r.stderr)
    return dt


def import_time(env, reps=5) -> float:
    """Median wall clock of ``python -c "import lsindy_cas.cli"`` minus a bare interpreter."""
    def once(code):
        return run([sys.executable, "-c", code], env)
    bare = statistics.median(once("pass") for _ in range(reps))
    full = statistics.median(once("import lsindy_cas.cli") for _ in range(reps))
    return full - bare


def stage_times(csv: Path, out: Path) -> dict:
    """cProfile one in-process ``lsindy identify`` run: cumulative seconds per stage."""
    import cProfile
    import pstats
    from lsindy_cas.cli import main
    import contextlib
    import io
    prof = cProfile.Profile()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        prof.runcall(main, cli_args(csv, out))
    total = time.perf_counter() - t0
    stats = pstats.Stats(prof).stats
    res = {}
    for stage, fn in STAGES.items():
        res[stage] = max((v[3] for (f, _, name), v in stats.items() if name == fn and "lsindy" in f),
                         default=0.0)
    res["total (in process)"] = total
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="folder for cli.json")
    ap.add_argument("--quick", action="store_true", help="3 runs of ours, 1 of the loop")
    ap.add_argument("--reps", type=int, default=None, help="runs of ours (default 5, quick 3)")
    a = ap.parse_args(argv)
    reps = a.reps or (3 if a.quick else 5)
    loop_reps = 1 if a.quick else 3
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(HERE.parent / "src"), env.get("PYTHONPATH", "")])
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        csv = spherical_file(tmp)
        ours_cmd = [sys.executable, "-m", "lsindy_cas.cli", *cli_args(csv, tmp / "m.json")]
        loop_cmd = [sys.executable, "-c", LOOP, str(csv), FEATURES, "3"]
        print("import time ...", file=sys.stderr)
        imp = import_time(env)
        print("stages (cProfile, in process) ...", file=sys.stderr)
        stages = stage_times(csv, tmp / "m_prof.json")
        print(f"lsindy identify x {reps}, paper-style loop x {loop_reps} ...", file=sys.stderr)
        run(ours_cmd, env)                                        # warm the file cache
        ours, loop = [], []
        for i in range(max(reps, loop_reps)):                     # interleaved: same load
            if i < reps:
                ours.append(run(ours_cmd, env))
            if i < loop_reps:
                loop.append(run(loop_cmd, env))
        model = json.loads((tmp / "m.json").read_text())
    t_ours, t_loop = statistics.median(ours), statistics.median(loop)
    print("\n| stage (one run, cProfile) | seconds |\n|---|---|")
    for k, v in stages.items():
        print(f"| {k} | {v:.3f} |")
    print(f"\nimport lsindy_cas.cli: {imp * 1e3:.0f} ms (over a bare interpreter)")
    print("\n| end to end (process start to JSON) | median | min | max |\n|---|---|---|---|")
    print(f"| lsindy identify (no accelerations), {reps} runs | {t_ours:.2f} s | {min(ours):.2f} s "
          f"| {max(ours):.2f} s |")
    print(f"| paper-style loop, {loop_reps} runs | {t_loop:.2f} s | {min(loop):.2f} s | "
          f"{max(loop):.2f} s |")
    print(f"\nspeed-up (medians): {t_loop / t_ours:.1f}x (target >= 20x); load average at start "
          f"{load[0]:.2f}; H = {model['hamiltonian']}")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "cli.json").write_text(json.dumps({
        "ours_s": ours, "loop_s": loop, "ours_median_s": t_ours, "loop_median_s": t_loop,
        "speedup": t_loop / t_ours, "import_s": imp, "stages_s": stages, "load_average": load,
        "hamiltonian": model["hamiltonian"], "status": model.get("status")}, indent=2))
    print(f"written {out / 'cli.json'}")


if __name__ == "__main__":
    main()
