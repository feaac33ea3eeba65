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
        ([*FRF, "--width", "200", "--speed", "0.5"], "above 100 mm"),  # as the Python API's UnitWarning
        ([*FRF, "--width", "0.0002", "--speed", "0.5"], "typed in m"),
        # the review's case: 2 mm typed in m gave "stable", exit 0 and no warning
        (["roots", SHAPER, "--width", "0.002", "--speed", "0.5", "--no-winding"], "typed in m"),
        (
            [
                "lobes",
                SHAPER,
                "--speed",
                "0.5",
                "0.6",
                "--points",
                "3",
                "--width-max",
                "0.001",
                "--verify",
                "0",
            ],
            "typed in m",
        ),  # fmt: skip
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


def test_python_api_warns_for_a_width_in_mm_and_the_cli_shows_only_its_own(capsys):
    """stability(width=2) meant 2 mm: a UnitWarning naming the likely value;
    the CLI says it in mm in its own one line, with no Python warning text."""
    import warnings

    import chatterlab as cl
    from chatterlab.errors import UnitWarning

    fz = cl.assemble(cl.load_model(SHAPER)).at(0.85)
    with pytest.warns(UnitWarning, match=r"width = 2 m is above 0.1 m and 1000 times.*did you mean 0.002"):
        cl.closed_loop(fz, width=2.0, speed=0.5)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitWarning)
        cl.closed_loop(fz, width=2e-3, speed=0.5)  # 2 mm in m: no warning
    code, _, err = run(
        capsys, "roots", SHAPER, "--width", "200", "--speed", "0.5", "--no-winding", "--count", "1"
    )
    assert "UnitWarning" not in err and err.count("warning:") == 1 and "above 100 mm" in err


TAP = str(Path(__file__).resolve().parents[1] / "studies" / "tap_test" / "tool_point.csv")
MILL_FRF = ["lobes", "--frf", TAP, "--teeth", "3", "--immersion", "0.5", "--speed", "3000", "30000",
            "--points", "20"]  # fmt: skip


def test_milling_from_a_measured_frf_says_zoa_warns_on_kt_in_n_per_mm2_and_refuses_floquet(capsys):
    """From a tap-test file the milling lobes are ZOA: the summary says so
    and what it misses; Kt typed in N/mm^2 is named as typed; --method
    spectral|sdm, which needs modes, is refused (all found by a review)."""
    code, out, err = run(capsys, *MILL_FRF, "--kt", "7e8", "--kn", "2.1e8")
    assert code == 0 and "zeroth-order approximation" in out and "flip lobes are not modelled" in out
    assert "warning" not in err
    code, _, err = run(capsys, *MILL_FRF, "--kt", "700", "--kn", "210")
    assert code == 0 and "milling Kt = 700 N/m^2" in err and "7e+08" in err
    code, _, err = run(capsys, *MILL_FRF, "--kt", "7e8", "--kn", "2.1e8", "--method", "spectral")
    assert code == 2 and "fit_modes" in err and len(err.strip().splitlines()) == 1
