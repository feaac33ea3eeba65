"""``chatterlab modes``: natural frequencies and mode shapes at a frozen configuration."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..io._files import PLOT_SUFFIXES
from ._common import FORMAT_SUFFIXES, emit, load, model_args, outputs


def add_parser(sub: Any) -> None:
    m = sub.add_parser("modes", help="natural frequencies and mode shapes at a frozen configuration")
    model_args(m)
    m.add_argument("--position", metavar="S", help="slide position s, m (default: the model's)")
    m.add_argument("--count", type=int, metavar="N", help="number of lowest modes (default: all)")
    m.add_argument("--format", choices=["table", "json", "csv"], default="table")
    m.add_argument("--out", metavar="FILE", help="write to FILE instead of standard output")
    m.add_argument(
        "--plot",
        metavar="FILE.png",
        help="the mode shapes on the structure (a bar chart of the frequencies for a model without geometry)",
    )
    m.add_argument(
        "--allow-rigid", action="store_true", help="report rigid-body modes instead of refusing them"
    )


def run(args: argparse.Namespace) -> int:
    from ..structure._assembly import assemble
    from ..structure._modal import modes

    with outputs(
        args, (args.out, "--out", FORMAT_SUFFIXES[args.format]), (args.plot, "--plot", PLOT_SUFFIXES)
    ) as outs:
        sy = assemble(load(args))
        md = modes(
            sy, count=args.count, position=args.position, rigid="report" if args.allow_rigid else "error"
        )
        out = outs.path(args.out) if args.out else None
        if args.format == "json":
            emit(md.to_json(), out)
        elif args.format == "csv":
            md.to_csv(out or sys.stdout)
        else:
            pos = "" if md.position is None else f" at position s = {md.position:g} m"
            emit(f"{sy.model.name}: natural frequencies{pos}\n" + md.table(), out)
        if args.plot:
            _plot(sy.model, md, outs.path(args.plot))
    return 0


def _plot(model: Any, md: Any, path: str) -> None:
    """Every mode listed (the --count lowest) drawn on the structure; a model
    without geometry (a matrix or modal table): its frequencies as labelled bars."""
    from ..plot import plot_frequencies, plot_mode_shapes, savefig

    if model.is_matrix_model:
        pos = "" if md.position is None else f", s = {md.position:g} m"
        title = f"{model.name}: natural frequencies of the {len(md)} mode{'s' * (len(md) != 1)}{pos}"
        ax = plot_frequencies(md.frequency_hz, damping_ratio=md.damping_ratio, title=title)
    else:
        ax = plot_mode_shapes(md.drawing(), modes=range(len(md)))
    savefig(ax, path)
