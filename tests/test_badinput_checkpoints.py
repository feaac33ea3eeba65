"""Issue 21, the sweep engine's inputs: checkpoints, grids, the cost caps and
a dask scheduler that answers garbage.

* A checkpoint manifest is checked field by field at the edge: a list, a
  missing key, zero chunks (AttributeError, KeyError, ZeroDivisionError
  before) are one line naming the manifest file, the field and the fix
  (remove the folder, or run without --resume), status 2.
* A damaged or foreign chunk file (truncated, zero bytes, not an archive, of
  other shapes, copied from another sweep) is recomputed with one
  ``chatterlab: warning:`` line (raw Python warnings before): a chunk is a
  cache of work that the manifest defines, so recomputing it loses nothing,
  and the result equals the clean run's.  A chunk name that is a folder
  cannot be replaced: refused in one line.
* Every knob whose work grows without bound has a cap: a grid axis count
  (a 400-digit count was "Maximum allowed size exceeded", status 3), the
  grid's size, ``lobes --points``, ``--positions N``, ``--jobs``.
* A dask address that answers garbage, or nothing, is one line within the
  connect timeout (was 20 s, then a traceback).
* Hypothesis: random damage to a checkpoint ends with status 0, 1 or 2 and
  chatterlab's own lines (never 3, never a traceback) within a time bound,
  and a completed resume equals the clean run.
"""

from __future__ import annotations

import json
import shutil
import socket
import struct
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import turning_text
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from chatterlab.cli._main import main
from chatterlab.errors import InputError, SweepError
from chatterlab.sweep import Grid, sweep

TURNING = turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning")
SWEEP = ["--quantity", "stable", "--width", "0.5", "--grid", "speed=3000:9000:4", "--backend", "serial", "--quiet"]  # fmt: skip
BOUND = 60.0  # s for one run, on 2 loaded cores (a clean one takes ~0.3 s)


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """The model, a complete checkpoint of the sweep (4 chunks) and its CSV."""
    tmp = tmp_path_factory.mktemp("clean")
    model = tmp / "t.toml"
    model.write_text(TURNING)
    out, ck = tmp / "clean.csv", tmp / "ck"
    assert main(["sweep", str(model), *SWEEP, "--out", str(out), "--checkpoint", str(ck)]) == 0
    assert sorted(p.name for p in ck.glob("chunk_*.npz")) == [f"chunk_00000{i}.npz" for i in range(4)]
    return {"model": model, "ck": ck, "csv": out.read_bytes(), "dir": tmp}


def resume(capsys, model: Path, ck: Path, out: Path) -> tuple[int, str, float]:
    t0 = time.monotonic()
    code = main(["sweep", str(model), *SWEEP, "--out", str(out), "--checkpoint", str(ck), "--resume"])
    return code, capsys.readouterr().err, time.monotonic() - t0


def copy_of(clean, tmp: Path) -> Path:
    ck = tmp / "ck"
    shutil.copytree(clean["ck"], ck)
    return ck


