"""``chatterlab absorber``: tune vibration absorbers against chatter
(:func:`chatterlab.design.tune_absorbers`) -- the model's ``[[absorber]]``
items, or one added at ``--at POINT`` -- and say what they buy: the tuned
mass, frequency and damping, the minimum limit before and after and with
Den Hartog's classical tuning, the lobes before and after on one plot.
Widths in mm, frequencies in Hz, masses in kg, speeds in the process's unit."""

from __future__ import annotations

import argparse
from typing import Any

from ..errors import InputError, check_count, check_positive
from ..io._files import DATA_SUFFIXES, PLOT_SUFFIXES
from ._common import model_args, outputs, write_result
from ._design_common import (
    design_mesh,
    lobe_args,
    lobe_model,
    objective_arg,
    refuse_json,
    speed_args,
    speeds_and_ceiling,
    verified_status,
)

HELP = "tune vibration absorbers to maximise the minimum chatter-free width; lobes before and after"


def add_parser(sub: Any) -> None:
    p = sub.add_parser("absorber", help=HELP)
    model_args(p)
    speed_args(p)
    p.add_argument(
        "--at",
        metavar="POINT",
        help="add an absorber at this point (a [[point]], body, node or contact name), named 'tva';"
        " default: tune the file's [[absorber]] items",
    )
    g = p.add_mutually_exclusive_group()
    g.add_argument("--direction", choices=["x", "y"], help="the added absorber's direction")
    g.add_argument(
        "--angle", type=float, metavar="DEG", help="the added absorber's direction, degrees from X"
    )
    p.add_argument("--mass", type=float, metavar="KG", help="the added absorber's mass, kg")
    p.add_argument(
        "--absorbers", nargs="+", metavar="ID", help="ids of the file's absorbers to tune (default: all)"
    )
    objective_arg(p)
    p.add_argument(
        "--mass-max", type=float, metavar="KG", help="tune each mass too, up to KG (default: masses kept)"
    )
    p.add_argument(
        "--frequency", type=float, nargs=2, metavar=("LO", "HI"), help="absorber frequency bounds, Hz"
        " (default: 0.6 to 1.4 times the bare structure's chatter frequency)"
    )  # fmt: skip
    p.add_argument(
        "--damping", type=float, nargs=2, metavar=("LO", "HI"), default=(0.005, 0.5),
        help="absorber damping-ratio bounds (default 0.005 0.5)",
    )  # fmt: skip
    p.add_argument("--starts", type=int, default=4, metavar="N", help="optimiser starts (default 4)")
    lobe_args(p)
    p.add_argument("--out", metavar="FILE.csv|FILE.nc", help="the tuned design's lobe diagram")
    p.add_argument("--plot", metavar="FILE.png", help="the lobes before and after on one axis")


def run(args: argparse.Namespace) -> int:
    with outputs(args, (args.out, "--out", DATA_SUFFIXES), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:
        return _run(args, outs)


def _run(args: argparse.Namespace, outs: Any) -> int:
    from ..design import tune_absorbers, with_absorber, without_absorbers

    refuse_json(args, "the tuned design's lobes")
    starts = check_count(args.starts, "--starts")
    model = lobe_model(args, "absorber tuning works on D-subdivision lobes (turning, shaping)")
    if args.at is not None:
        if args.mass is None or (args.direction is None and args.angle is None):
            raise InputError(
                "--at needs --mass KG and --direction x|y (or --angle DEG) for the added absorber"
            )
        if args.absorbers:
            raise InputError("--absorbers names the file's absorbers; with --at the added one 'tva' is tuned")
        mass = check_positive(args.mass, "--mass", "kg")
        model = with_absorber(
            model,
            "tva",
            args.at,
            direction=args.direction,
            angle_deg=args.angle,
            mass=mass,
            frequency_hz=1.0,
            damping_ratio=0.1,
        )  # fmt: skip  (the frequency is tuned; 1 Hz only makes the item readable)
    else:
        for opt, val in (("--mass", args.mass), ("--direction", args.direction), ("--angle", args.angle)):
            if val is not None:
                raise InputError(f"{opt} describes an absorber added with --at POINT; give --at too")
    mass_max = None if args.mass_max is None else check_positive(args.mass_max, "--mass-max", "kg")
    for opt, pair in (("--frequency", args.frequency), ("--damping", args.damping)):
        if pair is not None and not 0 < pair[0] < pair[1]:
            raise InputError(
                f"{opt} LO HI: the bound is empty or negative (got {pair[0]:g} {pair[1]:g}); give 0 < LO < HI"
            )
    v, wmax = speeds_and_ceiling(args, model)
    des = tune_absorbers(
        model,
        v,
        absorbers=args.absorbers,
        objective=args.objective,
        mass_max=mass_max,
        frequency_hz=tuple(args.frequency) if args.frequency else None,
        damping_ratio=tuple(args.damping),
        starts=starts,
        position=args.position,
        width_max=wmax,
        verify=args.verify,
    )
    print(des.summary())
    after = des.after
    mesh = design_mesh(without_absorbers(model), des.model, des.width, des.bare_width, des.objective, v,
                       args.position, wmax, "absorbers")  # fmt: skip
    if mesh is not None:  # a model with beams: before and after on the mesh twice as fine
        import dataclasses

        print("\n".join(f"  {ln}" for ln in mesh[0]))
        after = dataclasses.replace(after, meta={**after.meta, **mesh[1]})
    write_result(after, args, outs, plot=des.plot)
    return verified_status(des.verified, "the tuned design")
