"""``chatterlab lobes``: the stability lobe diagram b_lim(speed) at one
position, or an atlas of diagrams along the stroke (``--positions A B N``,
on the sweep engine).  Widths are typed and printed in mm, speeds in the
process's unit, ``--fmin``/``--fmax`` in Hz.

Where a new kind of input plugs in: ``_diagram`` turns what the command
line names (today: a model file with a cutting process, at one position)
into a ``LobeDiagram``; a milling process (its averaged directional matrix
as a ``lobes.Plant``) or a measured FRF (``--frf FILE``: a ``Plant`` whose
band is the measured one) is a branch there returning a ``LobeDiagram``.
Everything after it -- summary, files, plot, the verification status and
exit status -- is ``_report``, shared by every kind.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from typing import Any

from ..errors import InputError, check_count, check_position, check_speed
from ..io._files import DATA_SUFFIXES, PLOT_SUFFIXES, Outputs
from ._claims import ceiling_claim, check_verdict, inf_note, ok_infs
from ._common import (
    MAX_POSITIONS,
    CommandOutputs,
    load,
    m_to_mm,
    model_args,
    outputs,
    unchecked_mesh,
    warn,
    width_max_m,
    width_slips,
)
from ._measured import frf_args, frf_model, uses_frf
from ._milling import milling_lobe_args, milling_lobes
from ._parallel import (
    check_checkpoint,
    checkpoint,
    drop_checkpoint_after,
    engine_opts,
    fingerprint,
    parallel_args,
    resume_refusal,
)


def add_parser(sub: Any) -> None:
    lo = sub.add_parser(
        "lobes", help="stability lobe diagram (b_lim against speed), or an atlas along the stroke"
    )
    model_args(lo, optional=True)
    lo.add_argument(
        "--speed",
        nargs=2,
        required=True,
        metavar=("MIN", "MAX"),
        help="speed range in the process unit",
    )
    lo.add_argument("--points", type=int, default=300, help="number of speeds (default 300)")
    lo.add_argument(
        "--width-max",
        default=None,
        metavar="B",
        help="largest width considered, mm (default 20; milling: from the problem, 3 x the largest"
        " zeroth-order limit)",
    )
    g = lo.add_mutually_exclusive_group()
    g.add_argument("--position", metavar="S", help="slide position s, m (default: the model's)")
    g.add_argument(
        "--positions",
        type=float,
        nargs=3,
        metavar=("A", "B", "N"),
        help="atlas over N positions from A to B, m",
    )
    lo.add_argument(
        "--terms",
        choices=["pdo", "o"],
        default="pdo",
        help="pdo: all feedback terms (default); o: delayed only",
    )
    lo.add_argument("--fmin", help="lowest chatter frequency searched, Hz")
    lo.add_argument("--fmax", help="highest chatter frequency searched, Hz")
    lo.add_argument(
        "--verify",
        type=int,
        default=16,
        metavar="N",
        help="claims checked by the argument principle: the minimum, the N-1 highest cusps, N/2 lobe"
        " bottoms and every run of inf (default 16; 0 skips)",
    )
    lo.add_argument(
        "--confirm", type=int, default=0, metavar="N", help="confirm N boundary points by Newmark simulation"
    )
    lo.add_argument(
        "--no-mesh-check",
        action="store_true",
        help="a model with beams: skip the same diagram on a mesh twice as fine (it doubles an atlas's"
        " cost); the summary, the file and the figure then say the discretisation error was not estimated",
    )
    lo.add_argument("--out", metavar="FILE.nc|FILE.csv")
    lo.add_argument("--plot", metavar="FILE.png")
    parallel_args(lo)
    milling_lobe_args(lo)
    frf_args(lo)


def run(args: argparse.Namespace) -> int:
    with outputs(args, (args.out, "--out", DATA_SUFFIXES), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:
        check_checkpoint(args, outs)
        return _run(args, outs)


def _run(args: argparse.Namespace, outs: CommandOutputs) -> int:
    from ..structure._assembly import assemble

    model = frf_model(args) if uses_frf(args) else load(args)
    if model.process is None:
        raise InputError(f"{model.source} has no [process] table: add one so that speeds map to delays")
    if args.no_mesh_check and not getattr(model, "beams", ()):
        raise InputError(
            f"--no-mesh-check skips the check of a model with [[beam]]s on a mesh twice as fine; {model.source}"
            " has no beams (nothing to skip): drop it"
        )
    milling_model = model.process.kind == "milling" and model.frf is None and args.method != "zoa"
    if args.positions is None:
        _engine_options_unused(args, milling=milling_model)
    v = speeds(args, model.process)
    if milling_model:  # without --width-max the ceiling comes from the problem (lobes.milling_ceiling)
        return _report(args, model, milling_lobes(args, model, v, _width_max(args)), outs)
    if args.width_max is None:
        args.width_max = 20.0
    wmax = width_max_m(args)
    warn(args, width_slips(wmax, "--width-max"))
    if model.frf is not None:
        if args.method not in (None, "zoa"):
            raise InputError(
                f"--method {args.method} needs the structure's modes: a measured FRF gives milling lobes by"
                " the zeroth-order approximation only; fit modes to it (chatterlab.structure.fit_modes(...)"
                ".to_model(), docs/tap-test.md) for Floquet lobes"
            )
        return _report(args, model, _measured_diagram(args, model, v, wmax), outs)
    if args.method not in (None, "zoa"):
        raise InputError(f'--method {args.method} is for milling models ([process] kind = "milling")')
    sy = assemble(model)
    if args.positions is not None:
        return _atlas(args, model, v, wmax, outs)
    return _report(args, model, _diagram(args, sy, v, wmax), outs)


def _width_max(args: argparse.Namespace) -> float | None:
    """--width-max in m (None when not given), with a unit-slip warning."""
    if args.width_max is None:
        return None
    wmax = width_max_m(args)
    warn(args, width_slips(wmax, "--width-max"))
    return wmax


def _engine_options_unused(args: argparse.Namespace, milling: bool = False) -> None:
    """The sweep engine's options are for an atlas: a single diagram runs
    with no checkpoint, so they are refused, not ignored (a --resume after an
    interrupted diagram would silently compute it all); a milling diagram
    takes --jobs (its speeds are independent and split among processes)."""
    given = [
        opt
        for opt, val in (
            ("--resume", args.resume),
            ("--checkpoint", args.checkpoint),
            ("--backend", args.backend != "loky"),
            ("--scheduler", args.scheduler),
            ("--jobs", args.jobs != 2 and not milling),
            ("--tls-ca-file", args.tls_ca_file),
            ("--tls-cert", args.tls_cert),
            ("--tls-key", args.tls_key),
        )
        if val
    ]
    if given:
        raise InputError(
            f"{', '.join(given)}: for an atlas (--positions A B N) only; a single diagram has no checkpoint"
            " (an interrupted one is run again) and runs here (milling: --jobs N splits its speeds)"
        )


def speeds(args: argparse.Namespace, proc: Any) -> Any:
    """``--speed MIN MAX`` and ``--points`` as the array of speeds (process unit)."""
    import numpy as np

    lo, hi = (check_speed(v, "--speed MIN MAX", proc.speed_unit) for v in args.speed)
    if not hi > lo:
        raise InputError(f"--speed range is empty or reversed: MAX ({hi:g}) must exceed MIN ({lo:g})")
    if args.points < 2:
        raise InputError(f"--points must be >= 2 (got {args.points})")
    return np.linspace(lo, hi, args.points)


def _diagram(args: argparse.Namespace, sy: Any, v: Any, wmax: float) -> Any:
    """The lobe diagram of the model's structure at --position (and its
    --confirm table on standard error): the branch point for other inputs."""
    from ..lobes._diagram import lobes

    fz = sy.at(args.position)
    if fz.model.actuators:  # the controlled structure, checked on the full loop (docs/model-format.md)
        from ..design import design_lobes
        from ..lobes._mesh_error import not_estimated

        d = design_lobes(
            fz, v, width_max=wmax, terms=args.terms, fmin=args.fmin, fmax=args.fmax, verify=args.verify
        )
        if fz.model.beams:
            d = dataclasses.replace(
                d, meta={**d.meta, **not_estimated(fz.model, "the mesh check does not cover actuators yet")}
            )
    else:
        # a model with beams: the minimum (and envelope) on the mesh twice as fine, and the error bound
        d = lobes(
            fz,
            v,
            width_max=wmax,
            terms=args.terms,
            fmin=args.fmin,
            fmax=args.fmax,
            verify=args.verify,
            mesh_error=not args.no_mesh_check,
        )
    if args.no_mesh_check and fz.model.beams:
        d = dataclasses.replace(d, meta={**d.meta, **unchecked_mesh(fz.model)})
    if args.confirm:
        from ..lobes._confirm import confirm

        conf = confirm(sy, d, count=args.confirm)
        d = dataclasses.replace(d, meta={**d.meta, "confirm": conf.summary_line()})
        print(conf.table(), file=sys.stderr)
    return d


def _measured_diagram(args: argparse.Namespace, model: Any, v: Any, wmax: float) -> Any:
    """The branch of a measured FRF as the structure ([frf] or --frf)."""
    from ..lobes._measured import lobes_model_frf

    for opt, val in (
        ("--positions", args.positions),
        ("--position", args.position),
        ("--confirm", args.confirm or None),
    ):
        if val is not None:
            raise InputError(
                f"{opt} needs a model with matrices; a measured FRF has one configuration and no matrices"
            )
    return lobes_model_frf(model, v, width_max=wmax, fmin=args.fmin, fmax=args.fmax)


def _report(args: argparse.Namespace, model: Any, d: Any, outs: Outputs) -> int:
    """Summary, --out, --plot and the exit status of a lobe diagram (a
    :class:`~chatterlab.lobes.LobeDiagram`, for every process)."""
    print(d.summary())
    if args.out:
        if args.out.lower().endswith(".csv"):
            d.to_csv(outs.path(args.out))
        else:
            d.to_netcdf(outs.path(args.out), attrs={"model_text": model.text, "command": " ".join(sys.argv)})
    if args.plot:
        from pathlib import Path

        from ..plot import headless, savefig

        name = getattr(model, "name", "") or Path(str(model.source)).stem
        title = f"{name}: stability lobes"
        with headless():  # saved, never shown: no pyplot
            savefig(d.plot(title=title), outs.path(args.plot))
    if getattr(d, "verified", None) is False:
        print(check_verdict(d.checks), file=sys.stderr)
        return 1
    return 0


def _positions(args: argparse.Namespace, model: Any) -> Any:
    """``--positions A B N`` as an array of positions, m (at most
    :data:`MAX_POSITIONS`, and a sweep of at most ``MAX_TASKS`` points)."""
    import numpy as np

    from ..sweep._grid import MAX_TASKS

    a = check_position(args.positions[0], "--positions A")
    b = check_position(args.positions[1], "--positions B")
    n = check_count(args.positions[2], "--positions N")
    if n > MAX_POSITIONS:
        raise InputError(
            f"--positions N = {args.positions[2]:g} is more than the largest accepted, {MAX_POSITIONS}"
            " positions (a boundary is computed at each): use fewer positions"
        )
    if n * args.points > MAX_TASKS:
        raise InputError(
            f"--positions N x --points = {n} x {args.points} = {n * args.points} atlas points is more than"
            f" the largest sweep accepted, {MAX_TASKS}: use fewer positions or points"
        )
    if model.movable is not None:
        for x, nm in ((a, "--positions A"), (b, "--positions B")):
            check_position(x, nm, within=model.movable.range)
    if n > 1 and not b > a:
        raise InputError(f"--positions A B N: need B > A and N >= 1 (got {a:g} {b:g} {n})")
    return np.linspace(a, b, n)


def _atlas(args: argparse.Namespace, model: Any, v: Any, wmax: float, outs: CommandOutputs) -> int:
    from ..quantities._tasks import AtlasTask, model_fingerprint
    from ..sweep._engine import sweep

    pos = _positions(args, model)
    task = AtlasTask(
        model, wmax, tuple(float(x) for x in v), terms=args.terms, fmin=args.fmin, fmax=args.fmax
    )
    with resume_refusal(args):
        res = sweep(
            task,
            {"position": (pos, "m"), "speed": (v, model.process.speed_unit)},
            outputs={
                "b_lim": ("m", "largest chatter-free width of cut"),
                "chatter_frequency": ("Hz", "chatter frequency"),
            },
            chunk_size=v.size,
            checkpoint=checkpoint(args),
            resume=args.resume,
            fingerprint=fingerprint(
                model_fingerprint(model), args, ("--width-max", "--terms", "--fmin", "--fmax")
            ),
            attrs={"title": "chatterlab stability atlas", "model_text": model.text, "terms": args.terms},
            **engine_opts(args),
        )
    drop_checkpoint_after(args, outs, res)  # once the files below are in place
    fine = _atlas_mesh(args, model, task, res, pos, v) if model.beams and not args.no_mesh_check else None
    if fine is not None:
        res = dataclasses.replace(res, attrs={**res.attrs, **fine[1]})
    elif model.beams:  # --no-mesh-check: the file and the summary say what was not estimated
        res = dataclasses.replace(res, attrs={**res.attrs, **unchecked_mesh(model)})
    _atlas_summary(model, task, res, pos, v, wmax, None if fine is None else fine[0])
    if res.failures:
        print(f"  {len(res.failures)} task(s) failed: {res.message}", file=sys.stderr)
    if args.out:
        if args.out.lower().endswith(".csv"):
            res.to_csv(outs.path(args.out))
        else:
            res.to_netcdf(outs.path(args.out))
    if args.plot:
        from ..plot import plot_atlas, savefig

        savefig(
            plot_atlas(
                res, model.process, model=model.name or model.source, width_max=wmax, terms=args.terms
            ),
            outs.path(args.plot),
        )
    return 0 if res.status == "ok" else 1


def _atlas_mesh(
    args: argparse.Namespace, model: Any, task: Any, res: Any, pos: Any, v: Any
) -> tuple[Any, dict[str, Any]]:
    """The atlas of a model with beams on the mesh twice as fine
    (:meth:`Model.with_finer_mesh`), every point, through the same sweep
    engine (its jobs and progress; no checkpoint: an interrupted run computes
    it again), and the ``mesh_*`` attributes of its discretisation error
    (docs/lobes.md, Eqs. M1-M5): the worst case's value twice as fine and its
    bound, the change of every point (median, largest: a change, not a bound)
    and the points that end at the ceiling on this mesh but not on the finer
    one.  Returns (b_lim on h/2 [position, speed], attributes)."""
    import time

    import numpy as np

    from ..model._mesh import MeshEstimate, converged_tail, envelope_record, limit_line, mesh_record, pct
    from ..quantities._tasks import AtlasTask
    from ..sweep._engine import sweep

    t0 = time.perf_counter()
    fm = model.with_finer_mesh()
    ft = AtlasTask(fm, task.width_max, task.speeds, terms=task.terms, fmin=task.fmin, fmax=task.fmax)
    opts = {**engine_opts(args), "keep_checkpoint": False}
    if opts["progress"]:
        print(
            f"mesh check: the atlas again on a mesh twice as fine ({fm.beam_elements} beam elements)",
            file=sys.stderr,
        )
    fres = sweep(
        ft,
        {"position": (pos, "m"), "speed": (v, model.process.speed_unit)},
        outputs={
            "b_lim": ("m", "largest chatter-free width of cut, mesh twice as fine"),
            "chatter_frequency": ("Hz", "chatter frequency, mesh twice as fine"),
        },
        chunk_size=v.size,
        **opts,
    )
    bl, b2 = np.asarray(res.data["b_lim"], float), np.asarray(fres.data["b_lim"], float)
    worst, worst2 = float(np.nanmin(bl)), float(np.nanmin(b2))  # inf where every point is at the ceiling
    est = MeshEstimate(worst, worst2)
    attrs: dict[str, Any] = {
        **mesh_record(model),
        "mesh_fine_worst_m": worst2,
        "mesh_worst_change": float(est.relative_change),
        "mesh_worst_error_bound": float(est.relative_bound),
        **envelope_record(bl, b2, ok_infs(bl, res.task_status), "points"),
        "mesh_position_min_fine_m": np.nanmin(np.where(np.isnan(b2), np.inf, b2), axis=1),
    }
    lost = attrs["mesh_free_points_fine_limited"]
    line = limit_line(model, "worst-case b_lim", worst, worst2, tail=False)
    if attrs["mesh_envelope_points"]:
        line += (
            f"; the atlas moves by {pct(attrs['mesh_envelope_change_median'])} (median over"
            f" {attrs['mesh_envelope_points']} points), up to {pct(attrs['mesh_envelope_change_max'])}"
        )
    if lost:
        line += (
            f"; at {lost} of the {attrs['mesh_free_points']} points with no b_lim below the ceiling the finer"
            " mesh finds one: their stability is not established"
        )
    if fres.status != "ok":
        line += f"; the finer mesh's run is {fres.status} ({fres.message})"
    line += converged_tail(model)
    attrs["mesh_seconds"] = time.perf_counter() - t0
    attrs["mesh"] = line
    return b2, attrs


def _atlas_summary(model: Any, task: Any, res: Any, pos: Any, v: Any, wmax: float, fine: Any = None) -> None:
    """The worst case along the stroke and the smallest b_lim per position;
    a position with ``inf`` says what it means there (its band checked); a
    model with beams: each position's smallest b_lim on the mesh twice as
    fine (``fine``, :func:`_atlas_mesh`) and the mesh line."""
    import numpy as np

    bl = res.data["b_lim"]
    infs = ok_infs(bl, res.task_status)
    claims = {
        k: ceiling_claim(task.boundary(float(p)).band, wmax) for k, p in enumerate(pos) if infs[k].any()
    }
    worst = np.nanmin(np.where(np.isfinite(bl), bl, np.inf), axis=0)
    j = int(np.argmin(worst))
    i = int(np.argmin(bl[:, j]))
    head = f"stability atlas of {model.source}: {pos.size} positions x {v.size} speeds ({res.status})"
    if np.isfinite(worst[j]):
        print(
            f"{head}\n  worst case along the stroke: b_lim {m_to_mm(worst[j]):.4g} mm at {v[j]:.5g}"
            f" {model.process.speed_unit}, position {pos[i]:.4g} m, chatter {res.data['chatter_frequency'][i, j]:.2f} Hz"
        )
    else:
        print(f"{head}\n  worst case along the stroke: no finite b_lim")
    for k, p in enumerate(pos):
        row = bl[k]
        fin = row[np.isfinite(row)]
        line = f"  position {p:8.4f} m: " + (
            f"min b_lim {m_to_mm(fin.min()):.4g} mm" if fin.size else "no finite b_lim"
        )
        if k in claims:
            line += ("; " if fin.size else ", ") + inf_note(
                [claims[k]] * int(infs[k].sum()), row.size, "speeds"
            )
        if fine is not None:
            f2 = fine[k][np.isfinite(fine[k])]
            line += "; twice as fine: " + (f"{m_to_mm(f2.min()):.4g} mm" if f2.size else "no finite b_lim")
        print(line)
    if "mesh" in res.attrs:
        print(f"  {res.attrs['mesh']}")
