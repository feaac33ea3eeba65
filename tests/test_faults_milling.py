"""Issue 21, faults: SIGKILL and SIGINT during a milling lobe computation and
a milling sweep (``--quantity a-lim``), at a moment chosen by a hook of a
small driver script (the k-th speed of the diagram, the k-th chunk of the
sweep), not by a timing guess.  After the fault no process and no scratch or
temporary file is left; the sweep's resume computes only the missing chunks
and writes the uninterrupted run's bytes; the diagram (no checkpoint) run
again writes them too, and ``--resume`` on it is refused in one line instead
of silently computing everything.  SIGINT ends with one line
``chatterlab: interrupted: ...`` and status 130 -- for a sweep, "resume with
--resume".  A sweep or an atlas over a measured FRF ([frf]) is refused once,
before any work, leaving no checkpoint.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from chatterlab.cli._main import main

psutil = pytest.importorskip("psutil")

ROOT = Path(__file__).resolve().parents[1]
MILLING = ROOT / "studies" / "milling" / "benchmark_1dof.toml"

LOBES = ["lobes", str(MILLING), "--speed", "5000", "20000", "--points", "6", "--quiet"]
SWEEP = ["sweep", str(MILLING), "--quantity", "a-lim", "--grid", "speed=5000:20000:6", "--quiet"]

DRIVER = """
import os, signal, sys
from pathlib import Path

fault, at = os.environ.get("CL_FAULT", ""), int(os.environ.get("CL_AT", "0"))
on = os.environ.get("CL_ON", "")  # "speed": the at-th speed of a diagram; "chunk": after the at-th chunk saved
group = os.environ.get("CL_GROUP") == "1"
counts = {"speed": 0, "chunk": 0, "task": 0}


def strike(what):
    counts[what] += 1
    if what != on or counts[what] != at or not fault:
        return
    import psutil

    kids = psutil.Process().children(recursive=True)
    Path(os.environ["CL_PIDS"]).write_text(" ".join(str(p.pid) for p in kids))
    sys.stdout.flush()
    sys.stderr.flush()
    sig = signal.SIGKILL if fault == "kill" else signal.SIGINT
    if group:  # Ctrl-C at a terminal: the whole foreground group (the command and its workers)
        os.killpg(os.getpgrp(), sig)
    else:
        os.kill(os.getpid(), sig)


from chatterlab.lobes import _milling

limit = _milling.floquet_limit


def floquet_limit(*a, **k):
    strike("speed")
    return limit(*a, **k)


_milling.floquet_limit = floquet_limit

from chatterlab.quantities import _tasks

call = _tasks.QuantityTask.__call__


def counted(self, *a, **k):
    counts["task"] += 1
    return call(self, *a, **k)


_tasks.QuantityTask.__call__ = counted

from chatterlab.sweep import _engine

save = _engine._save_chunk


def save_chunk(directory, out, stop):
    save(directory, out, stop)
    strike("chunk")


_engine._save_chunk = save_chunk

from chatterlab.cli._main import main

