"""Tests of the generic sweep engine (chatterlab.sweep._engine) and labelled files (chatterlab.io._netcdf;
the netCDF container itself, xarray and old files: tests/test_netcdf.py)."""

from __future__ import annotations

import csv
import dataclasses
import functools
import io
import itertools
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import chatterlab
from chatterlab.errors import InputError, SweepError
from chatterlab.io import read_netcdf, write_csv, write_netcdf
from chatterlab.sweep._engine import Axis, Grid, SweepInterrupted, SweepResult, sweep

ROOT = Path(chatterlab.__file__).resolve().parent.parent
FIXED = {"created": "2000-01-01T00:00:00+00:00", "command_line": "test"}
OUTS = {"abscissa": "1/s", "freq": "Hz"}


# --------------------------------------------------------------------------- swept functions
# Module-level so that loky and dask workers can import them.


def model(width: float, speed: float, k: float = 1e6) -> dict[str, float]:
    """Deterministic but rounding-sensitive numerics (eigenvalues, long sums)."""
    a = np.array([[-k * width, 1.0, 0.3], [speed, -2.0 - width, 0.1], [0.5, speed * width, -1.0]])
    ev = np.linalg.eigvals(a)
    s = np.sum(np.sin(np.arange(1, 200) * speed * width * 1e3) / np.arange(1, 200))
    return {"abscissa": float(np.max(ev.real)), "freq": float(s + abs(ev.imag).max())}


def flaky(width: float, speed: float) -> dict[str, float]:
    if width == 2e-3 and speed == 2.0:
        raise np.linalg.LinAlgError("singular at this point")
    return {"abscissa": width * speed, "freq": width + speed}


def wrong_keys(width: float, speed: float) -> dict[str, float]:
    return {"abscissa": 1.0, "frq": 2.0}


def blas_env(x: float) -> dict[str, float]:
    return {
        "omp": float(os.environ.get("OMP_NUM_THREADS", "nan")),
        "openblas": float(os.environ.get("OPENBLAS_NUM_THREADS", "nan")),
    }


def small_grid() -> Grid:
    return Grid({"width": (np.linspace(1e-3, 4e-3, 4), "m"), "speed": ([1.0, 2.0, 3.0, 4.0, 5.0], "m/s")})


# --------------------------------------------------------------------------- grid


def test_grid_order_units_and_points() -> None:
    g = small_grid()
    assert g.names == ("width", "speed") and g.shape == (4, 5) and g.size == 20
    assert g.units == {"width": "m", "speed": "m/s"}
    pts = [g.point(i) for i in range(g.size)]
    expected = [{"width": w, "speed": s} for w, s in itertools.product(g["width"].values, g["speed"].values)]
    assert pts == expected  # C order: last axis fastest
    assert g.unravel(7) == (1, 2)
    with pytest.raises(IndexError):
        g.point(20)
    assert Grid([Axis("width", g["width"].values, "m"), Axis("speed", [1, 2, 3, 4, 5], "m/s")]) == g
    assert hash(Grid.from_spec("a=0:1:3")) == hash(Grid({"a": [0.0, 0.5, 1.0]}))
    with pytest.raises(ValueError):  # read-only values
        g["width"].values[0] = 1.0


def test_grid_from_spec() -> None:
    g = Grid.from_spec("k[N/m]=1e6:1e7:10", "c=5; z=0:1:3", units={"c": "N s/m"})
    assert g.names == ("k", "c", "z") and g.shape == (10, 1, 3)
    np.testing.assert_array_equal(g["k"].values, np.linspace(1e6, 1e7, 10))
    assert g.units == {"k": "N/m", "c": "N s/m", "z": ""}
    assert Grid.from_spec("k=2:2:1")["k"].values.tolist() == [2.0]


@pytest.mark.parametrize(
    ("spec", "fragment"),
    [
        ("k=1e7:1e6:10", "reversed range"),
        ("k=1:1:5", "empty range"),
        ("k=0:1:0", "N must be >= 1"),
        ("k=0:1:-2", "whole number"),
        ("k=0:1:2.5", "whole number"),
        ("k=a:1:3", "not a number"),
        ("k=0:nan:3", "finite"),
        ("k=1:2", "expected NAME=MIN:MAX:N"),
        ("k", "expected NAME=MIN:MAX:N"),
        ("1k=1:2:3", "not a valid axis name"),
        ("k=1:2:3 k=1:2:4", "given twice"),
        ("k=1:2:1", "ambiguous"),
    ],
)
def test_grid_spec_errors(spec: str, fragment: str) -> None:
    with pytest.raises(InputError) as err:
        Grid.from_spec(spec)
    assert fragment in str(err.value)
    assert spec.split()[-1] in str(err.value)  # the message names the spec


