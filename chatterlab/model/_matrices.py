"""Reader of [matrices]: a matrix-level model, its matrices inline or in
.mtx/.npy/.npz files (sizes read from the headers before anything is
allocated; files confined to the model's folder unless allowed)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ModelError
from ._fields import _Item
from ._items import MatrixBlock

MAX_COORDINATES = 4000  #: rows (and columns) of a [matrices] matrix
MAX_MATRIX_FILE_BYTES = 512 * 2**20  #: size of one .mtx/.npy/.npz file named by [matrices]


def _read_matrix_model(
    src: str, raw: dict[str, Any], base_dir: Path, files_outside: bool
) -> MatrixBlock | None:
    """[matrices]: a matrix-level model (never together with structural items)."""
    matrices: MatrixBlock | None = None
    if "matrices" in raw:
        matrices = _read_matrices(src, raw["matrices"], base_dir, files_outside)
        structural = [
            k for k in ("body", "node", "beam", "attachment", "contact", "constraint", "movable") if k in raw
        ]
        if structural:
            raise ModelError(
                "a model is either structural ([[body]], [[beam]], ...) or matrix-level ([matrices]), not both:"
                f" remove {', '.join(structural)} or the [matrices] table (a matrix-level model takes"
                " [[point]] with coords, [[spring]], [[support]] with coordinate, [[coupling]] and [process])",
                source=src,
                item="[matrices]",
            )
    return matrices


def _read_matrices(src: str, t: Any, base_dir: Path, files_outside: bool = False) -> MatrixBlock:
    it = _Item(src, "[matrices]", t, ("coordinates", "M", "L", "K", "file", "given", "description"))
    arrays: dict[str, np.ndarray] = {}
    coords = it.raw("coordinates", None)
    if isinstance(coords, list) and len(coords) > MAX_COORDINATES:
        raise it.err(
            "coordinates",
            f"{len(coords)} coordinates; a matrix-level model may have at most {MAX_COORDINATES}",
        )
    if it.has("file"):
        fn = _matrix_path(it, "file", it.str("file"), base_dir, files_outside)
        arrays_z, coords_z = _read_npz(it, fn)
        arrays.update(arrays_z)
        if coords is None and coords_z is not None:
            coords = coords_z
    for key in ("M", "L", "K"):
        if it.has(key):
            v = it.raw(key)
            if isinstance(v, str):
                arrays[key] = _read_matrix_file(it, key, _matrix_path(it, key, v, base_dir, files_outside))
            else:
                try:
                    arr = np.array(v, dtype=float)
                except (TypeError, ValueError, OverflowError):
                    raise it.err(key, "must be a list of rows of numbers, or a .mtx/.npy file name") from None
                arrays[key] = arr
    if "M" not in arrays or "K" not in arrays:
        raise it.err(
            "M" if "M" not in arrays else "K", "missing: a matrix-level model needs M and K (L optional)"
        )
    n = arrays["M"].shape[0] if arrays["M"].ndim == 2 else -1
    if not isinstance(coords, list) or not all(isinstance(c, str) for c in coords):
        raise it.err("coordinates", "must be a list of coordinate names, one per row of M")
    if len(set(coords)) != len(coords):
        dup = sorted({c for c in coords if coords.count(c) > 1})
        raise it.err("coordinates", f"duplicate coordinate names: {', '.join(dup)}")
    arrays.setdefault("L", np.zeros_like(arrays["M"]))
    for key, arr in arrays.items():
        if arr.ndim != 2 or arr.shape != (len(coords), len(coords)):
            raise it.err(
                key, f"must be {len(coords)}x{len(coords)} (one row per coordinate), got shape {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise it.err(key, "holds non-finite entries")
        if not np.allclose(arr, arr.T, rtol=1e-10, atol=1e-12 * max(1.0, np.abs(arr).max())):
            raise it.err(key, "must be symmetric")
        arr.setflags(write=False)
    try:
        np.linalg.cholesky(arrays["M"])
    except np.linalg.LinAlgError:
        raise it.err("M", "must be positive definite (every coordinate needs mass)") from None
    given = it.raw("given", [])
    if not isinstance(given, list) or any(g not in coords for g in given):
        raise it.err("given", "must be a list of names from coordinates")
    del n
    return MatrixBlock(tuple(coords), arrays["M"], arrays["L"], arrays["K"], tuple(given))


def _matrix_path(it: _Item, key: str, name: str, base_dir: Path, files_outside: bool) -> Path:
    """A [matrices] file name resolved against the model's folder; a name that
    leads outside it (``..``, an absolute path, a link pointing out) is refused
    unless ``files_outside``."""
    if "\x00" in name:
        raise it.err(key, "file name holds a NUL character")
    full = base_dir / name  # an absolute name replaces base_dir
    if not files_outside:
        root = base_dir.resolve()
        real = full.resolve()
        if not real.is_relative_to(root):
            raise it.err(
                key,
                f"'{name}' leads outside the model's folder {str(root)!r}; put the file in that folder, or"
                " allow it with --allow-outside-files (Python: load_model(..., files_outside=True))",
            )
    try:
        size = full.stat().st_size
    except FileNotFoundError:
        raise it.err(key, f"'{full}' not found (paths are relative to the model file)") from None
    except OSError as exc:
        raise it.err(key, f"'{full}' cannot be read ({exc.strerror or exc})") from None
    if size > MAX_MATRIX_FILE_BYTES:
        raise it.err(
            key,
            f"'{full}' is {size / 2**20:.0f} MiB; a matrix file may hold at most {MAX_MATRIX_FILE_BYTES // 2**20} MiB",
        )
    return full


def _check_shape(it: _Item, key: str, fn: Path, shape: tuple[int, ...]) -> None:
    if len(shape) != 2 or shape[0] != shape[1]:
        raise it.err(key, f"'{fn}' holds an array of shape {shape}; a matrix must be square")
    if shape[0] > MAX_COORDINATES:
        raise it.err(
            key,
            f"'{fn}' declares a {shape[0]}x{shape[1]} matrix; at most {MAX_COORDINATES} coordinates are allowed",
        )


_NOT_NUMBERS = "holds no plain array of numbers (object or pickled data is never loaded)"


def _npy_header(fh: Any) -> tuple[tuple[int, ...], np.dtype]:
    fmt = np.lib.format
    version = fmt.read_magic(fh)
    if version == (1, 0):
        shape, _, dtype = fmt.read_array_header_1_0(fh)
    else:
        shape, _, dtype = fmt.read_array_header_2_0(fh)
    return tuple(shape), dtype


def _read_npz(it: _Item, fn: Path) -> tuple[dict[str, np.ndarray], list[str] | None]:
    import zipfile

    arrays: dict[str, np.ndarray] = {}
    coords: list[str] | None = None
    try:
        with zipfile.ZipFile(fn) as zf:
            names = set(zf.namelist())
            for key in ("M", "L", "K", "coordinates"):
                member = f"{key}.npy"
                if member not in names:
                    continue
                if zf.getinfo(member).file_size > MAX_MATRIX_FILE_BYTES:
                    raise it.err(
                        "file", f"'{fn}': {member} unpacks to more than {MAX_MATRIX_FILE_BYTES // 2**20} MiB"
                    )
                with zf.open(member) as fh:
                    shape, dtype = _npy_header(fh)
                if dtype.hasobject:
                    raise it.err("file", f"'{fn}': {member} {_NOT_NUMBERS}")
                if key == "coordinates":
                    if len(shape) != 1 or shape[0] > MAX_COORDINATES or dtype.kind not in "US":
                        raise it.err(
                            "file",
                            f"'{fn}': coordinates must be a 1-D array of at most {MAX_COORDINATES} names",
                        )
                else:
                    _check_shape(it, "file", fn, shape)
        with np.load(fn, allow_pickle=False) as z:
            for key in ("M", "L", "K"):
                if key in z:
                    arrays[key] = np.asarray(z[key], float)
            if "coordinates" in z:
                coords = [str(x) for x in z["coordinates"]]
    except ModelError:
        raise
    except (ValueError, TypeError, OSError, EOFError, zipfile.BadZipFile) as exc:
        detail = f" ({exc})" if "pickle" not in str(exc).lower() else ""
        raise it.err("file", f"'{fn}' is not a readable .npz file of numbers{detail}") from None
    return arrays, coords


def _read_matrix_file(it: _Item, key: str, fn: Path) -> np.ndarray:
    try:
        if fn.suffix == ".mtx":
            from scipy.io import mminfo, mmread

            rows, cols, entries, _, field, _ = mminfo(str(fn))
            _check_shape(it, key, fn, (int(rows), int(cols)))
            if field == "complex":
                raise it.err(key, f"'{fn}' holds complex entries; a matrix holds real numbers")
            if int(entries) > int(rows) * int(cols):
                raise it.err(key, f"'{fn}' declares {entries} entries for a {rows}x{cols} matrix")
            m = mmread(str(fn))
            return np.asarray(m.toarray() if hasattr(m, "toarray") else m, float)
        if fn.suffix == ".npy":
            with open(fn, "rb") as fh:
                shape, dtype = _npy_header(fh)
            if dtype.hasobject:
                raise it.err(key, f"'{fn}' {_NOT_NUMBERS}")
            _check_shape(it, key, fn, shape)
            return np.asarray(np.load(fn, allow_pickle=False), float)
    except ModelError:
        raise
    except FileNotFoundError:
        raise it.err(key, f"'{fn}' not found (paths are relative to the model file)") from None
    except (ValueError, TypeError, OSError, EOFError, IndexError) as exc:
        detail = f" ({exc})" if "pickle" not in str(exc).lower() else f": it {_NOT_NUMBERS}"
        raise it.err(key, f"'{fn}' could not be read{detail}") from None
    raise it.err(key, f"'{fn}': use a Matrix Market (.mtx) or NumPy (.npy) file, or an inline list")
