"""Measured FRFs in CSV/TXT columns: the reader and the (atomic) writer
(format in docs/measured-frf.md, "CSV and TXT")."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ._frf_table import (
    _QNAME,
    FRFTable,
    _check_increasing,
    _delimiter,
    _is_number,
    _lines,
    _number,
    _resolve_units,
    _split,
    _to_receptance,
    parse_frf_units,
)

__all__ = ["read_frf_csv", "write_frf_csv"]


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
