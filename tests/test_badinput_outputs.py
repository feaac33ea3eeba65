"""Class 3 of issue 10: outputs are checked before anything is computed
(suffix, directory, writability, never an input), written under temporary
names and moved into place only when the command succeeded: a failed run
leaves no file, never half a file, and never overwrites its model file."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error, turning_text

from chatterlab.cli._main import main
from chatterlab.io import _files as _io
from chatterlab.io._netcdf import read_netcdf

TURNING = turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning")


@pytest.fixture
def turning(tmp_path):
    p = tmp_path / "turning.toml"
    p.write_text(TURNING)
    return str(p)


def files(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*"))


@pytest.fixture
def computed(monkeypatch):
    """Records whether an analysis ran: output checks must come first."""
    import chatterlab.structure._assembly

    calls = []
    real = chatterlab.structure._assembly.assemble

    def spy(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(chatterlab.structure._assembly, "assemble", spy)
    return calls


COMMANDS = {
    "lobes": "lobes {m} --speed 3000 4000 --points 4 --verify 0",
    "sweep": "sweep {m} --quantity b-lim --grid speed=3000:4000:2 --backend serial --quiet",
    "simulate": "simulate {m} --speed 3000 --position 0 --duration 0.01 --quiet",
    "frf": "frf {m} --input tip.x --output tip.x --points 5",
    "roots": "roots {m} --width 0.5 --speed 3000 --no-winding",
    "modes": "modes {m}",
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_missing_directory_is_refused_before_computing(capsys, tmp_path, turning, computed, command):
    out = tmp_path / "nodir" / ("x.txt" if command in ("roots", "modes") else "x.csv")
    code = main(COMMANDS[command].format(m=turning).split() + ["--out", str(out)])
    assert_clean_error(code, capsys.readouterr().err, "--out", "does not exist")
    assert computed == []


@pytest.mark.parametrize("command", ["lobes", "sweep", "simulate", "frf", "modes"])
def test_plot_in_a_missing_directory_is_refused_before_computing(
    capsys, tmp_path, turning, computed, command
):
    code = main(COMMANDS[command].format(m=turning).split() + ["--plot", str(tmp_path / "nodir" / "p.png")])
    assert_clean_error(code, capsys.readouterr().err, "--plot", "does not exist")
    assert computed == []


def test_unwritable_directory_is_refused_before_computing(capsys, tmp_path, turning, computed, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    if os.access(ro, os.W_OK):  # root writes anywhere: refuse the probe the way a read-only mount does

        def refuse(directory):
            if Path(directory) == ro:
                raise PermissionError(13, "Read-only file system")
            return _probe(directory)

        _probe = _io._probe
        monkeypatch.setattr(_io, "_probe", refuse)
    code = main(COMMANDS["lobes"].format(m=turning).split() + ["--out", str(ro / "l.nc")])
    assert_clean_error(code, capsys.readouterr().err, "cannot write in", "ro")
    assert computed == []
    ro.chmod(0o755)
    assert files(ro) == []


@pytest.mark.parametrize(
    "command, option, name",
    [
        ("lobes", "--out", "m.toml"),  # the example: never the model file
        ("lobes", "--out", "l.txt"),
        ("lobes", "--out", "l"),
        ("sweep", "--out", "s.json"),
        ("simulate", "--out", "s.png"),
        ("lobes", "--plot", "p.csv"),
        ("frf", "--out", "f.nc"),
        ("roots", "--out", "r.csv"),
        ("modes", "--plot", "m.nc"),
    ],
)
def test_unknown_suffix_is_refused(capsys, tmp_path, turning, computed, command, option, name):
    before = Path(turning).read_bytes()
    code = main(COMMANDS[command].format(m=turning).split() + [option, str(tmp_path / name)])
    assert_clean_error(code, capsys.readouterr().err, option, "must end in")
    assert computed == []
    assert Path(turning).read_bytes() == before


def test_the_model_file_is_never_an_output(capsys, tmp_path):
    model = tmp_path / "model.csv"  # a model file may have any name: its path is what counts
    model.write_text(TURNING)
    before = model.read_bytes()
    code = main(["sweep", str(model), "--quantity", "b-lim", "--grid", "speed=3000", "--out", str(model)])
    assert_clean_error(code, capsys.readouterr().err, "input of this command")
    link = tmp_path / "alias.csv"
    link.symlink_to(model)
    code = main(["lobes", str(model), "--speed", "3000", "4000", "--out", str(link)])
    assert_clean_error(code, capsys.readouterr().err, "input of this command")
    assert model.read_bytes() == before


def test_the_same_file_twice_is_refused(capsys, tmp_path, turning):
    png = str(tmp_path / "p.png")
    argv = COMMANDS["frf"].format(m=turning).split() + ["--closed-loop", "--width", "0.5", "--speed", "3000"]
    code = main([*argv, "--plot", png, "--nyquist", png])
    assert_clean_error(code, capsys.readouterr().err, "--nyquist", "also given to --plot")


def test_a_failing_command_leaves_no_file(capsys, tmp_path, turning):
    """The issue's example: frf --out f.csv --nyquist n.png failed after writing f.csv."""
    out, nyq = tmp_path / "f.csv", tmp_path / "n.png"
    code = main(COMMANDS["frf"].format(m=turning).split() + ["--out", str(out), "--nyquist", str(nyq)])
    assert_clean_error(code, capsys.readouterr().err, "--nyquist", "--closed-loop")
    assert files(tmp_path) == ["turning.toml"]


