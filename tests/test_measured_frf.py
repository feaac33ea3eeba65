"""Measured FRFs in and out (issue 13, item 1): the file formats round-trip
exactly or to their stated precision, units convert to receptance as the
closed forms say, the spline interpolation has the order and error the docs
state, and bad input is refused in one line naming the file and the line or
field, with nothing written."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import control  # a dependency of chatterlab: an import error fails, never skips
import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.frequency._frf import frf
from chatterlab.io._frf_files import G0, parse_frf_units, read_frf, write_frf_uff
from chatterlab.structure import FRF

DATA = Path(__file__).parent / "data" / "frf"
MASS, STIFF, DAMP = 2.0, 2.0e7, 400.0


def sdof(w: np.ndarray) -> np.ndarray:
    """Receptance of the 1-DOF oracle, m/N: 1 / (k - m w^2 + j c w)."""
    return 1.0 / (STIFF - MASS * w**2 + 1j * DAMP * w)


@pytest.fixture
def two_by_two() -> FRF:
    rng = np.random.default_rng(13)
    f = np.sort(rng.uniform(50.0, 2000.0, 120))  # uneven spacing
    H = (rng.normal(size=(2, 2, 120)) + 1j * rng.normal(size=(2, 2, 120))) * 1e-7
    coh = rng.uniform(0.2, 1.0, size=(2, 2, 120))
    return FRF.from_arrays(f, H, ["tool.x", "tool.y"], ["tool.x", "tool.y"], hz=True, coherence=coh)


def same_frequency(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal to the rounding of Hz <-> rad/s (w = 2 pi f and back: 2 ulps)."""
    return bool(np.all(np.abs(a - b) <= 2 * np.finfo(float).eps * np.abs(b)))


def one_line(exc: pytest.ExceptionInfo, *words: str) -> str:
    msg = str(exc.value)
    assert "\n" not in msg, msg
    for w in words:
        assert w in msg, msg
    return msg


# ----------------------------------------------------------------------------- round trips


def test_csv_round_trip_is_exact(tmp_path, two_by_two):
    p = tmp_path / "h.csv"
    two_by_two.to_csv(p)
    back = FRF.read(p)
    # 17 significant digits identify a double: H bit-for-bit, the frequency to
    # the rounding of its conversion to Hz in the file and back
    assert same_frequency(back.omega, two_by_two.omega)
    assert np.array_equal(back.data, two_by_two.data)
    assert np.array_equal(back.coherence, two_by_two.coherence)
    assert back.outputs == two_by_two.outputs and back.inputs == two_by_two.inputs


def test_csv_mm_and_magphase_round_trip(tmp_path, two_by_two):
    p = tmp_path / "h.csv"
    two_by_two.to_csv(p, units="um/N", form="magphase")
    back = FRF.read(p)
    # a scale by 1e6 and back, and |H| e^{j phase} from 17-digit mag and phase
    # in degrees: a few ulps of |H| (bound 8 eps)
    assert np.max(np.abs(back.data - two_by_two.data) / np.abs(two_by_two.data)) < 8 * np.finfo(float).eps
    assert same_frequency(back.omega, two_by_two.omega)


def test_uff58_ascii_round_trip_to_its_precision(tmp_path, two_by_two):
    pytest.importorskip("pyuff", reason="the uff extra (pip install chatterlab[uff]) is not installed")
    p = tmp_path / "h.uff"
    two_by_two.to_uff(p)
    back = FRF.read(p)
    assert back.outputs == two_by_two.outputs and back.inputs == two_by_two.inputs
    # ASCII 58: ordinates E20.11 (12 significant digits, half a unit in the last
    # place: 5e-12 of each part, so <= 5e-12 sqrt(2) of |H|), abscissa E13.5 (6 digits: 5e-6)
    assert np.max(np.abs(back.data - two_by_two.data) / np.abs(two_by_two.data)) <= 5e-12 * np.sqrt(2)
    assert np.max(np.abs(back.omega / two_by_two.omega - 1)) <= 5e-6
    assert np.max(np.abs(back.coherence - two_by_two.coherence)) <= 5e-12


def test_uff58b_binary_round_trip_is_exact(tmp_path, two_by_two):
    pytest.importorskip("pyuff", reason="the uff extra (pip install chatterlab[uff]) is not installed")
    p = tmp_path / "h.unv"
    two_by_two.to_uff(p, binary=True)
    back = FRF.read(p)
    assert np.array_equal(back.data, two_by_two.data)  # doubles written as doubles
    assert same_frequency(back.omega, two_by_two.omega)
    assert np.array_equal(back.coherence, two_by_two.coherence)


