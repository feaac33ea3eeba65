"""Where the results of a sweep go while it runs (:class:`_Store`)."""

from __future__ import annotations

import heapq
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from chatterlab.errors import InputError
from chatterlab.io._files import clean_stale
from chatterlab.io._netcdf import read_netcdf

from ._backends import _ChunkOut
from ._checkpoint import _SCRATCH
from ._grid import Grid
from ._result import STATUS_VARIABLE, SweepResult, TaskFailure

_KEEP_FAILURES = 1000  # failures kept in memory (all are counted and stored in chunks)
_MAX_REASONS = 1000  # distinct failure reasons kept per point (more share the last code)
_OTHER_REASON = f"other failure (more than {_MAX_REASONS} distinct reasons; see the failures attribute)"


class _Store:
    """Where the results of a sweep go: one float array per output and the
    per-point status codes (``np.memmap`` files in a scratch folder when
    streaming to ``out``), the failure reasons in order of arrival, and the
    lowest-index failures (a bounded heap)."""

    def __init__(self, grid: Grid, out_names: tuple[str, ...], out_path: Path | None, ckpt_dir: Path | None):
        self.grid = grid
        self.out_names = out_names
        self.out_path = out_path
        self.scratch: Path | None = None
        self.data: dict[str, np.ndarray]
        self.task_status: np.ndarray
        if out_path is not None:
            if out_path.is_dir():
                raise InputError(f"out={str(out_path)!r} is a directory; give a .nc file path")
            out_path.parent.mkdir(parents=True, exist_ok=True)
            if ckpt_dir is not None:  # cleaned by the next run that takes the lock
                self.scratch = Path(tempfile.mkdtemp(prefix=f"{_SCRATCH}{os.getpid()}-", dir=ckpt_dir))
            else:  # named after this process: a later run removes it once the process is gone
                clean_stale(out_path, tags=("sweep",))
                self.scratch = Path(
                    tempfile.mkdtemp(prefix=f".{out_path.name}.sweep-{os.getpid()}-", dir=out_path.parent)
                )
            scratch = self.scratch
            self.data = {
                o: np.lib.format.open_memmap(
                    scratch / f"{o}.npy", mode="w+", dtype=np.float64, shape=grid.shape
                )
                for o in out_names
            }
            self.task_status = np.lib.format.open_memmap(
                scratch / f"{STATUS_VARIABLE}.npy", mode="w+", dtype=np.int32, shape=grid.shape
            )
        else:
            self.data = {o: np.full(grid.shape, np.nan) for o in out_names}
            self.task_status = np.zeros(grid.shape, dtype=np.int32)
        self.flat = [self.data[o].reshape(-1) for o in out_names]
        self.flat_status = self.task_status.reshape(-1)
        self.reason_code: dict[str, int] = {}  # reason -> provisional code (order of arrival)
        self.reason_first: dict[str, int] = {}  # reason -> first task index (for a run-independent order)
        self.heap: list[tuple[int, str, str]] = []  # heap of the lowest-index failures (negated)
        self.n_failed = 0

    def record(self, res: _ChunkOut) -> None:
        """Place a chunk's values and failures."""
        s = res.start
        for j, arr in enumerate(self.flat):
            arr[s : s + res.values.shape[1]] = res.values[j]
        reason_code, failures = self.reason_code, self.heap
        for i, t, m in zip(res.failed_index, res.failed_type, res.failed_message, strict=True):
            reason = f"{t}: {m}"
            if reason not in reason_code and len(reason_code) >= _MAX_REASONS:
                reason = _OTHER_REASON
            code = reason_code.setdefault(reason, len(reason_code) + 1)
            self.reason_first[reason] = min(self.reason_first.get(reason, int(i)), int(i))
            self.flat_status[int(i)] = code
            self.n_failed += 1
            item = (-int(i), str(t), str(m))
            if len(failures) < _KEEP_FAILURES:
                heapq.heappush(failures, item)
            elif item > failures[0]:
                heapq.heapreplace(failures, item)

    def failures(self) -> list[TaskFailure]:
        """The kept failures, by task index."""
        grid = self.grid
        return sorted(
            (TaskFailure(grid.point(-i), t, m, -i) for i, t, m in self.heap), key=lambda f: f.task_index
        )

    def reasons(self) -> tuple[str, ...]:
        """The failure reasons in the order of their first grid point (the status
        codes renumbered to match): the same file whatever the order in which
        chunks finished (workers, resume)."""
        reason_code, flat_status = self.reason_code, self.flat_status
        order = sorted(reason_code, key=lambda r: (self.reason_first[r], r))
        if order:
            remap = np.zeros(len(reason_code) + 1, dtype=np.int32)
            for new, r in enumerate(order, start=1):
                remap[reason_code[r]] = new
            for start in range(0, flat_status.size, 1 << 20):
                flat_status[start : start + (1 << 20)] = remap[flat_status[start : start + (1 << 20)]]
        return tuple(order)

    def finish(self, common: dict[str, Any]) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """The final arrays: read-only in memory, or memory maps of the netCDF
        file written to ``out`` (the scratch memmaps dropped)."""
        if self.out_path is None:
            for arr in self.data.values():
                arr.flags.writeable = False
            self.task_status.flags.writeable = False
            return self.data, self.task_status
        SweepResult(data=self.data, task_status=self.task_status, **common).to_netcdf(self.out_path)
        del self.flat, self.data, self.flat_status, self.task_status  # drop the scratch memmaps
        stored = read_netcdf(self.out_path, mmap=True)
        return {o: stored.data[o][0] for o in self.out_names}, stored.data[STATUS_VARIABLE][0]
