"""What the command line's summaries say where a bare number would mislead
(issue 11): a refused ``--resume`` names what changed and how to start
afresh; an ``inf`` b_lim says whether it is proven (certified band) or
undetermined; a ``simulate`` run too short for a spectrum or a growth rate
says so, with its initial condition and how to ask for more, and exits 0.

The oracle model is docs/model-format.md's 1-DOF turning tool (m = 2 kg,
k = 2e7 N/m, c = 400 N s/m, K_f = 2e9 N/m^2): its smallest stability limit
over all speeds is b_min = 2 k zeta (1 + zeta) / K_f = 0.6525 mm (Tlusty).
"""

from __future__ import annotations

import json
import math
import re

import pytest
from conftest import assert_clean_error, turning_text

from chatterlab.cli._main import main

M, K, C, KF = 2.0, 2.0e7, 400.0, 2.0e9
ZETA = C / (2 * math.sqrt(K * M))
B_MIN_MM = 2 * K * ZETA * (1 + ZETA) / KF * 1e3  # 0.6525 mm


@pytest.fixture
def turning(tmp_path):
    p = tmp_path / "turning.toml"
    p.write_text(turning_text(mass=M, stiffness=K, damping=C, Kf=KF))
    return str(p)


@pytest.fixture
def forced(tmp_path):
    """The same tool with a constant 100 N cutting force: something to see."""
    p = tmp_path / "forced.toml"
    p.write_text(turning_text(mass=M, stiffness=K, damping=C, Kf=KF, forces=(100.0, 0.0, 0.0)))
    return str(p)


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


# ----------------------------------------------------------------------------- resume


def test_refused_resume_names_the_changed_option_and_how_to_start_afresh(capsys, turning, tmp_path):
    ck = str(tmp_path / "ck")

    def sweep(*, grid="width=0.1:1:3", speed="3000", extra=()):
        return ["sweep", turning, "--quantity", "stable", "--grid", grid, "--speed", speed, *extra,
                "--checkpoint", ck, "--backend", "serial", "--quiet"]  # fmt: skip

    assert run(capsys, *sweep())[0] == 0
    # the same sweep resumes (positive control: the refusals below are for the changes)
    assert run(capsys, *sweep(), "--resume")[0] == 0
    for argv, named in (
        (sweep(extra=("--terms", "o")), "--terms is 'pdo' there, 'o' now"),
        (sweep(speed="2000"), "--speed is '3000.0' there, '2000.0' now"),
        (sweep(extra=("--set", "spring.holder.c1=3e7")), "model (file, --variant, --set)"),
        (sweep(grid="width=0.1:1:4"), "axis 'width' differs"),  # named by the engine
    ):
        code, _, err = run(capsys, *argv, "--resume")
        assert_clean_error(code, err, named, "to start afresh", "without --resume", "--checkpoint DIR", ck)


# ----------------------------------------------------------------------------- inf


def test_sweep_inf_below_the_closed_form_minimum_is_a_proven_claim(capsys, turning):
    # a ceiling below b_min: no boundary can lie under it at any speed, and the
    # automatic band of this plant is certified (loop gain bound below 1 outside it)
    ceiling = 0.6
    assert ceiling < B_MIN_MM
    code, out, _ = run(capsys, "sweep", turning, "--quantity", "b-lim", "--grid", "speed=4000:9000:6",
                       "--width-max", str(ceiling), "--backend", "serial", "--quiet")  # fmt: skip
    assert code == 0, out
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("b_lim [m]"))
    assert (
        "no finite values; inf at 6 of 6 points: no boundary below the width ceiling 0.6 mm in the certified band"
        in line
    )
    # above b_min the minimum over the speeds is finite and not below the closed form
    code, out, _ = run(capsys, "sweep", turning, "--quantity", "min-b-lim", "--grid", "spring.holder.d1=400:400:1",
                       "--width-max", "1", "--backend", "serial", "--quiet")  # fmt: skip
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("b_lim_min [m]"))
    printed = float(re.search(r": min ([0-9.e+-]+),", line).group(1))
    # printed with 6 significant digits: rounding is within 5e-6 relative
    assert "inf" not in line and printed == pytest.approx(B_MIN_MM * 1e-3, rel=5e-6)


