"""One FRF container (issue 19, finding 4): chatterlab.structure.FRF holds a
modelled and a measured FRF alike, in one axis order (n_out, n_in, n_freq),
writes every file exactly and reads it back, goes to python-control and back
by one route each way, and the receptance J (K - w^2 M + j w C)^-1 J^T is one
function whose callers agree bit for bit.

Oracles: exactness (a double printed with 17 significant digits, or stored as
a double, is read back bit for bit; a frequency written in Hz comes back
within the two roundings of w = 2 pi f and back), the 1-DOF closed form
1 / (k - m w^2 + j c w), and a modal structure's closed form
J diag(1 / (k_r - m_r w^2 + j c_r w)) J^T."""

from __future__ import annotations

import json

import control  # a dependency of chatterlab: an import error fails, never skips
import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.structure import FRF, Structure, dynamic_receptance, receptance

EPS = np.finfo(float).eps
MASS, STIFF, DAMP = 2.0, 2.0e7, 400.0


def sdof(w: np.ndarray) -> np.ndarray:
    """The 1-DOF oracle, m/N: 1 / (k - m w^2 + j c w)."""
    return 1.0 / (STIFF - MASS * w**2 + 1j * DAMP * w)


def sdof_bound(w: np.ndarray) -> np.ndarray:
    """Round-off of 1 / (k - m w^2 + j c w) computed in floating point,
    relative: the denominator's terms each carry <= 2 eps of their size and
    the cancellation k - m w^2 divides by |D| (its condition), plus one
    rounding of the division; 4 eps per term covers both orders of
    evaluation."""
    D = np.abs(STIFF - MASS * w**2 + 1j * DAMP * w)
    return 4 * EPS * (STIFF + MASS * w**2 + DAMP * w) / D + 2 * EPS


