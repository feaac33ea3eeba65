"""The ``chatterlab`` command line (argparse).

Units at this edge: frequencies in Hz, width of cut in mm, the cutting speed
in the process's unit (shaping: m/s, turning: rpm), delay and positions in SI
(s, m).  Every input error prints one line ``chatterlab: error: ...`` and
exits with status 2; no traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, Literal

from ..errors import (
    ChatterlabError,
    InputError,
    check_axis_values,
    check_count,
    check_delay,
    check_nonneg,
    check_position,
    check_positive,
    check_speed,
    check_width,
)
from ..io._files import (
    CSV_SUFFIXES,
    DATA_SUFFIXES,
    JSON_SUFFIXES,
    PLOT_SUFFIXES,
    TEXT_SUFFIXES,
    Outputs,
    json_text,
)

__all__ = ["main", "build_parser"]

COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {}


def _command(
    name: str,
) -> Callable[[Callable[[argparse.Namespace], int]], Callable[[argparse.Namespace], int]]:
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
        if not k.strip():
            raise InputError(
                f"--set {it!r}: the PATH before '=' is empty, e.g. --set spring.leg3-foundation.c2=7e8"
            )
        try:
            out[k.strip()] = json.loads(v)
        except json.JSONDecodeError:
            out[k.strip()] = v
        except (ValueError, RecursionError):  # a 5000-digit integer, arrays nested 10^5 deep
            raise InputError(
                f"--set {k.strip()}: the value is not a usable number or list (too large or nested too deeply)"
            ) from None
    return out


def _load(args: argparse.Namespace) -> Any:
    from ..model._reader import load_model

    model = load_model(
        args.model,
        variant=getattr(args, "variant", None),
        overrides=_parse_set(getattr(args, "set", None)),
        files_outside=getattr(args, "allow_outside_files", False),
    )
    _warn(args, _model_slips(model, args))
    return model


def _frozen(args: argparse.Namespace) -> Any:
    from ..structure._assembly import assemble

    fz = assemble(_load(args)).at(getattr(args, "position", None))
    _warn(args, _frequency_slips(fz))
    return fz


def _width_m(args: argparse.Namespace) -> float:
    if args.width is None:
        raise InputError("--width is required here: the width of cut b in mm")
    b = check_width(args.width, "--width", "mm") * 1e-3
    _warn(args, _width_slips(b, "--width"))
    return b


# ----------------------------------------------------------------------------- unit slips
# A number off by a factor 1000 (mm typed for m, N/mm^2 for N/m^2) gives a
# confident answer; these ranges cover real machines with a wide margin, and
# a value outside them is named on one line of standard error (--quiet: none).


#: warnings of the running command: printed when it has run (an input error
#: is one line on its own, so they are dropped then)
_WARNINGS: list[str] = []


def _warn(args: argparse.Namespace, lines: list[str]) -> None:
    if not getattr(args, "quiet", False):
        _WARNINGS.extend(f"chatterlab: warning: {line}" for line in lines if line not in _WARNINGS)


def _flush_warnings() -> None:
    for line in dict.fromkeys(_WARNINGS):
        print(line, file=sys.stderr)
    _WARNINGS.clear()


def _width_slips(b: float, option: str) -> list[str]:
    if b < 1e-6:
        return [f"{option} is {b * 1e3:g} mm, below 1 um: was the width typed in m? (the CLI takes mm)"]
    if b > 1.0:
        return [f"{option} is {b * 1e3:g} mm, above 1 m: was the width typed in um?"]
    return []


def _model_slips(model: Any, args: argparse.Namespace) -> list[str]:
    import numpy as np

    out = []
    for c in model.couplings:
        kf = float(np.max(np.abs(np.asarray(c.DO, float)))) / c.width_ref
        if kf and not 1e7 <= kf <= 1e11:
            out.append(
                f"coupling '{c.id}': delayed cutting stiffness {kf:.3g} N/m^2 per unit width is outside"
                " 1e7..1e11 N/m^2: were the coefficients given in N/mm^2 or width_ref in mm?"
            )
    xy = [b.centre for b in model.bodies] + [n.xy for n in model.nodes]
    if len(xy) > 1:
        span = float(np.ptp(np.asarray(xy, float), axis=0).max())
        if 0 < span < 1e-3 or span > 100.0:
            out.append(
                f"the structure spans {span:g} m: outside 1 mm..100 m; were the coordinates given in mm?"
            )
    proc = model.process
    speed = getattr(args, "speed", None)
    limits = {"shaping": (1e-3, 10.0), "turning": (1.0, 1e5)}
    if proc is not None and proc.kind in limits:
        lo, hi = limits[proc.kind]
        given = speed if isinstance(speed, list | tuple) else [speed]
        for what, v in [("the model's speed", proc.speed)] + [("--speed", x) for x in given]:
            if v is not None and v > 0 and not lo <= v <= hi:
                out.append(
                    f"{what} {v:g} {proc.speed_unit} is outside {lo:g}..{hi:g} {proc.speed_unit}"
                    f" ({proc.kind}): is it in the right unit?"
                )
    return out


def _frequency_slips(fz: Any) -> list[str]:
    import numpy as np

    f = np.abs(fz.complex_modes.lam) / (2 * np.pi)
    f = f[f > 0]
    out = []
    if f.size and f.min() < 0.1:
        out.append(
            f"the lowest natural frequency is {f.min():.3g} Hz, below 0.1 Hz: a mass or stiffness unit slip?"
        )
    if f.size and f.max() > 1e5:
        out.append(
            f"the highest natural frequency is {f.max():.3g} Hz, above 100 kHz: a mass or stiffness unit slip?"
        )
    return out


def _terms_slips(args: argparse.Namespace) -> list[str]:
    if getattr(args, "terms", "pdo") == "pd" and (args.delay is not None or args.speed is not None):
        opt = "--delay" if args.delay is not None else "--speed"
        return [f"{opt} has no effect with --terms pd (no delayed term); use --terms pdo or o for the delay"]
    return []


def _check_numbers(args: argparse.Namespace, unit: str = "") -> None:
    """Every numeric option through the one validator set (chatterlab.errors),
    before the model is assembled: a width, speed or delay must be > 0, a
    position finite, a count a whole number; ``unit`` is the process's speed unit."""
    if getattr(args, "width", None) is not None:
        check_width(args.width, "--width", "mm")
    if getattr(args, "width_max", None) is not None:
        check_width(args.width_max, "--width-max", "mm")
    speed = getattr(args, "speed", None)
    if isinstance(speed, list):
        for v in speed:
            check_speed(v, "--speed", unit)
    elif speed is not None:
        check_speed(speed, "--speed", unit)
    if getattr(args, "delay", None) is not None:
        check_delay(args.delay, "--delay")
    if getattr(args, "position", None) is not None:
        check_position(args.position, "--position")
    for name in ("fmin", "fmax"):
        if getattr(args, name, None) is not None:
            check_nonneg(getattr(args, name), f"--{name}", "Hz")
    for name, unit_ in (("duration", "s"), ("step", "s")):
        if getattr(args, name, None) is not None:
            check_positive(getattr(args, name), f"--{name}", unit_)
    for name, least in (("points", 1), ("passes", 1), ("verify", 0), ("confirm", 0)):
        if getattr(args, name, None) is not None:
            check_count(getattr(args, name), f"--{name}", least)
    if getattr(args, "count", None) is not None:
        check_count(args.count, "--count", 1)


