"""The measured FRF as io hands it on (:class:`FRFTable`), the conversion
of a file's units and quantity to receptance in m/N, and the line and number
helpers the text readers share (the units are described in the docstring of
:mod:`chatterlab.io._frf_files`)."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["FRFTable", "G0", "parse_frf_units"]

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