def test_a_failure_after_the_first_file_removes_it(capsys, tmp_path, turning, monkeypatch):
    import chatterlab.plot

    def broken(*a, **k):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(chatterlab.plot, "savefig", broken)
    out, png = tmp_path / "l.nc", tmp_path / "l.png"
    code = main(COMMANDS["lobes"].format(m=turning).split() + ["--out", str(out), "--plot", str(png)])
    assert_clean_error(code, capsys.readouterr().err, "No space left on device")
    assert files(tmp_path) == ["turning.toml"]  # the .nc written before the plot failed is gone too


def test_interrupted_command_leaves_no_file(capsys, tmp_path, turning, monkeypatch):
    import chatterlab.plot

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(chatterlab.plot, "savefig", interrupted)
    code = main(COMMANDS["lobes"].format(m=turning).split() + ["--out", str(tmp_path / "l.csv"), "--plot", str(tmp_path / "l.png")])  # fmt: skip
    assert code == 130
    assert files(tmp_path) == ["turning.toml"]


def test_sweep_refused_up_front_writes_no_file_and_no_checkpoint(capsys, tmp_path, turning):
    out = tmp_path / "s.nc"
    code = main(COMMANDS["sweep"].format(m=turning).split() + ["--width-max", "-1", "--out", str(out)])
    assert_clean_error(code, capsys.readouterr().err, "--width-max")
    assert files(tmp_path) == ["turning.toml"]


def test_outputs_are_replaced_and_the_same_command_runs_twice(capsys, tmp_path, turning):
    """The documented policy: an existing output file is replaced, atomically, after success
    (the README's quick start runs twice)."""
    out, png = tmp_path / "l.nc", tmp_path / "l.png"
    argv = COMMANDS["lobes"].format(m=turning).split() + ["--out", str(out), "--plot", str(png)]
    assert main(argv) == 0
    first = read_netcdf(out).data["b_lim"][0]
    out_inode = out.stat().st_ino
    assert main(argv) == 0
    assert out.stat().st_ino != out_inode  # a new file renamed over the old one, not rewritten in place
    np.testing.assert_array_equal(read_netcdf(out).data["b_lim"][0], first)
    assert files(tmp_path) == ["l.nc", "l.png", "turning.toml"]  # no temporary file left


def test_stale_temporary_files_of_a_killed_run_are_removed(capsys, tmp_path, turning):
    dead = 2**22 + 12345  # above the default pid_max: no such process
    stale = tmp_path / f".l.csv.part-{dead}-abcd1234.csv"
    stale.write_text("half a file")
    # killed while write_netcdf wrote atomically to the command's temporary name
    nested = tmp_path / f"..l.csv.part-{dead}-abcd1234.csv.tmp-{dead}-0123abcd"
    nested.write_text("half of a temporary file")
    mine = tmp_path / f".l.csv.part-{os.getpid()}-abcd1234.csv"  # a live process's: kept
    mine.write_text("in progress")
    assert main(COMMANDS["lobes"].format(m=turning).split() + ["--out", str(tmp_path / "l.csv")]) == 0
    assert not stale.exists() and not nested.exists() and mine.exists()


def test_output_that_is_a_directory_is_refused(capsys, tmp_path, turning):
    (tmp_path / "d.csv").mkdir()
    code = main(COMMANDS["sweep"].format(m=turning).split() + ["--out", str(tmp_path / "d.csv")])
    assert_clean_error(code, capsys.readouterr().err, "is a directory")


def test_checkpoint_must_not_be_an_input(capsys, tmp_path, turning):
    code = main(COMMANDS["sweep"].format(m=turning).split() + ["--checkpoint", turning])
    assert_clean_error(code, capsys.readouterr().err, "--checkpoint")
