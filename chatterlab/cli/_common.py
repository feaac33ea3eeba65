"""What every command shares: the model and cut options, the one place where
the edge's units (width in mm, frequencies in Hz, speeds in the process's
unit) turn into SI, the unit-slip warnings, and writing results.

Units at this edge: frequencies in Hz, width of cut in mm, the cutting speed
in the process's unit (shaping: m/s, turning: rpm), delay and positions in SI
(s, m).  Inside chatterlab everything is SI; ``mm_to_m`` / ``m_to_mm`` are
the conversions of widths, and a frequency in Hz is handed on as the core's
Hz arguments say (``frequencies(fmin, fmax)``, ``lobes(fmin=, fmax=)``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from ..errors import (
    InputError,
    check_count,
    check_delay,
    check_nonneg,
    check_position,
    check_positive,
    check_speed,
    check_width,
)
from ..io._files import CSV_SUFFIXES, JSON_SUFFIXES, TEXT_SUFFIXES, Outputs

#: metres per millimetre: widths are typed and printed in mm
MM = 1e-3

#: the most speeds of a lobe diagram (``lobes --points``): the work grows with each
MAX_POINTS = 100_000
#: the most positions of an atlas (``lobes --positions A B N``): a boundary is computed at each
MAX_POSITIONS = 10_000
#: the largest value of every other count whose work grows with it (issue 20 item 7: every command
#: finishes or refuses within a bounded time): dest -> (largest accepted, what each unit costs)
COUNT_CAPS = {
    "verify": (1000, "each an argument-principle count"),
    "confirm": (50, "each a Newmark simulation of the closed loop"),
    "count": (200, "the rightmost roots searched"),
    "steps": (
        1000,
        "the semi-discretisation's matrices have a row and a column per step: memory grows as the steps squared, work as their cube, and the check doubles them (1000: 77 s, 330 MB for one 2-DOF speed)",
    ),
    "scan": (2000, "each depth one monodromy eigenvalue problem"),
    "teeth": (100, "the period's pieces grow with the teeth"),
}


def mm_to_m(value_mm: Any) -> Any:
    """A width typed in mm (number or array), in m."""
    return value_mm * MM


def m_to_mm(value_m: Any) -> Any:
    """A width in m (number or array), in mm for printing."""
    return value_m * 1e3


# ----------------------------------------------------------------------------- model and cut


def parse_set(items: Sequence[str] | None) -> dict[str, Any]:
    """``--set PATH=VALUE`` options as a dict of overrides (values as JSON where they parse)."""
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


def load(args: argparse.Namespace) -> Any:
    """The model of the command line (file, --variant, --set), with its unit-slip warnings."""
    from ..model._reader import load_model

    if args.model is None:
        raise InputError("give the model file (or, for lobes, a measured FRF with --frf FILE)")
    model = load_model(
        args.model,
        variant=getattr(args, "variant", None),
        overrides=parse_set(getattr(args, "set", None)),
        files_outside=getattr(args, "allow_outside_files", False),
    )
    if model.process is not None:
        from ._units import resolve_speed

        resolve_speed(args, model.process.speed_unit)
    warn(args, model_slips(model, args))
    return model


def frozen(args: argparse.Namespace) -> Any:
    """The assembled model held at ``--position``, with its frequency warnings."""
    from ..structure._assembly import assemble

    fz = assemble(load(args)).at(getattr(args, "position", None))
    warn(args, frequency_slips(fz))
    return fz


def unchecked_mesh(model: Any) -> dict[str, Any]:
    """The ``mesh`` line and ``mesh_estimated = 0`` of a result of a model
    with beams run with ``--no-mesh-check`` (:func:`chatterlab.lobes._mesh_error.not_estimated`)."""
    from ..lobes._mesh_error import not_estimated

    return not_estimated(model, "--no-mesh-check; without it the lobes command estimates it")


def width_m(args: argparse.Namespace) -> float:
    """``--width`` (mm, required here) in m."""
    if args.width is None:
        raise InputError("--width is required here: the width of cut b in mm")
    b = mm_to_m(check_width(args.width, "--width", "mm"))
    warn(args, width_slips(b, "--width"))
    return b


def width_max_m(args: argparse.Namespace) -> float:
    """``--width-max`` (mm) in m, checked."""
    return mm_to_m(check_width(args.width_max, "--width-max", "mm"))


def model_args(p: argparse.ArgumentParser, optional: bool = False) -> None:
    """The model file and the options that change it (every command;
    ``optional`` where another input can stand in for it, ``lobes --frf``)."""
    if optional:
        p.add_argument(
            "model", nargs="?", help="model file (TOML, see docs/model-format.md); optional with --frf"
        )
    else:
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


def cut_args(p: argparse.ArgumentParser, required_width: bool = False) -> None:
    """Width, speed or delay, and the feedback terms of one cut."""
    p.add_argument("--width", required=required_width, metavar="B", help="width of cut b, mm")
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--speed",
        metavar="V",
        help="cutting speed in the model's process unit (shaping: work speed m/s; turning: rpm)",
    )
    g.add_argument("--delay", metavar="T", help="delay between passes T, s")
    p.add_argument(
        "--terms",
        choices=["pdo", "pd", "o"],
        default="pdo",
        help="feedback terms: pdo = proportional+derivative+delayed (paper case c, default), "
        "pd = without delay (case b), o = delayed only",
    )


def check_numbers(args: argparse.Namespace, unit: str = "") -> None:
    """Every numeric option through the one validator set (chatterlab.errors),
    before the model is assembled: a width, speed or delay must be > 0, a
    position finite, a count a whole number; ``unit`` is the process's speed unit."""
    if getattr(args, "width", None) is not None:
        check_width(args.width, "--width", "mm")
    if getattr(args, "width_max", None) is not None:
        check_width(args.width_max, "--width-max", "mm")
    speed = getattr(args, "speed", None)  # a speed with its unit is checked once the process is known
    if isinstance(speed, list):
        for v in speed:
            if not isinstance(v, str):
                check_speed(v, "--speed", unit)
    elif speed is not None and not isinstance(speed, str):
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
    if getattr(args, "points", None) is not None and args.points > MAX_POINTS:
        raise InputError(
            f"--points {args.points} is more than the largest accepted, {MAX_POINTS} speeds (more than a"
            " diagram can show; the work grows with each): use fewer points, or several speed ranges"
        )
    if getattr(args, "count", None) is not None:
        check_count(args.count, "--count", 1)
    for dest, (cap, why) in COUNT_CAPS.items():
        value = getattr(args, dest, None)
        if dest == "count" and getattr(args, "command", None) != "roots":
            continue  # modes --count only lists modes already computed
        if isinstance(value, int) and not isinstance(value, bool) and value > cap:
            opt = "--" + dest.replace("_", "-")
            raise InputError(
                f"{opt} {value} is more than the largest accepted, {cap} ({why}): use at most {cap}"
            )


