"""A generic, restartable parameter-sweep engine.

:func:`sweep` maps a pure function over a named grid of parameters and returns
a :class:`SweepResult` holding one array per declared output, shaped like the
grid.  It knows nothing about chatter: the function is anything of the form
``func(**point) -> dict[str, float]``, typically a :func:`functools.partial`
carrying a frozen model.

Design
------
* **Grid**: an ordered set of named axes (:class:`Axis`: name, 1-D float
  values, unit).  Points are enumerated in C order (last axis fastest); the
  flat task index ``i`` maps to the point ``grid.point(i)``.
* **Chunks**: tasks are dispatched in chunks of contiguous flat indices
  (default: about ``32 * jobs`` chunks, at most 4096 tasks each) so that the
  per-task overhead is a function call, not an inter-process message.
* **Determinism**: each task is a pure function of its grid point, the point
  values are the same Python floats whatever the backend, and results are
  placed by index, so the arrays are bit-identical for the ``"serial"``,
  ``"loky"`` and ``"dask"`` backends and any number of workers.  Workers run
  BLAS/OpenMP single-threaded (loky's ``inner_max_num_threads=1``; dask's
  nanny sets ``OMP_NUM_THREADS=1`` and friends; in the serial backend
  threadpoolctl limits them when it is installed).
* **Checkpoint/resume**: with ``checkpoint=DIR`` every finished chunk is
  written atomically to ``DIR/chunk_NNNNNN.npz`` next to a ``manifest.json``
  (grid, outputs, chunk size, fingerprint of the function); ``resume=True``
  loads the finished chunks and computes only the missing ones, and refuses a
  checkpoint written for another grid, other outputs or another function.
* **Failures**: an exception in a task is caught in the worker; the task's
  outputs become NaN and the failure (grid point, exception type, message) is
  recorded; the result's ``status`` is then ``"partial"``.  ``on_error="raise"``
  raises :class:`~chatterlab.errors.SweepError` instead (finished chunks are
  kept in the checkpoint).
* **Bounded memory**: in-flight work is bounded (``pre_dispatch`` in joblib, a
  sliding window of futures in dask) and results go straight into
  preallocated float arrays -- ``np.memmap`` files when ``out=`` names a
  netCDF file -- so nothing per task accumulates in memory.

joblib, dask, tqdm and matplotlib are imported inside the functions that use
them; importing this module costs numpy only.

Example
-------
>>> import functools
>>> def rate(width, speed, k):
...     return {"abscissa": k * width - speed, "freq": speed / width}
>>> grid = Grid.from_spec("width[m]=1e-3:3e-3:3", "speed[m/s]=1:2:2")
>>> res = sweep(functools.partial(rate, k=1e3), grid, outputs={"abscissa": "1/s", "freq": "Hz"},
...             backend="serial", progress=False)
>>> res.status, res["freq"].shape
('ok', (3, 2))

With ``checkpoint="runs/ck", fingerprint=model_hash`` an interrupted sweep is
continued by the same call with ``resume=True``; ``out="runs/sweep.nc"``
streams the result to a netCDF file (``SweepResult.from_netcdf`` reads it).
"""

from __future__ import annotations

import functools
import hashlib
import heapq
import json
import math
import os
import pickle
import re
import shutil
import signal
import sys
import tempfile
import threading
import time
import warnings
from collections.abc import Callable, Generator, Iterable, Iterator, Mapping
from contextlib import AbstractContextManager, contextmanager, nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from chatterlab.errors import InputError, SweepError
from chatterlab.io._files import clean_stale
from chatterlab.io._netcdf import atomic_write, check_attrs, read_netcdf, write_csv, write_netcdf

__all__ = [
    "Axis",
    "Grid",
    "SweepInterrupted",
    "SweepResult",
    "TaskFailure",
    "sweep",
]

Backend = Literal["loky", "serial", "dask"]

_MANIFEST = "manifest.json"
_LOCK = ".lock"  # held (flock) by the run using the checkpoint; released by the kernel when it dies
_SCRATCH = "scratch-"  # memmap folders of a run streaming to out=, inside the checkpoint
_CHUNK_RE = re.compile(r"^chunk_(\d+)\.npz$")
_CHECKPOINT_FORMAT = "chatterlab-sweep-checkpoint"
_CHECKPOINT_VERSION = 1
_MAX_CHUNK = 4096
_CHUNKS_PER_JOB = 32
_KEEP_FAILURES = 1000  # failures kept in memory (all are counted and stored in chunks)
_FILE_FAILURES = 100  # failures written to the netCDF ``failures`` attribute
_MAX_REASONS = 1000  # distinct failure reasons kept per point (more share the last code)
_OTHER_REASON = f"other failure (more than {_MAX_REASONS} distinct reasons; see the failures attribute)"
STATUS_VARIABLE = "task_status"  # per grid point: 0 ok, k > 0 failed for reasons[k - 1]


# =========================================================================== grid


@dataclass(frozen=True, init=False, eq=False)
class Axis:
    """One named axis of a :class:`Grid`.

    Parameters
    ----------
    name : str
        A Python identifier (it is passed as a keyword argument to the swept
        function and becomes a netCDF coordinate name).
    values : array_like
        The 1-D, finite, non-empty coordinate values; stored as a read-only
        float64 copy.  A scalar gives a one-point axis.
    unit : str, optional
        The unit, e.g. ``"m"`` or ``"N/m"`` (``""`` if dimensionless).
    """

    name: str
    values: np.ndarray
    unit: str

    def __init__(self, name: str, values: ArrayLike, unit: str = "") -> None:
        if not isinstance(name, str) or not (name.isidentifier() and name.isascii()):
            raise InputError(
                f"axis name {name!r} must be an ASCII identifier (letters, digits, "
                "underscores; not starting with a digit)"
            )
        if not isinstance(unit, str):
            raise InputError(f"axis {name!r}: unit must be a string (got {unit!r})")
        try:
            arr = np.array(values, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InputError(f"axis {name!r}: values must be numbers ({exc})") from None
        if arr.ndim == 0:
            arr = arr.reshape(1)
        if arr.ndim != 1 or arr.size == 0:
            raise InputError(f"axis {name!r}: values must be a non-empty 1-D array (got shape {arr.shape})")
        if not np.all(np.isfinite(arr)):
            raise InputError(f"axis {name!r}: values must be finite (got {arr[~np.isfinite(arr)][0]})")
        arr.flags.writeable = False
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "values", arr)
        object.__setattr__(self, "unit", unit)

    def __len__(self) -> int:
        return int(self.values.size)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Axis):
            return NotImplemented
        return (
            self.name == other.name
            and self.unit == other.unit
            and self.values.tobytes() == other.values.tobytes()
        )

    def __hash__(self) -> int:
        return hash((self.name, self.unit, self.values.tobytes()))

    def __repr__(self) -> str:
        v = self.values
        span = f"{v[0]:g}" if v.size == 1 else f"{v[0]:g}..{v[-1]:g}"
        return f"Axis({self.name!r}, {v.size} values {span}, unit={self.unit!r})"


