"""netCDF through xarray (chatterlab.io._netcdf): exact round trips, names and
attributes as written, the container (netCDF-4/HDF5, no added attributes), atomic
writes, the files of chatterlab 0.1 (netCDF-3) still read, and results that convert
losslessly to xarray.Dataset."""

from __future__ import annotations

import base64
import os
import subprocess
import sys
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import xarray as xr  # a dependency of chatterlab: an import error fails, never skips

from chatterlab.errors import InputError
from chatterlab.io import read_netcdf, write_netcdf
from chatterlab.io._netcdf import make_dataset, read_dataset, write_dataset
from chatterlab.sweep import Grid, SweepResult, sweep

ROOT = Path(__file__).resolve().parents[1]
FIXED = {"created": "2026-01-01T00:00:00+00:00"}

# A sweep file written by chatterlab 0.1.0 (SweepResult.to_netcdf through scipy's
# netcdf_file, CDF-2), zlib-compressed and base64-encoded.  It was made with
#   f(width, speed) = {"abscissa": width * 1e3 - speed, "freq": speed / width}
#   (ZeroDivisionError("division by zero") at width=2e-3, speed=2.5),
#   grid width = [1e-3, 2e-3] m, speed = [1, 2.5, 4] m/s, outputs abscissa [1/s,
#   "real part of the rightmost root"] and freq [Hz], attrs below.
OLD_SWEEP = (
    "eNqNVDtvE0EQvjyMQ5IioglUjI4CEIk5WxCBUbAlEoSEiCioiKJj7RvHK/tuze46T4W0dLR0FFRUpKEG5SfwC/gJ0FFQMPu4"
    "xEmwyOrmdmZnd7557T5aejwauDFJZPjCJk90261ZWfUQEyePEU0TTRFdaraZ1ii7rBFvoFRcZMdnolK5FLkzxaZEpp0Fo7tS"
    "iSoL81GZvhdRVLXfLft3+6ebIk1ZlsRdnqE/M3uMBWoTsQe6pEXatX6nIsFurHFLH+HPrjaQpWuTy7AIlXKE9+EaHH45PDD6"
    "iSzuCZ5pRfw40QjRBePnJvL1tl228mjth3Oo9jvIxwWlme6rI5xij0nNmfWjmKJSbB1z3W4ZRAsWQDPVUdBivIsJ3NBt5BJE"
    "X/f6WgGTCCts5eYDoHVocak0MA22AotRKYoqkM6BLcBipXQX0tuqCi9RiiW+wU3Gl6UUsgqJF6GxDTuk9nE60IE4DRWpHEpk"
    "Kvfz+mp4DovhmrVpLPYlKn/2zepuaOKLeZbgVliFO3MQ2uwSvxvaOIizkZDGBkIyhbJHIhqoWG/3kNbOOhHSFp9Toz/j0Z51"
    "yfZi4VSf5rFO5/3Yz7irrJPHKJGGv9gV2XqcsRT/3e+mDy47tgAmftZQTU4u+b3B/3DKw3GuUh26YBrI9ImpvzT9lwrqASmE"
    "zvH9tSjcM3VsSXx9TuzRJzvBMOzczqB9c+WnbDGPm/w8OCPlYCjOU2MPnD1qAxCdOejAQ+L8fWgJaUPvzOs2YKbl9lEyXJfS"
    "ddCSN/raWh0fqMf7U2/ViPd1qJ/pcD8H7ZiczHiMg9pPx9XH/TwTnBhf/dvwbcK/FX7/fr7u99Xf1d388a2bP3t5v35if/1D"
    "PRgybHy1541n3399+lN75ea/jeQjLw=="
)
OLD_ATTRS = {
    "model_text": "[beam]\nE = 210e9 # µ°",
    "created": "2026-01-01T00:00:00+00:00",
    "chatterlab_version": "0.1.0",
    "command_line": "chatterlab sweep t.toml",
    "n_points": 6,
}


def _old_file(tmp_path: Path) -> Path:
    p = tmp_path / "old.nc"
    p.write_bytes(zlib.decompress(base64.b64decode(OLD_SWEEP)))
    return p


def _old_values() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    w, s = np.meshgrid([1e-3, 2e-3], [1.0, 2.5, 4.0], indexing="ij")
    abscissa, freq = w * 1e3 - s, s / w  # the same float operations as when the file was written
    status = np.zeros(w.shape, np.int32)
    abscissa[1, 1] = freq[1, 1] = np.nan
    status[1, 1] = 1
    return w, abscissa, freq, status


