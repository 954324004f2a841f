"""The family benchmark split by whether the simulated plant can reverse its cart inside the band.

Where one push's kick is so large that the pushes must alternate, the cart creeps at a speed
the start fixes (``bench_cart_phase.py``), and reversing that creep takes two pushes of one sign;
between them the pole's rate must turn round, which it does only at a lean of ``turn_lean =
(kick - 0.5) / omega`` or more.  Where that exceeds the success band's 0.1 rad, every reversal
leaves the band (:func:`lsindy_cas.control.cart_pendulum.upright.reversal_margin` checks it exactly, a linear
program on the plant's own upright linearisation with the band at 5 instants per period as
success is judged and the pushes at most 1 s apart), so no controller keeps such a pole in the
band once the track forces a reversal: its 10 s success is a matter of when that falls, and such
episodes are not "out of reach" (a viability kernel is not empty) but limited by the physics.

This script reads a ``bench_family.py`` JSON (default: the committed 60-start run), rebuilds
each episode's simulated plant from its mismatch factors, classifies it (``unreachable``: empty
kernel, as in the benchmark; ``no reversal in band``; ``reversal in band``) and prints success
per plant, scenario and class; writes ``family_reversal.json`` and ``.md`` to ``--out``.

    python benchmarks/family_reversal.py --out DIR                    # ~1 min
    python benchmarks/family_reversal.py --out DIR --json other/family.json
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path

import numpy as np

from lsindy_cas import systems
from lsindy_cas.control.ocp import rk4_step
from lsindy_cas.control.cart_pendulum.sequence_balancer import SequenceBalancer
from lsindy_cas.control.cart_pendulum.upright import reversal_margin

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the benchmarks' helpers
from _cli import out_folder  # noqa: E402

ROOT = Path(__file__).resolve().parent
DEFAULT = ROOT / "results" / "family_60starts.json"
DT, LEVELS = 0.05, np.array([-10.0, 0.0, 10.0])
CLASSES = ("reversal in band", "no reversal in band", "unreachable")


@functools.lru_cache(maxsize=None)
def plant_class(mc, mp, L):
    """``(turn_lean, reversal margin)`` of the exact plant (margin > 0: a reversal within 1 s
    stays inside the success band shrunk by that share)."""
    ode = systems.cart_pendulum(mc=mc, mp=mp, L=L).ode()
    b = SequenceBalancer(rk4_step(ode, 4, 2, DT, 1), ode, LEVELS, cart_index=0, pole_index=1,
                         upright=np.pi, track_limit=2.0, dt=DT, viability=False)
    return float(b.turn_lean), float(reversal_margin(b))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="output folder (family_reversal.json, .md)")
    ap.add_argument("--json", default=str(DEFAULT),
                    help="a bench_family.py JSON (default: the committed 60-start run)")
    args = ap.parse_args(argv)
    try:
        data = json.loads(Path(args.json).read_text())
        plants = data["plants"]
        _ = [c["episodes_detail"][0]["factors"] for p in plants for c in p["cells"].values()]
    except (OSError, ValueError, KeyError, IndexError, TypeError) as e:
        ap.error(f"--json {args.json}: not a bench_family.py result with episodes ({e})")
    out = out_folder(ap, args.out)
    t0 = time.perf_counter()
    rows, totals = [], {}
    for p in plants:
        for cell, c in p["cells"].items():
            scenario = cell.rsplit("/", 1)[-1]
            counts = {k: [0, 0] for k in CLASSES}
            leans, margins = [], []
            for e in c["episodes_detail"]:
                f = e["factors"]
                lean, margin = plant_class(round(p["mc"] * f[0], 12), round(p["mp"] * f[1], 12),
                                           round(p["L"] * f[2], 12))
                leans.append(lean)
                margins.append(margin)
                inside = margin > 0.0
                k = ("unreachable" if not e["reachable"]
                     else "reversal in band" if inside else "no reversal in band")
                counts[k][0] += bool(e["success"])
                counts[k][1] += 1
                tot = totals.setdefault((cell, k), [0, 0])
                tot[0] += bool(e["success"])
                tot[1] += 1
            rows.append({"plant": [p["mc"], p["mp"], p["L"]], "cell": cell,
                         "scenario": scenario, "turn_lean_range": [min(leans), max(leans)],
                         "margin_range": [min(margins), max(margins)],
                         "counts": counts})
            print(f"{p['mc']}/{p['mp']}/{p['L']} {cell}: " + ", ".join(
                f"{k} {s}/{n}" for k, (s, n) in counts.items() if n), flush=True)
    frac = lambda s, n: f"{s}/{n}" if n else "-"  # noqa: E731
    rng = lambda lo, hi: f"{lo:.3f}" + (f" to {hi:.3f}" if hi - lo > 5e-4 else "")  # noqa: E731
    src = Path(args.json).resolve()
    shown = (str(src.relative_to(ROOT.parent)) if src.is_relative_to(ROOT.parent)
             else str(args.json))
    lines = [f"`python benchmarks/family_reversal.py --out DIR --json {shown}` "
             f"({time.perf_counter() - t0:.0f} s): the episodes of `{Path(args.json).name}` by "
             "whether the plant simulated can reverse its cart's creep inside the success band "
             "(turn_lean = (kick - 0.5)/omega near 0.1 rad or below; checked exactly by a linear "
             "program on its upright linearisation, the band at 5 instants per period as "
             "success is judged, the two pushes at most 1 s apart; margin: the share by which "
             "the band could shrink with such a reversal still inside). `unreachable`: empty "
             "viability kernel, as in the benchmark.",
             "", "| plant | cell | turn_lean (rad) | margin | reversal in band | "
             "no reversal in band | unreachable | reversal in band >= 95 % |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        cnt = r["counts"]
        s, n = cnt["reversal in band"]
        lines.append(f"| {'/'.join(f'{v:g}' for v in r['plant'])} | {r['cell']} | "
                     f"{rng(*r['turn_lean_range'])} | {rng(*r['margin_range'])} | "
                     + " | ".join(frac(*cnt[k]) for k in CLASSES)
                     + f" | {'yes' if n and s >= 0.95 * n else ('-' if not n else 'no')} |")
    lines += ["", "Totals:", ""]
    for (cell, k), (s, n) in sorted(totals.items()):
        if n:
            lines.append(f"- {cell}, {k}: {s}/{n} ({100 * s / n:.1f} %)")
    (out / "family_reversal.md").write_text("\n".join(lines) + "\n")
    (out / "family_reversal.json").write_text(json.dumps(
        {"source": shown, "rows": rows,
         "totals": [{"cell": cell, "class": k, "successes": s, "episodes": n}
                    for (cell, k), (s, n) in sorted(totals.items())]}, indent=1))
    print("\n".join(lines))
    print(f"written: {out / 'family_reversal.md'} and family_reversal.json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
