"""``chatterlab recommend``: from a model file with a [machine] table to the
ranked table, its files and plot; the chatter-frequency rule from a number
or a recording; every refusal one line, status 2, nothing written."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from conftest import assert_clean_error, turning_text

from chatterlab.cli._main import main

MACHINE = """
[machine]
min_rpm = 2000
max_rpm = 12000
power = [[0, 1500], [3000, 3000], [12000, 3000]]
max_depth = 0.002
feed = 1.0e-4
workpiece_diameter = 0.05
"""
MODEL = turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning") + MACHINE


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture
def model(tmp_path):
    p = tmp_path / "turning.toml"
    p.write_text(MODEL)
    return p


def test_from_the_model_file_to_files_and_plot(capsys, model, tmp_path):
    out_csv, out_nc, out_json, png = (tmp_path / f"r.{s}" for s in ("csv", "nc", "json", "png"))
    code, out, err = run(
        capsys, "recommend", model, "--points", 120, "--count", 3, "--out", out_csv, "--plot", png
    )
    assert code == 0, err
    assert "rank" in out and "why:" in out and "check: stable" in out
    with open(out_csv, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 3 and all(r["verdict"] == "stable" for r in rows)
    speeds = [float(r["speed [rpm]"]) for r in rows]
    assert all(2000 <= v <= 12000 for v in speeds)
    # the file's power curve: P = K_f h b V (the regenerative coupling's bound), at most 3 kW
    power = np.array([float(r["power [W]"]) for r in rows])
    assert np.all(power <= 3000 * (1 + 1e-12))
    assert png.stat().st_size > 0
    # the same through the other formats, and options overriding the file
    code, _, err = run(
        capsys, "recommend", model, "--points", 60, "--count", 2, "--max-depth", "1mm", "--out", out_json
    )
    assert code == 0, err
    doc = json.loads(out_json.read_text())
    assert max(doc["data"]["width"]["values"]) <= 1e-3
    code, _, err = run(
        capsys, "recommend", model, "--points", 60, "--count", 2, "--out", out_nc, "--margin", 0.5
    )
    assert code == 0, err
    import xarray as xr

    with xr.open_dataset(out_nc, engine="h5netcdf") as ds:
        assert float(ds.attrs["margin"]) == 0.5
        assert "[machine]" in ds.attrs["model_text"]


def test_the_rule_without_a_model(capsys, tmp_path):
    code, out, err = run(
        capsys, "recommend", "--chatter", "951.3Hz", "--running", 10000, "--teeth", 2, "--count", 3
    )
    assert code == 0, err
    assert "undetermined" in out and "9513.0" in out  # 60 x 951.3 / (2 x 3)


def test_the_rule_from_a_recording_with_a_model(capsys, tmp_path):
    from scipy.io import wavfile

    fs, n = 20000.0, 3000.0
    t = np.arange(int(1.0 * fs)) / fs
    x = sum(np.sin(2 * np.pi * k * n / 60 * t + k) / k for k in range(1, 30)) + 0.05 * np.sin(
        2 * np.pi * 519.0 * t
    )
    wavfile.write(tmp_path / "cut.wav", int(fs), (x / np.max(np.abs(x)) * 30000).astype(np.int16))
    p = tmp_path / "plain.toml"
    p.write_text(turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning"))
    out_csv = tmp_path / "rule.csv"
    code, out, err = run(capsys, "recommend", p, "--recording", tmp_path / "cut.wav", "--running", 3000,
                         "--depth", 1, "--width-max", 50, "--out", out_csv)  # fmt: skip
    assert code == 0, err
    assert "chatter frequency 519.00 Hz" in out
    with open(out_csv, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["verdict"] for r in rows} <= {"stable", "within margin", "unstable"}


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--max-rpm", "-100"], ["--max-rpm", "> 0"]),
        (["--margin", "1.5"], ["--margin", "[0, 1)"]),
        (["--margin", "-0.1"], ["--margin"]),
        (["--max-speed", "3"], ["--max-speed", "--max-rpm"]),
        (["--max-depth", "2kg"], ["--max-depth", "mm"]),
        (["--min-rpm", "13000"], ["min_rpm", "below"]),
        (["--depth", "1"], ["--depth", "--chatter"]),
        (["--chatter", "900"], ["--running"]),
        (["--max-width", "3"], ["max_width", "milling"]),
        (["--refine", "50"], ["--refine"]),
    ],
)
def test_bad_options_are_one_line_and_write_nothing(capsys, model, tmp_path, argv, words):
    out = tmp_path / "r.csv"
    code, _, err = run(capsys, "recommend", model, "--points", 20, "--out", out, *argv)
    assert_clean_error(code, err, *words)
    assert not out.exists()
    assert not list(tmp_path.glob("*.part*"))


@pytest.mark.parametrize(
    ("table", "words"),
    [
        ("[machine]\nmax_rpm = -100\n", ["[machine]", "max_rpm", "> 0"]),
        ("[machine]\npower = [[0, 1000], [5000, 2000], [4000, 2500]]\n", ["power", "increase"]),
        ("[machine]\npower = [[0, -1000]]\n", ["power", "> 0"]),
        ("[machine]\nmax_speed = 3\n", ["max_speed", "max_rpm"]),
        ("[machine]\nmaxrpm = 3\n", ["maxrpm", "max_rpm"]),
        ("[machine]\nfeed = 'fast'\n", ["feed", "number"]),
    ],
)
def test_bad_machine_tables(capsys, tmp_path, table, words):
    p = tmp_path / "m.toml"
    p.write_text(turning_text() + table)
    out = tmp_path / "r.csv"
    code, _, err = run(capsys, "recommend", p, "--speed", 2000, 12000, "--out", out)
    assert_clean_error(code, err, *words)
    assert not out.exists()


def test_bad_recordings(capsys, tmp_path):
    bad = tmp_path / "bad.wav"
    bad.write_text("not audio")
    out = tmp_path / "r.csv"
    code, _, err = run(capsys, "recommend", "--recording", bad, "--running", 3000, "--out", out)
    assert_clean_error(code, err, "bad.wav", "WAV")
    assert not out.exists()
    short = tmp_path / "short.csv"
    t = np.arange(200) / 20000.0
    short.write_text("\n".join(f"{a!r},{math.sin(2 * math.pi * 500 * a)!r}" for a in t.tolist()))
    code, _, err = run(capsys, "recommend", "--recording", short, "--running", 3000, "--out", out)
    assert_clean_error(code, err, "short.csv", "record at least")
    assert not out.exists()
    code, _, err = run(capsys, "recommend", "--recording", short, "--running", 3000, "--out", short)
    assert_clean_error(code, err, "--out")
