"""Files: netCDF through xarray (labelled, with provenance), CSV and JSON
writers, atomic output handling.  Imports nothing of the analyses."""

from __future__ import annotations

from ._files import (
    CSV_SUFFIXES,
    DATA_SUFFIXES,
    JSON_SUFFIXES,
    PLOT_SUFFIXES,
    TEXT_SUFFIXES,
    Outputs,
    clean_stale,
    json_text,
    text_out,
)
from ._frf_files import (
    FRF_SUFFIXES,
    FRFTable,
    parse_frf_units,
    read_frf,
    read_frf_csv,
    read_frf_cutpro,
    read_frf_uff,
    write_frf_csv,
    write_frf_uff,
)
from ._netcdf import (
    LabelledData,
    atomic_write,
    check_attrs,
    make_dataset,
    provenance_attrs,
    read_dataset,
    read_netcdf,
    write_dataset,
    write_netcdf,
)
from ._netcdf_csv import write_csv

__all__ = [
    "DATA_SUFFIXES",
    "PLOT_SUFFIXES",
    "JSON_SUFFIXES",
    "TEXT_SUFFIXES",
    "CSV_SUFFIXES",
    "Outputs",
    "clean_stale",
    "json_text",
    "text_out",
    "LabelledData",
    "atomic_write",
    "check_attrs",
    "make_dataset",
    "provenance_attrs",
    "read_dataset",
    "read_netcdf",
    "write_csv",
    "write_dataset",
    "write_netcdf",
    "FRF_SUFFIXES",
    "FRFTable",
    "parse_frf_units",
    "read_frf",
    "read_frf_csv",
    "read_frf_cutpro",
    "read_frf_uff",
    "write_frf_csv",
    "write_frf_uff",
]