def one_error(code: int, err: str, *words: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("chatterlab: error: "), err
    for w in words:
        assert w in lines[0], (w, err)
    return lines[0]


# ============================================================================ the manifest


def _drop(key):
    def f(m):
        del m[key]
        return m

    return f


def _set(key, value):
    def f(m):
        m[key] = value
        return m

    return f


MANIFESTS = {
    # name: (what the manifest becomes, the field the refusal names)
    "a list": (lambda m: [m], "not a JSON object"),
    "null": (lambda m: None, "null"),
    "a number": (lambda m: 5, "not a JSON object"),
    "no grid": (_drop("grid"), "'grid' is missing"),
    "no outputs": (_drop("outputs"), "'outputs' is missing"),
    "no chunk_size": (_drop("chunk_size"), "'chunk_size' is missing"),
    "no n_tasks": (_drop("n_tasks"), "'n_tasks' is missing"),
    "no fingerprint": (_drop("fingerprint"), "'fingerprint' is missing"),
    "no version": (_drop("version"), "'version' is missing"),
    "no format": (_drop("format"), "'format' is missing"),
    "zero chunks": (_set("chunk_size", 0), "'chunk_size' must be a whole number >= 1 (got 0)"),
    "negative chunks": (_set("chunk_size", -3), "'chunk_size'"),
    "chunks as text": (_set("chunk_size", "1"), "'chunk_size'"),
    "fractional chunks": (_set("chunk_size", 1.5), "'chunk_size'"),
    "chunks true": (_set("chunk_size", True), "'chunk_size'"),
    "a 400-digit chunk size": (_set("chunk_size", 10**400), "'chunk_size'"),
    "wrong task count": (_set("n_tasks", 7), "'n_tasks' must be the number of grid points, 4"),
    "outputs a list": (_set("outputs", ["stable"]), "'outputs'"),
    "grid as text": (_set("grid", "x"), "'grid'"),
    "no axes": (_set("grid", {"axes": []}), "'grid'"),
    "axis values text": (_set("grid", {"axes": [{"name": "speed", "unit": "rpm", "values": "abc"}]}), "'values'"),
    "axis values NaN": (_set("grid", {"axes": [{"name": "speed", "unit": "rpm", "values": [float("nan")]}]}), "finite"),  # noqa: E501
    "axis name bad": (_set("grid", {"axes": [{"name": "1x", "values": [1.0]}]}), "'name'"),
    "fingerprint a list": (_set("fingerprint", [1, 2]), "'fingerprint'"),
    "version text": (_set("version", "1"), "'version'"),
    "source unknown": (_set("fingerprint_source", "moon"), "'fingerprint_source'"),
}  # fmt: skip
RAW = {"invalid JSON": "{not json", "empty": "", "not UTF-8": b"\xff\xfe{", "deep": "[" * 100_000}


@pytest.mark.parametrize("name", sorted(MANIFESTS) + sorted(RAW))
def test_a_damaged_manifest_is_one_line_naming_the_file_the_field_and_the_fix(tmp_path, clean, capsys, name):
    ck = copy_of(clean, tmp_path)
    mpath = ck / "manifest.json"
    if name in RAW:
        raw = RAW[name]
        mpath.write_bytes(raw if isinstance(raw, bytes) else raw.encode())
        field = "manifest.json"
    else:
        mutate, field = MANIFESTS[name]
        mpath.write_text(json.dumps(mutate(json.loads(mpath.read_text()))))
    before = {p.name: p.read_bytes() for p in ck.iterdir() if p.is_file()}
    code, err, elapsed = resume(capsys, clean["model"], ck, tmp_path / "o.csv")
    one_error(code, err, str(mpath), field, "--resume", f"remove the folder {str(ck)!r}")
    assert "internal error" not in err and elapsed < BOUND
    # nothing of the checkpoint is touched, and no output written
    assert {p.name: p.read_bytes() for p in ck.iterdir() if p.is_file() and p.name != ".lock"} == {
        k: v for k, v in before.items() if k != ".lock"
    }
    assert not (tmp_path / "o.csv").exists()


def test_a_damaged_manifest_through_the_python_api_says_how_in_its_words(tmp_path, clean):
    ck = copy_of(clean, tmp_path)
    (ck / "manifest.json").write_text("[]")
    with pytest.raises(InputError, match=r"manifest.json'.*the checkpoint is damaged.*resume=True"):
        sweep(
            _y, {"x": [1.0]}, outputs={"y": ""}, checkpoint=ck, resume=True, backend="serial", progress=False
        )


def _y(x: float) -> dict[str, float]:
    return {"y": 2 * x}


# ============================================================================ the chunks


def _chunk(ck: Path, i: int = 1) -> Path:
    return ck / f"chunk_{i:06d}.npz"


def _savez(path: Path, **arrays) -> None:
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def _arrays(start=1, stop=2, values=None, fi=(), ft=(), fm=()):
    return dict(
        start=np.int64(start), stop=np.int64(stop),
        values=np.zeros((2, stop - start)) if values is None else values,
        failed_index=np.asarray(fi, dtype=np.int64), failed_type=np.asarray(ft, dtype=np.str_),
        failed_message=np.asarray(fm, dtype=np.str_),
    )  # fmt: skip


CHUNKS = {
    "truncated": lambda ck: _chunk(ck).write_bytes(_chunk(ck).read_bytes()[:200]),
    "zero bytes": lambda ck: _chunk(ck).write_bytes(b""),
    "text": lambda ck: _chunk(ck).write_text("hello\n" * 20),
    "a foreign archive": lambda ck: _savez(_chunk(ck), a=np.arange(3)),
    "pickled objects": lambda ck: _savez(_chunk(ck), **{**_arrays(), "start": np.array([object()], dtype=object)}),
    "other shapes": lambda ck: _savez(_chunk(ck), **_arrays(values=np.zeros((3, 1)))),
    "other bounds": lambda ck: _savez(_chunk(ck), **_arrays(start=2, stop=3)),
    "a failure outside it": lambda ck: _savez(_chunk(ck), **_arrays(fi=[77], ft=["X"], fm=["m"])),
    "failures mismatched": lambda ck: _savez(_chunk(ck), **_arrays(fi=[1], ft=["X", "Y"], fm=["m"])),
    "values as text": lambda ck: _savez(_chunk(ck), **_arrays(values=np.array([["a"], ["b"]]))),
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(CHUNKS))
def test_a_damaged_chunk_is_recomputed_with_one_chatterlab_warning(tmp_path, clean, capsys, name):
    ck = copy_of(clean, tmp_path)
    CHUNKS[name](ck)
    out = tmp_path / "o.csv"
    code, err, elapsed = resume(capsys, clean["model"], ck, out)
    assert code == 0, err
    lines = err.strip().splitlines()
    warns = [ln for ln in lines if "warning" in ln.lower()]
    assert len(warns) == 1 and warns[0].startswith("chatterlab: warning: checkpoint "), err
    assert "chunk_000001.npz" in warns[0] and "recomputed" in warns[0], err
    assert all(ln.startswith(("chatterlab: warning:", "wrote ")) for ln in lines), err
    assert out.read_bytes() == clean["csv"] and elapsed < BOUND


def test_a_chunk_copied_from_another_sweep_is_recomputed(tmp_path, clean, capsys):
    """Same grid, same outputs, another model: its chunk has the right shape
    but another sweep's identity."""
    other = tmp_path / "other.toml"
    other.write_text(turning_text(mass=3.0, stiffness=2.0e7, damping=400.0, name="another"))
    ck2 = tmp_path / "ck2"
    assert main(["sweep", str(other), *SWEEP, "--checkpoint", str(ck2)]) == 0
    capsys.readouterr()
    ck = copy_of(clean, tmp_path)
    shutil.copy(_chunk(ck2, 2), _chunk(ck, 2))
    code, err, _ = resume(capsys, clean["model"], ck, tmp_path / "o.csv")
    assert code == 0 and "chunk_000002.npz: was written by another sweep" in err, err
    assert (tmp_path / "o.csv").read_bytes() == clean["csv"]


def test_deleted_chunks_and_stray_files_resume_to_the_clean_result(tmp_path, clean, capsys):
    ck = copy_of(clean, tmp_path)
    _chunk(ck, 0).unlink()
    _chunk(ck, 3).unlink()
    shutil.copy(_chunk(ck, 1), _chunk(ck, 99))  # beyond the grid: ignored
    (ck / "notes.txt").write_text("mine")
    code, err, _ = resume(capsys, clean["model"], ck, tmp_path / "o.csv")
    assert code == 0 and "warning" not in err, err
    assert (tmp_path / "o.csv").read_bytes() == clean["csv"]


def test_a_chunk_name_that_is_a_folder_is_refused_in_one_line(tmp_path, clean, capsys):
    ck = copy_of(clean, tmp_path)
    _chunk(ck).unlink()
    _chunk(ck).mkdir()
    code, err, _ = resume(capsys, clean["model"], ck, tmp_path / "o.csv")
    one_error(code, err, "chunk_000001.npz is not a regular file", "remove it")


# ============================================================================ cost caps


CAPS = {
    "a 400-digit count": (["sweep", "{m}", "--quantity", "b-lim", "--grid", "speed=3000:9000:1" + "0" * 400], ["--grid 'speed=3000:9000:1000", "a 401-digit number", "10000000"]),  # noqa: E501
    "a 5000-digit count": (["sweep", "{m}", "--quantity", "b-lim", "--grid", "speed=3000:9000:" + "7" * 5000], ["--grid", "10000000"]),  # noqa: E501
    "2e7 points on an axis": (["sweep", "{m}", "--quantity", "b-lim", "--grid", "speed=3000:9000:20000000"], ["N = 20000000 points", "10000000"]),  # noqa: E501
    "a grid of 2.5e7 points": (["sweep", "{m}", "--quantity", "stable", "--grid", "speed=3000:9000:5000", "--grid", "width=0.1:1:5000"], ["--grid: 5000 x 5000 = 25000000 points", "10000000"]),  # noqa: E501
    "lobes --points 1e8": (["lobes", "{m}", "--speed", "3000", "9000", "--points", "100000000"], ["--points 100000000", "100000"]),  # noqa: E501
    "atlas of 1e9 positions": (["lobes", "{m}", "--speed", "3000", "9000", "--positions", "0", "0.1", "1e9"], ["--positions N", "10000 positions"]),  # noqa: E501
    "atlas of 2.5e7 points": (["lobes", "{m}", "--speed", "3000", "9000", "--points", "5000", "--positions", "0", "0.1", "5000"], ["5000 x 5000", "10000000"]),  # noqa: E501
    "--jobs 100000": (["sweep", "{m}", "--quantity", "b-lim", "--grid", "speed=3000:9000:3", "--jobs", "100000"], ["--jobs 100000", "4 per core"]),  # noqa: E501
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(CAPS))
def test_every_knob_whose_work_grows_has_a_cap_named_in_one_line(tmp_path, capsys, monkeypatch, name):
    (tmp_path / "t.toml").write_text(TURNING)
    monkeypatch.chdir(tmp_path)
    argv, words = CAPS[name]
    t0 = time.monotonic()
    code = main([a.replace("{m}", "t.toml") for a in argv] + ["--out", "o.nc"])
    err = capsys.readouterr().err
    one_error(code, err, *words)
    assert len(err) < 600, err  # the 5000-digit option is not echoed whole
    assert time.monotonic() - t0 < 20
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.toml"]  # refused before the work: no checkpoint


def test_the_python_api_caps_grids_before_the_work():
    with pytest.raises(InputError, match="a 400-digit number points is more than the largest accepted"):
        Grid.from_spec("k=1:2:" + "9" * 400)
    calls = []
    with pytest.raises(InputError, match="4000 x 4000 = 16000000 points, more than the largest"):
        sweep(lambda a, b: calls.append(1) or {"y": 1.0}, {"a": np.arange(4000.0), "b": np.arange(4000.0)},
              outputs={"y": ""}, backend="serial", progress=False)  # fmt: skip
    assert calls == []
    with pytest.raises(InputError, match=r"jobs=100000 is more than the largest accepted"):
        sweep(_y, {"x": [1.0]}, outputs={"y": ""}, jobs=100000, progress=False)


# ============================================================================ a dask scheduler answering garbage


class GarbageServer:
    """A TCP server on 127.0.0.1 that answers every connection with ``mode``
    ("huge": frame lengths of exabytes, "junk": small frames of bytes that
    decode to nothing, "silent": accepts and says nothing); it stops by
    itself after ``life`` seconds."""

    def __init__(self, mode: str, life: float = 40.0) -> None:
        self.mode, self.end = mode, time.monotonic() + life
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.sock.settimeout(0.2)
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        conns = []
        while time.monotonic() < self.end:
            try:
                c, _ = self.sock.accept()
            except (TimeoutError, OSError):
                continue
            conns.append(c)
            try:
                if self.mode == "huge":
                    c.sendall(b"HTTP/1.1 200 OK garbage \x00\xff\xfe" * 64)
                elif self.mode == "junk":
                    c.sendall(struct.pack("<QQ", 1, 5) + b"\xc1\xc1\xc1\xc1\xc1")
            except OSError:
                pass
        for c in conns:
            c.close()
        self.sock.close()

    def stop(self) -> None:
        self.end = 0.0
        self.thread.join(5)


@pytest.mark.parametrize("mode", ["huge", "junk"])
def test_a_scheduler_address_answering_garbage_is_one_line_at_once(tmp_path, capsys, mode):
    pytest.importorskip("distributed")
    (tmp_path / "t.toml").write_text(TURNING)
    server = GarbageServer(mode)
    try:
        t0 = time.monotonic()
        code = main(["sweep", str(tmp_path / "t.toml"), "--quantity", "b-lim", "--grid", "speed=3000:9000:2",
                     "--backend", "dask", "--scheduler", server.address, "--quiet"])  # fmt: skip
        elapsed = time.monotonic() - t0
    finally:
        server.stop()
    err = capsys.readouterr().err
    one_error(code, err, server.address, "dask scheduler")
    assert "Traceback" not in err and elapsed < 15, (elapsed, err)


def test_a_silent_scheduler_address_is_refused_within_the_connect_timeout():
    pytest.importorskip("distributed")
    server = GarbageServer("silent")
    try:
        t0 = time.monotonic()
        with pytest.raises(SweepError, match=r"cannot reach the dask scheduler .* within 2 s"):
            sweep(_y, {"x": [1.0]}, outputs={"y": ""}, backend="dask", scheduler=server.address,
                  connect_timeout=2, progress=False)  # fmt: skip
        elapsed = time.monotonic() - t0
    finally:
        server.stop()
    assert elapsed < 8, elapsed  # was: until the peer hung up


# ============================================================================ hypothesis: random damage


def _flip(data: bytes, at: int, byte: int) -> bytes:
    if not data:
        return bytes([byte])
    at %= len(data)
    return data[:at] + bytes([byte]) + data[at + 1 :]


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-(10**30), 10**30) | st.floats() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner, max_size=3),
    max_leaves=6,
)
MANIFEST_KEYS = ["format", "version", "grid", "outputs", "chunk_size", "n_tasks", "fingerprint",
                 "fingerprint_source", "chatterlab"]  # fmt: skip