def same_frequency(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal to the rounding of rad/s -> Hz in the file -> rad/s (2 ulps)."""
    return bool(np.all(np.abs(a - b) <= 2 * EPS * np.abs(b)))


@pytest.fixture(scope="module")
def shaper(shaper_path):
    return cl.assemble(cl.load_model(shaper_path)).at(0.85)


@pytest.fixture(scope="module")
def modelled(shaper) -> FRF:
    """A closed-loop FRF of the shaper: two outputs, one input, the loop's facts."""
    w = 2 * np.pi * np.linspace(60.0, 100.0, 81)
    fb = cl.closed_loop(shaper, width=2e-3, speed=0.5)
    return cl.frf(fb, w, inputs="rfe5.x", outputs=["rfe5.x", "rfe5.y"])


@pytest.fixture(scope="module")
def measured() -> FRF:
    rng = np.random.default_rng(19)
    f = np.sort(rng.uniform(50.0, 2000.0, 90))  # uneven spacing
    H = (rng.normal(size=(2, 2, 90)) + 1j * rng.normal(size=(2, 2, 90))) * 1e-7
    coh = rng.uniform(0.2, 1.0, size=(2, 2, 90))
    return FRF.from_arrays(f, H, ["tool.x", "tool.y"], ["tool.x", "tool.y"], hz=True, coherence=coh)


FACTS = ("kind", "closed_loop", "method", "position", "width", "delay", "terms", "outputs", "inputs")


def assert_same(back: FRF, frf: FRF, *, exact_omega: bool) -> None:
    """The data bit for bit, omega exactly or to its Hz rounding, the labels and the facts."""
    assert np.array_equal(back.data, frf.data)
    assert np.array_equal(back.omega, frf.omega) if exact_omega else same_frequency(back.omega, frf.omega)
    for name in FACTS:
        assert getattr(back, name) == getattr(frf, name), name
    if frf.coherence is None:
        assert back.coherence is None
    else:
        assert np.array_equal(back.coherence, frf.coherence)


# ----------------------------------------------------------------------------- one container, one order


def test_a_computed_and_a_read_frf_are_one_type_in_one_axis_order(modelled, tmp_path):
    p = modelled.to_csv(tmp_path / "m.csv")
    back = FRF.read(p)
    assert type(back) is type(modelled) is cl.FRF is cl.frequency.FRF
    assert modelled.data.shape == back.data.shape == (2, 1, modelled.omega.size)  # (n_out, n_in, n_freq)
    # data[o, i] is output o per input i, by name as by index, in both
    for f in (modelled, back):
        assert np.array_equal(f["rfe5.y", "rfe5.x"], f.data[1, 0])
        # the one accessor for batched linear algebra: the same numbers, one matrix per frequency
        assert f.matrices.shape == (f.omega.size, 2, 1)
        assert np.array_equal(f.matrices, np.moveaxis(f.data, -1, 0)) and f.matrices.flags.c_contiguous


# ----------------------------------------------------------------------------- files


@pytest.mark.parametrize("kind", ["receptance", "mobility"])
def test_modelled_frf_round_trips_exactly_through_csv_and_netcdf(modelled, tmp_path, kind):
    frf = modelled.as_kind(kind)
    back = FRF.read(frf.to_csv(tmp_path / "m.csv"), kind=None)  # kind=None: the file's quantity
    assert_same(back, frf, exact_omega=False)
    assert back.meta["quantity"] == kind
    back = FRF.read(frf.to_netcdf(tmp_path / "m.nc"), kind=None)
    assert_same(back, frf, exact_omega=True)  # omega is stored as a double in netCDF
    if kind == "mobility":  # read as receptance (the default): the quantity converted back
        rec = FRF.read(tmp_path / "m.nc")
        # H = Y / (j w): two roundings ((j w) and the division) of each value
        assert np.max(np.abs(rec.data / modelled.data - 1)) < 4 * EPS


def test_measured_frf_round_trips_exactly_through_csv_netcdf_and_uff(measured, tmp_path):
    assert_same(FRF.read(measured.to_csv(tmp_path / "h.csv")), measured, exact_omega=False)
    assert_same(FRF.read(measured.to_netcdf(tmp_path / "h.nc")), measured, exact_omega=True)
    pytest.importorskip("pyuff", reason="the uff extra (pip install chatterlab[uff]) is not installed")
    assert_same(FRF.read(measured.to_uff(tmp_path / "h.uff", binary=True)), measured, exact_omega=False)


def test_modelled_frf_through_uff58b_keeps_its_quantity(modelled, tmp_path):
    pytest.importorskip("pyuff", reason="the uff extra (pip install chatterlab[uff]) is not installed")
    acc = modelled.as_kind("accelerance")
    back = FRF.read(acc.to_uff(tmp_path / "m.uff", binary=True), kind=None)
    # doubles written as doubles; the ordinate type (12: acceleration) says the quantity
    assert back.kind == "accelerance" and np.array_equal(back.data, acc.data)
    assert same_frequency(back.omega, acc.omega) and back.outputs == acc.outputs


def test_the_tap_test_file_round_trips(tmp_path):
    from conftest import ROOT

    tap = FRF.read(ROOT / "studies" / "tap_test" / "tool_point.csv")
    for back in (FRF.read(tap.to_csv(tmp_path / "t.csv")), FRF.read(tap.to_netcdf(tmp_path / "t.nc"))):
        assert np.array_equal(back.data, tap.data) and same_frequency(back.omega, tap.omega)
        assert back.outputs == tap.outputs and back.method == "measured" and not back.closed_loop


def test_the_cli_table_holds_exact_values(shaper_path, shaper, tmp_path):
    from chatterlab.cli import main

    out = tmp_path / "f.csv"
    code = main(["frf", str(shaper_path), "--input", "rfe5.x", "--output", "rfe5.x", "--output", "rfe5.y",
                 "--fmin", "60", "--fmax", "100", "--points", "41", "--position", "0.85", "--out", str(out)])  # fmt: skip
    assert code == 0
    assert out.read_text().startswith("frequency [Hz],|rfe5.x/rfe5.x| [m/N],phase rfe5.x/rfe5.x [deg],re ")
    w = cl.frequencies(60.0, 100.0, 41)
    ref = cl.frf(shaper, w, inputs="rfe5.x", outputs=["rfe5.x", "rfe5.y"])
    back = FRF.read(out)
    assert np.array_equal(back.data, ref.data) and same_frequency(back.omega, ref.omega)


def test_json_holds_exact_values(modelled):
    d = json.loads(modelled.to_json())
    z = np.array(d["real"]) + 1j * np.array(d["imag"])
    assert np.array_equal(z, modelled.data) and d["closed_loop"] and d["delay_s"] == modelled.delay


def test_xarray_labels_and_units(measured):
    ds = measured.to_xarray()
    assert ds["real"].dims == ("output", "input", "frequency")
    assert list(ds["output"].values) == list(measured.outputs)
    assert ds["frequency"].attrs["units"] == "Hz" and ds["omega"].attrs["units"] == "rad/s"
    assert ds["real"].attrs["units"] == "m/N" and ds.attrs["quantity"] == "receptance"
    assert np.array_equal(ds["omega"].values, measured.omega)
    assert np.array_equal(ds["real"].values + 1j * ds["imag"].values, measured.data)
    assert np.array_equal(ds["coherence"].values, measured.coherence)


def test_a_file_that_is_not_an_frf_dataset_is_one_line(tmp_path):
    from chatterlab.io import write_netcdf

    p = write_netcdf(tmp_path / "x.nc", {"t": (np.arange(3.0), "s")}, {"y": (np.zeros(3), "m")})
    with pytest.raises(InputError, match="not an FRF dataset") as exc:
        FRF.read(p)
    assert "\n" not in str(exc.value)


# ----------------------------------------------------------------------------- python-control


def test_to_control_and_from_control_round_trip_exactly(modelled, measured):
    for frf in (modelled, measured):
        frd = frf.to_control()
        assert isinstance(frd, control.FrequencyResponseData)
        back = FRF.from_control(frd)
        assert np.array_equal(back.data, frf.data) and np.array_equal(back.omega, frf.omega)
        assert back.outputs == frf.outputs and back.inputs == frf.inputs  # 'rfe5:x' there, 'rfe5.x' here
        # an FRD evaluated at its own frequencies: its data as stored
        at = FRF.from_control(frd, frf.omega[::3])
        assert np.array_equal(at.data, frf.data[..., ::3])


@pytest.mark.parametrize("form", ["tf", "ss"])
def test_from_control_of_an_lti_system_is_its_response(form):
    w = 2 * np.pi * np.linspace(10.0, 1000.0, 400)
    sys = control.tf([1.0], [MASS, DAMP, STIFF])
    if form == "ss":
        sys = control.tf2ss(sys)
    got = FRF.from_control(sys, w)
    assert got.data.shape == (1, 1, w.size) and got.kind == "receptance"
    # the polynomial (tf) or the resolvent (ss, 2 x 2) evaluated at j w: the 1-DOF round-off bound,
    # twice for the state space's companion-form solve (condition of the same cancellation)
    rel = np.abs(got.data[0, 0] / sdof(w) - 1)
    assert np.all(rel <= (1 if form == "tf" else 2) * sdof_bound(w)), np.max(rel / sdof_bound(w))


def test_lti_lobes_use_the_one_route(monkeypatch):
    """lti_plant evaluates its system through FRF.from_control (no second route)."""
    from chatterlab.lobes._control import lti_plant

    sys = control.tf([1.0], [MASS, DAMP, STIFF])
    w = np.array([900.0, 1000.0, 900.0])  # the engine's grids: any order, repeats
    ref = FRF.from_control(sys, w).data
    calls = []
    original = FRF.from_control.__func__  # type: ignore[attr-defined]

    def spy(cls, sys, omega=None, **kw):
        calls.append(omega)
        return original(cls, sys, omega, **kw)

    monkeypatch.setattr(FRF, "from_control", classmethod(spy))
    plant = lti_plant(sys, DO=[[-2e6]], width_ref=1e-3)
    assert np.array_equal(plant.H(w), np.moveaxis(ref, -1, 0)) and len(calls) == 1


def test_from_control_refuses_what_is_no_system():
    with pytest.raises(InputError, match="python-control system"):
        FRF.from_control("not a system", np.ones(3))
    with pytest.raises(InputError, match="give the frequencies"):
        FRF.from_control(control.tf([1.0], [1.0, 1.0, 1.0]))


# ----------------------------------------------------------------------------- the one receptance


def test_dynamic_receptance_is_the_closed_form_of_one_dof():
    w = 2 * np.pi * np.linspace(0.0, 1000.0, 2001)
    one = np.ones((1, 1))
    H = dynamic_receptance(MASS * one, DAMP * one, STIFF * one, w, one)[:, 0, 0]
    assert np.all(np.abs(H / sdof(w) - 1) <= sdof_bound(w))


def test_dynamic_receptance_of_a_modal_structure_is_its_modal_sum():
    # Structure.modal: diagonal M, C, K in modal coordinates; with the shapes as J (2 x modes),
    # J Z^-1 J^T = sum_r s_r s_r^T / (k_r - m_r w^2 + j c_r w): per mode the 1-DOF bound
    wn = 2 * np.pi * np.array([500.0, 920.0, 1400.0])
    zeta, k = np.array([0.02, 0.011, 0.05]), np.array([2e7, 3e7, 5e7])
    S = np.array([[1.0, 0.2], [0.3, -0.8], [-0.5, 0.4]])
    st = Structure.modal(wn, zeta, k)
    w = 2 * np.pi * np.linspace(1.0, 2000.0, 1500)
    m, c = k / wn**2, 2 * zeta * k / wn
    d = k[:, None] - m[:, None] * w**2 + 1j * c[:, None] * w  # (mode, freq)
    ref = np.einsum("ra,rb,rk->kab", S, S, 1 / d)
    got = st.receptance(w, S.T)
    assert np.array_equal(got, dynamic_receptance(st.M, st.C, st.K, w, S.T))  # the one function
    terms = np.einsum(
        "ra,rb,rk->kab",
        np.abs(S),
        np.abs(S),
        4 * EPS * (k[:, None] + m[:, None] * w**2 + c[:, None] * w) / np.abs(d) ** 2,
    )
    assert np.all(np.abs(got - ref) <= terms + 4 * EPS * np.abs(ref))


def test_the_frf_engine_and_receptance_coupling_solve_the_same_receptance():
    # frequency.frf(method="direct") and structure.receptance both call dynamic_receptance on the
    # frozen matrices: the same arithmetic, the same bits; and both are the 1-DOF closed form
    fz = cl.assemble(cl.loads_model(turning_text(mass=MASS, stiffness=STIFF, damping=DAMP))).at()
    w = 2 * np.pi * np.linspace(10.0, 1500.0, 300)
    a = cl.frf(fz, w, inputs="tip.x", outputs="tip.x")
    b = receptance(fz, "tip.x", "tip.x", w)
    assert np.array_equal(a.data, b.data) and type(a) is type(b)
    assert np.all(np.abs(a.data[0, 0] / sdof(w) - 1) <= sdof_bound(w))


# ----------------------------------------------------------------------------- the container's checks


def test_construction_refuses_a_wrong_shape_in_one_line():
    w = np.array([1.0, 2.0, 3.0])
    with pytest.raises(InputError, match=r"shape \(n_out, n_in, n_freq\) = \(1, 1, 3\)"):
        FRF(w, np.ones((3, 1, 1)), ("a.x",), ("a.x",))
    with pytest.raises(InputError, match="kind must be one of"):
        FRF(w, np.ones((1, 1, 3)), ("a.x",), ("a.x",), kind="compliance")
    f = FRF.from_arrays(np.array([0.0, 1.0, 2.0]), np.ones(3), kind="mobility")
    with pytest.raises(InputError, match="at 0 Hz cannot be converted"):
        f.as_kind("receptance")