def test_grid_construction_errors() -> None:
    bads: list[dict[str, Any]] = [{}, {"a": []}, {"a": [1.0, np.inf]}, {"a b": [1.0]}, {"a": [[1.0, 2.0]]}]
    for bad in bads:
        with pytest.raises(InputError):
            Grid(bad)
    with pytest.raises(InputError, match="duplicate"):
        Grid([Axis("a", [1.0]), Axis("a", [2.0])])


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(1, 4), min_size=1, max_size=4), st.data())
def test_flat_index_maps_to_c_order(shape: list[int], data: st.DataObject) -> None:
    g = Grid({f"x{i}": np.arange(n) * (i + 1.5) for i, n in enumerate(shape)})
    i = data.draw(st.integers(0, g.size - 1))
    expected = list(itertools.product(*(a.values for a in g.axes)))[i]
    assert tuple(g.point(i).values()) == expected
    assert np.ravel_multi_index(g.unravel(i), g.shape) == i


# --------------------------------------------------------------------------- backends


def test_serial_and_loky_identical_bitwise(tmp_path: Path) -> None:
    g = Grid.from_spec("width=1e-3:5e-3:7", "speed=0.5:40:9", units={"width": "m", "speed": "m/s"})
    f = functools.partial(model, k=2.5e6)
    ser = sweep(f, g, outputs=OUTS, backend="serial", progress=False, attrs={"model": "demo µ"})
    lok = sweep(
        f, g, outputs=OUTS, backend="loky", jobs=2, chunk_size=5, progress=False, attrs={"model": "demo µ"}
    )
    for name in OUTS:
        assert ser[name].shape == g.shape
        assert np.array_equal(ser[name], lok[name])
        assert ser[name].tobytes() == lok[name].tobytes()
    assert ser.status == lok.status == "ok" and lok.n_computed == g.size
    ser2 = dataclasses.replace(ser, attrs={**ser.attrs, **FIXED})
    lok2 = dataclasses.replace(lok, attrs={**lok.attrs, **FIXED})
    ser2.to_netcdf(tmp_path / "s.nc")
    lok2.to_netcdf(tmp_path / "l.nc")
    assert (tmp_path / "s.nc").read_bytes() == (tmp_path / "l.nc").read_bytes()


def test_loky_workers_run_blas_single_threaded() -> None:
    r = sweep(
        blas_env, Grid({"x": np.arange(8.0)}), outputs={"omp": "", "openblas": ""}, jobs=2, progress=False
    )
    assert np.all(r["omp"] == 1) and np.all(r["openblas"] == 1)


