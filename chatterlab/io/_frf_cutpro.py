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
    FRFRecord,
    _check_increasing,
    _is_number,
    _lines,
    _number,
    _resolve_units,
    check_points,
    parse_frf_units,
    to_si,
)

__all__ = ["read_frf_cutpro"]

#: the header keys the reader acts on (others are kept in ``meta``)
_KEYS = ("units", "unit", "quantity", "point")
#: a row's first value that starts like a number but is none: '1,5' (a decimal comma), '100;1e-7;...'
_NUMBER_LIKE = re.compile(r"^[+-]?(?:\d|\.\d)")
_FREQUENCY_UNITS = ("khz", "mhz", "rad/s", "rpm", "cpm", "1/s")


def _header_line(
    s: str,
    n: int,
    where: str,
    header: dict[str, str],
    captions: list[str],
    caption_units: list[tuple[int, str]],
) -> None:
    """One header line (before the first row): ``key: value`` / ``key =
    value`` or a caption; a line that starts like a number but is none, a
    misspelt key the reader acts on and a frequency unit other than Hz are
    refused (never read as a title)."""
    import difflib

    first = s.split()[0]
    if _NUMBER_LIKE.match(first):
        raise InputError(
            f"{where}, line {n}: {first!r} is not a number (a decimal comma, or values separated by ',' or ';'?);"
            " a .frf row is frequency [Hz], Re, Im separated by tabs or blanks"
        )
    m = re.match(r"^[#%!]?\s*([A-Za-z][\w ]*?)\s*[:=]\s*(.*)$", s)
    if m:
        key = m[1].strip().lower()
        near = difflib.get_close_matches(key, _KEYS, n=1, cutoff=0.8)
        if key not in _KEYS and near:
            raise InputError(
                f"{where}, line {n}: unknown header key {m[1].strip()!r}; did you mean {('units' if near[0] == 'unit' else near[0])!r}?"
            )
        if key in header and header[key] != m[2].strip():
            raise InputError(f"{where}, line {n}: {m[1].strip()!r} is given twice, differently; keep one")
        header[key] = m[2].strip()
        return
    captions.append(s)
    for u in re.findall(r"[\[(]\s*([^\])]*?)\s*[\])]", s):
        low = u.strip().lower()
        if low == "hz":
            continue
        if low in _FREQUENCY_UNITS:
            raise InputError(
                f"{where}, line {n}: the frequency must be in Hz (the caption says {u!r}); convert it"
            )
        try:
            parse_frf_units(u, where)
        except InputError:
            continue  # not a unit: a title's remark in brackets
        caption_units.append((n, u.strip()))


# ============================================================================ CutPro-style .frf


def read_frf_cutpro(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    quantity: str | None = None,
    point: str | None = None,
) -> FRFRecord:
    """Read a CutPro-style ``.frf`` text file (docs/measured-frf.md).

    Header lines (any line before the first numeric row): ``key: value`` or
    ``key = value``; the key ``units`` (or ``unit``) gives the unit,
    ``quantity`` the quantity, ``point`` the point; other lines (a title,
    column captions) are kept in ``meta``, and a unit in brackets in a
    caption (``Real(mm/N)``) is the unit too (it must agree with ``units``).
    Then one row per frequency: frequency [Hz], Re, Im, separated by tabs
    (or blanks).  Without a unit anywhere the data are m/N (receptance), as
    CutPro writes them."""
    p = Path(os.fspath(path))
    where = str(p)
    header: dict[str, str] = {}
    captions: list[str] = []
    caption_units: list[tuple[int, str]] = []  # (line, unit) of the captions' bracketed FRF units
    units_line = 0
    rows: list[list[float]] = []
    lines: list[int] = []
    for n, line in _lines(p):
        s = line.strip()
        if not s:
            continue
        if not rows and not _is_number(s.split()[0]):
            _header_line(s, n, where, header, captions, caption_units)
            if "units" in header or "unit" in header:
                units_line = units_line or n
            continue
        cells = s.split()
        if len(cells) != 3:
            raise InputError(
                f"{where}, line {n}: {len(cells)} values; a .frf row is frequency [Hz], Re, Im separated by tabs"
            )
        rows.append([_number(t, where, n, c) for t, c in zip(cells, ("frequency", "Re", "Im"), strict=True)])
        lines.append(n)
        check_points(len(rows), where, n)
    if not rows:
        raise InputError(f"{where}: no data rows (frequency [Hz], Re, Im per line)")
    data = np.array(rows)
    f = data[:, 0]
    _check_increasing(f, lines, where)
    file_units = header.get("units") or header.get("unit")
    for n, u in caption_units:
        said = file_units if file_units is not None else caption_units[0][1]
        if parse_frf_units(u, where) != parse_frf_units(said, where):
            other = (
                f"'Units: {file_units}'"
                if file_units is not None
                else f"line {caption_units[0][0]}'s {said!r}"
            )
            raise InputError(f"{where}, line {n}: the caption says {u!r} but {other}; make them agree")
    if file_units is None and caption_units:
        file_units = caption_units[0][1]
    scale, power, used = _resolve_units(units, quantity, file_units, header.get("quantity"), where, "m/N")
    pt = point if point is not None else header.get("point")
    name = pt if pt else "response"
    A = to_si(f, (data[:, 1] + 1j * data[:, 2])[None, None, :], scale, power, where, lines)
    meta: dict[str, Any] = dict(header)
    meta.update({"units": used, "quantity": _QNAME[power], "format": "frf"})
    if captions:
        meta["captions"] = captions
    return FRFRecord(f, A, (name,), (name if pt else "reference",), _QNAME[power], None, where, meta)
