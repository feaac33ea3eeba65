"""What the design commands (``chatterlab sensitivity``, ``absorber``,
``active``) share: the speed range and the lobe options they take, the model
they refuse (no process, milling), the speeds and the width ceiling, the
result written to ``--out`` and ``--plot``, and the status of a design whose
lobes failed an argument-principle check."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..errors import InputError
from ._common import load, warn, width_max_m, width_slips


def speed_args(p: argparse.ArgumentParser) -> None:
    """``--speed MIN MAX`` (required) and ``--points``."""
    p.add_argument(
        "--speed",
        type=float,
        nargs=2,
        required=True,
        metavar=("MIN", "MAX"),
        help="speed range in the process unit",
    )
    p.add_argument("--points", type=int, default=300, help="number of speeds (default 300)")


def objective_arg(p: argparse.ArgumentParser) -> None:
    """``--objective minimum|absolute``."""
    p.add_argument(
        "--objective",
        choices=["minimum", "absolute"],
        default="minimum",
        help="maximise the minimum b_lim over the speed range (default) or the absolute minimum over all speeds",
    )


def lobe_args(p: argparse.ArgumentParser, *, verify: bool = True) -> None:
    """``--position``, ``--width-max`` (mm) and, for a design whose lobes are
    checked, ``--verify``."""
    p.add_argument("--position", type=float, metavar="S", help="slide position s, m (default: the model's)")
    p.add_argument(
        "--width-max", type=float, default=20.0, metavar="B", help="largest width considered, mm (default 20)"
    )
    if verify:
        p.add_argument(
            "--verify",
            type=int,
            default=16,
            metavar="N",
            help="argument-principle checks of the lobes (default 16)",
        )


def lobe_model(args: argparse.Namespace, milling: str) -> Any:
    """The model of ``args``, refused in one line without a ``[process]`` or
    for milling (``milling``: why, after "is a milling model: ")."""
    model = load(args)
    if model.process is None:
        raise InputError(f"{model.source} has no [process] table: add one so that speeds map to delays")
    if model.process.kind == "milling":
        raise InputError(f"{model.source} is a milling model: {milling}")
    return model


def speeds_and_ceiling(args: argparse.Namespace, model: Any) -> tuple[Any, float]:
    """The speeds of ``--speed``/``--points`` and the ceiling ``--width-max``
    in metres (warned when it slips below the lobes' floor)."""
    from ._lobes import speeds

    v = speeds(args, model.process)
    wmax = width_max_m(args)
    warn(args, width_slips(wmax, "--width-max"))
    return v, wmax


def refuse_json(args: argparse.Namespace, what: str) -> None:
    """A result written only as CSV or netCDF: ``--out X.json`` refused."""
    if args.out and args.out.lower().endswith(".json"):
        raise InputError(f"--out: write {what} as .csv or .nc (not JSON)")


def verified_status(verified: bool | None, what: str) -> int:
    """1 (with a line on stderr) when ``what``'s lobes failed an
    argument-principle check, else 0."""
    if verified is False:
        print(f"chatterlab: {what}'s lobes failed an argument-principle check", file=sys.stderr)
        return 1
    return 0
