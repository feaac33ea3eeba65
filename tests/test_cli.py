"""The command line: outputs people and scripts rely on, and bad input that
must end in one line and status 2 (never a traceback)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error, turning_text

from chatterlab.cli._main import main
from chatterlab.io._netcdf import read_netcdf

ROOT = Path(__file__).resolve().parents[1]
SHAPER = str(ROOT / "studies" / "traverse_shaper" / "model.toml")
RECON = np.array([76.28, 83.34, 115.35, 137.58, 176.61, 211.26, 234.39])

TURNING = turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning")

MATRIX = """
[matrices]
coordinates = ["q1", "q2"]
M = [[1.0, 0.0], [0.0, 0.5]]
L = [[20.0, 0.0], [0.0, 10.0]]
K = [[2.0e6, -1.0e6], [-1.0e6, 1.0e6]]
[[point]]
id = "tip"
coords = { x = "q2" }
[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "regenerative"
Kf = 1.0e9
width_ref = 0.001
[process]
kind = "turning"
rpm = 1500
"""


@pytest.fixture
def turning(tmp_path):
    p = tmp_path / "turning.toml"
    p.write_text(TURNING)
    return str(p)


@pytest.fixture
def matrix_model(tmp_path):
    p = tmp_path / "matrix.toml"
    p.write_text(MATRIX)
    return str(p)


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_check_summarises_the_shaper(capsys):
    code, out, _ = run(capsys, "check", SHAPER)
    assert code == 0
    assert "independent q_i          36" in out
    assert "dependent q_d            12" in out
    assert "given q_g                3" in out
    code, out, _ = run(capsys, "check", SHAPER, "--format", "json")
    d = json.loads(out)
    assert (d["independent"], d["dependent"], d["given"], d["springs"], d["beams"]) == (36, 12, 3, 9, 6)


def test_modes_json_contract_gives_the_seven_frequencies(capsys):
    code, out, _ = run(capsys, "modes", SHAPER, "--count", "7", "--format", "json")
    assert code == 0
    d = json.loads(out)
    assert d["kind"] == "modes" and d["position_m"] == 0.85
    f = np.array([m["frequency_hz"] for m in d["modes"]])
    assert f.shape == (7,)
    assert np.all(np.abs(f / RECON - 1) < 5e-3)  # geometry.md: within 0.5 %
    assert set(d["modes"][0]["points"]) >= {"tool", "rfe5", "rfe6", "slide"}
    assert len(d["modes"][0]["points"]["rfe5"]) == 3


def test_modes_csv_and_variant(capsys, tmp_path):
    out_csv = tmp_path / "m.csv"
    code, _, _ = run(
        capsys,
        "modes",
        SHAPER,
        "--count",
        "3",
        "--format",
        "csv",
        "--variant",
        "printed",
        "--out",
        str(out_csv),
    )
    assert code == 0
    rows = out_csv.read_text().strip().splitlines()
    assert rows[0].startswith("mode [1],frequency [Hz]")
    assert abs(float(rows[2].split(",")[1]) / 80.56 - 1) < 5e-3  # printed Table 2, mode 2


@pytest.mark.parametrize(
    "text, words",
    [
        ("not = [toml", ["not valid TOML"]),
        (
            '[[body]]\nid = "a"\nmass = -1.0\ninertia = 1.0\ncentre = [0.0, 0.0]\n',
            ['[[body]] "a"', "mass", ">= 0"],
        ),
        (
            '[[body]]\nid = "a"\nmas = 1.0\ninertia = 1.0\ncentre = [0.0, 0.0]\n',
            ["unknown field 'mas'", "Did you mean 'mass'"],
        ),
    ],
)
def test_bad_model_file_is_one_line_and_status_2(capsys, tmp_path, text, words):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    code, _, err = run(capsys, "modes", str(p))
    assert_clean_error(code, err, str(p), *words)


def test_floating_structure_is_an_error_naming_the_part(capsys, tmp_path):
    p = tmp_path / "float.toml"
    p.write_text('[[body]]\nid = "loose"\nmass = 1.0\ninertia = 1.0\ncentre = [0.0, 0.0]\n')
    code, _, err = run(capsys, "modes", str(p))
    assert_clean_error(code, err, "not held by the foundation", "loose")


def test_frf_closed_loop_json_and_plot(capsys, tmp_path):
    png = tmp_path / "frf.png"
    code, out, _ = run(
        capsys, "frf", SHAPER, "--input", "rfe5.x", "--output", "rfe5.x", "--output", "rfe5.y",
        "--fmin", "60", "--fmax", "100", "--points", "50", "--closed-loop", "--width", "2", "--speed", "0.5",
        "--format", "json", "--plot", str(png),
    )  # fmt: skip
    assert code == 0
    d = json.loads(out)
    assert d["closed_loop"] and d["terms"] == "pdo" and abs(d["delay_s"] - 1.5) < 1e-12
    assert np.array(d["real"]).shape == (2, 1, 50)
    _assert_drawn(png)


def test_frf_and_roots_on_a_matrix_level_model(capsys, matrix_model):
    code, out, _ = run(capsys, "frf", matrix_model, "--input", "tip.x", "--output", "tip.x", "--points", "10")
    assert code == 0 and out.startswith("frequency [Hz]")
    code, out, _ = run(
        capsys, "roots", matrix_model, "--width", "0.01", "--speed", "1500", "--format", "json"
    )
    assert code == 0
    d = json.loads(out)
    assert d["verdict"] == "stable" and d["agree"] is True


@pytest.mark.parametrize(
    "argv, words",
    [
        (["frf", SHAPER, "--input", "rfe9.x", "--output", "rfe5.x"], ["unknown point 'rfe9'"]),
        (["frf", SHAPER, "--input", "rfe5.q", "--output", "rfe5.x"], ["POINT.DIRECTION"]),
        (
            ["frf", SHAPER, "--input", "rfe5.x", "--output", "rfe5.x", "--fmin", "50", "--fmax", "10"],
            ["empty"],
        ),
        (["frf", SHAPER, "--input", "rfe5.x", "--output", "rfe5.x", "--fmin", "-5"], ["fmin"]),
        (["roots", SHAPER, "--width", "-1", "--speed", "0.5"], ["--width", "> 0"]),
        (["roots", SHAPER, "--width", "2", "--delay", "0"], ["delay", "> 0"]),
        (["lobes", SHAPER, "--speed", "1.0", "0.5"], ["reversed"]),
        (["lobes", SHAPER, "--speed", "0.5", "1.0", "--points", "0"], ["--points"]),
        (["sweep", SHAPER, "--grid", "spring.nothere.c2=1e8:2e9:3", "--quantity", "min-b-lim"], ["nothere"]),
        (["sweep", SHAPER, "--grid", "width=3:1:4", "--quantity", "b-lim"], []),
        (["simulate", SHAPER, "--step", "2"], ["larger than the delay"]),
        (["simulate", SHAPER, "--duration", "-1"], ["--duration"]),
    ],
)
def test_bad_arguments_are_one_line_and_status_2(capsys, argv, words):
    code, _, err = run(capsys, *argv)
    assert_clean_error(code, err, *words)


def test_unreachable_dask_scheduler_is_a_clear_error(capsys, turning):
    pytest.importorskip("distributed")
    code, _, err = run(
        capsys, "sweep", turning, "--grid", "width=0.1:1:3", "--quantity", "stable", "--speed", "3000",
        "--backend", "dask", "--scheduler", "tcp://127.0.0.1:1", "--quiet",
    )  # fmt: skip
    assert_clean_error(code, err, "127.0.0.1:1")


def test_roots_table_and_verdict_on_turning(capsys, turning):
    # below and above the minimum b_lim = 0.6525 mm (2 k zeta (1 + zeta) / K_f) at its speed
    code, out, _ = run(capsys, "roots", turning, "--width", "0.5", "--speed", "6548.5")
    assert code == 0 and "verdict: stable" in out
    code, out, _ = run(capsys, "roots", turning, "--width", "0.8", "--speed", "6548.5", "--format", "json")
    d = json.loads(out)
    assert d["verdict"] == "unstable" and d["agree"] is True and d["roots"][0]["real_per_s"] > 0


def test_lobes_writes_netcdf_csv_and_png(capsys, turning, tmp_path):
    nc, csv_, png = tmp_path / "l.nc", tmp_path / "l.csv", tmp_path / "l.png"
    code, out, _ = run(capsys, "lobes", turning, "--speed", "4000", "9000", "--points", "80", "--width-max", "5",
                       "--out", str(nc), "--plot", str(png))  # fmt: skip
    assert code == 0 and "minimum b_lim" in out
    ds = read_netcdf(nc)
    b, unit, _ = ds.data["b_lim"]
    assert unit == "m" and ds.coords["speed"][1] == "rpm"
    # the sampled envelope cannot dip below the absolute minimum 2 k zeta (1 + zeta) / K_f and,
    # with 80 speeds over 4000-9000 rpm, comes within 0.1 % of it
    bmin = 2 * 2.0e7 * 0.0316227766 * (1 + 0.0316227766) / 2.0e9
    assert b.shape == (80,) and bmin * (1 - 1e-9) <= np.nanmin(b) < bmin * 1.001
    code, _, _ = run(
        capsys, "lobes", turning, "--speed", "4000", "9000", "--points", "80", "--out", str(csv_)
    )
    assert csv_.read_text().splitlines()[0].startswith("speed [rpm],delay [s],b_lim [m]")
    _assert_drawn(png)


@pytest.mark.slow
def test_lobes_atlas_resume_gives_the_same_file(capsys, tmp_path):
    out1, out2 = tmp_path / "a1.nc", tmp_path / "a2.nc"
    args = [
        "lobes",
        SHAPER,
        "--speed",
        "0.2",
        "0.6",
        "--points",
        "20",
        "--width-max",
        "1",
        "--positions",
        "0.7",
        "1.0",
        "2",
        "--quiet",
        "--jobs",
        "1",
    ]
    assert run(capsys, *args, "--out", str(out1))[0] == 0
    assert run(capsys, *args, "--out", str(out2))[0] == 0
    # resuming a finished run computes nothing and rewrites the same data
    assert run(capsys, *args, "--out", str(out2), "--resume")[0] == 0
    a, b = read_netcdf(out1), read_netcdf(out2)
    for k in ("b_lim", "chatter_frequency"):
        assert np.array_equal(a.data[k][0], b.data[k][0], equal_nan=True)


def test_simulate_continuous_cut_writes_csv(capsys, turning, tmp_path):
    out = tmp_path / "s.csv"
    code, txt, _ = run(capsys, "simulate", turning, "--speed", "3000", "--position", "0", "--duration", "0.05",
                       "--width", "0.5", "--out", str(out), "--quiet")  # fmt: skip
    assert code == 0, txt
    head = out.read_text().splitlines()[0]
    assert head.startswith("t [s],position [m],in_cut [-],cut_distance [m]")


def test_console_script_and_light_import():
    r = subprocess.run(
        [sys.executable, "-m", "chatterlab.cli._main", "--version"], capture_output=True, text=True
    )
    assert r.returncode == 0 and r.stdout.startswith("chatterlab ")
    code = "import sys, chatterlab; print(sorted(m for m in ('matplotlib', 'joblib', 'control', 'dask') if m in sys.modules))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.stdout.strip() == "[]"


def test_complete_atlas_drops_its_default_checkpoint_and_reruns(capsys, tmp_path):
    out = tmp_path / "atlas.nc"
    args = ["lobes", SHAPER, "--speed", "0.4", "0.6", "--points", "6", "--width-max", "1", "--positions", "0.8", "0.9", "2", "--quiet", "--jobs", "1", "--out", str(out)]  # fmt: skip
    assert run(capsys, *args)[0] == 0
    assert out.exists() and not (tmp_path / "atlas.nc.ckpt").exists()
    assert run(capsys, *args)[0] == 0  # the same command again works


def test_sweep_quantity_needing_a_width_is_refused_up_front(capsys):
    code, _, err = run(
        capsys, "sweep", SHAPER, "--grid", "speed=0.4:0.6:3", "--quantity", "stable", "--quiet"
    )
    assert_clean_error(code, err, "needs a width")


def test_json_is_strict_even_with_non_finite_numbers(capsys, matrix_model):
    # roots at a width far beyond the structure's range: whatever the numbers, the JSON must parse strictly
    code, out, _ = run(
        capsys, "roots", matrix_model, "--width", "0.01", "--speed", "1500", "--format", "json"
    )
    json.loads(out, parse_constant=lambda c: pytest.fail(f"non-standard JSON constant {c}"))
    from chatterlab.io._files import json_text

    assert json_text({"a": float("nan"), "b": [1.0, float("inf")]}, None) == '{"a": null, "b": [1.0, null]}'


def _assert_drawn(png) -> None:
    """A real figure, read back: an RGB(A) image of plausible size whose
    pixels are not one colour, with more than 1 % of them off the background
    (axes, curves, labels): a blank or failed canvas fails this."""
    import matplotlib.image

    img = matplotlib.image.imread(png)
    assert img.ndim == 3 and img.shape[0] >= 300 and img.shape[1] >= 400, img.shape
    rgb = img[..., :3]
    assert (np.abs(rgb - rgb[0, 0]).max(axis=-1) > 0.1).mean() > 0.01
