"""``lsindy reproduce``: the paper's Table I and figures."""
from __future__ import annotations

import json
import sys

from ._common import command

REPRODUCE_EXAMPLE = """example:
  lsindy reproduce --out results      # ~1 min: results/table1.md, fig3_complexity.png,
                                      # fig4_extrapolation.png, baselines.md (+ JSON)
Exit status 0 when every Table I model has the exact support and the figures show the paper's
claims (ours sparsest; our extrapolation error below SINDy's).  Without the optional pysindy the
figures are drawn without the SINDy baseline (the output says so)."""


def run(args) -> int:
    from pathlib import Path

    from ..paper.table1 import markdown, table_one, write_table
    say = lambda msg: print(msg, file=sys.stderr)  # noqa: E731
    cells = table_one(progress=say)
    print(markdown(cells))
    md, js = write_table(cells, Path(args.out))
    print(f"\nTable I written to {md} and {js}")
    ok = all(c.exact_support and c.lagrangian_exact_support for c in cells)
    if args.no_figures:
        return 0 if ok else 1
    from ..paper.baselines import require_pysindy
    from ..paper.comparison import claims
    from ..paper.figures import make_figures
    try:                                   # pysindy (the SINDy baseline) is an optional extra
        require_pysindy()
        sindy = True
    except ImportError as exc:
        say(f"lsindy reproduce: SINDy (Lasso) baseline columns skipped in Figs. 3-4 and "
            f"baselines.md: {exc}")
        sindy = False
    paths = make_figures(Path(args.out), cells=cells, progress=say,
                         echo=lambda text: print("\n" + text), sindy=sindy)
    print("\nfigures and numbers written to " + ", ".join(str(p) for p in paths))
    failed = claims(json.loads(paths[-1].read_text()))
    for msg in failed:
        say(f"lsindy reproduce: claim not reproduced: {msg}")
    return 0 if ok and not failed else 1


def add_to(sub) -> None:
    """Add the subcommand to the ``lsindy`` parser's subparsers."""
    rep = command(sub, "reproduce", "the paper's Table I and Figs. 3-4, printed and saved",
                   "Identify the three benchmark systems as in the paper "
                         "(Table I), compare with SINDy (Lasso, via pysindy) and KRONIC (Fig. 3: model "
                         "complexity; Fig. 4: extrapolation), print the numbers and write tables "
                         "and PNG figures.",
                   REPRODUCE_EXAMPLE)
    rep.add_argument("--out", default="results", help="output directory (default: results)")
    rep.add_argument("--no-figures", action="store_true",
                     help="only Table I (skip the baselines and figures; the SINDy baseline needs "
                     "pysindy and is left out without it)")
    rep.set_defaults(func=run)
