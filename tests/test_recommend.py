"""The speeds to choose (chatterlab.selection.recommend): the recommended cut
against closed forms written here, independently of chatterlab.

* 1-DOF turning (Tlusty & Polacek 1963; Altintas, *Manufacturing
  Automation*, 2nd ed., 2012, ch. 3): along lobe k the chatter frequency
  w > w_n solves w T = 3 pi + 2 arg G(jw) + 2 pi k, T = 60 / n, and
  b_lim = -1 / (2 K_f Re G(jw)).  The removal rate is b n times a constant,
  so the best cut is the closed form's maximum of b_lim(n) n: the peak
  (cusp) where two lobes cross.
* Milling by the zeroth-order approximation (Altintas & Budak, CIRP Annals
  44 (1995) 357-362) on a tool with one mode in x and the same in y (the
  2-DOF benchmark): the eigenvalues Lambda of [alpha][G] with Altintas &
  Budak's directional coefficients alpha, a_lim = -2 pi Lambda_R (1 +
  kappa^2) / (N K_t), kappa = Lambda_I / Lambda_R, w T = pi - 2 atan(kappa)
  + 2 pi k, n = 60 / (N T).

Invariants: the margin scales the width and leaves the speed; a depth cap
moves the best speed to the fastest one where the cap is stable; a power
limit makes MRR = P / specific energy exactly; a plug-in limit meets its
bound; every recommended cut is checked on its own.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import turning_text
from scipy.optimize import brentq

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.selection import Machine, WidthLimit, recommend, width_limit
from chatterlab.selection._recommend import stable_width

MASS, STIFF, DAMP, KF = 2.0, 2.0e7, 400.0, 2.0e9
TURNING = turning_text(mass=MASS, stiffness=STIFF, damping=DAMP, Kf=KF, name="1-DOF turning")
SPEEDS = np.linspace(2000.0, 12000.0, 300)


@pytest.fixture(scope="module")
def turning():
    return cl.loads_model(TURNING, source="turning.toml")


# ------------------------------------------------------------------------------ closed forms
def _G(w):
    return 1.0 / (STIFF - MASS * w**2 + 1j * DAMP * w)


def tlusty(n: float, kmax: int = 40) -> float:
    """The envelope b_lim(n), m: the lowest lobe at spindle speed n (rpm)."""
    wn = math.sqrt(STIFF / MASS)
    T = 60.0 / n
    best = math.inf
    for k in range(kmax):

        def f(w: float, k: int = k) -> float:
            return w * T - (3 * math.pi + 2 * np.angle(_G(w))) - 2 * math.pi * k

        a, b = wn * (1 + 1e-12), wn * 5
        if f(a) * f(b) < 0:
            w = brentq(f, a, b, xtol=1e-14, rtol=1e-15)
            best = min(best, -1.0 / (2 * KF * _G(w).real))
    return best


def _local_argmax(form, centre: float, half: float, step: float) -> tuple[float, float]:
    """The speed maximising form(n) * n on a grid of ``step`` around ``centre``, and the maximum."""
    n = np.arange(centre - half, centre + half + step / 2, step)
    r = np.array([form(x) * x for x in n])
    i = int(np.argmax(r))
    return float(n[i]), float(r[i])


# ------------------------------------------------------------------------------ turning oracle
def test_turning_best_speed_is_the_closed_form_lobe_peak(turning):
    rec = recommend(turning, SPEEDS, margin=0.2)
    n0, b0 = float(rec.speed[0]), float(rec.limit[0])
    # the closed form's maximum of b n, on a grid of 0.01 rpm around the recommendation
    step = 0.01
    n_cf, r_cf = _local_argmax(tlusty, n0, 3 * rec.resolution[0] + 0.5, step)
    assert abs(n0 - n_cf) <= rec.resolution[0] + step, (n0, n_cf, rec.resolution[0])
    # the refinement brackets the cusp: its resolution is far below the grid's 33 rpm
    assert rec.resolution[0] < 1.0
    # ... and it is the global best: no speed of the grid does better by the closed form
    coarse = max(tlusty(x) * x for x in SPEEDS)
    assert coarse <= r_cf * (1 + 1e-9)
    # the limit there is the closed form's (the engine refines the envelope to round-off; the
    # closed form's brentq to 1e-14 rad/s), the width 80 % of it
    assert b0 == pytest.approx(tlusty(n0), rel=1e-8)
    assert rec.width[0] == pytest.approx(0.8 * b0, rel=1e-12)
    assert rec.binding[0] == "stability"
    assert "peak where lobes" in rec.reason[0]
    assert rec.verdict[0] == "stable"  # the cut checked on its own (roots and argument principle)
    # the ranking is by b/T, best first
    assert np.all(np.diff(rec.width_rate) <= 0)
    assert np.allclose(rec.width_rate, rec.width * rec.speed / 60.0, rtol=1e-12)


def test_the_margin_scales_the_width_and_keeps_the_speed(turning):
    """b* = (1 - m) b_lim: the removal rate is (1 - m) b_lim n, with the same maxima."""
    a = recommend(turning, SPEEDS, margin=0.0, count=3, check=False)
    b = recommend(turning, SPEEDS, margin=0.5, count=3, check=False)
    np.testing.assert_allclose(b.speed, a.speed, atol=float(np.max(a.resolution + b.resolution)))
    np.testing.assert_allclose(b.width / b.limit, 0.5, rtol=1e-12)
    np.testing.assert_allclose(a.width, a.limit, rtol=1e-12)


def test_a_depth_cap_moves_the_best_speed_to_where_the_lobe_falls_below_it(turning):
    """With the tool's largest depth below the peak's 0.8 b_lim, the rate cap / T grows with the
    speed until the lobe right of the peak falls below the cap: 0.8 b_lim(n*) = cap there."""
    cap = 1.5e-3
    rec = recommend(turning, SPEEDS, margin=0.2, machine=Machine(max_depth=cap), check=False)
    n0 = float(rec.speed[0])
    assert rec.binding[0] == "max depth" and rec.width[0] == cap
    # the closed form's crossing, on the falling side right of the peak at ~10259 rpm
    n_star = brentq(lambda n: 0.8 * tlusty(n) - cap, 10260.0, 10400.0, xtol=1e-9)
    assert abs(n0 - n_star) <= rec.resolution[0], (n0, n_star)
    assert "fastest speed at which this width is stable" in rec.reason[0]


def test_power_limited_cuts_remove_power_over_specific_energy(turning):
    """P = K_c h b V = K_c MRR: where the spindle's power sets the width, MRR = P / K_c exactly,
    and the MRR is b h pi D n / 60."""
    P, Kc, f, D = 3000.0, 2.0e9, 1e-4, 0.05
    m = Machine(power=((0.0, P),), feed=f, workpiece_diameter=D, specific_energy=Kc)
    rec = recommend(turning, SPEEDS, margin=0.2, machine=m, check=False)
    np.testing.assert_allclose(rec.mrr, rec.width * f * math.pi * D * rec.speed / 60.0, rtol=1e-13)
    np.testing.assert_allclose(rec.power, Kc * rec.mrr, rtol=1e-13)
    by_power = rec.binding == "power"
    assert np.any(by_power)
    np.testing.assert_allclose(rec.mrr[by_power], P / Kc, rtol=1e-12)
    np.testing.assert_allclose(rec.power[by_power], P, rtol=1e-12)
    # a plateau of equal rates: the one cut kept is the one farthest from the lobes
    assert "farthest from the lobes" in rec.reason[int(np.nonzero(by_power)[0][0])]


def test_a_torque_curve_read_between_its_points(turning):
    """Torque M = K_c h b D / 2: where the curve sets the width, the torque is the curve's, read
    linearly between its points."""
    Kc, f, D = 2.0e9, 1e-4, 0.05
    curve = ((1000.0, 4.0), (13000.0, 1.0))
    m = Machine(torque=curve, feed=f, workpiece_diameter=D, specific_energy=Kc)
    rec = recommend(turning, SPEEDS, margin=0.2, machine=m, check=False)
    by = rec.binding == "torque"
    assert np.any(by)
    expect = 4.0 + (rec.speed[by] - 1000.0) * (1.0 - 4.0) / 12000.0
    np.testing.assert_allclose(rec.torque[by], expect, rtol=1e-12)
    np.testing.assert_allclose(rec.width[by], 2 * expect / (Kc * f * D), rtol=1e-12)


def test_a_plug_in_limit_bounds_the_width(turning):
    """A surface-location-error-like quantity q = b n / 1e4 (grows with the width) held to
    2.5e-4: the width it allows is 2.5 / n, found by bisection to rtol 1e-4 of the bound."""
    lim = width_limit("surface location error", lambda v, b: b * v / 1e4, 2.5e-4)
    assert isinstance(lim, WidthLimit)
    rec = recommend(turning, SPEEDS, margin=0.2, limits=[lim], check=False)
    by = rec.binding == "surface location error"
    assert np.any(by)
    upper = np.minimum(0.8 * rec.limit[by], np.inf)
    np.testing.assert_array_less(rec.width[by], 2.5 / rec.speed[by] + 1e-15)
    np.testing.assert_allclose(rec.width[by], 2.5 / rec.speed[by], atol=1e-4 * float(np.max(upper)))
    assert "'surface location error'" in rec.reason[int(np.nonzero(by)[0][0])]


def test_a_custom_width_limit_object(turning):
    class Wall:
        name = "thin wall"

        def max_width(self, speeds, upper):
            return np.minimum(upper, 1e-3)

    rec = recommend(turning, SPEEDS, margin=0.2, limits=[Wall()], check=False, count=2)
    assert np.all(rec.width <= 1e-3)
    assert rec.caps["thin wall"].shape == rec.grid_speed.shape


def test_the_machine_speed_range_is_respected_and_its_end_searched(turning):
    rec = recommend(turning, SPEEDS, margin=0.2, machine=Machine(max_speed=9000.0), check=False)
    assert rec.grid_speed.max() == 9000.0
    assert np.all(rec.speed <= 9000.0)
    assert any("dropped" in n for n in rec.notes)


def test_from_the_machine_range_alone(turning):
    rec = recommend(
        turning, margin=0.2, machine=Machine(min_speed=5000.0, max_speed=8000.0), points=40, check=False
    )
    assert rec.grid_speed.min() == 5000.0 and rec.grid_speed.max() == 8000.0


def test_undetermined_speeds_allow_no_cut():
    """Never claim stable without a check: a speed whose lobes establish nothing (claim 2: no
    boundary found in a band not proven complete; 3: contradicted by a check) allows no width."""
    d = SimpleNamespace(
        b_lim=np.array([1e-3, np.inf, np.inf, 2e-3, np.inf]), claim=np.array([0, 1, 2, 3, 5]), width_max=5e-3
    )
    w, ceiling = stable_width(d)
    np.testing.assert_array_equal(w, [1e-3, 5e-3, np.nan, np.nan, 5e-3])
    np.testing.assert_array_equal(ceiling, [False, True, False, False, True])


# ------------------------------------------------------------------------------ milling oracles
MILL2 = "studies/milling/benchmark_2dof.toml"


def _ab_zoa(model):
    """Altintas & Budak's closed form for the symmetric tool: a_lim(n) by lobe, every k."""
    cut = model.process.milling
    N, Kt, Kr = cut.teeth, cut.Kt, cut.Kn / cut.Kt

    def prim(f):
        return 0.5 * np.array(
            [
                [
                    np.cos(2 * f) - 2 * Kr * f + Kr * np.sin(2 * f),
                    -np.sin(2 * f) - 2 * f + Kr * np.cos(2 * f),
                ],
                [
                    -np.sin(2 * f) + 2 * f + Kr * np.cos(2 * f),
                    -np.cos(2 * f) - 2 * Kr * f - Kr * np.sin(2 * f),
                ],
            ]
        )

    alpha = np.linalg.eigvals(prim(cut.exit) - prim(cut.entry))
    mode = model.modes[0]
    m, wn, z = mode.mass, mode.omega, mode.damping_ratio

    def g(w):
        return 1.0 / (m * wn**2 - m * w**2 + 2j * z * wn * m * w)

    w = np.linspace(0.5 * wn, 2.0 * wn, 40001)

    def a_lim(n: float, kmax: int = 40) -> float:
        Tn = 60.0 / (N * n)
        best = math.inf
        for mu in alpha:

            def lam(x, mu=mu):
                return -1.0 / (g(x) * mu)

            def a_of(x):
                L = lam(x)
                return -2 * math.pi / (N * Kt) * L.real * (1 + (L.imag / L.real) ** 2)

            def T_of(x, k):
                L = lam(x)
                return (math.pi - 2 * np.arctan(L.imag / L.real) + 2 * math.pi * k) / x

            a = a_of(w)
            for k in range(kmax):
                f = T_of(w, k) - Tn
                for i in np.nonzero((np.sign(f[:-1]) != np.sign(f[1:])) & (a[:-1] > 0) & (a[1:] > 0))[0]:
                    r = brentq(lambda x, k=k: T_of(x, k) - Tn, w[i], w[i + 1], xtol=1e-13)
                    best = min(best, float(a_of(r)))
        return best

    return a_lim


