"""Numbers with their units at the command line (issue 20, item 4): a bare
number keeps the option's unit; a number written with its unit is converted
at the edge (pint) to exactly the same value; a unit of the wrong kind, or a
spindle speed in the ambiguous Hz, is one line and status 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import assert_clean_error

from chatterlab.cli import main
from chatterlab.cli._units import quantity, speed_in

ROOT = Path(__file__).resolve().parents[1]
SHAPER = str(ROOT / "studies" / "traverse_shaper" / "model.toml")
ONE = str(ROOT / "studies" / "milling" / "benchmark_1dof.toml")


def _roots_json(capsys, *args: str) -> dict:
    code = main(["roots", *args, "--format", "json", "--count", "2"])
    out = capsys.readouterr()
    assert code == 0, out.err
    return json.loads(out.out)


@pytest.mark.parametrize(
    ("text", "unit", "value"),
    [
        ("2", "mm", 2.0),
        ("2mm", "mm", 2.0),
        ("0.002 m", "mm", 2.0),
        ("2000N/mm^2", "N/m^2", 2.0e9),  # the issue's --kf typed in N/mm^2
        ("2 kHz", "Hz", 2000.0),
        ("1.5e-3 m", "m", 1.5e-3),
        ("90deg", "deg", 90.0),
    ],
)
def test_quantities_convert_to_the_options_unit(text, unit, value):
    # pint's conversion factors are exact decimal scalings here: equal to round-off of one product
    assert quantity(text, "--x", unit) == pytest.approx(value, rel=4e-16)


def test_spindle_speeds_in_every_unit_people_write():
    assert speed_in("12000rpm", "rpm") == pytest.approx(12000.0, rel=4e-16)
    assert speed_in("200 rev/s", "rpm") == pytest.approx(12000.0, rel=4e-16)
    assert speed_in("1256.6370614359173 rad/s", "rpm") == pytest.approx(12000.0, rel=1e-15)
    assert speed_in("30 m/min", "m/s") == pytest.approx(0.5, rel=4e-16)


def test_a_width_with_its_unit_gives_the_same_answer_as_the_bare_number(capsys):
    bare = _roots_json(capsys, SHAPER, "--width", "0.2", "--speed", "0.5")
    mm = _roots_json(capsys, SHAPER, "--width", "0.2mm", "--speed", "30 m/min")
    m = _roots_json(capsys, SHAPER, "--width", "0.0002 m", "--speed", "0.5m/s")
    for d in (mm, m):
        assert d["width_m"] == pytest.approx(bare["width_m"], rel=4e-16)
        assert d["delay_s"] == pytest.approx(bare["delay_s"], rel=4e-16)
        assert d["verdict"] == bare["verdict"]


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["roots", SHAPER, "--width", "2kg", "--speed", "0.5"], ["--width", "mass", "mm"]),
        (["roots", SHAPER, "--width", "0.2", "--speed", "12000rpm"], ["--speed", "m/s"]),
        (["roots", ONE, "--width", "1", "--speed", "200Hz"], ["--speed", "ambiguous", "rev/s or rpm"]),
        (["roots", SHAPER, "--width", "2 blorps", "--speed", "0.5"], ["--width", "mm"]),
        (["roots", SHAPER, "--width", "2mm mm", "--speed", "0.5"], ["--width"]),
    ],
)
def test_a_wrong_unit_is_one_line(capsys, args, words):
    code = main(args)
    err = capsys.readouterr().err
    assert_clean_error(code, err, *words)


@pytest.mark.parametrize(
    ("args", "option", "cap"),
    [
        (["lobes", SHAPER, "--speed", "0.1", "1", "--verify", "100000"], "--verify", 1000),
        (["lobes", SHAPER, "--speed", "0.1", "1", "--confirm", "51"], "--confirm", 50),
        (["roots", SHAPER, "--width", "0.2", "--count", "201"], "--count", 200),
        (["lobes", ONE, "--speed", "1000", "2000", "--scan", "1000000000"], "--scan", 2000),
        (["roots", ONE, "--width", "1", "--method", "sdm", "--steps", "1001"], "--steps", 1000),
    ],
)
def test_every_count_whose_work_grows_has_a_cap(capsys, args, option, cap):
    """Issue 20 item 7: a refusal before the work, naming the option and the largest accepted value."""
    code = main(args)
    assert_clean_error(code, capsys.readouterr().err, option, f"largest accepted, {cap}")
