"""A closed pipe never costs a file (issue 20, item 2).

``chatterlab lobes ... --out x.nc --plot x.png 2>&1 | head -1``: ``head``
leaves after the first line, and every later write of the command meets a
closed pipe.  The command must still finish and commit its outputs, the same
files an uninterrupted run writes, and exit with that run's status
(docs/cli.md, "Exit statuses").  Each case runs through a real shell pipe into
``head -1``, and once more with the pipe closed before the command writes
anything (the reader gone from the start: no race with ``head``).
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHAPER = ROOT / "studies" / "traverse_shaper" / "model.toml"

pytestmark = pytest.mark.slow

_ENV = {**os.environ, "MPLBACKEND": "Agg"}

SINGLE = ["lobes", str(SHAPER), "--speed", "0.1", "1.0", "--points", "16", "--width-max", "1",
          "--out", "x.nc", "--plot", "x.png"]  # fmt: skip
ATLAS = ["lobes", str(SHAPER), "--speed", "0.1", "1.0", "--points", "6", "--width-max", "1",
         "--positions", "0.7", "1.0", "2", "--backend", "serial", "--out", "atlas.nc", "--plot", "atlas.png"]  # fmt: skip


def _cmd(args: list[str]) -> list[str]:
    return [sys.executable, "-m", "chatterlab.cli", *args]


def _uninterrupted(args: list[str], cwd: Path) -> int:
    cwd.mkdir()
    return subprocess.run(_cmd(args), cwd=cwd, env=_ENV, capture_output=True, timeout=280).returncode


def _into_head(args: list[str], cwd: Path) -> tuple[int, str]:
    """The command's own status (pipefail) and what ``head -1`` printed."""
    cwd.mkdir()
    line = f"set -o pipefail; {shlex.join(_cmd(args))} 2>&1 | head -1"
    r = subprocess.run(["bash", "-c", line], cwd=cwd, env=_ENV, capture_output=True, text=True, timeout=280)
    return r.returncode, r.stdout


def _into_closed_pipe(args: list[str], cwd: Path) -> int:
    cwd.mkdir()
    p = subprocess.Popen(_cmd(args), cwd=cwd, env=_ENV, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    assert p.stdout is not None
    p.stdout.close()  # the reader is gone before the first line
    return p.wait(timeout=280)


def _same_files(ref: Path, other: Path) -> None:
    """The same files (checkpoints included, or their absence); the data and
    pictures equal (a netCDF's provenance says when it was made: compared
    without its attributes)."""
    import xarray as xr

    names = sorted(p.name for p in ref.iterdir())
    assert sorted(p.name for p in other.iterdir()) == names
    assert names, "the uninterrupted run wrote nothing"
    for name in names:
        a, b = ref / name, other / name
        if name.endswith(".nc"):
            with xr.open_dataset(a) as da, xr.open_dataset(b) as db:
                xr.testing.assert_equal(da.load(), db.load())
        elif a.is_file():
            assert a.read_bytes() == b.read_bytes(), name


@pytest.mark.parametrize("args", [SINGLE, ATLAS], ids=["diagram", "atlas"])
def test_a_closed_pipe_costs_no_file(args, tmp_path):
    status = _uninterrupted(args, tmp_path / "ref")
    assert status in (0, 1)

    piped, first = _into_head(args, tmp_path / "head")
    assert first.strip(), "head printed nothing"
    assert piped == status, f"status {piped} through | head -1, {status} uninterrupted"
    _same_files(tmp_path / "ref", tmp_path / "head")

    closed = _into_closed_pipe(args, tmp_path / "closed")
    assert closed == status
    _same_files(tmp_path / "ref", tmp_path / "closed")


def test_in_process_main_restores_the_streams(capsys):
    """main() puts standard output and error back as it found them."""
    from chatterlab.cli import main

    out, err = sys.stdout, sys.stderr
    assert main(["example"]) == 0
    assert sys.stdout is out and sys.stderr is err
    assert "traverse_shaper" in capsys.readouterr().out
