"""The ``chatterlab`` command line (argparse).

Units at this edge: frequencies in Hz, width of cut in mm, the cutting speed
in the process's unit (shaping: m/s, turning: rpm), delay and positions in SI
(s, m).  Every input error prints one line ``chatterlab: error: ...`` and
exits with status 2; no traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from typing import Any

from .errors import ChatterlabError, InputError

__all__ = ["main", "build_parser"]

COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {}


def _command(name: str) -> Callable[[Callable[[argparse.Namespace], int]], Callable[[argparse.Namespace], int]]:
    def deco(fn: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
        COMMANDS[name] = fn
        return fn

    return deco


# ----------------------------------------------------------------------------- helpers


def _parse_set(items: Sequence[str] | None) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for it in items or []:
        if "=" not in it:
            raise InputError(f"--set {it!r}: write PATH=VALUE, e.g. --set spring.leg3-foundation.c2=7e8")
        k, v = it.split("=", 1)
        try:
            out[k.strip()] = json.loads(v)
        except json.JSONDecodeError:
            out[k.strip()] = v
    return out


def _load(args: argparse.Namespace) -> Any:
    from .modelfile import load_model

    return load_model(args.model, variant=getattr(args, "variant", None), overrides=_parse_set(getattr(args, "set", None)))


def _frozen(args: argparse.Namespace) -> Any:
    from .assembly import assemble

    return assemble(_load(args)).at(getattr(args, "position", None))


def _width_m(args: argparse.Namespace) -> float:
    if args.width is None:
        raise InputError("--width is required here: the width of cut b in mm")
    if not args.width > 0:
        raise InputError(f"--width must be > 0 mm (got {args.width:g})")
    return args.width * 1e-3


def _emit(text: str, out: str | None) -> None:
    if out:
        with open(out, "w") as fh:
            fh.write(text if text.endswith("\n") else text + "\n")
    else:
        sys.stdout.write(text if text.endswith("\n") else text + "\n")


def _model_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", help="model file (TOML, see docs/model-format.md)")
    p.add_argument("--variant", help="use the [variant.NAME] parameter set of the file")
    p.add_argument(
        "--set",
        action="append",
        metavar="PATH=VALUE",
        help="change one model parameter, e.g. --set spring.leg3-foundation.c2=7e8 (repeatable)",
    )


def _cut_args(p: argparse.ArgumentParser, required_width: bool = False) -> None:
    p.add_argument("--width", type=float, required=required_width, metavar="B", help="width of cut b, mm")
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--speed",
        type=float,
        metavar="V",
        help="cutting speed in the model's process unit (shaping: work speed m/s; turning: rpm)",
    )
    g.add_argument("--delay", type=float, metavar="T", help="delay between passes T, s")
    p.add_argument(
        "--terms",
        choices=["pdo", "pd", "o"],
        default="pdo",
        help="feedback terms: pdo = proportional+derivative+delayed (paper case c, default), "
        "pd = without delay (case b), o = delayed only",
    )


# ----------------------------------------------------------------------------- commands


@_command("check")
def _check(args: argparse.Namespace) -> int:
    from .assembly import assemble

    model = _load(args)
    sy = assemble(model)
    summ = sy.summary()
    if args.format == "json":
        _emit(json.dumps(summ, indent=2), None)
        return 0
    print(f"{model.source}: OK  ({model.name}{', variant ' + model.variant if model.variant else ''})")
    rows = [
        ("rigid bodies (RFE)", summ["bodies"]),
        ("moving contact points", summ["contacts"]),
        ("beams (DFE) / elements", f"{summ['beams']} / {summ['beam elements']}"),
        ("nodes", summ["nodes"]),
        ("springs (SDE)", summ["springs"]),
        ("rigid attachments", summ["attachments"]),
        ("coupling elements (CE)", summ["couplings"]),
        ("coordinates", summ["coordinates"]),
        ("  independent q_i", summ["independent"]),
        ("  dependent q_d", summ["dependent"]),
        ("  given q_g", summ["given"]),
    ]
    if model.movable is not None:
        mv = model.movable
        rows.append(("movable bodies", ", ".join(mv.bodies)))
        rows.append(("position / range [m]", f"{mv.position:g} / [{mv.range[0]:g}, {mv.range[1]:g}]"))
    if model.process is not None:
        pr = model.process
        rows.append(("process", f"{pr.kind}, {pr.speed_name} {pr.speed:g} {pr.speed_unit}, T = {pr.delay():.6g} s"))
    for k, v in rows:
        print(f"  {k:<26} {v}")
    return 0


@_command("modes")
def _modes(args: argparse.Namespace) -> int:
    from .assembly import assemble
    from .modal import modes

    if args.count is not None and args.count < 1:
        raise InputError(f"--count must be >= 1 (got {args.count})")
    sy = assemble(_load(args))
    md = modes(sy, count=args.count, position=args.position, rigid="report" if args.allow_rigid else "error")
    if args.format == "json":
        _emit(md.to_json(), args.out)
    elif args.format == "csv":
        md.to_csv(args.out or sys.stdout)
    else:
        pos = "" if md.position is None else f" at position s = {md.position:g} m"
        _emit(f"{sy.model.name}: natural frequencies{pos}\n" + md.table(), args.out)
    if args.plot:
        from .plot import savefig

        savefig(md.plot(), args.plot)
    return 0


@_command("frf")
def _frf(args: argparse.Namespace) -> int:
    from .cutting import feedback
    from .frf import frequencies, frf

    fz = _frozen(args)
    w = frequencies(args.fmin, args.fmax, args.points)
    fb = None
    if args.closed_loop:
        fb = feedback(fz, width=_width_m(args), speed=args.speed, delay=args.delay, terms=args.terms)
    elif args.width is not None or args.speed is not None or args.delay is not None:
        raise InputError("--width/--speed/--delay describe the cut: add --closed-loop to use them")
    res = frf(fz, w, inputs=args.input, outputs=args.output, kind=args.kind, feedback=fb, method=args.method)
    if args.format == "json":
        _emit(res.to_json(), args.out)
    else:
        res.to_csv(args.out or sys.stdout)
    if args.plot:
        from .plot import plot_frf, savefig

        curves = [res]
        if fb is not None:
            curves = [frf(fz, w, inputs=args.input, outputs=args.output, kind=args.kind, method=args.method), res]
        savefig(plot_frf(curves, title=f"{fz.model.name}: {args.output[0]} / {args.input[0]}", peaks=2), args.plot)
        print(f"wrote {args.plot}", file=sys.stderr)
    return 0


# ----------------------------------------------------------------------------- parser


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    p = argparse.ArgumentParser(
        prog="chatterlab",
        description="Machining chatter from structural models (RDFEM): modes, FRFs, roots, transients, lobes.",
    )
    p.add_argument("--version", action="version", version=f"chatterlab {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    c = sub.add_parser("check", help="validate a model file and summarise it")
    _model_args(c)
    c.add_argument("--format", choices=["table", "json"], default="table")

    m = sub.add_parser("modes", help="natural frequencies and mode shapes at a frozen configuration")
    _model_args(m)
    m.add_argument("--position", type=float, metavar="S", help="slide position s, m (default: the model's)")
    m.add_argument("--count", type=int, metavar="N", help="number of lowest modes (default: all)")
    m.add_argument("--format", choices=["table", "json", "csv"], default="table")
    m.add_argument("--out", metavar="FILE", help="write to FILE instead of standard output")
    m.add_argument("--plot", metavar="FILE.png", help="bar chart of the frequencies")
    m.add_argument("--allow-rigid", action="store_true", help="report rigid-body modes instead of refusing them")

    f = sub.add_parser("frf", help="open- or closed-loop frequency response between named points")
    _model_args(f)
    f.add_argument("--input", action="append", required=True, metavar="P.DIR", help="force input, e.g. rfe5.x")
    f.add_argument("--output", action="append", required=True, metavar="P.DIR", help="response, e.g. rfe5.x")
    f.add_argument("--fmin", type=float, default=1.0, help="lowest frequency, Hz (default 1)")
    f.add_argument("--fmax", type=float, default=300.0, help="highest frequency, Hz (default 300)")
    f.add_argument("--points", type=int, default=2000, help="number of frequencies (default 2000)")
    f.add_argument("--position", type=float, metavar="S", help="slide position s, m")
    f.add_argument("--closed-loop", action="store_true", help="include the cutting process (needs --width)")
    _cut_args(f)
    f.add_argument("--kind", choices=["receptance", "mobility", "accelerance"], default="receptance")
    f.add_argument("--method", choices=["direct", "modal"], default="direct")
    f.add_argument("--format", choices=["csv", "json"], default="csv")
    f.add_argument("--out", metavar="FILE")
    f.add_argument("--plot", metavar="FILE.png", help="magnitude/phase plot (open vs closed loop)")

    for extra in _EXTRA_PARSERS:
        extra(sub)
    return p


_EXTRA_PARSERS: list[Callable[[Any], None]] = []


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``chatterlab`` command; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not args.command:
        parser.print_help()
        return 2
    try:
        return COMMANDS[args.command](args)
    except ChatterlabError as exc:
        print(f"chatterlab: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("chatterlab: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # pragma: no cover - e.g. piping into head
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
