"""``chatterlab ssv``: the stability limit under spindle-speed variation at
mean speeds, relative amplitudes RVA and relative frequencies RVF
(docs/ssv.md).  Widths are typed and printed in mm, speeds in the process's
unit; RVA and RVF are ratios.  The program's defaults are the model file's
``[ssv]`` table; RVA 0 is the constant speed (its limit is printed beside
the others' for the gain)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..errors import InputError, check_count
from ..io._files import PLOT_SUFFIXES
from ._common import frozen, model_args, outputs, width_max_m

#: the suffixes of --out: the limits as CSV (one row per speed, RVA, RVF), netCDF or JSON
OUT_SUFFIXES = (".csv", ".nc", ".json")
#: the most grid points (speeds x RVA x RVF) one command computes: each is a search of
#: ~20-40 Floquet problems over a period of the variation
MAX_GRID = 2000


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "ssv", help="stability limit under spindle-speed variation (RVA, RVF) against the mean speed"
    )
    model_args(p)
    p.add_argument(
        "--speed",
        nargs="+",
        required=True,
        metavar="V",
        help="mean speed(s) in the process unit; with --points: MIN MAX",
    )
    p.add_argument("--points", type=int, help="that many speeds evenly from MIN to MAX of --speed")
    p.add_argument(
        "--rva",
        type=float,
        nargs="+",
        metavar="A",
        help="relative amplitude(s) (0: constant speed; default [ssv])",
    )
    p.add_argument(
        "--rvf",
        type=float,
        nargs="+",
        metavar="F",
        help="relative frequency(ies) (default: the file's [ssv])",
    )
    p.add_argument(
        "--shape", choices=["sine", "triangle"], help="the wave (default: the file's [ssv], or sine)"
    )
    p.add_argument(
        "--width-max", type=float, default=5.0, metavar="B", help="largest width searched, mm (default 5)"
    )
    p.add_argument("--scan", type=int, default=20, help="scan widths up to --width-max (default 20)")
    p.add_argument(
        "--method",
        choices=["spectral", "sdm"],
        default="spectral",
        help="Floquet discretisation: spectral elements (default) or semi-discretisation",
    )
    p.add_argument(
        "--split",
        type=float,
        metavar="HZ",
        help="turning/shaping: the structure's modes above HZ respond quasi-statically (their exact static"
        " compliance at the cut), so only those below are integrated: a structure with many modes, a long delay",
    )
    p.add_argument(
        "--degree", type=int, metavar="P", help="spectral elements' polynomial degree (default 16)"
    )
    p.add_argument(
        "--span",
        type=float,
        metavar="RAD",
        help="radians the fastest solution turns per spectral element (default 5; with a higher --degree, more)",
    )
    p.add_argument("--position", type=float, metavar="S", help="slide position s, m (default: the model's)")
    p.add_argument("--jobs", type=int, default=1, help="worker processes for the grid (default 1)")
    p.add_argument("--out", metavar="FILE.csv|FILE.nc|FILE.json", help="the limits")
    p.add_argument("--plot", metavar="FILE.png", help="the limits against the mean speed")


def _grid(args: argparse.Namespace, model: Any) -> tuple[Any, Any, Any, str]:
    """(speeds, rva, rvf, shape) from the options and the file's [ssv]."""
    import numpy as np

    from ..process import SpeedVariation

    unit = model.process.speed_unit
    sp = [float(v) for v in args.speed]
    if args.points is not None:
        n = check_count(args.points, "--points", 2)
        if len(sp) != 2 or not sp[1] > sp[0]:
            raise InputError("--points needs --speed MIN MAX with MAX > MIN")
        speeds = np.linspace(sp[0], sp[1], n)
    else:
        speeds = np.array(sp)
    if np.any(speeds <= 0) or not np.all(np.isfinite(speeds)):
        raise InputError(f"--speed must be positive numbers in {unit} (got {speeds.tolist()})")
    own = SpeedVariation.of_model(model)
    if args.rva is None and own is None:
        raise InputError("give --rva (e.g. --rva 0 0.1 0.2) or an [ssv] table in the model file")
    if args.rvf is None and own is None:
        raise InputError("give --rvf (e.g. --rvf 0.5) or an [ssv] table in the model file")
    rva = np.array(args.rva if args.rva is not None else [0.0, own.amplitude])  # type: ignore[union-attr]
    rvf = np.array(args.rvf if args.rvf is not None else [own.frequency])  # type: ignore[union-attr]
    shape = args.shape or (own.shape if own is not None else "sine")
    size = speeds.size * rva.size * rvf.size
    if size > MAX_GRID:
        raise InputError(f"{size} grid points (speeds x RVA x RVF) are more than {MAX_GRID}: use fewer")
    for a in rva:
        for f in rvf:
            v = SpeedVariation(float(a), float(f), shape)
            if model.process.kind == "milling":
                v.passes(1)  # a milling cut under SSV repeats only for a rational RVF
    return speeds, rva, rvf, shape


