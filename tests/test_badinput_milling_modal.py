"""Bad input on milling models and ``[[mode]]`` tables (issue 21, classes 1, 2
and 6): every run of ``check``, ``modes`` and ``roots`` on a random milling
and modal table ends with status 0, 1 or 2, its standard error holds only
chatterlab's own one-line messages (never an internal error, a traceback or a
raw Python warning) and it ends within a time bound; plus the cases of the
hostile corpus that failed before, one by one."""

from __future__ import annotations

import re
import signal
import warnings
from pathlib import Path

import pytest
from conftest import assert_clean_error
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from chatterlab.cli import main

ROOT = Path(__file__).resolve().parents[1]

#: seconds one command may take on a random table (a shared 2-core machine)
TIME_BOUND = 60


def mode_text(mid: str, f: float, z: float, km: str, coord: str, shape: float | None = None) -> str:
    where = f'direction = "{coord}"' if shape is None else f'shape = {{ "{coord}" = {shape!r} }}'
    return f'[[mode]]\nid = "{mid}"\nfrequency_hz = {f!r}\ndamping_ratio = {z!r}\n{km}\n{where}\n'


def milling_text(modes: str, **proc: object) -> str:
    p = {"rpm": 10000.0, "teeth": 2, "diameter": 0.02, "Kt": 6.0e8, "Kn": 2.0e8, "radial_immersion": 0.05}
    p.update(proc)
    lines = "\n".join(f"{k} = {v!r}" for k, v in p.items())
    return (
        f'[model]\nname = "fuzz"\n\n{modes}\n'
        '[[point]]\nid = "tip"\ncoords = { x = "tool.x", y = "tool.y" }\n\n'
        '[[coupling]]\nid = "cut"\na = "tip"\nb = "ground"\nmodel = "milling"\n\n'
        f'[process]\nkind = "milling"\nmilling = "down"\n{lines}\n'
    )


BENCH = mode_text("x1", 922.0, 0.011, "mass = 0.03993", "tool.x") + mode_text(
    "y1", 922.0, 0.011, "mass = 0.03993", "tool.y"
)


class _Timeout(Exception):
    pass


def run(capsys, tmp_path, text: str, argv: list[str]) -> tuple[int, str, str]:
    """``chatterlab ARGV[0] MODEL ARGV[1:]`` in process, within TIME_BOUND, raw Python
    warnings shown (as a user's shell would show them)."""
    p = tmp_path / "m.toml"
    p.write_text(text)

    def stop(*_: object) -> None:
        raise _Timeout

    old = signal.signal(signal.SIGALRM, stop)
    signal.alarm(TIME_BOUND)
    try:
        with warnings.catch_warnings(record=True) as raw:
            warnings.simplefilter("always")
            code = main([argv[0], str(p), *argv[1:]])
    except _Timeout:
        pytest.fail(f"{argv} took over {TIME_BOUND} s on\n{text}")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    out, err = capsys.readouterr()
    # what escapes chatterlab's own channel would reach a user's terminal as a raw Python warning
    err += "".join(f"{w.filename}:{w.lineno}: {w.category.__name__}: {w.message}\n" for w in raw)
    return code, out, err


def assert_tidy(code: int, out: str, err: str, what: tuple[list[str], str]) -> None:
    assert code in (0, 1, 2), (code, err, what)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert all(ln.startswith("chatterlab: ") for ln in lines), (err, what)  # no raw warning, no traceback
    assert "internal error" not in err and "Traceback" not in err, (err, what)
    if code == 2:
        assert len(lines) == 1, (err, what)
    if code == 0 and what[0][0] == "modes":
        assert not re.search(r"\b(nan|inf)\b", out), (out, what)


# ----------------------------------------------------------------------------- random tables

EXTREMES = [5e-324, 1e-300, 1e-30, 1e-9, 1e-3, 1e16, 1e30, 1e300]


def decades(lo: float, hi: float) -> st.SearchStrategy[float]:
    """Mostly plausible values (log-uniform between 10^lo and 10^hi), sometimes an extreme."""
    plausible = st.floats(lo, hi).map(lambda e: float(f"{10.0**e:.4g}"))
    return st.one_of(*[plausible] * 8, st.sampled_from(EXTREMES))


