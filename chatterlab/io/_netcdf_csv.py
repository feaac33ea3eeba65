"""Labelled arrays as a long-format CSV file: the text twin of the netCDF
files of :mod:`._netcdf`, from the same specifications (one row per grid
point, coordinates first, header ``name [unit]``), written atomically."""

from __future__ import annotations

import csv
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, Any

import numpy as np

from chatterlab.errors import InputError

from ._netcdf import atomic_write
from ._netcdf_specs import check_name, normalise_coords, normalise_data

__all__ = ["write_csv"]


def write_csv(
    path: str | os.PathLike[str] | IO[str],
    coords: Mapping[str, Any],
    data: Mapping[str, Any],
    *,
    block: int = 65536,
    coded: Mapping[str, tuple[np.ndarray, Sequence[str]]] | None = None,
) -> Path | None:
    """Write labelled arrays as a long-format CSV file (atomically), or to an
    open text stream (standard output: then nothing is returned).

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
    stream: IO[str] | None = path if not isinstance(path, str | os.PathLike) else None
    target = None if stream is not None else Path(path)  # type: ignore[arg-type]
    cnorm = normalise_coords(coords)
    if not cnorm:
        raise InputError("write_csv needs at least one coordinate")
    dnorm = normalise_data(cnorm, data)
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
        check_name(name, "column")
        c = np.asarray(codes)
        if c.shape != shape:
            raise InputError(f"write_csv: coded column {name!r} has shape {c.shape}, the grid {shape}")
        header.append(name)
        texts.append((c.reshape(-1), list(labels)))

    def rows(fh: Any) -> None:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        for start in range(0, size, block):
            idx = np.arange(start, min(start + block, size))
            subs = np.unravel_index(idx, shape)
            cols = [v[s].tolist() for (v, _, _), s in zip(cnorm.values(), subs, strict=True)]
            cols += [_as_python(a[start : start + len(idx)]) for a in flat]
            cols += [[lab[int(k)] for k in c[start : start + len(idx)]] for c, lab in texts]
            w.writerows(zip(*cols, strict=True))

    if target is None:  # an open text stream (standard output): written as it is
        assert stream is not None
        rows(stream)
        return None
    with atomic_write(target) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        rows(fh)
    return target


def _as_python(a: np.ndarray) -> list[Any]:
    if a.dtype.kind == "b":
        return a.astype(np.int8).tolist()
    return np.asarray(a).tolist()
