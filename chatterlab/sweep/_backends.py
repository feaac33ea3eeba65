"""Running the chunks of a sweep: the worker side (:func:`_run_chunk`) and the
serial, loky and dask runners."""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
import warnings
from collections.abc import Callable, Generator, Iterator, Mapping
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

from chatterlab.errors import SweepError

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
    """Single-threaded BLAS/OpenMP in this process (a task may reach scipy
    only later: :func:`chatterlab._threads.one_blas_thread` loads it first)."""
    from .._threads import one_blas_thread

    return one_blas_thread(blas_only=False)


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
    idle timeout (5 minutes), holding the caller's stdout and stderr open.

    The worker also ignores SIGINT: Ctrl-C at a terminal reaches the whole
    foreground group, and a worker's own KeyboardInterrupt printed a
    traceback on the command's standard error; the sweep process handles
    the interrupt (saves, says how to resume) and stops its workers."""
    with contextlib.suppress(ValueError):  # not the main thread of the worker: leave it
        signal.signal(signal.SIGINT, signal.SIG_IGN)

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


#: the thread-count variables loky sets to 1 in its workers (joblib's list):
#: the calling process, when it computes chunks, shows its tasks the same
_THREAD_VARS = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMBA_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)


@contextmanager
def _worker_environment() -> Iterator[None]:
    """This process as one of the workers: one BLAS/OpenMP thread
    (:func:`_blas_limit`) and the thread-count variables a loky worker has,
    so that a task sees the same environment wherever it runs (restored
    afterwards)."""
    old = {v: os.environ.get(v) for v in _THREAD_VARS}
    os.environ.update(dict.fromkeys(_THREAD_VARS, "1"))
    try:
        with _blas_limit():
            yield
    finally:
        for v, val in old.items():
            if val is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = val


def _loky_runner(
    payload: _Payload, chunks: Iterator[tuple[int, int, int]], jobs: int
) -> Generator[_ChunkOut, None, None]:
    """``jobs`` processes compute the chunks: ``jobs - 1`` loky workers and
    this one.  This process has everything a task needs already imported
    and built (a worker pays its start-up -- the interpreter, numpy, scipy,
    chatterlab, the task's caches -- on its first chunk), and it would
    otherwise only wait: it computes a chunk whenever no worker's result is
    ready, while the workers keep two chunks each in flight.  Results are
    placed by chunk index, so where a chunk ran does not change a bit."""
    from concurrent.futures import FIRST_COMPLETED, Future, wait

    from joblib.externals.loky import ProcessPoolExecutor

    helpers = jobs - 1
    if helpers < 1:
        yield from _serial_runner(payload, chunks)
        return
    # the workers start with OMP/OPENBLAS/MKL/..._NUM_THREADS=1 (no BLAS
    # oversubscription) and watch this process, exiting when it dies (_watch_parent).
    # The sweep's own executor, not loky's process-wide reusable one: joblib's
    # Parallel (the milling diagram's speeds) reuses that singleton and finds it
    # without the memmapping state joblib gives the executors it makes
    # (AttributeError '_temp_folder_manager' after a sweep in the same process).
    executor = ProcessPoolExecutor(
        max_workers=helpers,
        timeout=300,
        initializer=_watch_parent,
        initargs=(os.getpid(),),
        env=dict.fromkeys(_THREAD_VARS, "1"),
    )
    futures: set[Future[_ChunkOut]] = set()
    exhausted = False
    clean = False

    def take() -> tuple[int, int, int] | None:
        nonlocal exhausted
        nxt = None if exhausted else next(chunks, None)
        exhausted = nxt is None
        return nxt

    def fill() -> None:
        while len(futures) < 2 * helpers:
            nxt = take()
            if nxt is None:
                return
            futures.add(executor.submit(_run_chunk, payload, *nxt))

    try:
        with _worker_environment():
            with _sigint_ignored():  # the workers start here and inherit SIG_IGN: no traceback of
                fill()  # a Ctrl-C that lands while one imports, before its initializer runs
            while True:
                ready = [f for f in futures if f.done()]
                if ready:
                    for f in ready:
                        futures.discard(f)
                        yield f.result()
                    fill()
                    continue
                nxt = take()
                if nxt is not None:
                    yield _run_chunk(payload, *nxt)
                    fill()
                elif futures:
                    wait(futures, return_when=FIRST_COMPLETED)
                else:
                    break
        clean = True
    finally:
        if not clean:
            # interrupted, failed or closed early: nothing more is computed
            for f in futures:
                f.cancel()
            executor.shutdown(wait=False, kill_workers=True)
        else:
            executor.shutdown(wait=True)


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
        client = _connect(Client, scheduler, timeout, security)
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


def _connect(client_class: Any, scheduler: str, timeout: float, security: Any) -> Any:
    """A client of the dask scheduler at ``scheduler``, within ``timeout``
    seconds, or one :class:`SweepError` line: nothing listens, it does not
    answer, or what answers does not speak dask's protocol (a garbage
    answer raised MemoryError or a decoding error, then the half-made
    client waited 20 s at exit to close and printed a traceback).  The
    half-made client is closed here, at once."""
    made: list[Any] = []

    class _Client(client_class):  # type: ignore[misc, valid-type, unused-ignore]
        def start(self, **kwargs: Any) -> Any:
            made.append(self)
            return super().start(**kwargs)

    fix = "check the address, or start one with `dask scheduler` and workers with `dask worker ADDRESS`"
    try:
        _probe(scheduler, timeout, security)  # bounded: a silent or garbage peer kept Client() waiting
        return _Client(scheduler, timeout=timeout, set_as_default=False, security=security)
    except (OSError, TimeoutError) as exc:
        why, what = (
            f"{type(exc).__name__}: {_short(exc, 200)}",
            f"cannot reach the dask scheduler at {scheduler!r}",
        )
        raise SweepError(f"{what} within {timeout:g} s ({why}); {fix}") from None
    except Exception as exc:  # noqa: BLE001 - whatever the garbage makes the protocol raise
        why = f"{type(exc).__name__}: {_short(exc, 120)}"
        raise SweepError(
            f"the address {scheduler!r} answered, but not as a dask scheduler ({why}); {fix}"
        ) from None
    finally:
        for c in made:
            if c.status != "running":
                with contextlib.suppress(Exception):
                    c.close(timeout=min(timeout, 2.0))


def _probe(address: str, timeout: float, security: Any) -> None:
    """Ask ``address`` who it is (dask's ``identity`` call), all within
    ``timeout`` seconds in a thread of its own: TimeoutError if it says
    nothing in time, OSError if it cannot be reached, ValueError if what
    answers is not a dask scheduler."""
    import asyncio
    import concurrent.futures

    async def ask() -> Any:
        from distributed.comm import connect

        kw = security.get_connection_args("client") if security is not None else {}
        comm = await connect(address, timeout=timeout, **kw)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    async def bounded() -> Any:
        return await asyncio.wait_for(ask(), timeout)

    pool = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="chatterlab-dask-probe")
    try:
        who = pool.submit(asyncio.run, bounded()).result(timeout + 5.0)
    except TimeoutError:
        raise TimeoutError(f"no answer within {timeout:g} s") from None
    finally:
        pool.shutdown(wait=False, cancel_futures=True)
    if not (isinstance(who, dict) and who.get("type") == "Scheduler"):
        raise ValueError(f"its identity is {str(who)[:60]!r}, not a scheduler's")


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
