"""The FRF as io hands it on and takes it (:class:`FRFRecord`, plain
arrays: no analysis type), the scale of a file's units to SI, and the line
and number helpers the text readers share (the units are described in the
docstring of :mod:`chatterlab.io._frf_files`)."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["FRFRecord", "G0", "QUANTITIES", "SI_UNITS", "parse_frf_units"]

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
#: the three quantities, by the power p of j w that turns a receptance into them
QUANTITIES = ("receptance", "mobility", "accelerance")
_QNAME = QUANTITIES
#: the SI unit of each quantity as the writers write it (and parse_frf_units reads it)
SI_UNITS = ("m/N", "m/s/N", "m/s^2/N")


@dataclass(frozen=True, eq=False)
class FRFRecord:
    """An FRF as a file holds it, in plain arrays (what the readers return
    and the writers take; :class:`chatterlab.structure.FRF` is the object
    built from it).

    ``frequency_hz`` (n,), Hz, strictly increasing; ``data`` (n_out, n_in,
    n) complex, the file's ``quantity`` (receptance, mobility or
    accelerance) in SI (m/N, m/s/N, m/s^2/N); ``coherence`` like ``data``
    (real) or None; ``meta``: what the file says besides (its ``units`` and
    ``quantity`` as found, ``format``, other header keys); ``omega`` the
    exact angular frequencies (rad/s) when the file holds them (netCDF),
    else None (2 pi ``frequency_hz``).  A private type: io's half of the
    exchange, not a second FRF container (not exported)."""

    frequency_hz: np.ndarray
    data: np.ndarray
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]
    quantity: str = "receptance"
    coherence: np.ndarray | None = None
    source: str = ""
    meta: dict[str, Any] = field(default_factory=dict)
    omega: np.ndarray | None = None


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


def to_si(
    f_hz: np.ndarray, A: np.ndarray, scale: float, power: int, where: str, lines: list[int] | None
) -> np.ndarray:
    """The file's values ``A`` (n_out, n_in, n) in SI of their quantity,
    ``scale * A``.  A mobility or accelerance at 0 Hz is refused (with its
    line): it has no receptance (H = A / (j w)^p, Ewins, *Modal Testing*, sec. 2.7), and a
    file is read to be used as one."""
    zero = np.nonzero(f_hz == 0)[0]
    if power and zero.size:
        at = f", line {lines[zero[0]]}" if lines else ""
        raise InputError(
            f"{where}{at}: a {_QNAME[power]} at 0 Hz cannot be converted to receptance; drop that line"
        )
    return A * scale


# ============================================================================ the file itself
# One reader contract (docs/measured-frf.md, "Bad input"): a reader reads the
# whole file as documented or refuses it with the file, the line and the
# reason.  Before a byte is parsed the path must be a regular file (a FIFO,
# a device such as /dev/zero or a directory would block, never end or make
# no sense) of at most MAX_FRF_FILE_BYTES; the file is an input of the
# running command (never one of its outputs: chatterlab.io._files).

#: the largest FRF file read, bytes: a tap test of 10^4 frequencies on a 2 x 2
#: matrix with coherences is 2-5 MiB in any of the formats
MAX_FRF_FILE_BYTES = 16 * 2**20

#: the most frequencies an FRF file may hold: the lobe engine works on every
#: measured frequency (10^5 frequencies: ~20 s and ~1 GB per diagram)
MAX_FRF_POINTS = 100_000

#: line ends read as such: LF, CRLF and CR (old Mac exports) -- nothing else
#: (form feeds, vertical tabs, U+2028 are not line ends here, but refused)
_EOL = re.compile(r"\r\n|\r|\n")
#: control characters no FRF text file holds (tab is a delimiter)
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f\x85\u2028\u2029]")


def check_regular(mode: int, where: str) -> None:
    """:class:`InputError` unless ``mode`` (``os.stat``) is a regular file's."""
    import stat

    if stat.S_ISDIR(mode):
        raise InputError(f"{where}: is a directory, not an FRF file")
    if not stat.S_ISREG(mode):
        kind = "a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a device or socket"
        raise InputError(f"{where}: is {kind}, not a regular file; give the FRF file itself")


def read_input(path: Path) -> bytes:
    """The bytes of the FRF file ``path``: a regular file of at most
    :data:`MAX_FRF_FILE_BYTES`, else :class:`InputError` naming it and the
    limit.  The file is opened without blocking (a FIFO), checked on the
    open descriptor, and noted as an input of the running command."""
    import os

    from ._files import note_input

    where = str(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise InputError(f"{where}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{where}: is a directory, not an FRF file") from None
    except (OSError, ValueError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise InputError(f"{where}: cannot be read ({reason})") from None
    try:
        st = os.fstat(fd)
        check_regular(st.st_mode, where)
        if st.st_size > MAX_FRF_FILE_BYTES:
            raise InputError(
                f"{where}: {st.st_size / 2**20:.1f} MiB; an FRF file may hold at most"
                f" {MAX_FRF_FILE_BYTES // 2**20} MiB (and {MAX_FRF_POINTS} frequencies): resample or split it"
            )
        note_input(path)
        with open(fd, "rb", closefd=False) as fh:
            data = fh.read(MAX_FRF_FILE_BYTES + 1)
    except OSError as exc:
        raise InputError(f"{where}: cannot be read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    if len(data) > MAX_FRF_FILE_BYTES:  # it grew while being read
        raise InputError(
            f"{where}: more than {MAX_FRF_FILE_BYTES // 2**20} MiB; an FRF file may hold at most that"
        )
    return data


def _line_of(data: bytes, offset: int) -> int:
    """The line (1-based) of byte ``offset``, line ends LF, CRLF or CR."""
    head = data[:offset]
    return head.count(b"\n") + head.count(b"\r") - head.count(b"\r\n") + 1


def decode_text(data: bytes, where: str) -> str:
    """The text of an FRF text file: UTF-8 (with or without a byte-order
    mark) or UTF-16 with its byte-order mark; anything else is refused with
    the line of the first byte that is not text."""
    import codecs

    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)) and not data.startswith(codecs.BOM_UTF8):
        try:
            return data.decode("utf-16")
        except UnicodeDecodeError:
            raise InputError(
                f"{where}: starts with a UTF-16 byte-order mark but is not UTF-16 text (an odd number of bytes"
                " or a broken character); save it again as UTF-8"
            ) from None
    if b"\x00" in data:
        at = _line_of(data, data.index(b"\x00"))
        raise InputError(
            f"{where}, line {at}: a NUL byte: a binary file, or UTF-16 text without its byte-order mark; save it"
            " as UTF-8 text (a binary UFF file needs the suffix .uff or .unv)"
        )
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        bom = 3 if data.startswith(codecs.BOM_UTF8) else 0
        at = _line_of(data, exc.start + bom)
        raise InputError(
            f"{where}, line {at}: byte 0x{data[exc.start + bom]:02x} is not UTF-8 text (Latin-1 or Windows"
            " text?); save the file as UTF-8 (or UTF-16 with a byte-order mark)"
        ) from None


def text_lines(text: str, where: str) -> list[tuple[int, str]]:
    """(line number, line) of ``text``, line ends LF, CRLF or CR; a control
    character other than a tab is refused with its line."""
    out = []
    for n, line in enumerate(_EOL.split(text), 1):
        m = _CONTROL.search(line)
        if m:
            raise InputError(
                f"{where}, line {n}: control character U+{ord(m[0]):04X}; an FRF text file holds only text,"
                " tabs and line ends (LF, CRLF or CR)"
            )
        out.append((n, line))
    if out and not out[-1][1]:
        out.pop()
    return out


def _lines(path: Path) -> list[tuple[int, str]]:
    """The lines of the FRF text file ``path`` (:func:`read_input`,
    :func:`decode_text`, :func:`text_lines`)."""
    return text_lines(decode_text(read_input(path), str(path)), str(path))


def check_points(count: int, where: str, line: int | None = None) -> None:
    """At most :data:`MAX_FRF_POINTS` frequencies."""
    if count > MAX_FRF_POINTS:
        at = f", line {line}" if line is not None else ""
        raise InputError(
            f"{where}{at}: more than {MAX_FRF_POINTS} frequencies; an FRF file may hold at most"
            f" {MAX_FRF_POINTS}: resample it (a few points per half-power width are enough, docs/measured-frf.md)"
        )


# ============================================================================ text reading helpers


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
        hint = (
            "; a decimal comma? write numbers with a decimal point"
            if re.fullmatch(r"[+-]?\d*,\d+.*", tok)
            else ""
        )
        raise InputError(f"{where}, line {line}, column {column!r}: {tok!r} is not a number{hint}") from None
    if not math.isfinite(x):
        raise InputError(
            f"{where}, line {line}, column {column!r}: {tok} is not a finite number; drop or repair the line"
        )
    return x


def _check_increasing(f: np.ndarray, lines: list[int], where: str) -> None:
    if f.size < 2:
        raise InputError(f"{where}: at least 2 frequencies are needed (got {f.size})")
    bad_f = np.nonzero(~np.isfinite(f))[0]
    if bad_f.size:
        k = int(bad_f[0])
        raise InputError(
            f"{where}, line {lines[k]}: frequency {f[k]} is not a finite number; drop or repair it"
        )
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