def test_dask_local_cluster_identical(tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    g = Grid.from_spec("width=1e-3:5e-3:5", "speed=0.5:40:6")
    f = functools.partial(model, k=2.5e6)
    ref = sweep(f, g, outputs=OUTS, backend="serial", progress=False, attrs=FIXED)
    with distributed.LocalCluster(
        n_workers=2, processes=True, host="127.0.0.1", threads_per_worker=1, dashboard_address=None
    ) as cluster:
        r = sweep(
            f,
            g,
            outputs=OUTS,
            backend="dask",
            scheduler=cluster.scheduler_address,
            chunk_size=4,
            progress=False,
            attrs=FIXED,
            out=tmp_path / "d.nc",
        )
        env = sweep(
            blas_env,
            Grid({"x": np.arange(4.0)}),
            outputs={"omp": "", "openblas": ""},
            backend="dask",
            scheduler=cluster.scheduler_address,
            progress=False,
        )
    assert np.all(env["omp"] == 1) and np.all(env["openblas"] == 1)  # distributed's nanny defaults
    for name in OUTS:
        assert np.array_equal(ref[name], r[name])
    ref.to_netcdf(tmp_path / "s.nc")
    assert (tmp_path / "s.nc").read_bytes() == (tmp_path / "d.nc").read_bytes()


def test_dask_unreachable_scheduler_fails_fast() -> None:
    pytest.importorskip("distributed")
    t0 = time.monotonic()
    with pytest.raises(SweepError, match=r"cannot reach the dask scheduler at 'tcp://127.0.0.1:1'"):
        sweep(
            model,
            small_grid(),
            outputs=OUTS,
            backend="dask",
            scheduler="tcp://127.0.0.1:1",
            connect_timeout=2,
            progress=False,
        )
    assert time.monotonic() - t0 < 15


# --------------------------------------------------------------------------- failures


@pytest.mark.parametrize("backend", ["serial", "loky"])
def test_task_failure_is_recorded_and_others_kept(backend: Any, tmp_path: Path) -> None:
    g = small_grid()
    r = sweep(
        flaky, g, outputs=OUTS, backend=backend, chunk_size=3, progress=False, checkpoint=tmp_path / "ck"
    )
    assert r.status == "partial" and r.n_failed == 1
    assert "width=0.002 m, speed=2 m/s" in r.message and "LinAlgError" in r.message
    [fail] = r.failures
    assert fail.point == {"width": 2e-3, "speed": 2.0} and fail.error_type == "LinAlgError"
    assert "singular" in fail.message and g.point(fail.task_index) == fail.point
    bad = np.isnan(r["abscissa"])
    assert bad.sum() == 1 and bad[1, 1]
    assert np.allclose(r["abscissa"][~bad], np.multiply.outer(g["width"].values, g["speed"].values)[~bad])
    # the failure survives a resume from the checkpoint, and reaches the file
    again = sweep(
        flaky, g, outputs=OUTS, backend="serial", checkpoint=tmp_path / "ck", resume=True, progress=False
    )
    assert again.n_computed == 0 and again.failures == r.failures
    back = SweepResult.from_netcdf(again.to_netcdf(tmp_path / "r.nc"))
    assert back.status == "partial" and back.failures[0].point == fail.point


def test_on_error_raise_keeps_finished_chunks(tmp_path: Path) -> None:
    g = small_grid()  # the failing task is index 6, in chunk 3 of chunk_size=2
    ck = tmp_path / "ck"
    with pytest.raises(SweepError, match=r"task 6 failed at width=0.002 m, speed=2 m/s: LinAlgError"):
        sweep(
            flaky,
            g,
            outputs=OUTS,
            backend="serial",
            chunk_size=2,
            on_error="raise",
            checkpoint=ck,
            fingerprint="v1",
            progress=False,
        )
    assert sorted(p.name for p in ck.glob("chunk_*.npz")) == [f"chunk_{i:06d}.npz" for i in range(3)]
    fixed = sweep(
        flaky_fixed,
        g,
        outputs=OUTS,
        backend="serial",
        checkpoint=ck,
        resume=True,
        fingerprint="v1",
        progress=False,
    )
    assert fixed.ok and fixed.n_resumed == 6 and fixed.n_computed == 14


def flaky_fixed(width: float, speed: float) -> dict[str, float]:
    return {"abscissa": width * speed, "freq": width + speed}


def test_retry_failed_recomputes_only_failed_chunks(tmp_path: Path) -> None:
    g = small_grid()
    ck = tmp_path / "ck"
    r = sweep(
        flaky, g, outputs=OUTS, backend="serial", chunk_size=4, checkpoint=ck, fingerprint="v", progress=False
    )
    assert r.status == "partial"
    again = sweep(
        flaky_fixed,
        g,
        outputs=OUTS,
        backend="serial",
        checkpoint=ck,
        resume=True,
        retry_failed=True,
        fingerprint="v",
        progress=False,
    )
    assert again.ok and again.n_computed == 4 and again.n_resumed == 16
    assert not np.isnan(again["abscissa"]).any()


def test_dask_missing_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    with pytest.raises(SweepError, match=r"pip install chatterlab\[dask\]"):
        sweep(flaky_fixed, small_grid(), outputs=OUTS, backend="dask", progress=False)


def test_output_contract_names_the_point() -> None:
    with pytest.raises(SweepError, match=r"missing \['freq'\], unexpected \['frq'\]") as err:
        sweep(wrong_keys, small_grid(), outputs=OUTS, backend="serial", progress=False)
    assert "'width': 0.001" in str(err.value)


def test_bad_arguments() -> None:
    g = small_grid()
    with pytest.raises(InputError, match="backend"):
        sweep(model, g, outputs=OUTS, backend="threads", progress=False)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="resume=True needs checkpoint"):
        sweep(model, g, outputs=OUTS, resume=True, progress=False)
    with pytest.raises(InputError, match="same name as a grid axis"):
        sweep(model, g, outputs={"width": "m"}, progress=False)
    with pytest.raises(InputError, match="jobs"):
        sweep(model, g, outputs=OUTS, jobs=0, progress=False)


# --------------------------------------------------------------------------- checkpoint / resume


