"""FRF files: CSV/TXT columns, UFF dataset 58/58b, CutPro-style ``.frf``
text, netCDF-4; readers and (atomic) writers.

io knows nothing of the analyses: a reader returns plain arrays (a private
record: frequency in Hz, the FRF shaped (n_out, n_in, n_freq) in SI of the
file's quantity, coordinate names, coherence, what the file says), which
:class:`chatterlab.structure.FRF` turns into the structure's response; the
writers take the same record.  The formats are specified field by field in
docs/measured-frf.md.

Units and quantities
--------------------
A file holds a receptance (displacement/force), a mobility
(velocity/force) or an accelerance (acceleration/force) in some length unit.
The unit string says both: ``m/N``, ``mm/N``, ``um/N`` (``µm/N``) are
receptances; ``m/s/N`` (``mm/s/N``, ``m/(N s)``) mobilities; ``m/s^2/N``
(``m/s2/N``, ``m/(N s^2)``) and ``g/N`` (g = 9.80665 m/s^2) accelerances.
The quantity word (``receptance``, ``mobility``, ``accelerance``; also
``compliance``, ``inertance``...) may be given alone (SI then) or with the
unit, which must agree.  The readers scale the values to SI of their
quantity; :meth:`chatterlab.structure.FRF.read` converts them to
receptance in m/N, H = A / (j w)^p with p = 0, 1, 2 (Ewins [1], sec. 2.7),
so a mobility or accelerance at 0 Hz cannot be converted and is refused
(by the reader, with its line).

References
----------
.. [1] D. J. Ewins, *Modal Testing: Theory, Practice and Application*, 2nd
   ed., Research Studies Press, 2000.
.. [2] Universal File Format, dataset 58 (function at nodal DOF), SDRC /
   Siemens I-deas documentation; read and written through pyuff.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import InputError
from ._frf_csv import read_frf_csv, write_frf_csv
from ._frf_cutpro import read_frf_cutpro
from ._frf_netcdf import frf_parts, read_frf_netcdf, write_frf_netcdf
from ._frf_table import G0 as G0
from ._frf_table import FRFRecord, check_regular, parse_frf_units
from ._frf_uff import read_frf_uff, write_frf_uff

__all__ = [
    "FRF_SUFFIXES",
    "frf_parts",
    "parse_frf_units",
    "read_frf",
    "read_frf_csv",
    "read_frf_cutpro",
    "read_frf_netcdf",
    "read_frf_uff",
    "write_frf_csv",
    "write_frf_netcdf",
    "write_frf_uff",
]

#: suffixes of measured-FRF files, by format
FRF_SUFFIXES = {".csv": "csv", ".txt": "csv", ".frf": "frf", ".uff": "uff", ".unv": "uff", ".nc": "netcdf"}


# ============================================================================ dispatch


def read_frf(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    quantity: str | None = None,
    point: str | None = None,
    format: str | None = None,
) -> FRFRecord:
    """Read any FRF file; the format from ``format`` (``"csv"``, ``"frf"``,
    ``"uff"``, ``"netcdf"``) or the suffix (:data:`FRF_SUFFIXES`)."""
    p = Path(os.fspath(path))
    try:  # a FIFO, a device or a folder is refused whatever its name (never opened here: a FIFO would block)
        mode = os.stat(p).st_mode
    except (OSError, ValueError):
        mode = None  # missing or unreadable: the reader says so
    if mode is not None:
        check_regular(mode, str(p))
    fmt = format or FRF_SUFFIXES.get(p.suffix.lower())
    if fmt is None:
        raise InputError(
            f"{p}: unknown FRF file type {p.suffix!r}; use .csv/.txt (columns), .frf (CutPro-style), .uff/.unv"
            " (dataset 58) or .nc (netCDF), or give the format"
        )
    readers = {"csv": read_frf_csv, "frf": read_frf_cutpro, "uff": read_frf_uff, "netcdf": read_frf_netcdf}
    reader = readers.get(fmt)
    if reader is None:
        raise InputError(f"format must be 'csv', 'frf', 'uff' or 'netcdf' (got {fmt!r})")
    return reader(p, units=units, quantity=quantity, point=point)