# ----------------------------------------------------------------------------- unit slips
# A number off by a factor 1000 (mm typed for m, N/mm^2 for N/m^2) gives a
# confident answer; these ranges cover real machines with a wide margin, and
# a value outside them is named on one line of standard error (--quiet: none).


#: warnings of the running command: printed when it has run (an input error
#: is one line on its own, so they are dropped then)
WARNINGS: list[str] = []


def warn(args: argparse.Namespace, lines: list[str]) -> None:
    """Queue warning lines (printed once, after the command; none with --quiet)."""
    if not getattr(args, "quiet", False):
        WARNINGS.extend(f"chatterlab: warning: {line}" for line in lines if line not in WARNINGS)


def flush_warnings() -> None:
    """Print the queued warnings to standard error, each once."""
    for line in dict.fromkeys(WARNINGS):
        print(line, file=sys.stderr)
    WARNINGS.clear()


#: widths (m) below this get a warning: the 0.1-20 mm of practice typed in m
#: (0.0001-0.02) land below it, as mm; a micro-machining width may too (--quiet)
WIDTH_SLIP_BELOW = 2e-5


def width_slips(b: float, option: str) -> list[str]:
    """A width ``b`` (m) below 0.02 mm, or above 100 mm (a width of cut, as
    the Python API warns) or 1 m (a ceiling): a unit slip."""
    from ..errors import WIDTH_WARN_ABOVE

    if b < WIDTH_SLIP_BELOW:
        return [
            f"{option} is {m_to_mm(b):g} mm, below {m_to_mm(WIDTH_SLIP_BELOW):g} mm: was the width typed"
            " in m? (the CLI takes mm; --quiet silences this)"
        ]
    hi = WIDTH_WARN_ABOVE if option == "--width" else 1.0
    if b > hi:
        return [f"{option} is {m_to_mm(b):g} mm, above {m_to_mm(hi):g} mm: was the width typed in um?"]
    return []


def model_slips(model: Any, args: argparse.Namespace) -> list[str]:
    """Cutting stiffness, structure size, speeds and a ``[[mode]]`` table's
    frequencies and stiffnesses outside what machines have."""
    import numpy as np

    from ..model._modes import modal_slips

    out = modal_slips(model.modes) if getattr(model, "modes", None) else []
    proc = model.process
    cut = getattr(proc, "milling", None)
    if cut is not None:  # the coefficients as the user typed them, not the ZOA matrix made of them
        for name, k in (("Kt", cut.Kt), ("Kn", cut.Kn)):
            if k and not 1e7 <= abs(k) <= 1e11:
                out.append(
                    f"milling {name} = {k:g} N/m^2 is outside 1e7..1e11 N/m^2: was it given in N/mm^2"
                    f" (x 1e6: {k * 1e6:g})?"
                )
    for c in model.couplings:
        if cut is not None and c.kind == "milling":
            continue  # said above, in the user's own numbers
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
    speed = getattr(args, "speed", None)
    limits = {"shaping": (1e-3, 10.0), "turning": (1.0, 1e5), "milling": (10.0, 2e5)}
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