def test_checkpoint_refusals(tmp_path: Path) -> None:
    ck = tmp_path / "ck"
    g = small_grid()
    sweep(flaky_fixed, g, outputs=OUTS, backend="serial", checkpoint=ck, fingerprint="m1", progress=False)
    with pytest.raises(InputError, match="not empty: pass resume=True"):
        sweep(flaky_fixed, g, outputs=OUTS, backend="serial", checkpoint=ck, fingerprint="m1", progress=False)
    other = Grid({"width": (np.linspace(1e-3, 4e-3, 4), "m"), "speed": ([1.0, 2.0, 3.0, 4.0, 6.0], "m/s")})
    with pytest.raises(InputError, match=r"different sweep: grid .*axis 'speed' differs"):
        sweep(
            flaky_fixed,
            other,
            outputs=OUTS,
            backend="serial",
            checkpoint=ck,
            resume=True,
            fingerprint="m1",
            progress=False,
        )
    with pytest.raises(InputError, match="fingerprint differs"):
        sweep(
            flaky_fixed,
            g,
            outputs=OUTS,
            backend="serial",
            checkpoint=ck,
            resume=True,
            fingerprint="m2",
            progress=False,
        )
    with pytest.raises(InputError, match="outputs"):
        sweep(
            flaky_fixed,
            g,
            outputs={"abscissa": "1/s", "freq": "rad/s"},
            backend="serial",
            checkpoint=ck,
            resume=True,
            fingerprint="m1",
            progress=False,
        )
    with pytest.raises(InputError, match="chunk_size"):
        sweep(
            flaky_fixed,
            g,
            outputs=OUTS,
            backend="serial",
            checkpoint=ck,
            resume=True,
            fingerprint="m1",
            chunk_size=7,
            progress=False,
        )
    # the automatic fingerprint tells partial arguments apart
    ck2 = tmp_path / "ck2"
    sweep(functools.partial(model, k=1e6), g, outputs=OUTS, backend="serial", checkpoint=ck2, progress=False)
    with pytest.raises(InputError, match="fingerprint"):
        sweep(
            functools.partial(model, k=2e6),
            g,
            outputs=OUTS,
            backend="serial",
            checkpoint=ck2,
            resume=True,
            progress=False,
        )
    # ... and resumes the same function with the same arguments (positive control)
    again = sweep(
        functools.partial(model, k=1e6), g, outputs=OUTS, backend="serial", checkpoint=ck2, resume=True,
        progress=False,
    )  # fmt: skip
    assert again.n_resumed == g.size and again.n_computed == 0
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "x.txt").write_text("x")
    with pytest.raises(InputError, match="not a chatterlab sweep checkpoint"):
        sweep(
            model,
            g,
            outputs=OUTS,
            backend="serial",
            checkpoint=tmp_path / "junk",
            resume=True,
            progress=False,
        )


def test_refused_resume_names_what_changed(tmp_path: Path) -> None:
    g = small_grid()
    run = functools.partial(sweep, flaky_fixed, g, outputs=OUTS, backend="serial", progress=False)
    run(checkpoint=tmp_path / "a", fingerprint={"model": "3f2a", "--terms": "pdo", "--width-max": "5"})
    with pytest.raises(InputError, match=r"fingerprint differs \(--terms is 'pdo' there, 'o' now\)"):
        run(
            checkpoint=tmp_path / "a",
            resume=True,
            fingerprint={"model": "3f2a", "--terms": "o", "--width-max": "5"},
        )
    run(checkpoint=tmp_path / "b", fingerprint="3f2a|b-lim|pdo")
    with pytest.raises(InputError, match=r"part 3 of 3: 'pdo' there, 'o' now"):
        run(checkpoint=tmp_path / "b", resume=True, fingerprint="3f2a|b-lim|o")
    with pytest.raises(
        InputError, match=r"fingerprint differs \(of another form: text there, named entries now\)"
    ):
        run(checkpoint=tmp_path / "b", resume=True, fingerprint={"model": "3f2a"})
    with pytest.raises(InputError, match="fingerprint must be a string or a mapping"):
        run(fingerprint=3)


def test_checkpoint_of_an_earlier_automatic_fingerprint_is_refused(tmp_path: Path) -> None:
    """chatterlab 0.1 hashed pickled bytecode; its automatic fingerprint cannot be
    recomputed, so such a checkpoint is refused in one line that says how to start afresh."""
    g = small_grid()
    ck = tmp_path / "ck"
    f = functools.partial(model, k=1e6)
    sweep(f, g, outputs=OUTS, backend="serial", checkpoint=ck, progress=False)
    manifest = json.loads((ck / "manifest.json").read_text())
    assert manifest["fingerprint_source"] == "auto" and manifest.pop("fingerprint_method")
    (ck / "manifest.json").write_text(json.dumps(manifest))  # as 0.1 wrote it
    with pytest.raises(InputError) as exc:
        sweep(f, g, outputs=OUTS, backend="serial", checkpoint=ck, resume=True, progress=False)
    msg = str(exc.value)
    assert "\n" not in msg and "earlier chatterlab" in msg
    assert (
        "start afresh" in msg and "--checkpoint DIR" in msg and "without resume=True (CLI: --resume)" in msg
    )
    # a caller's fingerprint (the CLI's) is compared as before: such checkpoints still resume
    sweep(f, g, outputs=OUTS, backend="serial", checkpoint=tmp_path / "c", fingerprint="m", progress=False)
    r = sweep(
        f,
        g,
        outputs=OUTS,
        backend="serial",
        checkpoint=tmp_path / "c",
        resume=True,
        fingerprint="m",
        progress=False,
    )
    assert r.n_resumed == g.size


