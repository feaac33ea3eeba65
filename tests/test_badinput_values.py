"""Class 1 of issue 10: a negative, zero or non-finite width, speed, delay or
position is refused the same way by every entry point (status 2, one line),
never turned into a result with status 0.  The checks live in one place,
chatterlab.errors.check_*; these tests go through each entry point."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error, turning_text
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from chatterlab import errors
from chatterlab.cli._main import main
from chatterlab.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
SHAPER = str(ROOT / "studies" / "traverse_shaper" / "model.toml")
TURNING = turning_text(mass=2.0, stiffness=2.0e7, damping=400.0, name="1-DOF turning")


@pytest.fixture
def turning(tmp_path):
    p = tmp_path / "turning.toml"
    p.write_text(TURNING)
    return str(p)


BAD = ["-1", "0", "nan", "inf", "-inf", "-0.0", "1e400"]


# the examples and their kin, on every command that takes the value
ENTRY_POINTS = [
    ("sweep {m} --quantity b-lim --grid position=0.85 --speed {v}", "--speed"),
    ("sweep {m} --quantity b-lim --grid position=0.85 --delay {v}", "--delay"),
    ("sweep {m} --quantity b-lim --grid position=0.85 --width-max {v}", "--width-max"),
    ("sweep {m} --quantity stable --grid speed=0.4:0.6:2 --width {v}", "--width"),
    ("sweep {m} --quantity b-lim --grid speed=0.4 --position {v}", "--position"),
    ("roots {m} --width 1 --speed {v}", "--speed"),
    ("roots {m} --width 1 --delay {v}", "--delay"),
    ("roots {m} --width {v} --speed 0.5", "--width"),
    ("roots {m} --width 1 --speed 0.5 --position {v}", "--position"),
    ("frf {m} --input rfe5.x --output rfe5.x --closed-loop --width {v}", "--width"),
    ("frf {m} --input rfe5.x --output rfe5.x --closed-loop --width 1 --speed {v}", "--speed"),
    ("lobes {m} --speed {v} 0.6", "--speed"),
    ("lobes {m} --speed 0.4 0.6 --width-max {v}", "--width-max"),
    ("lobes {m} --speed 0.4 0.6 --positions {v} 1.0 2", "--positions"),
    ("lobes {m} --speed 0.4 0.6 --positions 0.7 1.0 {v}", "--positions"),
    ("simulate {m} --speed {v}", "--speed"),
    ("simulate {m} --delay {v}", "--delay"),
    ("simulate {m} --width {v}", "--width"),
    ("simulate {m} --duration {v}", "--duration"),
    ("simulate {m} --step {v}", "--step"),
    ("modes {m} --position {v}", "--position"),
]


@pytest.mark.parametrize("template, option", ENTRY_POINTS)
@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf"])
def test_invalid_value_is_refused_by_every_entry_point(capsys, tmp_path, template, option, value):
    out = tmp_path / ("out.txt" if template.startswith("roots") else "out.csv")
    argv = template.format(m=SHAPER, v=value).split() + ["--out", str(out)]
    if argv[0] == "modes":
        argv += ["--format", "csv"]
    code = main(argv)
    err = capsys.readouterr().err
    # a position is checked against the model's movable range [0.55, 1.15] m
    assert_clean_error(code, err, option.lstrip("-") if "position" in option else option)
    assert not out.exists()


@pytest.mark.parametrize(
    "spec, words",
    [
        ("delay=-1:-0.5:2", ["grid axis delay", "> 0 s"]),
        ("delay=0:0.5:2", ["grid axis delay", "> 0 s"]),
        ("speed=-0.5:0.5:3", ["grid axis speed", "> 0"]),
        ("width=-1:1:3", ["grid axis width", "> 0 mm"]),
        ("width=0", ["grid axis width"]),
    ],
)
def test_invalid_grid_axis_is_refused_before_anything_runs(capsys, tmp_path, spec, words):
    out = tmp_path / "s.nc"
    argv = ["sweep", SHAPER, "--quantity", "b-lim", "--grid", spec, "--quiet", "--out", str(out)]
    if spec.startswith("width"):
        argv = [
            "sweep",
            SHAPER,
            "--quantity",
            "stable",
            "--speed",
            "0.5",
            "--grid",
            spec,
            "--quiet",
            "--out",
            str(out),
        ]
    code = main(argv)
    assert_clean_error(code, capsys.readouterr().err, *words)
    assert list(tmp_path.iterdir()) == []  # no file, no checkpoint, no scratch


def test_library_entry_points_share_the_checks(turning):
    import chatterlab as cl
    from chatterlab.process import delay_for
    from chatterlab.process._kinematics import kinematics_for
    from chatterlab.quantities._tasks import AtlasTask, QuantityTask

    model = cl.load_model(turning)
    proc = model.process
    for bad in (-1.0, 0.0, math.nan, math.inf):
        with pytest.raises(InputError, match="speed"):
            delay_for(proc, speed=bad)
        with pytest.raises(InputError, match="delay"):
            delay_for(proc, delay=bad)
        with pytest.raises(InputError, match="speed"):
            kinematics_for(proc, speed=bad)
        with pytest.raises(InputError, match="speed"):
            QuantityTask(model, "b-lim", {"speed": bad})
        with pytest.raises(InputError, match="delay"):
            QuantityTask(model, "b-lim", {"delay": bad})
        with pytest.raises(InputError, match="width"):
            QuantityTask(model, "stable", {"width": bad, "speed": 3000.0})
        with pytest.raises(InputError, match="width_max"):
            QuantityTask(model, "b-lim", width_max=bad)
        with pytest.raises(InputError, match="width_max"):
            AtlasTask(model, bad, (3000.0,))
        with pytest.raises(InputError, match="speed"):
            AtlasTask(model, 1e-3, (3000.0, bad))
        # a grid point handed to the task directly is checked too
        task = QuantityTask(model, "b-lim", width_max=5e-3)
        with pytest.raises(InputError, match="speed"):
            task(speed=bad)
        with pytest.raises(InputError, match="width"):
            cl.simulate(cl.assemble(model), width=bad, speed=3000.0, position=0.0, duration=0.01)


def test_the_validators_name_the_argument_and_unit():
    with pytest.raises(InputError, match=r"^--speed must be > 0 m/s \(got -1\)$"):
        errors.check_speed(-1, "--speed", "m/s")
    with pytest.raises(InputError, match=r"delay must be > 0 s and finite \(got nan\)"):
        errors.check_delay(float("nan"))
    with pytest.raises(InputError, match="digits"):
        errors.check_width(10**400)
    with pytest.raises(InputError, match="must be a number"):
        errors.check_width("1")
    with pytest.raises(InputError, match="must be a number"):
        errors.check_width(True)
    assert errors.check_width(np.float32(2.0)) == 2.0
    assert errors.check_count(3.0, "N") == 3
    with pytest.raises(InputError):
        errors.check_count(2.5, "N")
    with pytest.raises(InputError):
        errors.check_count(float("nan"), "N")


# ----------------------------------------------------------------------------- fuzz

invalid = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, 0.0, -0.0]),
    st.floats(max_value=0.0, allow_nan=False),
)

CHEAP = {
    "--speed": "roots {m} --width 0.5 --speed={v} --no-winding",
    "--delay": "roots {m} --width 0.5 --delay={v} --no-winding",
    "--width": "roots {m} --width={v} --speed 3000 --no-winding",
    "--width-max": "sweep {m} --quantity b-lim --grid speed=3000 --width-max={v} --backend serial --quiet",
    "--duration": "simulate {m} --speed 3000 --position 0 --duration={v} --quiet",
    "--step": "simulate {m} --speed 3000 --position 0 --duration 0.01 --step={v} --quiet",
    "grid speed": "sweep {m} --quantity b-lim --grid speed={v} --backend serial --quiet",
    "grid delay": "sweep {m} --quantity b-lim --grid delay={v} --backend serial --quiet",
}


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(option=st.sampled_from(sorted(CHEAP)), value=invalid)
def test_fuzz_invalid_numeric_options_end_in_status_2(capsys, turning, option, value):
    argv = CHEAP[option].format(m=turning, v=repr(value)).split()
    code = main(argv)
    err = capsys.readouterr().err
    assert_clean_error(code, err)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    width=st.floats(min_value=1e-3, max_value=10.0),
    speed=st.one_of(st.floats(min_value=100.0, max_value=1e5), st.sampled_from([math.nan, -5.0, 0.0])),
)
def test_fuzz_roots_options_never_traceback(capsys, turning, width, speed):
    code = main(["roots", turning, f"--width={width!r}", f"--speed={speed!r}", "--no-winding"])
    out = capsys.readouterr()
    if not (math.isfinite(speed) and speed > 0):
        assert_clean_error(code, out.err, "--speed")
    else:
        assert code in (0, 2), out.err
        assert "Traceback" not in out.err
        if code == 0:
            assert "verdict:" in out.out


def test_every_speed_to_delay_conversion_is_checked():
    """Process.delay is where every speed becomes a delay (the CLI, the tasks, the lobes,
    the kinematics): a speed <= 0 or non-finite never becomes a negative or infinite delay."""
    import chatterlab as cl

    proc = cl.load_model(SHAPER).process
    assert proc.delay(0.5) == pytest.approx(1.5)
    for bad in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(InputError, match="speed must be > 0 m/s"):
            proc.delay(bad)
        with pytest.raises(InputError, match="speed must be > 0 m/s"):
            proc.delay(np.array([0.5, bad]))


@pytest.mark.parametrize(
    "argv",
    [
        "roots {m} --width 1 --speed 1e-300",
        "lobes {m} --speed 1e-300 1e-299 --points 2",
        "roots {m} --width 1 --delay 1e300",
        "simulate {m} --delay 1e300 --position 0 --duration 0.01",
        "sweep {m} --quantity b-lim --grid speed=1e-300 --backend serial",
    ],
)
def test_an_absurdly_long_delay_is_an_input_error(capsys, turning, argv):
    """A speed of 1e-300 rpm is finite and > 0, but its delay (6e301 s) is no cut: refused
    by the delay check before any array is sized by it."""
    code = main(argv.format(m=turning).split())
    assert_clean_error(code, capsys.readouterr().err, "at most 1e+06 s")


# --- issue 25: a stiffness or modulus of 1e300 or 1e-300 is named, not reported as rigid-body modes


def _shaper_with(tmp_path: Path, old: str, new: str) -> str:
    """A copy of the shipped shaper with the first line ``old`` replaced by ``new``."""
    text = Path(SHAPER).read_text()
    assert old in text
    p = tmp_path / "shaper.toml"
    p.write_text(text.replace(old, new, 1))
    return str(p)


@pytest.mark.parametrize("value", ["1e300", "1e-300"])
@pytest.mark.parametrize(
    "old, field, item, unit",
    [
        ("c1 = 7.0e9\n", "c1", '[[spring]] "leg3-foundation"', "N/m"),
        ("c6 = 7.0e8\n", "c6", '[[spring]] "leg3-foundation"', "N m/rad"),
        ("E = 2.1e11\n", "E", '[[beam]] "shear-1"', "Pa"),
    ],
)
@pytest.mark.parametrize("command", ["modes {m}", "lobes {m} --speed 0.4 0.6 --points 3"])
def test_an_absurd_stiffness_or_modulus_names_its_field(
    capsys, tmp_path, value, old, field, item, unit, command
):
    m = _shaper_with(tmp_path, old, f"{old.split('=')[0]}= {value}\n")
    code = main(command.format(m=m).split())
    err = capsys.readouterr().err
    shown = f"{float(value):g}"
    assert_clean_error(
        code, err, "shaper.toml", item, f"{field}: {shown} {unit}", "plausible range", "correct the value"
    )
    assert "rigid-body" not in err and "foundation:" not in err


def test_an_absurd_value_given_by_set_is_named_too(capsys):
    code = main(["modes", SHAPER, "--set", "spring.leg4-foundation.c2=1e-300"])
    err = capsys.readouterr().err
    assert_clean_error(
        code, err, '[[spring]] "leg4-foundation": c2: 1e-300 N/m is outside the plausible range'
    )


def test_the_plausible_ranges_keep_the_real_and_the_idealised_values():
    """Zero where a field allows it, real machines and the idealisations the tests use
    (a shear modulus G = 1e8 E suppresses shear) stay within the ranges."""
    from chatterlab.model._fields import PLAUSIBLE, plausible

    for v, unit in [(0.0, "N/m"), (7e9, "N/m"), (50.0, "N m/rad"), (2.1e19, "Pa"), (700.0, "N/m^2"), (2e9, "N/m^2"), (0.04, "kg"), (1e-3, "kg m^2"), (4.17e-10, "m^4"), (4.0, "N m s/rad"), (1.0, "m")]:  # fmt: skip
        assert plausible(v, unit) is None, (v, unit)
    for unit, (lo, hi, _) in PLAUSIBLE.items():
        assert plausible(lo / 10, unit) and plausible(hi * 10, unit) and plausible(-hi * 10, unit)


# --- issue 25: a delay so long that the argument-principle count fails is a failed count, not a contradiction


def _with_checks(monkeypatch, edit):
    """``lobes`` whose diagram's checks are rewritten by ``edit(checks)`` (the count that
    fails is the one of a delay of ~1e5 s: minutes to reproduce, so it is injected here)."""
    import dataclasses

    from chatterlab.cli import _lobes

    real = _lobes._diagram

    def diagram(*a, **k):
        d = real(*a, **k)
        return dataclasses.replace(d, checks=tuple(edit([dict(c) for c in d.checks])))

    monkeypatch.setattr(_lobes, "_diagram", diagram)


def _failed_count(c):
    return {**c, "verdict": "undetermined", "rhp_roots": -1, "agrees": False}


@pytest.mark.parametrize("contradicted_too", [False, True])
def test_a_failed_root_count_is_reported_as_failed(capsys, turning, tmp_path, monkeypatch, contradicted_too):
    def edit(checks):
        checks[0] = _failed_count(checks[0])
        if contradicted_too:  # another speed's count disagrees: that one is a contradiction
            k = next(i for i, c in enumerate(checks) if c["speed"] != checks[0]["speed"])
            flip = "unstable" if checks[k]["expected"] == "stable" else "stable"
            checks[k] = {
                **checks[k],
                "verdict": flip,
                "rhp_roots": 2 if flip == "unstable" else 0,
                "agrees": False,
            }
        return checks

    _with_checks(monkeypatch, edit)
    out = tmp_path / "l.csv"
    code = main(["lobes", turning, "--speed", "3000", "9000", "--points", "12", "--quiet", "--out", str(out)])
    txt, err = capsys.readouterr()
    assert code == 1, err
    assert not re.search(r"-\d+ right-half-plane", txt + err)  # never a negative number of roots
    line = next(ln for ln in txt.splitlines() if "CHECK NOT COUNTED" in ln)
    assert "the argument-principle count failed (its phase did not close" in line
    assert "; 1 could not count the roots" in txt
    assert "the argument-principle count failed at 1 check(s)" in err
    import csv

    with open(out, newline="") as fh:
        status = [row["claim"] for row in csv.DictReader(fh)]
    if contradicted_too:
        assert "CHECK FAILED" in txt and "contradicts the diagram" in err
        assert status.count("contradicted by a check") == 1
    else:
        assert "CHECK FAILED" not in txt and "contradicts the diagram" not in err
        assert "contradicted by a check" not in status  # the speed keeps the diagram's claim, unverified


def test_a_failed_count_contradicts_nothing_in_the_library():
    from chatterlab.lobes._result import count_failed

    assert count_failed({"verdict": "undetermined", "rhp_roots": 0})
    assert count_failed({"verdict": "unstable", "rhp_roots": -1})  # a negative count is no count
    assert not count_failed({"verdict": "unstable", "rhp_roots": 2})
