"""``chatterlab sweep``: a chatter quantity over a grid of widths (mm),
speeds (process unit), delays (s), positions (m) or model parameters, on the
sweep engine (workers, dask, checkpoints)."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from ..errors import InputError, check_axis_values
from ..io._files import DATA_SUFFIXES, PLOT_SUFFIXES
from ._claims import inf_note, ok_infs, sweep_inf_claims
from ._common import (
    CommandOutputs,
    cut_args,
    load,
    mm_to_m,
    model_args,
    outputs,
    width_m,
    width_max_m,
)
from ._parallel import (
    check_checkpoint,
    checkpoint,
    drop_checkpoint_after,
    engine_opts,
    fingerprint,
    parallel_args,
    resume_refusal,
)

#: depths scanned by the a-lim quantity before a crossing is refined (chatterlab.lobes.milling_lobes)
MILLING_SCAN = 40

#: the quantities of the sweep command (chatterlab.quantities.QUANTITIES; the last two for milling models)
QUANTITY_NAMES = (
    "rightmost-root",
    "stable",
    "b-lim",
    "min-b-lim",
    "natural-frequencies",
    "spectral-radius",
    "a-lim",
)

#: the options a checkpoint belongs to (besides the model and the grid): a
#: --resume with another value of one of them is refused, naming it
_FINGERPRINT_OPTIONS = ("--quantity", "--terms", "--width-max", "--width", "--speed", "--delay", "--position")


def add_parser(sub: Any) -> None:
    sw = sub.add_parser(
        "sweep", help="a chatter quantity over a grid of widths, speeds, positions or model parameters"
    )
    model_args(sw)
    sw.add_argument(
        "--grid",
        action="append",
        metavar="PARAM=MIN:MAX:N",
        help="a grid axis: width (mm), speed, delay (s), position (m) or a model parameter path (repeatable)",
    )
    sw.add_argument("--quantity", required=True, choices=sorted(QUANTITY_NAMES))
    cut_args(sw)
    sw.add_argument("--position", metavar="S", help="slide position s, m (when not on the grid)")
    sw.add_argument("--width-max", default=20.0, metavar="B", help="largest width for b-lim quantities, mm")
    sw.add_argument("--out", metavar="FILE.nc|FILE.csv")
    sw.add_argument("--plot", metavar="FILE.png")
    parallel_args(sw)


def run(args: argparse.Namespace) -> int:
    with outputs(args, (args.out, "--out", DATA_SUFFIXES), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:
        check_checkpoint(args, outs)
        return _run(args, outs)


def _grid(args: argparse.Namespace, model: Any) -> tuple[Any, dict[str, str]]:
    """The --grid options as a Grid (widths in m) and the axis aliases of
    model-parameter paths."""
    import numpy as np

    from ..quantities._tasks import axis_name
    from ..sweep._engine import Axis, Grid
    from ..sweep._grid import MAX_TASKS, shown_spec

    if not args.grid:
        raise InputError("give at least one --grid PARAM=MIN:MAX:N")
    axes = []
    aliases: dict[str, str] = {}
    units = {
        "width": "m",
        "speed": model.process.speed_unit if model.process else "",
        "delay": "s",
        "position": "m",
    }
    for spec in args.grid:
        if "=" not in spec:
            raise InputError(f"--grid {spec!r}: write PARAM=MIN:MAX:N, e.g. width=0.5:3:11 (mm)")
        name, rng = (x.strip() for x in spec.split("=", 1))
        tok = f"{axis_name(name)}={rng}"
        try:
            g = Grid.from_spec(tok)
        except InputError as exc:  # in the option's own words
            text = str(exc).replace(f"grid spec {shown_spec(tok)!r}", f"--grid {shown_spec(spec)!r}", 1)
            raise InputError(text) from None
        vals = np.asarray(g.axes[0].values, float)
        check_axis_values(name, vals, "mm" if name == "width" else units.get(name, ""))
        if name == "width":
            vals = mm_to_m(vals)  # the CLI takes mm
        ax_name = axis_name(name) if "." in name else name
        if "." in name:
            aliases[ax_name] = name
        axes.append(Axis(ax_name, vals, units.get(name, "")))
    grid = Grid(axes)
    if grid.size > MAX_TASKS:
        raise InputError(
            f"--grid: {' x '.join(str(n) for n in grid.shape)} = {grid.size} points is more than the largest"
            f" sweep accepted, {MAX_TASKS} points (a task costs milliseconds to seconds): use fewer points"
        )
    return grid, aliases


def _run(args: argparse.Namespace, outs: CommandOutputs) -> int:
    from ..quantities._tasks import QUANTITIES, QuantityTask, model_fingerprint
    from ..sweep._engine import sweep

    model = load(args)
    grid, aliases = _grid(args, model)
    fixed: dict[str, float] = {}
    if args.width is not None:
        fixed["width"] = width_m(args)
    for nm in ("speed", "delay", "position"):
        if getattr(args, nm) is not None:
            fixed[nm] = getattr(args, nm)
    task = QuantityTask(
        model, args.quantity, fixed, terms=args.terms, width_max=width_max_m(args), aliases=aliases
    )
    task.check_grid(grid)
    with resume_refusal(args):
        res = sweep(
            task,
            grid,
            outputs=QUANTITIES[args.quantity],
            checkpoint=checkpoint(args),
            resume=args.resume,
            fingerprint=fingerprint(model_fingerprint(model), args, _FINGERPRINT_OPTIONS),
            out=outs.path(args.out) if args.out and not args.out.lower().endswith(".csv") else None,
            attrs={"model_text": model.text, "quantity": args.quantity, "parameters": json.dumps(aliases)},
            **engine_opts(args),
        )
    drop_checkpoint_after(args, outs, res)  # once the files below are in place
    res, mesh = _mesh(args, outs, task, grid, res)
    _summary(args, grid, res, QUANTITIES[args.quantity], task, model, mesh)
    if mesh is not None:
        print(f"  {mesh['mesh']}")
    if args.out and args.out.lower().endswith(".csv"):
        res.to_csv(outs.path(args.out))  # (a .nc file was streamed by the sweep)
    if args.plot:
        from ..plot import savefig

        first = next(iter(QUANTITIES[args.quantity]))
        savefig(res.plot(first), outs.path(args.plot))
    return 0 if res.status == "ok" else 1


def _mesh(args: argparse.Namespace, outs: CommandOutputs, task: Any, grid: Any, res: Any) -> tuple[Any, Any]:
    """A model with beams: the quantity on the mesh twice as fine at the
    grid's most critical point(s) (:func:`chatterlab.cli._mesh_checks.sweep_check`);
    a ``stable`` point it leaves undetermined becomes NaN; the facts become
    the result's attributes ``mesh_*`` (a ``.nc`` file streamed by the sweep
    is written again with them).  ``(result, facts or None)``; without beams
    the result unchanged."""
    import dataclasses

    import numpy as np

    from ._mesh_checks import sweep_check

    if not task.model.beams:
        return res, None
    facts = sweep_check(task, grid, res)
    if facts is None:
        return res, None
    set_nan = facts.pop("_set_nan", [])
    data = {k: np.array(v) for k, v in res.data.items()}  # copies: a streamed file's are memory maps
    if set_nan:
        flat = data["stable"].reshape(-1)
        flat[set_nan] = np.nan
    status = None if res.task_status is None else np.array(res.task_status)
    res = dataclasses.replace(res, data=data, task_status=status, attrs={**res.attrs, **facts})
    if args.out and not args.out.lower().endswith(".csv"):
        # staged after the sweep's own file, so moved onto it last; announced once
        res.to_netcdf(outs.path(args.out, announce=False))
    return res, facts


def _summary(
    args: argparse.Namespace,
    grid: Any,
    res: Any,
    outputs: dict[str, Any],
    task: Any,
    model: Any,
    mesh: dict[str, Any] | None = None,
) -> None:
    """The range of every output; an ``inf`` b_lim says what it means there."""
    import numpy as np

    print(
        f"sweep of {args.quantity} over {' x '.join(f'{a.name}[{a.values.size}]' for a in grid.axes)}: {res.status}"
    )
    for k, arr in res.data.items():
        a = np.asarray(arr)
        fin = a[np.isfinite(a)]
        rng = f"min {fin.min():.6g}, max {fin.max():.6g}" if fin.size else "no finite values"
        if k in ("b_lim", "b_lim_min") and ok_infs(a, res.task_status).any():
            rng += "; " + inf_note(*sweep_inf_claims(res, k, task, model))
        if k == "a_lim" and ok_infs(a, res.task_status).any():
            n_inf = int(ok_infs(a, res.task_status).sum())
            rng += (
                f"; inf at {n_inf} of {a.size} points: no instability at the {MILLING_SCAN} depths scanned up to"
                f" {task.width_max * 1e3:g} mm (a band narrower than {task.width_max * 1e3 / MILLING_SCAN:.3g} mm"
                " between two of them can be missed)"
            )
        if k == "stable" and args.quantity == "stable" and mesh and np.isnan(a).any():
            rng += f"; NaN (undetermined or marginal) at {int(np.isnan(a).sum())} points, the mesh line's included"
        if k == "stable" and args.quantity == "spectral-radius" and np.isnan(a).any():
            rng += f"; undetermined (|mu| within its error of 1) at {int(np.isnan(a).sum())} points"
        print(f"  {k} [{outputs[k]}]: {rng}")
    if res.failures:
        print(f"  {len(res.failures)} task(s) failed; first: {res.message}", file=sys.stderr)
