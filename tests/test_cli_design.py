"""``chatterlab sensitivity`` and ``chatterlab absorber``: the tables, files and
plots they promise, and bad input refused in one line with status 2.

The numbers are the library's (tests/test_design_sensitivity.py and
tests/test_design_absorber.py hold the oracles); here the command line must
print and write the same numbers: the 1-DOF tool's elasticity of b_min with
respect to K_f is exactly -1 (b_min is proportional to 1/K_f), and the
elasticity with respect to the damping c is 1 + zeta / (1 + zeta) ... written
out from b = 2 k zeta (1 + zeta) / K_f: (c/b) db/dc = (1 + 2 zeta)/(1 + zeta).
"""

from __future__ import annotations

import csv

import numpy as np
import pytest
from conftest import assert_clean_error, turning_text

from chatterlab.cli._main import main

M, K, C, KF = 1.0, 1.0e7, 189.7, 2.0e9
ZETA = C / (2 * np.sqrt(K * M))


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture
def tool(tmp_path):
    p = tmp_path / "tool.toml"
    p.write_text(turning_text(mass=M, stiffness=K, damping=C, Kf=KF))
    return str(p)


def test_sensitivity_table_csv_and_plot(capsys, tmp_path, tool):
    out_csv, png = tmp_path / "s.csv", tmp_path / "s.png"
    code, out, err = run(
        capsys, "sensitivity", tool, "--speed", "9000", "14000", "--points", "30", "--out", str(out_csv),
        "--plot", str(png),
    )  # fmt: skip
    assert code == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("sensitivity of the minimum over the speed range")
    # default fields: the body's mass and inertia, the spring's c1 and d1, the coupling's Kf
    rows = {r["field"]: r for r in csv.DictReader(open(out_csv))}
    assert set(rows) == {
        "body.tool.mass",
        "body.tool.inertia",
        "spring.holder.c1",
        "spring.holder.d1",
        "coupling.cut.Kf",
    }
    el = {f: float(r["elasticity_minimum [-]"]) for f, r in rows.items()}
    # the elasticities of the closed form b = 2 k zeta (1 + zeta) / K_f (1e-12: its exact derivatives)
    assert el["coupling.cut.Kf"] == pytest.approx(-1.0, rel=1e-12)
    assert el["spring.holder.d1"] == pytest.approx((1 + 2 * ZETA) / (1 + ZETA), rel=1e-12)
    assert el["body.tool.inertia"] == 0.0  # the rotation is held: the inertia does nothing
    # ranked by p db/dp: the damping first, K_f last, in the table as in the file
    assert "spring.holder.d1" in lines[3] and "coupling.cut.Kf" in lines[7]
    assert [r["field"] for r in csv.DictReader(open(out_csv))][0] == "spring.holder.d1"
    assert png.stat().st_size > 0


def test_sensitivity_of_chosen_fields_by_unit(capsys, tool):
    code, out, err = run(
        capsys, "sensitivity", tool, "--speed", "9000", "14000", "--points", "20", "--fields", "spring.holder.c1",
        "body.tool.mass", "--by", "unit", "--limit", "absolute",
    )  # fmt: skip
    assert code == 0, err
    assert "absolute minimum (all speeds)" in out and "per unit change" in out
    assert "2 fields" in out


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--fields", "spring.nope.c1"], ["spring.nope.c1", "no [[spring]] with id 'nope'"]),
        (["--fields", "spring.holder.c7"], ["spring.holder.c7", "no field 'c7'"]),
        (["--count", "0"], ["--count"]),
        (["--out", "s.json"], ["--out"]),
        (["--width-max", "-1"], ["--width-max"]),
    ],
)
def test_sensitivity_bad_input(capsys, tool, extra, words, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, "sensitivity", tool, "--speed", "9000", "14000", "--points", "10", *extra)
    assert_clean_error(code, err, *words)


