"""Can the MPC step itself be shipped as C?  Generated SQP (sqpmethod + qrqp) against the running one.

``lsindy export`` ships the identified ODE and its RK4 step as C; this script
answers the follow-up question for the optimisation each MPC step solves.  CasADi can generate C
for ``sqpmethod`` with its own active-set QP solver ``qrqp`` (HPIPM, IPOPT and fatrop are not
code-generated).  The script

1. runs closed-loop swing-up episodes of the default controller (paper plant, exact model) and
   records every warm SQP solve it makes (state, primal and dual warm start);
2. builds the same NLP (the controller's multiple-shooting transcription, Gauss-Newton Hessian)
   with ``sqpmethod`` + ``qrqp``, generates C for it, compiles it with the system C compiler
   (``-O2``) and loads it with ``casadi.external``;
3. replays the recorded solves through (a) the controller's own solver (sqpmethod + HPIPM,
   CasADi's virtual machine), (b) sqpmethod + qrqp in CasADi's virtual machine and (c) the generated
   C of (b), and reports time per solve (median, p90, p99, max) and how far the solutions are apart.

    python benchmarks/bench_mpc_codegen.py --out DIR [--episodes 2]

Times are wall clock in this process; run it alone for numbers to quote (the machine is shared).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

from lsindy_cas.control import shooting
from lsindy_cas.mpc import SwingUpMPC
from lsindy_cas.paper.swingup import random_starts, run_episode, scenario_plant


def _capture_nlp():
    """Make MultipleShootingNLP keep the NLP dict it builds its solvers from (as ``.nlp_dict``)."""
    original = shooting.MultipleShootingNLP._make_solver

    def keep(self, nlp, *args, **kwargs):
        self.nlp_dict = nlp
        return original(self, nlp, *args, **kwargs)

    shooting.MultipleShootingNLP._make_solver = keep
    return lambda: setattr(shooting.MultipleShootingNLP, "_make_solver", original)


def record_solves(ctrl, starts, rng):
    """Run episodes; return the warm solves' inputs (NLP parameters, i.e. the state and the
    input-gain estimate, z0, lam_g0, lam_x0) and HPIPM outputs."""
    nlp = ctrl.nlp
    solve = nlp.solve
    log = []

    def logged(x_init, z0, lam_g0, lam_x0, kind="warm", gain=0.0, ref=None):
        out = solve(x_init, z0, lam_g0, lam_x0, kind, gain, ref)
        if kind == "warm":
            log.append((nlp.parameters(x_init, gain, ref), np.array(z0, float),
                        np.array(lam_g0, float),
                        np.array(lam_x0, float), out[1]))
        return out

    nlp.solve = logged
    episodes = []
    for x0 in starts:
        plant, _ = scenario_plant("nominal", rng, ctrl.dt)
        episodes.append(run_episode(ctrl, plant, x0, rng=rng))
    nlp.solve = solve
    return log, episodes


def qrqp_solver(nlp, max_iter, tol):
    """sqpmethod + qrqp with the controller's Gauss-Newton Hessian: a code-generatable SQP."""
    opts = {"expand": True, "print_time": False, "error_on_fail": False, "qpsol": "qrqp",
            "qpsol_options": {"print_iter": False, "print_header": False, "print_info": False,
                              "error_on_fail": False},
            "max_iter": max_iter, "tol_pr": tol, "tol_du": 10 * tol, "print_header": False,
            "print_iteration": False, "print_status": False, "hess_lag": nlp._gn_hessian}
    return ca.nlpsol("mpc_qrqp", "sqpmethod", nlp.nlp_dict, opts)


def compile_c(solver, folder, cc="gcc"):
    src = Path(folder) / "mpc_qrqp.c"
    t0 = time.perf_counter()
    solver.generate(str(src.name), {"with_header": False})
    shutil.move(src.name, src)
    t_gen = time.perf_counter() - t0
    lib = Path(folder) / "mpc_qrqp.so"
    t0 = time.perf_counter()
    subprocess.run([cc, "-O2", "-shared", "-fPIC", str(src), "-o", str(lib), "-lm"], check=True,
                   capture_output=True)
    return ca.external(solver.name(), str(lib)), t_gen, time.perf_counter() - t0, src.stat().st_size


def replay(fn, nlp, log, solver=None):
    """Time ``fn`` on each recorded solve; return times (ms), solutions and SQP iterations."""
    times, sols, iters = [], [], []
    for x, z0, lg, lx, _ in log:
        t0 = time.perf_counter()
        res = fn(x, z0, lg, lx)
        times.append(1e3 * (time.perf_counter() - t0))
        sols.append(np.asarray(res).ravel())
        if solver is not None:
            iters.append(int(solver.stats().get("iter_count", -1)))
    return np.array(times), np.array(sols), iters