def test_caller_fingerprint_changed_with_the_version_says_so(tmp_path: Path) -> None:
    """The CLI's model fingerprint is a joblib.hash now (0.1: sha256 of the text):
    its old checkpoints are refused in one line naming the cause and how to start afresh."""
    g = small_grid()
    ck = tmp_path / "ck"
    sweep(
        flaky_fixed,
        g,
        outputs=OUTS,
        backend="serial",
        checkpoint=ck,
        fingerprint="9c1e|b-lim",
        progress=False,
    )
    manifest = json.loads((ck / "manifest.json").read_text())
    assert manifest.pop("chatterlab") == chatterlab.__version__
    (ck / "manifest.json").write_text(json.dumps(manifest))  # as 0.1 wrote it
    with pytest.raises(InputError) as exc:
        sweep(
            flaky_fixed, g, outputs=OUTS, backend="serial", checkpoint=ck, resume=True,
            fingerprint="41d7|b-lim", progress=False,
        )  # fmt: skip
    msg = str(exc.value)
    assert "\n" not in msg and "part 1 of 2: '9c1e' there, '41d7' now" in msg
    assert "written by an earlier chatterlab, whose fingerprints may be computed differently" in msg
    # the engine's way out, which the CLI replaces by its options (cli/_parallel.py)
    assert msg.endswith(
        "; use another checkpoint directory or delete this one (resume only continues the same sweep)"
    )


def test_model_fingerprint_sees_the_matrix_files(tmp_path: Path) -> None:
    """A [matrices] model reads M from M.npy: the model file alone does not define
    the model, so the checkpoint fingerprint hashes the matrices by content."""
    from chatterlab.quantities import model_fingerprint

    np.save(tmp_path / "M.npy", np.diag([1.0, 1.0]))
    text = (
        '[matrices]\ncoordinates = ["q1", "q2"]\nM = "M.npy"\nK = [[2.0e6, -1.0e6], [-1.0e6, 1.0e6]]\n'
        '[process]\nkind = "turning"\nrpm = 1500\n'
    )
    (tmp_path / "m.toml").write_text(text)
    a = model_fingerprint(chatterlab.load_model(tmp_path / "m.toml"))
    assert model_fingerprint(chatterlab.load_model(tmp_path / "m.toml")) == a  # deterministic
    np.save(tmp_path / "M.npy", np.diag([1.0, 1.0 + 2**-52]))  # one ulp in one entry
    b = model_fingerprint(chatterlab.load_model(tmp_path / "m.toml"))
    assert b != a and len(a) == len(b) == 16
    np.save(tmp_path / "M.npy", np.diag([1.0, 1.0]))
    assert model_fingerprint(chatterlab.load_model(tmp_path / "m.toml")) == a


