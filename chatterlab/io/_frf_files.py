"""Measured FRF files: CSV/TXT columns, UFF dataset 58/58b, CutPro-style
``.frf`` text; readers and (atomic) writers.

io knows nothing of the analyses: a reader returns an :class:`FRFTable`
(plain arrays, receptance in m/N, frequency in Hz, coordinate names), which
:class:`chatterlab.structure.MeasuredFRF` turns into the measured structure.
The formats are specified field by field in docs/measured-frf.md.

Units and quantities
--------------------
A file holds a receptance (displacement/force), a mobility
(velocity/force) or an accelerance (acceleration/force) in some length unit.
The unit string says both: ``m/N``, ``mm/N``, ``um/N`` (``µm/N``) are
receptances; ``m/s/N`` (``mm/s/N``, ``m/(N s)``) mobilities; ``m/s^2/N``
(``m/s2/N``, ``m/(N s^2)``) and ``g/N`` (g = 9.80665 m/s^2) accelerances.
The quantity word (``receptance``, ``mobility``, ``accelerance``; also
``compliance``, ``inertance``...) may be given alone (SI then) or with the
unit, which must agree.  Everything is converted to receptance in m/N:
H = scale * A / (j w)^p with p = 0, 1, 2 (Ewins [1], sec. 2.7), so a
mobility or accelerance at 0 Hz cannot be converted and is refused.

References
----------
.. [1] D. J. Ewins, *Modal Testing: Theory, Practice and Application*, 2nd
   ed., Research Studies Press, 2000.
.. [2] Universal File Format, dataset 58 (function at nodal DOF), SDRC /
   Siemens I-deas documentation; read and written through pyuff.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = [
    "FRFTable",
    "FRF_SUFFIXES",
    "parse_frf_units",
    "read_frf",
    "read_frf_csv",
    "read_frf_cutpro",
    "read_frf_uff",
    "write_frf_csv",
    "write_frf_uff",
]

#: suffixes of measured-FRF files, by format
FRF_SUFFIXES = {".csv": "csv", ".txt": "csv", ".frf": "frf", ".uff": "uff", ".unv": "uff"}

#: standard gravity, m/s^2 (the unit g of an accelerometer)
G0 = 9.80665

_LENGTHS = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "μm": 1e-6, "micron": 1e-6, "nm": 1e-9}
_QUANTITIES = {
    "receptance": 0,
    "compliance": 0,
    "dynamic compliance": 0,
    "displacement": 0,
    "mobility": 1,
    "admittance": 1,
    "velocity": 1,
    "accelerance": 2,
    "inertance": 2,
    "acceleration": 2,
}
_QNAME = ("receptance", "mobility", "accelerance")


@dataclass(frozen=True, eq=False)
class FRFTable:
    """A measured FRF as read from (or to be written to) a file.

    ``frequency_hz`` (n,), Hz, strictly increasing; ``H`` (n, n_out, n_in)
    receptance in m/N; ``coherence`` like ``H`` (real) or None; ``meta``:
    what the file said (``units``, ``quantity`` as found, header keys)."""

    frequency_hz: np.ndarray
    H: np.ndarray
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    coherence: np.ndarray | None = None
    source: str = ""
    meta: dict[str, Any] = field(default_factory=dict)


# ============================================================================ units


def parse_frf_units(units: str, where: str = "units") -> tuple[float, int]:
    """(scale to SI length, power p of j w) of an FRF unit string:
    ``"mm/N"`` -> (1e-3, 0), ``"m/s^2/N"`` -> (1, 2), ``"g/N"`` -> (9.80665, 2)."""
    raw = units
    s = units.strip().lower().replace("²", "^2").replace("**", "^")
    s = re.sub(r"[\s()*·]", "", s)
    s = s.replace("µ", "u").replace("μ", "u")
    tokens = s.split("/")
    bad = InputError(
        f"{where}: cannot convert {raw!r} to receptance; give a unit like m/N, mm/N, um/N (receptance),"
        " m/s/N (mobility), m/s^2/N or g/N (accelerance)"
    )
    if len(tokens) < 2:
        raise bad
    num = tokens[0]
    power = 0
    if num == "g":
        scale, power = G0, 2
    elif num in _LENGTHS or num.replace("u", "µ") in _LENGTHS:
        scale = _LENGTHS.get(num, 1e-6)
    else:
        raise bad
    newtons = 0
    for t in tokens[1:]:
        m = re.fullmatch(r"(n)?(s(?:\^?([12]))?)?(n)?", t)
        if not m or not t:
            raise bad
        newtons += (m[1] is not None) + (m[4] is not None)
        if m[2]:
            power += int(m[3] or 1)
    if newtons != 1 or power > 2:
        raise bad
    return scale, power


def _quantity_power(q: str, where: str) -> int:
    k = " ".join(q.strip().lower().split())
    if k not in _QUANTITIES:
        raise InputError(
            f"{where}: unknown quantity {q!r}; use receptance (displacement/force), mobility (velocity/force)"
            " or accelerance (acceleration/force)"
        )
    return _QUANTITIES[k]


def _resolve_units(
    arg_units: str | None,
    arg_quantity: str | None,
    file_units: str | None,
    file_quantity: str | None,
    where: str,
    default: str | None,
) -> tuple[float, int, str]:
    """Scale, power and a description of the units in force.  A unit or
    quantity given by the caller and a different one in the file is an
    error (never silently one of them)."""
    for what, a, f in (("units", arg_units, file_units), ("quantity", arg_quantity, file_quantity)):
        if a is not None and f is not None:
            same = (
                parse_frf_units(a, f"{where}: {what}") == parse_frf_units(f, f"{where}: {what}")
                if what == "units"
                else _quantity_power(a, where) == _quantity_power(f, where)
            )
            if not same:
                raise InputError(
                    f"{where}: the file says {what} {f!r} but {a!r} was given; remove one of them"
                )
    units = arg_units if arg_units is not None else file_units
    quantity = arg_quantity if arg_quantity is not None else file_quantity
    if units is None and quantity is None:
        if default is None:
            raise InputError(
                f"{where}: the units are not given; add a line '# units: mm/N' (or m/s/N, m/s^2/N, g/N)"
                " to the file or give them (units=..., the CLI's --frf-units)"
            )
        units = default
    if units is not None:
        scale, power = parse_frf_units(units, f"{where}: units")
        if quantity is not None and _quantity_power(quantity, where) != power:
            raise InputError(
                f"{where}: units {units!r} are a {_QNAME[power]} but the quantity is {quantity!r}; make them agree"
            )
        return scale, power, units
    assert quantity is not None
    power = _quantity_power(quantity, where)
    return 1.0, power, ("m/N", "m/s/N", "m/s^2/N")[power]


def _to_receptance(
    f_hz: np.ndarray, A: np.ndarray, scale: float, power: int, where: str, lines: list[int] | None
) -> np.ndarray:
    """Receptance (m/N) from the file's quantity: scale * A / (j w)^power."""
    if power == 0:
        return A * scale
    zero = np.nonzero(f_hz == 0)[0]
    if zero.size:
        at = f", line {lines[zero[0]]}" if lines else ""
        raise InputError(
            f"{where}{at}: a {_QNAME[power]} at 0 Hz cannot be converted to receptance; drop that line"
        )
    jw = 1j * 2 * np.pi * f_hz
    return A * scale / (jw**power).reshape((-1,) + (1,) * (A.ndim - 1))