def stats(ms):
    q = np.percentile(ms, [50, 90, 99])
    return {"median": float(q[0]), "p90": float(q[1]), "p99": float(q[2]),
            "max": float(ms.max()), "n": int(ms.size)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="folder for mpc_codegen.json")
    ap.add_argument("--episodes", type=int, default=2, help="recorded episodes (default 2)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--solves", type=int, default=60,
                    help="recorded solves replayed, evenly spaced (default 60; qrqp takes ~1 s each)")
    args = ap.parse_args(argv)
    if args.episodes < 1 or args.solves < 1:
        ap.error("--episodes and --solves must be at least 1")
    if shutil.which("gcc") is None:
        ap.error("needs the system C compiler (gcc)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    restore = _capture_nlp()
    try:
        ctrl = _paper_controller()
    finally:
        restore()
    nlp = ctrl.nlp
    print(f"recording warm solves over {args.episodes} episode(s) ...", flush=True)
    log, eps = record_solves(ctrl, random_starts(args.episodes, args.seed),
                             np.random.default_rng([args.seed, 7]))
    print(f"  {len(log)} warm solves, success {sum(e.success for e in eps)}/{len(eps)}")
    n_rec = len(log)
    keep = np.unique(np.linspace(0, n_rec - 1, min(args.solves, n_rec)).round().astype(int))
    log = [log[i] for i in keep]
    max_iter = nlp.max_iters["warm"]
    qr = qrqp_solver(nlp, max_iter, ctrl_tol(ctrl))
    with tempfile.TemporaryDirectory() as tmp:
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            gen, t_gen, t_cc, size = compile_c(qr, tmp)
        finally:
            os.chdir(cwd)
        bounds = dict(lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg)

        def casadi_call(solver):
            return lambda x, z0, lg, lx: solver(x0=z0, p=x, lam_g0=lg, lam_x0=lx, **bounds)["x"]

        def hpipm(x, z0, lg, lx):
            return nlp.solvers["warm"](x0=z0, p=x, lam_g0=lg, lam_x0=lx, **bounds)["x"]

        rows = {}
        for name, fn, solver in (
                ("sqpmethod+HPIPM (controller, CasADi VM)", hpipm, nlp.solvers["warm"]),
                ("sqpmethod+qrqp (CasADi VM)", casadi_call(qr), qr),
                ("sqpmethod+qrqp (generated C, gcc -O2)", casadi_call(gen), None)):
            replay(fn, nlp, log[:2])                           # warm caches
            ms, sols, iters = replay(fn, nlp, log, solver)
            st = stats(ms)
            if iters:
                st["sqp_iterations_median"] = float(np.median(iters))
            rows[name] = (st, sols)
            print(f"  {name}: median {np.median(ms):.2f} ms, p99 {np.percentile(ms, 99):.2f} ms")
    ref = rows["sqpmethod+qrqp (CasADi VM)"][1]
    hp = rows["sqpmethod+HPIPM (controller, CasADi VM)"][1]
    c = rows["sqpmethod+qrqp (generated C, gcc -O2)"][1]
    first = nlp._ic[0]
    report = {
        "episodes": args.episodes, "warm_solves_recorded": n_rec, "replayed": len(log), "max_iter": max_iter,
        "generate_s": round(t_gen, 2), "compile_s": round(t_cc, 2), "c_bytes": size,
        "loadavg": os.getloadavg(),
        "solve_ms": {k: v[0] for k, v in rows.items()},
        "max_abs_diff_C_vs_VM": float(np.max(np.abs(c - ref))),
        "first_force_max_diff_qrqp_vs_hpipm": float(np.max(np.abs(ref[:, first] - hp[:, first]))),
        "first_force_median_diff_qrqp_vs_hpipm": float(np.median(np.abs(ref[:, first]
                                                                         - hp[:, first]))),
    }
    lines = ["| solver | median (ms) | p90 (ms) | p99 (ms) | max (ms) | SQP iterations (median) |",
             "|---|---|---|---|---|---|"]
    for k, (s, _) in rows.items():
        it = s.get("sqp_iterations_median", "same as VM")
        lines.append(f"| {k} | {s['median']:.2f} | {s['p90']:.2f} | {s['p99']:.2f} | "
                     f"{s['max']:.2f} | {it} |")
    print()
    print("\n".join(lines))
    print(f"\nC vs CasADi VM (same algorithm): max |Δz| = {report['max_abs_diff_C_vs_VM']:.1e}; "
          f"first force qrqp vs HPIPM: median |Δ| {report['first_force_median_diff_qrqp_vs_hpipm']:.2e}"
          f" N, max {report['first_force_max_diff_qrqp_vs_hpipm']:.2e} N; generate {t_gen:.1f} s, "
          f"gcc {t_cc:.1f} s, {size / 1e3:.0f} kB of C")
    (out / "mpc_codegen.json").write_text(json.dumps(report, indent=2))
    (out / "mpc_codegen.md").write_text("\n".join(lines) + "\n")
    print(f"written to {out / 'mpc_codegen.json'}")
    return 0


def ctrl_tol(ctrl):
    """The controller's SQP tolerance (``tol`` of MPCController, default 1e-4)."""
    return float(getattr(ctrl, "tol", 1e-4))


def _paper_controller():
    from lsindy_cas.paper.swingup import identify_cart_pendulum
    model, _ = identify_cart_pendulum()
    return SwingUpMPC(model)


if __name__ == "__main__":
    raise SystemExit(main())
