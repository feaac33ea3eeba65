"""Issue 25: a checkpointed ``sweep`` or ``lobes --positions`` atlas killed
between its last chunk and its output file loses nothing.

The engine used to delete the checkpoint when the sweep ended, before the
command printed its summary and moved its output into place: a kill there
left neither.  Here the process kills itself (SIGKILL, from a hook of a small
driver script, not a timing guess) at three moments -- right after the last
chunk is stored, when the output files are about to be moved into place, and
right after they are -- and the resume must write the uninterrupted run's
file (byte for byte for CSV; for netCDF the same content, as its ``created``
and ``command_line`` attributes are the run's own) without evaluating a
single task.

The driver counts the tasks evaluated in its process (``--backend serial``:
every task runs there) and writes the count to ``$CL_COUNT`` when the command
returns.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import turning_text

from chatterlab.cli._main import main
from chatterlab.io._netcdf import read_netcdf

TURNING = turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning")

COMMANDS = {
    # (argv after the model, output file name); --out is added, and the checkpoint is OUT.ckpt
    "sweep-nc": (["sweep", "--quantity", "stable", "--grid", "width=0.2:1.2:3", "--grid", "speed=3000:9000:4"], "s.nc"),
    "sweep-csv": (["sweep", "--quantity", "b-lim", "--grid", "speed=3000:9000:5"], "s.csv"),
    "atlas-csv": (["lobes", "--speed", "4000", "9000", "--points", "5", "--positions", "0", "0.1", "3"], "a.csv"),
}  # fmt: skip

DRIVER = """
import json, os, signal, sys
from pathlib import Path

kill_at = os.environ.get("CL_KILL_AT", "")
evaluated = 0


def die():
    sys.stdout.flush()
    sys.stderr.flush()
    os.kill(os.getpid(), signal.SIGKILL)


from chatterlab.quantities import _tasks


def counted(orig):
    def call(self, *a, **k):
        global evaluated
        evaluated += 1
        return orig(self, *a, **k)

    return call


for cls in (_tasks.QuantityTask, _tasks.AtlasTask):
    cls.__call__ = counted(cls.__call__)

from chatterlab.sweep import _engine

save = _engine._save_chunk


def save_chunk(directory, out, stop):
    save(directory, out, stop)
    if kill_at == "last-chunk":
        m = json.loads((Path(directory) / "manifest.json").read_text())
        n = -(-m["n_tasks"] // m["chunk_size"])
        if len(list(Path(directory).glob("chunk_*.npz"))) == n:
            die()


_engine._save_chunk = save_chunk

from chatterlab.io import _files

commit = _files.Outputs.commit


def commit_then(self, note=None):
    if kill_at == "commit":
        die()
    done = commit(self, note)
    if kill_at == "after-commit":
        die()
    return done


_files.Outputs.commit = commit_then

from chatterlab.cli._main import main

code = main(sys.argv[1:])
Path(os.environ["CL_COUNT"]).write_text(str(evaluated))
sys.exit(code)
"""


def drive(tmp: Path, argv: list[str], kill_at: str = "") -> tuple[subprocess.CompletedProcess, int | None]:
    """Run the command through the driver; the tasks it evaluated (None if killed)."""
    driver, count = tmp / "driver.py", tmp / "count.txt"
    driver.write_text(DRIVER)
    count.unlink(missing_ok=True)
    env = {**os.environ, "CL_KILL_AT": kill_at, "CL_COUNT": str(count)}
    r = subprocess.run(
        [sys.executable, str(driver), *argv], cwd=tmp, env=env, capture_output=True, text=True, timeout=240
    )
    return r, int(count.read_text()) if count.exists() else None


def argv_of(name: str, model: Path, out: Path) -> list[str]:
    head, _ = COMMANDS[name]
    return [head[0], str(model), *head[1:], "--backend", "serial", "--quiet", "--out", str(out)]


@pytest.fixture(scope="module")
def references(tmp_path_factory) -> dict[str, Path]:
    """Each command's uninterrupted output (and its default checkpoint is gone)."""
    tmp = tmp_path_factory.mktemp("ref")
    model = tmp / "t.toml"
    model.write_text(TURNING)
    refs = {}
    for name, (_, file) in COMMANDS.items():
        out = tmp / f"{name}-{file}"
        assert main(argv_of(name, model, out)) == 0
        assert out.is_file() and not Path(f"{out}.ckpt").exists()
        refs[name] = out
    return refs


def same_output(ref: Path, got: Path) -> None:
    if ref.suffix == ".csv":
        assert got.read_bytes() == ref.read_bytes()
        return
    a, b = read_netcdf(ref), read_netcdf(got)
    assert a.data.keys() == b.data.keys()
    for k in a.data:
        assert np.array_equal(a.data[k][0], b.data[k][0], equal_nan=True), k
    own = ("created", "command_line")  # the run's own time stamp and command line
    assert {k: v for k, v in a.attrs.items() if k not in own} == {
        k: v for k, v in b.attrs.items() if k not in own
    }


#: every command at every moment; the kill at the commit of a sweep and of an atlas (the window
#: of the issue) run by default, the others with the slow tests (some 10 s each on 2 loaded cores)
CASES = [
    pytest.param(name, kill_at, marks=() if kill_at == "commit" and name != "sweep-nc" else pytest.mark.slow)
    for name in COMMANDS
    for kill_at in ("last-chunk", "commit", "after-commit")
]


@pytest.mark.parametrize("name, kill_at", CASES)
def test_a_kill_after_the_last_chunk_resumes_without_computing(tmp_path, references, name, kill_at, capsys):
    model = tmp_path / "t.toml"
    model.write_text(TURNING)
    out = tmp_path / COMMANDS[name][1]
    ckpt = Path(f"{out}.ckpt")
    argv = argv_of(name, model, out)

    r, _ = drive(tmp_path, argv, kill_at)
    assert r.returncode == -signal.SIGKILL, r.stderr
    # the work is kept: the complete checkpoint, whether or not the file was moved into place
    assert ckpt.is_dir() and (ckpt / "manifest.json").is_file(), sorted(p.name for p in tmp_path.iterdir())
    assert out.exists() == (kill_at == "after-commit")

    if kill_at == "commit":
        # the same command without --resume says what the checkpoint holds and how to write it
        code = main(argv)
        err = capsys.readouterr().err
        assert code == 2 and "holds every chunk of a finished sweep" in err and "--resume" in err, err
        assert ckpt.is_dir() and not out.exists()

    r, evaluated = drive(tmp_path, [*argv, "--resume"])
    assert r.returncode == 0, r.stderr
    assert evaluated == 0, f"the resume evaluated {evaluated} task(s)"
    assert f"wrote {out}" in r.stderr
    same_output(references[name], out)
    # the default checkpoint is removed once the output is in place; no scratch or temporary file is left
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["count.txt", "driver.py", "t.toml", out.name]
    )


