"""The one result protocol: :class:`Result`, what every result of chatterlab
does with files, implemented once.

A result describes itself once, as labelled arrays (:meth:`Result.dataset_parts`:
the coordinates, the data variables and the global attributes, in the
specifications of :func:`chatterlab.io.make_dataset`), and inherits

* :meth:`Result.to_xarray` -- an :class:`xarray.Dataset`;
* :meth:`Result.to_netcdf` -- a netCDF-4 file, written atomically, with
  provenance; returns the path;
* :meth:`Result.to_csv` -- a long-format CSV file of the variables that span
  every coordinate (one row per grid point, ``name [unit]`` headers, every
  number the shortest decimal that reads back to the same double); returns
  the path.  A result whose table has a layout of its own (words for codes,
  what was searched on every row) overrides it;
* :meth:`Result.to_json` -- the same numbers as JSON text (strict: NaN and
  infinities are ``null``), written to a path when one is given (the file
  holds exactly the text returned).  A result with a JSON contract of its
  own (``to_dict()``: the document ``chatterlab roots --format json`` or
  ``chatterlab modes`` prints) writes that document instead.

``plot(ax=None, **style)`` is each result's own (it draws through
:mod:`chatterlab.plot`) and returns the Axes it drew on (a tuple of Axes for
a figure of several panels).  ``tests/test_result_protocol.py`` checks every
public result type against this page.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Result"]


class Result:
    """Mixin: files from :meth:`dataset_parts` (see the module docstring)."""

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)``: the result as labelled arrays."""
        raise NotImplementedError(f"{type(self).__name__} does not describe itself as labelled arrays")

    def to_xarray(self) -> Any:
        """The result as an :class:`xarray.Dataset` (units in the attributes)."""
        from ._netcdf import make_dataset

        return make_dataset(*self.dataset_parts())

    def to_netcdf(
        self, path: str | os.PathLike[str], *, attrs: dict[str, Any] | None = None, provenance: bool = True
    ) -> Path:
        """A netCDF-4 file of :meth:`to_xarray` (``attrs`` added to the global
        attributes, e.g. the model's text; provenance -- version, time,
        command line -- unless ``provenance=False``), written atomically;
        returns the path."""
        from ._netcdf import write_netcdf

        coords, data, a = self.dataset_parts()
        return write_netcdf(path, coords, data, {**a, **(attrs or {})}, provenance=provenance)

    def to_csv(self, path: Any) -> Path | None:
        """A long-format CSV file of the variables that span every coordinate
        (exact floats, ``name [unit]`` headers), written atomically; returns the
        path (``None`` when ``path`` is an open text stream, e.g. standard output)."""
        from ._netcdf_csv import write_csv

        coords, data, _ = self.dataset_parts()
        full = {k: v for k, v in data.items() if not (isinstance(v, tuple) and len(v) == 4)}
        return write_csv(path, coords, full)

    def to_json(self, path: str | os.PathLike[str] | None = None, *, indent: int | None = 2) -> str:
        """The result's labelled arrays as JSON text (``coords``, ``data`` with
        ``units`` and ``values``, ``attrs``), or its own document when it has
        a ``to_dict()``; written (atomically) to ``path`` when given, the
        file holding exactly the text returned."""
        from ._files import json_text, text_out

        if isinstance(path, int) and not isinstance(path, bool):
            raise TypeError(
                f"{type(self).__name__}.to_json(path=None, *, indent=2): pass the indent by keyword"
            )
        to_dict = getattr(self, "to_dict", None)
        text = json_text(to_dict() if to_dict is not None else self._json_doc(), indent=indent)
        if path is not None:
            with text_out(path) as fh:
                fh.write(text)
        return text

    def _json_doc(self) -> dict[str, Any]:
        coords, data, attrs = self.dataset_parts()

        def values(x: Any) -> Any:
            a = np.asarray(x)
            if np.iscomplexobj(a):
                return {"re": a.real.tolist(), "im": a.imag.tolist()}
            return a.tolist()

        return {
            "coords": {k: {"units": v[1], "values": values(v[0])} for k, v in coords.items()},
            "data": {
                k: {"units": v[1] if len(v) > 1 else "", "values": values(v[0])} for k, v in data.items()
            },
            "attrs": {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in attrs.items()},
        }
