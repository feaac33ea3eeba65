"""Reader of ``[frf]``: a measured FRF as the structure of a model.

A model whose structure is a measured tool-point FRF (a tap test) instead of
bodies, beams or matrices.  The table names the file (CSV/TXT, CutPro-style
``.frf``, UFF 58/58b: ``docs/measured-frf.md``); its output and input
coordinates become the coordinates that ``[[point]]`` coords name, so the
``[[coupling]]`` and ``[process]`` of the file are written exactly as for a
matrix-level model.  The file is read when the model is read: a bad file is
a one-line error naming the model, the table and the field.  The model
keeps what io read (plain arrays: :func:`chatterlab.io.read_frf`); the
structure layer makes the :class:`~chatterlab.structure.FRF` of it
(:func:`chatterlab.lobes.model_frf`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..errors import InputError, ModelError
from ..io._frf_files import read_frf
from ._fields import _Item
from ._items import FrfSource
from ._matrices import _matrix_path

__all__ = ["read_frf_table"]

_FIELDS = ("file", "units", "quantity", "point", "format", "description")
_STRUCTURAL = (
    "matrices",
    "mode",
    "body",
    "node",
    "beam",
    "attachment",
    "contact",
    "constraint",
    "movable",
    "spring",
)


def read_frf_table(src: str, raw: dict[str, Any], base_dir: Path, files_outside: bool) -> FrfSource | None:
    """The ``[frf]`` table (None when the file has none)."""
    if "frf" not in raw:
        return None
    clash = [k for k in _STRUCTURAL if k in raw]
    if clash:
        raise ModelError(
            f"a measured FRF ([frf]) is the whole structure: remove {', '.join(clash)} (couple a measured"
            " spindle to a modelled tool with chatterlab.structure.rcsa instead)",
            source=src,
            item="[frf]",
        )
    it = _Item(src, "[frf]", raw["frf"], _FIELDS)
    name = it.str("file")
    path = _matrix_path(it, "file", name, base_dir, files_outside)
    units = it.str("units", None)
    quantity = it.str("quantity", None)
    point = it.str("point", None)
    fmt = it.str("format", None)
    try:
        table = read_frf(path, units=units, quantity=quantity, point=point, format=fmt)
    except InputError as exc:
        raise it.err("file", str(exc)) from None
    return FrfSource(name, str(path), table, units, quantity)
