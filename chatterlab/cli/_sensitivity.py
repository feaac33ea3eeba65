"""``chatterlab sensitivity``: which model field raises the minimum
chatter-free width most -- the exact derivatives of the stability limit
(:func:`chatterlab.design.sensitivity`) ranked per relative and per unit
change, as a table, CSV/netCDF and a bar chart.  Widths in mm, speeds in
the process's unit; the derivatives in SI (m per unit of the field)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..errors import check_count
from ..io._files import DATA_SUFFIXES, PLOT_SUFFIXES
from ._common import model_args, outputs, write_result
from ._design_common import lobe_args, lobe_model, refuse_json, speed_args, speeds_and_ceiling

HELP = "exact sensitivities of the stability limit to model fields, ranked (what to stiffen or damp)"


def add_parser(sub: Any) -> None:
    p = sub.add_parser("sensitivity", help=HELP)
    model_args(p)
    speed_args(p)
    p.add_argument(
        "--fields",
        nargs="+",
        metavar="PATH",
        help="parameter paths to differentiate, e.g. spring.holder.c1 beam.table.I (default: every number"
        " of the file's bodies, beams, springs, couplings, absorbers and modes, and each joint's damping)",
    )
    lobe_args(p, verify=False)
    p.add_argument(
        "--terms",
        choices=["pdo", "o"],
        default="pdo",
        help="pdo: all feedback terms (default); o: delayed only",
    )
    p.add_argument(
        "--limit",
        choices=["minimum", "absolute"],
        default="minimum",
        help="rank by the minimum over the speed range (default) or the absolute minimum over all speeds",
    )
    p.add_argument(
        "--by",
        choices=["relative", "unit"],
        default="relative",
        help="rank by p db/dp, the change per relative change of the field (default), or db/dp per unit",
    )
    p.add_argument(
        "--count", type=int, default=20, metavar="N", help="rows of the table printed (default 20)"
    )
    p.add_argument("--out", metavar="FILE.csv|FILE.nc", help="every field's derivatives")
    p.add_argument("--plot", metavar="FILE.png", help="the ranked bar chart")


def run(args: argparse.Namespace) -> int:
    with outputs(args, (args.out, "--out", DATA_SUFFIXES), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:
        return _run(args, outs)


def _run(args: argparse.Namespace, outs: Any) -> int:
    from ..design import sensitivity

    refuse_json(args, "the sensitivities")
    count = check_count(args.count, "--count")
    model = lobe_model(
        args,
        "sensitivities of the milling limit (Floquet multipliers) are not implemented; they are for turning"
        " and shaping models",
    )
    v, wmax = speeds_and_ceiling(args, model)
    s = sensitivity(
        model,
        v,
        fields=args.fields,
        position=args.position,
        width_max=wmax,
        terms=args.terms,
    )
    print(s.table(by=args.by, limit=args.limit, count=count))
    n = len(s.fields)
    if n > count:
        print(f"  ... {n - count} more field(s): --count {n} prints all, --out FILE.csv writes them")
    print(f"  {n} fields, {s.evaluations} model evaluations, {s.elapsed:.2f} s")
    write_result(s, args, outs, command=False, plot=lambda: s.plot(by=args.by, limit=args.limit))
    if s.degenerate:
        print(
            "chatterlab: warning: two boundaries meet at the minimum (a symmetric structure): it has no"
            " derivative there (nan)",
            file=sys.stderr,
        )
        return 1
    return 0