stiffnesses = decades(4.0, 9.0).map(lambda v: f"stiffness = {v!r}")
masses = decades(-3.0, 1.0).map(lambda v: f"mass = {v!r}")
frequencies = st.one_of(*[decades(1.5, 4.0)] * 4, st.sampled_from([0.922, 1e7, 1e9]))
dampings = st.sampled_from([0.0, 5e-324, 1e-3, 0.011, 0.05, 0.5, 0.999])
shapes = st.one_of(*[st.none()] * 4, st.floats(0.1, 3.0), st.sampled_from(EXTREMES))
process = st.fixed_dictionaries(
    {},
    optional={
        "rpm": st.one_of(decades(3.0, 5.0), st.sampled_from([0.01, 0.1, 1e7, 1e9])),
        "diameter": st.one_of(st.floats(0.002, 0.05), st.sampled_from([1e-300, 1e-9, 50.0, 1e300])),
        "Kt": st.one_of(decades(8.0, 9.0), st.sampled_from([1.0, 1e14, 1e300])),
        "Kn": st.one_of(st.just(0.0), decades(7.0, 9.0)),
        "helix_deg": st.one_of(st.floats(0.0, 60.0), st.sampled_from([84.0, 85.0, 89.9, 89.9999])),
        "teeth": st.sampled_from([1, 2, 4, 7]),
        "radial_immersion": st.sampled_from([1e-300, 0.05, 0.5, 1.0]),
    },
)


@st.composite
def tables(draw):
    modes = ""
    for mid, coord in (("x1", "tool.x"), ("y1", "tool.y")):
        km = draw(st.one_of(stiffnesses, masses))
        modes += mode_text(mid, draw(frequencies), draw(dampings), km, coord, draw(shapes)) + "\n"
    return milling_text(modes, **draw(process))


commands = st.sampled_from(
    [
        ["check"],
        ["modes"],
        ["roots", "--width", "1", "--speed", "10000"],
        ["roots", "--width", "1"],
        ["roots", "--width", "0.5", "--speed", "12000", "--method", "sdm", "--steps", "10"],
    ]
)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=tables(), argv=commands)
def test_random_milling_and_modal_tables_end_tidily(capsys, tmp_path, text, argv):
    code, out, err = run(capsys, tmp_path, text, argv)
    assert_tidy(code, out, err, (argv, text))


# ----------------------------------------------------------------------------- the corpus, case by case

ROOTS = ["roots", "--width", "1", "--speed", "10000"]


@pytest.mark.parametrize("speed", ["1e-300", "1e300", "0.01"], ids=["tiny", "absurd", "below-the-range"])
def test_absurd_spindle_speeds_are_refused(capsys, tmp_path, speed):
    """Were OverflowError and 'Maximum allowed size exceeded' (status 3)."""
    lobes = ["lobes", "--speed", speed, f"{2 * float(speed):g}", "--points", "2", "--width-max", "5"]
    for argv in (["roots", "--width", "1", "--speed", speed], lobes):
        code, _, err = run(capsys, tmp_path, milling_text(BENCH), argv)
        assert_clean_error(code, err, "--speed", "rpm", f"{float(speed):g}", "10..200000")


def test_a_model_speed_out_of_range_is_named_with_the_field(capsys, tmp_path):
    code, _, err = run(capsys, tmp_path, milling_text(BENCH, rpm=1e300), ["roots", "--width", "1"])
    assert_clean_error(code, err, "[process]: rpm", "1e+300")


@pytest.mark.parametrize(
    "mode, words",
    [
        (mode_text("x1", 1e-300, 0.011, "stiffness = 1.34e6", "tool.x"), ["frequency_hz", "1e-300", "Hz"]),
        (mode_text("x1", 5e-324, 0.011, "mass = 0.04", "tool.x"), ["frequency_hz", "Hz"]),
        (mode_text("x1", 922.0, 0.011, "stiffness = 5e-324", "tool.x"), ["stiffness", "N/m"]),
        (mode_text("x1", 922.0, 0.011, "stiffness = 1.34e6", "tool.x", 1e300), ["shape", "1e+300"]),
        (mode_text("x1", 1e6, 0.011, "mass = 1e6", "tool.x"), ["mass", "N/m", "1e+06 kg"]),
    ],
    ids=["tiny-frequency", "denormal-frequency", "denormal-stiffness", "huge-shape", "mass-stiffness"],
)
def test_modal_fields_out_of_range_are_one_line(capsys, tmp_path, mode, words):
    """Were LinAlgError / 'array must not contain infs or NaNs' (status 3) and raw RuntimeWarnings."""
    text = milling_text(mode + "\n" + mode_text("y1", 922.0, 0.011, "mass = 0.04", "tool.y"))
    for argv in (["check"], ["modes"], ROOTS):
        code, _, err = run(capsys, tmp_path, text, argv)
        assert_clean_error(code, err, "mode.x1", *words)