def _emit(text: str, out: str | None) -> None:
    """``text`` to the (staged) file ``out``, or to standard output."""
    if out:
        with open(out, "w") as fh:
            fh.write(text if text.endswith("\n") else text + "\n")
    else:
        sys.stdout.write(text if text.endswith("\n") else text + "\n")


_FORMAT_SUFFIXES = {"table": TEXT_SUFFIXES, "json": JSON_SUFFIXES, "csv": CSV_SUFFIXES}


@contextlib.contextmanager
def _outputs(args: argparse.Namespace, *specs: tuple[str | None, str, tuple[str, ...]]) -> Iterator[Outputs]:
    """Check every output of the command before it computes (suffix,
    directory, writability, not an input, not named twice); the command
    writes to ``outs.path(FILE)``; the files are moved into place together
    when it returns, and removed if it raises (docs/cli.md, "Output files")."""
    inputs = [args.model] if getattr(args, "model", None) else []
    outs = Outputs(inputs=inputs)
    for path, option, suffixes in specs:
        outs.add(path, option, suffixes)
    try:
        yield outs
    except BaseException:
        outs.discard()
        raise
    outs.commit(note=lambda msg: print(msg, file=sys.stderr))


def _model_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", help="model file (TOML, see docs/model-format.md)")
    p.add_argument("--variant", help="use the [variant.NAME] parameter set of the file")
    p.add_argument(
        "--set",
        action="append",
        metavar="PATH=VALUE",
        help="change one model parameter, e.g. --set spring.leg3-foundation.c2=7e8 (repeatable)",
    )
    p.add_argument(
        "--allow-outside-files",
        action="store_true",
        help="let [matrices] name files outside the model file's folder (../K.npy, absolute paths)",
    )
    p.add_argument(
        "--quiet", action="store_true", help="no progress bar and no warnings about implausible magnitudes"
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
    from ..structure._assembly import assemble

    model = _load(args)
    sy = assemble(model)
    summ = sy.summary()
    if args.format == "json":
        _emit(json_text(summ), None)
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
        rows.append(
            ("process", f"{pr.kind}, {pr.speed_name} {pr.speed:g} {pr.speed_unit}, T = {pr.delay():.6g} s")
        )
    for k, v in rows:
        print(f"  {k:<26} {v}")
    return 0


@_command("modes")
def _modes(args: argparse.Namespace) -> int:
    from ..structure._assembly import assemble
    from ..structure._modal import modes

    with _outputs(
        args, (args.out, "--out", _FORMAT_SUFFIXES[args.format]), (args.plot, "--plot", PLOT_SUFFIXES)
    ) as outs:
        sy = assemble(_load(args))
        md = modes(
            sy, count=args.count, position=args.position, rigid="report" if args.allow_rigid else "error"
        )
        out = outs.path(args.out) if args.out else None
        if args.format == "json":
            _emit(md.to_json(), out)
        elif args.format == "csv":
            md.to_csv(out or sys.stdout)
        else:
            pos = "" if md.position is None else f" at position s = {md.position:g} m"
            _emit(f"{sy.model.name}: natural frequencies{pos}\n" + md.table(), out)
        if args.plot:
            from ..plot._plot import savefig

            savefig(md.plot(), outs.path(args.plot))
    return 0


@_command("frf")
def _frf(args: argparse.Namespace) -> int:

    if not args.closed_loop and (args.width is not None or args.speed is not None or args.delay is not None):
        raise InputError("--width/--speed/--delay describe the cut: add --closed-loop to use them")
    if args.nyquist and not args.closed_loop:
        raise InputError("--nyquist draws det(I - G D) of the cutting loop: add --closed-loop --width ...")
    with _outputs(
        args,
        (args.out, "--out", _FORMAT_SUFFIXES[args.format]),
        (args.plot, "--plot", PLOT_SUFFIXES),
        (args.nyquist, "--nyquist", PLOT_SUFFIXES),
    ) as outs:
        return _frf_run(args, outs)


def _frf_run(args: argparse.Namespace, outs: Outputs) -> int:
    from ..frequency._frf import frequencies, frf
    from ..process._cutting import feedback

    fz = _frozen(args)
    w = frequencies(args.fmin, args.fmax, args.points)
    fb = None
    if args.closed_loop:
        fb = feedback(fz, width=_width_m(args), speed=args.speed, delay=args.delay, terms=args.terms)
    if args.nyquist and (fb is None or fb.is_zero):
        raise InputError(
            "--nyquist draws det(I - G D) of the cutting loop, which is zero here: check --terms"
        )
    res = frf(fz, w, inputs=args.input, outputs=args.output, kind=args.kind, feedback=fb, method=args.method)
    if args.format == "json":
        _emit(res.to_json(), outs.path(args.out) if args.out else None)
    else:
        res.to_csv(outs.path(args.out) if args.out else sys.stdout)
    if args.nyquist and fb is not None:
        import numpy as np

        from ..frequency._frf import loop_determinant, resonance_grid
        from ..plot._plot import plot_nyquist, savefig

        # resolve every resonance and the turning of e^{-jwT} (32 points per turn)
        n_turn = int(16 * (fb.delay or 0.0) * float(w[-1] - w[0]) / np.pi) + 1
        wn = resonance_grid(
            fz.complex_modes.lam, float(w[0]), float(w[-1]), min(max(w.size, n_turn), 400_000)
        )
        det = loop_determinant(fz, wn, fb)
        title = f"{fz.model.name}: det(I - G D), b = {args.width:g} mm"
        savefig(plot_nyquist(wn, det, title=title), outs.path(args.nyquist))
    if args.plot:
        from ..plot._plot import plot_frf, savefig

        curves = [res]
        if fb is not None:
            curves = [
                frf(fz, w, inputs=args.input, outputs=args.output, kind=args.kind, method=args.method),
                res,
            ]
        savefig(
            plot_frf(curves, title=f"{fz.model.name}: {args.output[0]} / {args.input[0]}", peaks=2),
            outs.path(args.plot),
        )
    return 0


@_command("roots")
def _roots(args: argparse.Namespace) -> int:

    with _outputs(args, (args.out, "--out", _FORMAT_SUFFIXES[args.format])) as outs:
        return _roots_run(args, outs)


def _roots_run(args: argparse.Namespace, outs: Outputs) -> int:
    from ..frequency._stability import stability

    _warn(args, _terms_slips(args))
    fz = _frozen(args)
    st = stability(
        fz,
        width=_width_m(args),
        speed=args.speed,
        delay=args.delay,
        terms=args.terms,
        count=args.count,
        winding=not args.no_winding,
    )
    out = outs.path(args.out) if args.out else None
    if args.format == "json":
        _emit(json_text(st.to_dict()), out)
    else:
        _emit(st.table(), out)
    return 0


def _speeds(args: argparse.Namespace, proc: Any) -> Any:
    import numpy as np

    lo, hi = (check_speed(v, "--speed MIN MAX", proc.speed_unit) for v in args.speed)
    if not hi > lo:
        raise InputError(f"--speed range is empty or reversed: MAX ({hi:g}) must exceed MIN ({lo:g})")
    if args.points < 2:
        raise InputError(f"--points must be >= 2 (got {args.points})")
    return np.linspace(lo, hi, args.points)


@_command("lobes")
def _lobes(args: argparse.Namespace) -> int:
    with _outputs(args, (args.out, "--out", DATA_SUFFIXES), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:
        _check_checkpoint(args, outs)
        return _lobes_run(args, outs)


def _lobes_run(args: argparse.Namespace, outs: Outputs) -> int:
    from ..structure._assembly import assemble

    model = _load(args)
    if model.process is None:
        raise InputError(f"{model.source} has no [process] table: add one so that speeds map to delays")
    v = _speeds(args, model.process)
    wmax = check_width(args.width_max, "--width-max", "mm") * 1e-3
    _warn(args, _width_slips(wmax, "--width-max"))
    sy = assemble(model)
    if args.positions is not None:
        return _atlas(args, model, v, wmax, outs)
    from ..lobes._diagram import lobes

    d = lobes(
        sy.at(args.position),
        v,
        width_max=wmax,
        terms=args.terms,
        fmin=args.fmin,
        fmax=args.fmax,
        verify=args.verify,
    )
    if args.confirm:
        from ..lobes._confirm import confirm

        conf = confirm(sy, d, count=args.confirm)
        d = dataclasses.replace(d, meta={**d.meta, "confirm": conf.summary_line()})
        print(conf.table(), file=sys.stderr)
    print(d.summary())
    if args.out:
        if args.out.lower().endswith(".csv"):
            d.to_csv(outs.path(args.out))
        else:
            d.to_netcdf(outs.path(args.out), attrs={"model_text": model.text, "command": " ".join(sys.argv)})
    if args.plot:
        from ..plot._plot import savefig

        savefig(d.plot(), outs.path(args.plot))
    if d.verified is False:
        print(
            "chatterlab: the argument principle contradicts the diagram at the checks marked CHECK FAILED:"
            " treat the diagram as undetermined there",
            file=sys.stderr,
        )
        return 1
    return 0


def _sweep_opts(args: argparse.Namespace) -> dict[str, Any]:
    if args.jobs < 1 and args.jobs != -1:
        raise InputError(f"--jobs must be >= 1 (or -1 for all cores), got {args.jobs}")
    if args.scheduler and args.backend != "dask":
        raise InputError("--scheduler is for --backend dask")
    return {
        "security": _security(args),
        "jobs": args.jobs,
        "backend": args.backend,
        "scheduler": args.scheduler,
        "progress": not args.quiet,
        # a complete run's results are in --out: the default checkpoint OUT.ckpt has done its job
        # (removed under its lock); a partial run keeps it; a --checkpoint DIR is the user's
        "keep_checkpoint": bool(args.checkpoint) or not args.out,
    }


def _check_checkpoint(args: argparse.Namespace, outs: Outputs) -> None:
    """The checkpoint directory is neither an input nor an output file."""
    import os

    ck = _checkpoint(args)
    if ck is None:
        return
    real = os.path.realpath(ck)
    for name, what in (
        (args.model, "the model file"),
        (args.out, "--out"),
        (getattr(args, "plot", None), "--plot"),
    ):
        if name and os.path.realpath(name) == real:
            raise InputError(f"--checkpoint {ck!r} is {what}; give the checkpoint its own directory")
    if Path(ck).exists() and not Path(ck).is_dir():
        raise InputError(f"--checkpoint {ck!r} exists and is not a directory")


def _security(args: argparse.Namespace) -> Any:
    """dask TLS settings for a remote --scheduler tls://..., or None."""
    files = {"--tls-ca-file": args.tls_ca_file, "--tls-cert": args.tls_cert, "--tls-key": args.tls_key}
    given = {k: v for k, v in files.items() if v}
    tls = bool(args.scheduler) and str(args.scheduler).startswith("tls://")
    if not given and not tls:
        return None
    if given and not tls:
        raise InputError(f"{', '.join(given)} need --backend dask --scheduler tls://HOST:PORT")
    missing = [k for k, v in files.items() if not v]
    if missing:
        raise InputError(f"a tls:// scheduler needs {', '.join(files)}; missing {', '.join(missing)}")
    for k, v in files.items():
        if not Path(v).is_file():
            raise InputError(f"{k} {v!r}: no such file")
    try:
        from distributed.security import Security
    except ImportError:
        raise InputError("--backend dask needs dask.distributed: pip install chatterlab[dask]") from None
    return Security(
        tls_ca_file=args.tls_ca_file,
        tls_client_cert=args.tls_cert,
        tls_client_key=args.tls_key,
        require_encryption=True,
    )


def _checkpoint(args: argparse.Namespace) -> str | None:
    if args.checkpoint:
        return args.checkpoint
    if args.out:
        return args.out + ".ckpt"
    if args.resume:
        raise InputError("--resume needs --out FILE (the checkpoint is FILE.ckpt) or --checkpoint DIR")
    return None


def _atlas(args: argparse.Namespace, model: Any, v: Any, wmax: float, outs: Outputs) -> int:
    import numpy as np

    from ..quantities._tasks import AtlasTask, model_fingerprint
    from ..sweep._engine import sweep

    a = check_position(args.positions[0], "--positions A")
    b = check_position(args.positions[1], "--positions B")
    n = check_count(args.positions[2], "--positions N")
    if model.movable is not None:
        for x, nm in ((a, "--positions A"), (b, "--positions B")):
            check_position(x, nm, within=model.movable.range)
    if n > 1 and not b > a:
        raise InputError(f"--positions A B N: need B > A and N >= 1 (got {a:g} {b:g} {n})")
    pos = np.linspace(a, b, n)
    task = AtlasTask(
        model, wmax, tuple(float(x) for x in v), terms=args.terms, fmin=args.fmin, fmax=args.fmax
    )
    res = sweep(
        task,
        {"position": (pos, "m"), "speed": (v, model.process.speed_unit)},
        outputs={
            "b_lim": ("m", "largest chatter-free width of cut"),
            "chatter_frequency": ("Hz", "chatter frequency"),
        },
        chunk_size=v.size,
        checkpoint=_checkpoint(args),
        resume=args.resume,
        fingerprint=model_fingerprint(model) + f"|{wmax}|{args.terms}|{args.fmin}|{args.fmax}",
        attrs={"title": "chatterlab stability atlas", "model_text": model.text, "terms": args.terms},
        **_sweep_opts(args),
    )
    bl = res.data["b_lim"]
    worst = np.nanmin(np.where(np.isfinite(bl), bl, np.inf), axis=0)
    j = int(np.argmin(worst))
    i = int(np.argmin(bl[:, j]))
    print(
        f"stability atlas of {model.source}: {n} positions x {v.size} speeds ({res.status})\n"
        f"  worst case along the stroke: b_lim {worst[j] * 1e3:.4g} mm at {v[j]:.5g} {model.process.speed_unit},"
        f" position {pos[i]:.4g} m, chatter {res.data['chatter_frequency'][i, j]:.2f} Hz"
    )
    for k, p in enumerate(pos):
        print(f"  position {p:8.4f} m: min b_lim {np.nanmin(bl[k]) * 1e3:.4g} mm")
    if res.failures:
        print(f"  {len(res.failures)} task(s) failed: {res.message}", file=sys.stderr)
    if args.out:
        if args.out.lower().endswith(".csv"):
            res.to_csv(outs.path(args.out))
        else:
            res.to_netcdf(outs.path(args.out))
    if args.plot:
        from ..plot._plot import plot_atlas, savefig

        savefig(
            plot_atlas(res, model.process, model=model.source, width_max=wmax, terms=args.terms),
            outs.path(args.plot),
        )
    return 0 if res.status == "ok" else 1


@_command("sweep")
def _sweep(args: argparse.Namespace) -> int:
    with _outputs(args, (args.out, "--out", DATA_SUFFIXES), (args.plot, "--plot", PLOT_SUFFIXES)) as outs:
        _check_checkpoint(args, outs)
        return _sweep_run(args, outs)


def _sweep_run(args: argparse.Namespace, outs: Outputs) -> int:
    import numpy as np

    from ..quantities._tasks import QUANTITIES, QuantityTask, axis_name, model_fingerprint
    from ..sweep._engine import Axis, Grid, sweep

    model = _load(args)
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
        g = Grid.from_spec(f"{axis_name(name)}={rng}")
        vals = np.asarray(g.axes[0].values, float)
        check_axis_values(name, vals, "mm" if name == "width" else units.get(name, ""))
        if name == "width":
            vals = vals * 1e-3  # the CLI takes mm
        ax_name = axis_name(name) if "." in name else name
        if "." in name:
            aliases[ax_name] = name
        axes.append(Axis(ax_name, vals, units.get(name, "")))
    grid = Grid(axes)
    fixed: dict[str, float] = {}
    if args.width is not None:
        fixed["width"] = _width_m(args)
    for nm in ("speed", "delay", "position"):
        if getattr(args, nm) is not None:
            fixed[nm] = getattr(args, nm)
    task = QuantityTask(
        model,
        args.quantity,
        fixed,
        terms=args.terms,
        width_max=check_width(args.width_max, "--width-max", "mm") * 1e-3,
        aliases=aliases,
    )
    task.check_grid(grid)
    res = sweep(
        task,
        grid,
        outputs=QUANTITIES[args.quantity],
        checkpoint=_checkpoint(args),
        resume=args.resume,
        fingerprint=model_fingerprint(model)
        + f"|{sorted(fixed.items())!r}|{args.quantity}|{args.terms}|{args.width_max}",
        out=outs.path(args.out) if args.out and not args.out.lower().endswith(".csv") else None,
        attrs={"model_text": model.text, "quantity": args.quantity, "parameters": json.dumps(aliases)},
        **_sweep_opts(args),
    )
    print(
        f"sweep of {args.quantity} over {' x '.join(f'{a.name}[{a.values.size}]' for a in grid.axes)}: {res.status}"
    )
    for k, arr in res.data.items():
        a = np.asarray(arr)
        fin = a[np.isfinite(a)]
        rng = f"min {fin.min():.6g}, max {fin.max():.6g}" if fin.size else "no finite values"
        print(f"  {k} [{QUANTITIES[args.quantity][k]}]: {rng}")
    if res.failures:
        print(f"  {len(res.failures)} task(s) failed; first: {res.message}", file=sys.stderr)
    if args.out and args.out.lower().endswith(".csv"):
        res.to_csv(outs.path(args.out))  # (a .nc file was streamed by the sweep)
    if args.plot:
        from ..plot._plot import savefig

        first = next(iter(QUANTITIES[args.quantity]))
        savefig(res.plot(first), outs.path(args.plot))
    return 0 if res.status == "ok" else 1


@_command("simulate")
def _simulate(args: argparse.Namespace) -> int:
    cases: list[Literal["none", "pd", "pdo"]] = (
        ["none", "pd", "pdo"] if args.feedback == "all" else [args.feedback]
    )
    files = [args.out if len(cases) == 1 else _suffixed(args.out, fb) for fb in cases] if args.out else []
    with _outputs(
        args, *((f, "--out", DATA_SUFFIXES) for f in files), (args.plot, "--plot", PLOT_SUFFIXES)
    ) as outs:
        return _simulate_run(args, outs, cases, files)


def _history_line(sim: Any, name: str) -> str:
    """One printed line per recorded output: mean, peak-to-peak and spectral
    peak of the last cut -- or, for a run that diverged, how large the
    response grew and when (a mean of a blown-up history means nothing)."""
    import numpy as np

    x = sim.data[name]
    unit, scale = ("rad", 1.0) if sim.units.get(name) == "rad" else ("um", 1e6)
    if sim.status == "diverged" or not np.all(np.isfinite(x)):
        fin = np.abs(x[np.isfinite(x)])
        peak = f"largest |value| {fin.max() * scale:.3g} {unit}" if fin.size else "no finite value"
        return f"  {name:10s} {peak} up to t = {sim.t[-1]:.6g} s (no mean or spectrum: the run diverged)"
    m = sim.window("last-cut")
    f, a = sim.spectrum(name)
    sel = f > 1.0
    fp = f[sel][int(a[sel].argmax())] if sel.any() else float("nan")
    line = (
        f"  {name:10s} mean {x[m].mean() * scale:9.3f} {unit}   peak-to-peak {(x[m].max() - x[m].min()) * scale:8.3f} {unit}"
        f"   main spectral peak {fp:7.2f} Hz"
    )
    if sim.in_cut.all():  # a continuous cut: the envelope's growth rate is meaningful
        g = sim.growth(name, window="all", skip=min(sim.delay, 0.2 * sim.t[-1]))
        line += f"   envelope: {g.classification} ({g.rate:+.4g} 1/s)"
    return line


def _simulate_run(args: argparse.Namespace, outs: Outputs, cases: list[Any], files: list[str]) -> int:
    from ..structure._assembly import assemble
    from ..time._simulate import simulate

    sy = assemble(_load(args))
    width = _width_m(args) if args.width is not None else None
    sims = []
    for fb in cases:
        sim = simulate(
            sy,
            feedback=fb,
            width=width,
            speed=args.speed,
            delay=args.delay,
            position=args.position,
            passes=args.passes,
            duration=args.duration,
            step=args.step,
            outputs=args.output,
            progress=None if args.quiet else _progress_bar(f"simulate ({fb})"),
        )
        sims.append(sim)
        print(f"feedback {fb}: {sim.message}")
        for name in sim.data:
            print(_history_line(sim, name))
        if sim.status != "ok":
            print(f"  status: {sim.status}", file=sys.stderr)
    for sim, out in zip(sims, files, strict=True):
        if out.lower().endswith(".csv"):
            sim.to_csv(outs.path(out))
        else:
            sim.to_netcdf(outs.path(out))
    if args.plot:
        import matplotlib.pyplot as plt

        from ..plot._plot import plot_histories, plot_spectra

        names = list(sims[0].data)[:2]
        fig, axs = plt.subplots(len(names) + 1, 1, figsize=(8.5, 2.6 * (len(names) + 1) + 0.5))
        plot_histories(sims, names, axes=axs[: len(names)], against="time")
        plot_spectra(sims, names[0], ax=axs[-1])
        fig.tight_layout()
        fig.savefig(outs.path(args.plot), dpi=130)
        plt.close(fig)
    if any(s.status == "interrupted" for s in sims):
        print("chatterlab: interrupted: the partial time histories above were kept", file=sys.stderr)
        return 130
    return 0 if all(s.status == "ok" for s in sims) else 1


def _suffixed(path: str, tag: str) -> str:
    p = Path(path)
    return str(p.with_name(f"{p.stem}_{tag}{p.suffix}"))


def _progress_bar(label: str) -> Callable[[float], None] | None:
    if not sys.stderr.isatty():
        return None
    state = {"last": -1}

    def show(frac: float) -> None:
        pct = int(100 * frac)
        if pct != state["last"]:
            state["last"] = pct
            bar = "#" * (pct // 4)
            sys.stderr.write(f"\r{label} [{bar:<25}] {pct:3d}%")
            if pct >= 100:
                sys.stderr.write("\n")
            sys.stderr.flush()

    return show


def _parallel_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--jobs", type=int, default=2, help="worker processes (default 2; -1: all cores)")
    p.add_argument("--backend", choices=["loky", "dask", "serial"], default="loky")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="dask scheduler, e.g. tls://host:8786 (with --backend dask); it runs code as you: trust it",
    )
    p.add_argument("--tls-ca-file", metavar="PEM", help="CA certificate of a tls:// scheduler")
    p.add_argument("--tls-cert", metavar="PEM", help="client certificate for a tls:// scheduler")
    p.add_argument("--tls-key", metavar="PEM", help="client private key for a tls:// scheduler")
    p.add_argument(
        "--checkpoint", metavar="DIR", help="checkpoint directory (default: OUT.ckpt when --out is given)"
    )
    p.add_argument("--resume", action="store_true", help="resume an interrupted run from its checkpoint")


def _more_parsers(sub: Any) -> None:
    r = sub.add_parser("roots", help="rightmost characteristic roots and the stability verdict at (b, T)")
    _model_args(r)
    _cut_args(r, required_width=True)
    r.add_argument("--count", type=int, default=6, metavar="K", help="number of rightmost roots (default 6)")
    r.add_argument("--position", type=float, metavar="S", help="slide position s, m")
    r.add_argument("--format", choices=["table", "json"], default="table")
    r.add_argument("--out", metavar="FILE")
    r.add_argument("--no-winding", action="store_true", help="skip the argument-principle cross-check")

    lo = sub.add_parser(
        "lobes", help="stability lobe diagram (b_lim against speed), or an atlas along the stroke"
    )
    _model_args(lo)
    lo.add_argument(
        "--speed",
        type=float,
        nargs=2,
        required=True,
        metavar=("MIN", "MAX"),
        help="speed range in the process unit",
    )
    lo.add_argument("--points", type=int, default=300, help="number of speeds (default 300)")
    lo.add_argument(
        "--width-max", type=float, default=20.0, metavar="B", help="largest width considered, mm (default 20)"
    )
    g = lo.add_mutually_exclusive_group()
    g.add_argument("--position", type=float, metavar="S", help="slide position s, m (default: the model's)")
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
    lo.add_argument("--fmin", type=float, help="lowest chatter frequency searched, Hz")
    lo.add_argument("--fmax", type=float, help="highest chatter frequency searched, Hz")
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
    lo.add_argument("--out", metavar="FILE.nc|FILE.csv")
    lo.add_argument("--plot", metavar="FILE.png")
    _parallel_args(lo)

    si = sub.add_parser("simulate", help="Newmark transient of the moving, delayed closed loop (Eq. 2.28)")
    _model_args(si)
    si.add_argument(
        "--feedback",
        choices=["none", "pd", "pdo", "all"],
        default="pdo",
        help="paper's cases: none (a), pd = proportional + derivative (b), pdo = + delayed (c), all = the three",
    )
    si.add_argument(
        "--passes", type=int, default=2, help="stroke cycles (or delay periods) simulated (default 2)"
    )
    si.add_argument("--duration", type=float, metavar="S", help="simulated time, s (overrides --passes)")
    si.add_argument(
        "--step",
        type=float,
        metavar="H",
        help="time step, s (default: 1/20 of the highest period below 300 Hz)",
    )
    si.add_argument(
        "--width",
        type=float,
        metavar="B",
        help="width of cut b, mm (default: the coupling's reference width)",
    )
    g2 = si.add_mutually_exclusive_group()
    g2.add_argument(
        "--speed", type=float, metavar="V", help="work speed (shaping, m/s) or spindle speed (turning, rpm)"
    )
    g2.add_argument(
        "--delay", type=float, metavar="T", help="hold the slide still and cut continuously with delay T, s"
    )
    si.add_argument("--position", type=float, metavar="S", help="hold the slide at s, m (continuous cut)")
    si.add_argument(
        "--output",
        action="append",
        metavar="P.DIR",
        help="time history to record (default: the contact point x, y)",
    )
    si.add_argument("--out", metavar="FILE.nc|FILE.csv")
    si.add_argument("--plot", metavar="FILE.png")

    sw = sub.add_parser(
        "sweep", help="a chatter quantity over a grid of widths, speeds, positions or model parameters"
    )
    _model_args(sw)
    sw.add_argument(
        "--grid",
        action="append",
        metavar="PARAM=MIN:MAX:N",
        help="a grid axis: width (mm), speed, delay (s), position (m) or a model parameter path (repeatable)",
    )
    sw.add_argument("--quantity", required=True, choices=sorted(QUANTITY_NAMES))
    _cut_args(sw)
    sw.add_argument("--position", type=float, metavar="S", help="slide position s, m (when not on the grid)")
    sw.add_argument(
        "--width-max", type=float, default=20.0, metavar="B", help="largest width for b-lim quantities, mm"
    )
    sw.add_argument("--out", metavar="FILE.nc|FILE.csv")
    sw.add_argument("--plot", metavar="FILE.png")
    _parallel_args(sw)


QUANTITY_NAMES = ("rightmost-root", "stable", "b-lim", "min-b-lim", "natural-frequencies")


# ----------------------------------------------------------------------------- parser


#: the command line being parsed (for "did you mean" in parser errors)
_ARGV: list[str] = []


class _Parser(argparse.ArgumentParser):
    """An argparse parser whose errors suggest the nearest option of the
    (sub)command for a misspelled one, with that command's own usage."""

    def error(self, message: str) -> Any:
        import difflib

        known = [o for a in self._actions for o in a.option_strings]
        hints = []
        for tok in _ARGV:
            opt = tok.split("=", 1)[0]
            if opt.startswith("--") and opt not in known:
                near = difflib.get_close_matches(opt, known, n=1)
                hints.append(f"{opt}: did you mean {near[0]}?" if near else f"{opt}: no such option")
        self.print_usage(sys.stderr)
        hint = f" ({'; '.join(hints)})" if hints else ""
        self.exit(2, f"{self.prog}: error: {message}{hint}\n")


def build_parser() -> argparse.ArgumentParser:
    from .._version import __version__

    p = _Parser(
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
    m.add_argument(
        "--allow-rigid", action="store_true", help="report rigid-body modes instead of refusing them"
    )

    f = sub.add_parser("frf", help="open- or closed-loop frequency response between named points")
    _model_args(f)
    f.add_argument(
        "--input", action="append", required=True, metavar="P.DIR", help="force input, e.g. rfe5.x"
    )
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
    f.add_argument("--nyquist", metavar="FILE.png", help="Nyquist plot of the loop determinant det(I - G D)")

    for extra in _EXTRA_PARSERS:
        extra(sub)
    return p


_EXTRA_PARSERS: list[Callable[[Any], None]] = [_more_parsers]


def _subparser(parser: argparse.ArgumentParser, name: str) -> argparse.ArgumentParser:
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            return a.choices[name]
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``chatterlab`` command; returns the exit status."""
    parser = build_parser()
    _ARGV[:] = list(sys.argv[1:] if argv is None else argv)
    args, extra = parser.parse_known_args(argv)
    if extra:
        # an unknown option: the subcommand's usage and a suggestion, not the top level's
        sub = _subparser(parser, args.command) if args.command else parser
        sub.error(f"unrecognized arguments: {' '.join(extra)}")
    if not args.command:
        parser.print_help()
        return 2
    _WARNINGS.clear()
    try:
        _check_numbers(args)
        # one BLAS thread: chatterlab's work is many small dense problems, and
        # on a 2-core machine with any other load, threaded BLAS oversubscribes
        # (README main job, load 2-3: 8.9 s with default threads, 2.5 s with one);
        # parallel work goes through the sweep engine's worker processes
        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1):
            code = COMMANDS[args.command](args)
        _flush_warnings()
        return code
    except ChatterlabError as exc:
        _WARNINGS.clear()
        print(f"chatterlab: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        # a sweep's interruption says how much is saved and how to resume
        detail = str(exc).strip()
        print(f"chatterlab: interrupted{': ' + detail if detail else ''}", file=sys.stderr)
        return 130
    except BrokenPipeError:  # pragma: no cover - e.g. piping into head
        return 0
    except MemoryError:
        print(
            "chatterlab: error: out of memory; make the problem smaller (fewer points, positions or modes)",
            file=sys.stderr,
        )
        return 2
    except OSError as exc:  # a file system refusal while writing: name the file
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"chatterlab: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except Exception as exc:  # a bug: one line and status 3, the traceback on request
        import os

        if os.environ.get("CHATTERLAB_DEBUG"):
            raise
        msg = str(exc).splitlines()[0][:300] if str(exc) else ""
        print(
            f"chatterlab: internal error: {type(exc).__name__}{': ' + msg if msg else ''} (a bug in chatterlab:"
            " please report it with the command; CHATTERLAB_DEBUG=1 shows the traceback)",
            file=sys.stderr,
        )
        return 3


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