def test_uff_nodes_directions_and_ordinate_types(tmp_path):
    """A matrix FRF from four datasets identified by node and direction, one
    reference pointing along -y, given as accelerance (ordinate type 12)."""
    pyuff = pytest.importorskip(
        "pyuff", reason="the uff extra (pip install chatterlab[uff]) is not installed"
    )
    f = np.linspace(100.0, 900.0, 81)
    w = 2 * np.pi * f
    G = np.array([[sdof(w), 0.3 * sdof(w)], [0.3 * sdof(w), 2 * sdof(w)]])  # (out, in, n)
    sets = []
    for o, (on, od) in enumerate(((7, 1), (7, 2))):
        for i, (inn, idir) in enumerate(((7, 1), (7, -2))):
            sign = -1.0 if idir < 0 else 1.0
            acc = -(w**2) * G[o, i] * sign
            sets.append(
                pyuff.prepare_58(
                    binary=1, func_type=4, rsp_node=on, rsp_dir=od, ref_node=inn, ref_dir=idir, x=f,
                    data=acc, ord_data_type=6, abscissa_spacing=0, abscissa_spec_data_type=18,
                    ordinate_spec_data_type=12, orddenom_spec_data_type=13, id1="acc",
                )
            )  # fmt: skip
    p = tmp_path / "acc.uff"
    p.touch()
    pyuff.UFF(str(p)).write_sets(sets, mode="add")
    back = FRF.read(p)
    assert back.outputs == ("7.x", "7.y") and back.inputs == ("7.x", "7.y")
    assert (
        back.meta["quantity"] == "accelerance" and back.kind == "receptance"
    )  # as the file says; read as receptance
    # -A / w^2 of exact doubles: a couple of ulps
    assert np.max(np.abs(back.data - G) / np.abs(G)) < 4 * np.finfo(float).eps


def test_cutpro_frf_file_reads_as_defined():
    p = DATA / "tool_point.frf"
    got = FRF.read(p)
    rows = np.loadtxt(p, skiprows=3)
    assert got.meta["units"] == "m/N" and got.outputs == ("tool",)
    assert same_frequency(got.frequency_hz, rows[:, 0])
    assert np.array_equal(got.data[0, 0], rows[:, 1] + 1j * rows[:, 2])


def test_frd_round_trip_is_exact(two_by_two):
    frd = two_by_two.to_control()
    assert isinstance(frd, control.FrequencyResponseData)
    back = FRF.from_control(frd)
    assert np.array_equal(back.data, two_by_two.data) and np.array_equal(back.omega, two_by_two.omega)
    assert back.outputs == two_by_two.outputs  # 'tool:x' in python-control, 'tool.x' again here


def test_from_model_equals_the_frf_of_the_model():
    m = cl.loads_model(turning_text(mass=MASS, stiffness=STIFF, damping=DAMP))
    fz = cl.assemble(m).at()
    w = 2 * np.pi * np.linspace(10.0, 1500.0, 300)
    got = FRF.from_model(fz, "tip.x", omega=w)
    ref = frf(fz, w, inputs="tip.x", outputs="tip.x")
    # pole-residue sum vs direct solve: both ~1e-11 of the peak (frequency/_frf.py)
    assert np.max(np.abs(got.data[0, 0] - ref.data[0, 0])) < 1e-9 * np.abs(ref.data).max()
    assert np.max(np.abs(got.data[0, 0] - sdof(w))) < 1e-9 * np.abs(sdof(w)).max()
    assert type(ref) is type(got) and ref.data.shape == got.data.shape == (1, 1, 300)  # one container


# ----------------------------------------------------------------------------- units


@pytest.mark.parametrize(
    ("units", "factor"),
    [
        ("m/N", lambda w: 1.0),
        ("mm/N", lambda w: 1e3),
        ("µm/N", lambda w: 1e6),
        ("m/s/N", lambda w: 1j * w),  # mobility = j w H
        ("mm/(N s)", lambda w: 1e3 * 1j * w),
        ("m/s^2/N", lambda w: -(w**2)),  # accelerance = -w^2 H
        ("g/N", lambda w: -(w**2) / G0),
    ],
)
def test_units_convert_to_receptance(tmp_path, units, factor):
    f = np.linspace(100.0, 900.0, 41)
    w = 2 * np.pi * f
    A = sdof(w) * factor(w)
    p = tmp_path / "u.csv"
    rows = "\n".join(f"{a:.17g},{z.real:.17g},{z.imag:.17g}" for a, z in zip(f, A, strict=True))
    p.write_text(f"# units: {units}\nf [Hz],xx re,xx im\n{rows}\n")
    got = FRF.read(p, point="tool")
    assert got.outputs == ("tool.x",)
    # the closed form divided back: a few roundings (scale, (j w)^p, division)
    assert np.max(np.abs(got.data[0, 0] / sdof(w) - 1)) < 8 * np.finfo(float).eps
    # the same file with the units given by the caller instead of the header
    p.write_text(f"f,xx re,xx im\n{rows}\n")
    got2 = FRF.read(p, units=units)
    assert np.array_equal(got2.data, got.data)