def test_huge_modal_stiffness_prints_no_nan_table(capsys, tmp_path):
    """Was exit 0 with nan/inf in the modes table."""
    text = milling_text(
        mode_text("x1", 922.0, 0.011, "stiffness = 1e300", "tool.x")
        + mode_text("y1", 922.0, 0.011, "mass = 0.04", "tool.y")
    )
    code, out, err = run(capsys, tmp_path, text, ["modes"])
    assert_clean_error(code, err, "stiffness")
    assert "nan" not in out


@pytest.mark.parametrize("helix", [89.9999, 89.0])
def test_helix_near_90_deg_is_refused_before_the_work(capsys, tmp_path, helix):
    """89.9999 deg hung (over 60 s); the refusal names the field and the largest accepted value."""
    code, _, err = run(capsys, tmp_path, milling_text(BENCH, helix_deg=helix), ROOTS)
    assert_clean_error(code, err, "helix_deg", "at most 85 deg")


def test_a_flute_wrapping_the_tool_is_a_cost_refusal(capsys, tmp_path):
    """A plausible helix on a 1e-6 m cutter wraps the flute thousands of times over 1 mm."""
    text = milling_text(BENCH, helix_deg=30.0, diameter=1e-6)
    code, _, err = run(capsys, tmp_path, text, ROOTS)
    assert_clean_error(code, err, "helix", "turns", "helix_deg must be at most")


@pytest.mark.parametrize(
    "argv, words",
    [
        (["roots", "--width", "1", "--speed", "10000", "--steps", "80"], ["--steps", "--method sdm"]),
        (["lobes", "--speed", "8000", "9000", "--points", "2", "--steps", "80"], ["--steps", "spectral"]),
        (
            ["lobes", "--speed", "8000", "9000", "--points", "2", "--method", "spectral", "--ste=40"],
            ["--steps"],
        ),
    ],
    ids=["roots-spectral", "lobes-spectral", "abbreviated"],
)
def test_options_the_route_ignores_are_refused(capsys, tmp_path, argv, words):
    """Were accepted silently (the spectral method has no steps)."""
    code, _, err = run(capsys, tmp_path, milling_text(BENCH), argv)
    assert_clean_error(code, err, *words)


@pytest.mark.parametrize("argv", [ROOTS, ["check"], ["modes"]])
def test_a_modal_table_typed_in_khz_warns(capsys, tmp_path, argv):
    """Was exit 0 with no word: 0.922 'Hz' for 922 Hz -- on every command that
    reads the table (the milling routes warned, check and modes did not)."""
    text = milling_text(BENCH.replace("922.0", "0.922"))
    code, _, err = run(capsys, tmp_path, text, argv)
    assert code == 0, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("chatterlab: warning:"), err
    assert "kHz" in lines[0] and "x1 (0.922 Hz), y1 (0.922 Hz)" in lines[0]
    code, _, err = run(capsys, tmp_path, milling_text(BENCH), argv)
    assert code == 0 and err == ""


@pytest.mark.parametrize("opt", [["--steps", "80"], ["--scan", "5"]])
def test_floquet_options_on_a_measured_frf_are_refused(capsys, opt):
    """lobes --frf (ZOA from the measurement) accepted --steps and --scan silently."""
    frf = ROOT / "studies" / "tap_test" / "tool_point.csv"
    argv = ["lobes", "--frf", str(frf), "--speed", "8000", "20000", "--points", "3", "--width-max", "5",
            "--teeth", "2", "--kt", "6e8", "--kn", "2e8", "--immersion", "0.05", *opt]  # fmt: skip
    code = main(argv)
    assert_clean_error(code, capsys.readouterr().err, opt[0], "drop")


@pytest.mark.parametrize(
    "proc, words",
    [
        ({"helix_deg": 89.9}, ("[process]", "helix_deg", "85 deg")),
        ({"rpm": 1.7e308}, ("[process]", "rpm", "0.1..1e+07 rpm")),
        ({"rpm": 1e-300}, ("[process]", "rpm", "0.1..1e+07 rpm")),
    ],
)
def test_check_refuses_a_milling_process_out_of_range_when_reading(capsys, tmp_path, proc, words):
    """``check`` reads the model and builds no cutter: the helix and spindle-speed
    limits of :mod:`chatterlab.process` hold at read time too (0.2.0's ``check``
    accepted 89.9 deg and printed a raw overflow warning at 1.7e308 rpm)."""
    code, out, err = run(capsys, tmp_path, milling_text(BENCH, **proc), ["check"])
    assert_clean_error(code, err, *words)
