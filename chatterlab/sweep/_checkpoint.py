"""The checkpoint of a sweep: a locked directory with a manifest and one .npz file
per finished chunk, written atomically; resume loads the valid ones.  The
manifest's fingerprint (the caller's, or a :func:`joblib.hash` of the function
and its bound data) tells whether a checkpoint belongs to the same sweep."""

from __future__ import annotations

import functools
import json
import math
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
        _IDENTITY[str(directory)] = _identity(manifest)
        return manifest
    if not mpath.is_file():
        raise InputError(
            f"{where} holds files but no {_MANIFEST}: it is not a chatterlab sweep checkpoint; "
            "choose another directory"
        )
    old = _read_manifest(directory)
    old_grid = Grid.from_json(old["grid"])
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
    _IDENTITY[str(directory)] = _identity(old)
    return old


class CheckpointWarning(UserWarning):
    """A chunk file of a checkpoint is damaged (truncated, not an archive of
    this format, of other shapes) or belongs to another sweep: it is
    recomputed.  The command line prints it as one chatterlab warning line."""


#: how a damaged manifest is fixed (the command line says it in its options: cli/_parallel.py)
DAMAGED_FIX = (
    "; the checkpoint is damaged and cannot be resumed: delete the directory (its saved chunks are lost)"
    " and run without resume=True, or give another checkpoint directory"
)

#: the largest manifest read: its grid values are the only part that grows (a grid of the
#: engine's largest size, MAX_TASKS points on one axis, is some 250 MB of JSON: refused before)
_MAX_MANIFEST_BYTES = 64 << 20

#: checkpoint directory -> the identity of its sweep, written into every chunk (_save_chunk)
_IDENTITY: dict[str, str] = {}


def _identity(manifest: dict[str, Any]) -> str:
    """A digest of what makes a sweep (grid, outputs, chunk size, fingerprint):
    a chunk carrying another one was copied from another checkpoint."""
    import hashlib

    keys = ("grid", "outputs", "chunk_size", "n_tasks", "fingerprint")
    text = json.dumps({k: manifest.get(k) for k in keys}, sort_keys=True)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def _got(x: Any) -> str:
    """A manifest value as the file writes it, shortened for a message."""
    try:
        t = json.dumps(x)
    except (TypeError, ValueError):  # pragma: no cover - json.loads gives JSON values
        t = repr(x)
    return t if len(t) <= 40 else t[:37] + "..."


