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

Both are timed as wall clock (the target) and as CPU time of the child process (user + sys, from
``os.wait4``), which a machine shared with other jobs disturbs much less.  The package is first
byte-compiled (``python -m compileall``, as ``pip install`` does): a source tree run with
``PYTHONDONTWRITEBYTECODE=1`` would otherwise compile its ~45 modules in every process (~0.08 s of
CPU); ``--no-compile`` skips that step.

Also: the import time of the CLI and the time of each stage of one ``lsindy identify`` run, in
process, by wrapping the stage functions with timers (CPU and wall; no profiler: cProfile's
per-call overhead inflates sympy-heavy stages several-fold), and whether that run imported sympy
(with the library's cache warm it should not: the printout and model file are assembled from the
cached per-term templates, ``lsindy_cas.symbolic.template``).

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_cli.py --out results          # 5 runs / 3 loops
    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_cli.py --out results --quick  # 3 runs / 1 loop
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
STAGES = {    # stage -> (module, function or Class.method) timed in one `lsindy identify` run
    "load files": ("lsindy_cas.data.trajectory", "load_trajectories"),
    "library (terms from the cache)": ("lsindy_cas.commands._common", "library"),
    "smoothing": ("lsindy_cas.data.smoothing", "smooth"),
    "energy balance (incl. CasADi functions)": ("lsindy_cas.identify.estimator",
                                                "LagrangianSINDy._balance"),
    "noise model": ("lsindy_cas.identify.uncertainty", "noise_model"),
    "support search + k": ("lsindy_cas.identify.selection", "select"),
    "errors in variables (re-weight, re-select)": ("lsindy_cas.identify.estimator",
                                                   "LagrangianSINDy._refine"),
    "Legendre + mechanics (CasADi)": ("lsindy_cas.identify.estimator",
                                      "LagrangianSINDy._set_coefficients"),
    "standard errors": ("lsindy_cas.identify.standard_errors", "coefficient_errors"),
    "diagnostics": ("lsindy_cas.identify.diagnostics", "diagnose"),
    "status (incl. simulation)": ("lsindy_cas.identify.estimator", "LagrangianSINDy._assess"),
    "printout": ("lsindy_cas.printing", "model_text"),
    "model file": ("lsindy_cas.identify.model_file", "save_model"),
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


def run(cmd, env) -> tuple:
    """Run ``cmd``; (wall seconds, CPU seconds of the child: user + sys)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    dt = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode()
    proc.stderr.close()
    if proc.returncode not in (0, 3):
        raise RuntimeError(err)
    return dt, usage.ru_utime + usage.ru_stime


def import_time(env, reps=5) -> dict:
    """Median wall and CPU of ``python -c "import lsindy_cas.cli"`` minus a bare interpreter, and
    of the imports an identify run adds (numpy, casadi, sympy and the package's modules)."""
    def med(code):
        res = [run([sys.executable, "-c", code], env) for _ in range(reps)]
        return statistics.median(r[0] for r in res), statistics.median(r[1] for r in res)
    bare = med("pass")
    cli = med("import lsindy_cas.cli")
    full = med("import lsindy_cas.cli, lsindy_cas.identify.estimator, lsindy_cas.printing, "
               "lsindy_cas.identify.model_file, lsindy_cas.data.trajectory")
    sp = med("import sympy")
    return {"cli_s": cli[0] - bare[0], "cli_cpu_s": cli[1] - bare[1],
            "identify_imports_s": full[0] - bare[0], "identify_imports_cpu_s": full[1] - bare[1],
            "sympy_s": sp[0] - bare[0], "sympy_cpu_s": sp[1] - bare[1]}


def stage_times(csv: Path, out: Path) -> dict:
    """One in-process ``lsindy identify`` run with each stage function wrapped by a timer:
    {stage: [CPU seconds, wall seconds]} (outermost calls only; a stage called twice adds up)."""
    import contextlib
    import functools
    import importlib
    import io
    from lsindy_cas.cli import main
    acc, wrapped = {}, []

    def timer(stage, f):
        @functools.wraps(f)
        def timed(*a, **kw):
            d = acc.setdefault(stage, [0.0, 0.0, 0])
            if d[2]:
                return f(*a, **kw)
            d[2] += 1
            c0, t0 = time.process_time(), time.perf_counter()
            try:
                return f(*a, **kw)
            finally:
                d[0] += time.process_time() - c0
                d[1] += time.perf_counter() - t0
                d[2] -= 1
        return timed

    for mod in ("lsindy_cas.identify.estimator", "lsindy_cas.printing",
                "lsindy_cas.identify.model_file", "lsindy_cas.data.trajectory",
                "lsindy_cas.commands.identify"):
        importlib.import_module(mod)
    for stage, (mod, name) in STAGES.items():
        m = importlib.import_module(mod)
        if "." in name:                        # a method: wrap it on the class
            cls, meth = name.split(".")
            owner, attr = getattr(m, cls), meth
        else:                                  # a function: wrap it wherever it was imported to
            owner, attr = None, name
        f = getattr(owner or m, attr)
        w = timer(stage, f)
        homes = [owner] if owner else [x for k, x in list(sys.modules.items())
                                      if k.startswith("lsindy_cas") and getattr(x, attr, None) is f]
        for h in homes:
            wrapped.append((h, attr, f))
            setattr(h, attr, w)
    try:
        c0, t0 = time.process_time(), time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            main(cli_args(csv, out))
        total = [time.process_time() - c0, time.perf_counter() - t0]
    finally:
        for h, attr, f in wrapped:
            setattr(h, attr, f)
    res = {stage: acc.get(stage, [0.0, 0.0])[:2] for stage in STAGES}
    res["total (in process, after imports)"] = total
    res["sympy imported (1 = yes)"] = [float("sympy" in sys.modules)] * 2
    return res


def fresh_stage_times(csv: Path, out: Path, env) -> dict:
    """:func:`stage_times` in a fresh interpreter (nothing imported or cached yet), as JSON."""
    code = ("import json, sys; sys.path.insert(0, %r); from pathlib import Path; "
            "from bench_cli import stage_times; "
            "print(json.dumps(stage_times(Path(sys.argv[1]), Path(sys.argv[2]))))" % str(HERE))
    r = subprocess.run([sys.executable, "-c", code, str(csv), str(out)], capture_output=True,
                       text=True, env=env, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


def compile_package(env, src: Path = HERE.parent / "src") -> None:
    """Byte-compile the package as an installation does (``__pycache__`` is git-ignored)."""
    e = dict(env)
    e.pop("PYTHONDONTWRITEBYTECODE", None)
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(Path(src) / "lsindy_cas")],
                   check=True, env=e, stdout=subprocess.DEVNULL)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="folder for cli.json")
    ap.add_argument("--quick", action="store_true", help="3 runs of ours, 1 of the loop")
    ap.add_argument("--reps", type=int, default=None, help="runs of ours (default 5, quick 3)")
    ap.add_argument("--no-compile", action="store_true",
                    help="do not byte-compile the package first (each process compiles it)")
    ap.add_argument("--baseline-src", metavar="DIR",
                    help="also time `lsindy identify` from this source tree (e.g. an earlier "
                    "commit's src/, from `git archive`), interleaved: before/after in one run")
    a = ap.parse_args(argv)
    reps = a.reps or (3 if a.quick else 5)
    loop_reps = 1 if a.quick else 3
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(HERE.parent / "src"), env.get("PYTHONPATH", "")])
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    base_env = None
    if a.baseline_src:
        base_env = dict(env, PYTHONPATH=os.pathsep.join([str(Path(a.baseline_src).resolve()),
                                                        os.environ.get("PYTHONPATH", "")]))
    if not a.no_compile:
        compile_package(env)
        if base_env:
            compile_package(env, Path(a.baseline_src))
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        # the CasADi-Function / library cache (symbolic/fcache.py) in a fresh folder: the first
        # run fills it (reported as "cold"), the timed runs read it
        env["LSINDY_CACHE_DIR"] = str(tmp / "fcache")
        csv = spherical_file(tmp)
        ours_cmd = [sys.executable, "-m", "lsindy_cas.cli", *cli_args(csv, tmp / "m.json")]
        loop_cmd = [sys.executable, "-c", LOOP, str(csv), FEATURES, "3"]
        print("import time ...", file=sys.stderr)
        imp = import_time(env)
        cold = run(ours_cmd, env)                                 # fills the cache
        print("stages (in process) ...", file=sys.stderr)
        stages = fresh_stage_times(csv, tmp / "m_stages.json", env)
        print(f"lsindy identify x {reps}, paper-style loop x {loop_reps} ...", file=sys.stderr)
        base_cmd = [sys.executable, "-m", "lsindy_cas.cli", *cli_args(csv, tmp / "b.json")]
        if base_env:
            run(base_cmd, base_env)
        ours, loop, base = [], [], []
        for i in range(max(reps, loop_reps)):                     # interleaved: same load
            if i < reps:
                ours.append(run(ours_cmd, env))
                if base_env:
                    base.append(run(base_cmd, base_env))
            if i < loop_reps:
                loop.append(run(loop_cmd, env))
        model = json.loads((tmp / "m.json").read_text())
        same_as_base = (base_env is not None
                        and (tmp / "m.json").read_bytes() == (tmp / "b.json").read_bytes())
    med = statistics.median
    t_ours, t_loop = med(w for w, _ in ours), med(w for w, _ in loop)
    c_ours, c_loop = med(c for _, c in ours), med(c for _, c in loop)
    print("\n| stage (one run, in a fresh process, after its imports) | CPU s | wall s |\n|---|---|---|")
    for k, (c, w) in stages.items():
        print(f"| {k} | {c:.3f} | {w:.3f} |")
    print(f"\nimport lsindy_cas.cli: {imp['cli_s'] * 1e3:.0f} ms wall, {imp['cli_cpu_s'] * 1e3:.0f} ms "
          f"CPU; everything identify imports: {imp['identify_imports_s']:.2f} s wall, "
          f"{imp['identify_imports_cpu_s']:.2f} s CPU (sympy alone {imp['sympy_cpu_s']:.2f} s CPU); "
          "over a bare interpreter")
    print("\n| end to end (process start to JSON) | median wall | min | max | median CPU |"
          "\n|---|---|---|---|---|")
    rows = [(f"lsindy identify (no accelerations), {reps} runs", ours),
            ("lsindy identify, first run (empty function cache)", [cold])]
    if base:
        rows.append((f"lsindy identify from {a.baseline_src}, {reps} runs", base))
    rows.append((f"paper-style loop, {loop_reps} runs", loop))
    for name, runs in rows:
        w = [x for x, _ in runs]
        print(f"| {name} | {med(w):.2f} s | {min(w):.2f} s | {max(w):.2f} s | "
              f"{med(c for _, c in runs):.2f} s |")
    print(f"\nspeed-up (medians): {t_loop / t_ours:.1f}x wall (target >= 20x), "
          f"{c_loop / c_ours:.1f}x CPU; byte-compiled: {not a.no_compile}; load average at start "
          f"{load[0]:.2f}; H = {model['hamiltonian']}")
    if base:
        print(f"baseline: {t_loop / med(w for w, _ in base):.1f}x wall, "
              f"{c_loop / med(c for _, c in base):.1f}x CPU; same model file bytes: {same_as_base}")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "cli.json").write_text(json.dumps({
        "ours_s": [w for w, _ in ours], "loop_s": [w for w, _ in loop],
        "ours_cpu_s": [c for _, c in ours], "loop_cpu_s": [c for _, c in loop],
        "ours_median_s": t_ours, "loop_median_s": t_loop, "speedup": t_loop / t_ours,
        "ours_median_cpu_s": c_ours, "loop_median_cpu_s": c_loop, "speedup_cpu": c_loop / c_ours,
        "byte_compiled": not a.no_compile, "imports": imp,
        "cold_s": cold[0], "cold_cpu_s": cold[1],
        "baseline": None if not base else {
            "src": a.baseline_src, "wall_s": [w for w, _ in base], "cpu_s": [c for _, c in base],
            "median_s": med(w for w, _ in base), "median_cpu_s": med(c for _, c in base),
            "speedup": t_loop / med(w for w, _ in base),
            "speedup_cpu": c_loop / med(c for _, c in base), "same_model_file": same_as_base},
        "stages_cpu_wall_s": stages, "load_average": load,
        "hamiltonian": model["hamiltonian"], "status": model.get("status")}, indent=2))
    print(f"written {out / 'cli.json'}")


if __name__ == "__main__":
    main()
