"""The checkpoint of a sweep: a locked directory with a manifest and one .npz file
per finished chunk, written atomically; resume loads the valid ones.  The
manifest's fingerprint (the caller's, or a :func:`joblib.hash` of the function
and its bound data) tells whether a checkpoint belongs to the same sweep."""

from __future__ import annotations

import functools
import json
import os
import re
import shutil
import sys
import warnings
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from chatterlab.errors import InputError
from chatterlab.io._netcdf import atomic_write

from ._backends import _ChunkOut
from ._grid import Grid

_MANIFEST = "manifest.json"
_LOCK = ".lock"  # held (flock) by the run using the checkpoint; released by the kernel when it dies
_SCRATCH = "scratch-"  # memmap folders of a run streaming to out=, inside the checkpoint
_CHUNK_RE = re.compile(r"^chunk_(\d+)\.npz$")
_CHECKPOINT_FORMAT = "chatterlab-sweep-checkpoint"
_CHECKPOINT_VERSION = 1

_FINGERPRINT_METHOD = "joblib.hash-sha1 v1"  # of the automatic fingerprint (manifest)


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
        done = (
            " (it holds every chunk of a finished sweep, e.g. one killed before its output was written:"
            " the resume computes nothing and gives its results)"
            if _is_complete(directory)
            else ""
        )
        raise InputError(
            f"{where} is not empty: pass resume=True (CLI: --resume) to continue the sweep "
            f"saved there{done}, or delete the directory to start afresh"
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
    # (the CLI replaces this text by its own options: keep the two in step, cli/_parallel.py)
    fix = "; use another checkpoint directory or delete this one (resume only continues the same sweep)"
    new_grid = Grid.from_json(manifest["grid"])
    if old_grid != new_grid:
        raise InputError(
            f"{refuse}: grid {old_grid!r} there, {new_grid!r} now{_grid_diff(old_grid, new_grid)}{fix}"
        )
    if old["outputs"] != manifest["outputs"]:
        raise InputError(f"{refuse}: outputs {old['outputs']} there, {manifest['outputs']} now{fix}")
    if (old.get("fingerprint_source"), old.get("fingerprint_method")) == ("auto", None) and manifest.get(
        "fingerprint_source"
    ) == "auto":
        raise InputError(
            f"{where} was written by an earlier chatterlab (0.1), whose automatic fingerprint of the function is "
            "computed differently, so nothing shows that its results come from this function; start "
            "afresh: delete the directory, or give another checkpoint=DIR (CLI: --checkpoint DIR) "
            "without resume=True (CLI: --resume)"
        )
    if old["fingerprint"] != manifest["fingerprint"]:
        era = ""
        if old.get("chatterlab") != manifest.get("chatterlab"):
            by = f"chatterlab {old['chatterlab']}" if "chatterlab" in old else "an earlier chatterlab"
            era = f" (it was written by {by}, whose fingerprints may be computed differently)"
        raise InputError(
            f"{refuse}: the function/model fingerprint differs "
            f"({_fingerprint_diff(old['fingerprint'], manifest['fingerprint'])}), so the saved "
            f"results may come from another model{era}{fix}"
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


def _is_complete(directory: Path) -> bool:
    """True when the checkpoint holds a chunk file for every chunk its manifest
    declares (a sweep that finished; whether it was stored is the caller's)."""
    try:
        m = json.loads((directory / _MANIFEST).read_text(encoding="utf-8"))
        n_chunks = -(-int(m["n_tasks"]) // int(m["chunk_size"]))
        have = {int(g[1]) for p in directory.iterdir() if (g := _CHUNK_RE.match(p.name))}
    except (OSError, ValueError, KeyError, TypeError, ZeroDivisionError):
        return False
    return n_chunks > 0 and have >= set(range(n_chunks))


def _remove_checkpoint(directory: Path) -> bool:
    """Remove a sweep's checkpoint directory once its results are stored
    elsewhere, taking its lock first: a run using it (a ``--resume`` started
    meanwhile) keeps it.  A directory without a manifest is not a checkpoint
    and is left alone.  True when removed."""
    if not (directory / _MANIFEST).is_file():
        return False
    try:
        lock = _lock_checkpoint(directory)
    except InputError:  # in use by another run, or not writable
        return False
    try:
        shutil.rmtree(directory, ignore_errors=True)
    finally:
        if lock is not None:
            lock.close()
    return not directory.exists()


def _auto_fingerprint(func: Callable[..., Any]) -> str:
    """A :func:`joblib.hash` of the function's identity, code and bound data (best effort).

    Covers the module and qualified name, the source code (the bytecode
    where the source cannot be found), ``functools.partial`` arguments, the
    instance of a bound method, closure cells and defaults, or the object
    itself for a callable instance.  joblib hashes NumPy arrays by content
    and dictionaries whatever their order; data that joblib cannot hash
    count by their ``repr`` with memory addresses removed.
    """
    import inspect

    parts: list[Any] = []
    f: Any = func
    while isinstance(f, functools.partial):
        parts.append(("partial", f.args, sorted(f.keywords.items())))
        f = f.func
    parts.append(
        ("name", f"{getattr(f, '__module__', '')}.{getattr(f, '__qualname__', type(f).__qualname__)}")
    )
    owner = getattr(f, "__self__", None)
    if owner is not None and not isinstance(owner, type(sys)):
        parts.append(("self", owner))  # a bound method: the model instance matters
    code = getattr(f, "__code__", None)
    if code is not None:
        try:
            parts.append(("source", inspect.getsource(f)))
        except (OSError, TypeError):
            simple = [c for c in code.co_consts if isinstance(c, int | float | str | bytes | None)]
            parts.append(("code", code.co_code, simple))
        cells = []
        for cell in getattr(f, "__closure__", None) or ():
            try:
                cells.append(cell.cell_contents)
            except ValueError:  # an empty cell
                cells.append(None)
        parts.append(("bound", cells, getattr(f, "__defaults__", None), getattr(f, "__kwdefaults__", None)))
    elif owner is None and not isinstance(f, type):
        parts.append(("object", f))  # a callable object, e.g. a frozen task with __call__
    return _hash([_hashable(p) for p in parts])


def _caller_fingerprint(fingerprint: str | Mapping[str, Any]) -> str | dict[str, str]:
    """The caller's fingerprint as stored in the manifest (a mapping as text values)."""
    if isinstance(fingerprint, str):
        return fingerprint
    if isinstance(fingerprint, Mapping):
        return {str(k): str(v) for k, v in fingerprint.items()}
    raise InputError(
        f"fingerprint must be a string or a mapping name -> value (got {type(fingerprint).__name__})"
    )


def _hash(obj: Any) -> str:
    import joblib

    return str(joblib.hash(obj, hash_name="sha1"))


def _hashable(part: Any) -> Any:
    """``part``, or its address-free ``repr`` when joblib cannot hash it."""
    try:
        _hash(part)
    except Exception:  # noqa: BLE001 - unpicklable: fall back to the repr
        return re.sub(r"0x[0-9a-fA-F]+", "0x?", repr(part))
    return part


def _fingerprint_diff(old: Any, new: Any) -> str:
    """Where two fingerprints differ, in words: the first differing entry of
    a mapping (its name: a caller names each option), or of a ``|``-joined
    string, or the two strings from their first difference."""

    def short(x: Any) -> str:
        t = str(x)
        return repr(t if len(t) <= 40 else t[:37] + "...")

    if isinstance(old, dict) != isinstance(new, dict):
        forms = ("named entries", "text") if isinstance(old, dict) else ("text", "named entries")
        return f"of another form: {forms[0]} there, {forms[1]} now"
    if isinstance(old, dict) and isinstance(new, dict):
        for k in [*old, *(k for k in new if k not in old)]:
            if old.get(k) != new.get(k):
                a = short(old[k]) if k in old else "unset"
                b = short(new[k]) if k in new else "unset"
                return f"{k} is {a} there, {b} now"
    if isinstance(old, str) and isinstance(new, str):
        pa, pb = old.split("|"), new.split("|")
        if len(pa) == len(pb) > 1:
            i = next(i for i, (x, y) in enumerate(zip(pa, pb, strict=True)) if x != y)
            return f"part {i + 1} of {len(pa)}: {short(pa[i])} there, {short(pb[i])} now"
        i = next(
            (i for i, (x, y) in enumerate(zip(old, new, strict=False)) if x != y), min(len(old), len(new))
        )
        return f"{short(old[max(0, i - 4) :])} there, {short(new[max(0, i - 4) :])} now"
    return f"{short(old)} there, {short(new)} now"


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
