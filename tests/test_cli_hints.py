"""The command line helps with slips (issue 11, item 5): a misspelled option
gets its subcommand's usage and the nearest option; magnitudes far outside
what machines have (a unit slip) get one warning line each; an option that
does nothing says so; --quiet silences warnings; the shipped models raise no
warning at all."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import turning_text

from chatterlab.cli import main

ROOT = Path(__file__).resolve().parents[1]
SHAPER = str(ROOT / "studies" / "traverse_shaper" / "model.toml")
#: a cheap command that takes a width: the closed-loop FRF at 5 frequencies
FRF = ["frf", SHAPER, "--input", "rfe5.x", "--output", "rfe5.x", "--closed-loop", "--points", "5",
       "--fmin", "70", "--fmax", "71"]  # fmt: skip


def run(capsys, *argv):
    try:
        code = main(list(argv))
    except SystemExit as e:  # argparse
        code = e.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    ("argv", "suggestion"),
    [
        (["lobes", SHAPER, "--speed", "0.1", "1", "--widht-max", "1"], "did you mean --width-max?"),
        (["modes", SHAPER, "--cont", "3"], "did you mean --count?"),
        (["lobes", SHAPER, "--speedd", "0.1", "1"], "did you mean --speed?"),
    ],
)
def test_misspelled_option_gets_one_line_with_a_suggestion(capsys, argv, suggestion):
    code, _, err = run(capsys, *argv)
    assert code == 2
    (line,) = err.splitlines()  # one line, like every input error: no 18-line usage before it
    assert line.startswith(f"chatterlab {argv[0]}: error:") and suggestion in line
    assert line.endswith(f"the options: chatterlab {argv[0]} -h")


def test_shipped_model_raises_no_warning(capsys):
    code, _, err = run(capsys, "roots", SHAPER, "--width", "0.2", "--speed", "0.5", "--no-winding")
    assert code == 0 and "warning" not in err


@pytest.mark.parametrize(
    ("argv", "phrase"),
    [
        ([*FRF, "--width", "200000", "--speed", "0.5"], "typed in um"),
        ([*FRF, "--width", "0.0002", "--speed", "0.5"], "typed in m"),
        # the review's case: 2 mm typed in m gave "stable", exit 0 and no warning
        (["roots", SHAPER, "--width", "0.002", "--speed", "0.5", "--no-winding"], "typed in m"),
        (["lobes", SHAPER, "--speed", "0.5", "0.6", "--points", "3", "--width-max", "0.001", "--verify", "0"],
         "typed in m"),  # fmt: skip
        (["roots", SHAPER, "--width", "0.2", "--speed", "500", "--no-winding"], "outside 0.001..10 m/s"),
        (["roots", SHAPER, "--width", "0.2", "--terms", "pd", "--delay", "1.5"], "--delay has no effect"),
    ],
)
def test_unit_slips_warn_once_and_quiet_silences(capsys, argv, phrase):
    code, _, err = run(capsys, *argv)
    assert code == 0
    lines = [ln for ln in err.splitlines() if phrase in ln]
    assert len(lines) == 1 and lines[0].startswith("chatterlab: warning:")
    code, _, err = run(capsys, *argv, "--quiet")
    assert code == 0 and "warning" not in err


def test_cutting_stiffness_in_wrong_units_warns(capsys, tmp_path):
    """K_f = 2e3 'N/mm^2' typed as N/m^2: six decades too small."""
    m = tmp_path / "t.toml"
    m.write_text(turning_text(Kf=2.0e3))
    code, _, err = run(capsys, "check", str(m))
    assert code == 0 and "cutting stiffness" in err and "N/mm^2" in err


def test_every_documented_field_is_sweepable(capsys, tmp_path):
    """spring.holder.c2 is documented with a default and not written in the
    turning file: --set accepted it, --grid refused it. Sweeping it now works,
    and the lateral stiffness does not change the 1-DOF cut along x (b_lim
    equal at both grid points, to round-off); a misspelled field gets the
    reader's 'did you mean'."""
    import csv

    m = tmp_path / "t.toml"
    m.write_text(turning_text())
    out = tmp_path / "s.csv"
    code, _, err = run(
        capsys, "sweep", str(m), "--quantity", "b-lim", "--grid", "spring.holder.c2=1e7:2e7:2",
        "--speed", "3000", "--out", str(out), "--quiet",
    )  # fmt: skip
    assert code == 0, err
    rows = list(csv.DictReader(open(out)))
    b = [float(r["b_lim [m]"]) for r in rows if r.get("b_lim [m]")]
    assert len(b) == 2 and b[0] == pytest.approx(b[1], rel=1e-12)
    code, _, err = run(
        capsys, "sweep", str(m), "--quantity", "b-lim", "--grid", "spring.holder.cc2=1e7:2e7:2",
        "--speed", "3000", "--out", str(out), "--quiet",
    )  # fmt: skip
    assert code == 2 and "Did you mean 'c2'" in err
