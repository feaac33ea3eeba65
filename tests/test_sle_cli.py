"""``chatterlab sle``: the command prints and writes what the API computes
(chatterlab.frequency.surface_location, runout_response), reports chatter
and undetermined speeds instead of an SLE, and refuses bad input in one line
with status 2, writing nothing."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error, turning_text

import chatterlab as cl
from chatterlab.cli import main
from chatterlab.frequency import runout_response, surface_location
from chatterlab.lobes import milling_loop_of

ROOT = Path(__file__).resolve().parents[1]
WALL = ROOT / "studies" / "sle" / "benchmark_1dof_y.toml"
ONE = ROOT / "studies" / "milling" / "benchmark_1dof.toml"


def test_csv_is_the_api_result(tmp_path, capsys):
    out = tmp_path / "s.csv"
    code = main(
        ["sle", str(WALL), "--speed", "12000", "16000", "--points", "5", "--width", "2", "--out", str(out)]
    )
    printed = capsys.readouterr().out
    ref = surface_location(
        milling_loop_of(cl.assemble(cl.load_model(WALL)).at()), np.linspace(12e3, 16e3, 5), 2e-3, 1e-4
    )
    assert ref.verdict.count("unstable") >= 1 and ref.verdict.count("stable") >= 1  # both kinds of speed
    assert code == 1  # a speed chatters: the command says so by its status
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    head = rows[0]
    assert head[:3] == ["speed [rpm]", "sle [m]", "sle_error [m]"]
    got = np.array([float(r[1]) if r[1] else math.nan for r in rows[1:]])
    # the same computation: the CSV holds the shortest repr of each double, so exactly equal
    np.testing.assert_array_equal(got, ref.sle)
    assert [int(r[head.index("verdict [1]")]) for r in rows[1:]] == [
        ("stable", "unstable", "undetermined").index(v) for v in ref.verdict
    ]
    assert "unstable (chatter, no SLE)" in printed


def test_sdm_csv_is_the_api_result_and_records_the_method(tmp_path, capsys):
    out, js = tmp_path / "s.csv", tmp_path / "s.json"
    args = ["sle", str(WALL), "--speed", "20000", "24000", "--points", "3", "--width", "1", "--method", "sdm"]
    assert main([*args, "--steps", "60", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "semi-discretisation, 60 steps per period" in printed
    ref = surface_location(
        milling_loop_of(cl.assemble(cl.load_model(WALL)).at()), np.linspace(20e3, 24e3, 3), 1e-3, 1e-4,
        method="sdm", steps=60,
    )  # fmt: skip
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))
    np.testing.assert_array_equal([float(r[1]) for r in rows[1:]], ref.sle)  # the same computation
    fig = tmp_path / "s.png"
    assert main([*args, "--steps", "60", "--no-check", "--out", str(js), "--plot", str(fig)]) == 0
    doc = json.loads(js.read_text())
    assert doc["attrs"]["method"] == "sdm" and doc["attrs"]["resolution"] == "60 steps", doc["attrs"]
    assert fig.stat().st_size > 0  # the SLE under the lobes of the same discretisation


def test_benchmark_along_the_feed_has_no_sle_and_json(tmp_path, capsys):
    out = tmp_path / "s.json"
    assert (
        main(
            [
                "sle",
                str(ONE),
                "--speed",
                "8000",
                "10000",
                "--points",
                "3",
                "--width",
                "0.2",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    doc = json.loads(out.read_text())
    # x-flexible tool, wall normal y: SLE at round-off of the orbit (~1e-6 m) times sin(pi) ~ 1e-16
    assert max(abs(v) for v in doc["data"]["sle"]["values"]) < 1e-20


def test_turning_runout(tmp_path, capsys):
    model = tmp_path / "t.toml"
    model.write_text(turning_text())
    out = tmp_path / "r.csv"
    code = main(["sle", str(model), "--speed", "2000", "4000", "--points", "3", "--width", "0.2",
                 "--eccentricity", "0.02", "--feed", "0.1", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    loop = cl.closed_loop(cl.assemble(cl.load_model(model)).at(), width=2e-4, speed=2000.0)
    ref = runout_response(loop, np.linspace(2000, 4000, 3), 2e-5, 1e-4, 2e9, inputs="tip.x", outputs="tip.x")
    with open(out, newline="") as fh:
        rows = list(csv.reader(fh))[1:]
    np.testing.assert_array_equal([float(r[1]) for r in rows], ref.amplitude)


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--width", "-1"], ["--width"]),
        (["--width", "0.2", "--points", "1"], ["--points"]),
        (["--width", "0.2", "--eccentricity", "0.01"], ["--eccentricity", "turning"]),
        (["--width", "0.2", "--feed", "-0.1"], ["--feed"]),
        (["--width", "0.2", "--speed", "9000", "8000"], ["--speed"]),
        (["--width", "0.2", "--steps", "80"], ["--steps", "--method sdm"]),
        (["--width", "0.2", "--method", "sdm", "--steps", "1"], ["--steps"]),
    ],
)
def test_bad_input_one_line_nothing_written(extra, words, tmp_path, capsys):
    out, fig = tmp_path / "s.csv", tmp_path / "s.png"
    args = [
        "sle",
        str(WALL),
        "--speed",
        "8000",
        "9000",
        "--points",
        "3",
        *extra,
        "--out",
        str(out),
        "--plot",
        str(fig),
    ]
    if extra[-2] == "--speed":
        args = ["sle", str(WALL), *extra, "--out", str(out), "--plot", str(fig)]
    code = main(args)
    assert_clean_error(code, capsys.readouterr().err, *words)
    assert not out.exists() and not fig.exists()


def test_an_unknown_method_is_argparse_one_line(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["sle", str(WALL), "--speed", "8000", "9000", "--width", "0.2", "--method", "sd"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "invalid choice: 'sd'" in err and "sdm" in err and len(err.strip().splitlines()) == 1


def test_turning_refuses_the_milling_method(tmp_path, capsys):
    model = tmp_path / "t.toml"
    model.write_text(turning_text())
    code = main(["sle", str(model), "--speed", "2000", "4000", "--width", "0.2", "--eccentricity", "0.02",
                 "--feed", "0.1", "--method", "sdm"])  # fmt: skip
    assert_clean_error(code, capsys.readouterr().err, "--method", "turning")


def test_turning_needs_the_eccentricity(tmp_path, capsys):
    model = tmp_path / "t.toml"
    model.write_text(turning_text())
    code = main(["sle", str(model), "--speed", "2000", "4000", "--width", "0.2", "--feed", "0.1"])
    assert_clean_error(code, capsys.readouterr().err, "--eccentricity")
