"""Mismatched family episodes re-run with the controller built on the plant actually simulated.

The family benchmark's ``mismatch`` cells control a plant whose cart mass, pole mass and pole
length are each off by +-10 % with a controller built on the nominal model (identified).  This
script takes the episodes of one family plant whose mismatch factors follow given sign patterns
(e.g. ``+--``: cart +10 %, pole mass and length -10 %), re-runs each from the same start with a
controller built on the *simulated plant's own exact equations*, and prints both outcomes: where
the second succeeds and the first did not, the shortfall is the model's error, not the plant's
physics.  With ``--plan-only`` the controller is the nominal model's and only its relaxed NLP
(the swing-up plan) runs on the plant's own equations -- the balancer and the online correction
stay the nominal model's: ``SwingUpMPC(nominal, adapt_model=True)`` with the coefficient
estimate held at the plant's own (hand-derived) coefficients.  Writes ``family_true_model.json``
and ``.md`` to ``--out``.

    python benchmarks/family_true_model.py --out DIR --plant 0.8/0.2/0.7 --patterns +--
    python benchmarks/family_true_model.py --out DIR --plant 0.7/0.4/0.8 --patterns +--,++-
    python benchmarks/family_true_model.py --out DIR --plant 0.6/0.2/1.0 --patterns=--+
    python benchmarks/family_true_model.py --out DIR --plant 0.6/0.2/1.0 --patterns=-++ \
        --plan-only

(A pattern that starts with ``-`` needs the ``--patterns=`` form, or argparse takes it for an
option.)
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

from lsindy_cas import systems
from lsindy_cas.control.coefficients import parametric_form
from lsindy_cas.mpc import SwingUpMPC
from lsindy_cas.paper.swingup import Plant, random_starts, run_episode

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the benchmarks' helpers
from _cli import out_folder  # noqa: E402
from bench_family import physical  # noqa: E402

ROOT = Path(__file__).resolve().parent
DEFAULT = ROOT / "results" / "family_60starts.json"
DT = 0.05


def pattern(factors):
    return "".join("+" if f > 1 else "-" for f in factors)


def plan_only(plant, f):
    """The nominal model's controller whose relaxed NLP runs on the plant's own coefficients
    (its Lagrangian's, hand-derived: ``bench_family.physical``)."""
    nominal = systems.cart_pendulum(mc=plant[0], mp=plant[1], L=plant[2])
    ctrl = SwingUpMPC(nominal, dt=DT, adapt_model=True)
    own = physical(plant[0] * f[0], plant[1] * f[1], plant[2] * f[2])
    names = parametric_form(nominal, ["x", "theta"])[2]
    coef = np.array([own[n] for n in names])
    est = ctrl.estimator
    est.update = lambda *transition: None  # held: no estimation

    def reset():
        est.coef = coef.copy()
    est.reset = reset
    return ctrl


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="output folder (family_true_model.json, .md)")
    ap.add_argument("--plant", required=True, help="m_c/m_p/L of a family plant, e.g. 0.8/0.2/0.7")
    ap.add_argument("--patterns", required=True,
                    help="comma-separated sign patterns of the mismatch (cart mass, pole mass, "
                         "pole length), e.g. +--,++- (one starting with '-': --patterns=--+)")
    ap.add_argument("--plan-only", action="store_true",
                    help="only the swing-up plan on the plant's equations (module docstring)")
    ap.add_argument("--json", default=str(DEFAULT),
                    help="the bench_family.py JSON (default: the committed 60-start run, seed 0)")
    args = ap.parse_args(argv)
    pats = [p.strip() for p in args.patterns.split(",") if p.strip()]
    if not pats or not all(re.fullmatch(r"[+-]{3}", p) for p in pats):
        ap.error(f"--patterns must be comma-separated triples of + and -, got {args.patterns!r}")
    try:
        plant = tuple(float(v) for v in args.plant.split("/"))
        if len(plant) != 3:
            raise ValueError
    except ValueError:
        ap.error(f"--plant must be m_c/m_p/L, got {args.plant!r}")
    try:
        data = json.loads(Path(args.json).read_text())
        found = [q for q in data["plants"] if (q["mc"], q["mp"], q["L"]) == plant]
        cells = [v for k, v in found[0]["cells"].items() if k.endswith("/mismatch")] if found \
            else []
        seed = int(data["seed"])
    except (OSError, ValueError, KeyError, IndexError, TypeError) as e:
        ap.error(f"--json {args.json}: not a bench_family.py result ({e})")
    if not cells:
        ap.error(f"--plant {args.plant}: no mismatch cell for it in {args.json}")
    out = out_folder(ap, args.out)
    t0 = time.perf_counter()
    episodes = cells[0]["episodes_detail"]
    starts = random_starts(len(episodes), seed)
    ctrls, rows = {}, []
    for i, e in enumerate(episodes):
        pat = pattern(e["factors"])
        if pat not in pats or not e["reachable"]:
            continue
        f = e["factors"]
        true = systems.cart_pendulum(mc=plant[0] * f[0], mp=plant[1] * f[1], L=plant[2] * f[2])
        if pat not in ctrls:
            ctrls[pat] = (plan_only(plant, f) if args.plan_only else SwingUpMPC(true, dt=DT))
        ep = run_episode(ctrls[pat], Plant(true, DT), starts[i])
        rows.append({"start": i, "pattern": pat, "factors": f, "nominal_model": e["success"],
                     "true_model": bool(ep.success), "track_used": float(ep.track_used)})
        print(f"start {i:2d} {pat}: nominal model {'success' if e['success'] else 'FAILED '}  "
              f"plant's own model {'success' if ep.success else 'FAILED'}", flush=True)
    n = len(rows)
    a = sum(r["nominal_model"] for r in rows)
    b = sum(r["true_model"] for r in rows)
    src = Path(args.json).resolve()
    shown = ("" if src == DEFAULT.resolve() else " --json " + (
        str(src.relative_to(ROOT.parent)) if src.is_relative_to(ROOT.parent) else args.json))
    shown += " --plan-only" if args.plan_only else ""
    own = ("the nominal model with only its swing-up plan on the simulated plant's own equations"
           if args.plan_only else "the simulated plant's own exact equations")
    lines = [f"`python benchmarks/family_true_model.py --out DIR --plant {args.plant} --patterns="
             f"{','.join(pats)}{shown}` ({time.perf_counter() - t0:.0f} s): the reachable mismatched "
             f"episodes of {args.plant} with these sign patterns (cart mass, pole mass, length), "
             f"controller on the nominal identified model (the family run) against one on "
             f"{own}.", "",
             "| start | pattern | nominal model | plant's own model |", "|---|---|---|---|"]
    lines += [f"| {r['start']} | {r['pattern']} | {'yes' if r['nominal_model'] else 'no'} | "
              f"{'yes' if r['true_model'] else 'no'} |" for r in rows]
    lines += ["", f"Successes: nominal model {a}/{n}, plant's own model {b}/{n}."]
    (out / "family_true_model.md").write_text("\n".join(lines) + "\n")
    (out / "family_true_model.json").write_text(json.dumps(
        {"plant": list(plant), "patterns": pats, "episodes": rows,
         "nominal_model_successes": a, "true_model_successes": b, "n": n}, indent=1))
    print("\n".join(lines[-1:]))
    print(f"written: {out / 'family_true_model.md'} and family_true_model.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
