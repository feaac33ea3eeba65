"""``chatterlab roots``: the rightmost characteristic roots and the stability
verdict of one cut (width b, speed or delay T).

Where a new kind of input plugs in: ``_verdict`` computes the result for
what the command line names (today: a model file with a cutting process);
a milling process or a measured FRF (``--frf FILE``) is a branch there that
returns a result with the same ``table()`` / ``to_dict()``, and ``run``
writes it unchanged.
"""

from __future__ import annotations

import argparse
from typing import Any

from ..errors import InputError
from ..io._files import json_text
from ._common import FORMAT_SUFFIXES, cut_args, emit, frozen, load, model_args, outputs, warn, width_m


def add_parser(sub: Any) -> None:
    r = sub.add_parser("roots", help="rightmost characteristic roots and the stability verdict at (b, T)")
    model_args(r)
    cut_args(r, required_width=True)
    r.add_argument("--count", type=int, default=6, metavar="K", help="number of rightmost roots (default 6)")
    r.add_argument("--position", metavar="S", help="slide position s, m")
    r.add_argument("--format", choices=["table", "json"], default="table")
    r.add_argument("--out", metavar="FILE")
    r.add_argument("--no-winding", action="store_true", help="skip the argument-principle cross-check")
    r.add_argument(
        "--method",
        choices=["spectral", "sdm"],
        help="milling models: Floquet multipliers by spectral elements (default) or semi-discretisation",
    )
    r.add_argument("--steps", type=int, default=40, metavar="M", help="milling, sdm: steps per period")


def run(args: argparse.Namespace) -> int:
    with outputs(args, (args.out, "--out", FORMAT_SUFFIXES[args.format])) as outs:
        st = _verdict(args)
        out = outs.path(args.out) if args.out else None
        if args.format == "json":
            emit(json_text(st.to_dict()), out)
        else:
            emit(st.table(), out)
    return 0


def _verdict(args: argparse.Namespace) -> Any:
    """The stability result of the cut the command line names (a model file)."""
    from ..frequency._stability import stability

    warn(args, terms_slips(args))
    model = load(args)
    if model.process is not None and model.process.kind == "milling":
        from ._milling import milling_verdict

        return milling_verdict(args, model)
    if args.method is not None:
        raise InputError(f'--method {args.method} is for milling models ([process] kind = "milling")')
    fz = frozen(args)
    b = width_m(args)

    def verdict(f: Any) -> Any:
        return stability(
            f,
            width=b,
            speed=args.speed,
            delay=args.delay,
            terms=args.terms,
            count=args.count,
            winding=not args.no_winding,
        )

    st = verdict(fz)
    if not model.beams:
        return st
    # a model with beams: the same cut on the mesh twice as fine; a claim that
    # mesh (or the margin's discretisation error) contradicts is undetermined
    from ..frequency._stability import mesh_checked
    from ..structure._assembly import assemble

    return mesh_checked(st, verdict(assemble(model.with_finer_mesh()).at(args.position)), model)


def terms_slips(args: argparse.Namespace) -> list[str]:
    """--delay or --speed given with --terms pd, which has no delayed term."""
    if getattr(args, "terms", "pdo") == "pd" and (args.delay is not None or args.speed is not None):
        opt = "--delay" if args.delay is not None else "--speed"
        return [f"{opt} has no effect with --terms pd (no delayed term); use --terms pdo or o for the delay"]
    return []