def frequency_slips(fz: Any) -> list[str]:
    """Natural frequencies below 0.1 Hz, or none below 100 kHz: a mass or
    stiffness unit slip.  The upper check is on the lowest frequency: a
    finely meshed beam's highest frequencies are megahertz by nature (the
    mesh's own modes), while a structure whose fundamental is above 100 kHz
    is no machine tool."""
    import numpy as np

    f = np.abs(fz.complex_modes.lam) / (2 * np.pi)
    f = f[f > 0]
    out = []
    if f.size and f.min() < 0.1:
        out.append(
            f"the lowest natural frequency is {f.min():.3g} Hz, below 0.1 Hz: a mass or stiffness unit slip?"
        )
    if f.size and f.min() > 1e5:
        out.append(
            f"the lowest natural frequency is {f.min():.3g} Hz, above 100 kHz: a mass or stiffness unit slip?"
        )
    return out


# ----------------------------------------------------------------------------- output


#: the suffixes ``--out`` may have for each ``--format``
FORMAT_SUFFIXES = {"table": TEXT_SUFFIXES, "json": JSON_SUFFIXES, "csv": CSV_SUFFIXES}


def emit(text: str, out: str | None) -> None:
    """``text`` to the (staged) file ``out``, or to standard output."""
    if out:
        with open(out, "w") as fh:
            fh.write(text if text.endswith("\n") else text + "\n")
    else:
        sys.stdout.write(text if text.endswith("\n") else text + "\n")


class CommandOutputs(Outputs):
    """The output files of one command (:class:`Outputs`) and what is done
    only once they are all in place (:meth:`then`: e.g. removing the
    checkpoint they were made from)."""

    def __init__(self, inputs: Sequence[str]) -> None:
        super().__init__(inputs=inputs)
        self.after: list[Callable[[], Any]] = []

    def then(self, action: Callable[[], Any]) -> None:
        """Run ``action()`` after the files are moved into place (never if the
        command fails or is killed before)."""
        self.after.append(action)


@contextlib.contextmanager
def outputs(
    args: argparse.Namespace, *specs: tuple[str | None, str, tuple[str, ...]]
) -> Iterator[CommandOutputs]:
    """Check every output of the command before it computes (suffix,
    directory, writability, not an input, not named twice); the command
    writes to ``outs.path(FILE)``; the files are moved into place together
    when it returns, and removed if it raises (docs/cli.md, "Output files");
    then the actions given to ``outs.then`` run."""
    inputs = [args.model] if getattr(args, "model", None) else []
    outs = CommandOutputs(inputs=inputs)
    for path, option, suffixes in specs:
        outs.add(path, option, suffixes)
    try:
        yield outs
    except BaseException:
        outs.discard()
        raise
    outs.commit(note=lambda msg: print(msg, file=sys.stderr))
    for action in outs.after:
        action()


def progress_bar(label: str) -> Callable[[float], None] | None:
    """A ``progress(fraction)`` bar on a terminal's standard error (None
    elsewhere): :func:`chatterlab._progress.fraction_bar`, the one progress."""
    if not sys.stderr.isatty():
        return None
    from .._progress import fraction_bar

    return fraction_bar(label)


def write_result(
    result: Any,
    args: argparse.Namespace,
    outs: Any,
    *,
    model: Any = None,
    command: bool = True,
    plot: Callable[[], Any] | None = None,
) -> None:
    """``result`` to ``--out`` by its suffix (CSV, JSON, else netCDF with the
    command line in its attributes when ``command`` and the model's text
    when ``model`` is given) and its plot (``plot()``, default
    ``result.plot()``) to ``--plot``: the one writer of the commands that
    save a :class:`~chatterlab.io.Result`."""
    if args.out:
        low = args.out.lower()
        path = outs.path(args.out)
        if low.endswith(".csv"):
            result.to_csv(path)
        elif low.endswith(".json"):
            result.to_json(path)
        else:
            attrs = {"command": " ".join(sys.argv)} if command else {}
            if model is not None:
                attrs["model_text"] = model.text
            result.to_netcdf(path, attrs=attrs or None)
    if args.plot:
        from ..plot import savefig

        savefig(plot() if plot is not None else result.plot(), outs.path(args.plot))