def test_milling_zoa_establishes_no_cut():
    """The zeroth-order approximation misses the flip lobes (review: on the
    1-DOF benchmark it called 10.77 mm at 9147.7 rpm stable, where the
    Floquet multiplier is -1.72), so its limits establish nothing: no cut is
    recommended from them, every speed is undetermined, and the reason says
    so.  (Before, this test checked its best speed against the closed-form
    Altintas-Budak peak; the peak search is checked on the Floquet route
    below and on turning.)"""
    model = cl.load_model(MILL2)
    rec = recommend(model, np.linspace(5000.0, 8000.0, 31), margin=0.2, method="zoa", width_max=0.05, count=3)
    assert len(rec.speed) == 0
    assert any("zeroth-order approximation, which misses the flip lobes" in n for n in rec.notes)


def test_milling_floquet_recommendation_lies_on_its_multipliers():
    """The Floquet route: the limit at the recommended speed has a multiplier on the unit circle
    (an independent computation: the multipliers at that one depth), and the cut (80 %) is
    stable by them."""
    from chatterlab.frequency import multipliers
    from chatterlab.lobes import milling_loop_of

    model = cl.load_model("studies/milling/benchmark_1dof.toml")
    rec = recommend(model, np.linspace(9000.0, 12000.0, 31), margin=0.2, width_max=0.01, count=1)
    loop = milling_loop_of(cl.assemble(model).at())
    n0, a0 = float(rec.speed[0]), float(rec.limit[0])
    mu = multipliers(loop, n0, a0)
    assert abs(mu.spectral_radius - 1) < 1e-6
    assert rec.verdict[0] == "stable"
    assert multipliers(loop, n0, float(rec.width[0])).spectral_radius < 1


