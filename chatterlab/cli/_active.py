"""``chatterlab active``: an active damper with the paper's feedback
(:func:`chatterlab.design.design_active`) -- the model's ``[[actuator]]``
items, or one added with ``--sensor POINT.DIR`` -- and the gains (and
placement) that maximise the minimum chatter-free width: the optimised
gains, the limit before and after, the force at the design width, the
control loop's margins, the trade-off of width against actuator force, the
lobes before and after on one plot.  Widths in mm, forces in N, gains in
N/m and N s/m, delays in s, speeds in the process's unit."""

from __future__ import annotations

import argparse
from typing import Any

from ..errors import InputError, check_count, check_positive
from ..io._files import DATA_SUFFIXES, PLOT_SUFFIXES
from ._common import mm_to_m, model_args, outputs, write_result
from ._design_common import (
    design_mesh,
    lobe_args,
    lobe_model,
    objective_arg,
    speed_args,
    speeds_and_ceiling,
    verified_status,
    with_attributes,
)

HELP = "co-design an active damper's gains (and placement) for the widest chatter-free cut; lobes before and after"


def add_parser(sub: Any) -> None:
    p = sub.add_parser("active", help=HELP)
    model_args(p)
    speed_args(p)
    g = p.add_argument_group("an actuator added to the model (default: the file's [[actuator]] items)")
    g.add_argument(
        "--sensor", metavar="POINT.DIR", help="add an actuator 'damper' sensing POINT along DIR (x, y)"
    )
    g.add_argument(
        "--at", metavar="POINT.DIR", help="its force's point and direction (default: the sensor's)"
    )
    g.add_argument(
        "--actuator-delay", type=float, default=0.0, metavar="S", help="its delay T_a, s (default 0)"
    )
    g.add_argument(
        "--bandwidth", type=float, metavar="HZ", help="its first-order bandwidth, Hz (default: none)"
    )
    p.add_argument(
        "--force-limit", type=float, metavar="N", help="the actuators' force limit, N (default: the file's)"
    )
    p.add_argument(
        "--actuators", nargs="+", metavar="ID", help="ids of the file's actuators to tune (default: all)"
    )
    p.add_argument(
        "--free",
        nargs="+",
        choices=["proportional", "velocity", "delayed"],
        default=["proportional", "velocity", "delayed"],
        help="the gains varied (default: all three; delayed only with a delay)",
    )
    for name, unit in (("proportional", "N/m"), ("velocity", "N s/m"), ("delayed", "N/m")):
        p.add_argument(
            f"--{name}", metavar="LO,HI", help=f"bounds of the {name} gain, {unit} (default: from the host mode"
            f" the sensor sees); a negative bound as --{name}=-2e6,2e6",
        )  # fmt: skip
    p.add_argument(
        "--places",
        nargs="+",
        metavar="SENSOR[:AT]",
        help="candidate placements (POINT.DIR, or SENSOR:AT for a force elsewhere); the best is kept",
    )
    objective_arg(p)
    p.add_argument(
        "--design-width", type=float, metavar="MM", help="the width of the force limit, mm (default: 1.1 x the"
        " bare structure's minimum)"
    )  # fmt: skip
    p.add_argument(
        "--gain-margin", type=float, default=2.0, metavar="R", help="required gain margin (default 2)"
    )
    p.add_argument(
        "--phase-margin",
        type=float,
        default=45.0,
        metavar="DEG",
        help="required phase margin, deg (default 45)",
    )
    p.add_argument(
        "--tradeoff", type=int, default=0, metavar="N", help="points of the width-force trade-off (0)"
    )
    p.add_argument("--starts", type=int, default=3, metavar="N", help="optimiser starts (default 3)")
    lobe_args(p)
    p.add_argument(
        "--no-confirm",
        action="store_true",
        help="skip the time-domain confirmation (the cut at the optimised gains and 1.1 x the old limit)",
    )
    p.add_argument(
        "--out", metavar="FILE.csv|FILE.nc|FILE.json", help="the lobes before and after (and the curve)"
    )
    p.add_argument(
        "--plot", metavar="FILE.png", help="the lobes before and after on one axis (and the trade-off)"
    )


