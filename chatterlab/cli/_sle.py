"""``chatterlab sle``: what a stable cut leaves (:mod:`chatterlab.frequency._forced`).

* milling (``[process] kind = "milling"``): the surface location error and
  the wall's peak-to-valley against the spindle speed at the depth
  ``--width`` (mm), from the periodic forced vibration under the static
  cutting force (feed per tooth ``--feed``, or the model's ``[process]
  feed_per_tooth``, or its ``[machine] feed``); a speed where the cut
  chatters gets no SLE and is reported as unstable, one whose stability is
  within its convergence error as undetermined.  ``--method sdm --steps M``:
  the fixed point of the semi-discretisation's one-period map instead of the
  spectral elements' (the same discretisation as ``lobes --method sdm``, which
  draws the ``--plot``'s lobes then).  ``--plot``: the SLE under
  the Floquet lobes on the same speed axis (``--no-lobes``: the SLE alone).
* turning (``kind = "turning"``): the vibration at the spindle frequency
  under a workpiece eccentric by ``--eccentricity`` (mm) with the feed per
  revolution ``--feed``, through the closed loop at ``--width`` b.

Units at this edge: widths, feed and eccentricity in mm, speeds in rpm; the
printed SLE and peak-to-valley in um.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from typing import Any, Literal

from ..errors import InputError, check_count
from ..io._files import DATA_SUFFIXES, JSON_SUFFIXES, PLOT_SUFFIXES
from ._common import load, model_args, outputs, progress_bar, width_m, write_result

HELP = (
    "surface location error of the stable cuts against speed (milling), or the response to runout (turning)"
)


def add_parser(sub: Any) -> None:
    p = sub.add_parser("sle", help=HELP)
    model_args(p)
    p.add_argument("--speed", nargs=2, required=True, metavar=("MIN", "MAX"), help="spindle speeds, rpm")
    p.add_argument("--points", type=int, default=50, help="number of speeds (default 50)")
    p.add_argument("--width", required=True, metavar="W", help="depth of cut, mm (milling a_p, turning b)")
    p.add_argument(
        "--feed",
        metavar="MM",
        help="feed per tooth (milling) or per revolution (turning), mm (default: the model's feed_per_tooth"
        " or [machine] feed)",
    )
    p.add_argument("--eccentricity", metavar="MM", help="turning: the workpiece's eccentricity e, mm")
    p.add_argument("--position", metavar="S", help="slide position s, m (default: the model's)")
    p.add_argument(
        "--method",
        choices=["spectral", "sdm"],
        help="milling: the discretisation of the one-period map whose fixed point is the orbit: spectral"
        " elements (default) or first-order semi-discretisation",
    )
    p.add_argument("--steps", type=int, default=40, metavar="M", help="sdm: steps per period (default 40)")
    p.add_argument(
        "--no-check", action="store_true", help="no convergence check per speed (degree raised, or 2 x steps)"
    )
    p.add_argument("--no-lobes", action="store_true", help="--plot the SLE alone, without the lobes above it")
    p.add_argument("--out", metavar="FILE.csv|FILE.nc|FILE.json", help="the SLE (or amplitude) per speed")
    p.add_argument("--plot", metavar="FILE.png", help="the SLE under the lobes (turning: the amplitude)")


def run(args: argparse.Namespace) -> int:
    with outputs(args, (args.out, "--out", DATA_SUFFIXES + JSON_SUFFIXES), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:  # fmt: skip
        return _run(args, outs)


def _mm(text: Any, option: str, *, zero: bool = False) -> float:
    from ._units import quantity

    v = quantity(text, option, "mm")
    if not (math.isfinite(v) and (v >= 0 if zero else v > 0)):
        raise InputError(f"{option} {text}: must be a finite number {'>= 0' if zero else '> 0'} (mm)")
    return v * 1e-3


def _typed(option: str) -> bool:
    from ._milling import _typed as typed

    return typed(option)


def _speeds(args: argparse.Namespace, model: Any) -> Any:
    from ._lobes import speeds

    n = check_count(args.points, "--points", 2)
    if n > 2000:
        raise InputError(f"--points {n}: at most 2000 speeds (each is a forced-response solve)")
    return speeds(args, model.process)


def _feed(args: argparse.Namespace, model: Any, fallback: float) -> float:
    if args.feed is not None:
        return _mm(args.feed, "--feed", zero=True)
    if fallback > 0:
        return fallback
    mach = model.machine
    if mach is not None and math.isfinite(mach.feed):
        return float(mach.feed)
    return 0.0


def _position(args: argparse.Namespace) -> float | None:
    if args.position is None:
        return None
    from ._units import quantity

    return quantity(args.position, "--position", "m")


def _run(args: argparse.Namespace, outs: Any) -> int:
    model = load(args)
    proc = model.process
    if proc is None or proc.kind not in ("milling", "turning"):
        raise InputError(
            f'{model.source}: sle needs a milling or turning [process] (kind = "milling" or "turning")'
        )
    v = _speeds(args, model)
    if proc.kind == "milling":
        if args.eccentricity is not None:
            raise InputError(
                "--eccentricity is for turning; a milling cut's SLE comes from its feed per tooth"
            )
        res, lobes = _milling(args, model, v)
        res = _mesh(args, model, res)
    else:
        if args.no_lobes:
            raise InputError("--no-lobes is for milling's SLE plot; the turning plot has no lobes")
        if args.method is not None or _typed("--steps"):
            raise InputError(
                "--method and --steps are for milling's one-period map; the turning runout response is the"
                " closed loop's FRF at the spindle frequency: drop them"
            )
        res, lobes = _turning(args, model, v), None
    write_result(
        res, args, outs, model=model, plot=(lambda: res.plot(lobes=lobes)) if lobes is not None else None
    )
    if any(x != "stable" for x in res.verdict):
        return 1
    return 0


def _milling(args: argparse.Namespace, model: Any, v: Any) -> tuple[Any, Any]:
    from ..frequency._forced import generation_angle, surface_location
    from ._milling import _helix_cost, _structure, refuse_unused
    from ._milling import _speeds as check_rpm

    method: Literal["spectral", "sdm"] = "sdm" if args.method == "sdm" else "spectral"
    refuse_unused(args, method)
    steps = check_count(args.steps, "--steps", 2)
    check_rpm(v, "--speed")
    a = width_m(args)
    cut = model.process.milling
    feed = _feed(args, model, cut.feed_per_tooth)
    if feed == 0.0 and cut.Kte == 0.0 and cut.Kne == 0.0:
        raise InputError(
            f"{model.source}: no feed and no edge forces, so the cut has no static force and no SLE: give --feed"
            " MM (or [process] feed_per_tooth)"
        )
    if cut.helix > 0:
        raise InputError(
            f"{model.source}: the SLE is computed for straight teeth (helix_deg = 0); a helical flute generates"
            " the wall along its length at different instants"
        )
    loop, mill, note = _structure(model, _position(args), args)
    generation_angle(mill)
    _helix_cost(mill, a)
    if note:
        print(note)
    bar = None if args.quiet else progress_bar(f"surface location ({len(v)} speeds)")
    done = [0]

    def tick() -> None:
        done[0] += 1
        if bar is not None:
            bar(done[0] / len(v))

    res = surface_location(
        loop, v, a, feed, method=method, steps=steps, check=not args.no_check, progress=tick
    )
    res = dataclasses.replace(res, name=model.name or str(model.source))
    print(res.summary())
    lobes = None
    if args.plot and not args.no_lobes:
        from ..lobes._milling import milling_ceiling, milling_lobes

        wmax, _ = milling_ceiling(loop, v)
        lobes = milling_lobes(loop, v, method=method, steps=steps, depth_max=max(wmax, 1.5 * a))
    return res, lobes


def _mesh(args: argparse.Namespace, model: Any, res: Any) -> Any:
    """A milling model with beams: the SLE's critical speeds computed again
    on the mesh twice as fine (:func:`chatterlab.cli._mesh_checks.sle_check`),
    its lines printed, its facts in the files; ``res`` unchanged without beams."""
    if not model.beams:
        return res
    from ..frequency._forced import surface_location
    from ._mesh_checks import sle_check, sle_picks
    from ._milling import _structure

    picks = sle_picks(res)
    if not picks:
        print(f"mesh: {model.beam_elements} beam elements; no speed with a verdict to check on a finer mesh")
        return res
    loop, _, _ = _structure(model.with_finer_mesh(), _position(args), args)
    method: Literal["spectral", "sdm"] = "sdm" if args.method == "sdm" else "spectral"
    fine = surface_location(
        loop, res.speeds[picks], res.depth, res.feed, method=method, steps=args.steps, check=not args.no_check
    )
    out, _, lines = sle_check(model, res, fine, picks)
    for line in lines:
        print(line)
    return out


def _turning(args: argparse.Namespace, model: Any, v: Any) -> Any:
    import numpy as np

    from ..frequency._forced import runout_response
    from ..process._loop import closed_loop
    from ..structure._assembly import assemble

    if args.eccentricity is None:
        raise InputError("turning: give the workpiece's eccentricity with --eccentricity MM")
    e = _mm(args.eccentricity, "--eccentricity", zero=True)
    feed = _feed(args, model, 0.0)
    if feed <= 0.0:
        raise InputError("turning: give the feed per revolution with --feed MM (or [machine] feed)")
    regen = [c for c in model.couplings if c.kind == "regenerative"]
    if len(regen) != 1:
        raise InputError(
            f'{model.source}: sle for turning takes one model = "regenerative" coupling (its K_f and direction)'
        )
    c = regen[0]
    deg = math.degrees(c.angle) % 180.0
    if min(deg, 180.0 - deg) <= 1e-9:
        axis = "x"
    elif abs(deg - 90.0) <= 1e-9:
        axis = "y"
    else:
        raise InputError(
            f"{model.source}: coupling {c.id} cuts at {math.degrees(c.angle):g} deg; the runout response is"
            " computed along x or y (angle 0 or 90 deg)"
        )
    named = [pt.id for pt in model.points if pt.ref == c.a]
    if not named and c.a.kind in ("body", "node") and c.a.offset == (0.0, 0.0):
        named = [c.a.target]  # a body's (node's) own name is a point: its reference point
    if not named:
        raise InputError(
            f"{model.source}: coupling {c.id}'s tool side is not a named [[point]]: name it to read its response"
        )
    point = f"{named[0]}.{axis}"
    kf = dict(c.params).get("Kf")
    if kf is None:
        raise InputError(f"{model.source}: coupling {c.id} has no Kf")
    b = width_m(args)
    pos = _position(args)
    loop = closed_loop(assemble(model).at(pos), width=b, speed=float(v[0]))
    res = runout_response(loop, v, e, feed, float(kf), inputs=point, outputs=point)
    lines: list[str] = []
    if model.beams:
        res, lines = _turning_mesh(model, res, loop.terms, pos, float(kf), point)
    ok = np.array([x == "stable" for x in res.verdict])
    head = (
        f"runout response: {model.name or model.source}, b = {b * 1e3:.4g} mm, e = {e * 1e3:.4g} mm,"
        f" h_0 = {feed * 1e3:.4g} mm: force amplitude K_f h_0 e = {res.force:.4g} N at the spindle frequency\n"
        f"{len(v)} speeds {v[0]:g}..{v[-1]:g} rpm: {int(ok.sum())} stable,"
        f" {res.verdict.count('unstable')} unstable (chatter, no response), {res.verdict.count('undetermined')}"
        " undetermined"
    )
    if ok.any():
        amp = res.amplitude[ok]
        i = int(amp.argmax())
        head += (
            f"\namplitude {amp.min() * 1e6:.4g} to {amp.max() * 1e6:.4g} um (largest at {v[ok][i]:.6g} rpm);"
            " the runout is not regenerated"
        )
    print(head)
    for line in lines:
        print(line)
    return res


#: the ceiling of the limits a turning model's verdicts are judged against on both meshes: the
#: larger of this and TURNING_CEILING_FACTOR times the width (m)
TURNING_CEILING = 0.02
TURNING_CEILING_FACTOR = 4.0


def _turning_mesh(
    model: Any, res: Any, terms: Any, position: Any, kf: float, point: str
) -> tuple[Any, list[str]]:
    """A turning model with beams: the whole runout response again on the
    mesh twice as fine (an FRF and a verdict per speed on a model twice the
    size: two to three times the response's own cost, measured), the limit
    b_lim at each speed on both meshes on the lobes' own claim
    (:func:`~chatterlab.cli._mesh_checks.established_limits`), each verdict judged by
    :func:`chatterlab.cli._mesh_checks.runout_check`.  ``(result with its mesh
    record, the lines to print)``."""
    import time

    from ..frequency._forced import runout_response
    from ..process._loop import closed_loop
    from ..structure._assembly import assemble
    from ._mesh_checks import established_limits, runout_check

    t0 = time.perf_counter()
    b, v = float(res.width), res.speeds
    ceiling = max(TURNING_CEILING, TURNING_CEILING_FACTOR * b)
    fine_model = model.with_finer_mesh()
    fz2 = assemble(fine_model).at(position)
    loop2 = closed_loop(fz2, width=b, speed=float(v[0]))
    fine = runout_response(loop2, v, res.eccentricity, res.feed, kf, inputs=point, outputs=point)
    # on each diagram's own claim: NaN where it establishes nothing (width_verdict: undetermined)
    limits = [established_limits(m, v, ceiling, position, terms=terms) for m in (model, fine_model)]
    out, record, lines = runout_check(model, res, fine, *limits)
    record["mesh_width_max_m"] = ceiling
    record["mesh_seconds"] = time.perf_counter() - t0
    return out, lines