def test_the_shaper_from_its_model_file():
    """Shaping: the removal rate b h L_cut / T and the power F_z b v_w from the grasso coupling's
    main cutting force (forces[0] / width_ref)."""
    model = cl.load_model("studies/traverse_shaper/model.toml")
    rec = recommend(model, np.linspace(0.3, 1.0, 80), margin=0.2, machine=Machine(feed=2e-4), count=2)
    L, T = model.process.cut, model.process.delay(rec.speed)
    np.testing.assert_allclose(rec.mrr, rec.width * 2e-4 * L / T, rtol=1e-12)
    np.testing.assert_allclose(rec.power, 3260.0 / 0.002 * rec.width * rec.speed, rtol=1e-12)
    assert set(rec.verdict) <= {"stable"}


# ------------------------------------------------------------------------------ refusals
@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"margin": 1.0}, ["margin", "[0, 1)"]),
        ({"margin": -0.1}, ["margin"]),
        ({"machine": Machine(max_speed=-100.0)}, ["max_rpm", "> 0"]),
        ({"machine": Machine(power=((0.0, 1e3), (5000.0, 2e3), (4000.0, 2e3)))}, ["power", "increase"]),
        ({"machine": Machine(max_width=1e-3)}, ["max_width", "milling"]),
        ({"machine": Machine(power=((0.0, 1e3),))}, ["power", "specific_energy"]),
        ({"machine": Machine(min_speed=20000.0, max_speed=30000.0)}, ["no speed searched"]),
        ({"limits": [object()]}, ["WidthLimit"]),
        ({"count": 0}, ["count"]),
    ],
)
def test_bad_input_is_one_line_naming_the_field(turning, kwargs, words):
    with pytest.raises(InputError) as e:
        recommend(turning, SPEEDS, check=False, **kwargs)
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_torque_on_a_shaper_is_refused():
    model = cl.load_model("studies/traverse_shaper/model.toml")
    with pytest.raises(InputError, match="torque"):
        recommend(model, np.linspace(0.3, 1.0, 10), machine=Machine(torque=((0.0, 10.0),)))


