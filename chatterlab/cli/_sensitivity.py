"""``chatterlab sensitivity``: which model field raises the minimum
chatter-free width most -- the exact derivatives of the stability limit
(:func:`chatterlab.design.sensitivity`) ranked per relative and per unit
change, as a table, CSV/netCDF and a bar chart.  Widths in mm, speeds in
the process's unit; the derivatives in SI (m per unit of the field)."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from ..errors import InputError, check_count
from ..io._files import DATA_SUFFIXES, PLOT_SUFFIXES
from ._common import model_args, outputs, write_result
from ._design_common import (
    lobe_args,
    lobe_model,
    refuse_json,
    speed_args,
    speeds_and_ceiling,
    with_attributes,
)

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
    if args.limit == "minimum" and not math.isfinite(float(s.minimum["width"])):
        raise InputError(
            f"{model.source}: no limit below --width-max {wmax * 1e3:.4g} mm in the speed range: nothing to"
            " rank by its minimum; raise --width-max, or rank by --limit absolute"
        )
    print(s.table(by=args.by, limit=args.limit, count=count))
    n = len(s.fields)
    if n > count:
        print(f"  ... {n - count} more field(s): --count {n} prints all, --out FILE.csv writes them")
    print(f"  {n} fields, {s.evaluations} model evaluations, {s.elapsed:.2f} s")
    result: Any = s
    mesh = _mesh(s, model, v, args, wmax, min(count, n))
    if mesh is not None:  # a model with beams: the limit and the ranking on the mesh twice as fine
        print("\n".join(f"  {ln}" for ln in mesh[0]))
        result = with_attributes(s, mesh[1])
    write_result(result, args, outs, command=False, plot=lambda: s.plot(by=args.by, limit=args.limit))
    if s.degenerate:
        print(
            "chatterlab: warning: two boundaries meet at the minimum (a symmetric structure): it has no"
            " derivative there (nan)",
            file=sys.stderr,
        )
        return 1
    return 0


def _mesh(s: Any, model: Any, speeds: Any, args: argparse.Namespace, wmax: float, k: int) -> Any:
    """A model with beams (else None): the limit ranked by on the mesh twice as
    fine (:meth:`Model.with_finer_mesh`) by :func:`chatterlab.model._mesh.limit_line`
    (its change and the bound of its error, docs/lobes.md Eq. M3), and the
    ``k`` fields the table prints, differentiated again there and ranked
    among themselves by the same key: whether their order survives, and
    which move.  Only those fields are differentiated twice (a field outside
    them that would enter the top on h/2 is not looked for).  Returns the
    summary's lines and the files' ``mesh_*`` attributes."""
    if not model.beams or k < 1:
        return None
    import json
    import time

    import numpy as np

    from ..design import sensitivity
    from ..model._mesh import MeshEstimate, limit_line, mesh_record, pct

    t0 = time.perf_counter()
    top = [s.fields[i] for i in s.ranked(args.by, args.limit)[:k]]
    fs = sensitivity(model.with_finer_mesh(), speeds, fields=top, position=args.position, width_max=wmax,
                     terms=args.terms)  # fmt: skip
    name = "minimum" if args.limit == "minimum" else "absolute minimum"
    b, b2 = s.width(args.limit), fs.width(args.limit)
    lines = [limit_line(model, name, b, b2)]
    fine_order = [fs.fields[i] for i in fs.ranked(args.by, args.limit)]
    ranks = [fine_order.index(f) + 1 for f in top]
    key = "p db/dp" if args.by == "relative" else "db/dp"
    coarse_key = (s.relative if args.by == "relative" else s.derivative)(args.limit)
    fine_key = (fs.relative if args.by == "relative" else fs.derivative)(args.limit)
    idx = [s.fields.index(f) for f in top]
    with np.errstate(invalid="ignore", divide="ignore"):
        change = np.abs(MeshEstimate(coarse_key[idx], fine_key).relative_change)
    worst = float(np.nanmax(change)) if np.any(np.isfinite(change)) else float("nan")
    moved = [f"{f} {i + 1} -> {r}" for i, (f, r) in enumerate(zip(top, ranks, strict=True)) if r != i + 1]
    what = f"the top {k} field{'s' * (k != 1)}"
    if fs.degenerate or s.degenerate:
        lines.append(f"mesh: {what}: two boundaries meet at the minimum on a mesh: no ranking to compare")
    elif not moved:
        lines.append(
            f"mesh: {what} keep their order on the mesh twice as fine (ranked among themselves by {key};"
            f" their {key} change by up to {pct(worst)})"
        )
    else:
        lines.append(
            f"mesh: {what} change order on the mesh twice as fine (ranked among themselves by {key}):"
            f" {', '.join(moved)}; their {key} change by up to {pct(worst)}"
        )
    e = MeshEstimate(b, b2)
    meta: dict[str, Any] = {
        **mesh_record(model),
        "mesh_fine_width_m": b2,
        "mesh_width_change": float(e.relative_change),
        "mesh_width_error_bound": float(e.relative_bound),
        "mesh_top_fields": json.dumps(top),
        "mesh_fine_ranks": json.dumps(ranks),
        "mesh_ranking_same": "true" if not moved and not (fs.degenerate or s.degenerate) else "false",
        "mesh_top_change_max": worst,
        "mesh_seconds": time.perf_counter() - t0,
        "mesh": " | ".join(lines),
    }
    return lines, meta
