"""Lobes straight from a measured FRF (issue 13, item 2).

The oracle is a model whose FRF is "measured" on a grid (FRF.from_model):
the lobes from the spline-interpolated FRF must equal the model's lobes to
the error that the interpolation of H near the chatter frequency carries
into b_lim, derived to first order (docs/measured-frf.md):

    |db| <= b eps / |Re G| + |db/dT| |dT|,   |dT| <= 2 eps / (|G| w),

eps the interpolation error of the oriented FRF G near the chatter frequency
w (measured here against the exact G), b = -1 / (2 K_f Re G) Tlusty's width
and T the delay on the lobe (z = e^{-jwT} = -conj(G)/G, so the phase of z
moves by twice that of G).  The envelope converges like the spline, O(h^4).
A chatter frequency outside the measured band is never "stable".
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.lobes import lobes, lobes_measured, measured_plant
from chatterlab.model import Process
from chatterlab.process import Milling
from chatterlab.structure import FRF

MASS, STIFF, DAMP, KF = 2.0, 2.0e7, 400.0, 2.0e9
RPM = np.linspace(2500.0, 11000.0, 150)


def sdof(w: np.ndarray) -> np.ndarray:
    return 1.0 / (STIFF - MASS * w**2 + 1j * DAMP * w)


@pytest.fixture(scope="module")
def turning():
    m = cl.loads_model(turning_text(mass=MASS, stiffness=STIFF, damping=DAMP, Kf=KF))
    fz = cl.assemble(m).at()
    return m, fz, lobes(fz, RPM, width_max=0.05, verify=0)


def measured(fz, df: float, lo: float = 100.0, hi: float = 1500.0) -> FRF:
    f = np.arange(lo, hi + df / 2, df)
    return FRF.from_model(fz, "tip.x", omega=2 * np.pi * f)


def first_order_bound(frf: FRF, ref, j: int) -> float:
    """The derived bound on |b_meas - b_model| at speed j (1-DOF, f = n = x)."""
    wc = 2 * np.pi * ref.chatter_hz[j]
    k = int(ref.lobe[j])
    x = frf.omega
    i = int(np.searchsorted(x, wc))
    wq = np.linspace(x[max(i - 2, 0)], x[min(i + 1, x.size - 1)], 401)
    eps = float(np.max(np.abs(frf.interpolate(wq)[0, 0] - sdof(wq))))
    G = sdof(np.array([wc]))[0]
    b = -1.0 / (2 * KF * G.real)

    def lnb(w: float) -> float:
        return float(np.log(-1.0 / (2 * KF * sdof(np.array([w]))[0].real)))

    def z(w: float) -> complex:
        g = sdof(np.array([w]))[0]
        return complex(-np.conj(g) / g)

    d = 1e-6 * wc
    theta = np.mod(-np.angle(z(wc)), 2 * np.pi)
    dtheta = -np.angle(z(wc + d) / z(wc - d)) / (2 * d)
    dT = (dtheta * wc - (theta + 2 * np.pi * k)) / wc**2  # T = (theta + 2 pi k) / w
    slope = (lnb(wc + d) - lnb(wc - d)) / (2 * d) / dT  # d ln b / dT on lobe k
    return b * eps / abs(G.real) + b * abs(slope) * 2 * eps / (abs(G) * wc)


def inside_one_lobe(ref, meas) -> np.ndarray:
    """Speeds whose neighbours lie on the same lobe in both diagrams (at a
    cusp the bound is the larger of the two lobes')."""
    same = np.ones(ref.lobe.size, bool)
    for d in (ref, meas):
        lb = d.lobe
        same[1:-1] &= (lb[1:-1] == lb[:-2]) & (lb[1:-1] == lb[2:])
    same[[0, -1]] = False
    return same & np.isfinite(ref.b_lim)


@pytest.mark.parametrize("df", [2.0, 1.0])
def test_turning_lobes_from_measured_frf_within_the_derived_bound(turning, df):
    m, fz, ref = turning
    frf = measured(fz, df)
    got = lobes_measured(frf, RPM, process=m.process, Kf=KF, width_max=0.05)
    assert np.array_equal(np.isfinite(got.b_lim), np.isfinite(ref.b_lim))
    err = np.abs(got.b_lim - ref.b_lim)
    sel = np.nonzero(inside_one_lobe(ref, got))[0]
    assert sel.size > 100
    bound = np.array([first_order_bound(frf, ref, j) for j in sel])
    # first order: the neglected terms are O(eps^2) relative (< 1e-8 here), so 10 %
    # covers them; 1e-12 b the round-off of the two refinements (each to ~1e-14)
    assert np.all(err[sel] <= 1.1 * bound + 1e-12 * ref.b_lim[sel]), np.max(err[sel] / bound)
    # the bound is not vacuous: the error reaches a good part of it somewhere
    assert np.max(err[sel] / bound) > 0.3  # measured 0.68 (2 Hz), 0.81 (1 Hz)
    # absolute minimum: min over w of b(w), so only the eps / |Re G| term (envelope theorem)
    a, r = got.absolute_minimum, ref.absolute_minimum
    wc = 2 * np.pi * r["chatter_hz"]
    wq = np.linspace(wc - 2 * (frf.omega[1] - frf.omega[0]), wc + 2 * (frf.omega[1] - frf.omega[0]), 201)
    eps = np.max(np.abs(frf.interpolate(wq)[0, 0] - sdof(wq)))
    assert abs(a["width"] - r["width"]) <= 1.1 * r["width"] * eps / abs(sdof(np.array([wc]))[0].real)
    assert set(np.unique(got.claim)) == {4}  # boundaries, from the measured band only


def test_noisy_measured_frf_within_the_same_bound(turning):
    """Measurement noise (complex Gaussian, 1e-3 of |H| at each sample): the
    spline passes through the noisy samples, so eps near the chatter
    frequency is the noise times the spline's Lebesgue constant (< 2 for a
    cubic spline on a uniform grid, de Boor, A Practical Guide to Splines,
    ch. XII) plus the smooth error; the first-order bound holds with that
    eps (measured against the exact G), and eps is below that sum."""
    m, fz, ref = turning
    clean = measured(fz, 1.0)
    rng = np.random.default_rng(2026)
    H = clean.data[0, 0]
    noise = 1e-3 * np.abs(H) * (rng.normal(size=H.size) + 1j * rng.normal(size=H.size)) / np.sqrt(2)
    noisy = FRF.from_arrays(clean.omega, H + noise, ["tip.x"], ["tip.x"])
    got = lobes_measured(noisy, RPM, process=m.process, Kf=KF, width_max=0.05)
    sel = np.nonzero(inside_one_lobe(ref, got))[0]
    err = np.abs(got.b_lim - ref.b_lim)[sel]
    bound = np.array([first_order_bound(noisy, ref, j) for j in sel])
    assert np.all(err <= 1.1 * bound), np.max(err / bound)
    assert np.max(np.abs(got.b_lim[sel] / ref.b_lim[sel] - 1)) > 1e-5  # the noise shows (clean: 1.2e-6)
    w = noisy.omega
    wq = np.linspace(w[300], w[600], 3001)
    eps = np.abs(noisy.interpolate(wq)[0, 0] - sdof(wq))
    smooth = np.abs(clean.interpolate(wq)[0, 0] - sdof(wq))
    assert np.max(eps) <= 2.0 * np.max(np.abs(noise[299:602])) + np.max(smooth)


def test_turning_lobes_converge_like_the_spline(turning):
    """Envelope error against grid spacing h: fitted order 4 (the cubic
    spline's, Hall & Meyer); +-0.5 for the pre-asymptotic terms, O(h / sigma)
    relative with sigma = zeta f_n = 16 Hz the half-power half-width and
    h / sigma <= 1/8 here, and for the speed at which the maximum error sits
    moving between grids."""
    m, fz, ref = turning
    fin = np.isfinite(ref.b_lim)
    hs, errs = [], []
    for df in (2.0, 1.0, 0.5):
        got = lobes_measured(measured(fz, df), RPM, process=m.process, Kf=KF, width_max=0.05)
        errs.append(np.max(np.abs(got.b_lim[fin] / ref.b_lim[fin] - 1)))
        hs.append(df)
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert 3.5 < order < 4.5, (order, errs)


def test_lobes_from_a_measured_file_equal_lobes_from_the_object(turning, tmp_path):
    m, fz, ref = turning
    frf = measured(fz, 2.0)
    p = tmp_path / "tap.csv"
    frf.to_csv(p, units="um/N")
    back = FRF.read(p)
    a = lobes_measured(frf, RPM, process=m.process, Kf=KF, width_max=0.05)
    b = lobes_measured(back, RPM, process=m.process, Kf=KF, width_max=0.05)
    # the file holds H to a few ulps (um/N scaling) and f to 2 ulps: the same lobes to round-off
    assert np.max(np.abs(a.b_lim / b.b_lim - 1)) < 1e-10


def test_chatter_outside_the_measured_band_is_unknown_never_stable(turning):
    m, fz, ref = turning
    # the band stops below the mode (503 Hz): no boundary inside it
    low = measured(fz, 2.0, 100.0, 400.0)
    d = lobes_measured(low, RPM, process=m.process, Kf=KF, width_max=0.05)
    assert np.all(np.isinf(d.b_lim))
    assert not d.band_certified and d.band_measured
    assert set(np.unique(d.claim)) == {2}  # "undetermined", never 1 ("stable below width_max")
    assert "undetermined" in d.summary() and "no chatter below" not in d.summary()
    # fmin/fmax cannot reach outside the measured band
    with pytest.raises(InputError, match="outside the measured band"):
        lobes_measured(low, RPM, process=m.process, Kf=KF, fmax=600.0)


def test_a_mode_outside_the_band_is_missed_and_said_so():
    """Two modes (x at 503 Hz, and a stiffer y-mode coupled in by an oblique
    cut); the measured band covers only the first.  Where the model's chatter
    is at the second mode, the measured diagram's b_lim is larger (it cannot
    see it) -- and it claims only 'boundary in the measured band'."""
    text = """
[[body]]
id = "tool"
mass = 2.0
inertia = 1.0
centre = [0.0, 0.0]
[[support]]
body = "tool"
fix = ["rz"]
[[spring]]
id = "k"
a = "tool"
b = "ground"
c1 = 2.0e7
c2 = 1.2e8
d1 = 400.0
d2 = 300.0
[[coupling]]
id = "cut"
a = "tool"
b = "ground"
model = "regenerative"
Kf = 2.0e9
force_angle_deg = 60.0
normal_angle_deg = 45.0
width_ref = 0.001
[process]
kind = "turning"
rpm = 3000
"""
    m = cl.loads_model(text)
    fz = cl.assemble(m).at()
    rpm = np.linspace(3000.0, 30000.0, 200)
    ref = lobes(fz, rpm, width_max=0.2, verify=0)
    f = np.arange(100.0, 900.0, 1.0)  # the y mode is at 1233 Hz
    frf = FRF.from_model(fz, ["tool.x", "tool.y"], omega=2 * np.pi * f)
    got = lobes_measured(
        frf,
        rpm,
        process=m.process,
        Kf=2.0e9,
        force_angle=np.radians(60.0),
        normal_angle=np.radians(45.0),
        width_max=0.2,
    )
    outside = np.isfinite(ref.b_lim) & (ref.chatter_hz > 900.0)
    assert outside.any()
    assert np.all(got.b_lim[outside] > ref.b_lim[outside])
    assert np.all(got.claim == np.where(np.isfinite(got.b_lim), 4, 2))
    inside = np.isfinite(ref.b_lim) & (ref.chatter_hz < 850.0)
    assert inside.any()
    # where the model chatters inside the band the two agree (1 Hz grid: ~1e-6, bound as above)
    assert np.max(np.abs(got.b_lim[inside] / ref.b_lim[inside] - 1)) < 1e-4


# ----------------------------------------------------------------------------- milling, ZOA

MILL = Milling.from_immersion(teeth=3, diameter=0.02, Kt=6e8, Kn=0.3 * 6e8, radial_immersion=0.5, mode="down")


def _mat(A: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(repr(float(x)) for x in r) + "]" for r in A) + "]"


@pytest.fixture(scope="module")
def milling_model():
    H0 = MILL.zoa()
    DP = np.zeros((3, 3))
    DP[:2, :2] = 1e-3 * H0  # at width_ref = 1 mm: force on the tool -a_p H0 [r(t) - r(t - tau)]
    text = f"""
[[body]]
id = "tool"
mass = 1.0
inertia = 1.0
centre = [0.0, 0.0]
[[support]]
body = "tool"
fix = ["rz"]
[[spring]]
id = "k"
a = "tool"
b = "ground"
c1 = 2.0e7
c2 = 3.0e7
d1 = 200.0
d2 = 250.0
[[coupling]]
id = "cut"
a = "tool"
b = "ground"
model = "matrices"
width_ref = 0.001
DP = {_mat(DP)}
DO = {_mat(-DP)}
[process]
kind = "delay"
delay = 0.001
"""
    return cl.assemble(cl.loads_model(text)).at()


def test_milling_zoa_from_measured_frf(milling_model):
    fz = milling_model
    rpm = np.linspace(5000.0, 20000.0, 60)
    tau = 60.0 / (MILL.teeth * rpm)
    ref = lobes(fz, tau, width_max=0.05, verify=0, process=Process(kind="delay"))
    frf = FRF.from_model(fz, ["tool.x", "tool.y"], omega=2 * np.pi * np.arange(300.0, 2000.0, 1.0))
    got = lobes_measured(frf, rpm, milling=MILL, width_max=0.05)
    fin = np.isfinite(ref.b_lim)
    assert fin.any() and np.array_equal(np.isfinite(got.b_lim), fin)
    # 1 Hz grid, resonances 712 and 872 Hz with half-widths 16 and 20 Hz: measured 3.6e-7;
    # the bound of the turning test scaled by the coupling of two modes (x10) is 1e-5
    assert np.max(np.abs(got.b_lim[fin] / ref.b_lim[fin] - 1)) < 1e-5
    assert got.speed_unit == "rpm" and np.array_equal(got.speed, rpm)
    # Altintas & Budak's closed form at the chatter frequency w_c: the eigenvalues of
    # Phi0 = G(j w_c) alpha0, alpha0 = (2 pi / N) [A0] = -(2 pi / N)(2 H0 / K_t), give
    # Lambda = -1 / eig and a_lim = -(2 pi / (N K_t)) Re Lambda (1 + kappa^2)
    N, Kt = MILL.teeth, MILL.Kt
    alpha0 = -(2 * np.pi / N) * 2 * MILL.zoa() / Kt
    for j in np.nonzero(np.isfinite(got.b_lim))[0][::6]:
        G = frf.interpolate([2 * np.pi * got.chatter_hz[j]])[:, :, 0]
        lam = -1.0 / np.linalg.eigvals(G @ alpha0)
        a = -(2 * np.pi / (N * Kt)) * lam.real * (1 + (lam.imag / lam.real) ** 2)
        # the same spline G: round-off of the refinement (~1e-12)
        assert np.min(np.abs(a / got.b_lim[j] - 1)) < 1e-9


# ----------------------------------------------------------------------------- bad input


def test_measured_plant_refuses_what_it_cannot_use(turning):
    _, fz, _ = turning
    two = FRF.from_arrays(
        2 * np.pi * np.array([100.0, 200.0, 300.0]), np.ones((2, 2, 3)), ["a.x", "a.y"], ["b.x", "b.y"]
    )
    with pytest.raises(InputError, match="driving-point"):
        measured_plant(two, Kf=1e9)
    one = measured(fz, 10.0)
    with pytest.raises(InputError, match="not both"):
        measured_plant(one, Kf=1e9, DO=[[1.0]], width_ref=1e-3)
    with pytest.raises(InputError, match="Kf must be > 0"):
        measured_plant(one, Kf=-1.0)
    with pytest.raises(InputError, match="2 x 2 FRF"):
        measured_plant(one, milling=MILL)
    with pytest.raises(InputError, match="uniform pitch"):
        vp = Milling(
            teeth=2, diameter=0.02, Kt=6e8, Kn=1e8, entry=0.0, exit=np.pi, pitch=(2.8, 2 * np.pi - 2.8)
        )
        three = two.renamed(inputs=["a.x", "a.y"])
        measured_plant(three, milling=vp)
    with pytest.raises(InputError, match="no component on the measured coordinate"):
        measured_plant(one, Kf=1e9, force_angle=np.pi / 2)


def test_plot_of_a_measured_frf_draws_no_envelope_between_the_requested_speeds():
    """A noisy measured FRF breaks the lobe curves into pieces the plot cannot
    join: their minimum between samples drew 'pockets' up to 4 mm over a
    0.9 mm limit (17 mm over 0.42 mm in milling; found by a review).  The plot
    draws the engine's b_lim at the requested speeds and nothing between, and
    claims no undetermined speed the diagram does not."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from chatterlab.cli._main import build_parser
    from chatterlab.cli._measured import frf_model
    from chatterlab.cli._units import resolve_units
    from chatterlab.lobes._measured import lobes_model_frf
    from chatterlab.plot import plot_lobes

    csv = Path(__file__).resolve().parents[1] / "studies" / "tap_test" / "tool_point.csv"
    args = build_parser().parse_args(["lobes", "--frf", str(csv), "--kf", "1e9", "--normal-angle", "90",
                                      "--force-angle", "90", "--speed", "3000", "30000"])  # fmt: skip
    resolve_units(args)  # as the command does after parsing: numbers may carry units
    v = np.linspace(3000.0, 30000.0, 300)
    d = lobes_model_frf(frf_model(args), v, width_max=20e-3)
    axes = plot_lobes(d)
    try:
        assert len(axes) == 2  # no zoom on curves that are not exact
        (env,) = [ln for ln in axes[0].lines if ln.get_gid() == "envelope"]
        np.testing.assert_array_equal(env.get_xdata(), v)
        np.testing.assert_array_equal(env.get_ydata(), d.b_lim * 1e3)
        if not np.any(d.claim == 2):
            assert not [c for c in axes[0].collections if c.get_gid() == "claim-2"]
    finally:
        plt.close("all")


def test_milling_lobes_of_a_measured_frf_claim_only_the_zeroth_order(tmp_path, capsys):
    """A measured FRF has no matrices for the Floquet engines, so its milling
    lobes are the zeroth-order approximation's and claim no more (claim 6,
    basis zoa: flip lobes not modelled).  Review: they carried the measured
    band's claim, and recommend's speed rule called a cut stable whose
    Floquet multiplier is 1.49; recommend reads claim 6 as establishing
    nothing."""
    import csv

    from chatterlab.cli import main

    out = tmp_path / "m.csv"
    code = main([
        "lobes", "--frf", "studies/tap_test/tool_point.csv", "--teeth", "3", "--kt", "6e8", "--kn", "2e8",
        "--immersion", "0.5", "--speed", "4000", "12000", "--points", "12", "--width-max", "5", "--out", str(out),
    ])  # fmt: skip
    capsys.readouterr()
    assert code == 0
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 12 and {r["basis"] for r in rows} == {"zoa"}
    assert {r["claim"] for r in rows} == {"zeroth-order approximation (flip lobes not modelled)"}
