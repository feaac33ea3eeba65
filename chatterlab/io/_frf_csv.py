"""Measured FRFs in CSV/TXT columns: the reader and the (atomic) writer
(format in docs/measured-frf.md, "CSV and TXT")."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from ..errors import InputError
from ._frf_table import (
    _QNAME,
    SI_UNITS,
    FRFRecord,
    _check_increasing,
    _delimiter,
    _is_number,
    _lines,
    _number,
    _resolve_units,
    _split,
    check_points,
    parse_frf_units,
    to_si,
)

__all__ = ["read_frf_csv", "write_frf_csv"]


# ============================================================================ CSV / TXT

_FREQ = re.compile(
    r"^(?:f|freq|frequency)(?:\s*[\[(]\s*(?P<unit>[^\])]*?)\s*[\])]|[\s_]+(?P<bare>hz))?$", re.I
)
#: the part words of a column (upper or lower case), by the part they name
_PART_WORDS = {
    "re": ("re", "real", "real part"),
    "im": ("im", "imag", "imaginary", "imag part", "imaginary part"),
    "mag": ("mag", "magnitude", "abs", "amp", "amplitude"),
    "phase": ("phase", "phase angle", "arg", "angle"),
    "coh": ("coh", "coherence"),
}
_PARTS = {w: part for part, words in _PART_WORDS.items() for w in words}
_WORD = "|".join(sorted((w.replace(" ", r"[\s_]") for w in _PARTS), key=len, reverse=True))
#: a bracketed unit after a name: ``[mm/N]``, ``(deg)``; or ``_deg``/`` rad`` after a phase
_UNIT = r"(?:\s*[\[(]\s*(?P<unit>[^\])]*?)\s*[\])]|[\s_]+(?P<bare>deg|degrees?|rad|radians?))?"
#: PAIR PART [unit] (``xx re``, ``tool.x/tool.y_imag``, ``re``); PART PAIR [unit] (``re tool.x/tool.x [m/N]``,
#: as ``chatterlab frf`` writes); ``|PAIR| [unit]`` (a magnitude, as ``chatterlab frf`` writes)
_PAIR_PART = re.compile(rf"^(?P<pair>.*?)(?:^|[\s_:]+)(?P<part>{_WORD}){_UNIT}$", re.I)
_PART_PAIR = re.compile(rf"^(?P<part>{_WORD})[\s_:]+(?P<pair>[^\s\[(]+){_UNIT}$", re.I)
_ABS_PAIR = re.compile(rf"^\|(?P<pair>[^|]+)\|{_UNIT}$", re.I)
#: the simplest header, named in every refusal of a header
SIMPLEST = (
    "the simplest header is 'f, re, im' (or 'f, mag, phase [deg]'), with a line '# units: m/N' above it"
)
_PHASE_UNITS = {
    "deg": False,
    "degree": False,
    "degrees": False,
    "°": False,
    "rad": True,
    "radian": True,
    "radians": True,
}
_DIRS = "xyz"
#: the '# key:' lines the reader acts on (above the header row; below it they are refused, never ignored)
_READ_KEYS = ("units", "unit", "quantity", "point")
_KEY_VALUE = re.compile(r"^#\s*([A-Za-z][\w ]*?)\s*[:=]\s*(.*)$")


def _pair_names(pair: str, point: str | None, where: str, column: str) -> tuple[str, str]:
    p = pair.strip().strip("_:")
    if not p:
        return ("response", "reference")
    if "/" in p:
        o, _, i = p.partition("/")
        if not o.strip() or not i.strip():
            raise InputError(
                f"{where}, column {column!r}: write the pair as OUTPUT/INPUT, e.g. tool.x/tool.y"
            )
        return o.strip(), i.strip()
    if len(p) == 2 and p[0].lower() in _DIRS and p[1].lower() in _DIRS:
        pre = f"{point}." if point else ""
        return pre + p[0].lower(), pre + p[1].lower()
    raise InputError(
        f"{where}, column {column!r}: cannot tell the response and reference of {p!r}; name the pair"
        " OUTPUT/INPUT (tool.x/tool.y) or with two directions (xy: response x, force y)"
    )


@dataclass
class _Column:
    index: int
    name: str
    pair: tuple[str, str]
    part: str
    unit: str | None
    raw: str = ""


def _column(c: str) -> tuple[str, str, str | None] | None:
    """(pair, part, unit) of a column name, None when it is not one."""
    for rx in (_PAIR_PART, _PART_PAIR, _ABS_PAIR):
        m = rx.match(c.strip())
        if m:
            part = (
                _PARTS[" ".join(m["part"].lower().replace("_", " ").split())]
                if "part" in m.re.groupindex
                else "mag"
            )
            return m["pair"], part, m["unit"] if m["unit"] is not None else m["bare"]
    return None


def _parse_header(cells: list[str], point: str | None, where: str, line: int) -> list[_Column]:
    m = _FREQ.match(cells[0])
    if not m:
        raise InputError(
            f"{where}, line {line}: the first column must be the frequency in Hz (named f, freq or"
            f" frequency [Hz]); got {cells[0]!r}; {SIMPLEST}"
        )
    unit = (m["unit"] or m["bare"] or "hz").strip().lower()
    if unit != "hz":
        raise InputError(
            f"{where}, line {line}: the frequency column must be in Hz (got {unit!r}); convert it"
        )
    cols = []
    for k, c in enumerate(cells[1:], 1):
        got = _column(c)
        if got is None:
            raise InputError(
                f"{where}, line {line}, column {k + 1} {c!r}: not a known column; {SIMPLEST}; per pair:"
                " 'tool.x/tool.x re', 'xx_imag', 'xy magnitude', 'phase [rad]', 'coh' (docs/measured-frf.md)"
            )
        pair, part, cunit = got
        if part == "phase":
            u = (cunit or "").strip().lower()
            if u not in _PHASE_UNITS:
                raise InputError(
                    f"{where}, line {line}, column {k + 1} {c!r}: "
                    + (f"phase unit {cunit!r}; " if cunit else "the phase needs its unit: ")
                    + "write 'phase [deg]' or 'phase [rad]'"
                )
        elif part == "coh" and cunit:
            raise InputError(f"{where}, line {line}, column {k + 1} {c!r}: a coherence has no unit")
        cols.append(_Column(k, c, _pair_names(pair, point, where, c), part, cunit, pair.strip()))
    return cols


def read_frf_csv(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    quantity: str | None = None,
    point: str | None = None,
) -> FRFRecord:
    """Read a CSV/TXT FRF file (docs/measured-frf.md, "CSV and TXT").

    ``# key: value`` comment lines (``units``, ``quantity``, ``point``, any
    other key kept in ``meta``), then a header row naming the columns (the
    frequency in Hz first, then per pair ``re``/``im`` or ``mag``/``phase``
    [deg] and optionally ``coh``), then one row per frequency.  A file of
    three unnamed numeric columns is (f [Hz], Re, Im).  Delimiter: comma,
    tab, semicolon or blanks (from the header row)."""
    p = Path(os.fspath(path))
    where = str(p)
    header: dict[str, str] = {}
    cols: list[_Column] | None = None
    delim: str | None = None
    rows: list[list[float]] = []
    lines: list[int] = []
    header_line = 0
    for n, line in _lines(p):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            kv = _KEY_VALUE.match(s)
            if kv and cols is None:
                header[kv[1].strip().lower()] = kv[2].strip()
            elif kv and kv[1].strip().lower() in _READ_KEYS:
                raise InputError(
                    f"{where}, line {n}: '# {kv[1].strip()}' below the header row (line {header_line}) is not"
                    " read; move it above the header row"
                )
            continue
        if cols is None:
            delim = _delimiter(s)
            cells = _split(s, delim)
            pt = point if point is not None else header.get("point")
            if all(_is_number(c) for c in cells):
                if len(cells) != 3:
                    raise InputError(
                        f"{where}, line {n}: no header row naming the columns; a file without one must have"
                        f" exactly 3 columns (f [Hz], Re, Im), this line has {len(cells)}"
                    )
                cols = _parse_header(["f", "re", "im"], pt, where, n)
            else:
                cols = _parse_header(cells, pt, where, n)
                header_line = n
                continue
        assert cols is not None
        cells = _split(s, delim)
        if len(cells) != len(cols) + 1:
            raise InputError(
                f"{where}, line {n}: {len(cells)} columns, the header has {len(cols) + 1}; a missing or extra value"
            )
        names = ["frequency"] + [c.name for c in cols]
        rows.append([_number(t, where, n, names[k]) for k, t in enumerate(cells)])
        lines.append(n)
        check_points(len(rows), where, n)
    if cols is None or not rows:
        raise InputError(f"{where}: no data rows (f [Hz], Re, Im per line)")
    data = np.array(rows)
    f = data[:, 0]
    _check_increasing(f, lines, where)
    col_units = {c.unit for c in cols if c.part in ("re", "im", "mag") and c.unit}
    if len({parse_frf_units(u, f"{where}, line {header_line}: a column's unit") for u in col_units}) == 1:
        col_units = {min(col_units)}
    if len(col_units) > 1:
        raise InputError(
            f"{where}, line {header_line}: the columns give different units {sorted(col_units)}; use one"
        )
    file_units = header.get("units") or header.get("unit")
    if col_units:
        cu = col_units.pop()
        if file_units is not None and parse_frf_units(cu, where) != parse_frf_units(file_units, where):
            raise InputError(
                f"{where}, line {header_line}: the columns say {cu!r} but '# units' says {file_units!r}; make them agree"
            )
        file_units = file_units or cu
    scale, power, used = _resolve_units(units, quantity, file_units, header.get("quantity"), where, None)
    A, coh, outs, ins = _assemble(cols, data, where, header_line, lines)
    meta = {k: v for k, v in header.items()}
    meta.update({"units": used, "quantity": _QNAME[power], "format": "csv"})
    return FRFRecord(f, to_si(f, A, scale, power, where, lines), outs, ins, _QNAME[power], coh, where, meta)


def _assemble(
    cols: list[_Column], data: np.ndarray, where: str, line: int, lines: list[int]
) -> tuple[np.ndarray, np.ndarray | None, tuple[str, ...], tuple[str, ...]]:
    """Complex matrix (n_out, n_in, n) from the columns of each pair; a pair
    given both as re/im and as mag/phase (``chatterlab frf`` writes both)
    is read from re/im and the two must agree."""
    parts: dict[tuple[str, str], dict[str, int]] = {}
    phase_rad: dict[tuple[str, str], bool] = {}
    raw: dict[tuple[str, str], str] = {}
    for c in cols:
        raw.setdefault(c.pair, c.raw)
        if c.part == "phase":
            phase_rad[c.pair] = _PHASE_UNITS[(c.unit or "").strip().lower()]
        d = parts.setdefault(c.pair, {})
        if c.part in d:
            raise InputError(
                f"{where}, line {line}: column {c.name!r} repeats the {c.part} of {'/'.join(c.pair)}"
            )
        d[c.part] = c.index
    outs = tuple(dict.fromkeys(o for o, _ in parts))
    ins = tuple(dict.fromkeys(i for _, i in parts))
    n = data.shape[0]
    A = np.zeros((len(outs), len(ins), n), dtype=complex)
    coh = np.ones((len(outs), len(ins), n))
    any_coh = False
    for (o, i), d in parts.items():
        pair = raw[(o, i)] or f"{o}/{i}"
        forms = [
            f
            for f, need in (("re/im", ("re", "im")), ("mag/phase", ("mag", "phase")))
            if any(k in d for k in need)
        ]
        if not forms:
            raise InputError(
                f"{where}, line {line}: pair {pair} has only a coherence; add its re and im columns"
            )
        for form in forms:
            for need in form.split("/"):
                if need not in d:
                    raise InputError(
                        f"{where}, line {line}: column '{pair} {need}' is missing (the pair has the other part"
                        f" of {form}); {SIMPLEST}"
                    )
        z_mp = None
        if "mag/phase" in forms:
            mag = data[:, d["mag"]]
            neg = np.nonzero(mag < 0)[0]
            if neg.size:
                raise InputError(
                    f"{where}, line {lines[int(neg[0])]}: magnitude {mag[neg[0]]:g} of {pair} is negative; a"
                    " magnitude is |H| >= 0 (a signed value is a real part: name the column re)"
                )
            ph = data[:, d["phase"]]
            z_mp = mag * np.exp(1j * (ph if phase_rad[(o, i)] else np.radians(ph)))
        if "re/im" in forms:
            z = data[:, d["re"]] + 1j * data[:, d["im"]]
            if z_mp is not None:
                off = np.abs(z - z_mp) > 1e-3 * np.maximum(np.abs(z), np.abs(z_mp)) + 1e-300  # printed digits
                if off.any():
                    k = int(np.nonzero(off)[0][0])
                    raise InputError(
                        f"{where}, line {lines[k]}: pair {pair} is given twice (re/im and mag/phase) and the two"
                        " disagree there by more than 0.1 %; keep one form"
                    )
        else:
            assert z_mp is not None
            z = z_mp
        A[outs.index(o), ins.index(i)] = z
        if "coh" in d:
            any_coh = True
            coh[outs.index(o), ins.index(i)] = data[:, d["coh"]]
    missing = [f"{o}/{i}" for o in outs for i in ins if (o, i) not in parts]
    if missing:
        raise InputError(
            f"{where}, line {line}: the pairs form a {len(outs)}x{len(ins)} matrix but {', '.join(missing)}"
            " is not given; add its columns (zeros if it is negligible)"
        )
    if any_coh:
        bad = np.nonzero(~np.all((coh >= 0) & (coh <= 1 + 1e-9), axis=(0, 1)))[0]
        if bad.size:
            raise InputError(f"{where}, line {lines[int(bad[0])]}: a coherence outside [0, 1]")
    return A, (coh if any_coh else None), outs, ins


def _text(value: Any) -> str:
    """A header value as written: floats exactly (repr), booleans as true/false."""
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, float | np.floating):
        return repr(float(value))
    return " ".join(str(value).split())  # one line


#: the columns of each pair, by form: (part, name pattern) in order
_FORMS = {
    "reim": ("re", "im"),
    "magphase": ("mag", "phase"),
    "both": ("mag", "phase", "re", "im"),
}


def write_frf_csv(
    path: str | os.PathLike[str] | IO[str],
    record: FRFRecord,
    *,
    units: str | None = None,
    form: str = "reim",
    comments: bool = True,
) -> Path | None:
    """Write a CSV file that :func:`read_frf_csv` reads back
    (docs/measured-frf.md, "CSV and TXT").

    With ``comments``: a ``# chatterlab FRF`` line, ``# units``, ``#
    quantity`` and ``# source``, and one ``# key: value`` line per entry of
    ``record.meta`` (floats as ``repr``: exact).  Then a header row
    (``frequency [Hz]``, then per pair, outputs outer and inputs inner,
    ``re OUT/IN [unit]``, ``im OUT/IN [unit]``; ``form="magphase"``:
    ``|OUT/IN| [unit]``, ``phase OUT/IN [deg]``; ``"both"``: magnitude,
    phase, real and imaginary part; ``coh OUT/IN`` when the coherence is
    known) and one row per frequency, every value with 17 significant digits
    (re/im: an exact round trip).  ``units`` (default: SI, ``m/N``,
    ``m/s/N``, ``m/s^2/N``) must be a unit of the record's quantity
    (``mm/N`` for a receptance).  Written atomically; a text stream is
    written to as it is (returns None), a path is returned."""
    from ._files import text_out

    power = _QNAME.index(record.quantity)
    units = SI_UNITS[power] if units is None else units
    scale, p = parse_frf_units(units, "units")
    if p != power:
        raise InputError(
            f"units {units!r} are a {_QNAME[p]}, the FRF is a {record.quantity}: give a unit of a"
            f" {record.quantity} ({SI_UNITS[power]} scaled, e.g. m{SI_UNITS[power][1:]} -> mm{SI_UNITS[power][1:]})"
        )
    if form not in _FORMS:
        raise InputError(f"form must be 'reim', 'magphase' or 'both' (got {form!r})")
    for name in record.outputs + record.inputs:
        bad = [c for c in ",|/" if c in name]
        if bad or name != name.strip():
            raise InputError(
                f"coordinate name {name!r} holds {bad[0] if bad else 'blanks at an end'!r}; rename it"
            )
    head = ["frequency [Hz]"]
    cols: list[np.ndarray] = [np.asarray(record.frequency_hz, dtype=float)]
    for o, on in enumerate(record.outputs):
        for i, inn in enumerate(record.inputs):
            z = record.data[o, i] / scale
            pair = f"{on}/{inn}"
            for part in _FORMS[form]:
                if part == "re":
                    head.append(f"re {pair} [{units}]")
                    cols.append(z.real)
                elif part == "im":
                    head.append(f"im {pair} [{units}]")
                    cols.append(z.imag)
                elif part == "mag":
                    head.append(f"|{pair}| [{units}]")
                    cols.append(np.abs(z))
                else:
                    head.append(f"phase {pair} [deg]")
                    cols.append(np.degrees(np.angle(z)))
            if record.coherence is not None:
                head.append(f"coh {pair}")
                cols.append(record.coherence[o, i])
    data = np.column_stack(cols)
    with text_out(path) as fh:
        if comments:
            fh.write("# chatterlab FRF\n")
            fh.write(f"# units: {units}\n# quantity: {record.quantity}\n")
            if record.source:
                fh.write(f"# source: {_text(record.source)}\n")
            for key, val in record.meta.items():
                if val is not None and key not in ("units", "quantity", "source"):
                    fh.write(f"# {key}: {_text(val)}\n")
        fh.write(",".join(head) + "\n")
        for row in data:
            fh.write(",".join(f"{v:.17g}" for v in row) + "\n")
    return None if hasattr(path, "write") else Path(os.fspath(path))
