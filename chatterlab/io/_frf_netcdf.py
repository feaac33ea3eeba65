"""FRFs in netCDF-4 (docs/measured-frf.md, "netCDF"): the dataset's
layout, its writer and its reader.

The dataset has the dimensions ``output``, ``input`` and ``frequency``; the
coordinate ``frequency`` is in Hz, the data variable ``omega`` (on
``frequency``) holds the angular frequencies in rad/s exactly, ``real`` and
``imag`` the FRF (output, input, frequency) in SI of its quantity (netCDF
has no complex type), ``coherence`` the coherence when known.  The
coordinates ``output`` and ``input`` are indices (a netCDF coordinate here
is numeric); the attributes ``outputs`` and ``inputs`` name them (JSON
lists), ``quantity`` and ``units`` say what the values are, and every
other entry of the record's ``meta`` is an attribute of its own.  Values
are stored as doubles: the round trip is exact.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from ._frf_table import _QNAME, SI_UNITS, FRFRecord, _check_increasing, _resolve_units

__all__ = ["frf_parts", "read_frf_netcdf", "write_frf_netcdf"]

#: the title attribute that marks an FRF dataset
TITLE = "chatterlab FRF"


def frf_parts(record: FRFRecord) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """``(coords, data, attrs)`` of the FRF dataset (module docstring), for
    :func:`chatterlab.io.make_dataset` and :func:`chatterlab.io.write_netcdf`."""
    q = record.quantity
    unit = SI_UNITS[_QNAME.index(q)]
    omega = (
        2 * np.pi * np.asarray(record.frequency_hz, float)
        if record.omega is None
        else np.asarray(record.omega)
    )
    coords = {
        "output": (
            np.arange(len(record.outputs)),
            "1",
            "output coordinate (index into the attribute outputs)",
        ),
        "input": (np.arange(len(record.inputs)), "1", "input coordinate (index into the attribute inputs)"),
        "frequency": (np.asarray(record.frequency_hz, float), "Hz", "frequency"),
    }
    data: dict[str, Any] = {
        "omega": (omega, "rad/s", "angular frequency", ("frequency",)),
        "real": (np.ascontiguousarray(record.data.real), unit, f"real part of the {q}"),
        "imag": (np.ascontiguousarray(record.data.imag), unit, f"imaginary part of the {q}"),
    }
    if record.coherence is not None:
        data["coherence"] = (np.asarray(record.coherence, float), "1", "ordinary coherence")
    attrs: dict[str, Any] = {
        "title": TITLE,
        "quantity": q,
        "units": unit,
        "outputs": json.dumps(list(record.outputs)),
        "inputs": json.dumps(list(record.inputs)),
        "source": record.source,
    }
    for key, val in record.meta.items():
        if val is None or key in attrs or key in ("format",):
            continue
        attrs[key] = val if isinstance(val, bool | int | float | str) else json.dumps(val)
    return coords, data, attrs


def write_frf_netcdf(path: str | os.PathLike[str], record: FRFRecord) -> Path:
    """The FRF dataset to a netCDF-4 file, atomically
    (:func:`chatterlab.io.write_netcdf`)."""
    from ._netcdf import write_netcdf

    return write_netcdf(path, *frf_parts(record))


def _names(value: Any, n: int, what: str, where: str) -> tuple[str, ...]:
    try:
        names = json.loads(value) if isinstance(value, str) else None
    except ValueError:
        names = None
    if not isinstance(names, list) or len(names) != n or not all(isinstance(x, str) for x in names):
        raise InputError(f"{where}: the attribute {what} must be a JSON list of {n} coordinate name(s)")
    return tuple(names)


def read_frf_netcdf(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    quantity: str | None = None,
    point: str | None = None,
) -> FRFRecord:
    """Read an FRF dataset (module docstring) written by
    :func:`write_frf_netcdf` (``FRF.to_netcdf``).  ``units`` and
    ``quantity``, when given, must agree with the file's; ``point`` does not
    apply (the file names its coordinates)."""
    from ._netcdf import read_netcdf

    p = Path(os.fspath(path))
    where = str(p)
    d = read_netcdf(p)
    if d.attrs.get("title") != TITLE or not {"real", "imag", "omega"} <= set(d.data):
        raise InputError(
            f"{where}: not an FRF dataset (no title {TITLE!r} with real, imag and omega); write it with"
            " FRF.to_netcdf"
        )
    fq = str(d.attrs.get("quantity", ""))
    if fq not in _QNAME:
        raise InputError(f"{where}: the attribute quantity must be one of {', '.join(_QNAME)} (got {fq!r})")
    scale, power, used = _resolve_units(units, quantity, str(d.attrs.get("units", "")), fq, where, None)
    if scale != 1.0:
        raise InputError(f"{where}: an FRF dataset holds SI values ({SI_UNITS[power]}), not {used!r}")
    f = np.asarray(d.coords.get("frequency", (np.zeros(0), ""))[0], float)
    _check_increasing(f, list(range(1, f.size + 1)), f"{where}, frequency point")
    re, im = np.asarray(d.data["real"][0], float), np.asarray(d.data["imag"][0], float)
    if re.shape != im.shape or re.ndim != 3 or re.shape[2] != f.size:
        raise InputError(
            f"{where}: real and imag must be (output, input, frequency) = (n_out, n_in, {f.size})"
        )
    outs = _names(d.attrs.get("outputs"), re.shape[0], "outputs", where)
    ins = _names(d.attrs.get("inputs"), re.shape[1], "inputs", where)
    z = np.empty(re.shape, complex)
    z.real, z.imag = re, im  # exactly the stored parts
    coh = np.asarray(d.data["coherence"][0], float) if "coherence" in d.data else None
    omega = np.asarray(d.data["omega"][0], float)
    if omega.shape != f.shape:
        raise InputError(f"{where}: omega must hold one value per frequency ({f.size})")
    # the layout's own attributes, and the provenance the writer adds (a new one with every write)
    reserved = (
        "title",
        "quantity",
        "units",
        "outputs",
        "inputs",
        "chatterlab_version",
        "created",
        "command_line",
    )
    meta = {k: v for k, v in d.attrs.items() if k not in reserved}
    meta.update({"units": used, "quantity": fq, "format": "netcdf"})
    return FRFRecord(f, z, outs, ins, fq, coh, where, meta, omega)