def test_milling_radial_width_above_the_tools_is_refused():
    model = cl.load_model("studies/milling/benchmark_1dof.toml")  # a_e = 1 mm
    with pytest.raises(InputError, match="max_width"):
        recommend(model, np.linspace(9000.0, 12000.0, 5), machine=Machine(max_width=0.5e-3))


# ------------------------------------------------------------------------------ files and plot
def test_result_protocol(turning, tmp_path):
    import csv
    import json

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import xarray as xr

    rec = recommend(turning, SPEEDS, margin=0.2, count=3,
                    machine=Machine(max_depth=2e-3, feed=1e-4, workpiece_diameter=0.05))  # fmt: skip
    ds = rec.to_xarray()
    assert all("units" in v.attrs for v in ds.variables.values())
    p = rec.to_netcdf(tmp_path / "r.nc")
    with xr.open_dataset(p, engine="h5netcdf") as back:
        for k, v in ds.data_vars.items():
            if v.dtype.kind == "f":
                np.testing.assert_array_equal(back[k].values, v.values)
    with open(rec.to_csv(tmp_path / "r.csv"), newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["speed [rpm]"]) for r in rows] == list(rec.speed)
    assert [float(r["width [m]"]) for r in rows] == list(rec.width)
    assert [r["reason"] for r in rows] == list(rec.reason)
    text = rec.to_json()
    assert "NaN" not in text and "Infinity" not in text
    json.loads(text)
    axes = rec.plot()
    assert len(axes) == 2
    assert rec.plot(ax=axes) == axes
    plt.close("all")
    assert "rank" in rec.summary() and "why:" in rec.summary()