def test_atlas_inf_is_proven_in_the_automatic_band_and_undetermined_in_a_given_one(capsys, turning):
    args = ["lobes", turning, "--speed", "4000", "9000", "--points", "5", "--width-max", "0.6",
            "--positions", "0", "0.1", "2", "--backend", "serial", "--quiet"]  # fmt: skip
    code, out, _ = run(capsys, *args)
    assert code == 0, out
    assert "worst case along the stroke: no finite b_lim" in out and "inf mm" not in out
    rows = [ln for ln in out.splitlines() if ln.strip().startswith("position")]
    assert len(rows) == 2
    for ln in rows:
        assert "inf at 5 of 5 speeds: no boundary below the width ceiling 0.6 mm in the certified band" in ln
    # a band given by --fmin/--fmax proves nothing outside it: the same inf is undetermined
    code, out, _ = run(capsys, *args, "--fmin", "100", "--fmax", "2000")
    rows = [ln for ln in out.splitlines() if ln.strip().startswith("position")]
    assert code == 0 and all("inf at 5 of 5 speeds: undetermined" in ln and "fmin/fmax" in ln for ln in rows)


# ----------------------------------------------------------------------------- simulate


def _sim(capsys, model, duration, *extra):
    return run(capsys, "simulate", model, "--speed", "3000", "--position", "0", "--width", "0.5",
               "--duration", str(duration), "--quiet", *extra)  # fmt: skip


def test_a_short_simulation_says_what_it_cannot_estimate_and_exits_0(capsys, forced):
    # Newmark's 5 steps: the growth window after the first delay holds fewer than the estimator's 8 samples
    code, out, err = _sim(capsys, forced, 0.0005, "--integrator", "newmark")
    assert code == 0, err
    assert "main spectral peak     n/a" in out and "envelope: not estimated" in out
    assert "too short to estimate the spectrum" in out and "fewer than 4 periods" in out
    assert "fewer than 8 samples" in out
    assert "initial condition: at rest (q = 0, v = 0, zero delay history before t = 0)" in out
    assert "ask for a longer run with --duration S" in out and "--passes N" in out
    # an output that never moved (y is held by the guide) says so instead of a spectral peak
    assert "tool.y     identically 0" in out
    # the default exponential step map takes 16 steps in a run shorter than the delay: enough samples,
    # but no oscillation in them, and it says so instead of a rate
    code, out, err = _sim(capsys, forced, 0.0005)
    assert code == 0, err
    assert "16 steps" in out and "envelope: undetermined" in out and "fewer than two extrema" in out
    assert "too short to estimate the spectrum" in out and "tool.y     identically 0" in out


def test_the_spectrum_needs_four_periods_of_its_peak(capsys, forced, turning):
    # 0.005 s holds 2.5 periods of the ~500 Hz response: no spectral peak
    code, out, _ = _sim(capsys, forced, 0.005)
    assert code == 0 and "too short to estimate the spectrum" in out
    # 0.3 s holds ~150: a peak, within the Hann main lobe (2 / L) of a characteristic root
    L = 0.3
    code, out, _ = _sim(capsys, forced, L)
    assert code == 0 and "too short" not in out and "initial condition" not in out
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("tool.x"))
    fp = float(line.split("main spectral peak")[1].split("Hz")[0])
    code, js, _ = run(capsys, "roots", forced, "--width", "0.5", "--speed", "3000", "--format", "json")
    roots = [r["frequency_hz"] for r in json.loads(js)["roots"]]
    assert min(abs(fp - f) for f in roots) <= 2 / L, (fp, roots)
    # nothing excites the unforced tool from rest: every output is zero, and the
    # summary shows the initial condition instead of a spectral peak of zeros
    code, out, _ = _sim(capsys, turning, L)
    assert code == 0 and out.count("identically 0") == 4 and "initial condition: at rest" in out


def test_simulate_without_out_writes_nothing_and_exits_0(capsys, forced):
    # the runs' files are zipped with --out's names: none given is none written (it was status 3)
    code, _, err = _sim(capsys, forced, 0.05)
    assert code == 0 and "internal error" not in err
