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
  The engine never removes a checkpoint before the results are stored: it
  writes ``out=`` first, and by default keeps the directory for the caller to
  remove (``SweepResult.discard_checkpoint``) once its own files are in
  place, so a kill at any moment leaves the finished chunks or the output.
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
The checkpoint is kept after a complete run: remove it with
``res.discard_checkpoint()`` once the results are stored (the command line
does so after moving its output files into place), or pass
``keep_checkpoint=False`` to have the engine remove it after writing ``out=``.
"""

from __future__ import annotations

import math
import os
import shutil
import time
from collections.abc import Callable, Generator, Iterable, Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np

from chatterlab._version import __version__
from chatterlab.errors import InputError, SweepError
from chatterlab.io._netcdf import check_attrs

from .._progress import Progress
from ._backends import _ChunkOut, _dask_runner, _loky_runner, _Payload, _serial_runner
from ._checkpoint import (
    _CHECKPOINT_FORMAT,
    _CHECKPOINT_VERSION,
    _CHUNK_RE,
    _FINGERPRINT_METHOD,
    _MANIFEST,
    _auto_fingerprint,
    _caller_fingerprint,
    _load_chunks,
    _lock_checkpoint,
    _open_checkpoint,
    _save_chunk,
)
from ._grid import MAX_TASKS, Axis, Grid
from ._result import STATUS_VARIABLE, SweepInterrupted, SweepResult, TaskFailure
from ._store import _Store

__all__ = [
    "Axis",
    "Grid",
    "SweepInterrupted",
    "SweepResult",
    "TaskFailure",
    "sweep",
]

Backend = Literal["loky", "serial", "dask"]

_MAX_CHUNK = 4096
_CHUNKS_PER_JOB = 32


# =========================================================================== sweep


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


def max_jobs() -> int:
    """The most worker processes a sweep starts: 4 per core (at least 4)."""
    return max(4, 4 * (os.cpu_count() or 1))


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
    fingerprint: str | Mapping[str, Any] | None = None,
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
        Processes that compute (loky: this one and ``jobs - 1`` worker
        processes, this one computing whenever no worker's result waits; the
        local dask cluster: ``jobs`` workers).  ``-1``: all CPUs.
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
    fingerprint : str or mapping, optional
        Identity of the function and its model (e.g. a hash of the model
        file), stored in the manifest and compared on resume.  A mapping
        ``{name: value}`` (e.g. ``{"model": hash, "--terms": "pdo"}``) lets a
        refused resume name the entry that changed.  Default: a
        :func:`joblib.hash` of the function's module, name, source code and
        bound data (``partial`` arguments, closure, instance), which is best
        effort -- pass your own to be safe.
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
        Progress on stderr: a tqdm bar on a terminal; elsewhere (a log file,
        a pipe) a line naming the work and one line at the end.
    attrs : mapping, optional
        Attributes for the result and its files (e.g. the model text).
    connect_timeout : float, default 10
        Seconds to wait for a dask scheduler (and its first worker).
    keep_checkpoint : bool, default True
        True: the checkpoint directory stays, complete, after the run; the
        result names it (``SweepResult.checkpoint``) and
        :meth:`SweepResult.discard_checkpoint` removes it once the caller
        has stored the results where it wants them (a kill before that
        loses nothing: ``resume=True`` on the complete checkpoint computes
        no task).  False: remove it after a complete run (status ``"ok"``),
        while this run still holds its lock -- after ``out=`` is written,
        so with ``out=`` nothing is ever lost; without ``out=`` the results
        are then only in memory.
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
    if grid.size > MAX_TASKS:
        dims = " x ".join(str(n) for n in grid.shape)
        raise InputError(
            f"the grid has {dims} = {grid.size} points, more than the largest sweep accepted, {MAX_TASKS}"
            " points (a task costs milliseconds to seconds): sweep a coarser grid, or in parts"
        )
    out_names, units, long_names = _normalise_outputs(outputs, grid)
    if backend not in ("loky", "serial", "dask"):
        raise InputError(f"backend must be 'loky', 'serial' or 'dask' (got {backend!r})")
    if isinstance(jobs, bool) or not isinstance(jobs, int) or not (jobs >= 1 or jobs == -1):
        raise InputError(f"jobs must be a positive integer or -1 for all CPUs (got {jobs!r})")
    if jobs == -1:
        jobs = os.cpu_count() or 1
    if jobs > max_jobs():
        raise InputError(
            f"jobs={jobs} is more than the largest accepted here, {max_jobs()} (4 per core of this machine's"
            f" {os.cpu_count() or 1}): more workers only share the cores, each with its own memory"
        )
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
    if fingerprint is not None:
        _caller_fingerprint(fingerprint)  # a string or a mapping
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
    fingerprint: str | Mapping[str, Any] | None,
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
    cs = _chunk_size(func, grid, units, jobs, chunk_size, ckpt_dir, resume, fingerprint)
    n_chunks = math.ceil(size / cs)

    def bounds(c: int) -> tuple[int, int]:
        return c * cs, min((c + 1) * cs, size)

    store = _Store(grid, out_names, Path(out) if out is not None else None, ckpt_dir)
    try:
        done: set[int] = set()
        n_resumed = 0
        if ckpt_dir is not None and resume:
            for res in _load_chunks(ckpt_dir, n_chunks, bounds, len(out_names), retry_failed):
                store.record(res)
                done.add(res.chunk)
                n_resumed += res.values.shape[1]
        pending = ((c, *bounds(c)) for c in range(n_chunks) if c not in done)

        payload = _Payload(func, grid.names, tuple(a.values for a in grid.axes), grid.shape, out_names)
        bar = Progress(size, n_resumed, progress, "sweep")
        workers = {
            "serial": "1 process",
            "loky": f"{jobs} processes (this one and {jobs - 1} loky worker{'s' if jobs > 2 else ''})"
            if jobs > 1
            else "1 process",
            "dask": "dask" if scheduler is None else f"dask at {scheduler}",
        }[backend]
        bar.note(
            f"{size} points in {n_chunks} chunks of {cs}, {workers}"
            + (f", {len(done)} chunks from checkpoint" if done else "")
        )
        runner: Generator[_ChunkOut, None, None]
        if len(done) == n_chunks:  # a finished checkpoint (its output was not written): no workers
            runner = _serial_runner(payload, iter(()))
        elif backend == "serial":
            runner = _serial_runner(payload, pending)
        elif backend == "loky":
            runner = _loky_runner(payload, pending, jobs)
        else:
            runner = _dask_runner(payload, pending, jobs, scheduler, connect_timeout, security)
        n_computed = _collect(
            runner, store, bar, grid, bounds, n_chunks, len(done), n_resumed, ckpt_dir, on_error, backend
        )
        fails = store.failures()
        if fails and on_error == "raise":  # failures loaded from the checkpoint
            raise SweepError(
                f"{store.n_failed} task(s) failed (saved in the checkpoint), the first "
                f"{fails[0].describe(grid)}; pass retry_failed=True to recompute them"
            )
        if fails:
            status = "partial"
            message = (
                f"{store.n_failed} of {size} tasks failed (their outputs are NaN); the first "
                f"{fails[0].describe(grid)}"
            )
        else:
            status = "ok"
            message = f"all {size} tasks succeeded"  # run-independent: files of resumed runs match
        common: dict[str, Any] = dict(
            grid=grid,
            reasons=store.reasons(),
            units=units,
            status=status,
            message=message,
            failures=tuple(fails),
            attrs=user_attrs,
            long_names=long_names,
            n_computed=n_computed,
            n_resumed=n_resumed,
            n_failed=store.n_failed,
        )
        data, task_status = store.finish(common)  # out= is written (atomically) before anything is removed
        kept = ckpt_dir
        if ckpt_dir is not None and status == "ok" and not keep_checkpoint:
            shutil.rmtree(ckpt_dir, ignore_errors=True)  # still under our lock
            store.scratch = None
            kept = None
        return SweepResult(
            data=data,
            task_status=task_status,
            elapsed=time.perf_counter() - t0,
            checkpoint=None if kept is None else str(kept),
            **common,
        )
    finally:
        if store.scratch is not None:
            shutil.rmtree(store.scratch, ignore_errors=True)


def _chunk_size(
    func: Callable[..., Mapping[str, Any]],
    grid: Grid,
    units: dict[str, str],
    jobs: int,
    chunk_size: int | None,
    ckpt_dir: Path | None,
    resume: bool,
    fingerprint: str | Mapping[str, Any] | None,
) -> int:
    """Tasks per chunk: the caller's, the default, or the checkpoint's when
    resuming (the checkpoint is created or checked here)."""
    size = grid.size
    if ckpt_dir is None:
        return chunk_size or _default_chunk_size(size, jobs)
    manifest: dict[str, Any] = {
        "format": _CHECKPOINT_FORMAT,
        "version": _CHECKPOINT_VERSION,
        "grid": grid.to_json(),
        "outputs": units,
        "chunk_size": chunk_size or _default_chunk_size(size, jobs),
        "n_tasks": size,
        "chatterlab": __version__,
        "fingerprint": _caller_fingerprint(fingerprint)
        if fingerprint is not None
        else _auto_fingerprint(func),
        "fingerprint_source": "caller" if fingerprint is not None else "auto",
    }
    if fingerprint is None:
        manifest["fingerprint_method"] = _FINGERPRINT_METHOD
    manifest = _open_checkpoint(ckpt_dir, manifest, resume, chunk_size)
    return int(manifest["chunk_size"])


def _collect(
    runner: Generator[_ChunkOut, None, None],
    store: _Store,
    bar: Progress,
    grid: Grid,
    bounds: Callable[[int], tuple[int, int]],
    n_chunks: int,
    n_done: int,
    n_resumed: int,
    ckpt_dir: Path | None,
    on_error: str,
    backend: str,
) -> int:
    """Take the chunks from the runner into the store (and the checkpoint);
    returns the points computed.  An interrupt, a broken contract, a failing
    task with ``on_error="raise"`` or a failing backend says what is kept."""
    size = grid.size
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
            store.record(res)
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
    return n_computed