def test_file_of_chatterlab_0_1_still_reads(tmp_path: Path) -> None:
    p = _old_file(tmp_path)
    assert p.read_bytes()[:4] == b"CDF\x02"
    f = read_netcdf(p)
    assert list(f.coords) == ["width", "speed"]
    assert f.coords["width"][1] == "m" and f.coords["speed"][0].tolist() == [1.0, 2.5, 4.0]
    _, abscissa, freq, status = _old_values()
    a, unit, long_name = f.data["abscissa"]
    assert np.array_equal(a, abscissa, equal_nan=True) and (unit, long_name) == (
        "1/s",
        "real part of the rightmost root",
    )
    assert np.array_equal(f.data["freq"][0], freq, equal_nan=True) and f.data["freq"][1:] == ("Hz", "freq")
    assert f.data["task_status"][0].dtype == np.int32 and np.array_equal(f.data["task_status"][0], status)
    assert {k: f.attrs[k] for k in OLD_ATTRS} == OLD_ATTRS and f.attrs["weights"].tolist() == [0.5, 1.5]
    assert f.attrs["status"] == "partial" and f.attrs["n_failed"] == 1
    mm = read_netcdf(p, mmap=True)  # netCDF-3: read into memory, same values
    assert np.array_equal(mm.data["freq"][0], freq, equal_nan=True)
    r = SweepResult.from_netcdf(p)
    assert r.grid == Grid({"width": ([1e-3, 2e-3], "m"), "speed": ([1.0, 2.5, 4.0], "m/s")})
    assert r.status == "partial" and r.n_failed == 1 and r.reasons == ("ZeroDivisionError: division by zero",)
    assert r.failures[0].task_index == 4 and r.failures[0].point == {"width": 0.002, "speed": 2.5}
    assert (
        np.array_equal(r.task_status, status)
        and r.long_names["abscissa"] == "real part of the rightmost root"
    )
    # written again: netCDF-4 now, the same names, attributes and values
    q = r.to_netcdf(tmp_path / "new.nc", provenance=False)
    assert q.read_bytes()[:8] == b"\x89HDF\r\n\x1a\n"
    g = read_netcdf(q)
    assert list(g.coords) == list(f.coords) and g.dims == f.dims and list(g.data) == list(f.data)
    for name, (arr, unit, long_name) in f.data.items():
        b, u, ln = g.data[name]
        assert (
            b.dtype == arr.dtype and np.array_equal(b, arr, equal_nan=True) and (u, ln) == (unit, long_name)
        )
    assert set(g.attrs) == set(f.attrs)
    for k, v in f.attrs.items():
        assert np.array_equal(g.attrs[k], v) and type(g.attrs[k]) is type(v), k


