"""Small I/O helpers shared by result objects."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from typing import IO, Any


@contextlib.contextmanager
def text_out(target: str | os.PathLike[str] | IO[str]) -> Iterator[Any]:
    """Open ``target`` for writing text (CSV-friendly), or pass a file-like
    object through.  Files are written to a temporary name and renamed, so an
    interrupted write never leaves half a file."""
    if hasattr(target, "write"):
        yield target
        return
    path = os.fspath(target)
    tmp = f"{path}.part"
    with open(tmp, "w", newline="") as fh:
        yield fh
    os.replace(tmp, path)