@dataclass(frozen=True, init=False, eq=False)
class Grid:
    """An ordered set of named axes; its points are enumerated in C order.

    Parameters
    ----------
    axes : mapping or iterable of Axis
        Either ``{"width": (values, "m"), "speed": (values, "m/s")}`` (a bare
        array means a dimensionless axis) or ``[Axis("width", values, "m"),
        ...]``.  At least one axis; names must be unique.

    Examples
    --------
    >>> g = Grid({"width": ([1e-3, 2e-3], "m"), "speed": ([1.0, 2.0, 3.0], "m/s")})
    >>> g.shape, g.size
    ((2, 3), 6)
    >>> g.point(4)
    {'width': 0.002, 'speed': 2.0}
    >>> Grid.from_spec("k=1e6:1e7:10", "c=5").shape
    (10, 1)
    """

    axes: tuple[Axis, ...]

    def __init__(self, axes: Mapping[str, Any] | Iterable[Axis]) -> None:
        items: list[Axis] = []
        if isinstance(axes, Mapping):
            for name, spec in axes.items():
                if isinstance(spec, Axis):
                    if spec.name != name:
                        raise InputError(f"axis {spec.name!r} given under the key {name!r}")
                    items.append(spec)
                elif isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[1], str):
                    items.append(Axis(name, spec[0], spec[1]))
                else:
                    items.append(Axis(name, spec))
        else:
            for ax in axes:
                if not isinstance(ax, Axis):
                    raise InputError(
                        f"Grid expects a mapping name -> (values, unit) or Axis objects, "
                        f"got {type(ax).__name__}"
                    )
                items.append(ax)
        if not items:
            raise InputError("a grid needs at least one axis")
        seen: set[str] = set()
        for ax in items:
            if ax.name in seen:
                raise InputError(f"duplicate axis name {ax.name!r} in the grid")
            seen.add(ax.name)
        object.__setattr__(self, "axes", tuple(items))

    # ------------------------------------------------------------- construction

    @classmethod
    def from_spec(cls, *specs: str, units: Mapping[str, str] | None = None) -> Grid:
        """Build a grid from ``NAME=MIN:MAX:N`` specifications.

        Parameters
        ----------
        *specs : str
            One axis each, or several separated by spaces, commas or
            semicolons.  Forms: ``NAME=MIN:MAX:N`` (``N`` linearly spaced
            values, ``MIN < MAX`` when ``N > 1``), ``NAME=VALUE`` (one point).
            A unit may follow the name in brackets: ``k[N/m]=1e6:1e7:10``.
        units : mapping, optional
            Units by axis name (for axes whose spec has no ``[unit]``).

        Returns
        -------
        Grid

        Raises
        ------
        chatterlab.errors.InputError
            Naming the offending spec: bad syntax, a non-number, a non-finite
            bound, ``N < 1`` or not an integer, an empty or reversed range, a
            duplicate name.
        """
        units = dict(units or {})
        tokens = [t for s in specs for t in re.split(r"[\s,;]+", str(s).strip()) if t]
        if not tokens:
            raise InputError("empty grid specification: expected NAME=MIN:MAX:N, e.g. k=1e6:1e7:10")
        axes: list[Axis] = []
        seen: set[str] = set()
        for tok in tokens:
            ax = _parse_axis_spec(tok, units)
            if ax.name in seen:
                raise InputError(f"grid spec {tok!r}: axis {ax.name!r} is given twice")
            seen.add(ax.name)
            axes.append(ax)
        unknown = set(units) - seen
        if unknown:
            raise InputError(f"units given for unknown axes {sorted(unknown)}; axes are {sorted(seen)}")
        return cls(axes)

    @classmethod
    def from_json(cls, obj: Mapping[str, Any]) -> Grid:
        """Inverse of :meth:`to_json`."""
        try:
            return cls([Axis(a["name"], a["values"], a.get("unit", "")) for a in obj["axes"]])
        except (KeyError, TypeError) as exc:
            raise InputError(f"not a grid description: {exc}") from None

    def to_json(self) -> dict[str, Any]:
        """A JSON-serialisable description (floats round-trip exactly)."""
        return {"axes": [{"name": a.name, "unit": a.unit, "values": a.values.tolist()} for a in self.axes]}

    # ------------------------------------------------------------- shape & points

    @property
    def names(self) -> tuple[str, ...]:
        """Axis names, in order."""
        return tuple(a.name for a in self.axes)

    @property
    def units(self) -> dict[str, str]:
        """Axis units by name."""
        return {a.name: a.unit for a in self.axes}

    @property
    def shape(self) -> tuple[int, ...]:
        """Number of values along each axis."""
        return tuple(len(a) for a in self.axes)

    @property
    def size(self) -> int:
        """Number of grid points (tasks)."""
        return math.prod(self.shape)

    @property
    def ndim(self) -> int:
        """Number of axes."""
        return len(self.axes)

    @property
    def coords(self) -> dict[str, tuple[np.ndarray, str]]:
        """``name -> (values, unit)``, as :func:`chatterlab.io._netcdf.write_netcdf` takes."""
        return {a.name: (a.values, a.unit) for a in self.axes}

    def __getitem__(self, name: str) -> Axis:
        for a in self.axes:
            if a.name == name:
                return a
        raise KeyError(f"no axis {name!r}; axes are {list(self.names)}")

    def unravel(self, index: int) -> tuple[int, ...]:
        """Per-axis indices of flat task index ``index`` (C order)."""
        if not 0 <= int(index) < self.size:
            raise IndexError(f"task index {index} out of range for a grid of {self.size} points")
        return tuple(int(i) for i in np.unravel_index(int(index), self.shape))

    def point(self, index: int) -> dict[str, float]:
        """The grid point of flat task index ``index``: ``{name: value}``."""
        sub = self.unravel(index)
        return {a.name: float(a.values[i]) for a, i in zip(self.axes, sub, strict=True)}

    def format_point(self, point: Mapping[str, float]) -> str:
        """``"width=0.003 m, speed=2 m/s"`` for messages."""
        units = self.units
        return ", ".join(f"{k}={v:.10g}" + (f" {units[k]}" if units.get(k) else "") for k, v in point.items())

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Grid):
            return NotImplemented
        return self.axes == other.axes

    def __hash__(self) -> int:
        return hash(self.axes)

    def __repr__(self) -> str:
        dims = " x ".join(f"{a.name}[{len(a)}]" for a in self.axes)
        return f"Grid({dims} = {self.size} points)"


_NUM = r"[^:=\[\]]+"
_SPEC_RE = re.compile(r"^(?P<name>[^=\[\]]+)(?:\[(?P<unit>[^\]]*)\])?=(?P<rhs>.*)$")


def _parse_axis_spec(tok: str, units: Mapping[str, str]) -> Axis:
    hint = "expected NAME=MIN:MAX:N (e.g. k=1e6:1e7:10) or NAME=VALUE"
    m = _SPEC_RE.match(tok)
    if not m:
        raise InputError(f"grid spec {tok!r}: {hint}")
    name = m["name"].strip()
    if not (name.isidentifier() and name.isascii()):
        raise InputError(f"grid spec {tok!r}: {name!r} is not a valid axis name (an identifier)")
    unit = m["unit"] if m["unit"] is not None else units.get(name, "")
    parts = m["rhs"].split(":")
    if len(parts) not in (1, 3):
        raise InputError(f"grid spec {tok!r}: {hint}")

    def number(text: str, what: str) -> float:
        try:
            x = float(text)
        except ValueError:
            raise InputError(f"grid spec {tok!r}: {what} {text!r} is not a number; {hint}") from None
        if not math.isfinite(x):
            raise InputError(f"grid spec {tok!r}: {what} must be finite (got {text!r})")
        return x

    if len(parts) == 1:
        return Axis(name, np.array([number(parts[0], "VALUE")]), unit)
    lo, hi = number(parts[0], "MIN"), number(parts[1], "MAX")
    if not re.fullmatch(r"\s*[+]?\d+\s*", parts[2]):
        raise InputError(f"grid spec {tok!r}: N {parts[2]!r} must be a whole number of points >= 1; {hint}")
    n = int(parts[2])
    if n < 1:
        raise InputError(f"grid spec {tok!r}: N must be >= 1 (got {n}): the axis would be empty")
    if n > 1 and lo >= hi:
        what = "empty" if lo == hi else "reversed"
        raise InputError(f"grid spec {tok!r}: {what} range: MIN ({lo:g}) must be < MAX ({hi:g}) when N > 1")
    if n == 1 and lo != hi:
        raise InputError(
            f"grid spec {tok!r}: N=1 with MIN != MAX is ambiguous; write {name}={lo:g} for a single point"
        )
    return Axis(name, np.linspace(lo, hi, n), unit)


# =========================================================================== results


class TaskFailure(NamedTuple):
    """One failed task: where, and what was raised."""

    point: dict[str, float]
    """The grid point ``{name: value}``."""
    error_type: str
    """The exception class name, e.g. ``"LinAlgError"``."""
    message: str
    """``str(exception)`` (truncated to 500 characters)."""
    task_index: int
    """The flat task index (``grid.point(task_index) == point``)."""

    def describe(self, grid: Grid | None = None) -> str:
        """``"at width=0.003 m, speed=2 m/s: ZeroDivisionError: division by zero"``."""
        where = (
            grid.format_point(self.point)
            if grid
            else ", ".join(f"{k}={v:.10g}" for k, v in self.point.items())
        )
        return f"at {where}: {self.error_type}: {self.message}"


