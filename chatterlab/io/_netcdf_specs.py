"""The checks behind every labelled file: names, shapes, storable dtypes and
attribute values (shared by the netCDF and CSV writers of :mod:`._netcdf`).

A coordinate is given as ``values``, ``(values, unit)`` or ``(values, unit,
long_name)``; a data variable as ``array``, ``(array, unit)``, ``(array,
unit, long_name)`` or ``(array, unit, long_name, dims)``.  Everything that a
netCDF file cannot hold is refused here with an
:class:`~chatterlab.errors.InputError` naming the variable and the fix, before
any file is opened.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from chatterlab.errors import InputError

_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_.@+\-]*$")
_INT32 = np.iinfo(np.int32)
_INT64 = np.iinfo(np.int64)

#: normalised coordinate: (values, unit, long_name)
Coord = tuple[np.ndarray, str, str]
#: normalised data variable: (array, unit, long_name, dims)
Var = tuple[np.ndarray, str, str, tuple[str, ...]]


def check_name(name: object, what: str) -> str:
    """``name`` if it is a valid netCDF name, else an InputError."""
    if not isinstance(name, str) or not _NAME_RE.match(name):
        raise InputError(
            f"{what} name {name!r} is not a valid netCDF name: use letters, digits and "
            "underscores, starting with a letter or underscore"
        )
    return name


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


def storable(arr: np.ndarray, name: str) -> np.ndarray:
    """The array in a dtype every netCDF reader takes, with the same values:
    float64/float32 as they are, other floats as float64, booleans as int8,
    integers as int32 (int8 when 1 byte wide; int64 beyond the 32-bit range).
    Complex, string and object arrays are refused."""
    kind = arr.dtype.kind
    if kind == "b":
        return arr.astype(np.int8)
    if kind in "iu":
        if arr.dtype.itemsize == 1 and kind == "i":
            return arr
        if arr.size and (arr.min() < _INT32.min or arr.max() > _INT32.max):
            if arr.min() < _INT64.min or arr.max() > _INT64.max:
                raise InputError(
                    f"variable {name!r}: integers beyond the 64-bit range; convert them to float"
                )
            return arr.astype(np.int64, copy=False)
        return arr.astype(np.int32, copy=False)  # a memory map of int32 stays one
    if kind == "f":
        return arr if arr.dtype in (np.float32, np.float64) else arr.astype(np.float64)
    if kind == "c":
        raise InputError(
            f"variable {name!r} is complex: netCDF has no standard complex type; "
            "store the real and imaginary parts (or magnitude and phase) as two variables"
        )
    raise InputError(f"variable {name!r}: cannot store an array of dtype {arr.dtype} in netCDF")


def normalise_coords(coords: Mapping[str, Any]) -> dict[str, Coord]:
    """``name -> (values, unit, long_name)``, 1-D and storable."""
    out: dict[str, Coord] = {}
    for name, spec in coords.items():
        check_name(name, "coordinate")
        values, unit, long_name = _unpack(spec, name, "coordinate")[:3]
        arr = np.asarray(values)
        if arr.ndim != 1:
            raise InputError(f"coordinate {name!r} must be 1-D (got an array of shape {arr.shape})")
        out[name] = (storable(arr, name), unit, long_name)
    return out


def normalise_data(coords: dict[str, Coord], data: Mapping[str, Any]) -> dict[str, Var]:
    """``name -> (array, unit, long_name, dims)``: every array spans all the
    coordinates in order unless it names its ``dims``; lengths must agree."""
    dim_sizes = {name: len(values) for name, (values, _, _) in coords.items()}
    all_dims = tuple(coords)
    out: dict[str, Var] = {}
    for name, spec in data.items():
        check_name(name, "data variable")
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
            if name in dims:
                raise InputError(
                    f"data variable {name!r} has the name of one of its dimensions; a variable "
                    "named like a dimension is that dimension's coordinate: rename one of them"
                )
            for d, n in zip(dims, arr.shape, strict=True):
                check_name(d, "dimension")
                if dim_sizes.setdefault(d, n) != n:
                    raise InputError(
                        f"data variable {name!r}: dimension {d!r} has length {n} here but "
                        f"{dim_sizes[d]} elsewhere"
                    )
        out[name] = (storable(arr, name), unit, long_name, tuple(dims))
    return out


def attr_value(name: str, value: Any) -> Any:
    """One attribute as netCDF stores it losslessly: str as UTF-8 text,
    bool and integers as int32 (int64 beyond its range), floats as float64,
    1-D numeric sequences as arrays.  Names starting with ``_`` are reserved
    for the netCDF and HDF5 libraries (``_FillValue``, ``_NCProperties``...)."""
    check_name(name, "attribute")
    if name.startswith("_"):
        raise InputError(
            f"attribute name {name!r} is reserved (netCDF keeps names starting with '_' for "
            f"itself); rename it, e.g. 'chatterlab_{name.lstrip('_')}'"
        )
    if isinstance(value, str):
        return value
    if isinstance(value, bytes | np.bytes_):
        return bytes(value).decode("utf-8", errors="replace")
    if isinstance(value, bool | np.bool_):
        return np.int32(int(value))
    if isinstance(value, int | np.integer):
        if _INT32.min <= int(value) <= _INT32.max:
            return np.int32(value)
        if _INT64.min <= int(value) <= _INT64.max:
            return np.int64(value)
        raise InputError(f"attribute {name!r}: integer {value} is beyond the 64-bit range; store it as text")
    if isinstance(value, float | np.floating):
        return np.float64(value)
    if isinstance(value, Sequence | np.ndarray) and not isinstance(value, str | bytes):
        arr = np.asarray(value)
        if arr.ndim == 1 and arr.size and arr.dtype.kind in "biuf":
            if arr.dtype.kind == "f":
                return arr.astype(np.float64)
            return storable(arr, name)
    raise InputError(
        f"attribute {name!r}: cannot store {type(value).__name__} {value!r:.60} as a netCDF "
        "attribute (use a string, a number or a 1-D list of numbers; e.g. json.dumps a dict)"
    )


def check_attrs(attrs: Mapping[str, Any]) -> None:
    """Raise :class:`~chatterlab.errors.InputError` if an attribute cannot be stored.

    Use it before a long computation whose result will be written with
    :func:`~chatterlab.io.write_netcdf`, so that a bad attribute fails early.
    """
    for k, v in attrs.items():
        attr_value(k, v)


def decode_attr(value: Any) -> Any:
    """An attribute as read back: text as ``str``, numeric scalars as Python
    ``int``/``float``, numeric arrays in native byte order."""
    if isinstance(value, bytes | np.bytes_):
        return bytes(value).decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "SU" and value.size == 1:
            return decode_attr(value.reshape(()).item())
        return value.astype(value.dtype.newbyteorder("="))
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    return value
