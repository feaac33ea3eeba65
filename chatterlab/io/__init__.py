"""Files: netCDF through xarray (labelled, with provenance), CSV and JSON
writers, atomic output handling.  Imports nothing of the analyses.

The names below come from their module on first use (PEP 562), so that
``from chatterlab.io._files import Outputs`` -- the command line's output
handling, loaded for every ``chatterlab ... --help`` -- costs no numpy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_names

if TYPE_CHECKING:  # what type checkers and the API reference see; at run time, below
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
        frf_parts,
        parse_frf_units,
        read_frf,
        read_frf_csv,
        read_frf_cutpro,
        read_frf_netcdf,
        read_frf_uff,
        write_frf_csv,
        write_frf_netcdf,
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
    from ._result import Result

#: public name -> the module that holds it, imported on first use
_HOME = {
    **dict.fromkeys(
        (
            "CSV_SUFFIXES",
            "DATA_SUFFIXES",
            "JSON_SUFFIXES",
            "PLOT_SUFFIXES",
            "TEXT_SUFFIXES",
            "Outputs",
            "clean_stale",
            "json_text",
            "text_out",
        ),
        "_files",
    ),
    **dict.fromkeys(
        (
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
        ),
        "_frf_files",
    ),
    **dict.fromkeys(
        (
            "LabelledData",
            "atomic_write",
            "check_attrs",
            "make_dataset",
            "provenance_attrs",
            "read_dataset",
            "read_netcdf",
            "write_dataset",
            "write_netcdf",
        ),
        "_netcdf",
    ),
    "write_csv": "_netcdf_csv",
    "Result": "_result",
}


__getattr__, __dir__ = lazy_names(__name__, _HOME)


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
    "Result",
    "write_dataset",
    "write_netcdf",
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