# ============================================================================ text reading helpers


def _lines(path: Path) -> Iterator[tuple[int, str]]:
    try:
        with open(path, encoding="utf-8-sig") as fh:
            for n, line in enumerate(fh, 1):
                yield n, line.rstrip("\r\n")
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except UnicodeDecodeError:
        raise InputError(
            f"{path}: not a text file (not UTF-8); a binary UFF file needs the suffix .uff or .unv"
        ) from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, not an FRF file") from None


def _split(line: str, delim: str | None) -> list[str]:
    parts = line.split(delim) if delim else line.split()
    return [p.strip() for p in parts]


def _delimiter(line: str) -> str | None:
    for d in (",", "\t", ";"):
        if d in line:
            return d
    return None


def _is_number(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _number(tok: str, where: str, line: int, column: str) -> float:
    try:
        x = float(tok)
    except ValueError:
        raise InputError(f"{where}, line {line}, column {column!r}: {tok!r} is not a number") from None
    if not math.isfinite(x):
        raise InputError(
            f"{where}, line {line}, column {column!r}: {tok} is not a finite number; drop or repair the line"
        )
    return x


def _check_increasing(f: np.ndarray, lines: list[int], where: str) -> None:
    if f.size < 2:
        raise InputError(f"{where}: at least 2 frequencies are needed (got {f.size})")
    if f[0] < 0:
        raise InputError(f"{where}, line {lines[0]}: frequency {f[0]:g} Hz is negative")
    d = np.diff(f)
    bad = np.nonzero(d <= 0)[0]
    if bad.size:
        k = int(bad[0])
        what = "repeats" if d[k] == 0 else "is lower than"
        raise InputError(
            f"{where}, line {lines[k + 1]}: frequency {f[k + 1]:g} Hz {what} the previous one"
            f" (line {lines[k]}, {f[k]:g} Hz); frequencies must increase strictly: sort and drop duplicates"
        )


# ============================================================================ CSV / TXT

_FREQ = re.compile(r"^(f|freq|frequency)\s*(?:[\[(]\s*([^\])]*)\s*[\])]|_(hz))?$", re.I)
_PART = re.compile(
    r"^(?P<pair>.*?)(?:^|[\s_:]+)(?P<part>re|real|im|imag|mag|abs|amp|phase|coh|coherence)"
    r"\s*(?:[\[(]\s*(?P<unit>[^\])]*)\s*[\])])?$",
    re.I,
)
_PARTS = {
    "re": "re",
    "real": "re",
    "im": "im",
    "imag": "im",
    "mag": "mag",
    "abs": "mag",
    "amp": "mag",
    "phase": "phase",
    "coh": "coh",
    "coherence": "coh",
}
_DIRS = "xyz"


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


def _parse_header(cells: list[str], point: str | None, where: str, line: int) -> list[_Column]:
    m = _FREQ.match(cells[0])
    if not m:
        raise InputError(
            f"{where}, line {line}: the first column must be the frequency in Hz (named f, freq or"
            f" frequency [Hz]); got {cells[0]!r}"
        )
    unit = (m[2] or m[3] or "hz").strip().lower()
    if unit != "hz":
        raise InputError(
            f"{where}, line {line}: the frequency column must be in Hz (got {unit!r}); convert it"
        )
    cols = []
    for k, c in enumerate(cells[1:], 1):
        pm = _PART.match(c)
        if not pm:
            raise InputError(
                f"{where}, line {line}, column {k + 1} {c!r}: not a known column; name it PAIR re, PAIR im"
                " (or mag, phase [deg], coh), e.g. 'tool.x/tool.x re' or 'xx_re'"
            )
        cols.append(
            _Column(
                k,
                c,
                _pair_names(pm["pair"], point, where, c),
                _PARTS[pm["part"].lower()],
                pm["unit"],
                pm["pair"].strip(),
            )
        )
    return cols


def read_frf_csv(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    quantity: str | None = None,
    point: str | None = None,
) -> FRFTable:
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
            key, sep, val = s[1:].partition(":")
            if sep and cols is None:
                header[key.strip().lower()] = val.strip()
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
    if cols is None or not rows:
        raise InputError(f"{where}: no data rows (f [Hz], Re, Im per line)")
    data = np.array(rows)
    f = data[:, 0]
    _check_increasing(f, lines, where)
    col_units = {c.unit for c in cols if c.part in ("re", "im", "mag") and c.unit}
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
    A, coh, outs, ins = _assemble(cols, data, where, header_line)
    H = _to_receptance(f, A, scale, power, where, lines)
    meta = {k: v for k, v in header.items()}
    meta.update({"units": used, "quantity": _QNAME[power], "format": "csv"})
    return FRFTable(f, H, outs, ins, coh, where, meta)


def _assemble(
    cols: list[_Column], data: np.ndarray, where: str, line: int
) -> tuple[np.ndarray, np.ndarray | None, tuple[str, ...], tuple[str, ...]]:
    """Complex matrix (n, n_out, n_in) from the columns of each pair."""
    parts: dict[tuple[str, str], dict[str, int]] = {}
    phase_rad: dict[tuple[str, str], bool] = {}
    raw: dict[tuple[str, str], str] = {}
    for c in cols:
        raw.setdefault(c.pair, c.raw)
        if c.part == "phase" and c.unit:
            u = c.unit.strip().lower()
            if u not in ("deg", "degree", "degrees", "°", "rad"):
                raise InputError(
                    f"{where}, line {line}, column {c.name!r}: phase unit {c.unit!r}; use deg or rad"
                )
            phase_rad[c.pair] = u == "rad"
        d = parts.setdefault(c.pair, {})
        if c.part in d:
            raise InputError(
                f"{where}, line {line}: column {c.name!r} repeats the {c.part} of {'/'.join(c.pair)}"
            )
        d[c.part] = c.index
    outs = tuple(dict.fromkeys(o for o, _ in parts))
    ins = tuple(dict.fromkeys(i for _, i in parts))
    n = data.shape[0]
    A = np.zeros((n, len(outs), len(ins)), dtype=complex)
    coh = np.ones((n, len(outs), len(ins)))
    any_coh = False
    for (o, i), d in parts.items():
        pair = raw[(o, i)] or f"{o}/{i}"
        if "re" in d or "im" in d:
            for need in ("re", "im"):
                if need not in d:
                    raise InputError(
                        f"{where}, line {line}: column '{pair} {need}' is missing (the pair has the other part)"
                    )
            if "mag" in d or "phase" in d:
                raise InputError(
                    f"{where}, line {line}: pair {pair} is given twice (re/im and mag/phase); keep one form"
                )
            z = data[:, d["re"]] + 1j * data[:, d["im"]]
        elif "mag" in d or "phase" in d:
            for need in ("mag", "phase"):
                if need not in d:
                    raise InputError(
                        f"{where}, line {line}: column '{pair} {need}' is missing (the pair has the other part)"
                    )
            ph = data[:, d["phase"]]
            z = data[:, d["mag"]] * np.exp(1j * (ph if phase_rad.get((o, i)) else np.radians(ph)))
        else:
            raise InputError(
                f"{where}, line {line}: pair {pair} has only a coherence; add its re and im columns"
            )
        A[:, outs.index(o), ins.index(i)] = z
        if "coh" in d:
            any_coh = True
            coh[:, outs.index(o), ins.index(i)] = data[:, d["coh"]]
    missing = [f"{o}/{i}" for o in outs for i in ins if (o, i) not in parts]
    if missing:
        raise InputError(
            f"{where}, line {line}: the pairs form a {len(outs)}x{len(ins)} matrix but {', '.join(missing)}"
            " is not given; add its columns (zeros if it is negligible)"
        )
    if any_coh and not np.all((coh >= 0) & (coh <= 1 + 1e-9)):
        raise InputError(f"{where}: a coherence outside [0, 1]")
    return A, (coh if any_coh else None), outs, ins


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


# ============================================================================ UFF 58 / 58b

_UFF_DIRS = {1: "x", 2: "y", 3: "z", 4: "rx", 5: "ry", 6: "rz"}
_UFF_DIR_CODES = {v: k for k, v in _UFF_DIRS.items()}
#: ordinate specific data types of dataset 58 (record 8) -> power of j w
_UFF_ORDINATE = {8: 0, 11: 1, 12: 2}


def _pyuff() -> Any:
    try:
        import pyuff
    except ImportError:
        raise InputError(
            "reading or writing UFF files needs pyuff: pip install chatterlab[uff] (or pip install pyuff)"
        ) from None
    return pyuff


def read_frf_uff(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    quantity: str | None = None,
    point: str | None = None,
) -> FRFTable:
    """Read the FRFs (function type 4) of a UFF file, datasets 58 and 58b.

    Each dataset is one (response node+direction, reference node+direction)
    pair; together they form the matrix, coordinates named ``NODE.DIR``
    (``x, y, z, rx, ry, rz``; a negative direction flips the sign of the
    data so the name is the positive axis) -- or ``ENTITY.DIR`` when every
    node carries one entity name (as chatterlab writes).  Coherences
    (function type 6) of the same pairs are read too.  The ordinate type
    (record 8: 8 displacement, 11 velocity, 12 acceleration) gives the
    quantity; the values are taken as SI unless ``units`` says otherwise
    (dataset 164 is not read)."""
    pyuff = _pyuff()
    p = Path(os.fspath(path))
    where = str(p)
    if not p.is_file():
        raise InputError(f"{where}: no such file")
    try:
        uf = pyuff.UFF(str(p))
        types = [int(t) for t in uf.get_set_types()]
    except Exception as exc:  # pyuff raises bare Exceptions on malformed files
        raise InputError(f"{where}: not a readable UFF file ({exc})") from None
    idx = [k for k, t in enumerate(types) if t == 58]
    if not idx:
        found = ", ".join(str(t) for t in dict.fromkeys(types)) or "none"
        raise InputError(
            f"{where}: no dataset 58 (FRF) in the file (datasets found: {found}); export the FRFs as UFF 58"
        )
    sets = []
    for k in idx:
        try:
            sets.append((k, uf.read_sets(k)))
        except Exception as exc:
            raise InputError(f"{where}, dataset {k + 1} (58): cannot be read ({exc})") from None
    frfs = [(k, s) for k, s in sets if int(s.get("func_type", 0)) == 4]
    cohs = [(k, s) for k, s in sets if int(s.get("func_type", 0)) == 6]
    if not frfs:
        kinds = sorted({int(s.get("func_type", 0)) for _, s in sets})
        raise InputError(f"{where}: the datasets 58 hold no FRF (function type 4; found types {kinds})")
    ent = _entity_names(frfs)
    x0: np.ndarray | None = None
    power0: int | None = None
    entries: dict[tuple[str, str], np.ndarray] = {}
    coh_entries: dict[tuple[str, str], np.ndarray] = {}
    for group, target in ((frfs, entries), (cohs, coh_entries)):
        for k, s in group:
            ds = f"{where}, dataset {k + 1} (58)"
            x = np.asarray(s["x"], dtype=float)
            y = np.asarray(s["data"])
            if target is entries and not np.iscomplexobj(y):
                raise InputError(
                    f"{ds}: ordinate data type {s.get('ord_data_type')} is real; an FRF is complex (5 or 6)"
                )
            if x0 is None:
                x0 = x
                _check_increasing(x, list(range(1, x.size + 1)), f"{ds}, abscissa point")
            elif x.shape != x0.shape or not np.allclose(x, x0, rtol=1e-9, atol=0):
                raise InputError(
                    f"{ds}: its frequencies differ from the first FRF's; resample all FRFs on one grid"
                )
            o, sgn_o = _uff_coord(s, "rsp", ent, ds)
            i, sgn_i = _uff_coord(s, "ref", ent, ds)
            if target is entries:
                pw = _UFF_ORDINATE.get(int(s.get("ordinate_spec_data_type", 0)))
                if pw is None and quantity is None:
                    raise InputError(
                        f"{ds}: ordinate type {s.get('ordinate_spec_data_type')} is not displacement (8), velocity (11)"
                        " or acceleration (12); give the quantity (quantity=..., --frf-quantity)"
                    )
                if power0 is not None and pw != power0:
                    raise InputError(
                        f"{ds}: a different quantity than the first FRF's; give all FRFs as one quantity"
                    )
                power0 = pw
                val = y.astype(complex) * sgn_o * sgn_i
            else:
                val = np.abs(np.asarray(y, dtype=complex))
            if (o, i) in target:
                raise InputError(f"{ds}: the pair {o}/{i} appears twice; keep one dataset per pair")
            if not np.all(np.isfinite(val)):
                j = int(np.nonzero(~np.isfinite(val))[0][0])
                raise InputError(f"{ds}, point {j + 1} ({x[j]:g} Hz): not a finite value; repair or drop it")
            target[(o, i)] = val
    assert x0 is not None
    outs = tuple(dict.fromkeys(o for o, _ in entries))
    ins = tuple(dict.fromkeys(i for _, i in entries))
    missing = [f"{o}/{i}" for o in outs for i in ins if (o, i) not in entries]
    if missing:
        raise InputError(
            f"{where}: the FRFs form a {len(outs)}x{len(ins)} matrix but {', '.join(missing)} is not in the file;"
            " add its dataset 58"
        )
    A = np.empty((x0.size, len(outs), len(ins)), dtype=complex)
    for (o, i), v in entries.items():
        A[:, outs.index(o), ins.index(i)] = v
    coh = None
    if coh_entries:
        coh = np.ones(A.shape)
        for (o, i), v in coh_entries.items():
            if o in outs and i in ins:
                coh[:, outs.index(o), ins.index(i)] = v
    qname = None if power0 is None else _QNAME[power0]
    scale, power, used = _resolve_units(units, quantity, None, qname, where, "m/N" if qname is None else None)
    H = _to_receptance(x0, A, scale, power, where, None)
    meta = {"units": used, "quantity": _QNAME[power], "format": "uff58", "datasets": len(frfs)}
    return FRFTable(x0, H, outs, ins, coh, where, meta)


def _entity_names(frfs: list[tuple[int, dict[str, Any]]]) -> dict[int, str] | None:
    """Node -> entity name when every node carries exactly one real name."""
    names: dict[int, set[str]] = {}
    for _, s in frfs:
        for side in ("rsp", "ref"):
            nm = str(s.get(f"{side}_ent_name", "")).strip()
            names.setdefault(int(s[f"{side}_node"]), set()).add(nm)
    out = {}
    for node, ns in names.items():
        if len(ns) != 1:
            return None
        nm = next(iter(ns))
        if not nm or nm.upper() == "NONE":
            return None
        out[node] = nm
    if len(set(out.values())) != len(out):
        return None
    return out


def _uff_coord(s: dict[str, Any], side: str, ent: dict[int, str] | None, ds: str) -> tuple[str, float]:
    node = int(s[f"{side}_node"])
    d = int(s[f"{side}_dir"])
    if abs(d) not in _UFF_DIRS:
        what = "response" if side == "rsp" else "reference"
        raise InputError(f"{ds}: {what} direction {d} is not one of +-1..6 (x, y, z, rx, ry, rz)")
    name = ent[node] if ent else str(node)
    return f"{name}.{_UFF_DIRS[abs(d)]}", (1.0 if d > 0 else -1.0)


# ============================================================================ dispatch


def read_frf(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    quantity: str | None = None,
    point: str | None = None,
    format: str | None = None,
) -> FRFTable:
    """Read any measured-FRF file; the format from ``format`` (``"csv"``,
    ``"frf"``, ``"uff"``) or the suffix (:data:`FRF_SUFFIXES`)."""
    p = Path(os.fspath(path))
    fmt = format or FRF_SUFFIXES.get(p.suffix.lower())
    if fmt is None:
        raise InputError(
            f"{p}: unknown FRF file type {p.suffix!r}; use .csv/.txt (columns), .frf (CutPro-style) or .uff/.unv"
            " (dataset 58), or give the format"
        )
    reader = {"csv": read_frf_csv, "frf": read_frf_cutpro, "uff": read_frf_uff}.get(fmt)
    if reader is None:
        raise InputError(f"format must be 'csv', 'frf' or 'uff' (got {fmt!r})")
    return reader(p, units=units, quantity=quantity, point=point)


# ============================================================================ writers


def write_frf_csv(
    path: str | os.PathLike[str], table: FRFTable, *, units: str = "m/N", form: str = "reim"
) -> None:
    """Write a CSV file that :func:`read_frf_csv` reads back: ``# units``,
    ``# quantity: receptance`` and ``# source`` lines, a header row
    (``frequency [Hz]``, then per pair ``OUT/IN re``, ``OUT/IN im`` or
    ``mag``, ``phase`` [deg], and ``coh`` when known), values with 17
    significant digits (re/im: exact round trip).  Atomic."""
    from ._files import text_out

    scale, power = parse_frf_units(units, "units")
    if power != 0:
        raise InputError(f"units {units!r}: the CSV writer writes receptance (m/N, mm/N, um/N)")
    if form not in ("reim", "magphase"):
        raise InputError(f"form must be 'reim' or 'magphase' (got {form!r})")
    head = ["frequency [Hz]"]
    cols: list[np.ndarray] = [np.asarray(table.frequency_hz, dtype=float)]
    for o, on in enumerate(table.outputs):
        for i, inn in enumerate(table.inputs):
            z = table.H[:, o, i] / scale
            if form == "reim":
                head += [f"{on}/{inn} re", f"{on}/{inn} im"]
                cols += [z.real, z.imag]
            else:
                head += [f"{on}/{inn} mag", f"{on}/{inn} phase [deg]"]
                cols += [np.abs(z), np.degrees(np.angle(z))]
            if table.coherence is not None:
                head.append(f"{on}/{inn} coh")
                cols.append(table.coherence[:, o, i])
    for name in head[1:]:
        if "," in name:
            raise InputError(f"coordinate name in {name!r} holds a comma; rename it")
    data = np.column_stack(cols)
    with text_out(path) as fh:
        fh.write("# chatterlab measured FRF\n")
        fh.write(f"# units: {units}\n# quantity: receptance\n")
        if table.source:
            fh.write(f"# source: {table.source}\n")
        fh.write(",".join(head) + "\n")
        for row in data:
            fh.write(",".join(f"{v:.17g}" for v in row) + "\n")


def write_frf_uff(path: str | os.PathLike[str], table: FRFTable, *, binary: bool = False) -> None:
    """Write one UFF dataset 58 (58b with ``binary``) per (output, input)
    pair: function type 4 (FRF), displacement over force (ordinate types 8 /
    13), SI, frequencies as explicit abscissa values (uneven spacing, so an
    uneven grid is kept), complex double ordinates.  A coordinate named
    ``NODE.DIR`` with an integer node keeps its node; other point names get
    nodes 1, 2, ... in order and are written as the entity name (at most 10
    characters), which :func:`read_frf_uff` reads back.  Coherences as
    function type 6.  Written to a temporary name and moved into place.

    Precision: 58b (binary) is exact; ASCII 58 writes ordinates with 12
    significant digits (E20.11) and the abscissa with 6 (E13.5), so two
    frequencies closer than ~1e-5 relative collapse in ASCII."""
    from ._files import _tmp_name

    pyuff = _pyuff()
    coords = list(dict.fromkeys(table.outputs + table.inputs))
    points = list(dict.fromkeys(c.rpartition(".")[0] for c in coords))
    node_of: dict[str, int] = {}
    numeric = all(pt.isdigit() for pt in points)
    for k, pt in enumerate(points, 1):
        if not pt:
            raise InputError("UFF coordinates must be named POINT.DIR (e.g. tool.x or 12.x); rename them")
        node_of[pt] = int(pt) if numeric else k
        if not numeric and len(pt) > 10:
            raise InputError(f"UFF entity names hold at most 10 characters: rename point {pt!r}")

    def split(c: str) -> tuple[int, int, str]:
        pt, _, d = c.rpartition(".")
        if d not in _UFF_DIR_CODES:
            raise InputError(
                f"UFF coordinate {c!r}: the direction must be one of {', '.join(_UFF_DIR_CODES)}"
            )
        return node_of[pt], _UFF_DIR_CODES[d], ("NONE" if numeric else pt)

    x = np.asarray(table.frequency_hz, dtype=float)
    sets = []
    for func, arr in ((4, table.H), (6, table.coherence)):
        if arr is None:
            continue
        for o, on in enumerate(table.outputs):
            for i, inn in enumerate(table.inputs):
                rn, rd, re_ = split(on)
                fn, fd, fe = split(inn)
                sets.append(
                    pyuff.prepare_58(
                        binary=int(binary),
                        id1=("FRF" if func == 4 else "Coherence") + f" {on}/{inn}"[:70],
                        id2="chatterlab measured FRF",
                        func_type=func,
                        rsp_ent_name=re_,
                        rsp_node=rn,
                        rsp_dir=rd,
                        ref_ent_name=fe,
                        ref_node=fn,
                        ref_dir=fd,
                        ord_data_type=6,
                        abscissa_spacing=0,
                        abscissa_spec_data_type=18,
                        ordinate_spec_data_type=8 if func == 4 else 0,
                        orddenom_spec_data_type=13 if func == 4 else 0,
                        data=np.asarray(arr[:, o, i], dtype=complex),
                        x=x,
                    )
                )
    final = Path(os.fspath(path))
    tmp = _tmp_name(final)
    try:
        tmp.touch()
        # mode "add": pyuff's binary writer reopens the file by name and would truncate it in "overwrite"
        pyuff.UFF(str(tmp)).write_sets(sets, mode="add")
        os.replace(tmp, final)
    except BaseException:
        import contextlib

        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise
