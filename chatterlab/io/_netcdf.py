"""Labelled result files: netCDF classic (via :mod:`scipy.io`) and long-format CSV.

Every array result chatterlab writes (a parameter sweep, a lobe diagram, a
time history) is a set of *data variables* laid on a set of named
*coordinates*, each with a unit.  This module writes and reads them in two
formats:

* **netCDF classic** (``CDF-2``, 64-bit offsets) through
  :class:`scipy.io.netcdf_file`: each coordinate is a 1-D coordinate variable
  whose dimension has the same name; each data variable carries ``units`` and
  ``long_name`` attributes; global attributes record provenance (chatterlab
  version, creation time, command line) and whatever the caller adds (the
  model text, the status of the run...).  Strings are stored only as
  attributes (UTF-8 bytes).  The files open with xarray
  (``xarray.open_dataset(path)``), ncdump, Panoply, MATLAB's ``ncread``...
* **CSV**, long format: one row per grid point, coordinates first, header
  ``name [unit]``.

Writes are atomic: the file is written under a temporary name in the target
directory, flushed to disk and then renamed over the target with
:func:`os.replace`, so a reader never sees a half-written file and a crash
never leaves one behind.
"""

from __future__ import annotations

import csv
import datetime as _dt
import os
import re
import secrets
import shlex
import sys
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from chatterlab.errors import InputError

__all__ = [
    "LabelledData",
    "atomic_write",
    "check_attrs",
    "provenance_attrs",
    "read_netcdf",
    "write_csv",
    "write_netcdf",
]

_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_.@+\-]*$")
_INT32 = np.iinfo(np.int32)


@dataclass(frozen=True)
class LabelledData:
    """Contents of a labelled result file, as returned by :func:`read_netcdf`.

    Attributes
    ----------
    coords : dict
        ``name -> (values, unit)``: the coordinate variables, in file order.
    data : dict
        ``name -> (array, unit, long_name)``: the data variables.
    attrs : dict
        Global attributes (strings decoded from UTF-8, numeric scalars as
        Python ``int``/``float``, numeric lists as arrays).
    dims : dict
        ``name -> tuple of dimension names`` for every data variable.

    The fields are shaped so that ``write_netcdf(path, d.coords, d.data,
    d.attrs)`` writes the same file again.
    """

    coords: dict[str, tuple[np.ndarray, str]]
    data: dict[str, tuple[np.ndarray, str, str]]
    attrs: dict[str, Any] = field(default_factory=dict)
    dims: dict[str, tuple[str, ...]] = field(default_factory=dict)


# --------------------------------------------------------------------------- atomic writes


@contextmanager
def atomic_write(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success move it onto ``path``.

    The caller writes the temporary file (and closes it) inside the ``with``
    block.  On normal exit the file is fsync'ed and renamed onto ``path`` with
    :func:`os.replace` (atomic on POSIX and Windows); on any exception,
    including :class:`KeyboardInterrupt`, the temporary file is removed and
    ``path`` is left untouched.

    Parameters
    ----------
    path : path-like
        Final location of the file.

    Yields
    ------
    pathlib.Path
        The temporary path to write, in the same directory as ``path``.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}")
    try:
        yield tmp
        _fsync(tmp)
        os.replace(tmp, path)
    except BaseException:
        try:
            tmp.unlink()
        except FileNotFoundError:
            pass
        raise


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


# --------------------------------------------------------------------------- provenance


def provenance_attrs() -> dict[str, str]:
    """Global attributes that record where a file came from.

    Returns
    -------
    dict
        ``chatterlab_version``, ``created`` (UTC, ISO 8601, seconds) and
        ``command_line`` (``sys.argv`` joined with shell quoting).
    """
    return {
        "chatterlab_version": _chatterlab_version(),
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "command_line": shlex.join(sys.argv) if sys.argv and sys.argv[0] else "",
    }


def _chatterlab_version() -> str:
    try:
        from importlib.metadata import PackageNotFoundError, version

        try:
            return version("chatterlab")
        except PackageNotFoundError:
            pass
    except ImportError:  # pragma: no cover
        pass
    from .._version import __version__

    return __version__


# --------------------------------------------------------------------------- normalisation


def _check_name(name: object, what: str) -> str:
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise InputError(
            f"{what} name {name!r} is not a valid netCDF name: use letters, digits and "
            "underscores, starting with a letter or underscore"
        )
    return name


def _normalise_coords(
    coords: Mapping[str, tuple[ArrayLike, str] | tuple[ArrayLike, str, str] | ArrayLike],
) -> dict[str, tuple[np.ndarray, str, str]]:
    out: dict[str, tuple[np.ndarray, str, str]] = {}
    for name, spec in coords.items():
        _check_name(name, "coordinate")
        values, unit, long_name = _unpack(spec, name, "coordinate")[:3]
        arr = np.asarray(values)
        if arr.ndim != 1:
            raise InputError(f"coordinate {name!r} must be 1-D (got an array of shape {arr.shape})")
        out[name] = (_storable(arr, name), unit, long_name)
    return out


def _unpack(spec: Any, name: str, what: str) -> tuple[Any, str, str, tuple[str, ...] | None]:
    """Split ``array | (array, unit) | (array, unit, long_name[, dims])``."""
    if isinstance(spec, tuple):
        if not 1 <= len(spec) <= 4:
            raise InputError(
                f"{what} {name!r}: expected (values, unit[, long_name[, dims]]), "
                f"got a tuple of {len(spec)} items"
            )
        values = spec[0]
        unit = spec[1] if len(spec) > 1 else ""
        long_name = spec[2] if len(spec) > 2 else ""
        dims = tuple(spec[3]) if len(spec) > 3 and spec[3] is not None else None
    else:
        values, unit, long_name, dims = spec, "", "", None
    if not isinstance(unit, str) or not isinstance(long_name, str):
        raise InputError(f"{what} {name!r}: unit and long_name must be strings")
    return values, unit, long_name or name, dims


def _storable(arr: np.ndarray, name: str) -> np.ndarray:
    """Convert to a dtype netCDF classic can hold (float64, float32, int32, int8)."""
    kind = arr.dtype.kind
    if kind == "b":
        return arr.astype(np.int8)
    if kind in "iu":
        if arr.size and (arr.min() < _INT32.min or arr.max() > _INT32.max):
            raise InputError(
                f"variable {name!r}: integers beyond the 32-bit range cannot be stored in "
                "netCDF classic; convert them to float"
            )
        return arr.astype(np.int32) if arr.dtype.itemsize != 1 else arr.astype(np.int8)
    if kind == "f":
        return arr if arr.dtype in (np.float32, np.float64) else arr.astype(np.float64)
    if kind == "c":
        raise InputError(
            f"variable {name!r} is complex: netCDF classic has no complex type; "
            "store the real and imaginary parts (or magnitude and phase) as two variables"
        )
    raise InputError(f"variable {name!r}: cannot store an array of dtype {arr.dtype} in netCDF")


def _normalise_data(
    coords: dict[str, tuple[np.ndarray, str, str]],
    data: Mapping[str, Any],
) -> tuple[dict[str, tuple[np.ndarray, str, str, tuple[str, ...]]], dict[str, int]]:
    """Return data ``name -> (array, unit, long_name, dims)`` and all dimension sizes."""
    dim_sizes = {name: len(values) for name, (values, _, _) in coords.items()}
    all_dims = tuple(coords)
    out: dict[str, tuple[np.ndarray, str, str, tuple[str, ...]]] = {}
    for name, spec in data.items():
        _check_name(name, "data variable")
        if name in coords:
            raise InputError(f"data variable {name!r} has the same name as a coordinate")
        values, unit, long_name, dims = _unpack(spec, name, "data variable")
        arr = values if isinstance(values, np.ndarray) else np.asarray(values)
        if dims is None:
            dims = all_dims
            if arr.shape != tuple(dim_sizes[d] for d in dims):
                raise InputError(
                    f"data variable {name!r} has shape {arr.shape} but the coordinates "
                    f"{list(dims)} give {tuple(dim_sizes[d] for d in dims)}; pass "
                    "(array, unit, long_name, dims) to lay it on other dimensions"
                )
        else:
            if len(dims) != arr.ndim:
                raise InputError(
                    f"data variable {name!r}: {len(dims)} dimension names {list(dims)} for "
                    f"an array of {arr.ndim} dimensions"
                )
            for d, n in zip(dims, arr.shape, strict=True):
                _check_name(d, "dimension")
                if dim_sizes.setdefault(d, n) != n:
                    raise InputError(
                        f"data variable {name!r}: dimension {d!r} has length {n} here but "
                        f"{dim_sizes[d]} elsewhere"
                    )
        out[name] = (_storable(arr, name), unit, long_name, tuple(dims))
    return out, dim_sizes


# Instance attributes of scipy's netcdf_file: a global attribute of the same name
# would overwrite them when the file is read back (scipy sets them with setattr).
_RESERVED_ATTRS = frozenset(
    {"dimensions", "filename", "fp", "maskandscale", "mode", "use_mmap", "variables", "version_byte"}
)


def _attr_value(name: str, value: Any) -> Any:
    """Convert one attribute to something scipy writes losslessly."""
    _check_name(name, "attribute")
    if name in _RESERVED_ATTRS or name.startswith("_"):
        raise InputError(
            f"attribute name {name!r} is reserved (scipy's netCDF reader uses it); rename it, "
            f"e.g. 'chatterlab_{name.lstrip('_')}'"
        )
    if isinstance(value, str):
        return value.encode("utf-8")
    if isinstance(value, bytes):
        return value
    if isinstance(value, bool | np.bool_):
        return np.int32(int(value))
    if isinstance(value, int | np.integer):
        if _INT32.min <= int(value) <= _INT32.max:
            return np.int32(value)
        if abs(int(value)) <= 2**53:
            return np.float64(value)
        raise InputError(f"attribute {name!r}: integer {value} is too large for netCDF classic")
    if isinstance(value, float | np.floating):
        return np.float64(value)  # scipy would write a bare Python float as float32
    if isinstance(value, Sequence | np.ndarray) and not isinstance(value, str | bytes):
        arr = np.asarray(value)
        if arr.ndim == 1 and arr.size and arr.dtype.kind in "biuf":
            if arr.dtype.kind == "f":
                return arr.astype(np.float64)
            return _storable(arr, name)
    raise InputError(
        f"attribute {name!r}: cannot store {type(value).__name__} {value!r:.60} as a netCDF "
        "attribute (use a string, a number or a 1-D list of numbers; e.g. json.dumps a dict)"
    )


def check_attrs(attrs: Mapping[str, Any]) -> None:
    """Raise :class:`~chatterlab.errors.InputError` if an attribute cannot be stored.

    Use it before a long computation whose result will be written with
    :func:`write_netcdf`, so that a bad attribute fails early.
    """
    for k, v in attrs.items():
        _attr_value(k, v)


def _decode_attr(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray):
        return value.astype(value.dtype.newbyteorder("="))
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    return value


# --------------------------------------------------------------------------- netCDF


def write_netcdf(
    path: str | os.PathLike[str],
    coords: Mapping[str, Any],
    data: Mapping[str, Any],
    attrs: Mapping[str, Any] | None = None,
    *,
    provenance: bool = True,
) -> Path:
    """Write labelled arrays to a netCDF classic file (atomically).

    Parameters
    ----------
    path : path-like
        Output file (conventionally ``.nc``).  Written to a temporary file in
        the same directory and renamed on success.
    coords : mapping
        ``name -> (values, unit)`` or ``(values, unit, long_name)``: the
        coordinate axes, 1-D, in dimension order.  Each becomes a dimension
        and a coordinate variable of the same name with a ``units``
        attribute.
    data : mapping
        ``name -> (array, unit, long_name)`` (``unit`` and ``long_name`` may
        be omitted).  By default an array spans all coordinates in order,
        ``shape == tuple(len(v) for v in coords)`` (any N >= 1).  A fourth
        item ``dims`` (tuple of dimension names) lays it on a subset, or on
        extra dimensions without a coordinate variable.  float64, float32,
        integer (stored as int32) and boolean (int8) arrays are accepted;
        ``np.memmap`` inputs are copied one variable at a time.
    attrs : mapping, optional
        Global attributes: strings (stored as UTF-8), numbers (float64 /
        int32) or 1-D lists of numbers.
    provenance : bool, default True
        Add ``chatterlab_version``, ``created`` and ``command_line`` (see
        :func:`provenance_attrs`) unless ``attrs`` already sets them.  Pass a
        fixed ``created`` to get byte-identical files for identical data.

    Returns
    -------
    pathlib.Path
        The written path.

    Raises
    ------
    chatterlab.errors.InputError
        On an invalid name, mismatched shapes, a complex array or an
        attribute of an unsupported type.
    """
    from scipy.io import netcdf_file

    path = Path(path)
    cnorm = _normalise_coords(coords)
    dnorm, dim_sizes = _normalise_data(cnorm, data)
    all_attrs: dict[str, Any] = dict(provenance_attrs()) if provenance else {}
    all_attrs.update(attrs or {})
    encoded = {k: _attr_value(k, v) for k, v in all_attrs.items()}

    with atomic_write(path) as tmp:
        f = netcdf_file(tmp, "w", version=2, mmap=False)
        try:
            for k, v in encoded.items():
                setattr(f, k, v)
            for d, n in dim_sizes.items():
                f.createDimension(d, n)
            for name, (values, unit, long_name) in cnorm.items():
                var = f.createVariable(name, values.dtype, (name,))
                var[:] = values
                var.units = unit.encode("utf-8")
                var.long_name = long_name.encode("utf-8")
            for name, (arr, unit, long_name, dims) in dnorm.items():
                var = f.createVariable(name, arr.dtype, dims)
                _copy_into(var.data, arr)
                var.units = unit.encode("utf-8")
                var.long_name = long_name.encode("utf-8")
        finally:
            f.close()
    return path


def _copy_into(dest: np.ndarray, src: np.ndarray, block: int = 1 << 20) -> None:
    """Copy ``src`` into ``dest`` in blocks so a memmap source is never read whole."""
    if dest.ndim == 0 or src.size <= block:
        dest[...] = src
        return
    d = dest.reshape(-1)
    s = src.reshape(-1)
    for i in range(0, s.size, block):
        d[i : i + block] = s[i : i + block]


def read_netcdf(path: str | os.PathLike[str], *, mmap: bool = False) -> LabelledData:
    """Read a netCDF classic file written by :func:`write_netcdf` (or any other).

    Parameters
    ----------
    path : path-like
        The file.
    mmap : bool, default False
        If True, data variables are returned as read-only :class:`numpy.memmap`
        arrays on the file (big-endian dtype, as stored) instead of being read
        into memory; useful for very large sweeps.  Coordinates are always
        copied.

    Returns
    -------
    LabelledData
        ``coords``, ``data``, ``attrs`` and ``dims``.  A 1-D variable whose
        name equals its dimension is a coordinate; every other variable is a
        data variable.
    """
    from scipy.io import netcdf_file

    path = Path(path)
    if not path.exists():
        raise InputError(f"netCDF file {str(path)!r} does not exist")
    try:
        f = netcdf_file(path, "r", mmap=True)
    except (TypeError, ValueError, OSError) as exc:
        raise InputError(f"{str(path)!r} is not a readable netCDF classic file: {exc}") from exc
    try:
        attrs, coords, data, dims, offsets = _read_contents(f, mmap)
    finally:
        f.close()  # no array on the mmap survives _read_contents
    for name, (off, dtype, shape) in offsets.items():
        _, unit, long_name = data[name]
        arr = np.memmap(path, dtype=dtype, mode="r", offset=off, shape=shape)
        data[name] = (arr, unit, long_name)
    return LabelledData(coords=coords, data=data, attrs=attrs, dims=dims)


def _read_contents(f: Any, mmap: bool) -> tuple[dict, dict, dict, dict, dict]:
    # scipy exposes attributes only as ``_attributes`` (xarray reads them the same way).
    attrs = {k: _decode_attr(v) for k, v in f._attributes.items()}
    coords: dict[str, tuple[np.ndarray, str]] = {}
    data: dict[str, tuple[np.ndarray, str, str]] = {}
    dims: dict[str, tuple[str, ...]] = {}
    offsets: dict[str, tuple[int, np.dtype, tuple[int, ...]]] = {}
    for name, var in f.variables.items():
        vattrs = {k: _decode_attr(v) for k, v in var._attributes.items()}
        unit = str(vattrs.get("units", ""))
        long_name = str(vattrs.get("long_name", name))
        arr = var.data
        native = arr.dtype.newbyteorder("=")
        if tuple(var.dimensions) == (name,):
            coords[name] = (np.array(arr, dtype=native), unit)
            continue
        dims[name] = tuple(var.dimensions)
        off = _offset_in_file(arr) if mmap else None
        if off is not None:
            offsets[name] = (off, arr.dtype, arr.shape)
            data[name] = (np.empty(0), unit, long_name)  # replaced by a memmap after close
        else:
            data[name] = (np.array(arr, dtype=native), unit, long_name)
    order = list(f.dimensions)
    coords = {k: coords[k] for k in order if k in coords} | coords
    return attrs, coords, data, dims, offsets


def _offset_in_file(arr: np.ndarray) -> int | None:
    """Byte offset of a scipy mmap-backed variable in its file, or None if unknown."""
    base = arr.base
    if (
        arr.size == 0
        or not isinstance(base, np.ndarray)
        or base.ndim != 1
        or base.dtype != np.int8
        or not arr.flags.c_contiguous
    ):
        return None
    off = arr.__array_interface__["data"][0] - base.__array_interface__["data"][0]
    if off < 0 or off + arr.nbytes > base.nbytes:
        return None
    return int(off)


# --------------------------------------------------------------------------- CSV


def write_csv(
    path: str | os.PathLike[str],
    coords: Mapping[str, Any],
    data: Mapping[str, Any],
    *,
    block: int = 65536,
    coded: Mapping[str, tuple[np.ndarray, Sequence[str]]] | None = None,
) -> Path:
    """Write labelled arrays as a long-format CSV file (atomically).

    One row per grid point in C order (last coordinate fastest); the columns
    are the coordinates then the data variables; the header names each
    column ``name [unit]`` (just ``name`` when the unit is empty).  Floats are
    written with the shortest representation that reads back exactly
    (``repr``), missing values as ``nan``.

    Parameters
    ----------
    path : path-like
        Output file.
    coords, data : mapping
        As for :func:`write_netcdf`; every data variable must span all the
        coordinates (no ``dims`` subset).
    block : int, default 65536
        Rows formatted at a time (bounds memory for very large grids).
    coded : mapping, optional
        Text columns written last: ``name -> (codes, labels)``, an integer
        array shaped like the grid and the text of each code
        (``labels[code]``), e.g. a per-point status and reason.

    Returns
    -------
    pathlib.Path
        The written path.
    """
    path = Path(path)
    cnorm = _normalise_coords(coords)
    if not cnorm:
        raise InputError("write_csv needs at least one coordinate")
    dnorm, _ = _normalise_data(cnorm, data)
    full = tuple(cnorm)
    for name, (_, _, _, dims) in dnorm.items():
        if dims != full:
            raise InputError(
                f"write_csv: data variable {name!r} spans {list(dims)}, not all the "
                f"coordinates {list(full)}; write it with write_netcdf instead"
            )
    shape = tuple(len(v) for v, _, _ in cnorm.values())
    size = int(np.prod(shape))
    header = [f"{n} [{u}]" if u else n for n, (_, u, _) in cnorm.items()]
    header += [f"{n} [{u}]" if u else n for n, (_, u, _, _) in dnorm.items()]
    flat = [a.reshape(-1) for a, _, _, _ in dnorm.values()]
    texts = []
    for name, (codes, labels) in (coded or {}).items():
        _check_name(name, "column")
        c = np.asarray(codes)
        if c.shape != shape:
            raise InputError(f"write_csv: coded column {name!r} has shape {c.shape}, the grid {shape}")
        header.append(name)
        texts.append((c.reshape(-1), list(labels)))
    with atomic_write(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        for start in range(0, size, block):
            idx = np.arange(start, min(start + block, size))
            subs = np.unravel_index(idx, shape)
            cols = [v[s].tolist() for (v, _, _), s in zip(cnorm.values(), subs, strict=True)]
            cols += [_as_python(a[start : start + len(idx)]) for a in flat]
            cols += [[lab[int(k)] for k in c[start : start + len(idx)]] for c, lab in texts]
            w.writerows(zip(*cols, strict=True))
    return path


def _as_python(a: np.ndarray) -> list[Any]:
    if a.dtype.kind == "b":
        return a.astype(np.int8).tolist()
    return np.asarray(a).tolist()