def _mesh(args: argparse.Namespace, model: Any, res: Any, kwargs: dict[str, Any]) -> Any:
    """A model with beams: the limit searched again on the mesh twice as fine
    at the grid's smallest limit and at its points with no limit below the
    ceiling (at most :data:`~chatterlab.cli._mesh_checks.SSV_FREE_CAP` of
    them; :func:`~chatterlab.cli._mesh_checks.ssv_check`); the table (with
    ``undetermined`` where the finer mesh contradicts a claim of no chatter)
    and the mesh line printed, the facts in the files' ``mesh_*`` attributes."""
    from ..frequency import ssv_limits_at
    from ..structure._assembly import assemble
    from ._mesh_checks import ssv_check

    fine_model = model.with_finer_mesh()
    source: Any = assemble(fine_model).at(args.position)
    if model.process.kind == "milling":
        from ..lobes import milling_loop_of

        source = milling_loop_of(source)

    def fine_limits(points: list[tuple[float, float, float]]) -> Any:
        return ssv_limits_at(
            source, points, jobs=args.jobs, backend="loky" if args.jobs > 1 else "serial", **kwargs
        )

    out, record = ssv_check(model, res, fine_limits)
    print(out.table())
    print(record["mesh"])
    return out


def run(args: argparse.Namespace) -> int:
    from ..frequency import ssv_limits

    with outputs(args, (args.out, "--out", OUT_SUFFIXES), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:
        fz = frozen(args)
        model = fz.model
        if model.process is None or model.process.kind == "delay":
            raise InputError(
                f"{model.source}: spindle-speed variation needs a [process] of kind turning, shaping or milling"
            )
        speeds, rva, rvf, shape = _grid(args, model)
        check_count(args.scan, "--scan", 2)
        if args.jobs < 1:
            raise InputError(f"--jobs must be >= 1 (got {args.jobs})")
        if args.split is not None:
            if model.process.kind == "milling":
                raise InputError("--split is modelled for turning and shaping, not for milling: leave it out")
            if args.method != "spectral":
                raise InputError("--split needs --method spectral (the quasi-static rest is collocated)")
            if not args.split > 0:
                raise InputError(f"--split must be a frequency > 0 in Hz (got {args.split:g})")
        if args.degree is not None:
            check_count(args.degree, "--degree", 2)
        if args.span is not None and not args.span > 0:
            raise InputError(f"--span must be > 0 radians (got {args.span:g})")
        source: Any = fz
        if model.process.kind == "milling":
            from ..lobes import milling_loop_of

            source = milling_loop_of(fz)
        kwargs: dict[str, Any] = dict(
            shape=shape, width_max=width_max_m(args), scan=args.scan, method=args.method,
            split=args.split, degree=args.degree, span=args.span,
        )  # fmt: skip
        res = ssv_limits(
            source, speeds, rva, rvf, jobs=args.jobs, backend="loky" if args.jobs > 1 else "serial", **kwargs
        )
        if model.beams:
            res = _mesh(args, model, res, kwargs)
        else:
            print(res.table())
        if args.out:
            path = outs.path(args.out)
            suffix = str(args.out).rsplit(".", 1)[-1].lower()
            if suffix == "csv":
                res.to_csv(path)
            elif suffix == "nc":
                res.to_netcdf(path)
            else:
                res.to_json(path)
        if args.plot:
            import matplotlib

            matplotlib.use("Agg")
            from ..plot import savefig

            savefig(res.plot(), str(outs.path(args.plot)))
    # a claim of no chatter the mesh twice as fine contradicts is undetermined: not a clean result
    lost = (getattr(res, "mesh", None) or {}).get("mesh_undetermined_points")
    if lost:
        print(
            f"chatterlab: {lost} point(s) undetermined: the mesh twice as fine does not confirm their claim of"
            " no chatter",
            file=sys.stderr,
        )
        return 1
    return 0
