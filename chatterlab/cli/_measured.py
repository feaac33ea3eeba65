"""``chatterlab lobes --frf FILE``: lobes from a measured FRF (a tap test).

Two ways in, one path: a model file whose structure is an ``[frf]`` table
(or any model file with ``--frf FILE`` in place of its structure: its
``[process]`` and ``[[coupling]]`` are used), or no model file at all, the
cut given on the command line:

* turning / boring: ``--kf`` (N/m^2), ``--force-angle``, ``--normal-angle``
  (deg), speeds in rpm (T = 60/n);
* milling (zeroth-order approximation): ``--teeth``, ``--kt``, ``--kn``
  (N/m^2), ``--immersion`` (a_e/D) and ``--milling down|up``, speeds in rpm
  (T = 60/(N n)), the width the axial depth a_p.

Without a model file chatterlab writes the equivalent model text (printed
with ``--show-model``) and reads it as any model, so both ways share every
check and the one engine, :func:`chatterlab.lobes.lobes_model_frf`.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from ..errors import InputError

__all__ = ["frf_args", "frf_model", "uses_frf"]


def frf_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("a measured FRF as the structure (docs/measured-frf.md)")
    g.add_argument(
        "--frf",
        metavar="FILE",
        help="measured FRF file (.csv/.txt, .frf, .uff/.unv) in place of the model's structure; the model file"
        " may then be left out and the cut given by --kf or --teeth ...",
    )
    g.add_argument(
        "--frf-units",
        metavar="U",
        help="units of the FRF file when it does not say (m/N, mm/N, m/s^2/N, g/N)",
    )
    g.add_argument(
        "--frf-quantity", choices=["receptance", "mobility", "accelerance"], help="what the FRF file holds"
    )
    g.add_argument(
        "--frf-point", metavar="NAME", help="point name of a file whose columns say only xx, xy, ..."
    )
    g.add_argument("--kf", metavar="KF", help="turning without a model file: cutting coefficient, N/m^2")
    g.add_argument("--force-angle", default=0.0, metavar="DEG", help="cutting force direction, deg")
    g.add_argument("--normal-angle", default=0.0, metavar="DEG", help="chip-thickness normal, deg")
    g.add_argument("--teeth", type=int, metavar="N", help="milling without a model file: number of teeth")
    g.add_argument("--kt", metavar="KT", help="milling: tangential coefficient, N/m^2")
    g.add_argument("--kn", metavar="KN", help="milling: normal (radial) coefficient, N/m^2")
    g.add_argument(
        "--immersion", type=float, metavar="AE_D", help="milling: radial immersion a_e/D in (0, 1]"
    )
    g.add_argument("--milling", choices=["down", "up"], default="down", help="milling: down (default) or up")
    g.add_argument("--show-model", action="store_true", help="print the model text built from the options")


def uses_frf(args: argparse.Namespace) -> bool:
    return getattr(args, "frf", None) is not None


def frf_model(args: argparse.Namespace) -> Any:
    """The model of ``lobes --frf``: the model file with the FRF as its
    structure, or a model written from the command-line cut."""
    from ..model._reader import loads_model
    from ._milling import _typed

    for opt in ("--steps", "--scan"):
        if _typed(opt):  # the Floquet methods' knobs: a measured FRF has no modes to run them on
            raise InputError(
                f"{opt} is for the Floquet lobes of a milling model with modes (--method sdm, spectral);"
                " lobes --frf is computed from the measured FRF by the D-subdivision engine (the"
                f" zeroth-order approximation for milling), which does not use it: drop {opt}"
            )
    frf = Path(args.frf)
    if args.model is not None:
        return _with_frf(args, frf)
    from ._units import resolve_speed

    resolve_speed(args, "rpm")  # a model written from the options: a spindle (turning or milling)
    text = _model_text(args, frf)
    if args.show_model:
        print(text)
    from ._common import model_slips, warn

    model = loads_model(
        text, source=f"lobes --frf {args.frf}", base_dir=frf.parent.resolve(), files_outside=True
    )
    warn(args, model_slips(model, args))
    return model


def _frf_table(args: argparse.Namespace, name: str) -> str:
    lines = ["[frf]", f"file = {json.dumps(name)}"]
    for key, val in (("units", args.frf_units), ("quantity", args.frf_quantity), ("point", args.frf_point)):
        if val is not None:
            lines.append(f"{key} = {json.dumps(val)}")
    return "\n".join(lines) + "\n"


def _with_frf(args: argparse.Namespace, frf: Path) -> Any:
    """The model file with --frf as the file of its [frf] table."""
    from ..model._reader import load_model
    from ._common import model_slips, parse_set, warn

    if any(getattr(args, k) is not None for k in ("kf", "teeth", "kt", "kn", "immersion")):
        raise InputError(
            "with a model file the cut is the model's [[coupling]] and [process]: drop --kf/--teeth/..."
        )
    overrides = parse_set(getattr(args, "set", None))
    overrides["frf.file"] = str(frf.resolve())  # named by the user on the command line
    for key, val in (("units", args.frf_units), ("quantity", args.frf_quantity), ("point", args.frf_point)):
        if val is not None:
            overrides[f"frf.{key}"] = val
    model = load_model(
        args.model, variant=getattr(args, "variant", None), overrides=overrides, files_outside=True
    )
    if model.process is not None:
        from ._units import resolve_speed

        resolve_speed(args, model.process.speed_unit)
    warn(args, model_slips(model, args))
    return model


def _model_text(args: argparse.Namespace, frf: Path) -> str:
    from ..io._frf_files import read_frf

    record = read_frf(frf, units=args.frf_units, quantity=args.frf_quantity, point=args.frf_point)
    coords = list(dict.fromkeys(record.outputs))
    milling = args.teeth is not None or args.kt is not None or args.immersion is not None
    if milling == (args.kf is not None):
        raise InputError(
            "lobes --frf without a model file needs the cut: --kf KF (turning) or --teeth N --kt KT --kn KN"
            " --immersion AE_D (milling), or a model file with [[coupling]] and [process]"
        )
    head = _frf_table(args, frf.name)
    if milling:
        missing = [
            o
            for o, v in (
                ("--teeth", args.teeth),
                ("--kt", args.kt),
                ("--kn", args.kn),
                ("--immersion", args.immersion),
            )
            if v is None
        ]
        if missing:
            raise InputError(f"milling from a measured FRF needs {', '.join(missing)} as well")
        if len(coords) != 2:
            raise InputError(
                f"{frf}: milling needs the 2 x 2 FRF of the cutter's x (feed) and y (got outputs {coords})"
            )
        point = f"coords = {{ x = {json.dumps(coords[0])}, y = {json.dumps(coords[1])} }}"
        coupling = 'model = "milling"'
        process = (
            f'kind = "milling"\nrpm = {args.speed[0]!r}\nteeth = {args.teeth}\ndiameter = 1.0\n'  # D: no effect on ZOA
            f"Kt = {args.kt!r}\nKn = {args.kn!r}\nradial_immersion = {args.immersion!r}\nmilling = {json.dumps(args.milling)}"
        )
    else:
        if len(coords) > 2:
            raise InputError(
                f"{frf}: the regenerative cut acts in a plane: give an FRF on 1 or 2 coordinates"
            )
        xy = ", ".join(f"{d} = {json.dumps(c)}" for d, c in zip(("x", "y"), coords, strict=False))
        point = f"coords = {{ {xy} }}"
        coupling = (
            f'model = "regenerative"\nwidth_ref = 0.001\nKf = {args.kf!r}\n'
            f"force_angle_deg = {args.force_angle!r}\nnormal_angle_deg = {args.normal_angle!r}"
        )
        process = f'kind = "turning"\nrpm = {args.speed[0]!r}'
    return (
        f'{head}\n[[point]]\nid = "tool"\n{point}\n\n'
        f'[[coupling]]\nid = "cut"\na = "tool"\nb = "ground"\n{coupling}\n\n[process]\n{process}\n'
    )
