"""``chatterlab recommend``: the speeds to choose (:mod:`chatterlab.selection`).

Two routes:

* from a model (the default): the speeds and depths that maximise the
  material removal rate while stable with ``--margin`` and within the
  machine's and tool's limits (the model's ``[machine]`` table, each field
  overridden by its option), ranked, with the reason for each;
* the shop floor's chatter-frequency rule (``--chatter HZ`` or
  ``--recording FILE.wav|FILE.csv``, with the ``--running`` speed): the
  nearest speeds that put the tooth-passing frequency on the chatter
  frequency, checked against the lobes when a model is given
  ("undetermined" without one).

Units at this edge: widths, depths, feed and diameters in mm, frequencies in
Hz, speeds in the process's unit (rpm; a shaper's work speed m/s), power in
kW, torque in N m, the specific cutting energy in N/m^2; a number may carry
its own unit (``--power 15kW``, ``--max-depth 0.004m``).
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from ..errors import InputError, check_count
from ..io._files import DATA_SUFFIXES, JSON_SUFFIXES, PLOT_SUFFIXES
from ._common import load, model_args, outputs, warn, width_slips, write_result

HELP = "the speeds and depths to choose: most material removed while stable, or the chatter-frequency rule"

#: option dest -> (the unit of a bare number, the [machine] field it overrides, its SI factor)
_MACHINE_OPTIONS = {
    "power": ("kW", "power", 1e3),
    "torque": ("N*m", "torque", 1.0),
    "max_depth": ("mm", "max_depth", 1e-3),
    "max_width": ("mm", "max_width", 1e-3),
    "feed": ("mm", "feed", 1e-3),
    "workpiece_diameter": ("mm", "workpiece_diameter", 1e-3),
    "specific_energy": ("N/m^2", "specific_energy", 1.0),
}


def add_parser(sub: Any) -> None:
    p = sub.add_parser("recommend", help=HELP)
    model_args(p, optional=True)
    p.add_argument("--speed", nargs=2, metavar=("MIN", "MAX"),
                   help="speeds searched, in the process unit (default: [machine] min..max)")  # fmt: skip
    p.add_argument("--points", type=int, default=300, help="number of speeds (default 300)")
    p.add_argument("--margin", type=float, default=0.2, metavar="F",
                   help="safety margin in [0, 1): cut at most (1 - F) x the stability limit (default 0.2)")  # fmt: skip
    p.add_argument("--count", type=int, default=5, metavar="N", help="cuts ranked (default 5)")
    m = p.add_argument_group("the machine and the tool (override the model's [machine] table)")
    m.add_argument("--max-rpm", metavar="N", help="the spindle's highest speed, rpm (turning, milling)")
    m.add_argument("--min-rpm", metavar="N", help="the spindle's lowest speed, rpm")
    m.add_argument("--max-speed", metavar="V", help="a shaper's highest work speed, m/s")
    m.add_argument("--min-speed", metavar="V", help="a shaper's lowest work speed, m/s")
    m.add_argument("--power", metavar="P", help="power available at the cut, kW (the same at every speed)")
    m.add_argument("--torque", metavar="M", help="the spindle's torque, N m (the same at every speed)")
    m.add_argument("--max-depth", metavar="MM", help="the tool's largest depth of cut (milling a_p), mm")
    m.add_argument("--max-width", metavar="MM", help="the tool's largest radial width a_e (milling), mm")
    m.add_argument(
        "--feed", metavar="MM", help="feed per tooth (milling), per revolution (turning), per stroke, mm"
    )
    m.add_argument("--workpiece-diameter", metavar="MM", help="turning: the workpiece diameter, mm")
    m.add_argument("--specific-energy", metavar="K",
                   help="cutting force per unit chip area along the cutting speed, N/m^2 (turning, shaping)")  # fmt: skip
    a = p.add_argument_group("the lobes")
    a.add_argument("--width-max", metavar="MM", help="largest width searched, mm (default: from the limits)")
    a.add_argument("--position", metavar="S", help="slide position s, m (default: the model's)")
    a.add_argument("--method", choices=["spectral", "sdm", "zoa"], help="milling: Floquet (default) or ZOA")
    a.add_argument(
        "--refine", type=int, default=3, metavar="N", help="refinement rounds per candidate (default 3)"
    )
    a.add_argument("--no-check", action="store_true", help="do not check each recommended cut on its own")
    r = p.add_argument_group("the chatter-frequency rule")
    g = r.add_mutually_exclusive_group()
    g.add_argument("--chatter", metavar="HZ", help="the chatter frequency measured, Hz")
    g.add_argument("--recording", metavar="FILE", help="a recording of the cut: WAV, or CSV of time,signal")
    r.add_argument(
        "--running", metavar="V", help="the speed the cut runs at (process unit; rpm without a model)"
    )
    r.add_argument(
        "--depth", metavar="MM", help="the depth being cut, mm: each speed says if it is stable there"
    )
    r.add_argument("--teeth", type=int, metavar="N", help="teeth, without a model (default 1: turning)")
    r.add_argument("--channel", type=int, default=0, metavar="K", help="the recording's channel (default 0)")
    r.add_argument("--fmin", metavar="HZ", help="lowest chatter frequency searched in the recording, Hz")
    r.add_argument("--fmax", metavar="HZ", help="highest chatter frequency searched in the recording, Hz")
    p.add_argument(
        "--out", metavar="FILE.csv|FILE.nc|FILE.json", help="the ranked cuts (or the rule's speeds)"
    )
    p.add_argument("--plot", metavar="FILE.png", help="the cuts on the lobes over the removal rate")


def run(args: argparse.Namespace) -> int:
    with outputs(args, (args.out, "--out", DATA_SUFFIXES + JSON_SUFFIXES),
                 (args.plot, "--plot", PLOT_SUFFIXES)) as outs:  # fmt: skip
        if args.recording is not None:
            outs.add_input(args.recording)
        code = _run(args, outs)
    return code


def _run(args: argparse.Namespace, outs: Any) -> int:
    rule = args.chatter is not None or args.recording is not None
    for opt, val in (("--running", args.running), ("--depth", args.depth), ("--teeth", args.teeth)):
        if val is not None and not rule:
            raise InputError(
                f"{opt} is for the chatter-frequency rule: give --chatter HZ or --recording FILE"
            )
    model = load(args) if args.model is not None else None
    if model is None and not rule:
        raise InputError(
            "give the model file (or, for the chatter-frequency rule, --chatter HZ or --recording FILE)"
        )
    margin = _margin(args.margin)
    count = check_count(args.count, "--count")
    if rule:
        return _rule(args, model, margin, count, outs)
    return _speeds(args, model, margin, count, outs)


# ----------------------------------------------------------------------------- options
def _margin(v: float) -> float:
    if not (math.isfinite(v) and 0 <= v < 1):
        raise InputError(f"--margin {v:g}: give a fraction in [0, 1), e.g. 0.2 to cut at 80 % of the limit")
    return float(v)


def _positive(text: Any, option: str, unit: str, factor: float = 1.0) -> float:
    from ._units import quantity

    v = quantity(text, option, unit)
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"{option} {text}: must be a finite number > 0 ({unit})")
    return v * factor


def _speed(text: Any, option: str, unit: str) -> float:
    from ._units import speed_in

    v = speed_in(text, unit, option)
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"{option} {text}: must be a speed > 0 {unit}")
    return v


def machine_of(args: argparse.Namespace, model: Any) -> Any:
    """The model's ``[machine]`` with each field given as an option replaced,
    checked for its process (one line naming the option or field)."""
    import dataclasses

    from ..model._items import Machine, machine_problem

    proc = model.process
    spindle = proc.kind in ("turning", "milling")
    base = model.machine if model.machine is not None else Machine()
    changes: dict[str, Any] = {}
    for opt, dest, field in (("--max-rpm", "max_rpm", "max_speed"), ("--min-rpm", "min_rpm", "min_speed"),
                             ("--max-speed", "max_speed", "max_speed"), ("--min-speed", "min_speed", "min_speed")):  # fmt: skip
        val = getattr(args, dest)
        if val is None:
            continue
        if ("rpm" in dest) != spindle:
            use = opt.replace("speed", "rpm") if spindle else opt.replace("rpm", "speed")
            raise InputError(f"{opt}: a {proc.kind} process's speed is in {proc.speed_unit}: give {use}")
        if dest.startswith("min"):
            from ._units import speed_in

            v = speed_in(val, proc.speed_unit, opt)
            if not (math.isfinite(v) and v >= 0):
                raise InputError(f"{opt} {val}: must be a speed >= 0 {proc.speed_unit}")
        else:
            v = _speed(val, opt, proc.speed_unit)
        changes[field] = v
    for dest, (unit, field, factor) in _MACHINE_OPTIONS.items():
        val = getattr(args, dest)
        if val is None:
            continue
        opt = "--" + dest.replace("_", "-")
        v = _positive(val, opt, unit, factor)
        changes[field] = ((0.0, v),) if field in ("power", "torque") else v
    m = dataclasses.replace(base, **changes)
    bad = machine_problem(m, proc.kind)
    if bad is not None:
        field, fix = bad
        opt = {"max_rpm": "--max-rpm", "min_rpm": "--min-rpm"}.get(field, "--" + field.replace("_", "-"))
        raise InputError(f"{opt} / [machine] {field}: {fix}")
    return m


# ----------------------------------------------------------------------------- the speed route
def _speeds(args: argparse.Namespace, model: Any, margin: float, count: int, outs: Any) -> int:
    from ..selection import recommend

    if model.process is None:
        raise InputError(f"{model.source} has no [process] table: add one so that speeds map to delays")
    if model.process.kind == "delay":
        raise InputError(
            f"{model.source}: a delay process has no speed to choose (turning, milling or shaping)"
        )
    for opt, val in (("--channel", args.channel != 0 or None), ("--fmin", args.fmin), ("--fmax", args.fmax)):
        if val is not None:
            raise InputError(f"{opt} is for a recording (--recording FILE)")
    mach = machine_of(args, model)
    speeds = None
    if args.speed is not None:
        from ._lobes import speeds as grid

        speeds = grid(args, model.process)
    elif not (mach.min_speed > 0 and math.isfinite(mach.max_speed)):
        lo, hi = (
            ("--min-rpm", "--max-rpm") if model.process.kind != "shaping" else ("--min-speed", "--max-speed")
        )
        raise InputError(f"give --speed MIN MAX, or the machine's speed range ([machine] or {lo} and {hi})")
    width_max = None
    if args.width_max is not None:
        width_max = float(args.width_max) * 1e-3
        warn(args, width_slips(width_max, "--width-max"))
    options: dict[str, Any] = {}
    if args.method is not None:
        if model.process.kind != "milling":
            raise InputError(f'--method {args.method} is for milling models ([process] kind = "milling")')
        if args.method != "spectral":
            options["method"] = args.method
    position = None
    if args.position is not None:
        from ._units import quantity

        position = quantity(args.position, "--position", "m")
    refine = check_count(args.refine, "--refine", 0)
    if refine > 10:
        raise InputError(
            f"--refine {refine} is more than the largest accepted, 10 (each round evaluates more speeds)"
        )
    rec = recommend(
        model, speeds, machine=mach, margin=margin, count=count, width_max=width_max, position=position,
        points=args.points, refine=refine, check=not args.no_check, **options,
    )  # fmt: skip
    rec = mesh_checked(rec, model, position, options)
    print(rec.summary())
    write_result(rec, args, outs, model=model)
    if not rec.speed.size:
        return 1
    if any(str(v) in ("unstable", "undetermined") for v in rec.verdict):
        how = " or on the mesh twice as fine" if rec.meta.get("mesh_undetermined") else ""
        print(
            f"chatterlab: a recommended cut was not confirmed stable by its own check{how}", file=sys.stderr
        )
        return 1
    return 0


# ----------------------------------------------------------------------------- the mesh
def mesh_checked(rec: Any, model: Any, position: float | None, options: dict[str, Any]) -> Any:
    """``rec`` of a model with beams with each cut checked on the mesh twice as
    fine (unchanged without beams, or without a cut).

    The stability limit at every recommended speed is computed again on
    :meth:`Model.with_finer_mesh` (the same lobes' route, options and
    ceiling) and each cut of width > 0 is judged by
    :func:`chatterlab.model._mesh.width_verdict` against the limit on h and
    h/2: a cut that the finer mesh, or the limit's discretisation error
    (docs/lobes.md, Eq. M3), does not confirm becomes ``undetermined`` (a cut
    the roots found unstable stays so); its ``check`` gets the verdict's
    line.  A note says how far the limits the ranking rests on move and
    their error bound; ``meta`` carries the same for the files (``mesh_*``,
    docs/cli.md)."""
    if not model.beams or not rec.speed.size:
        return rec
    import dataclasses

    import numpy as np

    mesh_v, why, note, meta = _mesh_widths(
        model, rec.speed, rec.width, rec.limit, rec.width_max, position, options, rec.limit_name, "cut"
    )
    verdicts, checks = list(rec.verdict), list(rec.check)
    for i, (v, line) in enumerate(zip(mesh_v, why, strict=True)):
        if v == "not checked":
            continue
        if v != "stable" and verdicts[i] != "unstable":
            verdicts[i] = v
        checks[i] = f"{checks[i]}; {line}"
    return dataclasses.replace(
        rec,
        verdict=np.array(verdicts, dtype=str),
        check=tuple(checks),
        notes=(*rec.notes, note),
        elapsed=rec.elapsed + meta["mesh_seconds"],
        meta={**rec.meta, **meta},
    )


def rule_mesh_checked(res: Any, model: Any, position: float | None, options: dict[str, Any]) -> Any:
    """The chatter-frequency rule's speeds of a model with beams (``res``
    unchanged otherwise) judged on the mesh twice as fine, as
    :func:`mesh_checked` judges a cut: the depth (``--depth``), else the width
    each speed allows with the margin, against the limit there on h and h/2
    (:func:`chatterlab.model._mesh.width_verdict`).  A verdict the finer mesh
    or the limit's error bound does not confirm becomes ``undetermined``;
    each reason gets the line, the notes the limits' change and bound."""
    import numpy as np

    if not model.beams or res.diagram is None or not res.speed.size:
        return res
    import dataclasses

    widths = np.full(res.speed.size, res.depth) if res.depth is not None else np.asarray(res.width, float)
    judged = np.isin(np.asarray(res.verdict).astype(str), ("stable", "within margin", "unstable", "limit"))
    widths = np.where(judged, widths, 0.0)
    mesh_v, why, note, meta = _mesh_widths(
        model, res.speed, widths, res.limit, float(res.diagram.width_max), position, options,
        res.diagram.limit_name, "speed",
    )  # fmt: skip
    verdicts, reasons = list(res.verdict), list(res.reason)
    for i, (v, line) in enumerate(zip(mesh_v, why, strict=True)):
        if v == "not checked":
            continue
        if v == "undetermined":
            verdicts[i] = "undetermined"
        reasons[i] = f"{reasons[i]}; {line}"
    return dataclasses.replace(
        res,
        verdict=np.array(verdicts, dtype=str),
        reason=tuple(reasons),
        notes=(*res.notes, note),
        meta={**res.meta, **meta},
    )