class SweepInterrupted(KeyboardInterrupt):
    """Raised (instead of a bare :class:`KeyboardInterrupt`) when a sweep is
    interrupted with Ctrl-C.  Its message says how many chunks are done and
    how to resume; ``except KeyboardInterrupt`` still catches it."""

    def __init__(self, message: str, *, done: int, total: int, checkpoint: str | None) -> None:
        super().__init__(message)
        self.done = done
        self.total = total
        self.checkpoint = checkpoint


@dataclass(frozen=True, eq=False)
class SweepResult:
    """The outcome of :func:`sweep`.

    Attributes
    ----------
    grid : Grid
        The swept grid.
    data : dict
        ``output name -> float64 array`` of shape ``grid.shape`` (NaN where a
        task failed).  Read-only; when the sweep streamed to ``out=``, these
        are memory maps of that netCDF file.
    units : dict
        ``output name -> unit``.
    status : {"ok", "partial"}
        ``"partial"`` when some tasks failed.
    message : str
        A one-line summary; names the first failing grid point, if any.
    failures : tuple of TaskFailure
        The failed tasks, by increasing index (the first 1000 only;
        ``n_failed`` counts them all).
    attrs : dict
        Caller attributes (e.g. the model text), written to files as global
        attributes.
    long_names : dict
        ``output name -> long name`` (defaults to the name).
    n_computed, n_resumed, n_failed : int
        Tasks computed in this call, loaded from the checkpoint, failed.
    elapsed : float
        Wall time of the call, in seconds.
    task_status : ndarray of int32, optional
        Shaped like the grid: 0 where the task succeeded, ``k > 0`` where it
        failed, for the reason ``reasons[k - 1]`` (``"ErrorType: message"``).
        Written to files: a ``task_status`` variable and a ``reasons``
        attribute (netCDF), ``status`` and ``reason`` columns (CSV).
    reasons : tuple of str
        The distinct failure reasons, in the order of their first grid point.
    """

    grid: Grid
    data: dict[str, np.ndarray]
    units: dict[str, str]
    status: str = "ok"
    message: str = ""
    failures: tuple[TaskFailure, ...] = ()
    attrs: dict[str, Any] = field(default_factory=dict)
    long_names: dict[str, str] = field(default_factory=dict)
    n_computed: int = 0
    n_resumed: int = 0
    n_failed: int = 0
    elapsed: float = 0.0
    task_status: np.ndarray | None = field(default=None, repr=False)
    reasons: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        """True when every task succeeded."""
        return self.status == "ok"

    def __getitem__(self, output: str) -> np.ndarray:
        try:
            return self.data[output]
        except KeyError:
            raise KeyError(f"no output {output!r}; outputs are {list(self.data)}") from None

    # ------------------------------------------------------------------ files

    def file_attrs(self) -> dict[str, Any]:
        """Global attributes written to files: ``attrs`` plus the run status."""
        out = dict(self.attrs)
        out["status"] = self.status
        out["message"] = self.message
        out["n_failed"] = int(self.n_failed)
        if self.task_status is not None:
            out["reasons"] = json.dumps(list(self.reasons))
        if self.failures:
            out["failures"] = json.dumps(
                [
                    {
                        "task_index": f.task_index,
                        "point": f.point,
                        "error_type": f.error_type,
                        "message": f.message,
                    }
                    for f in self.failures[:_FILE_FAILURES]
                ]
            )
        return out

    def _data_specs(self) -> dict[str, tuple[np.ndarray, str, str]]:
        return {n: (a, self.units.get(n, ""), self.long_names.get(n, n)) for n, a in self.data.items()}

    def _status_spec(self) -> dict[str, tuple[np.ndarray, str, str]]:
        if self.task_status is None:
            return {}
        return {
            STATUS_VARIABLE: (
                self.task_status,
                "1",
                "task status: 0 ok, k > 0 failed for the k-th entry of the reasons attribute",
            )
        }

    def to_netcdf(self, path: str | os.PathLike[str], *, provenance: bool = True) -> Path:
        """Write a netCDF classic file (see :func:`chatterlab.io._netcdf.write_netcdf`).

        Grid axes become coordinate variables, outputs data variables with
        ``units`` and ``long_name``; ``attrs``, ``status``, ``message``,
        ``n_failed`` (and the first failures, as JSON) become global
        attributes, plus provenance unless ``provenance=False`` or ``attrs``
        fixes it (e.g. ``attrs={"created": "..."}`` for reproducible bytes).
        """
        return write_netcdf(
            path,
            self.grid.coords,
            self._data_specs() | self._status_spec(),
            self.file_attrs(),
            provenance=provenance,
        )

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write a long-format CSV file: one row per grid point, header ``name [unit]``,
        then (when the task status is known) ``status`` (``ok``/``failed``) and
        ``reason`` (empty, or ``ErrorType: message``)."""
        coded = None
        if self.task_status is not None:
            coded = {
                "status": (self.task_status, ["ok"] + ["failed"] * len(self.reasons)),
                "reason": (self.task_status, ["", *self.reasons]),
            }
        return write_csv(path, self.grid.coords, self._data_specs(), coded=coded)

    @classmethod
    def from_netcdf(cls, path: str | os.PathLike[str], *, mmap: bool = False) -> SweepResult:
        """Read a file written by :meth:`to_netcdf` (or by ``sweep(..., out=path)``)."""
        f = read_netcdf(path, mmap=mmap)
        grid = Grid({n: (v, u) for n, (v, u) in f.coords.items()})
        attrs = dict(f.attrs)
        status = str(attrs.pop("status", "ok"))
        message = str(attrs.pop("message", ""))
        n_failed = int(attrs.pop("n_failed", 0))
        failures: tuple[TaskFailure, ...] = ()
        if "failures" in attrs:
            try:
                failures = tuple(
                    TaskFailure(d["point"], d["error_type"], d["message"], d["task_index"])
                    for d in json.loads(attrs.pop("failures"))
                )
            except (ValueError, KeyError, TypeError):
                pass
        reasons: tuple[str, ...] = ()
        if "reasons" in attrs:
            try:
                reasons = tuple(str(r) for r in json.loads(attrs.pop("reasons")))
            except (ValueError, TypeError):
                reasons = ()
        data, units, long_names = {}, {}, {}
        task_status = None
        for name, (arr, unit, long_name) in f.data.items():
            if f.dims.get(name) != grid.names:
                continue
            if name == STATUS_VARIABLE:
                task_status = np.asarray(arr, dtype=np.int32)
                continue
            data[name], units[name], long_names[name] = arr, unit, long_name
        return cls(
            grid,
            data,
            units,
            status,
            message,
            failures,
            attrs,
            long_names,
            n_failed=n_failed,
            task_status=task_status,
            reasons=reasons,
        )

    def to_dataset(self) -> Any:
        """An :class:`xarray.Dataset` (needs xarray: ``pip install xarray``)."""
        try:
            import xarray as xr
        except ImportError:
            raise ImportError(
                "SweepResult.to_dataset needs xarray, which chatterlab does not depend on: pip install xarray"
            ) from None
        names = self.grid.names
        coords = {a.name: (a.name, np.asarray(a.values), {"units": a.unit}) for a in self.grid.axes}
        data_vars = {
            n: (names, np.asarray(a), {"units": u, "long_name": ln})
            for n, (a, u, ln) in self._data_specs().items()
        }
        return xr.Dataset(data_vars, coords=coords, attrs=self.file_attrs())

    # ------------------------------------------------------------------ plotting

    def plot(
        self,
        output: str,
        ax: Any = None,
        *,
        x: str | None = None,
        at: Mapping[str, float] | None = None,
    ) -> Any:
        """Plot one output: a line over a 1-D grid, a colour map over a 2-D grid.

        Parameters
        ----------
        output : str
            The output to plot.
        ax : matplotlib Axes, optional
            Where to draw (a new figure otherwise).
        x : str, optional
            For a 2-D map, the axis on the abscissa (default: the last free
            axis, i.e. the fastest-varying one).
        at : mapping, optional
            Values for the axes to hold fixed (nearest grid value) when the
            grid has more than two axes, e.g. ``at={"depth": 2e-3}``.

        Returns
        -------
        matplotlib.axes.Axes
        """
        import matplotlib.pyplot as plt

        arr = np.asarray(self[output], dtype=float)
        at = dict(at or {})
        for name in at:
            self.grid[name]  # KeyError for an unknown axis
        sel: list[Any] = []
        free: list[Axis] = []
        for a in self.grid.axes:
            if a.name in at:
                sel.append(int(np.argmin(np.abs(a.values - float(at[a.name])))))
            else:
                sel.append(slice(None))
                free.append(a)
        sub = arr[tuple(sel)]
        if not 1 <= len(free) <= 2:
            raise InputError(
                f"plot({output!r}): {len(free)} free axes {[a.name for a in free]}; hold all "
                "but one or two fixed with at={name: value}"
            )
        if ax is None:
            _, ax = plt.subplots()
        unit = self.units.get(output, "")
        label = self.long_names.get(output, output) + (f" [{unit}]" if unit else "")

        def axis_label(a: Axis) -> str:
            return a.name + (f" [{a.unit}]" if a.unit else "")

        if len(free) == 1:
            ax.plot(free[0].values, sub, marker="." if sub.size < 60 else None)
            ax.set_xlabel(axis_label(free[0]))
            ax.set_ylabel(label)
        else:
            xa = free[1] if x is None else self.grid[x]
            if xa not in free:
                raise InputError(f"plot: x={x!r} is held fixed by at=")
            ya = free[0] if xa is free[1] else free[1]
            c = sub if xa is free[1] else sub.T
            mesh = ax.pcolormesh(xa.values, ya.values, np.ma.masked_invalid(c), shading="auto")
            ax.set_xlabel(axis_label(xa))
            ax.set_ylabel(axis_label(ya))
            ax.figure.colorbar(mesh, ax=ax, label=label)
        if at:
            ax.set_title(self.grid.format_point({k: float(v) for k, v in at.items()}))
        return ax


# =========================================================================== worker side


@dataclass(frozen=True)
class _Payload:
    """What a worker needs to run any chunk (pickled with each chunk)."""

    func: Callable[..., Mapping[str, Any]]
    names: tuple[str, ...]
    axes: tuple[np.ndarray, ...]
    shape: tuple[int, ...]
    outputs: tuple[str, ...]


class _ChunkOut(NamedTuple):
    chunk: int
    start: int
    values: np.ndarray  # (n_outputs, n_tasks) float64
    failed_index: list[int]
    failed_type: list[str]
    failed_message: list[str]
    contract: str | None  # a broken output contract: always fatal


def _short(exc: BaseException, limit: int = 500) -> str:
    msg = str(exc)
    return msg if len(msg) <= limit else msg[: limit - 3] + "..."


def _run_chunk(payload: _Payload, chunk: int, start: int, stop: int) -> _ChunkOut:
    """Evaluate the tasks ``start <= i < stop`` (runs in the worker)."""
    func, names, outputs = payload.func, payload.names, payload.outputs
    n = stop - start
    subs = np.unravel_index(np.arange(start, stop), payload.shape)
    cols = [ax[s].tolist() for ax, s in zip(payload.axes, subs, strict=True)]
    values = np.full((len(outputs), n), np.nan)
    expected = set(outputs)
    f_idx: list[int] = []
    f_type: list[str] = []
    f_msg: list[str] = []
    for k in range(n):
        point = {name: col[k] for name, col in zip(names, cols, strict=True)}
        try:
            res = func(**point)
        except Exception as exc:  # noqa: BLE001 - any task error becomes a recorded failure
            f_idx.append(start + k)
            f_type.append(type(exc).__name__)
            f_msg.append(_short(exc))
            continue
        if not isinstance(res, Mapping) or res.keys() != expected:
            got = sorted(res) if isinstance(res, Mapping) else type(res).__name__
            detail = ""
            if isinstance(res, Mapping):
                missing = sorted(expected - set(res))
                extra = sorted(set(res) - expected)
                detail = f" (missing {missing}, unexpected {extra})"
            return _ChunkOut(
                chunk,
                start,
                values,
                f_idx,
                f_type,
                f_msg,
                f"the swept function returned {got} at task {start + k} ({point}); it must "
                f"return a dict with exactly the declared outputs {sorted(expected)}{detail}",
            )
        try:
            for j, o in enumerate(outputs):
                values[j, k] = float(res[o])
        except (TypeError, ValueError) as exc:
            values[:, k] = np.nan
            f_idx.append(start + k)
            f_type.append(type(exc).__name__)
            f_msg.append(f"output {o!r} is not a real number: {_short(exc)}")
    return _ChunkOut(chunk, start, values, f_idx, f_type, f_msg, None)


# =========================================================================== runners


def _blas_limit() -> AbstractContextManager[Any]:
    """Single-threaded BLAS/OpenMP in this process, when threadpoolctl is installed."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return nullcontext()
    return threadpool_limits(limits=1)


