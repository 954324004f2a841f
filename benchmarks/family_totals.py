"""``bench_family.py`` runs of different seeds (different starts) summed per plant and cell.

Each run holds 60 starts per plant; the per-run share of a cell rests on ~40-60 episodes, so one
episode moves it by ~2 %.  This script adds the runs up: per plant and cell, the reachable
successes of every run and their sum, its share and whether it is at least 95 %.  Writes
``family_totals.json`` and ``family_totals.md`` to ``--out``.

    python benchmarks/family_totals.py --out DIR --json \\
        benchmarks/results/family_60starts.json benchmarks/results/family_seed1_all.json \\
        benchmarks/results/family_seed2_all.json benchmarks/results/family_seed3_all.json
"""

from __future__ import annotations

import argparse
import json

from _cli import out_folder
from compare_family import _load

TARGET = 0.95


def totals(paths):
    """Rows (one per plant and cell present in every run), JSON-ready; runs of one seed twice
    are refused (the same starts would count twice)."""
    runs = [_load(p) for p in paths]
    seeds = [report.get("seed") for report, _ in runs]
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"the runs must have different seeds (the same starts would count "
                         f"twice), got seeds {seeds}")
    rows = []
    for key, plant in runs[0][1].items():
        if not all(key in plants for _, plants in runs):
            continue
        for cell in plant["cells"]:
            if not all(cell in plants[key]["cells"] for _, plants in runs):
                continue
            per = []
            for _, plants in runs:
                eps = plants[key]["cells"][cell]["episodes_detail"]
                per.append([sum(e["success"] and e["reachable"] for e in eps),
                            sum(e["reachable"] for e in eps)])
            s, n = sum(p[0] for p in per), sum(p[1] for p in per)
            rows.append({"plant": list(key), "cell": cell, "per_run": per, "successes": s,
                         "reachable": n, "share": s / n if n else None,
                         "at_target": bool(n and s / n >= TARGET)})
    return seeds, rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", nargs="+", required=True, help="bench_family.py JSONs, one per seed")
    ap.add_argument("--out", required=True, help="output folder (family_totals.json, .md)")
    args = ap.parse_args(argv)
    try:
        seeds, rows = totals(args.json)
    except ValueError as exc:
        ap.error(str(exc))
    out = out_folder(ap, args.out)
    lines = [f"| plant | cell | reachable successes, seeds {' / '.join(map(str, seeds))} | "
             f"together | >= 95 % |", "|---|---|---|---|---|"]
    for r in rows:
        share = "-" if r["share"] is None else f"{100 * r['share']:.1f} %"
        lines.append(f"| {'/'.join(f'{v:g}' for v in r['plant'])} | {r['cell'].split('/')[-1]} "
                     f"| {' / '.join(f'{s}/{n}' for s, n in r['per_run'])} | "
                     f"{r['successes']}/{r['reachable']} ({share}) | "
                     f"{'yes' if r['at_target'] else '**no**'} |")
    met = sum(r["at_target"] for r in rows)
    lines.append(f"\n{met} of {len(rows)} plant cells at >= 95 % of their reachable episodes "
                 f"over seeds {', '.join(map(str, seeds))}")
    print("\n".join(lines))
    (out / "family_totals.md").write_text("\n".join(lines) + "\n")
    (out / "family_totals.json").write_text(json.dumps(
        {"runs": args.json, "seeds": seeds, "target": TARGET, "rows": rows}, indent=1))
    print(f"wrote {out / 'family_totals.md'} and family_totals.json")


if __name__ == "__main__":
    main()