def _mesh_widths(
    model: Any, speeds: Any, widths: Any, limits: Any, width_max: float, position: float | None,
    options: dict[str, Any], name: str, item: str,
) -> tuple[list[str], list[str], str, dict[str, Any]]:  # fmt: skip
    """Each width (> 0; else "not checked") at its speed judged against the
    limit there on h (``limits``) and on :meth:`Model.with_finer_mesh` (the
    same lobes' route and ceiling) by :func:`chatterlab.model._mesh.width_verdict`:
    the verdicts, their lines, one note on how far the limits move and the
    largest bound of their error (Eq. M3), and the files' ``mesh_*``."""
    import json
    import time

    import numpy as np

    from ..model._mesh import MeshEstimate, converged_tail, mesh_record, mesh_words, pct, width_verdict
    from ._mesh_checks import established_limits

    t0 = time.perf_counter()
    v = np.asarray(speeds, float)
    fine_lim = established_limits(model.with_finer_mesh(), v, width_max, position, **options)
    limits = np.asarray(limits, float)
    mesh_v, why = [], []
    for i in range(v.size):
        w, lim, lim2 = float(widths[i]), float(limits[i]), float(fine_lim[i])
        if not w > 0:
            mesh_v.append("not checked")
            why.append("")
            continue
        verdict, line = width_verdict(model, w, lim, lim2)  # nan: the lobes establish nothing there
        mesh_v.append(verdict)
        why.append(line)
    both = np.isfinite(limits) & np.isfinite(fine_lim)
    est = MeshEstimate(limits[both], fine_lim[both])
    und = sum(x == "undetermined" for x in mesh_v)
    n = sum(x != "not checked" for x in mesh_v)
    where = "recommended speeds" if item == "cut" else "speeds of the rule"
    if np.any(both):
        ch = est.relative_change
        lo, hi = float(np.min(ch)), float(np.max(ch))
        moves = pct(lo, "+") if lo == hi else f"{pct(lo, '+')} .. {pct(hi, '+')}"
        head = (
            f"twice as fine, the {name} at the {int(np.sum(both))} {where} with a limit on both"
            f" meshes moves by {moves}; discretisation error of these limits <= {pct(float(np.max(est.relative_bound)))}"
            " (docs/lobes.md, Eq. M3)"
        )
    else:
        head = (
            f"no {where[:-1]} has a limit ({name}) below the ceiling on both meshes: no estimate of its error"
        )
    tail = (
        f"; {und} of {n} {item}{'s' * (n != 1)} undetermined on it"
        if und
        else (f"; every {item} confirmed on it" if n else "")
    )
    note = f"mesh: {mesh_words(model)}; {head}{tail}{converged_tail(model)}"

    def js(x: Any) -> str:
        return json.dumps([None if not np.isfinite(y) else float(y) for y in np.asarray(x, float)])

    full = MeshEstimate(limits, fine_lim)
    meta = {
        **mesh_record(model),
        "mesh_fine_limit_m": js(fine_lim),
        "mesh_limit_change": js(full.relative_change),
        "mesh_limit_error_bound": js(full.relative_bound),
        "mesh_verdicts": json.dumps(mesh_v),
        "mesh_undetermined": int(und),
        "mesh_seconds": time.perf_counter() - t0,
        "mesh": note,
    }
    return mesh_v, why, note, meta