def test_quantity_alone_means_si(tmp_path):
    f = np.linspace(100.0, 900.0, 11)
    w = 2 * np.pi * f
    A = 1j * w * sdof(w)
    p = tmp_path / "m.txt"
    p.write_text(
        "# quantity: mobility\n"
        + "".join(f"{a:.17g}\t{z.real:.17g}\t{z.imag:.17g}\n" for a, z in zip(f, A, strict=True))
    )
    got = FRF.read(p)
    assert np.max(np.abs(got.data[0, 0] / sdof(w) - 1)) < 4 * np.finfo(float).eps


def test_unit_parser_refuses_what_is_no_frf_unit():
    for bad in ("N/m", "m", "m/N/N", "m/s^3/N", "kg/N", "furlong/N"):
        with pytest.raises(InputError, match="cannot convert"):
            parse_frf_units(bad)


# ----------------------------------------------------------------------------- interpolation


def test_interpolation_exact_at_samples_and_never_extrapolated(two_by_two):
    assert np.array_equal(two_by_two.interpolate(two_by_two.omega), two_by_two.data)
    lo, hi = two_by_two.band
    with pytest.raises(InputError, match="outside the measured band"):
        two_by_two.interpolate([0.5 * lo])
    h = two_by_two.interpolate([0.5 * lo, lo, hi, 1.01 * hi], outside="nan")
    assert np.all(np.isnan(h[..., [0, 3]])) and np.all(np.isfinite(h[..., [1, 2]]))


def test_interpolation_order_and_error_estimate():
    """The spline error falls like h^4 (fitted order 4 +- 0.3: the
    pre-asymptotic term is O(h / sigma) relative, sigma = 100 rad/s the
    half-power half-width, h/sigma <= 0.25 here); the estimate
    (5/384) h^4 |H''''| is within a factor 2 of the true error where the
    resonance has >= 8 points per half-power width (it samples H'''' near
    the interval, the true error its maximum over the interval)."""
    errs, hs = [], []
    for n in (400, 800, 1600):
        f = np.linspace(100.0, 900.0, n)
        w = 2 * np.pi * f
        m = FRF.from_arrays(w, sdof(w))
        wq = np.linspace(w[0], w[-1], 40001)
        e = np.abs(m.interpolate(wq)[0, 0] - sdof(wq))
        est = m.interpolation_error(wq)[0, 0]
        inner = (wq > w[3]) & (wq < w[-4])  # not-a-knot end intervals have a larger constant
        assert np.max(e[inner] / est[inner]) < 2.0
        errs.append(e.max())
        hs.append(w[1] - w[0])
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert 3.7 < order < 4.3, order


# ----------------------------------------------------------------------------- bad input


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


GOOD = "# units: mm/N\nf [Hz],xx re,xx im\n100,1e-3,-2e-3\n110,2e-3,-3e-3\n120,1e-3,-4e-3\n"


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("# units: mm/N\nf [Hz],xx re\n100,1e-3\n110,2e-3\n", ["line 2", "xx im", "missing"]),
        (GOOD.replace("110,2e-3", "110,abc"), ["line 4", "'xx re'", "'abc' is not a number"]),
        (GOOD.replace("110,2e-3", "110,nan"), ["line 4", "'xx re'", "not a finite number"]),
        (GOOD.replace("120,", "105,"), ["line 5", "105 Hz is lower than", "sort"]),
        (GOOD.replace("120,", "110,"), ["line 5", "110 Hz repeats", "drop duplicates"]),
        (GOOD.replace("mm/N", "N/mm"), ["units", "cannot convert 'N/mm'"]),
        (GOOD.replace("# units: mm/N\n", ""), ["units are not given", "# units: mm/N"]),
        (GOOD.replace("100,1e-3,-2e-3", "100,1e-3"), ["line 3", "2 columns", "header has 3"]),
        (GOOD.replace("f [Hz]", "f [rad/s]"), ["line 2", "must be in Hz"]),
        ("# units: m/s/N\nf,re,im\n0,1,1\n10,1,1\n", ["line 3", "mobility at 0 Hz", "drop that line"]),
        ("# units: mm/N\nf,xx re,xx im,yy re,yy im\n1,1,1,1,1\n2,1,1,1,1\n", ["x/y", "not given", "zeros"]),
    ],
)
def test_bad_csv_is_one_line_naming_file_and_line(tmp_path, text, words):
    p = _write(tmp_path, "bad.csv", text)
    with pytest.raises(InputError) as exc:
        FRF.read(p)
    one_line(exc, str(p), *words)


