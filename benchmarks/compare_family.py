"""Two ``bench_family.py`` runs of the same starts compared episode by episode.

Pairs each plant and cell of ``--base`` with ``--new`` (several runs, e.g. one per seed, in the
same order on both sides) and prints, per cell: reachable successes before and after, how many
episodes are identical (success, time to upright and track used), in how many the plan took up
the coefficient estimate (``model_released_at``, ``SwingUpMPC(adapt_model=...)``) and which
starts were gained or lost -- and, for the episodes that changed, whether the estimate was in
them (a change without it means the runs differ in something else, e.g. compiled against
uncompiled code).  Writes ``compare.json`` and ``compare.md`` to ``--out``.

    python benchmarks/compare_family.py --out DIR \\
        --base /tmp/before/family.json \\
        --new benchmarks/results/family_60starts.json        # a run before a change, one after
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from _cli import out_folder


def _same(a, b):
    """Whether two episode records agree in success, time to upright and track used."""
    ta, tb = a["time_to_upright"], b["time_to_upright"]
    same_t = ta == tb or (all(isinstance(t, float) and (math.isnan(t) or math.isinf(t))
                              for t in (ta, tb)) and str(ta) == str(tb))
    return a["success"] == b["success"] and same_t and a["track_used"] == b["track_used"]


def _load(path):
    try:
        report = json.loads(Path(path).read_text())
        return report, {(p["mc"], p["mp"], p["L"]): p for p in report["plants"]}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ValueError(f"{path} is not a bench_family.py JSON ({exc})") from None


def compare(base_path, new_path):
    """Rows (one per plant and cell present in both runs) of the comparison, JSON-ready."""
    base_report, base = _load(base_path)
    new_report, new = _load(new_path)
    if base_report.get("seed") != new_report.get("seed"):
        raise ValueError(f"{base_path} and {new_path} have different seeds ({base_report.get('seed')}, "
            f"{new_report.get('seed')}): their starts differ")
    rows = []
    for key, plant in new.items():
        if key not in base:
            continue
        for cell, c_new in plant["cells"].items():
            if cell not in base[key]["cells"]:
                continue
            old, cur = base[key]["cells"][cell]["episodes_detail"], c_new["episodes_detail"]
            if len(old) != len(cur):
                raise ValueError(f"{cell} of plant {key}: {len(old)} episodes against "
                                 f"{len(cur)}")
            changed = [i for i, (a, b) in enumerate(zip(old, cur)) if not _same(a, b)]
            released = [i for i, b in enumerate(cur) if b.get("model_released_at") is not None]
            rows.append({
                "seed": new_report.get("seed"), "plant": list(key), "cell": cell,
                "episodes": len(cur),
                "reachable": sum(b["reachable"] for b in cur),
                "base_reachable_successes": sum(a["success"] and a["reachable"] for a in old),
                "new_reachable_successes": sum(b["success"] and b["reachable"] for b in cur),
                "identical": len(cur) - len(changed), "released": released,
                "released_at": [cur[i]["model_released_at"] for i in released],
                "gained": [i for i in changed if cur[i]["success"] and not old[i]["success"]],
                "lost": [i for i in changed if old[i]["success"] and not cur[i]["success"]],
                "changed_without_estimate": [i for i in changed if i not in released]})
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", nargs="+", required=True, help="bench_family.py JSON(s), before")
    ap.add_argument("--new", nargs="+", required=True, help="the same runs after, in order")
    ap.add_argument("--out", required=True, help="output folder (compare.json, compare.md)")
    args = ap.parse_args(argv)
    if len(args.base) != len(args.new):
        ap.error(f"--base has {len(args.base)} files and --new {len(args.new)}: pair them")
    try:
        rows = [r for b, n in zip(args.base, args.new) for r in compare(b, n)]
    except ValueError as exc:
        ap.error(str(exc))
    out = out_folder(ap, args.out)
    lines = ["| seed | plant | cell | reachable successes | identical | estimate taken up "
             "(start: s) | gained | lost | changed without the estimate |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        rel = ", ".join(f"{i}: {t:.2f}" for i, t in zip(r["released"], r["released_at"]))
        lines.append(
            f"| {r['seed']} | {'/'.join(f'{v:g}' for v in r['plant'])} | "
            f"{r['cell'].split('/')[-1]} | {r['base_reachable_successes']} -> "
            f"{r['new_reachable_successes']}/{r['reachable']} | {r['identical']}/{r['episodes']}"
            f" | {rel or '-'} | {r['gained'] or '-'} | {r['lost'] or '-'} | "
            f"{r['changed_without_estimate'] or '-'} |")
    n = sum(r["episodes"] for r in rows)
    lines.append(f"\n{sum(r['identical'] for r in rows)}/{n} episodes identical; the estimate "
                 f"was taken up in {sum(len(r['released']) for r in rows)}; reachable successes "
                 f"{sum(r['base_reachable_successes'] for r in rows)} -> "
                 f"{sum(r['new_reachable_successes'] for r in rows)}/"
                 f"{sum(r['reachable'] for r in rows)}")
    print("\n".join(lines))
    (out / "compare.md").write_text("\n".join(lines) + "\n")
    (out / "compare.json").write_text(json.dumps(
        {"base": args.base, "new": args.new, "rows": rows}, indent=1))
    print(f"wrote {out / 'compare.md'} and compare.json")


if __name__ == "__main__":
    main()
