"""``chatterlab ssv``: the SSV limits from the command line are the API's, in
every output format; bad input is one line, status 2, nothing written."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from conftest import assert_clean_error

import chatterlab as cl
from chatterlab.cli import main
from chatterlab.frequency import ssv_limits

ROOT = Path(__file__).resolve().parents[1]
TURNING = ROOT / "studies" / "process_damping" / "turning.toml"  # the 1-DOF turning benchmark, [machine] kept
ONE = ROOT / "studies" / "milling" / "benchmark_1dof.toml"


def test_the_csv_and_json_are_the_api_result(tmp_path, capsys):
    out, js = tmp_path / "s.csv", tmp_path / "s.json"
    args = ["ssv", str(TURNING), "--speed", "6000", "--rva", "0", "0.2", "--rvf", "0.5", "--scan", "4"]
    assert main([*args, "--out", str(out)]) == 0
    assert main([*args, "--out", str(js)]) == 0
    printed = capsys.readouterr().out
    ref = ssv_limits(
        cl.assemble(cl.load_model(TURNING)).at(), [6000.0], [0.0, 0.2], [0.5], width_max=5e-3, scan=4
    )
    rows = list(csv.DictReader(out.open()))
    assert [float(r["b_lim [m]"]) for r in rows] == ref.b_lim.ravel().tolist()
    assert json.loads(js.read_text())["data"]["b_lim"]["values"] == ref.b_lim.tolist()
    assert f"{ref.b_lim[0, 1, 0] * 1e3:.6g}" in printed


def test_milling_takes_the_file_program_and_plots(tmp_path, capsys):
    model = tmp_path / "m.toml"
    model.write_text(ONE.read_text() + '\n[ssv]\nshape = "sine"\nrva = 0.1\nrvf = 0.25\n')
    png = tmp_path / "m.png"
    code = main(
        ["ssv", str(model), "--speed", "10000", "--width-max", "3", "--scan", "6", "--plot", str(png)]
    )
    assert code == 0, capsys.readouterr().err
    text = capsys.readouterr().out
    assert "a_lim" in text and "0.25" in text and png.stat().st_size > 0


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--rva", "1.5", "--rvf", "0.5"], ["RVA", "0.9"]),
        (["--rva", "0.1", "--rvf", "0"], ["RVF"]),
        (["--rva", "0.1"], ["--rvf"]),
        (["--rvf", "0.5"], ["--rva"]),
        (["--rva", "0.1", "--rvf", "0.5", "--width-max", "-1"], ["--width-max"]),
        (["--rva", "0.1", "--rvf", "0.5", "--scan", "1"], ["--scan"]),
        (["--rva", "0.1", "--rvf", "0.5", "--points", "1"], ["--points"]),
        (["--rva", "0.1", "--rvf", "0.5", "--split", "-5"], ["--split", "Hz"]),
        (["--rva", "0.1", "--rvf", "0.5", "--split", "900", "--method", "sdm"], ["--split", "spectral"]),
        (["--rva", "0.1", "--rvf", "0.5", "--span", "0"], ["--span"]),
        (["--rva", "0.1", "--rvf", "0.5", "--degree", "1"], ["--degree"]),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(extra, words, tmp_path, capsys):
    out = tmp_path / "o.csv"
    code = main(["ssv", str(TURNING), "--speed", "2000", *extra, "--out", str(out)])
    assert_clean_error(code, capsys.readouterr().err, *words)
    assert not out.exists()


def test_a_milling_rvf_that_never_repeats_is_refused(capsys, tmp_path):
    out = tmp_path / "o.nc"
    code = main(
        ["ssv", str(ONE), "--speed", "10000", "--rva", "0.1", "--rvf", "0.3183098", "--out", str(out)]
    )
    assert_clean_error(code, capsys.readouterr().err, "RVF", "ratio")
    assert not out.exists()


def test_split_on_milling_is_refused(capsys, tmp_path):
    out = tmp_path / "o.csv"
    code = main(
        [
            "ssv",
            str(ONE),
            "--speed",
            "10000",
            "--rva",
            "0.1",
            "--rvf",
            "0.25",
            "--split",
            "900",
            "--out",
            str(out),
        ]
    )
    assert_clean_error(code, capsys.readouterr().err, "--split", "milling")
    assert not out.exists()


def test_split_above_every_mode_is_the_unsplit_limit(tmp_path, capsys):
    """The 1-DOF turning benchmark (503 Hz) split at 1 kHz keeps its one mode and leaves no
    quasi-static rest (G = K^-1 - Phi Lambda^-1 Phi^T = 0 to round-off): Eq. (1q) is then
    Eq. (1), and the limits agree to the search's tolerance (rtol 1e-6)."""
    base = ["ssv", str(TURNING), "--speed", "6000", "--rva", "0.1", "--rvf", "0.5", "--scan", "4"]
    outs = []
    for extra in ([], ["--split", "1000"]):
        out = tmp_path / f"s{len(extra)}.csv"
        assert main([*base, *extra, "--out", str(out)]) == 0
        outs.append(float(next(csv.DictReader(out.open()))["b_lim [m]"]))
    text = capsys.readouterr().out
    assert "modes above 1000 Hz quasi-static" in text
    assert abs(outs[1] - outs[0]) <= 2e-6 * outs[0]
