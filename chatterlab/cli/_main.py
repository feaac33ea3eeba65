"""The ``chatterlab`` command line (argparse): the parser, the dispatch to
one module per command, and the exit statuses.

Each command lives in its own module (``_check``, ``_modes``, ``_frf``,
``_roots``, ``_lobes``, ``_simulate``, ``_sweep``) with ``add_parser(sub)``
and ``run(args) -> int``; what they share (model and cut options, the mm/Hz
and speed units of this edge, warnings, output files) is ``_common``, the
sweep engine's options ``_parallel``, the meaning of an ``inf`` b_lim in a
sweep's summary ``_claims``.

Units at this edge: frequencies in Hz, width of cut in mm, the cutting speed
in the process's unit (shaping: m/s, turning: rpm), delay and positions in SI
(s, m).  Every input error prints one line ``chatterlab: error: ...`` and
exits with status 2; no traceback.  Exit statuses: 0 done, 1 computed but
not everything succeeded or was verified, 2 refused input (or a file system
refusal, or out of memory), 3 an internal error, 130 interrupted.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from typing import Any

# absolute imports of the sibling modules: ``from . import _check`` would also
# import this package's __init__, which imports this module (a cycle to the
# import contract of tests/test_architecture.py)
import chatterlab.cli._check as _check
import chatterlab.cli._frf as _frf
import chatterlab.cli._lobes as _lobes
import chatterlab.cli._modes as _modes
import chatterlab.cli._roots as _roots
import chatterlab.cli._simulate as _simulate
import chatterlab.cli._sweep as _sweep

from ..errors import ChatterlabError
from ._common import WARNINGS, check_numbers, flush_warnings

__all__ = ["main", "build_parser"]

#: the commands in the order ``chatterlab --help`` lists them
_MODULES = (_check, _modes, _frf, _roots, _lobes, _simulate, _sweep)

#: command name -> run(args) -> exit status (the dispatch table)
COMMANDS: dict[str, Callable[[argparse.Namespace], int]] = {
    name: mod.run
    for name, mod in zip(
        ("check", "modes", "frf", "roots", "lobes", "simulate", "sweep"), _MODULES, strict=True
    )
}

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


def build_parser() -> argparse.ArgumentParser:
    """The parser of the ``chatterlab`` command and its subcommands."""
    from .._version import __version__

    p = _Parser(
        prog="chatterlab",
        description="Machining chatter from structural models (RDFEM): modes, FRFs, roots, transients, lobes.",
    )
    p.add_argument("--version", action="version", version=f"chatterlab {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for mod in _MODULES:
        mod.add_parser(sub)
    return p


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
    WARNINGS.clear()
    try:
        check_numbers(args)
        # one BLAS thread: chatterlab's work is many small dense problems, and
        # on a 2-core machine with any other load, threaded BLAS oversubscribes
        # (README main job, load 2-3: 8.9 s with default threads, 2.5 s with one);
        # parallel work goes through the sweep engine's worker processes
        import warnings

        from .._threads import one_blas_thread
        from ..errors import UnitWarning

        with one_blas_thread(blas_only=False), warnings.catch_warnings():
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