def _is_int(x: Any) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _read_manifest(directory: Path) -> dict[str, Any]:
    """The manifest of a checkpoint with every field checked at the edge --
    present, of its type, in range, consistent (``n_tasks`` is the grid's
    size) -- or :class:`InputError` naming the file, the field and the fix.
    Unknown extra fields are ignored (a later chatterlab may add some)."""
    mpath = directory / _MANIFEST
    where = f"checkpoint manifest {str(mpath)!r}"

    def bad(what: str) -> InputError:
        return InputError(f"{where}: {what}{DAMAGED_FIX}")

    try:
        if not mpath.is_file():
            raise bad("is not a regular file")
        if mpath.stat().st_size > _MAX_MANIFEST_BYTES:
            raise bad(f"is larger than {_MAX_MANIFEST_BYTES >> 20} MiB, more than any sweep writes")
        text = mpath.read_bytes().decode("utf-8")
    except OSError as exc:
        raise InputError(f"{where} cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise bad("is not UTF-8 text") from None
    try:
        m = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise bad(f"is not valid JSON ({str(exc)[:80]})") from None
    if not isinstance(m, dict):
        kind = {list: "a list", str: "a string", type(None): "null", bool: "a boolean"}.get(
            type(m), "a number"
        )
        raise bad(f"holds {kind}, not a JSON object of fields")
    for key in ("format", "version"):
        if key not in m:
            raise bad(f"field {key!r} is missing")
    if m.get("format") != _CHECKPOINT_FORMAT:
        raise bad(f"field 'format' is {_got(m.get('format'))}, not {_CHECKPOINT_FORMAT!r}")
    if not _is_int(m.get("version")):
        raise bad(f"field 'version' must be a whole number (got {_got(m.get('version'))})")
    if m["version"] != _CHECKPOINT_VERSION:
        raise InputError(
            f"checkpoint directory {str(directory)!r} was written by an incompatible version of chatterlab"
            f" (checkpoint format version {m['version']}; this chatterlab reads {_CHECKPOINT_VERSION})"
        )
    for key in ("grid", "outputs", "chunk_size", "n_tasks", "fingerprint"):
        if key not in m:
            raise bad(f"field {key!r} is missing")
    # grid: {"axes": [{"name": identifier, "unit": str, "values": [finite numbers]}, ...]}
    grid = m["grid"]
    axes = grid.get("axes") if isinstance(grid, dict) else None
    if not isinstance(axes, list) or not axes:
        raise bad("field 'grid' must be an object whose 'axes' is a non-empty list")
    names = set()
    size = 1
    for k, ax in enumerate(axes):
        f = f"field 'grid', axis {k + 1}"
        if not isinstance(ax, dict):
            raise bad(f"{f} must be an object with name, unit and values")
        name, unit, values = ax.get("name"), ax.get("unit", ""), ax.get("values")
        if not (isinstance(name, str) and name.isidentifier() and name.isascii()) or name in names:
            raise bad(f"{f}: 'name' must be a distinct identifier (got {_got(name)})")
        names.add(name)
        if not isinstance(unit, str):
            raise bad(f"{f} ({name}): 'unit' must be text")
        if not isinstance(values, list) or not values:
            raise bad(f"{f} ({name}): 'values' must be a non-empty list of numbers")
        for v in values:
            if not (isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)):
                raise bad(f"{f} ({name}): 'values' must be finite numbers (got {_got(v)})")
        size *= len(values)
    outputs = m["outputs"]
    if not (
        isinstance(outputs, dict)
        and outputs
        and all(isinstance(k, str) and k.isidentifier() and isinstance(u, str) for k, u in outputs.items())
    ):
        raise bad("field 'outputs' must be a non-empty object output name -> unit")
    cs = m["chunk_size"]
    if not _is_int(cs) or not 1 <= cs <= _MAX_INT:
        raise bad(f"field 'chunk_size' must be a whole number >= 1 (got {_got(cs)})")
    n = m["n_tasks"]
    if not _is_int(n) or n != size:
        raise bad(f"field 'n_tasks' must be the number of grid points, {size} (got {_got(n)})")
    fp = m["fingerprint"]
    if not (isinstance(fp, str) or (isinstance(fp, dict) and all(isinstance(v, str) for v in fp.values()))):
        raise bad("field 'fingerprint' must be text or an object of text values")
    for key in ("chatterlab", "fingerprint_method"):
        if key in m and not isinstance(m[key], str):
            raise bad(f"field {key!r} must be text (got {_got(m[key])})")
    if "fingerprint_source" in m and m["fingerprint_source"] not in ("caller", "auto"):
        raise bad(
            f"field 'fingerprint_source' must be 'caller' or 'auto' (got {_got(m['fingerprint_source'])})"
        )
    try:
        Grid.from_json(grid)
    except InputError as exc:  # pragma: no cover - every field is checked above
        raise bad(f"field 'grid': {exc}") from None
    return m