def _serial_runner(
    payload: _Payload, chunks: Iterator[tuple[int, int, int]]
) -> Generator[_ChunkOut, None, None]:
    with _blas_limit():
        for c, s, e in chunks:
            yield _run_chunk(payload, c, s, e)


_WATCHDOG_PERIOD = 0.2  # s between two looks at the parent process


def _watch_parent(parent: int) -> None:
    """Worker initializer: a daemon thread ends this worker process as soon
    as ``parent`` (the process that runs the sweep) is gone -- killed with
    SIGKILL, it cannot tell its workers, and loky would keep them for its
    idle timeout (5 minutes), holding the caller's stdout and stderr open."""

    def watch() -> None:
        while True:
            time.sleep(_WATCHDOG_PERIOD)
            if os.getppid() != parent or not _alive(parent):
                os._exit(0)

    threading.Thread(target=watch, name="chatterlab-parent-watchdog", daemon=True).start()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


def _loky_runner(
    payload: _Payload, chunks: Iterator[tuple[int, int, int]], jobs: int
) -> Generator[_ChunkOut, None, None]:
    from joblib import Parallel, delayed, parallel_config

    # inner_max_num_threads=1: loky starts its workers with OMP/OPENBLAS/MKL/...
    # _NUM_THREADS=1 so that BLAS does not oversubscribe the cores.  Each
    # worker watches this process and exits when it dies (_watch_parent).
    with parallel_config(
        backend="loky",
        n_jobs=jobs,
        inner_max_num_threads=1,
        initializer=_watch_parent,
        initargs=(os.getpid(),),
    ):
        par = Parallel(return_as="generator_unordered", pre_dispatch="2*n_jobs", batch_size=1)
        gen = par(delayed(_run_chunk)(payload, c, s, e) for c, s, e in chunks)
    try:
        yield from gen
    finally:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            gen.close()


@contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT while starting worker processes (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def _dask_runner(
    payload: _Payload,
    chunks: Iterator[tuple[int, int, int]],
    jobs: int,
    scheduler: Any,
    timeout: float,
    security: Any = None,
) -> Generator[_ChunkOut, None, None]:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise SweepError(
            "the dask backend needs dask.distributed, which is not installed: pip install chatterlab[dask]"
        ) from None

    cluster = None
    own_client = True
    if scheduler is None:
        cluster, client = _local_cluster(jobs)
    elif isinstance(scheduler, str):
        try:
            client = Client(scheduler, timeout=timeout, set_as_default=False, security=security)
        except (OSError, TimeoutError) as exc:
            raise SweepError(
                f"cannot reach the dask scheduler at {scheduler!r} within {timeout:g} s "
                f"({type(exc).__name__}: {exc}); check the address, or start one with "
                "`dask scheduler` and workers with `dask worker ADDRESS`"
            ) from None
    else:  # an existing distributed.Client
        client = scheduler
        own_client = False
    outstanding: set[Any] = set()
    try:
        try:
            client.wait_for_workers(1, timeout=timeout)
        except (OSError, TimeoutError):
            raise SweepError(
                f"the dask scheduler {client.scheduler.address} has no workers "
                f"(waited {timeout:g} s); start some with `dask worker ADDRESS`"
            ) from None
        nthreads = sum(client.nthreads().values()) or 1
        window = max(2, 2 * nthreads)
        [pfut] = client.scatter([payload], broadcast=True, hash=False)
        ac = as_completed(loop=client.loop)

        def submit_next() -> bool:
            nxt = next(chunks, None)
            if nxt is None:
                return False
            c, s, e = nxt
            fut = client.submit(_run_chunk, pfut, c, s, e, pure=False)
            outstanding.add(fut)
            ac.add(fut)
            return True

        for _ in range(window):
            if not submit_next():
                break
        for fut in ac:
            res = fut.result()
            outstanding.discard(fut)
            fut.release()
            submit_next()
            yield res
    finally:
        if outstanding:
            try:
                client.cancel(list(outstanding))
            except Exception:  # noqa: BLE001 - best effort on the way out
                pass
        if own_client:
            client.close()
        if cluster is not None:
            cluster.close()


@contextmanager
def _local_cluster_config() -> Iterator[None]:
    """dask settings for chatterlab's own local cluster: no dashboard and no
    HTTP routes at all (the scheduler and the workers still open an HTTP
    listener, on a random loopback port, that answers 404)."""
    import dask

    with dask.config.set(
        {
            "distributed.scheduler.http.routes": [],
            "distributed.worker.http.routes": [],
            "distributed.nanny.http.routes": [],
        }
    ):
        yield


def _local_cluster(jobs: int) -> tuple[Any, Any]:
    """A local dask cluster of ``jobs`` single-threaded worker processes and
    a client: listening on the loopback interface only, with no dashboard,
    and (when ``cryptography`` is installed) TLS with temporary credentials."""
    from distributed import Client, LocalCluster

    with _sigint_ignored(), _local_cluster_config():  # the worker processes inherit SIG_IGN
        security = _local_security()
        cluster = LocalCluster(
            n_workers=jobs,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",  # its HTTP listener: loopback, a random port, not 8787
            worker_dashboard_address=None,
            scheduler_kwargs={"dashboard": False},  # ... and no dashboard behind it
            **({"security": security, "protocol": "tls"} if security is not None else {"protocol": "tcp"}),
        )
    try:
        client = Client(cluster, security=security, set_as_default=False)
    except BaseException:
        cluster.close()
        raise
    return cluster, client


def _local_security() -> Any:
    """Temporary TLS credentials for a local cluster, held in memory: only
    this process and the workers it starts can talk to the scheduler, so
    another user of the machine cannot submit code through its loopback
    ports.  None (plain TCP on loopback) when ``cryptography`` is missing."""
    try:
        from distributed.security import Security

        return Security.temporary()
    except ImportError:
        warnings.warn(
            "the local dask cluster runs without TLS (install 'cryptography' for temporary TLS"
            " credentials); its loopback ports accept any local user",
            stacklevel=3,
        )
        return None


# =========================================================================== checkpoint


def _open_checkpoint(
    directory: Path, manifest: dict[str, Any], resume: bool, chunk_size: int | None
) -> dict[str, Any]:
    """Create or validate the checkpoint directory; return the manifest in force."""
    if directory.exists() and not directory.is_dir():
        raise InputError(f"checkpoint {str(directory)!r} exists and is not a directory")
    existing = directory.is_dir() and any(
        p.name != _LOCK and not p.name.startswith(_SCRATCH) for p in directory.iterdir()
    )
    where = f"checkpoint directory {str(directory)!r}"
    if existing and not resume:
        raise InputError(
            f"{where} is not empty: pass resume=True (CLI: --resume) to continue the sweep "
            "saved there, or delete the directory to start afresh"
        )
    mpath = directory / _MANIFEST
    if not existing:
        _write_json(mpath, manifest)
        return manifest
    if not mpath.is_file():
        raise InputError(
            f"{where} holds files but no {_MANIFEST}: it is not a chatterlab sweep checkpoint; "
            "choose another directory"
        )
    try:
        old = json.loads(mpath.read_text(encoding="utf-8"))
        if old.get("format") != _CHECKPOINT_FORMAT:
            raise ValueError("not a sweep checkpoint manifest")
        old_grid = Grid.from_json(old["grid"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{where}: cannot read {_MANIFEST} ({exc}); delete the directory") from None
    if old.get("version") != _CHECKPOINT_VERSION:
        raise InputError(f"{where} was written by an incompatible version of chatterlab")
    refuse = f"{where} was written for a different sweep"
    fix = "; use another checkpoint directory or delete this one (resume only continues the same sweep)"
    new_grid = Grid.from_json(manifest["grid"])
    if old_grid != new_grid:
        raise InputError(
            f"{refuse}: grid {old_grid!r} there, {new_grid!r} now{_grid_diff(old_grid, new_grid)}{fix}"
        )
    if old["outputs"] != manifest["outputs"]:
        raise InputError(f"{refuse}: outputs {old['outputs']} there, {manifest['outputs']} now{fix}")
    if old["fingerprint"] != manifest["fingerprint"]:
        raise InputError(
            f"{refuse}: the function/model fingerprint differs ({str(old['fingerprint'])[:16]} "
            f"there, {str(manifest['fingerprint'])[:16]} now), so the saved results may come "
            f"from another model{fix}"
        )
    if chunk_size is not None and chunk_size != old["chunk_size"]:
        raise InputError(
            f"{where} uses chunk_size={old['chunk_size']}, not {chunk_size}: leave chunk_size "
            "unset when resuming"
        )
    return old


def _lock_checkpoint(directory: Path) -> Any:
    """Create ``directory`` if needed and hold its lock file for this run.

    A second run on the same checkpoint (two ``--resume`` at once) is refused
    instead of computing the same chunks and reporting them "saved" in a
    folder the other run removes.  The lock is an ``flock`` on ``.lock``: the
    kernel releases it when this process ends, even by SIGKILL, so a killed
    run never blocks its resume.  Returns the open lock file (close it to
    release), or None where ``fcntl`` does not exist (Windows)."""
    if directory.exists() and not directory.is_dir():
        raise InputError(f"checkpoint {str(directory)!r} exists and is not a directory")
    try:
        directory.mkdir(parents=True, exist_ok=True)
        fh = open(directory / _LOCK, "a+")  # noqa: SIM115 - held for the whole run
    except OSError as exc:
        raise InputError(
            f"checkpoint directory {str(directory)!r} cannot be written ({exc.strerror or exc})"
        ) from None
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: no lock
        return fh
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        fh.seek(0)
        holder = fh.read().strip() or "another process"
        fh.close()
        raise InputError(
            f"checkpoint directory {str(directory)!r} is in use by a running sweep (pid {holder}); wait"
            " for it to finish, or stop it, before resuming"
        ) from None
    fh.seek(0)
    fh.truncate()
    fh.write(str(os.getpid()))
    fh.flush()
    # we hold the lock: scratch folders and temporary files here are a dead run's
    for p in directory.iterdir():
        if p.name.startswith(_SCRATCH) and p.is_dir():
            shutil.rmtree(p, ignore_errors=True)
        elif p.name.startswith(".") and ".tmp-" in p.name:
            p.unlink(missing_ok=True)
    return fh


def _grid_diff(a: Grid, b: Grid) -> str:
    if a.names != b.names:
        return f" (axes {list(a.names)} vs {list(b.names)})"
    for x, y in zip(a.axes, b.axes, strict=True):
        if x != y:
            return f" (axis {x.name!r} differs)"
    return ""


def _write_json(path: Path, obj: Any) -> None:
    with atomic_write(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=1), encoding="utf-8")


def _chunk_path(directory: Path, chunk: int) -> Path:
    return directory / f"chunk_{chunk:06d}.npz"


def _save_chunk(directory: Path, out: _ChunkOut, stop: int) -> None:
    with atomic_write(_chunk_path(directory, out.chunk)) as tmp:
        with open(tmp, "xb") as fh:
            np.savez(
                fh,
                start=np.int64(out.start),
                stop=np.int64(stop),
                values=out.values,
                failed_index=np.asarray(out.failed_index, dtype=np.int64),
                failed_type=np.asarray(out.failed_type, dtype=np.str_).reshape(-1),
                failed_message=np.asarray(out.failed_message, dtype=np.str_).reshape(-1),
            )


def _load_chunks(
    directory: Path,
    n_chunks: int,
    bounds: Callable[[int], tuple[int, int]],
    n_out: int,
    retry_failed: bool,
) -> Iterator[_ChunkOut]:
    """Yield the valid finished chunks of a checkpoint (and clean stale temp files)."""
    for p in sorted(directory.iterdir()):
        m = _CHUNK_RE.match(p.name)
        if not m:
            continue
        c = int(m[1])
        if c >= n_chunks:
            continue
        s, e = bounds(c)
        try:
            with np.load(p, allow_pickle=False) as z:
                out = _ChunkOut(
                    c,
                    int(z["start"]),
                    np.array(z["values"], dtype=np.float64),
                    z["failed_index"].tolist(),
                    z["failed_type"].tolist(),
                    z["failed_message"].tolist(),
                    None,
                )
                ok = (int(z["start"]), int(z["stop"])) == (s, e) and out.values.shape == (n_out, e - s)
        except Exception as exc:  # noqa: BLE001 - a damaged chunk is recomputed
            warnings.warn(f"checkpoint chunk {p.name} is unreadable ({exc}); recomputing it", stacklevel=3)
            continue
        if not ok:
            warnings.warn(f"checkpoint chunk {p.name} does not match the grid; recomputing it", stacklevel=3)
            continue
        if retry_failed and out.failed_index:
            continue
        yield out


# =========================================================================== progress


class _Progress:
    """tqdm on a terminal (a plain bar without tqdm), a line per ~10 % otherwise."""

    def __init__(self, total: int, initial: int, enabled: bool, desc: str) -> None:
        self.total, self.n, self.desc = total, initial, desc
        self.mode = "off"
        self._bar: Any = None
        self._t0 = time.monotonic()
        self._last = 0.0
        self._next_decile = 1 + (10 * initial) // max(total, 1)
        if not enabled or total <= 0:
            return
        stream = sys.stderr
        tty = bool(getattr(stream, "isatty", lambda: False)())
        if tty:
            try:
                from tqdm import tqdm

                self._bar = tqdm(
                    total=total,
                    initial=initial,
                    unit="pt",
                    desc=desc,
                    file=stream,
                    dynamic_ncols=True,
                    mininterval=0.2,
                )
                self.mode = "tqdm"
            except ImportError:
                self.mode = "bar"
        else:
            self.mode = "lines"

    def note(self, text: str) -> None:
        if self.mode == "lines":
            print(f"{self.desc}: {text}", file=sys.stderr, flush=True)
        elif self.mode == "tqdm":
            self._bar.write(f"{self.desc}: {text}", file=sys.stderr)
        elif self.mode == "bar":
            print(f"\r{self.desc}: {text}", file=sys.stderr, flush=True)

    def update(self, k: int) -> None:
        self.n += k
        if self.mode == "tqdm":
            self._bar.update(k)
        elif self.mode == "bar":
            now = time.monotonic()
            if now - self._last >= 0.2 or self.n >= self.total:
                self._last = now
                frac = self.n / self.total
                bar = "#" * int(30 * frac) + "-" * (30 - int(30 * frac))
                print(
                    f"\r{self.desc}: [{bar}] {100 * frac:5.1f}% {self.n}/{self.total} {now - self._t0:.1f} s",
                    end="",
                    file=sys.stderr,
                    flush=True,
                )
        elif self.mode == "lines":
            decile = (10 * self.n) // self.total
            if decile >= self._next_decile:
                self._next_decile = decile + 1
                el = time.monotonic() - self._t0
                print(
                    f"{self.desc}: {10 * decile:3d}% ({self.n}/{self.total} points, {el:.1f} s)",
                    file=sys.stderr,
                    flush=True,
                )

    def close(self) -> None:
        if self.mode == "tqdm":
            self._bar.close()
        elif self.mode == "bar":
            print(file=sys.stderr, flush=True)
        self.mode = "off"


# =========================================================================== sweep


def _auto_fingerprint(func: Callable[..., Any]) -> str:
    """A hash of the function's identity and of the data bound to it (best effort).

    Covers the module and qualified name, the bytecode and simple constants,
    ``functools.partial`` arguments, the instance of a bound method, closure
    cells and defaults, or the object itself for a callable instance.  Bound
    data are hashed through pickle (their ``repr``, with memory addresses
    removed, when they do not pickle).
    """

    def blob(obj: Any) -> bytes:
        try:
            return pickle.dumps(obj, protocol=4)
        except Exception:  # noqa: BLE001 - unpicklable: fall back to the repr
            return re.sub(r"0x[0-9a-fA-F]+", "0x?", repr(obj)).encode()

    h = hashlib.sha256()
    f: Any = func
    while isinstance(f, functools.partial):
        h.update(b"partial:" + blob((f.args, sorted(f.keywords.items()))))
        f = f.func
    ident = f"{getattr(f, '__module__', '')}.{getattr(f, '__qualname__', type(f).__qualname__)}"
    h.update(ident.encode())
    owner = getattr(f, "__self__", None)
    if owner is not None and not isinstance(owner, type(sys)):
        h.update(b"self:" + blob(owner))  # a bound method: the model instance matters
    code = getattr(f, "__code__", None)
    if code is not None:
        h.update(code.co_code)
        simple = [c for c in code.co_consts if isinstance(c, int | float | str | bytes | None)]
        h.update(repr(simple).encode())
        cells = getattr(f, "__closure__", None) or ()
        bound = []
        for cell in cells:
            try:
                bound.append(cell.cell_contents)
            except ValueError:  # an empty cell
                bound.append(None)
        h.update(
            b"bound:" + blob((bound, getattr(f, "__defaults__", None), getattr(f, "__kwdefaults__", None)))
        )
    elif owner is None and not isinstance(f, type):
        h.update(blob(f))  # a callable object, e.g. a frozen model with __call__
    return h.hexdigest()


def _normalise_outputs(
    outputs: Mapping[str, str | tuple[str, str]] | Iterable[str], grid: Grid
) -> tuple[tuple[str, ...], dict[str, str], dict[str, str]]:
    if isinstance(outputs, str):
        raise InputError("outputs must be a mapping name -> unit, e.g. {'freq': 'Hz'}")
    items = outputs.items() if isinstance(outputs, Mapping) else ((n, "") for n in outputs)
    names: list[str] = []
    units: dict[str, str] = {}
    longs: dict[str, str] = {}
    for name, spec in items:
        if not isinstance(name, str) or not (name.isidentifier() and name.isascii()):
            raise InputError(f"output name {name!r} must be an ASCII identifier")
        if name in grid.names:
            raise InputError(f"output {name!r} has the same name as a grid axis")
        if name == STATUS_VARIABLE:
            raise InputError(f"output name {name!r} is reserved for the per-point status")
        if isinstance(spec, tuple) and 1 <= len(spec) <= 2:
            unit, long_name = spec[0], spec[1] if len(spec) == 2 else ""
        else:
            unit, long_name = spec, ""
        if not isinstance(unit, str) or not isinstance(long_name, str):
            raise InputError(f"output {name!r}: expected a unit string or (unit, long_name)")
        names.append(name)
        units[name] = unit
        longs[name] = long_name or name
    if not names:
        raise InputError("outputs is empty: declare at least one output, e.g. {'freq': 'Hz'}")
    return tuple(names), units, longs


def _default_chunk_size(size: int, jobs: int) -> int:
    return max(1, min(_MAX_CHUNK, math.ceil(size / (_CHUNKS_PER_JOB * max(jobs, 1)))))


def sweep(
    func: Callable[..., Mapping[str, Any]],
    grid: Grid | Mapping[str, Any],
    *,
    outputs: Mapping[str, str | tuple[str, str]],
    jobs: int = 2,
    backend: Backend = "loky",
    scheduler: Any = None,
    chunk_size: int | None = None,
    checkpoint: str | os.PathLike[str] | None = None,
    resume: bool = False,
    fingerprint: str | None = None,
    on_error: Literal["nan", "raise"] = "nan",
    retry_failed: bool = False,
    out: str | os.PathLike[str] | None = None,
    progress: bool = True,
    attrs: Mapping[str, Any] | None = None,
    connect_timeout: float = 10.0,
    keep_checkpoint: bool = True,
    security: Any = None,
) -> SweepResult:
    """Evaluate ``func(**point)`` at every point of ``grid``.

    Parameters
    ----------
    func : callable
        ``func(**point) -> {output: float}``; a pure function of the grid
        point (e.g. a :func:`functools.partial` carrying a frozen model).  It
        must return exactly the keys of ``outputs``, else :class:`SweepError`
        naming the point.  For the process backends it must be picklable.
    grid : Grid or mapping
        The points; a mapping is passed to :class:`Grid`.
    outputs : mapping
        ``name -> unit`` (or ``name -> (unit, long_name)``), e.g.
        ``{"abscissa": "1/s", "freq": "Hz"}``.
    jobs : int, default 2
        Worker processes (loky; the local dask cluster).  ``-1``: all CPUs.
    backend : {"loky", "serial", "dask"}, default "loky"
        ``"serial"`` runs in this process; ``"dask"`` uses
        :class:`distributed.Client` on ``scheduler`` (or a local cluster of
        ``jobs`` single-threaded worker processes when it is None).
    scheduler : str or distributed.Client, optional
        Dask scheduler address (``"tcp://host:8786"``) or an existing client.
    chunk_size : int, optional
        Tasks per chunk (dispatch and checkpoint unit).  Default: about
        ``32 * jobs`` chunks, at most 4096 tasks each.  Fixed by the
        checkpoint when resuming.
    checkpoint : path-like, optional
        Directory where each finished chunk is saved atomically, with a
        ``manifest.json``.  Must be empty or absent unless ``resume``.
    resume : bool, default False
        Continue the sweep saved in ``checkpoint``: load its finished chunks
        and compute only the missing ones.  Refused (InputError) if the
        checkpoint was written for another grid, outputs or fingerprint.
    fingerprint : str, optional
        Identity of the function and its model (e.g. a hash of the model
        file), stored in the manifest and compared on resume.  Default: a hash
        of the function's module, name, bytecode and ``partial`` arguments,
        which is best effort -- pass your own to be safe.
    on_error : {"nan", "raise"}, default "nan"
        ``"nan"``: a task that raises gets NaN outputs, is recorded in
        ``failures`` and makes the status ``"partial"``.  ``"raise"``: raise
        :class:`SweepError` naming the grid point (finished chunks are
        already on disk).
    retry_failed : bool, default False
        On resume, recompute the saved chunks that contain failures.
    out : path-like, optional
        netCDF file to stream the results to: the arrays are filled as
        ``np.memmap`` files, the netCDF is written atomically at the end, and
        ``SweepResult.data`` are memory maps of it.  Not written when the
        sweep is interrupted or raises.
    progress : bool, default True
        Progress on stderr: a bar on a terminal (tqdm if installed), a line
        per 10 % otherwise.
    attrs : mapping, optional
        Attributes for the result and its files (e.g. the model text).
    connect_timeout : float, default 10
        Seconds to wait for a dask scheduler (and its first worker).
    keep_checkpoint : bool, default True
        False: remove the checkpoint directory after a complete run (status
        ``"ok"``), while this run still holds its lock.
    security : distributed.Security, optional
        TLS settings for a remote dask ``scheduler`` (``"tls://host:8786"``):
        CA, client certificate and key.  A scheduler can run any code as the
        user who submits to it: use only a scheduler you trust.

    Returns
    -------
    SweepResult

    Raises
    ------
    chatterlab.errors.InputError
        Invalid arguments, or a checkpoint that does not match.
    chatterlab.errors.SweepError
        A broken output contract, ``on_error="raise"`` and a failing task, an
        unreachable dask scheduler, or a crashed worker.
    SweepInterrupted
        On Ctrl-C (a :class:`KeyboardInterrupt`), after saving the finished
        chunks; the message says how many are done and how to resume.
    """
    t0 = time.perf_counter()
    if not callable(func):
        raise InputError(f"func must be callable (got {type(func).__name__})")
    if not isinstance(grid, Grid):
        grid = Grid(grid)
    out_names, units, long_names = _normalise_outputs(outputs, grid)
    if backend not in ("loky", "serial", "dask"):
        raise InputError(f"backend must be 'loky', 'serial' or 'dask' (got {backend!r})")
    if isinstance(jobs, bool) or not isinstance(jobs, int) or not (jobs >= 1 or jobs == -1):
        raise InputError(f"jobs must be a positive integer or -1 for all CPUs (got {jobs!r})")
    if jobs == -1:
        jobs = os.cpu_count() or 1
    if on_error not in ("nan", "raise"):
        raise InputError(f"on_error must be 'nan' or 'raise' (got {on_error!r})")
    if chunk_size is not None and (
        isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1
    ):
        raise InputError(f"chunk_size must be a positive integer (got {chunk_size!r})")
    if resume and checkpoint is None:
        raise InputError("resume=True needs checkpoint=DIR (the directory of the interrupted sweep)")
    if security is not None and backend != "dask":
        raise InputError(f"security= is only used with backend='dask' (backend is {backend!r})")
    if scheduler is not None and backend != "dask":
        raise InputError(f"scheduler= is only used with backend='dask' (backend is {backend!r})")
    if not (isinstance(connect_timeout, int | float) and connect_timeout > 0):
        raise InputError(f"connect_timeout must be > 0 seconds (got {connect_timeout!r})")
    user_attrs = dict(attrs or {})
    if out is not None:
        check_attrs(user_attrs)  # fail now, not after the computation

    # --- checkpoint: locked for this run; decides the chunk size when resuming
    ckpt_dir = Path(checkpoint) if checkpoint is not None else None
    created = ckpt_dir is not None and not ckpt_dir.exists()
    lock = _lock_checkpoint(ckpt_dir) if ckpt_dir is not None else None
    try:
        return _sweep_locked(
            func, grid, out_names, units, long_names, jobs, backend, scheduler, chunk_size, ckpt_dir, resume,
            fingerprint, on_error, retry_failed, out, progress, user_attrs, float(connect_timeout),
            keep_checkpoint, security, t0,
        )  # fmt: skip
    except Exception:
        # a run that failed before saving any chunk leaves no checkpoint it created
        if created and ckpt_dir is not None and not any(_CHUNK_RE.match(p.name) for p in ckpt_dir.iterdir()):
            shutil.rmtree(ckpt_dir, ignore_errors=True)
        raise
    finally:
        if lock is not None:
            lock.close()


def _sweep_locked(
    func: Callable[..., Mapping[str, Any]],
    grid: Grid,
    out_names: tuple[str, ...],
    units: dict[str, str],
    long_names: dict[str, str],
    jobs: int,
    backend: str,
    scheduler: Any,
    chunk_size: int | None,
    ckpt_dir: Path | None,
    resume: bool,
    fingerprint: str | None,
    on_error: str,
    retry_failed: bool,
    out: str | os.PathLike[str] | None,
    progress: bool,
    user_attrs: dict[str, Any],
    connect_timeout: float,
    keep_checkpoint: bool,
    security: Any,
    t0: float,
) -> SweepResult:
    """The body of :func:`sweep`, run while the checkpoint's lock is held."""
    size = grid.size
    if ckpt_dir is not None:
        manifest: dict[str, Any] = {
            "format": _CHECKPOINT_FORMAT,
            "version": _CHECKPOINT_VERSION,
            "grid": grid.to_json(),
            "outputs": units,
            "chunk_size": chunk_size or _default_chunk_size(size, jobs),
            "n_tasks": size,
            "fingerprint": fingerprint if fingerprint is not None else _auto_fingerprint(func),
            "fingerprint_source": "caller" if fingerprint is not None else "auto",
        }
        manifest = _open_checkpoint(ckpt_dir, manifest, resume, chunk_size)
        cs = int(manifest["chunk_size"])
    else:
        cs = chunk_size or _default_chunk_size(size, jobs)
    n_chunks = math.ceil(size / cs)

    def bounds(c: int) -> tuple[int, int]:
        return c * cs, min((c + 1) * cs, size)

    # --- storage: plain arrays, or memmaps when streaming to a file
    scratch: Path | None = None
    data: dict[str, np.ndarray]
    task_status: np.ndarray
    out_path = Path(out) if out is not None else None
    if out_path is not None:
        if out_path.is_dir():
            raise InputError(f"out={str(out_path)!r} is a directory; give a .nc file path")
        out_path.parent.mkdir(parents=True, exist_ok=True)
        if ckpt_dir is not None:  # cleaned by the next run that takes the lock
            scratch = Path(tempfile.mkdtemp(prefix=f"{_SCRATCH}{os.getpid()}-", dir=ckpt_dir))
        else:  # named after this process: a later run removes it once the process is gone
            clean_stale(out_path, tags=("sweep",))
            scratch = Path(
                tempfile.mkdtemp(prefix=f".{out_path.name}.sweep-{os.getpid()}-", dir=out_path.parent)
            )
        data = {
            o: np.lib.format.open_memmap(scratch / f"{o}.npy", mode="w+", dtype=np.float64, shape=grid.shape)
            for o in out_names
        }
        task_status = np.lib.format.open_memmap(
            scratch / f"{STATUS_VARIABLE}.npy", mode="w+", dtype=np.int32, shape=grid.shape
        )
    else:
        data = {o: np.full(grid.shape, np.nan) for o in out_names}
        task_status = np.zeros(grid.shape, dtype=np.int32)
    flat = [data[o].reshape(-1) for o in out_names]
    flat_status = task_status.reshape(-1)
    reason_code: dict[str, int] = {}  # reason -> provisional code (order of arrival)
    reason_first: dict[str, int] = {}  # reason -> first task index (for a run-independent order)

    failures: list[tuple[int, str, str]] = []  # heap of the lowest-index failures (negated)
    n_failed = 0

    def record(res: _ChunkOut) -> None:
        nonlocal n_failed
        s = res.start
        for j, arr in enumerate(flat):
            arr[s : s + res.values.shape[1]] = res.values[j]
        for i, t, m in zip(res.failed_index, res.failed_type, res.failed_message, strict=True):
            reason = f"{t}: {m}"
            if reason not in reason_code and len(reason_code) >= _MAX_REASONS:
                reason = _OTHER_REASON
            code = reason_code.setdefault(reason, len(reason_code) + 1)
            reason_first[reason] = min(reason_first.get(reason, int(i)), int(i))
            flat_status[int(i)] = code
            n_failed += 1
            item = (-int(i), str(t), str(m))
            if len(failures) < _KEEP_FAILURES:
                heapq.heappush(failures, item)
            elif item > failures[0]:
                heapq.heapreplace(failures, item)

    try:
        done: set[int] = set()
        n_resumed = 0
        if ckpt_dir is not None and resume:
            for res in _load_chunks(ckpt_dir, n_chunks, bounds, len(out_names), retry_failed):
                record(res)
                done.add(res.chunk)
                n_resumed += res.values.shape[1]
        pending = ((c, *bounds(c)) for c in range(n_chunks) if c not in done)

        payload = _Payload(func, grid.names, tuple(a.values for a in grid.axes), grid.shape, out_names)
        bar = _Progress(size, n_resumed, progress, "sweep")
        workers = {
            "serial": "1 process",
            "loky": f"{jobs} loky workers",
            "dask": "dask" if scheduler is None else f"dask at {scheduler}",
        }[backend]
        bar.note(
            f"{size} points in {n_chunks} chunks of {cs}, {workers}"
            + (f", {len(done)} chunks from checkpoint" if done else "")
        )
        runner: Generator[_ChunkOut, None, None]
        if backend == "serial":
            runner = _serial_runner(payload, pending)
        elif backend == "loky":
            runner = _loky_runner(payload, pending, jobs)
        else:
            runner = _dask_runner(payload, pending, jobs, scheduler, connect_timeout, security)

        n_done = len(done)
        n_computed = 0

        def where(counts: bool = True) -> str:
            if ckpt_dir is None:
                return (
                    "no checkpoint was given, so nothing is kept: pass checkpoint=DIR "
                    "(CLI: --checkpoint DIR) to be able to resume"
                )
            if not (ckpt_dir / _MANIFEST).is_file():
                return f"the checkpoint directory {str(ckpt_dir)!r} was removed meanwhile, so nothing is kept"
            done = f"{n_done} of {n_chunks} chunks " if counts else ""
            return (
                f"{done}saved in {str(ckpt_dir)!r}; run again with resume=True (CLI: --resume) "
                f"to compute only the {n_chunks - n_done} missing ones"
            )

        try:
            for res in runner:
                if res.contract is not None:
                    raise SweepError(f"{res.contract}; {where()}")
                s, e = bounds(res.chunk)
                if on_error == "raise" and res.failed_index:
                    k = int(np.argmin(res.failed_index))
                    i = res.failed_index[k]
                    raise SweepError(
                        f"task {i} failed at {grid.format_point(grid.point(i))}: "
                        f"{res.failed_type[k]}: {res.failed_message[k]}; {where()}"
                    )
                record(res)
                if ckpt_dir is not None:
                    _save_chunk(ckpt_dir, res, e)
                n_done += 1
                n_computed += e - s
                bar.update(e - s)
        except KeyboardInterrupt:
            bar.close()
            msg = (
                f"sweep interrupted: {n_done} of {n_chunks} chunks done "
                f"({n_resumed + n_computed} of {size} points); {where(counts=False)}"
            )
            raise SweepInterrupted(
                msg, done=n_done, total=n_chunks, checkpoint=None if ckpt_dir is None else str(ckpt_dir)
            ) from None
        except (SweepError, InputError):
            raise
        except Exception as exc:
            hint = ""
            if backend != "serial" and "pickl" in f"{type(exc).__name__} {exc}".lower():
                hint = " (the process backends need a picklable func; try backend='serial')"
            raise SweepError(
                f"the {backend} backend failed ({type(exc).__name__}: {exc}){hint}; {where()}"
            ) from exc
        finally:
            runner.close()
            bar.close()

        # --- summary
        fails = sorted(
            (TaskFailure(grid.point(-i), t, m, -i) for i, t, m in failures), key=lambda f: f.task_index
        )
        if fails and on_error == "raise":  # failures loaded from the checkpoint
            raise SweepError(
                f"{n_failed} task(s) failed (saved in the checkpoint), the first "
                f"{fails[0].describe(grid)}; pass retry_failed=True to recompute them"
            )
        if fails:
            status = "partial"
            message = (
                f"{n_failed} of {size} tasks failed (their outputs are NaN); the first "
                f"{fails[0].describe(grid)}"
            )
        else:
            status = "ok"
            message = f"all {size} tasks succeeded"  # run-independent: files of resumed runs match
        # reasons in the order of their first grid point: the same file whatever the
        # order in which chunks finished (workers, resume)
        order = sorted(reason_code, key=lambda r: (reason_first[r], r))
        if order:
            remap = np.zeros(len(reason_code) + 1, dtype=np.int32)
            for new, r in enumerate(order, start=1):
                remap[reason_code[r]] = new
            for start in range(0, flat_status.size, 1 << 20):
                flat_status[start : start + (1 << 20)] = remap[flat_status[start : start + (1 << 20)]]
        common: dict[str, Any] = dict(
            grid=grid,
            reasons=tuple(order),
            units=units,
            status=status,
            message=message,
            failures=tuple(fails),
            attrs=user_attrs,
            long_names=long_names,
            n_computed=n_computed,
            n_resumed=n_resumed,
            n_failed=n_failed,
        )
        if out_path is not None:
            SweepResult(data=data, task_status=task_status, **common).to_netcdf(out_path)
            del flat, data, flat_status, task_status  # drop the scratch memmaps
            stored = read_netcdf(out_path, mmap=True)
            data = {o: stored.data[o][0] for o in out_names}
            task_status = stored.data[STATUS_VARIABLE][0]
        else:
            for arr in data.values():
                arr.flags.writeable = False
            task_status.flags.writeable = False
        if ckpt_dir is not None and status == "ok" and not keep_checkpoint:
            shutil.rmtree(ckpt_dir, ignore_errors=True)  # still under our lock
            scratch = None
        return SweepResult(data=data, task_status=task_status, elapsed=time.perf_counter() - t0, **common)
    finally:
        if scratch is not None:
            shutil.rmtree(scratch, ignore_errors=True)
