"""Small I/O helpers shared by result objects and the command line.

* :func:`text_out` -- write a text file atomically (temporary name, rename).
* :class:`Outputs` -- the files one command will write: checked before it
  computes (suffix, directory, writability, never an input), written under
  temporary names in their own directories and moved into place together
  only when the command has succeeded, so a failed run leaves no file and
  never half a file.
* :func:`check_not_input` -- the one output rule: an output is never an
  input, whatever the spelling (relative, absolute, ``..``, a symbolic or
  hard link): paths are compared after symbolic links are resolved
  (``os.path.realpath``) and as files (``os.path.samefile``).
  :func:`note_input` is how a reader tells the running command's
  :class:`Outputs` what it reads (a measured FRF named by a model's
  ``[frf]`` table is only known once the model is read): a file that is
  also an output is refused then, before any work.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import weakref
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import IO, Any

from ..errors import InputError

__all__ = [
    "DATA_SUFFIXES",
    "PLOT_SUFFIXES",
    "JSON_SUFFIXES",
    "TEXT_SUFFIXES",
    "CSV_SUFFIXES",
    "Outputs",
    "check_not_input",
    "clean_stale",
    "note_input",
    "json_text",
    "text_out",
]

#: suffixes a result file may have, by kind (docs/cli.md, "Output files")
DATA_SUFFIXES = (".nc", ".csv")
PLOT_SUFFIXES = (".png", ".pdf", ".svg")
JSON_SUFFIXES = (".json",)
TEXT_SUFFIXES = (".txt",)
CSV_SUFFIXES = (".csv",)


def _tmp_name(path: Path, tag: str = "part") -> Path:
    """A hidden temporary name next to ``path`` keeping its suffix (matplotlib
    picks the format from it): ``.NAME.part-PID-HEX.SUFFIX``."""
    return path.with_name(f".{path.name}.{tag}-{os.getpid()}-{secrets.token_hex(4)}{path.suffix}")


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean_stale(path: str | os.PathLike[str], tags: Iterable[str] = ("part", "tmp", "sweep")) -> list[Path]:
    """Remove temporary files and folders left next to ``path`` by a run that
    was killed (``.NAME.TAG-PID-...`` whose process is gone, and the
    ``..NAME.TAG-PID-....tmp-...`` of a writer that was itself writing
    atomically to that temporary name); returns them."""
    import re
    import shutil

    p = Path(path)
    pat = re.compile(rf"^\.\.?{re.escape(p.name)}\.(?:{'|'.join(map(re.escape, tags))})-(\d+)-")
    # chatterlab 0.1 named a sweep's scratch folder .NAME.sweep-XXXXXXXX (no pid): always stale now
    legacy = re.compile(rf"^\.{re.escape(p.name)}\.sweep-[a-z0-9_]{{8}}$") if "sweep" in tags else None
    removed: list[Path] = []
    try:
        entries = list(p.parent.iterdir())
    except OSError:
        return removed
    for e in entries:
        m = pat.match(e.name)
        if (m and not _pid_alive(int(m[1]))) or (legacy is not None and legacy.match(e.name) and e.is_dir()):
            if e.is_dir() and not e.is_symlink():
                shutil.rmtree(e, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    e.unlink()
            removed.append(e)
    return removed


@contextlib.contextmanager
def text_out(target: str | os.PathLike[str] | IO[str]) -> Iterator[Any]:
    """Open ``target`` for writing text (CSV-friendly), or pass a file-like
    object through.  Files are written to a temporary name in the same
    directory and renamed, so an interrupted or failed write never leaves
    half a file (and the temporary file is removed)."""
    if hasattr(target, "write"):
        yield target
        return
    path = Path(os.fspath(target))
    tmp = _tmp_name(path)
    try:
        with open(tmp, "w", newline="") as fh:
            yield fh
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def _probe(directory: Path) -> None:
    """Create and remove a file in ``directory``: the one reliable test of
    writability (permissions, ACLs, read-only mounts, root)."""
    import tempfile

    fd, name = tempfile.mkstemp(prefix=".chatterlab-probe-", dir=directory)
    os.close(fd)
    os.unlink(name)


def _same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """``a`` and ``b`` name one file: equal after symbolic links, ``..`` and
    relative spellings are resolved, or the same file on disk (a hard link)."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):  # one of them does not exist (yet), or holds a NUL
        return False


def check_not_input(
    out: str | os.PathLike[str], inputs: Iterable[str | os.PathLike[str]], option: str = "--out"
) -> None:
    """The output rule: :class:`InputError` when the output ``out`` (given to
    ``option``) is one of ``inputs`` under any spelling -- relative or
    absolute, through ``..``, a symbolic link (to the file or a folder on its
    path) or a hard link.  An input is never overwritten."""
    for inp in inputs:
        if _same_file(out, inp):
            raise InputError(
                f"{option} {os.fspath(out)!r} is an input of this command ({os.fspath(inp)}); it is never overwritten:"
                " give the output another name"
            )


#: the :class:`Outputs` of the running command(s): told by :func:`note_input` what is read
_ACTIVE: weakref.WeakSet[Outputs] = weakref.WeakSet()