def test_automatic_fingerprint_is_the_same_in_another_process() -> None:
    """joblib.hash is deterministic: a fresh interpreter (other string-hash seed) agrees."""
    code = (
        "import functools, numpy as np; from chatterlab.errors import check_width; "
        "from chatterlab.sweep._checkpoint import _auto_fingerprint; "
        "print(_auto_fingerprint(functools.partial(check_width, name='w', unit={'a': np.arange(3.0), 'b': 1})))"
    )
    outs = []
    for seed in ("1", "2"):
        env = {**os.environ, "PYTHONPATH": str(ROOT), "PYTHONHASHSEED": seed}
        outs.append(
            subprocess.run(
                [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
            ).stdout
        )
    assert outs[0] == outs[1] and len(outs[0].strip()) == 40


def test_keyboard_interrupt_then_resume(tmp_path: Path) -> None:
    g = small_grid()
    ref = sweep(model, g, outputs=OUTS, backend="serial", progress=False)
    calls = {"n": 0}

    def interrupted(width: float, speed: float) -> dict[str, float]:
        calls["n"] += 1
        if calls["n"] == 8:  # inside chunk 2 (tasks 6-8)
            raise KeyboardInterrupt
        return model(width, speed)

    ck = tmp_path / "ck"
    with pytest.raises(SweepInterrupted) as err:
        sweep(
            interrupted,
            g,
            outputs=OUTS,
            backend="serial",
            chunk_size=3,
            checkpoint=ck,
            fingerprint="model-v1",
            progress=False,
        )
    msg = str(err.value)
    assert "2 of 7 chunks done (6 of 20 points); saved in" in msg and "resume=True" in msg and str(ck) in msg
    assert isinstance(err.value, KeyboardInterrupt) and err.value.done == 2

    calls["n"] = -1000  # no more interrupts; count the resumed calls
    r = sweep(
        interrupted,
        g,
        outputs=OUTS,
        backend="serial",
        checkpoint=ck,
        resume=True,
        fingerprint="model-v1",
        progress=False,
    )
    assert calls["n"] == -1000 + 14 and r.n_computed == 14 and r.n_resumed == 6
    for name in OUTS:
        assert np.array_equal(ref[name], r[name])


SCRIPT = textwrap.dedent(
    """
    import sys, time
    import numpy as np
    from chatterlab.sweep._engine import Grid, sweep

    def slow(x, y):
        time.sleep(0.06)
        return {"u": np.sin(x) * y, "v": x + y}

    if __name__ == "__main__":
        g = Grid.from_spec("x=0:3:6", "y=1:2:4")
        try:
            sweep(slow, g, outputs={"u": "", "v": ""}, backend="loky", jobs=2, chunk_size=2,
                  checkpoint=sys.argv[1], fingerprint="slow-v1", progress=True)
        except KeyboardInterrupt as exc:
            print("INTERRUPTED:", exc, file=sys.stderr)
            sys.exit(130)
    """
)


def fast(x: float, y: float, log: Path) -> dict[str, float]:
    """Same values as the script's ``slow``; leaves one file per call."""
    (log / f"{x!r}_{y!r}").touch()
    return {"u": np.sin(x) * y, "v": x + y}


def _start_script(tmp_path: Path, ck: Path) -> subprocess.Popen[str]:
    script = tmp_path / "run_sweep.py"
    script.write_text(SCRIPT)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.Popen(
        [sys.executable, str(script), str(ck)],
        env=env,
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def _wait_for_chunks(proc: subprocess.Popen[str], ck: Path, n: int, timeout: float = 60) -> int:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        k = len(list(ck.glob("chunk_*.npz"))) if ck.exists() else 0
        if k >= n:
            return k
        if proc.poll() is not None:
            pytest.fail(f"sweep script ended early: {proc.communicate()[1]}")
        time.sleep(0.02)
    _kill_group(proc)
    pytest.fail("no chunks written in time")


def _kill_group(proc: subprocess.Popen[str]) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.communicate()


def _resume_and_check(tmp_path: Path, ck: Path) -> None:
    done = len(list(ck.glob("chunk_*.npz")))
    assert 0 < done < 12
    log = tmp_path / "calls"
    log.mkdir()
    g = Grid.from_spec("x=0:3:6", "y=1:2:4")
    f = functools.partial(fast, log=log)
    r = sweep(
        f,
        g,
        outputs={"u": "", "v": ""},
        backend="serial",
        checkpoint=ck,
        resume=True,
        fingerprint="slow-v1",
        progress=False,
    )
    ref = sweep(
        functools.partial(fast, log=tmp_path), g, outputs={"u": "", "v": ""}, backend="serial", progress=False
    )
    assert r.n_resumed == 2 * done and r.n_computed == 24 - 2 * done
    assert len(list(log.iterdir())) == r.n_computed  # only the missing chunks were computed
    assert not [p for p in ck.iterdir() if ".tmp-" in p.name]
    for name in ("u", "v"):
        assert np.array_equal(ref[name], r[name])
    a = dataclasses.replace(r, attrs=FIXED)
    b = dataclasses.replace(ref, attrs=FIXED)
    assert a.to_netcdf(tmp_path / "a.nc").read_bytes() == b.to_netcdf(tmp_path / "b.nc").read_bytes()


def test_sigkill_midway_then_resume(tmp_path: Path) -> None:
    ck = tmp_path / "ck"
    proc = _start_script(tmp_path, ck)
    try:
        _wait_for_chunks(proc, ck, 3)
    finally:
        _kill_group(proc)  # the sweep and its loky workers
    assert proc.returncode == -signal.SIGKILL
    _resume_and_check(tmp_path, ck)


def test_sigint_midway_stops_cleanly_then_resume(tmp_path: Path) -> None:
    ck = tmp_path / "ck"
    proc = _start_script(tmp_path, ck)
    try:
        _wait_for_chunks(proc, ck, 3)
        os.killpg(proc.pid, signal.SIGINT)  # Ctrl-C: the sweep and its workers get SIGINT
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            _kill_group(proc)
    assert proc.returncode == 130, err
    assert "INTERRUPTED: sweep interrupted:" in err and "of 12 chunks done" in err
    assert "resume=True (CLI: --resume)" in err
    assert "24 points in 12 chunks of 2" in err  # progress header on a non-TTY stderr
    _resume_and_check(tmp_path, ck)


# --------------------------------------------------------------------------- files


def test_netcdf_round_trip(tmp_path: Path) -> None:
    coords = {"width": (np.array([1e-3, 2e-3, 3e-3]), "m"), "speed": (np.array([1.0, 2.5]), "m/s")}
    freq = np.arange(6.0).reshape(3, 2) / 7
    data = {
        "freq": (freq, "Hz", "chatter frequency"),
        "stable": (freq > 0.3, ""),
        "depth": (np.arange(8.0).reshape(4, 2), "m", "lobe depth", ("lobe", "speed")),
    }
    attrs = {
        "model": "beam µm °C\nline 2",
        "n": 3,
        "tol": 1e-9,
        "big": 2**40,
        "weights": [0.5, 1.5],
    }
    p = write_netcdf(tmp_path / "r.nc", coords, data, attrs)
    assert not [q for q in tmp_path.iterdir() if ".tmp-" in q.name]
    f = read_netcdf(p)
    assert list(f.coords) == ["width", "speed"]
    assert f.coords["speed"][1] == "m/s" and np.array_equal(f.coords["width"][0], coords["width"][0])
    arr, unit, long_name = f.data["freq"]
    assert arr.tobytes() == freq.tobytes() and unit == "Hz" and long_name == "chatter frequency"
    assert f.dims["depth"] == ("lobe", "speed") and f.data["stable"][0].dtype == np.int8
    assert f.attrs["model"] == attrs["model"] and f.attrs["n"] == 3 and f.attrs["tol"] == 1e-9
    assert f.attrs["big"] == 2**40 and f.attrs["weights"].tolist() == [0.5, 1.5]
    assert {"chatterlab_version", "created", "command_line"} <= set(f.attrs)
    m = read_netcdf(p, mmap=True)
    assert isinstance(m.data["freq"][0], np.memmap) and np.array_equal(m.data["freq"][0], freq)
    with pytest.raises(InputError, match="'_NCProperties' is reserved"):
        write_netcdf(tmp_path / "c.nc", coords, data, {"_NCProperties": "x"})
    with pytest.raises(InputError, match="'lobe' has the name of one of its dimensions"):
        write_netcdf(tmp_path / "c.nc", coords, {"lobe": (np.zeros((4, 2)), "m", "", ("lobe", "speed"))})
    with pytest.raises(InputError, match="complex"):
        write_netcdf(tmp_path / "c.nc", coords, {"h": (freq + 1j, "")})
    with pytest.raises(InputError, match="shape"):
        write_netcdf(tmp_path / "c.nc", coords, {"h": (freq.T, "")})
    import xarray as xr  # a dependency of chatterlab: an import error fails, never skips

    with xr.open_dataset(p) as ds:
        assert ds["freq"].attrs["units"] == "Hz" and ds["width"].attrs["units"] == "m"
        assert ds.attrs["model"] == attrs["model"]
        np.testing.assert_array_equal(ds["freq"].values, freq)


def test_csv_long_format(tmp_path: Path) -> None:
    g = small_grid()
    r = sweep(flaky, g, outputs=OUTS, backend="serial", progress=False)
    p = r.to_csv(tmp_path / "r.csv")
    rows = list(csv.reader(p.open()))
    assert rows[0] == ["width [m]", "speed [m/s]", "abscissa [1/s]", "freq [Hz]", "task_status", "reason"]
    assert len(rows) == 1 + g.size
    for i, row in enumerate(rows[1:]):
        pt = g.point(i)
        assert [float(v) for v in row[:2]] == [pt["width"], pt["speed"]]
        if i == 6:
            assert row[2] == "nan"
            assert row[4] == "failed" and row[5] == f"{r.failures[0].error_type}: {r.failures[0].message}"
        else:
            assert float(row[2]) == r["abscissa"].reshape(-1)[i]  # exact round trip
            assert row[4:] == ["ok", ""]
    write_csv(tmp_path / "t.csv", {"time": (np.array([0.0, 0.5]), "s")}, {"x": (np.array([1.0, 2.0]), "m")})
    assert (tmp_path / "t.csv").read_text() == "time [s],x [m]\n0.0,1.0\n0.5,2.0\n"


def test_streaming_out_file(tmp_path: Path) -> None:
    g = small_grid()
    out = tmp_path / "sub" / "sweep.nc"
    r = sweep(flaky, g, outputs=OUTS, backend="loky", chunk_size=3, out=out, attrs=FIXED, progress=False)
    assert isinstance(r["freq"], np.memmap) and r.status == "partial"
    assert sorted(p.name for p in out.parent.iterdir()) == ["sweep.nc"]  # scratch removed
    ref = sweep(flaky, g, outputs=OUTS, backend="serial", attrs=FIXED, progress=False)
    assert ref.to_netcdf(tmp_path / "ref.nc").read_bytes() == out.read_bytes()
    back = SweepResult.from_netcdf(out)
    assert back.grid == g and back.units == OUTS and back.status == "partial" and back.n_failed == 1
    assert np.array_equal(back["abscissa"], ref["abscissa"], equal_nan=True)


def test_progress_lines_on_non_tty(capsys: pytest.CaptureFixture[str]) -> None:
    sweep(flaky_fixed, small_grid(), outputs=OUTS, backend="serial", chunk_size=2, progress=True)
    err = capsys.readouterr().err
    assert "20 points in 10 chunks of 2, 1 process" in err
    lines = [ln for ln in err.splitlines() if "%" in ln]
    assert len(lines) == 1 and lines[0].startswith("sweep: 100% (20/20 points")  # one line at the end
    assert "\r" not in err  # no bar in a log file
    sweep(flaky_fixed, small_grid(), outputs=OUTS, backend="serial", progress=False)
    assert capsys.readouterr().err == ""


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_on_a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    term = _Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    g = small_grid()
    sweep(flaky_fixed, g, outputs=OUTS, backend="serial", chunk_size=2, progress=True)
    out = term.getvalue()
    assert "20 points in 10 chunks of 2, 1 process" in out
    assert "\r" in out and f"{g.size}/{g.size}" in out.rsplit("\r", 1)[-1]  # tqdm's last state: all done
    term.truncate(0)
    sweep(flaky_fixed, g, outputs=OUTS, backend="serial", progress=False)
    assert term.getvalue() == ""


def test_plot_and_dataset(tmp_path: Path) -> None:
    mpl = pytest.importorskip("matplotlib")
    mpl.use("Agg")
    r = sweep(flaky_fixed, small_grid(), outputs=OUTS, backend="serial", progress=False)
    ax = r.plot("freq")
    assert (
        ax.get_xlabel() == "speed [m/s]" and ax.get_ylabel() == "width [mm]"
    )  # lengths shown in mm (plot_sweep)
    assert ax.figure.axes[-1].get_ylabel() == "freq [Hz]"  # the colour bar
    ax = r.plot("freq", at={"width": 2e-3})
    assert ax.get_xlabel() == "speed [m/s]" and ax.get_ylabel() == "freq [Hz]"
    import xarray as xr

    ds = r.to_xarray()
    assert isinstance(ds, xr.Dataset) and ds["freq"].attrs["units"] == "Hz" and ds.attrs["status"] == "ok"
    assert ds.identical(r.to_xarray())


def test_import_is_light() -> None:
    code = (
        "import sys, chatterlab.sweep._engine, chatterlab.io._netcdf; "
        "print(sorted(m for m in ('joblib', 'dask', 'distributed', 'matplotlib', 'tqdm', 'xarray') "
        "if m in sys.modules))"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize(("verdict", "code"), [("stable", 1.0), ("unstable", 0.0), ("undetermined", None),
                                               ("marginal", None)])  # fmt: skip
def test_stable_quantity_never_counts_undetermined_with_either(verdict, code, monkeypatch, tmp_path):
    """The 'stable' output is 1 / 0 for a proven verdict and NaN otherwise (an
    undetermined point was 0, the same as a proven chatter)."""
    import types

    import chatterlab as cl
    import chatterlab.frequency._stability as st
    from chatterlab.quantities._tasks import QuantityTask
    from tests.conftest import turning_text

    m = tmp_path / "t.toml"
    m.write_text(turning_text())
    monkeypatch.setattr(
        st, "stability", lambda *a, **k: types.SimpleNamespace(verdict=verdict, abscissa=-1.0)
    )
    out = QuantityTask(cl.load_model(m), "stable")(width=1e-3, speed=3000.0)
    assert (np.isnan(out["stable"]) if code is None else out["stable"] == code) and out["abscissa"] == -1.0
