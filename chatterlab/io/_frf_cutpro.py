"""Measured FRFs in CutPro-style ``.frf`` text files: the reader (format
in docs/measured-frf.md)."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ._frf_table import (
    _QNAME,
    FRFTable,
    _check_increasing,
    _is_number,
    _lines,
    _number,
    _resolve_units,
    _to_receptance,
)

__all__ = ["read_frf_cutpro"]


# ============================================================================ CutPro-style .frf


def read_frf_cutpro(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    quantity: str | None = None,
    point: str | None = None,
) -> FRFTable:
    """Read a CutPro-style ``.frf`` text file (docs/measured-frf.md).

    Header lines (any line before the first numeric row): ``key: value`` or
    ``key = value``; the key ``units`` (or ``unit``) gives the unit,
    ``quantity`` the quantity, ``point`` the point; other lines (a title,
    column captions) are kept in ``meta``.  Then one row per frequency:
    frequency [Hz], Re, Im, separated by tabs (or blanks).  Without a units
    line the data are m/N (receptance), as CutPro writes them."""
    p = Path(os.fspath(path))
    where = str(p)
    header: dict[str, str] = {}
    captions: list[str] = []
    rows: list[list[float]] = []
    lines: list[int] = []
    for n, line in _lines(p):
        s = line.strip()
        if not s:
            continue
        if not rows and not _is_number(s.split()[0]):
            m = re.match(r"^[#%!]?\s*([A-Za-z][\w ]*?)\s*[:=]\s*(.*)$", s)
            if m:
                header[m[1].strip().lower()] = m[2].strip()
            else:
                captions.append(s)
            continue
        cells = s.split()
        if len(cells) != 3:
            raise InputError(
                f"{where}, line {n}: {len(cells)} values; a .frf row is frequency [Hz], Re, Im separated by tabs"
            )
        rows.append([_number(t, where, n, c) for t, c in zip(cells, ("frequency", "Re", "Im"), strict=True)])
        lines.append(n)
    if not rows:
        raise InputError(f"{where}: no data rows (frequency [Hz], Re, Im per line)")
    data = np.array(rows)
    f = data[:, 0]
    _check_increasing(f, lines, where)
    scale, power, used = _resolve_units(
        units, quantity, header.get("units") or header.get("unit"), header.get("quantity"), where, "m/N"
    )
    pt = point if point is not None else header.get("point")
    name = pt if pt else "response"
    H = _to_receptance(f, (data[:, 1] + 1j * data[:, 2])[:, None, None], scale, power, where, lines)
    meta: dict[str, Any] = dict(header)
    meta.update({"units": used, "quantity": _QNAME[power], "format": "frf"})
    if captions:
        meta["captions"] = captions
    return FRFTable(f, H, (name,), (name if pt else "reference",), None, where, meta)
