"""``chatterlab fit-damping``: the process-damping coefficient C_pd of a
model fitted to cutting tests (stable and chattering cuts, measured chatter
onsets), with its uncertainty (docs/process-damping.md).  Widths in mm,
speeds in the process's unit, C_pd in N/m."""

from __future__ import annotations

import argparse
from typing import Any

from ..io._files import PLOT_SUFFIXES
from ._common import load, mm_to_m, outputs

#: the suffixes of --out: the fit as JSON, CSV (one row per test) or netCDF
OUT_SUFFIXES = (".json", ".csv", ".nc")


def add_parser(sub: Any) -> None:
    p = sub.add_parser(
        "fit-damping",
        help="fit the process-damping coefficient C_pd to cutting tests (stable, chatter, onset), with its error",
    )
    p.add_argument(
        "cuts", help="the tests: CSV with speed, width_mm, result (stable|chatter|onset)[, sigma_mm]"
    )
    p.add_argument("--model", required=True, help="model file (TOML): the machine the tests were cut on")
    p.add_argument("--variant", help="use the [variant.NAME] parameter set of the file")
    p.add_argument(
        "--set", action="append", metavar="PATH=VALUE", help="change one model parameter (repeatable)"
    )
    p.add_argument(
        "--allow-outside-files", action="store_true", help="let [matrices] name files outside its folder"
    )
    p.add_argument("--position", type=float, metavar="S", help="slide position s, m (default: the model's)")
    p.add_argument(
        "--width-max",
        type=float,
        metavar="B",
        help="ceiling of the limits searched, mm (default: twice the widest test)",
    )
    p.add_argument(
        "--out", metavar="FILE.json|FILE.csv|FILE.nc", help="the fit and every test's critical C_pd"
    )
    p.add_argument("--plot", metavar="FILE.png", help="the lobes at the fitted C_pd with the tests marked")
    p.add_argument(
        "--speed",
        type=float,
        nargs=2,
        metavar=("MIN", "MAX"),
        help="speed range of --plot (default: the tests')",
    )
    p.add_argument("--quiet", action="store_true", help="no warnings about implausible magnitudes")


def run(args: argparse.Namespace) -> int:
    from ..lobes._fit_damping import fit_process_damping, read_cuts

    with outputs(args, (args.out, "--out", OUT_SUFFIXES), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:
        model = load(args)
        speed, width, result, sigma = read_cuts(args.cuts)
        wmax = None if args.width_max is None else mm_to_m(args.width_max)
        fit = fit_process_damping(
            model, speed, width, result, sigma=sigma, position=args.position, width_max=wmax
        )
        print(fit.summary())
        print(fit.table())
        print(f"in the model file:\n[process_damping]\nC_pd = {fit.C_pd:.6g}    # N/m, fitted to {args.cuts}")
        if args.out:
            _write(fit, outs.path(args.out))
        if args.plot:
            _plot(args, fit, model, str(outs.path(args.plot)))
    return 0


def _plot(args: argparse.Namespace, fit: Any, model: Any, path: str) -> None:
    """The lobes at the fitted C_pd over the tests' speeds (or ``--speed``) with the tests."""
    import numpy as np

    from ..lobes import lobes
    from ..plot._fit_damping import plot_fit_damping

    lo, hi = args.speed if args.speed else (float(fit.speed.min()) * 0.8, float(fit.speed.max()) * 1.2)
    fitted = model.with_parameter("process_damping.C_pd", fit.C_pd)
    d = lobes(
        fitted,
        np.geomspace(lo, hi, 300),
        width_max=float(fit.meta["width_max"]),
        position=args.position,
        verify=0,
    )
    plot_fit_damping(fit, d, path)


def _write(fit: Any, path: Any) -> None:
    suffix = str(path).rsplit(".", 1)[-1].lower()
    if suffix == "json":
        fit.to_json(path)
    elif suffix == "csv":
        fit.to_csv(path)
    else:
        fit.to_netcdf(path)