def test_absorber_added_at_a_point(capsys, tmp_path, tool):
    png, out_csv = tmp_path / "a.png", tmp_path / "a.csv"
    code, out, err = run(
        capsys, "absorber", tool, "--speed", "3000", "15000", "--points", "40", "--at", "tip", "--direction", "x",
        "--mass", "0.05", "--starts", "1", "--verify", "2", "--objective", "absolute", "--plot", str(png),
        "--out", str(out_csv),
    )  # fmt: skip
    assert code == 0, err
    assert "tva: mass 0.05 kg" in out
    assert "checks agree" in out and "FAILED" not in out
    tuned = float(out.split("tuned: ")[1].split(" mm")[0])
    bare = float(out.split("without the absorbers: ")[1].split(" mm")[0])
    dh = float(out.split("Den Hartog's tuning")[1].split("): ")[1].split(" mm")[0])
    assert tuned > dh > bare  # tuned above Den Hartog's, both above the bare tool's 0.309 mm
    assert bare == pytest.approx(2 * K * ZETA * (1 + ZETA) / KF * 1e3, rel=1e-3)  # printed to 4 digits
    assert png.stat().st_size > 0
    header = next(csv.reader(open(out_csv)))
    assert header[0].startswith("speed") and "b_lim [m]" in header


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--at", "tip", "--direction", "x"], ["--at needs --mass"]),
        (["--at", "tip", "--direction", "x", "--mass", "-0.1"], ["--mass", "> 0"]),
        (["--at", "nowhere", "--direction", "x", "--mass", "0.05"], ["'nowhere' is not a point"]),
        (
            ["--at", "tip", "--direction", "x", "--mass", "0.05", "--frequency", "500", "400"],
            ["--frequency LO HI", "empty"],
        ),
        (
            ["--at", "tip", "--direction", "x", "--mass", "0.05", "--damping", "0.3", "0.1"],
            ["--damping LO HI", "empty"],
        ),
        (["--at", "tip", "--direction", "x", "--mass", "0.05", "--mass-max", "0"], ["--mass-max", "> 0"]),
        (["--mass", "0.05"], ["--mass", "--at"]),
        ([], ["no [[absorber]]"]),
        (["--at", "tip", "--direction", "x", "--mass", "0.05", "--starts", "0"], ["--starts"]),
    ],
)
def test_absorber_bad_input(capsys, tool, extra, words):
    code, _, err = run(capsys, "absorber", tool, "--speed", "3000", "15000", "--points", "10", *extra)
    assert_clean_error(code, err, *words)