DAMAGE = st.one_of(
    st.tuples(st.just("truncate chunk"), st.integers(0, 3), st.integers(0, 2000)),
    st.tuples(st.just("zero-byte chunk"), st.integers(0, 3)),
    st.tuples(st.just("delete chunk"), st.integers(0, 3)),
    st.tuples(st.just("flip chunk byte"), st.integers(0, 3), st.integers(0, 10**6), st.integers(0, 255)),
    st.tuples(st.just("foreign file"), st.integers(0, 12), st.binary(max_size=300)),
    st.tuples(st.just("truncate manifest"), st.integers(0, 2000)),
    st.tuples(st.just("flip manifest byte"), st.integers(0, 10**6), st.integers(0, 255)),
    st.tuples(st.just("manifest value"), st.sampled_from(MANIFEST_KEYS), JSON_VALUES),
    st.tuples(st.just("drop manifest key"), st.sampled_from(MANIFEST_KEYS)),
    st.tuples(st.just("zero-byte manifest")),
)


def _damage(ck: Path, op: tuple) -> None:
    kind, *arg = op
    m = ck / "manifest.json"
    if kind == "truncate chunk" and _chunk(ck, arg[0]).exists():
        p = _chunk(ck, arg[0])
        p.write_bytes(p.read_bytes()[: arg[1]])
    elif kind == "zero-byte chunk":
        _chunk(ck, arg[0]).write_bytes(b"")
    elif kind == "delete chunk":
        _chunk(ck, arg[0]).unlink(missing_ok=True)
    elif kind == "flip chunk byte" and _chunk(ck, arg[0]).exists():
        p = _chunk(ck, arg[0])
        p.write_bytes(_flip(p.read_bytes(), arg[1], arg[2]))
    elif kind == "foreign file":
        (ck / f"chunk_{arg[0]:06d}.npz").write_bytes(arg[1])
    elif kind == "truncate manifest":
        m.write_bytes(m.read_bytes()[: arg[0]])
    elif kind == "flip manifest byte":
        m.write_bytes(_flip(m.read_bytes(), arg[0], arg[1]))
    elif kind in ("manifest value", "drop manifest key"):
        try:
            obj = json.loads(m.read_text())
        except ValueError:
            return
        if not isinstance(obj, dict):
            return
        if kind == "manifest value":
            obj[arg[0]] = arg[1]
        else:
            obj.pop(arg[0], None)
        m.write_text(json.dumps(obj))
    elif kind == "zero-byte manifest":
        m.write_bytes(b"")


@settings(
    max_examples=40,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(ops=st.lists(DAMAGE, min_size=1, max_size=4))
def test_random_checkpoint_damage_is_status_0_1_or_2_in_chatterlabs_own_lines(tmp_path, clean, capsys, ops):
    work = Path(tmp_path) / f"run-{time.monotonic_ns()}"
    work.mkdir()
    ck = copy_of(clean, work)
    for op in ops:
        _damage(ck, op)
    out = work / "o.csv"
    code, err, elapsed = resume(capsys, clean["model"], ck, out)
    assert code in (0, 1, 2), err
    assert "Traceback" not in err and "internal error" not in err, err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert elapsed < BOUND
    if code == 2:
        assert len(lines) == 1 and lines[0].startswith("chatterlab: error: "), err
        assert not out.exists()
    else:
        assert all(ln.startswith(("chatterlab: warning: ", "wrote ")) for ln in lines), err
        assert sum("warning" in ln for ln in lines) <= 1, err
        if code == 0:
            assert out.read_bytes() == clean["csv"]
    shutil.rmtree(work, ignore_errors=True)
