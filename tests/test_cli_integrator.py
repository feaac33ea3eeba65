"""``chatterlab simulate --integrator exponential --rtol R``: the exact step
map from the command line (issue 26, time rows).

Oracle: the 1-DOF turning tool of docs/model-format.md, G = 1/(k - m w^2 +
j c w).  Its envelope's growth rate must be the real part of the rightmost
characteristic root (an independent route: the roots of the delay equation,
chatterlab.frequency.characteristic_roots) within the error bar the command
prints, and the class (decaying / growing) must be that root's sign, below
and above Tlusty's limit; bad combinations are one line, status 2."""

from __future__ import annotations

import re

import pytest
from conftest import assert_clean_error, turning_text

import chatterlab as cl
from chatterlab.cli import main
from chatterlab.frequency import characteristic_roots


@pytest.fixture(scope="module")
def tool(tmp_path_factory):
    path = tmp_path_factory.mktemp("integrator") / "tool.toml"
    path.write_text(turning_text())
    return path


def _rightmost(path, width_m: float) -> float:
    frozen = cl.assemble(cl.load_model(str(path))).at()
    loop = cl.closed_loop(frozen, width=width_m, speed=3000.0)
    return float(max(characteristic_roots(loop, count=6).roots.real))


# 0.15 mm is half Tlusty's unconditional limit 2 k zeta (1 + zeta) / K_f = 0.309 mm (zeta = 0.03),
# so stable at any speed; 1 mm is three times it and, at 3000 rpm, unstable (the root says so)
@pytest.mark.parametrize("width_mm", [0.15, 1.0])
def test_the_rate_is_the_rightmost_roots_within_the_printed_error(tool, width_mm, capsys):
    code = main(["simulate", str(tool), "--width", str(width_mm), "--integrator", "exponential", "--rtol", "1e-4",
                 "--passes", "40", "--q0", "tip.x=0.01", "--quiet"])  # fmt: skip
    out = capsys.readouterr().out
    m = re.search(r"tool\.x .*envelope: (decaying|growing) \(([-+][0-9.]+) \+- ([0-9.e-]+) 1/s\)", out)
    assert m, out
    sigma = _rightmost(tool, width_mm * 1e-3)
    assert m.group(1) == ("growing" if sigma > 0 else "decaying")
    # the printed rate and its error bar (Richardson's step error + the fit's 2 standard errors)
    # are rounded to their printed digits: one unit of the last digit on top
    rate, err = float(m.group(2)), float(m.group(3))
    assert abs(rate - sigma) <= err + 0.01, (rate, err, sigma)
    assert "exponential step map of order 6" in out and "rtol = 0.0001" in out
    assert code == 0


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--integrator", "newmark"], ("--rtol", "--integrator newmark")),
        (["--step", "1e-4"], ("--rtol", "--step")),
    ],
)
def test_rtol_with_a_newmark_run_is_refused(tool, extra, words, capsys):
    code = main(["simulate", str(tool), "--rtol", "1e-3", "--quiet", *extra])
    assert_clean_error(code, capsys.readouterr().err, *words)


def test_rtol_on_the_moving_slide_is_refused(capsys):
    """The moving slide integrates with Newmark (its coefficients change with
    the slide's position): an error target there would be ignored, so it is refused."""
    from pathlib import Path

    shaper = Path(__file__).resolve().parents[1] / "studies" / "traverse_shaper" / "model.toml"
    code = main(["simulate", str(shaper), "--rtol", "1e-3", "--passes", "1", "--quiet"])
    assert_clean_error(code, capsys.readouterr().err, "rtol", "moving slide")


def test_the_default_scheme_of_a_continuous_cut_is_the_exponential_step_map(tool, capsys):
    """``--integrator auto`` (the default): a turning cut has constant
    coefficients, so it runs the exponential step map for the default rtol;
    with --step it is the paper's Newmark at that step."""
    assert main(["simulate", str(tool), "--width", "0.15", "--passes", "10", "--quiet"]) == 0
    assert "exponential step map of order 6" in capsys.readouterr().out
    assert (
        main(["simulate", str(tool), "--width", "0.15", "--passes", "10", "--step", "1e-4", "--quiet"]) == 0
    )
    out = capsys.readouterr().out
    assert "exponential step map" not in out and "2000 steps of h = 0.0001 s" in out


def test_a_milling_run_refuses_the_exponential_integrator(capsys):
    from pathlib import Path

    mill = Path(__file__).resolve().parents[1] / "studies" / "milling" / "benchmark_1dof.toml"
    code = main(["simulate", str(mill), "--integrator", "exponential", "--quiet"])
    assert_clean_error(code, capsys.readouterr().err, "--integrator exponential", "milling")


def test_a_milling_run_refuses_rtol(capsys):
    """A milling run integrates with Newmark: an error target there would be ignored (found by review)."""
    from pathlib import Path

    mill = Path(__file__).resolve().parents[1] / "studies" / "milling" / "benchmark_1dof.toml"
    code = main(["simulate", str(mill), "--width", "0.2", "--rtol", "1e-3", "--quiet"])
    assert_clean_error(code, capsys.readouterr().err, "--rtol", "milling")


@pytest.mark.parametrize("rtol", ["0", "2", "nan", "1e-20"])
def test_an_rtol_outside_0_1_is_one_line(tool, rtol, capsys):
    code = main(["simulate", str(tool), "--integrator", "exponential", "--rtol", rtol, "--quiet"])
    assert_clean_error(code, capsys.readouterr().err, "rtol")


def test_a_mode_the_step_does_not_resolve_is_no_contradiction(capsys):
    """The shaper's rightmost root is a weakly excited 2789 Hz mode; the
    exponential map steps over its period (h = 0.24 ms, exact in the linear
    part) and the envelopes follow the 76 Hz modes, which decay faster.
    Newmark's period error (w h)^2/12 widened the frequency window of the
    contradiction check to 4 kHz; the exact map has no period error, so the
    window is the spectral resolution and no contradiction is claimed."""
    from pathlib import Path

    shaper = Path(__file__).resolve().parents[1] / "studies" / "traverse_shaper" / "model.toml"
    code = main(["simulate", str(shaper), "--delay", "0.05", "--position", "0.85", "--duration", "2",
                 "--q0", "rfe5.y=0.01", "--history", "constant", "--integrator", "exponential", "--quiet"])  # fmt: skip
    cap = capsys.readouterr()
    assert code == 0, cap.err
    assert "CONTRADICTION" not in cap.out + cap.err
    assert cap.out.count("envelope: decaying") == 4


@pytest.mark.parametrize("integrator", ["exponential", "newmark"])
def test_a_run_within_the_first_delay_decides_nothing(tool, integrator, capsys):
    """At 0.39 mm, 3000 rpm (T = 20 ms) the rightmost root is +0.689 1/s:
    the cut chatters.  A run of one delay only shows the structure's own
    decay (-94.8 1/s: the delayed term reads the zero history before t = 0),
    which the exponential map resolves so well that its error bar was tiny
    and the verdict said "decaying" (found by review).  Such a window is
    undetermined, with the reason, and is no contradiction of the root."""
    code = main(["simulate", str(tool), "--width", "0.39", "--speed", "3000", "--duration", "0.02",
                 "--q0", "tip.x=0.001", "--integrator", integrator, "--quiet"])  # fmt: skip
    out = capsys.readouterr().out
    assert code == 0 and "decaying" not in out and "CONTRADICTION" not in out, out
    assert _rightmost(tool, 0.39e-3) > 0.5
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("tool.x"))
    assert "envelope: undetermined" in line
