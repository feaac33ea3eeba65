"""The result of a sweep: :class:`SweepResult` (arrays shaped like the grid, per-point
status, failures), its files, and :class:`TaskFailure` / :class:`SweepInterrupted`."""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from chatterlab.io import LabelledData, Result, read_netcdf, write_csv

from ._grid import Grid

_FILE_FAILURES = 100  # failures written to the netCDF ``failures`` attribute
STATUS_VARIABLE = "task_status"  # per grid point: 0 ok, k > 0 failed for reasons[k - 1]


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
class SweepResult(Result):
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
    checkpoint : str or None
        The checkpoint directory this result's chunks are saved in, kept
        after the run (None: no checkpoint, or ``keep_checkpoint=False``
        removed it).  :meth:`discard_checkpoint` removes it once the results
        are stored.
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
    checkpoint: str | None = None

    @property
    def ok(self) -> bool:
        """True when every task succeeded."""
        return self.status == "ok"

    def discard_checkpoint(self) -> bool:
        """Remove the checkpoint directory of this result (:attr:`checkpoint`).

        Call it once the results are stored where they belong (a file moved
        into place): until then a killed process loses nothing, since
        ``resume=True`` on the complete checkpoint computes no task and gives
        the same result.  The checkpoint's lock is taken first, so a run that
        is using it meanwhile keeps it.  A ``"partial"`` result's checkpoint
        holds its failures (``retry_failed=True`` recomputes them): keep it
        if they may be retried.  Returns True when the directory was removed.
        """
        if self.checkpoint is None:
            return False
        from ._checkpoint import _remove_checkpoint

        return _remove_checkpoint(Path(self.checkpoint))

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

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """The result losslessly (:meth:`from_xarray` and :meth:`from_netcdf`
        give it back): grid axes as index coordinates (``units``), outputs as
        data variables (``units``, ``long_name``), the per-point
        ``task_status`` a data variable, and ``attrs`` plus the run status
        (``status``, ``message``, ``n_failed``, ``reasons`` and the first
        failures as JSON) global attributes -- all but the bookkeeping of
        this call (``n_computed``, ``n_resumed``, ``elapsed``; only the first
        100 failures are attributes).  Memory-mapped outputs stay memory
        maps until written; provenance is added to a file unless ``attrs``
        fixes it (e.g. ``attrs={"created": "..."}`` for reproducible bytes)."""
        return self.grid.coords, self._data_specs() | self._status_spec(), self.file_attrs()

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write a long-format CSV file: one row per grid point, header ``name [unit]``,
        then (when the task status is known) ``status`` (``ok``/``failed``) and
        ``reason`` (empty, or ``ErrorType: message``)."""
        coded = None
        if self.task_status is not None:
            coded = {
                "task_status": (self.task_status, ["ok"] + ["failed"] * len(self.reasons)),
                "reason": (self.task_status, ["", *self.reasons]),
            }
        out = write_csv(path, self.grid.coords, self._data_specs(), coded=coded)
        assert out is not None  # a path was given
        return out

    @classmethod
    def from_netcdf(cls, path: str | os.PathLike[str], *, mmap: bool = False) -> SweepResult:
        """Read a file written by :meth:`to_netcdf` (or by ``sweep(..., out=path)``;
        also the netCDF-3 files of chatterlab 0.1).  ``mmap=True``: the outputs
        are memory maps of the file (see :func:`chatterlab.io.read_netcdf`)."""
        return cls._from_labelled(read_netcdf(path, mmap=mmap))

    @classmethod
    def from_xarray(cls, ds: Any) -> SweepResult:
        """The result from a dataset made by :meth:`to_xarray` (or read from
        its file with :func:`chatterlab.io.read_dataset`)."""
        return cls._from_labelled(LabelledData.from_dataset(ds))

    @classmethod
    def _from_labelled(cls, f: LabelledData) -> SweepResult:
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

    # ------------------------------------------------------------------ plotting

    def plot(
        self,
        output: str | None = None,
        ax: Any = None,
        *,
        x: str | None = None,
        at: Mapping[str, float] | None = None,
    ) -> Any:
        """Plot one output: a line over a 1-D grid, a colour map over a 2-D grid.

        Parameters
        ----------
        output : str, optional
            The output to plot (default: the first).
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
        from ..plot import plot_sweep

        return plot_sweep(self, output if output is not None else next(iter(self.data)), ax=ax, x=x, at=at)