# ----------------------------------------------------------------------------- the rule
def _rule(args: argparse.Namespace, model: Any, margin: float, count: int, outs: Any) -> int:
    from ..selection import chatter_frequency, chatter_rule

    if args.running is None:
        raise InputError("--running V: the speed the cut runs at is needed by the chatter-frequency rule")
    for opt, val in (("--speed", args.speed), ("--max-depth", args.max_depth), ("--power", args.power),
                     ("--torque", args.torque), ("--feed", args.feed), ("--no-check", args.no_check or None)):  # fmt: skip
        if val is not None:
            raise InputError(
                f"{opt} is for the speed search from a model; the chatter-frequency rule does not use it"
            )
    proc = model.process if model is not None else None
    if model is not None and proc is None:
        raise InputError(f"{model.source} has no [process] table: add one so that speeds map to delays")
    unit = proc.speed_unit if proc is not None else "rpm"
    running = _speed(args.running, "--running", unit)
    mach = machine_of(args, model) if model is not None else None
    if model is None:
        for opt in ("max_rpm", "min_rpm", "max_speed", "min_speed", "width_max", "position", "method"):
            if getattr(args, opt) is not None:
                raise InputError(f"--{opt.replace('_', '-')} needs the model file")
    depth = _positive(args.depth, "--depth", "mm", 1e-3) if args.depth is not None else None
    teeth = args.teeth
    if teeth is not None:
        teeth = check_count(teeth, "--teeth")
        if model is not None:
            raise InputError("--teeth is for the rule without a model: the model's cutter says how many")
    n_teeth = teeth or (proc.milling.teeth if proc is not None and proc.kind == "milling" else 1)
    if args.recording is not None:
        from ._units import quantity

        if proc is not None and proc.kind == "shaping":
            spindle_hz = 1.0 / float(proc.delay(running))
        else:
            spindle_hz = running / 60.0
        chatter: Any = chatter_frequency(
            args.recording, spindle_hz=spindle_hz, teeth=n_teeth, channel=check_count(args.channel, "--channel", 0),
            fmin=None if args.fmin is None else quantity(args.fmin, "--fmin", "Hz"),
            fmax=None if args.fmax is None else quantity(args.fmax, "--fmax", "Hz"),
        )  # fmt: skip
        if not chatter.found:
            print(chatter.summary())
            return 1
    else:
        chatter = _positive(args.chatter, "--chatter", "Hz")
        for opt, val in (
            ("--channel", args.channel != 0 or None),
            ("--fmin", args.fmin),
            ("--fmax", args.fmax),
        ):
            if val is not None:
                raise InputError(f"{opt} is for a recording (--recording FILE)")
    options: dict[str, Any] = {}
    if args.method is not None and args.method != "spectral":
        options["method"] = args.method
    width_max = float(args.width_max) * 1e-3 if args.width_max is not None else None
    position = float(args.position) if args.position is not None else None
    res = chatter_rule(
        chatter, running, source=model, teeth=teeth, depth=depth, margin=margin, count=count, machine=mach,
        width_max=width_max, position=position, **options,
    )  # fmt: skip
    out: Any = res
    if model is not None:  # a model with beams: each speed's verdict on the mesh twice as fine
        res = rule_mesh_checked(res, model, position, options)
        if res.meta.get("mesh"):
            from ._design_common import with_attributes

            out = with_attributes(res, {k: v for k, v in res.meta.items() if k.startswith("mesh")})
    print(res.summary())
    write_result(out, args, outs, model=model, plot=res.plot)
    return 0