_MAX_INT = 2**62  # chunk bounds are stored as int64


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
        m = _read_manifest(directory)
        n_chunks = -(-m["n_tasks"] // m["chunk_size"])
        have = {int(g[1]) for p in directory.iterdir() if (g := _CHUNK_RE.match(p.name))}
    except (OSError, InputError):
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
    ident = _IDENTITY.get(str(directory))
    with atomic_write(_chunk_path(directory, out.chunk)) as tmp:
        with open(tmp, "xb") as fh:
            extra: dict[str, Any] = {"sweep": np.str_(ident)} if ident is not None else {}
            np.savez(
                fh,
                start=np.int64(out.start),
                stop=np.int64(stop),
                values=out.values,
                failed_index=np.asarray(out.failed_index, dtype=np.int64),
                failed_type=np.asarray(out.failed_type, dtype=np.str_).reshape(-1),
                failed_message=np.asarray(out.failed_message, dtype=np.str_).reshape(-1),
                **extra,
            )


_CHUNK_KEYS = {"start", "stop", "values", "failed_index", "failed_type", "failed_message"}


def _read_chunk(path: Path, chunk: int, start: int, stop: int, n_out: int, ident: str | None) -> _ChunkOut:
    """One chunk file, every member checked (names, dtypes, shapes, bounds,
    failures inside the chunk), or ValueError saying what is wrong with it."""
    import zipfile

    n = stop - start
    # the largest honest chunk: its values, and per task an index and two texts of <= 1000 characters
    limit = (1 << 20) + n * (8 * n_out + 8 + 8000)
    try:
        with zipfile.ZipFile(path) as zf:
            members = {i.filename: i.file_size for i in zf.infolist()}
    except (zipfile.BadZipFile, EOFError, ValueError) as exc:
        raise ValueError(f"not an archive of arrays ({str(exc)[:60]})") from None
    if sum(members.values()) > limit:
        raise ValueError(f"holds {sum(members.values())} bytes, more than a chunk of {n} tasks")
    keys = {k.removesuffix(".npy") for k in members}
    if not _CHUNK_KEYS <= keys or not keys <= _CHUNK_KEYS | {"sweep"}:
        raise ValueError(f"holds the arrays {sorted(keys)[:8]}, not those of a sweep chunk")
    with np.load(path, allow_pickle=False) as z:
        a = {k: z[k] for k in keys}
    if ident is not None and "sweep" in a and str(a["sweep"]) != ident:
        raise ValueError("was written by another sweep (copied from another checkpoint?)")
    for k in ("start", "stop"):
        if a[k].shape != () or a[k].dtype.kind not in "iu":
            raise ValueError(f"its {k!r} is not a whole number")
    if (int(a["start"]), int(a["stop"])) != (start, stop):
        raise ValueError(
            f"covers tasks {int(a['start'])}..{int(a['stop'])}, not {start}..{stop} of this grid"
        )
    values = a["values"]
    if values.dtype.kind not in "fiu" or values.shape != (n_out, n):
        raise ValueError(f"its values are {values.dtype} {values.shape}, not float64 {(n_out, n)}")
    fi, ft, fm = a["failed_index"], a["failed_type"], a["failed_message"]
    if fi.size == 0:  # np.asarray([]) saved as float64
        fi = fi.astype(np.int64).reshape(0)
    if fi.ndim != 1 or fi.dtype.kind not in "iu" or not np.all((fi >= start) & (fi < stop)):
        raise ValueError("its failed tasks are not task indices of the chunk")
    if np.unique(fi).size != fi.size:
        raise ValueError("it lists a failed task twice")
    for arr in (ft, fm):
        if arr.size and arr.dtype.kind != "U" or arr.shape != fi.shape:
            raise ValueError("its failure types and messages do not match its failed tasks")
    return _ChunkOut(
        chunk,
        start,
        np.array(values, dtype=np.float64),
        fi.tolist(),
        [str(x) for x in ft.tolist()],
        [str(x) for x in fm.tolist()],
        None,
    )


def _load_chunks(
    directory: Path,
    n_chunks: int,
    bounds: Callable[[int], tuple[int, int]],
    n_out: int,
    retry_failed: bool,
) -> Iterator[_ChunkOut]:
    """Yield the valid finished chunks of a checkpoint.

    A chunk file that is damaged (truncated, zero bytes, not an archive of
    this format, of other shapes) or foreign (written by another sweep) is
    recomputed, with one :class:`CheckpointWarning` for all of them: a
    chunk is a cache of work the manifest defines, so recomputing it loses
    nothing.  A chunk name that is not a regular file (a folder, a pipe)
    cannot be replaced and is refused (:class:`InputError`)."""
    damaged: list[str] = []
    ident = _IDENTITY.get(str(directory))
    for p in sorted(directory.iterdir()):
        m = _CHUNK_RE.match(p.name)
        if not m:
            continue
        c = int(m[1])
        if c >= n_chunks:
            continue
        if not p.is_file():
            raise InputError(
                f"checkpoint directory {str(directory)!r}: {p.name} is not a regular file, so this chunk"
                " cannot be saved; remove it and resume"
            )
        s, e = bounds(c)
        try:
            out = _read_chunk(p, c, s, e, n_out, ident)
        except (ValueError, OSError, EOFError) as exc:
            damaged.append(f"{p.name}: {str(exc)[:120]}")
            continue
        except Exception as exc:  # noqa: BLE001 - whatever a damaged archive raises, it is recomputed
            damaged.append(f"{p.name}: unreadable ({type(exc).__name__})")
            continue
        if retry_failed and out.failed_index:
            continue
        yield out
    if damaged:
        more = f" and {len(damaged) - 1} more" if len(damaged) > 1 else ""
        warnings.warn(
            CheckpointWarning(
                f"checkpoint {str(directory)!r}: {len(damaged)} damaged or foreign chunk file(s) recomputed"
                f" ({damaged[0]}{more})"
            ),
            stacklevel=3,
        )