def test_a_measured_frf_model_is_ranked_but_not_checked(tmp_path):
    """A model whose structure is a measured FRF ([frf]): its lobes rank the cuts; no model can
    check a cut on its own, so each says 'not checked', and the note says the limits hold in
    the measured band only."""
    from chatterlab.structure import FRF

    f = np.arange(100.0, 1500.0 + 1e-9, 1.0)
    w = 2 * np.pi * f
    H = 1.0 / (1e7 - w**2 + 2j * 0.03 * math.sqrt(1e7) * w)
    FRF.from_arrays(f, H, ("tool.x",), ("tool.x",), hz=True).to_csv(tmp_path / "tool.csv")
    text = turning_text().split("[[body]]")[0] + '[frf]\nfile = "tool.csv"\n[[point]]\nid = "tip"\n'
    text += 'coords = { x = "tool.x" }\n[[coupling]]\nid = "cut"\na = "tip"\nb = "ground"\n'
    text += (
        'model = "regenerative"\nwidth_ref = 0.001\nKf = 2.0e9\n[process]\nkind = "turning"\nrpm = 3000.0\n'
    )
    (tmp_path / "m.toml").write_text(text)
    model = cl.load_model(tmp_path / "m.toml")
    rec = recommend(model, np.linspace(2000.0, 6000.0, 41), width_max=0.005, count=2)
    assert set(rec.verdict) == {"not checked"}
    assert any("measured" in n for n in rec.notes)
    ref = cl.lobes(model, rec.speed, width_max=0.005)
    np.testing.assert_allclose(rec.limit, ref.b_lim, rtol=1e-12)
