"""Exit statuses exactly as docs/cli.md documents them, one test per status,
and class 7 of issue 10: numerical faults reported for humans (no absurd
means from a diverged run; every file says its status and, per failed
sweep point, why)."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import turning_text

import chatterlab.cli._main as cli
from chatterlab.cli._main import main
from chatterlab.io._netcdf import read_netcdf
from chatterlab.sweep._engine import SweepResult

ROOT = Path(__file__).resolve().parents[1]
TURNING = turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning")
FORCED = turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, forces=(100.0, 0.0, 0.0), name="forced")
TESTED = {0, 1, 2, 3, 130}


@pytest.fixture
def turning(tmp_path):
    p = tmp_path / "turning.toml"
    p.write_text(TURNING)
    return str(p)


def documented_statuses() -> set[int]:
    text = (ROOT / "docs" / "cli.md").read_text()
    section = text.split("## Exit status and messages", 1)[1].split("\n## ", 1)[0]
    return {int(m[1]) for m in re.finditer(r"^\| (\d+) \|", section, re.M)}


def test_the_documented_statuses_are_the_tested_ones():
    assert documented_statuses() == TESTED


def test_status_0_success(capsys, turning):
    assert main(["check", turning]) == 0
    assert "OK" in capsys.readouterr().out


def test_status_1_partial_sweep_says_why_per_point(capsys, tmp_path, turning):
    """A sweep whose first point has no spring stiffness (a floating tool: no modes) ends
    partial; the CSV and the netCDF name the failed point and the reason."""
    out_csv, out_nc = tmp_path / "s.csv", tmp_path / "s.nc"
    argv = ["sweep", turning, "--quantity", "natural-frequencies", "--grid", "spring.holder.c1=0:2e7:3",
            "--backend", "serial", "--quiet"]  # fmt: skip
    assert main([*argv, "--out", str(out_csv)]) == 1
    err = capsys.readouterr().err
    assert "1 task(s) failed" in err
    rows = list(csv.reader(out_csv.open()))
    assert rows[0][-2:] == ["task_status", "reason"]
    assert [r[-2] for r in rows[1:]] == ["failed", "ok", "ok"]
    assert rows[1][-1] and rows[2][-1] == rows[3][-1] == ""
    assert main([*argv, "--out", str(out_nc)]) == 1
    capsys.readouterr()
    res = SweepResult.from_netcdf(out_nc)
    assert res.status == "partial" and list(res.task_status) == [1, 0, 0]
    assert res.reasons == (rows[1][-1],)
    f = read_netcdf(out_nc)
    assert f.attrs["status"] == "partial" and "task_status" in f.data


def test_status_1_diverged_simulation_prints_no_absurd_means(capsys, tmp_path):
    model = tmp_path / "forced.toml"
    model.write_text(FORCED)
    out = tmp_path / "sim.csv"
    code = main(["simulate", str(model), "--speed", "3000", "--position", "0", "--duration", "2", "--width", "5",
                 "--quiet", "--out", str(out)])  # fmt: skip
    std = capsys.readouterr()
    assert code == 1
    assert "diverged at t =" in std.out and "status: diverged" in std.err
    assert not re.search(r"mean +-?\d", std.out)  # the issue: "mean -4194520312329653 um"
    assert "no mean or spectrum: the run diverged" in std.out
    rows = list(csv.reader(out.open()))
    assert rows[0][-1] == "status" and {r[-1] for r in rows[1:]} == {"diverged"}
    out_nc = tmp_path / "sim.nc"
    assert main(["simulate", str(model), "--speed", "3000", "--position", "0", "--duration", "2", "--width", "5",
                 "--quiet", "--out", str(out_nc)]) == 1  # fmt: skip
    assert read_netcdf(out_nc).attrs["status"] == "diverged"


def test_status_1_ok_run_files_say_ok(capsys, tmp_path, turning):
    out = tmp_path / "sim.csv"
    argv = ["simulate", turning, "--speed", "3000", "--position", "0", "--duration", "0.01", "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    rows = list(csv.reader(out.open()))
    assert {r[-1] for r in rows[1:]} == {"ok"}
    s = tmp_path / "s.csv"
    assert main(["sweep", turning, "--quantity", "b-lim", "--grid", "speed=3000:4000:2", "--backend", "serial",
                 "--quiet", "--out", str(s)]) == 0  # fmt: skip
    assert [r[-2:] for r in csv.reader(s.open())][1:] == [["ok", ""], ["ok", ""]]


def test_status_2_input_error(capsys, turning):
    assert main(["roots", turning, "--width", "-1", "--speed", "3000"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("chatterlab: error: --width") and len(err.strip().splitlines()) == 1


def test_status_3_internal_error_is_one_line(capsys, monkeypatch, turning):
    def bug(args):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setitem(cli.COMMANDS, "check", bug)
    assert main(["check", turning]) == 3
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("chatterlab: internal error: ZeroDivisionError: float division by zero")
    monkeypatch.setenv("CHATTERLAB_DEBUG", "1")
    with pytest.raises(ZeroDivisionError):
        main(["check", turning])


def test_status_130_interrupted(capsys, monkeypatch, turning):
    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setitem(cli.COMMANDS, "check", interrupted)
    assert main(["check", turning]) == 130
    assert capsys.readouterr().err.strip() == "chatterlab: interrupted"


def test_status_2_for_a_file_system_refusal(capsys, monkeypatch, turning):
    def full(args):
        raise OSError(28, "No space left on device", "out.nc")

    monkeypatch.setitem(cli.COMMANDS, "check", full)
    assert main(["check", turning]) == 2
    assert capsys.readouterr().err.strip() == "chatterlab: error: out.nc: No space left on device"


def test_task_status_survives_resume(tmp_path):
    from chatterlab.sweep._engine import sweep

    def kw(**more):
        return dict(outputs={"y": ""}, backend="serial", progress=False, chunk_size=2, **more)

    g = {"x": [1.0, 2.0, 3.0, 4.0]}
    ck = tmp_path / "ck"
    a = sweep(_odd_fails, g, **kw(checkpoint=ck, fingerprint="f"))
    b = sweep(_odd_fails, g, **kw(checkpoint=ck, fingerprint="f", resume=True))
    assert b.n_resumed == 4
    assert np.array_equal(a.task_status, b.task_status) and a.reasons == b.reasons
    assert list(a.task_status) == [1, 0, 2, 0]
    assert a.reasons == ("ValueError: odd 1.0", "ValueError: odd 3.0")


def _odd_fails(x: float) -> dict[str, float]:
    if int(x) % 2:
        raise ValueError(f"odd {x}")
    return {"y": x}