def note_input(path: str | os.PathLike[str]) -> None:
    """Tell the running command's outputs that ``path`` is read: an input
    found only while the command runs (the measured FRF of a model's
    ``[frf]`` table).  :class:`InputError` when it is one of the outputs
    (:func:`check_not_input`); outside a command it does nothing."""
    for outs in list(_ACTIVE):
        outs.add_input(path)


class Outputs:
    """The files one command writes.

    :meth:`add` checks an output before anything is computed: a documented
    suffix, an existing and writable directory, not a directory itself, not
    one of ``inputs`` (the model file...), not named twice.  :meth:`path`
    gives the temporary name to write instead; :meth:`commit` moves every
    temporary file onto its target (``os.replace``) once the command has
    succeeded, :meth:`discard` removes them after a failure.  An existing
    target is replaced (chatterlab's policy on outputs: docs/cli.md).
    Until it commits or discards, every file a reader reports through
    :func:`note_input` is an input too (:meth:`add_input`).
    """

    def __init__(self, inputs: Iterable[str | os.PathLike[str]] = ()) -> None:
        self._inputs = {os.path.realpath(p): os.fspath(p) for p in inputs}
        self._targets: dict[str, str] = {}  # real path -> option
        self._given: dict[str, str] = {}  # real path -> the path as given
        self._staged: list[tuple[Path, Path, bool]] = []  # (tmp, final, announce)
        _ACTIVE.add(self)

    def add_input(self, path: str | os.PathLike[str]) -> None:
        """One more input of the command (a file it reads): refused when it
        is one of the outputs already checked (:func:`check_not_input`)."""
        for real, option in self._targets.items():
            check_not_input(self._given.get(real, real), [path], option)
        self._inputs.setdefault(os.path.realpath(path), os.fspath(path))

    def add(self, path: str | None, option: str, suffixes: tuple[str, ...]) -> str | None:
        """Check one output path (None: the option was not given).  A refused
        output ends the command: these outputs then stop watching reads."""
        if path is None:
            return None
        try:
            return self._add(path, option, suffixes)
        except InputError:
            _ACTIVE.discard(self)
            raise

    def _add(self, path: str, option: str, suffixes: tuple[str, ...]) -> str:
        p = Path(path)
        if p.suffix.lower() not in suffixes:
            raise InputError(
                f"{option} {path!r}: the file name must end in {', '.join(suffixes)}"
                f"{' (the suffix picks the format)' if len(suffixes) > 1 else ''}"
            )
        real = os.path.realpath(p)
        check_not_input(path, self._inputs.values(), option)
        if real in self._targets:
            raise InputError(
                f"{option} {path!r} is also given to {self._targets[real]}; give each output its own file"
            )
        if p.is_dir():
            raise InputError(f"{option} {path!r} is a directory; give a file name")
        if p.exists() and not p.is_file():
            raise InputError(f"{option} {path!r} exists and is not a regular file")
        parent = p.parent
        if not parent.is_dir():
            raise InputError(
                f"{option} {path!r}: the directory {str(parent)!r} does not exist; create it first"
            )
        try:
            _probe(parent)
        except OSError as exc:
            raise InputError(
                f"{option} {path!r}: cannot write in {str(parent)!r} ({exc.strerror or exc}); choose a writable directory"
            ) from None
        self._targets[real] = option
        self._given[real] = path
        clean_stale(p)
        return path

    def path(self, final: str | os.PathLike[str], announce: bool = True) -> str:
        """The temporary name to write ``final`` to (same directory, same suffix)."""
        f = Path(final)
        tmp = _tmp_name(f)
        self._staged.append((tmp, f, announce))
        return str(tmp)

    def commit(self, note: Any = None) -> list[Path]:
        """Move every written temporary file onto its target; ``note(msg)``
        reports each (``wrote FILE``)."""
        _ACTIVE.discard(self)
        done = []
        try:  # the output rule once more, at the last moment: an input read since is never replaced
            for _, final, _ in self._staged:
                option = self._targets.get(os.path.realpath(final), "output")
                check_not_input(
                    self._given.get(os.path.realpath(final), final), self._inputs.values(), option
                )
        except InputError:
            self.discard()
            raise
        for tmp, final, announce in self._staged:
            if not tmp.exists():
                continue
            os.replace(tmp, final)
            done.append(final)
            if announce and note is not None:
                note(f"wrote {final}")
        self._staged.clear()
        return done

    def discard(self) -> None:
        """Remove the temporary files of a failed command."""
        _ACTIVE.discard(self)
        for tmp, _, _ in self._staged:
            with contextlib.suppress(OSError):
                tmp.unlink()
        self._staged.clear()


def _finite(obj: Any) -> Any:
    import math

    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj


def json_text(obj: Any, indent: int | None = 2) -> str:
    """Strict JSON (RFC 8259): NaN and infinities become ``null``, so every
    JSON parser reads chatterlab's output."""
    import json

    return json.dumps(_finite(obj), indent=indent, allow_nan=False)
