"""``chatterlab check``: validate a model file and summarise it."""

from __future__ import annotations

import argparse
from typing import Any

from ..io._files import json_text
from ._common import emit, load, model_args


def add_parser(sub: Any) -> None:
    c = sub.add_parser("check", help="validate a model file and summarise it")
    model_args(c)
    c.add_argument("--format", choices=["table", "json"], default="table")


def run(args: argparse.Namespace) -> int:
    from ..structure._assembly import assemble

    model = load(args)
    if model.frf is not None:  # a measured FRF: no matrices to assemble, checked as lobes reads it
        from ..lobes._measured import model_frf_summary

        summ = model_frf_summary(model)
        rows = _frf_rows(summ)
    else:
        summ = assemble(model).summary()
        rows = _rows(model, summ)
    if args.format == "json":
        emit(json_text(summ), None)
        return 0
    print(f"{model.source}: OK  ({model.name}{', variant ' + model.variant if model.variant else ''})")
    for k, v in rows + _process_rows(model):
        print(f"  {k:<26} {v}")
    return 0


def _frf_rows(summ: dict[str, Any]) -> list[tuple[str, Any]]:
    lo, hi = summ["band [Hz]"]
    cuts = "; ".join(f"{k} on {', '.join(v)}" for k, v in summ["couplings"].items()) or "none"
    return [
        ("structure", f"measured FRF {summ['file']} ({summ['format']}, {summ['units']}, {summ['quantity']})"),
        ("frequencies", f"{summ['frequencies']}, {lo:g} .. {hi:g} Hz"),
        ("outputs", ", ".join(summ["outputs"])),
        ("inputs", ", ".join(summ["inputs"])),
        ("coherence", "yes" if summ["coherence"] else "no"),
        ("coupling elements (CE)", cuts),
    ]


def _rows(model: Any, summ: dict[str, Any]) -> list[tuple[str, Any]]:
    rows = [
        ("rigid bodies (RFE)", summ["bodies"]),
        ("moving contact points", summ["contacts"]),
        ("beams (DFE) / elements", f"{summ['beams']} / {summ['beam elements']}"),
        ("nodes", summ["nodes"]),
        ("springs (SDE)", summ["springs"]),
        ("rigid attachments", summ["attachments"]),
        ("coupling elements (CE)", summ["couplings"]),
        ("coordinates", summ["coordinates"]),
        ("  independent q_i", summ["independent"]),
        ("  dependent q_d", summ["dependent"]),
        ("  given q_g", summ["given"]),
    ]
    if model.movable is not None:
        mv = model.movable
        rows.append(("movable bodies", ", ".join(mv.bodies)))
        rows.append(("position / range [m]", f"{mv.position:g} / [{mv.range[0]:g}, {mv.range[1]:g}]"))
    return rows


def _process_rows(model: Any) -> list[tuple[str, Any]]:
    if model.process is None:
        return []
    pr = model.process
    return [("process", f"{pr.kind}, {pr.speed_name} {pr.speed:g} {pr.speed_unit}, T = {pr.delay():.6g} s")]
