"""The ``chatterlab`` command line (argparse): the parser, the dispatch to
one module per command, and the exit statuses.

Each command lives in its own module (``_check``, ``_modes``, ``_frf``,
``_roots``, ``_lobes``, ``_simulate``, ``_sweep``, ``_example``) with
``add_parser(sub)`` and ``run(args) -> int``, imported only when its command
is chosen (the command line is parsed first: ``--help`` and every ``-h`` load
no numpy); what they share (model and cut options, the mm/Hz
and speed units of this edge, warnings, output files) is ``_common``, the
sweep engine's options ``_parallel``, the meaning of an ``inf`` b_lim in a
sweep's summary ``_claims``.

Units at this edge: frequencies in Hz, width of cut in mm, the cutting speed
in the process's unit (shaping: m/s, turning: rpm), delay and positions in SI
(s, m).  Every input error prints one line ``chatterlab: error: ...`` and
exits with status 2; no traceback.  Exit statuses: 0 done, 1 computed but
not everything succeeded or was verified, 2 refused input (or a file system
refusal, or out of memory), 3 an internal error, 130 interrupted.

``example:NAME`` in place of a model or FRF file is a bundled example
(chatterlab/_examples.py), resolved here before the command opens anything.

A closed standard output or error (``chatterlab lobes ... | head -1``) costs
nothing: what is printed after the reader left is dropped, the command
finishes, commits its output files and checkpoint as an uninterrupted run
would, and exits with the status that run would have had (not 141, the
shell's SIGPIPE convention for a writer that stops: this one does not stop,
its files are its real output).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from typing import Any

# nothing heavy at the top: the parser is built and the command line parsed
# first (``chatterlab --help`` and every ``-h`` load no numpy), then only the
# chosen command's module is imported (tests/test_cli_help_fast.py)
from ..errors import ChatterlabError

__all__ = ["main", "build_parser"]

#: command -> (its module, the line ``chatterlab --help`` shows for it), in
#: the order ``chatterlab --help`` lists them; each module has
#: ``add_parser(sub)`` and ``run(args) -> int``, and is imported only when its
#: command is chosen (the line equals the module's own ``help=``: tested)
_COMMAND_TABLE: dict[str, tuple[str, str]] = {
    "check": ("chatterlab.cli._check", "validate a model file and summarise it"),
    "modes": ("chatterlab.cli._modes", "natural frequencies and mode shapes at a frozen configuration"),
    "frf": ("chatterlab.cli._frf", "open- or closed-loop frequency response between named points"),
    "roots": ("chatterlab.cli._roots", "rightmost characteristic roots and the stability verdict at (b, T)"),
    "lobes": (
        "chatterlab.cli._lobes",
        "stability lobe diagram (b_lim against speed), or an atlas along the stroke",
    ),
    "simulate": (
        "chatterlab.cli._simulate",
        "Newmark transient of the moving, delayed closed loop (Eq. 2.28)",
    ),
    "sweep": (
        "chatterlab.cli._sweep",
        "a chatter quantity over a grid of widths, speeds, positions or model parameters",
    ),
    "sensitivity": (
        "chatterlab.cli._sensitivity",
        "exact sensitivities of the stability limit to model fields, ranked (what to stiffen or damp)",
    ),
    "absorber": (
        "chatterlab.cli._design",
        "tune vibration absorbers to maximise the minimum chatter-free width; lobes before and after",
    ),
    "active": (
        "chatterlab.cli._active",
        "co-design an active damper's gains (and placement) for the widest chatter-free cut; lobes before and after",
    ),
    "risk": (
        "chatterlab.cli._risk",
        "probabilistic lobes: P(chatter), quantile lobes and Sobol' indices from [uncertainty]",
    ),
    "fit-damping": (
        "chatterlab.cli._damping",
        "fit the process-damping coefficient C_pd to cutting tests (stable, chatter, onset), with its error",
    ),
    "recommend": (
        "chatterlab.cli._recommend",
        "the speeds and depths to choose: most material removed while stable, or the chatter-frequency rule",
    ),
    "sle": (
        "chatterlab.cli._sle",
        "surface location error of the stable cuts against speed (milling), or the response to runout (turning)",
    ),
    "ssv": (
        "chatterlab.cli._ssv",
        "stability limit under spindle-speed variation (RVA, RVF) against the mean speed",
    ),
    "example": (
        "chatterlab.cli._example",
        "copy a bundled example (model, FRF) into this folder; alone: list them",
    ),
}


def _module(command: str) -> Any:
    # absolute imports of the sibling modules: ``from . import _check`` would also
    # import this package's __init__, which imports this module (a cycle to the
    # import contract of tests/test_architecture.py)
    import importlib

    return importlib.import_module(_COMMAND_TABLE[command][0])


def _runner(command: str) -> Callable[[argparse.Namespace], int]:
    def run(args: argparse.Namespace) -> int:
        return int(_module(command).run(args))

    run.__name__ = f"run_{command}"
    return run


#: command name -> run(args) -> exit status (the dispatch table)
COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {name: _runner(name) for name in _COMMAND_TABLE}

#: the command line being parsed (for "did you mean" in parser errors)
_ARGV: list[str] = []


class _Parser(argparse.ArgumentParser):
    """An argparse parser whose errors are one line, like every chatterlab
    input error: the message, the nearest option of the (sub)command for a
    misspelled one, and where the command's usage is (``-h``)."""

    def error(self, message: str) -> Any:
        import difflib

        known = [o for a in self._actions for o in a.option_strings]
        hints = []
        for tok in _ARGV:
            opt = tok.split("=", 1)[0]
            if opt.startswith("--") and opt not in known:
                near = difflib.get_close_matches(opt, known, n=1)
                hints.append(f"{opt}: did you mean {near[0]}?" if near else f"{opt}: no such option")
        hint = f" ({'; '.join(hints)})" if hints else ""
        self.exit(2, f"{self.prog}: error: {message}{hint}; the options: {self.prog} -h\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of the ``chatterlab`` command and its subcommands (every
    command's module imported); with ``command``, only that subcommand's
    options are built and its module imported, the others are listed by
    name and help line."""
    return _build(list(_COMMAND_TABLE) if command is None else [command])


def _build(full: Sequence[str]) -> argparse.ArgumentParser:
    """The parser with the options of the commands ``full`` (their modules
    imported) and the other commands as a name and a help line."""
    from .._version import __version__

    p = _Parser(
        prog="chatterlab",
        description="Machining chatter from structural models (RDFEM): modes, FRFs, roots, transients, lobes.",
        epilog="Worked examples (the traverse shaper, milling benchmarks, tap-test FRFs) come with the package:"
        " 'chatterlab example' lists them, and 'example:NAME' stands for one wherever a model or FRF file"
        " is asked for (chatterlab lobes example:traverse_shaper ...). The model format: docs/model-format.md"
        " in the source tree.",
    )
    p.add_argument("--version", action="version", version=f"chatterlab {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name, (_, line) in _COMMAND_TABLE.items():
        if name in full:
            _module(name).add_parser(sub)
            cmd = sub.choices[name]
            if cmd.epilog is None:
                cmd.epilog = _EPILOG
        else:
            sub.add_parser(name, help=line, add_help=False)
    return p


#: the end of every command's -h: where the examples and the model format are, installed or not
_EPILOG = (
    "A model or FRF file may be a bundled example: example:NAME (chatterlab example lists them and copies"
    " one here). The model format: docs/model-format.md in the source tree."
)


def _chosen(argv: Sequence[str]) -> str | None:
    """The command named on the command line (its first word that is not an
    option), if it is one; else None (``--help``, ``--version``, a misspelling)."""
    for tok in argv:
        if tok == "--":
            return None
        if not tok.startswith("-"):
            return tok if tok in _COMMAND_TABLE else None
    return None


def _subparser(parser: argparse.ArgumentParser, name: str) -> argparse.ArgumentParser:
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            return a.choices[name]
    return parser


class _PipeGuard:
    """Standard output or error that outlives its reader: when the pipe is
    closed (``chatterlab lobes ... | head -1``), what is printed after goes to
    the null device instead of raising ``BrokenPipeError`` in the middle of the
    command, so the command finishes and its output files and checkpoint are
    committed as in an uninterrupted run (docs/cli.md, "Exit statuses")."""

    def __init__(self, stream: Any) -> None:
        self._stream = stream
        self.closed_pipe = False

    def _closed(self) -> None:
        self.closed_pipe = True
        # the descriptor now points to the null device: what is still in the
        # stream's buffer, and the interpreter's last flush at exit, go there
        try:
            fd = self._stream.fileno()
            null = os.open(os.devnull, os.O_WRONLY)
            try:
                os.dup2(null, fd)
            finally:
                os.close(null)
        except (OSError, ValueError, AttributeError):  # no descriptor (a test's capture): nothing to redirect
            pass

    def write(self, text: str) -> int:
        if not self.closed_pipe:
            try:
                return int(self._stream.write(text))
            except BrokenPipeError:
                self._closed()
        return len(text)

    def writelines(self, lines: Any) -> None:
        for line in lines:
            self.write(line)

    def flush(self) -> None:
        if self.closed_pipe:
            return
        try:
            self._stream.flush()
        except BrokenPipeError:
            self._closed()
            self.flush_to_null()

    def flush_to_null(self) -> None:
        """The stream's pending bytes, now to the null device (no error)."""
        try:
            self._stream.flush()
        except (BrokenPipeError, OSError, ValueError):
            pass

    def __getattr__(self, name: str) -> Any:  # isatty, fileno, encoding, buffer, ...
        return getattr(self._stream, name)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``chatterlab`` command; returns the exit status."""
    _ARGV[:] = list(sys.argv[1:] if argv is None else argv)
    chosen = _chosen(_ARGV)
    parser = _build([chosen] if chosen else [])
    args, extra = parser.parse_known_args(_ARGV)
    if extra:
        # an unknown option: the subcommand's usage and a suggestion, not the top level's
        sub = _subparser(parser, args.command) if args.command else parser
        sub.error(f"unrecognized arguments: {' '.join(extra)}")
    if not args.command:
        parser.print_help()
        return 2
    out, err = sys.stdout, sys.stderr
    guards = _PipeGuard(out), _PipeGuard(err)
    sys.stdout, sys.stderr = guards
    try:
        # the command owns the process when it was started as one (argv from the command line):
        # a Python caller's main([...]) leaves its BLAS threads as they would have been
        return _run(args, own_process=argv is None)
    finally:
        for g in guards:
            g.flush()
        sys.stdout, sys.stderr = out, err


class _SingleThreadLoad:
    """OpenBLAS started with one thread, as the command runs it.

    numpy's and scipy's OpenBLAS each start their worker threads when they
    are loaded, and the idle workers spin on the cores before they sleep:
    0.07 s of CPU for numpy's and 0.14 s for scipy's on 2 cores, a tenth of
    the README main job, for threads the command never uses (it runs under
    :func:`chatterlab._threads.one_blas_thread`).  ``OPENBLAS_NUM_THREADS=1``
    while the libraries load starts none; the variable is put back as soon as
    they are loaded (``restore``), so the sweep engine's worker processes
    start with the user's environment.  Nothing changes when the user set
    the variable (or ``GOTO_NUM_THREADS``/``OMP_NUM_THREADS``, which OpenBLAS
    reads after it), nor in a process that loaded numpy before, nor when
    :func:`main` is called from Python with its arguments (the caller's
    process keeps the BLAS threads it would have had)."""

    _VARS = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS")

    def __init__(self) -> None:
        self._set = False

    def __enter__(self) -> None:
        fresh = "numpy" not in sys.modules and not any(v in os.environ for v in self._VARS)
        if fresh:
            os.environ["OPENBLAS_NUM_THREADS"] = "1"
            self._set = True

    def restore(self) -> None:
        if self._set:
            os.environ.pop("OPENBLAS_NUM_THREADS", None)
            self._set = False

    def __exit__(self, *exc: object) -> None:
        self.restore()


#: entered before the command's first import of numpy, left once the BLAS libraries are loaded
_SINGLE_THREAD_LOAD = _SingleThreadLoad()


def _run(args: argparse.Namespace, own_process: bool = True) -> int:
    if not own_process:
        return _run_command(args)
    with _SINGLE_THREAD_LOAD:
        return _run_command(args)


def _run_command(args: argparse.Namespace) -> int:
    from ._common import WARNINGS, check_numbers, flush_warnings

    WARNINGS.clear()
    try:
        from .._examples import resolve_args

        resolve_args(args)  # example:NAME -> the bundled file, before any command opens it
        from ._units import resolve_units

        resolve_units(args)  # 2mm, 2000N/mm^2, 12000rpm: in each option's unit (pint, only if written)
        check_numbers(args)
        # one BLAS thread: chatterlab's work is many small dense problems, and
        # on a 2-core machine with any other load, threaded BLAS oversubscribes
        # (README main job, load 2-3: 8.9 s with default threads, 2.5 s with one);
        # parallel work goes through the sweep engine's worker processes
        import warnings

        from .._threads import one_blas_thread
        from ..errors import UnitWarning

        with one_blas_thread(blas_only=False), warnings.catch_warnings():
            _SINGLE_THREAD_LOAD.restore()  # the libraries are loaded: a worker process gets the user's setting
            warnings.simplefilter("ignore", UnitWarning)  # the CLI's own warnings say it in its units
            code = COMMANDS[args.command](args)
        flush_warnings()
        return code
    except ChatterlabError as exc:
        WARNINGS.clear()
        print(f"chatterlab: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        # a sweep's interruption says how much is saved and how to resume
        detail = str(exc).strip()
        print(f"chatterlab: interrupted{': ' + detail if detail else ''}", file=sys.stderr)
        return 130
    except BrokenPipeError:  # pragma: no cover - a write past the guards (a descriptor written directly)
        # standard output and error are guarded (_PipeGuard): a closed pipe costs no file; this is a
        # write that went around them, and the command did not finish
        print("chatterlab: error: the output pipe closed before the command finished", file=sys.stderr)
        return 1
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
