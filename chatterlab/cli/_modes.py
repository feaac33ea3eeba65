"""``chatterlab modes``: natural frequencies and mode shapes at a frozen configuration."""

from __future__ import annotations

import argparse
import sys
from typing import Any, Literal

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
        rigid: Literal["report", "error"] = "report" if args.allow_rigid else "error"
        md = modes(sy, count=args.count, position=args.position, rigid=rigid)
        # a model with beams: the same modes on the mesh twice as fine (None: no beams)
        fine = _fine_frequencies(sy.model, md, args.position, rigid)
        out = outs.path(args.out) if args.out else None
        if args.format == "json":
            from ..io._files import json_text

            doc = md.to_dict()
            if fine is not None:
                doc["mesh"] = _mesh_doc(sy.model, md.frequency_hz, fine)
            emit(json_text(doc), out)
        elif args.format == "csv":
            md.to_csv(out or sys.stdout)
        else:
            pos = "" if md.position is None else f" at position s = {md.position:g} m"
            table = md.table() if fine is None else _mesh_table(sy.model, md, fine)
            emit(f"{sy.model.name}: natural frequencies{pos}\n" + table, out)
        if args.plot:
            _plot(sy.model, md, outs.path(args.plot))
    return 0


def _fine_frequencies(model: Any, md: Any, position: Any, rigid: Literal["report", "error"]) -> Any:
    """The natural frequencies (Hz) of the modes listed, on the mesh twice as
    fine (None for a model without beams).  Modes are matched by their rank
    (the k-th lowest on both meshes)."""
    if not model.beams:
        return None
    from ..structure._assembly import assemble
    from ..structure._modal import modes

    fm = modes(assemble(model.with_finer_mesh()), count=len(md), position=position, rigid=rigid)
    return fm.frequency_hz[: len(md)]


def _mesh_doc(model: Any, f: Any, fine: Any) -> dict[str, Any]:
    """The ``mesh`` member of ``--format json`` (docs/cli.md)."""
    from ..model._mesh import MeshEstimate, mesh_record

    e = MeshEstimate(f[: len(fine)], fine)
    return {
        **mesh_record(model, prefix=""),
        "fine_frequency_hz": [float(x) for x in fine],
        "change_hz": [float(x) for x in e.change],
        "error_bound_hz": [float(x) for x in e.bound],
    }


def _mesh_table(model: Any, md: Any, fine: Any) -> str:
    """The table with two columns more: each frequency's change on the mesh
    twice as fine and the bound of its discretisation error (docs/lobes.md,
    Eq. M3), in % of f; and one line saying so."""
    from ..model._mesh import MeshEstimate, mesh_words

    e = MeshEstimate(md.frequency_hz[: len(fine)], fine)
    lines = md.table().split("\n")
    lines[0] += f"  {'df(h/2)':>8}  {'err <=':>7}"
    for k in range(len(fine)):
        lines[k + 1] += f"  {e.relative_change[k]:>+8.2%}  {e.relative_bound[k]:>7.2%}"
    head = (
        f"mesh: {mesh_words(model)}; df(h/2): change of f on a mesh twice as fine; err: its discretisation"
        " error on this mesh, <= 2 |df| (docs/lobes.md, Eq. M3)"
    )
    return head + "\n" + "\n".join(lines)


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