def test_active_velocity_feedback_from_the_command_line(capsys, tmp_path, tool):
    """``chatterlab active --sensor tip.x`` with velocity feedback alone, no delay:
    the limit grows with the gain, so the optimum is the bound g = 300 N s/m and
    the absolute minimum Tlusty's 2 k zeta' (1 + zeta') / K_f with zeta' = zeta +
    g / (2 sqrt(k m)), printed to 5 digits; one delay (the cut's), so the
    time-domain confirmation can be proven: STABLE at 1.1 x the old limit."""
    out_json, out_csv = tmp_path / "a.json", tmp_path / "a.csv"
    code, out, err = run(
        capsys, "active", tool, "--speed", "3000", "15000", "--points", "30", "--sensor", "tip.x", "--free",
        "velocity", "--velocity", "0,300", "--objective", "absolute", "--gain-margin", "1", "--phase-margin", "0",
        "--starts", "1", "--verify", "2", "--out", str(out_json),
    )  # fmt: skip
    assert code == 0, err
    zp = ZETA + 300.0 / (2 * np.sqrt(K * M))
    want = 2 * K * zp * (1 + zp) / KF * 1e3
    got = float(out.split("optimised: ")[1].split(" mm")[0])
    assert got == pytest.approx(want, rel=5e-5)  # 5 significant digits printed
    assert "g_V 300 N s/m" in out
    assert "time-domain confirmation at" in out and ": STABLE (" in out
    assert "checks agree" in out and "FAILED" not in out
    import json

    attrs = json.loads(out_json.read_text())["attrs"]
    assert attrs["confirmation_verdict"] == "stable" and attrs["confirmation_count_proven"] == "True"
    code, out2, err = run(
        capsys, "active", tool, "--speed", "3000", "15000", "--points", "30", "--sensor", "tip.x", "--free",
        "velocity", "--velocity", "0,300", "--objective", "absolute", "--gain-margin", "1", "--phase-margin", "0",
        "--starts", "1", "--verify", "0", "--no-confirm", "--out", str(out_csv),
    )  # fmt: skip
    assert code == 0, err
    assert "time-domain confirmation" not in out2 and "not verified" in out2
    header = next(csv.reader(open(out_csv)))
    assert header[0].startswith("speed") and "b_lim_after [m]" in header


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--sensor", "nowhere.x"], ["'nowhere' is not a point"]),
        (["--sensor", "tip.z"], ["POINT.DIR"]),
        (["--sensor", "tip.x", "--velocity", "5,1"], ["the bound is empty"]),
        (["--sensor", "tip.x", "--velocity", "abc"], ["--velocity takes LO,HI"]),
        (["--sensor", "tip.x", "--bandwidth", "-3"], ["--bandwidth"]),
        (["--sensor", "tip.x", "--starts", "0"], ["--starts"]),
        (["--bandwidth", "300"], ["--bandwidth", "--sensor"]),
        ([], ["no [[actuator]]"]),
    ],
)
def test_active_bad_input(capsys, tool, extra, words):
    code, _, err = run(capsys, "active", tool, "--speed", "3000", "15000", "--points", "10", *extra)
    assert_clean_error(code, err, *words)


def test_lobes_of_a_model_with_actuators_are_the_controlled_structure_s(capsys, tmp_path):
    """Review: `lobes` ignored [[actuator]] (the bare tool's limit, one
    failed check).  An ideal collocated velocity feedback g at the tip is a
    damper: the 1-DOF tool with c + g, whose smallest limit is the closed
    form 2 k zeta (1 + zeta) / K_f per b_ref (Tlusty), zeta = (c + g) /
    (2 sqrt(k m)); the speed range holds lobes down to that minimum."""
    g = 300.0
    p = tmp_path / "act.toml"
    p.write_text(
        turning_text(mass=M, stiffness=K, damping=C, Kf=KF)
        + '\n[[actuator]]\nid = "d"\nsensor = "tip"\nsensor_direction = "x"\nvelocity_gain = 300.0\n'
    )
    code, out, err = run(capsys, "lobes", str(p), "--speed", "1000", "6000", "--width-max", "50")
    assert code == 0, err
    zeta = (C + g) / (2 * np.sqrt(K * M))
    b_min = 2 * K * zeta * (1 + zeta) / KF * 1e3  # mm (width_ref 1 mm: K_f per metre of width)
    line = next(ln for ln in out.splitlines() if "absolute minimum" in ln)
    # the D-subdivision's minimum: exact to its root finding (rtol ~1e-9), printed to 4 digits
    assert f"{b_min:.4g} mm" in line, (line, b_min)


def test_sensitivity_with_no_limit_below_the_ceiling_is_refused(capsys, tmp_path, tool):
    """Review: a ceiling below every limit ranked nothing (all NaN) with exit
    0 and wrote the file.  The tool's smallest limit at any speed is the
    closed form 2 k zeta (1 + zeta) / K_f = 0.31 mm: below a 0.2 mm ceiling
    there is nothing to differentiate -- one line, status 2, no file."""
    out = tmp_path / "s.csv"
    code, _, err = run(
        capsys, "sensitivity", tool, "--speed", "1000", "6000", "--width-max", "0.2", "--out", str(out)
    )
    assert_clean_error(code, err, "no limit below the width ceiling 0.2 mm", "raise the ceiling")
    assert not out.exists()
    assert 2 * K * ZETA * (1 + ZETA) / KF > 0.2e-3  # the oracle: the limit lies above the ceiling