def test_round_trip_is_exact_and_adds_nothing(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    coords = {"time": (np.linspace(0, 1, 5), "s", "time"), "output": (np.arange(3), "")}
    q = rng.standard_normal((5, 3))
    q[2, 1] = np.nan
    data = {
        "q": (q, "m", "displacement"),
        "hit": (q > 0, "1"),
        "count": (np.arange(15).reshape(5, 3), "1"),
        "f32": (q.astype(np.float32), "N"),
        "shape": (rng.standard_normal((2, 3)), "m", "mode shape", ("mode", "output")),
    }
    attrs = {
        "model": 'µ°\n"quoted"',
        "n": 3,
        "big": -(2**40),
        "tol": 1e-300,
        "inf": float("inf"),
        "flag": True,
    }
    p = write_netcdf(tmp_path / "r.nc", coords, data, attrs)
    f = read_netcdf(p)
    assert list(f.coords) == ["time", "output"] and f.dims["shape"] == ("mode", "output")
    assert f.coords["output"][0].dtype == np.int32
    for name, (arr, unit, *_) in data.items():
        b = f.data[name][0]
        assert np.array_equal(b, arr, equal_nan=True) and f.data[name][1] == unit
    assert f.data["hit"][0].dtype == np.int8 and f.data["count"][0].dtype == np.int32
    assert (
        f.data["f32"][0].dtype == np.float32 and f.data["f32"][0].tobytes() == q.astype(np.float32).tobytes()
    )
    assert f.data["q"][0].tobytes() == q.tobytes()  # bit for bit, NaN included
    assert f.attrs["model"] == attrs["model"] and f.attrs["big"] == -(2**40) and f.attrs["tol"] == 1e-300
    assert f.attrs["inf"] == float("inf") and f.attrs["flag"] == 1 and f.attrs["n"] == 3
    with xr.open_dataset(
        p, decode_cf=False
    ) as ds:  # what any reader sees: units and long_name, nothing added
        for name, var in ds.variables.items():
            assert set(var.attrs) == {"units", "long_name"}, name
        assert set(ds.attrs) == set(attrs) | {"chatterlab_version", "created", "command_line"}
    m = read_netcdf(p, mmap=True)
    assert isinstance(m.data["q"][0], np.memmap) and m.data["q"][0].tobytes() == q.tobytes()
    assert isinstance(m.data["shape"][0], np.memmap) and np.array_equal(m.data["shape"][0], data["shape"][0])


def test_dataset_round_trip_and_byte_identical_files(tmp_path: Path) -> None:
    ds = make_dataset(
        {"speed": (np.array([1.0, 2.0, 3.0]), "m/s")},
        {"b_lim": (np.array([1e-3, np.inf, np.nan]), "m", "largest width")},
        {"title": "lobes", **FIXED},
    )
    assert (
        ds["b_lim"].attrs == {"units": "m", "long_name": "largest width"}
        and ds["speed"].attrs["units"] == "m/s"
    )
    a = write_dataset(tmp_path / "a.nc", ds, provenance=False)
    xr.testing.assert_identical(read_dataset(a), ds)
    b = write_dataset(tmp_path / "b.nc", ds, provenance=False)
    assert a.read_bytes() == b.read_bytes()  # same data, same bytes (no time stamps in the HDF5 file)
    assert ds.attrs == {"title": "lobes", **FIXED}  # writing added provenance to its copy only
    c = read_dataset(write_dataset(tmp_path / "c.nc", ds))
    assert c.attrs["created"] == FIXED["created"] and "chatterlab_version" in c.attrs


def test_a_foreign_file_with_fill_values_is_written_again(tmp_path: Path) -> None:
    """read_dataset keeps a _FillValue as stored (an attribute); write_dataset
    turns it back into the variable's fill value instead of refusing it."""
    ds = xr.Dataset({"y": ("x", np.array([1.0, -999.0]), {"units": "m"})}, coords={"x": [0.0, 1.0]})
    ds.to_netcdf(tmp_path / "foreign.nc", engine="h5netcdf", encoding={"y": {"_FillValue": -999.0}})
    raw = read_dataset(tmp_path / "foreign.nc")
    assert raw["y"].attrs["_FillValue"] == -999.0 and raw["y"].values.tolist() == [1.0, -999.0]
    again = read_dataset(write_dataset(tmp_path / "again.nc", raw, provenance=False))
    xr.testing.assert_identical(again, raw)
    assert raw["y"].attrs["_FillValue"] == -999.0  # the caller's dataset is left as it was


def _hdf5_contents(path: Path) -> list[tuple[Any, ...]]:
    """Every HDF5 object of a file: name, kind, dtype, shape, layout, fill
    value, attributes (dimension lists as the names they point to) and the
    values' bytes."""
    import h5py

    def attr(f: Any, k: str, v: Any) -> Any:
        if k in ("DIMENSION_LIST", "REFERENCE_LIST"):
            return k, repr(
                [[f[r].name for r in np.atleast_1d(row)] for row in v]
            ) if k == "DIMENSION_LIST" else k
        return k, repr(v)

    out: list[tuple[Any, ...]] = []
    with h5py.File(path, "r") as f:
        out.append(("/", sorted(attr(f, k, v) for k, v in f.attrs.items())))

        def visit(name: str, obj: Any) -> None:
            attrs = sorted(attr(f, k, v) for k, v in obj.attrs.items())
            if isinstance(obj, h5py.Dataset):
                out.append((name, obj.dtype.str, obj.shape, obj.chunks, obj.compression, obj.fillvalue, attrs,
                            obj[()].tobytes()))  # fmt: skip
            else:
                out.append((name, "group", attrs))

        f.visititems(visit)
    return out


def test_direct_writer_gives_the_xarray_file(tmp_path: Path) -> None:
    """write_netcdf writes with h5netcdf alone (no xarray import): the file must
    hold what write_dataset(make_dataset(...)) writes through xarray -- the same
    HDF5 objects, dtypes, contiguous layout, fill values, attributes and
    dimension scales, and the values bit for bit -- and, for fixed provenance,
    the same bytes each time."""
    rng = np.random.default_rng(3)
    q = rng.standard_normal((4, 3))
    q[1, 2] = np.nan
    mm = np.lib.format.open_memmap(tmp_path / "m.npy", mode="w+", dtype=np.float64, shape=(4, 3))
    mm[:] = -q
    coords = {"speed": (np.linspace(0.1, 1.0, 4), "m/s", "speed"), "mode": (np.arange(3), "")}
    data = {
        "b_lim": (q, "m", "largest width"),
        "mapped": (mm, "m"),
        "hit": (q > 0, "1"),
        "count": (np.arange(12).reshape(4, 3), "1"),
        "big": (np.arange(12).reshape(4, 3) * 2**40, "1"),
        "f32": (q.astype(np.float32), "N"),
        "shape": (rng.standard_normal((2, 4)), "m", "extra dim", ("k", "speed")),
    }
    attrs = {"title": "µ°\n", "n": 3, "big": -(2**40), "x": 1e-300, "band": [0.0, 2.5], "flag": True, **FIXED}
    a = write_netcdf(tmp_path / "direct.nc", coords, data, attrs)
    b = write_dataset(tmp_path / "xarray.nc", make_dataset(coords, data, attrs))
    assert _hdf5_contents(a) == _hdf5_contents(b)
    xr.testing.assert_identical(read_dataset(a), read_dataset(b))
    again = write_netcdf(tmp_path / "again.nc", coords, data, attrs)
    assert again.read_bytes() == a.read_bytes()


def test_importing_and_writing_netcdf_leaves_xarray_unloaded(tmp_path: Path) -> None:
    """A result written by write_netcdf does not import xarray (a quarter of a
    second of the main job): checked in a fresh interpreter."""
    code = (
        "import sys, numpy as np\n"
        "from chatterlab.io import write_netcdf\n"
        f"write_netcdf({str(tmp_path / 'x.nc')!r}, {{'x': (np.arange(3.0), 'm')}}, {{'y': (np.ones(3), 'N')}})\n"
        "print('xarray' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
    assert read_netcdf(tmp_path / "x.nc").data["y"][0].tolist() == [1.0, 1.0, 1.0]


@pytest.mark.parametrize("route", ["direct", "xarray"])
def test_write_is_atomic(route: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import chatterlab.io._netcdf as nc

    coords = {"x": (np.arange(4.0), "m")}
    p = write_netcdf(tmp_path / "r.nc", coords, {"y": (np.ones(4), "N")}, FIXED)
    before = p.read_bytes()

    def half_then_interrupt(path: os.PathLike[str]) -> None:
        Path(path).write_bytes(before[: len(before) // 2])
        raise KeyboardInterrupt

    if route == "direct":
        monkeypatch.setattr(nc, "_write_h5netcdf", lambda path, *a: half_then_interrupt(path))
    else:
        monkeypatch.setattr(xr.Dataset, "to_netcdf", lambda self, path, *a, **k: half_then_interrupt(path))
    with pytest.raises(KeyboardInterrupt):
        if route == "direct":
            write_netcdf(p, coords, {"y": (np.zeros(4), "N")}, FIXED)
        else:
            write_dataset(p, make_dataset(coords, {"y": (np.zeros(4), "N")}, FIXED))
    assert p.read_bytes() == before and sorted(q.name for q in tmp_path.iterdir()) == ["r.nc"]


def test_sweep_result_converts_losslessly(tmp_path: Path) -> None:
    def f(width: float, speed: float) -> dict[str, float]:
        if speed == 2.5 and width == 2e-3:
            raise ZeroDivisionError("division by zero")
        return {"abscissa": width * 1e3 - speed, "freq": speed / width}

    g = Grid({"width": ([1e-3, 2e-3], "m"), "speed": ([1.0, 2.5, 4.0], "m/s")})
    r = sweep(
        f,
        g,
        outputs={"abscissa": ("1/s", "real part"), "freq": "Hz"},
        backend="serial",
        progress=False,
        attrs=FIXED,
    )
    ds = r.to_xarray()
    assert ds["freq"].dims == ("width", "speed") and ds["width"].attrs["units"] == "m"
    assert (
        ds["abscissa"].attrs == {"units": "1/s", "long_name": "real part"} and ds.attrs["status"] == "partial"
    )
    for back in (
        SweepResult.from_xarray(ds),
        SweepResult.from_xarray(read_dataset(r.to_netcdf(tmp_path / "s.nc"))),
    ):
        assert back.grid == r.grid and back.units == r.units and back.long_names == r.long_names
        assert (back.status, back.message, back.n_failed) == (r.status, r.message, r.n_failed)
        assert back.failures == r.failures and back.reasons == r.reasons
        assert np.array_equal(back.task_status, r.task_status)
        for name in r.data:
            assert back[name].tobytes() == r[name].tobytes()
        assert {k: back.attrs[k] for k in FIXED} == FIXED
    xr.testing.assert_identical(SweepResult.from_xarray(ds).to_xarray(), ds)


def test_memory_mapped_results_are_written_without_a_copy(tmp_path: Path) -> None:
    """sweep(out=...) fills np.memmap files and writes them through to_xarray: no
    variable may be copied into memory on the way (the bound is half the smallest
    variable, so any copy of any one fails; imports are warmed up first)."""
    import tracemalloc

    n = 600
    a = np.lib.format.open_memmap(tmp_path / "a.npy", mode="w+", dtype=np.float64, shape=(n, n))
    a[:] = 0.5
    st = np.lib.format.open_memmap(tmp_path / "s.npy", mode="w+", dtype=np.int32, shape=(n, n))
    g = Grid({"x": (np.arange(float(n)), "m"), "y": (np.arange(float(n)), "s")})
    small = SweepResult(
        Grid({"x": ([0.0, 1.0], "m")}), {"a": np.zeros(2)}, {"a": ""}, task_status=np.zeros(2, np.int32)
    )
    small.to_netcdf(tmp_path / "warm.nc")
    r = SweepResult(g, {"a": a}, {"a": "m"}, task_status=st)
    tracemalloc.start()
    try:
        r.to_netcdf(tmp_path / "big.nc")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < st.nbytes / 2, peak
    back = read_netcdf(tmp_path / "big.nc", mmap=True)
    assert np.array_equal(back.data["a"][0], a) and back.data["task_status"][0].dtype == np.int32


def test_unreadable_and_unstorable_are_one_line_errors(tmp_path: Path) -> None:
    def one_line(exc: pytest.ExceptionInfo[InputError], *parts: str) -> None:
        msg = str(exc.value)
        assert "\n" not in msg and all(p in msg for p in parts), msg

    with pytest.raises(InputError) as e:
        read_netcdf(tmp_path / "missing.nc")
    one_line(e, "missing.nc", "does not exist")
    (tmp_path / "t.nc").write_text("speed,b_lim\n1,2\n")
    with pytest.raises(InputError) as e:
        read_netcdf(tmp_path / "t.nc")
    one_line(e, "t.nc", "is not a readable netCDF-4 (HDF5) file")
    (tmp_path / "c5.nc").write_bytes(b"CDF\x05" + bytes(60))
    with pytest.raises(InputError) as e:
        read_netcdf(tmp_path / "c5.nc")
    one_line(e, "c5.nc", "CDF-5", "nccopy")
    c = {"x": (np.arange(2.0), "m")}
    for data, attrs, parts in [
        ({"h": (np.ones(2) + 1j, "")}, {}, ("'h' is complex", "two variables")),
        ({"y": (np.ones(2), "")}, {"tags": ["a", "b"]}, ("attribute 'tags'", "json.dumps")),
        ({"y": (np.ones(2), "")}, {"_FillValue": 1.0}, ("'_FillValue' is reserved", "chatterlab_FillValue")),
        ({"y": (np.ones(3), "")}, {}, ("'y' has shape (3,)", "(2,)")),
        ({"bad name": (np.ones(2), "")}, {}, ("'bad name' is not a valid netCDF name",)),
        ({"y": (np.ones(2), "")}, {Path("p"): 1}, ("is not a valid netCDF name",)),  # not a str
    ]:
        with pytest.raises(InputError) as e:
            write_netcdf(tmp_path / "w.nc", c, data, attrs)
        one_line(e, *parts)
    assert sorted(q.name for q in tmp_path.iterdir()) == ["c5.nc", "t.nc"]  # nothing written


def test_importing_io_loads_no_file_library() -> None:
    code = (
        "import sys, chatterlab, chatterlab.io; "
        "print(sorted(m for m in ('xarray', 'h5netcdf', 'h5py', 'tqdm', 'netCDF4') if m in sys.modules))"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "[]"
