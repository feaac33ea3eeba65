"""Class 4 of issue 10: a sweep SIGKILLed at random moments and resumed gives
the same file as an uninterrupted run, and leaves no process and no scratch
behind; a second run on a checkpoint in use is refused (lock file)."""

from __future__ import annotations

import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import turning_text

from chatterlab.cli._main import main
from chatterlab.io._netcdf import read_netcdf

psutil = pytest.importorskip("psutil")

TURNING = turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning")
GRID = ["--quantity", "stable", "--grid", "width=0.2:1.2:8", "--grid", "speed=3000:9000:12", "--quiet"]


def gone_within(procs, seconds: float) -> list:
    t0 = time.monotonic()
    while True:
        alive = []
        for p in procs:
            try:
                if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                    alive.append(p)
            except psutil.NoSuchProcess:
                pass
        if not alive or time.monotonic() - t0 > seconds:
            return alive
        time.sleep(0.05)


def eof_within(stream, seconds: float) -> bool:
    """True when the pipe reaches end of file (every process holding it is gone)."""
    done = threading.Event()

    def read():
        stream.read()
        done.set()

    threading.Thread(target=read, daemon=True).start()
    return done.wait(seconds)


def start(model: Path, out: Path, resume: bool) -> subprocess.Popen:
    argv = [
        sys.executable,
        "-m",
        "chatterlab.cli._main",
        "sweep",
        str(model),
        *GRID,
        "--jobs",
        "2",
        "--out",
        str(out),
    ]
    return subprocess.Popen(
        argv + (["--resume"] if resume else []), stdout=subprocess.PIPE, stderr=subprocess.STDOUT
    )


@pytest.mark.slow
def test_sigkill_at_random_moments_then_resume_gives_the_same_file(tmp_path, capsys):
    model = tmp_path / "t.toml"
    model.write_text(TURNING)
    ref = tmp_path / "ref.nc"
    assert main(["sweep", str(model), *GRID, "--backend", "serial", "--out", str(ref)]) == 0
    capsys.readouterr()

    out = tmp_path / "out.nc"
    rng = random.Random(10)
    resume = False
    for _ in range(3):
        proc = start(model, out, resume)
        time.sleep(rng.uniform(0.6, 2.0))
        try:
            family = [psutil.Process(proc.pid), *psutil.Process(proc.pid).children(recursive=True)]
        except psutil.NoSuchProcess:  # it finished before the kill
            family = []
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        # nothing outlives the parent: no worker, and nobody holds its output open
        assert gone_within(family, 5.0) == []
        assert eof_within(proc.stdout, 5.0)
        proc.stdout.close()
        resume = True

    assert main(["sweep", str(model), *GRID, "--jobs", "2", "--out", str(out), "--resume"]) == 0
    a, b = read_netcdf(ref), read_netcdf(out)
    for k in ("stable", "abscissa", "task_status"):
        assert np.array_equal(a.data[k][0], b.data[k][0], equal_nan=True), k
    assert {k: v for k, v in a.attrs.items() if k not in ("created", "command_line")} == {
        k: v for k, v in b.attrs.items() if k not in ("created", "command_line")
    }
    # no checkpoint, no scratch folder, no temporary file left
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.nc", "ref.nc", "t.toml"]


def test_a_second_run_on_a_checkpoint_in_use_is_refused(tmp_path):
    import fcntl

    from chatterlab.errors import InputError
    from chatterlab.sweep._engine import sweep

    ck = tmp_path / "ck"
    ck.mkdir()
    with open(ck / ".lock", "w") as fh:  # another run holds the checkpoint
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        fh.write("4242")
        fh.flush()
        with pytest.raises(InputError, match="in use by a running sweep.*4242"):
            sweep(_square, {"x": [1.0, 2.0]}, outputs={"y": ""}, checkpoint=ck, resume=True, backend="serial", progress=False)  # fmt: skip
    # released (as the kernel does when the holder dies): the resume runs
    r = sweep(_square, {"x": [1.0, 2.0]}, outputs={"y": ""}, checkpoint=ck, resume=True, backend="serial", progress=False)  # fmt: skip
    assert r.ok and list(r["y"]) == [1.0, 4.0]


def test_resume_clears_a_dead_runs_scratch_and_temporary_files(tmp_path):
    from chatterlab.sweep._engine import sweep

    ck, out = tmp_path / "ck", tmp_path / "o.nc"
    kw = dict(outputs={"y": ""}, checkpoint=ck, backend="serial", progress=False, chunk_size=1)
    sweep(_fail_at_two, {"x": [1.0, 2.0, 3.0]}, **kw, out=out)
    out.unlink()
    (ck / "scratch-4199999-abc").mkdir()  # as left by a run killed while streaming
    (ck / "scratch-4199999-abc" / "y.npy").write_bytes(b"x" * 100)
    (ck / ".chunk_000009.npz.tmp-4199999-ab").write_bytes(b"half")
    r = sweep(_fail_at_two, {"x": [1.0, 2.0, 3.0]}, **kw, out=out, resume=True)
    assert r.n_resumed == 3 and r.status == "partial"
    assert sorted(p.name for p in ck.iterdir()) == [
        ".lock", "chunk_000000.npz", "chunk_000001.npz", "chunk_000002.npz", "manifest.json"
    ]  # fmt: skip


def test_library_sweep_without_checkpoint_cleans_dead_scratch_next_to_out(tmp_path):
    from chatterlab.sweep._engine import sweep

    out = tmp_path / "o.nc"
    dead = tmp_path / ".o.nc.sweep-4199999-zz"
    dead.mkdir()
    sweep(_square, {"x": [1.0]}, outputs={"y": ""}, out=out, backend="serial", progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.nc"]


def _square(x: float) -> dict[str, float]:
    return {"y": x * x}


def _fail_at_two(x: float) -> dict[str, float]:
    if x == 2.0:
        raise ValueError("two is not allowed")
    return {"y": x}


def test_a_scratch_folder_left_by_a_killed_01_run_is_removed(tmp_path, capsys):
    """chatterlab 0.1 left .OUT.sweep-XXXXXXXX next to --out when killed, and nothing removed it."""
    model = tmp_path / "t.toml"
    model.write_text(TURNING)
    old = tmp_path / ".s.nc.sweep-k2x9_q7a"
    old.mkdir()
    (old / "stable.npy").write_bytes(b"\0" * 64)
    argv = [
        "sweep",
        str(model),
        "--quantity",
        "b-lim",
        "--grid",
        "speed=3000",
        "--backend",
        "serial",
        "--quiet",
    ]
    assert main([*argv, "--out", str(tmp_path / "s.nc")]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.nc", "t.toml"]
