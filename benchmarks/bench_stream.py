"""Identification from 10⁴ … 10⁶ samples in bounded memory (streamed, compressed balances).

Data: the paper's double pendulum (library of 209 terms: features cos θ1, cos θ2, sin θ1, sin θ2,
θ̇1, θ̇2, degree 4), runs of ``--seconds`` s at 100 Hz from random initial states, driven on the
first link by u = a sin(ω t + φ) (random a, ω, φ per run), simulated by CVODES (rtol 1e-10) with
exact accelerations, saved as NPZ files.  Each size is fitted in a fresh process —
``LagrangianSINDy(lib, n_terms=6, prior=Table I's four terms).fit(runs)`` (derivative form), the
estimator's whole path: streamed balance, search, held-out folds, jackknife significance and
standard errors, diagnostics, status — and reports wall time and peak resident memory
(``resource.getrusage``, including the interpreter, NumPy, CasADi and sympy).

    python benchmarks/bench_stream.py --out results            # 10⁴, 10⁵, 10⁶ samples
    python benchmarks/bench_stream.py --out results --quick    # 10⁴, 10⁵
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
FEATURES = "cos(theta1),cos(theta2),sin(theta1),sin(theta2),theta1_dot,theta2_dot"
PRIOR = ["theta1_dot**2", "cos(theta1)", "theta2_dot**2", "cos(theta2)"]

CHILD = r"""
import json, resource, sys, time
t0 = time.perf_counter()
import numpy as np
from lsindy_cas import LagrangianSINDy, Library, load_trajectories
files = sys.argv[2:]
runs = load_trajectories(files, ["theta1", "theta2"])
t1 = time.perf_counter()
lib = Library.polynomial(["theta1", "theta2"], {features!r}, 4)
m = LagrangianSINDy(lib, n_terms=6, prior={prior!r}).fit(runs)
t2 = time.perf_counter()
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024      # Linux: kB
json.dump({{"samples": int(sum(r.n_samples for r in runs)), "runs": len(runs),
           "terms": len(lib), "load_s": t1 - t0, "fit_s": t2 - t1, "peak_rss_bytes": peak,
           "support": [lib.names[j] for j in m.support_],
           "coef": {{lib.names[j]: float(m.coef_[j]) for j in m.support_}},
           "compressed": bool(m._record.balance.compressed) if hasattr(m, "_record") else None,
           "status": m.status_, "std_method": m.std_method_}}, open(sys.argv[1], "w"))
"""


def make_runs(folder: Path, n_runs: int, seconds: float, seed: int = 0) -> list:
    """Double-pendulum runs (NPZ with exact accelerations), simulated by CVODES on the grid."""
    import casadi as ca
    from lsindy_cas.data.trajectory import Trajectory
    from lsindy_cas.paper import systems
    s = systems.double_pendulum()
    ode = s.ode()
    x, tt = ca.SX.sym("x", 4), ca.SX.sym("t")
    par = ca.SX.sym("par", 3)                       # a, ω, φ
    u = par[0] * ca.sin(par[1] * tt + par[2])
    f = ode(x, ca.vertcat(u, 0))
    dae = {"x": ca.vertcat(x, tt), "p": par, "ode": ca.vertcat(f, 1)}
    t = np.arange(int(round(seconds * 100)) + 1) * 0.01
    F = ca.integrator("F", "cvodes", dae, 0.0, t[1:], {"abstol": 1e-11, "reltol": 1e-10,
                                                       "max_num_steps": 100000})
    rng = np.random.default_rng(seed)
    paths = []
    for i in range(n_runs):
        x0 = np.r_[rng.uniform(-1.5, 1.5, 2), rng.uniform(-1, 1, 2)]
        p = [rng.uniform(0.5, 2.0), rng.uniform(0.5, 3.0), rng.uniform(0, 2 * np.pi)]
        xf = np.asarray(F(x0=np.r_[x0, 0.0], p=p)["xf"])
        X = np.vstack([x0, xf[:4].T])
        U = p[0] * np.sin(p[1] * t + p[2])
        Q = np.c_[U, np.zeros_like(U)]
        Xdot = np.asarray(ode.map(len(t))(X.T, Q.T)).T
        tr = Trajectory(t, X[:, :2], X[:, 2:], ["theta1", "theta2"], Q=Q, qdd=Xdot[:, 2:])
        paths.append(tr.save(folder / f"run{i:03d}.npz"))
    return paths


def fit_in_child(paths, out: Path, env) -> dict:
    code = CHILD.format(features=FEATURES, prior=PRIOR)
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", code, str(out), *map(str, paths)],
                       capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(r.stderr[-3000:])
    res = json.loads(out.read_text())
    res["wall_s"] = wall
    return res


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="folder for stream.json")
    ap.add_argument("--quick", action="store_true", help="10⁴ and 10⁵ samples only")
    ap.add_argument("--seconds", type=float, default=100.0, help="length of a run (s)")
    a = ap.parse_args(argv)
    sizes = [1, 10] if a.quick else [1, 10, 100]            # runs of --seconds at 100 Hz
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(HERE.parent / "src"), env.get("PYTHONPATH", "")])
    load = os.getloadavg()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        print(f"simulating {max(sizes)} runs of {a.seconds:g} s ...", file=sys.stderr)
        paths = make_runs(tmp, max(sizes), a.seconds)
        sim_s = time.perf_counter() - t0
        for n in sizes:
            print(f"fitting {n} run(s) ...", file=sys.stderr)
            rows.append(fit_in_child(paths[:n], tmp / f"fit{n}.json", env))
    truth = {"theta1_dot**2", "cos(theta1)", "theta2_dot**2", "cos(theta2)",
             "theta1_dot*theta2_dot*cos(theta1)*cos(theta2)",
             "theta1_dot*theta2_dot*sin(theta1)*sin(theta2)"}
    print("\n| samples | runs | terms | load (s) | fit (s) | wall (s) | peak RSS (MB) | exact "
          "support | status |\n|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        r["exact"] = set(r["support"]) == truth
        print(f"| {r['samples']:,} | {r['runs']} | {r['terms']} | {r['load_s']:.1f} | "
              f"{r['fit_s']:.1f} | {r['wall_s']:.1f} | {r['peak_rss_bytes'] / 2**20:.0f} | "
              f"{r['exact']} | {r['status']} |")
    if len(rows) > 1:
        slope = np.polyfit(np.log([r["samples"] for r in rows]), np.log([r["fit_s"] for r in rows]),
                           1)[0]
        print(f"\nfit time grows as samples^{slope:.2f}; simulation of the data {sim_s:.0f} s "
              f"(not counted); load average at start {load[0]:.2f}")
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "stream.json").write_text(json.dumps({"rows": rows, "simulation_s": sim_s,
                                                 "load_average": load}, indent=2))
    print(f"written {out / 'stream.json'}")


if __name__ == "__main__":
    main()
