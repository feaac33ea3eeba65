"""Small I/O helpers shared by result objects and the command line.

* :func:`text_out` -- write a text file atomically (temporary name, rename).
* :class:`Outputs` -- the files one command will write: checked before it
  computes (suffix, directory, writability, never an input), written under
  temporary names in their own directories and moved into place together
  only when the command has succeeded, so a failed run leaves no file and
  never half a file.
"""

from __future__ import annotations

import contextlib
import os
import secrets
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
    "clean_stale",
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


class Outputs:
    """The files one command writes.

    :meth:`add` checks an output before anything is computed: a documented
    suffix, an existing and writable directory, not a directory itself, not
    one of ``inputs`` (the model file...), not named twice.  :meth:`path`
    gives the temporary name to write instead; :meth:`commit` moves every
    temporary file onto its target (``os.replace``) once the command has
    succeeded, :meth:`discard` removes them after a failure.  An existing
    target is replaced (chatterlab's policy on outputs: docs/cli.md).
    """

    def __init__(self, inputs: Iterable[str | os.PathLike[str]] = ()) -> None:
        self._inputs = {os.path.realpath(p): os.fspath(p) for p in inputs}
        self._targets: dict[str, str] = {}  # real path -> option
        self._staged: list[tuple[Path, Path, bool]] = []  # (tmp, final, announce)

    def add(self, path: str | None, option: str, suffixes: tuple[str, ...]) -> str | None:
        """Check one output path (None: the option was not given)."""
        if path is None:
            return None
        p = Path(path)
        if p.suffix.lower() not in suffixes:
            raise InputError(
                f"{option} {path!r}: the file name must end in {', '.join(suffixes)}"
                f"{' (the suffix picks the format)' if len(suffixes) > 1 else ''}"
            )
        real = os.path.realpath(p)
        if real in self._inputs:
            raise InputError(
                f"{option} {path!r} is an input of this command ({self._inputs[real]}); it is never overwritten"
            )
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
        done = []
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
