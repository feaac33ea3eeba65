"""``chatterlab frf``: open- or closed-loop frequency response between named
points, with its magnitude/phase plot and the Nyquist plot of the loop
determinant.  Frequencies are typed in Hz (``--fmin``, ``--fmax``)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..errors import InputError
from ..io._files import PLOT_SUFFIXES, Outputs
from ._common import FORMAT_SUFFIXES, cut_args, emit, frozen, model_args, outputs, width_m


def add_parser(sub: Any) -> None:
    f = sub.add_parser("frf", help="open- or closed-loop frequency response between named points")
    model_args(f)
    f.add_argument(
        "--input", action="append", required=True, metavar="P.DIR", help="force input, e.g. rfe5.x"
    )
    f.add_argument("--output", action="append", required=True, metavar="P.DIR", help="response, e.g. rfe5.x")
    f.add_argument("--fmin", default=1.0, help="lowest frequency, Hz (default 1)")
    f.add_argument("--fmax", default=300.0, help="highest frequency, Hz (default 300)")
    f.add_argument("--points", type=int, default=2000, help="number of frequencies (default 2000)")
    f.add_argument("--position", metavar="S", help="slide position s, m")
    f.add_argument("--closed-loop", action="store_true", help="include the cutting process (needs --width)")
    cut_args(f)
    f.add_argument("--kind", choices=["receptance", "mobility", "accelerance"], default="receptance")
    f.add_argument("--method", choices=["direct", "modal"], default="direct")
    f.add_argument(
        "--format",
        choices=["csv", "json"],
        default=None,
        help="table format (default csv); with --plot and no --out the table is printed only when asked for",
    )
    f.add_argument("--out", metavar="FILE")
    f.add_argument("--plot", metavar="FILE.png", help="magnitude/phase plot (open vs closed loop)")
    f.add_argument("--nyquist", metavar="FILE.png", help="Nyquist plot of the loop determinant det(I - G D)")


def run(args: argparse.Namespace) -> int:
    if not args.closed_loop and (args.width is not None or args.speed is not None or args.delay is not None):
        raise InputError("--width/--speed/--delay describe the cut: add --closed-loop to use them")
    if args.nyquist and not args.closed_loop:
        raise InputError("--nyquist draws det(I - G D) of the cutting loop: add --closed-loop --width ...")
    with outputs(
        args,
        (args.out, "--out", FORMAT_SUFFIXES[args.format or "csv"]),
        (args.plot, "--plot", PLOT_SUFFIXES),
        (args.nyquist, "--nyquist", PLOT_SUFFIXES),
    ) as outs:
        return _run(args, outs)


def _run(args: argparse.Namespace, outs: Outputs) -> int:
    from ..frequency._frf import frequencies, frf
    from ..process import closed_loop

    fz = frozen(args)
    w = frequencies(args.fmin, args.fmax, args.points)
    fb = None
    if args.closed_loop:
        fb = closed_loop(fz, width=width_m(args), speed=args.speed, delay=args.delay, terms=args.terms)
    if args.nyquist and (fb is None or fb.is_zero):
        raise InputError(
            "--nyquist draws det(I - G D) of the cutting loop, which is zero here: check --terms"
        )
    res = frf(
        fb if fb is not None else fz,
        w,
        inputs=args.input,
        outputs=args.output,
        kind=args.kind,
        method=args.method,
    )
    # a model with beams: the resonance peaks on the mesh twice as fine (None: no beams)
    mesh = _mesh(args, fz, w, res)
    if args.out or args.format or not (args.plot or args.nyquist):
        if args.format == "json":
            if mesh is None:
                emit(res.to_json(), outs.path(args.out) if args.out else None)
            else:
                from ..io._files import json_text

                doc = {**res.to_dict(), "mesh": mesh}
                emit(json_text(doc, indent=None), outs.path(args.out) if args.out else None)
        else:
            # magnitude, phase, real and imaginary part per pair, 17 digits; no comment lines (a plain table)
            res.to_csv(outs.path(args.out) if args.out else sys.stdout, form="both", comments=False)
    else:  # a picture was asked for: a line, not the whole table on the terminal
        print(
            f"frf: {len(res.frequency_hz)} frequencies, {res.data.shape[0]} output(s) x {res.data.shape[1]}"
            " input(s); add --out FILE to keep the table"
        )
    if mesh is not None and args.format != "json":
        from ._mesh_checks import frf_lines

        # the CSV on standard output stays a plain table: the lines go to standard error then
        to_err = not args.out and (args.format is not None or not (args.plot or args.nyquist))
        for line in frf_lines(fz.model, mesh):
            print(line, file=sys.stderr if to_err else sys.stdout)
    if args.nyquist and fb is not None:
        _nyquist(args, outs, fz, w, fb)
    if args.plot:
        from ..plot import savefig
        from ..plot._frf import plot_frf_pairs

        curves = [res]
        if fb is not None:
            curves = [
                frf(fz, w, inputs=args.input, outputs=args.output, kind=args.kind, method=args.method),
                res,
            ]
        savefig(plot_frf_pairs(curves, title=fz.model.name, peaks=2), outs.path(args.plot))
    return 0


def _mesh(args: argparse.Namespace, fz: Any, w: Any, res: Any) -> dict[str, Any] | None:
    """The resonance peaks of every (output, input) pair of ``res`` on the
    model's mesh and on the mesh twice as fine, with the bound of their
    discretisation error (:func:`chatterlab.cli._mesh_checks.frf_check`);
    None for a model without beams."""
    model = fz.model
    if not model.beams:
        return None
    import numpy as np

    from ..frequency._frf import frf
    from ..process import closed_loop
    from ..structure._assembly import assemble
    from ._mesh_checks import follow_peak, frf_check, frf_peaks, refine_peak

    fz2 = assemble(model.with_finer_mesh()).at(args.position)
    systems = [fz, fz2]
    if args.closed_loop:
        systems = [
            closed_loop(s, width=width_m(args), speed=args.speed, delay=args.delay, terms=args.terms)
            for s in systems
        ]
    f = np.asarray(res.frequency_hz, float)
    coarse: list[list[Any]] = []
    fine: list[list[Any]] = []
    names = []
    for o, out in enumerate(res.outputs):
        for i, inp in enumerate(res.inputs):
            names.append(f"{out}/{inp}")

            def mag(fhz: float, s: Any, out: str = out, inp: str = inp) -> float:
                r = frf(s, np.array([2 * np.pi * fhz]), inputs=[inp], outputs=[out], kind=args.kind,
                        method=args.method)  # fmt: skip
                return float(abs(r.data[0, 0, 0]))

            curve = np.abs(res.data[o, i])
            curve2 = np.abs(
                frf(systems[1], w, inputs=[inp], outputs=[out], kind=args.kind, method=args.method).data[0, 0]
            )
            ks = frf_peaks(curve)
            coarse.append([refine_peak(lambda x: mag(x, systems[0]), f, k) for k in ks])
            js = [follow_peak(curve2, k) for k in ks]
            # two peaks climbing to the same one on the finer mesh: only the nearest is that resonance
            for n, (k, j) in enumerate(zip(ks, js, strict=True)):
                if j is not None and any(
                    j == j2 and abs(k2 - j) < abs(k - j) for k2, j2 in zip(ks, js, strict=True)
                ):
                    js[n] = None
            fine.append([None if j is None else refine_peak(lambda x: mag(x, systems[1]), f, j) for j in js])
    return frf_check(model, coarse, fine, names)


def _nyquist(args: argparse.Namespace, outs: Outputs, fz: Any, w: Any, fb: Any) -> None:
    import numpy as np

    from ..frequency._frf import loop_determinant, resonance_grid
    from ..plot import plot_nyquist, savefig

    # resolve every resonance and the turning of e^{-jwT} (32 points per turn)
    n_turn = int(16 * (fb.delay or 0.0) * float(w[-1] - w[0]) / np.pi) + 1
    wn = resonance_grid(fz.complex_modes.lam, float(w[0]), float(w[-1]), min(max(w.size, n_turn), 400_000))
    det = loop_determinant(fb, wn)
    title = f"{fz.model.name}: det(I - G D), b = {args.width:g} mm"
    savefig(plot_nyquist(wn, det, title=title), outs.path(args.nyquist))