@pytest.mark.parametrize("name, tasks", [("sweep-csv", 5), ("atlas-csv", 15)])
def test_the_driver_counts_every_task_of_an_uninterrupted_run(tmp_path, references, name, tasks):
    """The count the resumes above are held to is a real one: a fresh run evaluates every task."""
    model = tmp_path / "t.toml"
    model.write_text(TURNING)
    out = tmp_path / COMMANDS[name][1]
    r, evaluated = drive(tmp_path, argv_of(name, model, out))
    assert r.returncode == 0, r.stderr
    assert evaluated == tasks
    same_output(references[name], out)


def test_the_checkpoint_outlives_a_failing_output_commit(tmp_path, capsys, monkeypatch):
    """An output that cannot be moved into place keeps the checkpoint, and the resume writes it."""
    from chatterlab.io import _files

    model = tmp_path / "t.toml"
    model.write_text(TURNING)
    out = tmp_path / "s.csv"
    argv = argv_of("sweep-csv", model, out)

    def refuse(self, note=None):
        raise PermissionError(13, "Permission denied", str(out))

    monkeypatch.setattr(_files.Outputs, "commit", refuse)
    assert main(argv) != 0
    monkeypatch.undo()
    assert "Permission denied" in capsys.readouterr().err
    assert Path(f"{out}.ckpt").is_dir() and not out.exists()
    assert main([*argv, "--resume"]) == 0
    assert out.is_file() and not Path(f"{out}.ckpt").exists()


def test_library_sweep_keeps_its_checkpoint_until_discarded(tmp_path):
    from chatterlab.sweep import sweep

    ck = tmp_path / "ck"
    kw = dict(outputs={"y": ""}, checkpoint=ck, backend="serial", progress=False, chunk_size=1)
    r = sweep(_square, {"x": [1.0, 2.0, 3.0]}, **kw)
    assert r.checkpoint == str(ck) and (ck / "manifest.json").is_file()
    # resuming the complete checkpoint computes nothing and gives the same values
    again = sweep(_square, {"x": [1.0, 2.0, 3.0]}, **kw, resume=True)
    assert (again.n_computed, again.n_resumed) == (0, 3) and list(again["y"]) == [1.0, 4.0, 9.0]
    assert again.discard_checkpoint() and not ck.exists()
    assert not again.discard_checkpoint()  # nothing left to remove
    # keep_checkpoint=False: removed by the engine after out= is written
    out = tmp_path / "o.nc"
    r = sweep(_square, {"x": [1.0, 2.0]}, **kw, out=out, keep_checkpoint=False)
    assert r.checkpoint is None and not ck.exists() and out.is_file()


def test_discard_leaves_a_checkpoint_in_use_and_a_foreign_directory(tmp_path):
    import fcntl

    from chatterlab.sweep import sweep

    ck = tmp_path / "ck"
    r = sweep(_square, {"x": [1.0]}, outputs={"y": ""}, checkpoint=ck, backend="serial", progress=False)
    with open(ck / ".lock", "a+") as fh:  # a --resume started meanwhile holds it
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        assert not r.discard_checkpoint() and (ck / "manifest.json").is_file()
    assert r.discard_checkpoint() and not ck.exists()
    # a directory that is not a checkpoint (no manifest) is never removed
    ck.mkdir()
    (ck / "precious.txt").write_text("x")
    assert not r.discard_checkpoint() and (ck / "precious.txt").is_file()


def _square(x: float) -> dict[str, float]:
    return {"y": x * x}