code = main(sys.argv[1:])
Path(os.environ["CL_COUNT"]).write_text(str(counts["task"]))
sys.exit(code)
"""


def drive(tmp: Path, argv: list[str], fault: str = "", on: str = "", at: int = 0, group: bool = False):
    """Run the command through the driver: (completed process, tasks evaluated
    in the driver's process or None, pids of its children at the fault)."""
    driver, count, pids = tmp / "driver.py", tmp / "count.txt", tmp / "pids.txt"
    driver.write_text(DRIVER)
    for p in (count, pids):
        p.unlink(missing_ok=True)
    env = {
        **os.environ,
        "CL_FAULT": fault,
        "CL_AT": str(at),
        "CL_ON": on,
        "CL_GROUP": "1" if group else "",
        "CL_COUNT": str(count),
        "CL_PIDS": str(pids),
    }
    r = subprocess.run(
        [sys.executable, str(driver), *argv],
        cwd=tmp,
        env=env,
        capture_output=True,
        text=True,
        timeout=240,
        start_new_session=True,  # its own process group: a group SIGINT reaches only it and its workers
    )
    kids = [int(x) for x in pids.read_text().split()] if pids.exists() else []
    return r, int(count.read_text()) if count.exists() else None, kids


def none_alive(pids: list[int], seconds: float = 10.0) -> list[int]:
    """The pids still running (not zombies) after ``seconds``."""
    t0 = time.monotonic()
    while True:
        alive = []
        for pid in pids:
            try:
                p = psutil.Process(pid)
                if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                    alive.append(pid)
            except psutil.NoSuchProcess:
                pass
        if not alive or time.monotonic() - t0 > seconds:
            return alive
        time.sleep(0.05)


def scratch(tmp: Path) -> list[str]:
    """Temporary, partial or scratch files anywhere under ``tmp``."""
    bad = (".tmp-", ".part", "scratch-", ".sweep-")
    return sorted(str(p.relative_to(tmp)) for p in tmp.rglob("*") if any(b in p.name for b in bad))


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict[str, bytes]:
    """The uninterrupted diagram's and sweep's CSV bytes."""
    tmp = tmp_path_factory.mktemp("ref")
    out = {}
    for name, argv in (("lobes", LOBES), ("sweep", [*SWEEP, "--backend", "serial"])):
        f = tmp / f"{name}.csv"
        assert main([*argv, "--out", str(f)]) in (0, 1)
        out[name] = f.read_bytes()
    return out


def one_interrupted_line(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("chatterlab: interrupted"), err
    assert "Traceback" not in err
    return lines[0]


# ============================================================================ a milling lobe diagram


@pytest.mark.parametrize("fault", ["kill", "int"])
def test_a_fault_during_a_milling_diagram_leaves_nothing_and_the_rerun_gives_its_bytes(
    tmp_path, reference, fault
):
    out = tmp_path / "l.csv"
    argv = [*LOBES, "--out", str(out)]
    r, _, kids = drive(tmp_path, argv, fault, on="speed", at=3)  # during the third speed
    if fault == "kill":
        assert r.returncode == -signal.SIGKILL, r.stderr
    else:
        assert r.returncode == 130, r.stderr
        one_interrupted_line(r.stderr)
    assert none_alive(kids) == []
    assert not out.exists() and scratch(tmp_path) == [], sorted(p.name for p in tmp_path.iterdir())
    # a diagram has no checkpoint: --resume is refused in one line, not ignored
    code = main([*argv, "--resume"])
    assert code == 2 and not out.exists()
    r, _, _ = drive(tmp_path, argv)
    assert r.returncode == 0, r.stderr
    assert out.read_bytes() == reference["lobes"]
    assert scratch(tmp_path) == []


def test_resume_and_engine_options_on_a_single_diagram_are_refused(tmp_path, capsys):
    """--jobs is not among them: a milling diagram splits its speeds among
    --jobs processes (bit-identical, tests/test_milling_defaults.py)."""
    for extra in (
        ["--resume"],
        ["--checkpoint", str(tmp_path / "ck")],
        ["--backend", "dask"],
    ):
        code = main([*LOBES, "--out", str(tmp_path / "l.csv"), *extra])
        err = capsys.readouterr().err
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert extra[0] in err and "--positions" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


# ============================================================================ a milling sweep


SWEEP_FAULTS = [
    pytest.param("serial", "kill", False, id="serial-sigkill"),
    pytest.param("serial", "int", False, id="serial-sigint"),
    pytest.param("loky", "kill", True, id="loky-sigkill-group"),
    pytest.param("loky", "int", True, id="loky-ctrl-c"),
    pytest.param("loky", "kill", False, id="loky-sigkill-parent-only", marks=pytest.mark.slow),
    pytest.param("loky", "int", False, id="loky-sigint-parent-only", marks=pytest.mark.slow),
]


@pytest.mark.parametrize("backend, fault, group", SWEEP_FAULTS)
def test_a_fault_during_a_milling_sweep_then_resume_gives_its_bytes(
    tmp_path, reference, backend, fault, group
):
    out = tmp_path / "s.csv"
    ckpt = Path(f"{out}.ckpt")
    argv = [*SWEEP, "--backend", backend, "--jobs", "2", "--out", str(out)]
    r, _, kids = drive(
        tmp_path, argv, fault, on="chunk", at=2, group=group
    )  # right after the second chunk is saved
    if fault == "kill":
        assert r.returncode == -signal.SIGKILL, r.stderr
    else:
        assert r.returncode == 130, r.stderr
        line = one_interrupted_line(r.stderr)
        assert "resume with --resume" in line and "resume=True" not in line, line
        assert "chunks done" in line and str(ckpt) in line, line
    if backend == "loky":
        assert kids, "the loky workers were running at the fault"
    assert none_alive(kids) == [], "a worker outlived the sweep"
    assert not out.exists() and scratch(tmp_path) == []
    saved = sorted(p.name for p in ckpt.glob("chunk_*.npz"))
    assert len(saved) >= 2

    r, evaluated, _ = drive(tmp_path, [*SWEEP, "--backend", "serial", "--out", str(out), "--resume"])
    assert r.returncode == 0, r.stderr
    assert evaluated == 6 - len(saved), (evaluated, saved)  # only the missing chunks (of one task each)
    assert out.read_bytes() == reference["sweep"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["count.txt", "driver.py", "s.csv"] + (
        ["pids.txt"] if (tmp_path / "pids.txt").exists() else []
    )


# ============================================================================ a measured FRF: refused before the work

FRF_MODEL = """[frf]
file = "tap.csv"

[[point]]
id = "tool"
coords = { x = "response" }

[[coupling]]
id = "cut"
a = "tool"
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = 2e9

[process]
kind = "turning"
rpm = 3000
"""


@pytest.mark.parametrize(
    "argv",
    [
        ["sweep", "m.toml", "--quantity", "b-lim", "--grid", "speed=3000:4000:3"],
        ["lobes", "m.toml", "--speed", "3000", "4000", "--points", "5", "--positions", "0", "0.1", "3"],
    ],
    ids=["sweep", "atlas"],
)
def test_a_sweep_or_atlas_over_a_measured_frf_is_refused_before_the_work(tmp_path, capsys, monkeypatch, argv):
    f = np.arange(100.0, 1500.0, 4.0)
    w = 2 * np.pi * f
    H = 1.0 / (1.0e7 - w**2 + 2j * 0.03 * np.sqrt(1.0e7) * w)
    rows = "".join(f"{a!r},{z.real!r},{z.imag!r}\n" for a, z in zip(f.tolist(), H.tolist(), strict=True))
    (tmp_path / "tap.csv").write_text(f"# units: m/N\nf,re,im\n{rows}")
    (tmp_path / "m.toml").write_text(FRF_MODEL)
    monkeypatch.chdir(tmp_path)
    t0 = time.monotonic()
    code = main([*argv, "--backend", "serial", "--quiet", "--out", "s.csv"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "measured FRF" in err and "task" not in err, err
    assert time.monotonic() - t0 < 30
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.toml", "tap.csv"]  # no checkpoint, no file