def test_units_in_file_and_argument_must_agree(tmp_path):
    p = _write(tmp_path, "u.csv", GOOD)
    with pytest.raises(InputError) as exc:
        FRF.read(p, units="m/N")
    one_line(exc, str(p), "'mm/N'", "'m/N'", "remove one")
    assert FRF.read(p, units="mm/N").data.shape == (1, 1, 3)  # the same unit: fine


def test_bad_frf_file(tmp_path):
    p = _write(tmp_path, "bad.frf", "Units: m/N\n100\t1e-8\t2e-8\n110\t1e-8\n")
    with pytest.raises(InputError) as exc:
        FRF.read(p)
    one_line(exc, str(p), "line 3", "2 values")


def test_uff_without_dataset_58(tmp_path):
    pyuff = pytest.importorskip(
        "pyuff", reason="the uff extra (pip install chatterlab[uff]) is not installed"
    )
    p = tmp_path / "nodes.uff"
    ds = pyuff.prepare_15(node_nums=[1, 2], def_cs=[0, 0], disp_cs=[0, 0], color=[1, 1],
                          x=[0.0, 1.0], y=[0.0, 0.0], z=[0.0, 0.0])  # fmt: skip
    pyuff.UFF(str(p)).write_sets([ds], mode="overwrite")
    with pytest.raises(InputError) as exc:
        FRF.read(p)
    one_line(exc, str(p), "no dataset 58", "15")


def test_uff_without_pyuff_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyuff", None)  # import pyuff raises ImportError
    p = _write(tmp_path, "x.uff", "")
    with pytest.raises(InputError) as exc:
        FRF.read(p)
    one_line(exc, "pip install chatterlab[uff]")


def test_unknown_suffix(tmp_path):
    p = _write(tmp_path, "h.xlsx", "")
    with pytest.raises(InputError) as exc:
        read_frf(p)
    one_line(exc, str(p), ".xlsx", ".csv")


def test_writers_write_nothing_on_bad_input(tmp_path, two_by_two):
    bad = two_by_two.renamed(outputs=["tool.x", "tool.q"], inputs=["tool.x", "tool.q"])
    target = tmp_path / "out.uff"
    with pytest.raises(InputError) as exc:
        write_frf_uff(target, bad._record())
    one_line(exc, "tool.q", "direction")
    with pytest.raises(InputError):
        two_by_two.to_csv(tmp_path / "out.csv", units="m/s/N")
    assert os.listdir(tmp_path) == []


def test_from_arrays_checks():
    w = np.array([1.0, 2.0, 3.0])
    with pytest.raises(InputError, match="not finite at"):
        FRF.from_arrays(w, np.array([1.0, np.nan, 1.0]))
    with pytest.raises(InputError, match="repeated"):
        FRF.from_arrays(np.array([1.0, 2.0, 2.0]), np.ones(3))
    with pytest.raises(InputError, match="shape"):
        FRF.from_arrays(w, np.ones((3, 2)))
    with pytest.raises(InputError, match=r"looks like \(n_freq, n_out, n_in\).*moveaxis"):
        FRF.from_arrays(w, np.ones((3, 2, 2)))  # the old (n_freq, n_out, n_in) order is named, not misread
    m = FRF.from_arrays(w, np.ones((2, 2, 3)), ["a.x", "a.y"], ["a.x", "a.y"])
    with pytest.raises(InputError, match="did you mean 'a.x'"):
        m.select(["a.xx"], ["a.x"])
    assert m.select("a.y", ["a.x", "a.y"]).data.shape == (1, 2, 3)


def test_plot_draws_every_entry(two_by_two):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a0, a1 = two_by_two.plot()
    assert len(a0.get_lines()) == 4 and len(a1.get_lines()) == 4
    ys = a0.get_lines()[1].get_ydata()
    assert np.array_equal(ys, np.abs(two_by_two.data[0, 1]))  # tool.x / tool.y magnitude
    assert [t.get_text() for t in a0.get_legend().get_texts()][1] == "tool.x / tool.y"
    b0, b1 = two_by_two.plot(part="reim")
    assert np.array_equal(b1.get_lines()[3].get_ydata(), two_by_two.data[1, 1].imag)
    c0, _ = two_by_two.plot(output="tool.y", input="tool.x")  # one entry, by name
    assert len(c0.get_lines()) == 1 and np.array_equal(
        c0.get_lines()[0].get_ydata(), np.abs(two_by_two.data[1, 0])
    )
    plt.close("all")