def run(args: argparse.Namespace) -> int:
    data = (*DATA_SUFFIXES, ".json")
    with outputs(args, (args.out, "--out", data), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:
        return _run(args, outs)


def _pair(text: str, option: str) -> tuple[float, float]:
    """``"LO,HI"`` as two numbers."""
    parts = str(text).split(",")
    try:
        lo, hi = (float(x) for x in parts)
    except ValueError:
        raise InputError(
            f"{option} takes LO,HI (two numbers and a comma, e.g. {option}=-2e6,2e6); got {text!r}"
        ) from None
    return lo, hi


def _places(items: list[str] | None) -> list[tuple[str, str]] | None:
    if items is None:
        return None
    out = []
    for it in items:
        sensor, _, at = it.partition(":")
        out.append((sensor, at or sensor))
    return out


def _run(args: argparse.Namespace, outs: Any) -> int:
    from ..design import design_active, with_actuator, without_actuators

    starts = check_count(args.starts, "--starts")
    if args.tradeoff < 0:
        raise InputError(f"--tradeoff must be a whole number >= 0 (got {args.tradeoff})")
    model = lobe_model(args, "the active co-design works on D-subdivision lobes (turning, shaping)")
    if args.sensor is not None:
        if args.actuators:
            raise InputError(
                "--actuators names the file's actuators; with --sensor the added one 'damper' is tuned"
            )
        if not args.actuator_delay >= 0:
            raise InputError(f"--actuator-delay must be >= 0 s (got {args.actuator_delay:g})")
        bw = None if args.bandwidth is None else check_positive(args.bandwidth, "--bandwidth", "Hz")
        # a small velocity gain to start from: the optimiser moves it
        model = with_actuator(model, "damper", args.sensor, at=args.at, velocity_gain=1.0, delay=args.actuator_delay,
                              bandwidth_hz=bw)  # fmt: skip
    else:
        for opt, val in (
            ("--at", args.at),
            ("--bandwidth", args.bandwidth),
            ("--actuator-delay", args.actuator_delay or None),
        ):
            if val is not None:
                raise InputError(
                    f"{opt} describes an actuator added with --sensor POINT.DIR; give --sensor too"
                )
    flim = None if args.force_limit is None else check_positive(args.force_limit, "--force-limit", "N")
    bounds = {}
    for name in ("proportional", "velocity", "delayed"):
        text = getattr(args, name)
        if text is not None:
            bounds[name] = _pair(text, f"--{name}")
    bd = (
        None
        if args.design_width is None
        else mm_to_m(check_positive(args.design_width, "--design-width", "mm"))
    )
    v, wmax = speeds_and_ceiling(args, model)
    des = design_active(
        model,
        v,
        actuators=args.actuators,
        free=tuple(args.free),
        bounds=bounds,
        places=_places(args.places),
        objective=args.objective,
        design_width=bd,
        force_limit=flim,
        gain_margin=args.gain_margin,
        phase_margin=args.phase_margin,
        tradeoff=args.tradeoff,
        starts=starts,
        position=args.position,
        width_max=wmax,
        verify=args.verify,
        confirm=not args.no_confirm,
    )
    print(des.summary())
    result: Any = des
    mesh = design_mesh(without_actuators(model), des.model, des.width, des.bare_width, des.objective, v,
                       args.position, wmax, "actuators")  # fmt: skip
    if mesh is not None:  # a model with beams: before and after on the mesh twice as fine
        print("\n".join(f"  {ln}" for ln in mesh[0]))
        result = with_attributes(des, mesh[1])
    write_result(result, args, outs, plot=des.plot)
    return verified_status(des.verified, "the optimised design")
