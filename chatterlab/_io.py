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
