"""Spindle-speed variation (issue 22 item 2): the speed program and its delay,
and the Floquet multipliers of the varying-speed cut.

Oracles: the kinematics against its defining integral (quadrature) and its
first-order expansion; RVA -> 0 against the constant-speed engines (turning:
the characteristic roots, |mu| = exp(Re lambda T); milling: the constant-speed
multipliers to the power of the tooth passes in the period); the SD
multipliers converge to the spectral ones at the order the method has (2); the
spectral ones converge geometrically (degree raised); a time integration of
the same equation grows or decays by the critical |mu| per period.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.frequency import characteristic_roots, multipliers, ssv_multipliers
from chatterlab.process import Milling, SpeedVariation, closed_loop, milling_loop, ssv_loop, varying_milling
from chatterlab.structure import Structure
from chatterlab.time._ssv import simulate_ssv

# the 1-DOF turning benchmark (studies/turning_benchmark.py): m = 2 kg, k = 2e7 N/m, c = 400 N s/m, K_f = 2e9 N/m^2
TURNING = """
[model]
name = "1-DOF turning benchmark"
[[body]]
id = "tool"
mass = 2.0
inertia = 1.0
centre = [0.0, 0.0]
[[support]]
body = "tool"
fix = ["y", "rz"]
[[spring]]
id = "holder"
a = "tool"
b = "ground"
c1 = 2.0e7
d1 = 400.0
[[coupling]]
id = "cut"
a = "tool"
b = "ground"
model = "regenerative"
Kf = 2.0e9
width_ref = 0.001
[process]
kind = "turning"
rpm = 3000
"""
RPM = 3000.0


@pytest.fixture(scope="module")
def turning():
    fz = cl.assemble(cl.loads_model(TURNING)).at()
    return closed_loop(fz, width=1e-3, speed=RPM)


@pytest.fixture(scope="module")
def milling():
    """The 1-DOF milling benchmark (studies/milling/benchmark_1dof.toml)."""
    st = Structure.single_dof(0.03993, 2 * np.pi * 922.0, 0.011)
    return milling_loop(st, Milling.from_immersion(2, 0.02, 6e8, 2e8, 0.05, "down"))


# ============================================================================ kinematics
@pytest.mark.parametrize("shape", ["sine", "triangle"])
def test_the_delay_turns_the_spindle_by_the_pitch_angle(shape):
    """int_{t - tau}^t Omega = phi_p (Eq. 3), by adaptive quadrature of the rate; the
    inverse phase to round-off; the first-order delay of the module docstring to O(RVA^2)."""
    v = SpeedVariation(0.3, 0.07, shape)
    x = np.linspace(-40.0, 300.0, 1501)
    assert np.max(np.abs(v.inverse(v.phase(x)) - x)) <= 8 * np.finfo(float).eps * 300.0
    for x0 in (1.3, 17.0, 55.0):
        lag = float(v.lag(np.array([x0]), 2 * math.pi)[0])
        turned = quad(lambda s: float(v.rate(s)), x0 - lag, x0, limit=200, epsabs=1e-13)[0]
        assert turned == pytest.approx(2 * math.pi, abs=1e-11)  # quad's own tolerance
    small = SpeedVariation(1e-4, 0.07, shape)
    xs = np.linspace(0.0, 100.0, 11)
    P = small.phase(xs) - xs
    first = 2 * math.pi - (P - (small.phase(xs - 2 * math.pi) - (xs - 2 * math.pi)))
    # the next term is O(RVA^2 phi_p^2 max|S'| / 2) = (1e-4)^2 (2 pi)^2 / 2 * RVF-scale < 2e-7
    assert np.max(np.abs(small.lag(xs, 2 * math.pi) - first)) < 2e-7 * 0.07 * 10


def test_the_milling_period_holds_whole_variations_and_tooth_passes():
    """theta advances by whole pitch angles over the period, and the delay repeats."""
    for teeth, rvf in ((2, 0.25), (3, 0.3), (4, 0.125)):
        v = SpeedVariation(0.1, rvf)
        L, k = v.passes(teeth)
        X = v.period_phase(teeth)
        assert X == pytest.approx(L * 2 * math.pi / teeth)
        assert X == pytest.approx(k * 2 * math.pi / rvf)
        x = np.linspace(0, 5, 7)
        assert np.allclose(v.lag(x + X, 2 * math.pi / teeth), v.lag(x, 2 * math.pi / teeth), atol=1e-12)


def test_bad_programs_are_one_line_errors():
    for args, word in (((1.2, 0.1), "RVA"), ((0.1, 0.0), "RVF"), ((0.1, 0.1, "square"), "shape")):
        with pytest.raises(InputError, match=word) as e:
            SpeedVariation(*args)
        assert "\n" not in str(e.value)
    with pytest.raises(InputError, match="ratio"):
        SpeedVariation(0.1, 1 / math.pi).passes(2)


# ============================================================================ RVA -> 0
def test_constant_speed_turning_multipliers_are_the_characteristic_roots(turning):
    """With RVA -> 0 the period-T_v map of the constant-delay loop has spectral radius
    exp(Re lambda_1 T_v), lambda_1 the rightmost characteristic root."""
    b = 2e-3
    lam = characteristic_roots(turning.at(width=b), count=1).roots[0]
    v = SpeedVariation(1e-12, 0.5)
    m = ssv_multipliers(turning, RPM, b, v, method="spectral")
    expect = math.exp(lam.real * m.period)
    # the roots are Newton-refined to ~1e-10 relative; the spectral error is reported
    assert m.spectral_radius == pytest.approx(expect, rel=1e-8 + m.error)
    sd = ssv_multipliers(turning, RPM, b, v, method="sdm", steps=800)
    assert abs(sd.spectral_radius - expect) <= 2 * sd.error  # SD's doubled-steps change bounds its error


def test_constant_speed_milling_multipliers_are_the_tooth_period_ones(milling):
    """A period of L tooth passes maps by X^L: |mu| = |mu_tooth|^L (uniform pitch)."""
    v = SpeedVariation(1e-12, 0.25)
    L, _ = v.passes(2)
    ref = multipliers(milling, 10000.0, 1e-3)
    m = ssv_multipliers(milling, 10000.0, 1e-3, v)
    assert m.spectral_radius == pytest.approx(ref.spectral_radius**L, rel=1e-9)
    assert varying_milling(milling.milling, SpeedVariation(0.0, 0.25)) is milling.milling


# ============================================================================ the two engines
def _sd_errors(loop, speed, width, v, steps):
    ref = ssv_multipliers(loop, speed, width, v, method="spectral")
    assert ref.error < 1e-9  # the reference is exact to the SD errors' digits
    return np.array([
        abs(ssv_multipliers(loop, speed, width, v, method="sdm", steps=m, check=False).spectral_radius
            - ref.spectral_radius)
        for m in steps
    ])  # fmt: skip


@pytest.mark.parametrize("shape", ["sine", "triangle"])
def test_sd_converges_to_the_spectral_multipliers_at_order_two_turning(turning, shape):
    """Turning: the observed order of every doubling is 2; the next term O(steps^-3) moves it
    by ~log2(1 + C/m), < 0.1 from 400 steps (8 per vibration).  The triangle's corners are
    element ends of the spectral mesh (with their delayed images), so it stays the reference."""
    steps = (400, 800, 1600)
    e = _sd_errors(turning, RPM, 2e-3, SpeedVariation(0.2, 0.5, shape), steps)
    orders = np.log2(e[:-1] / e[1:])
    assert np.all(np.abs(orders - 2.0) < 0.1), (e, orders)


def test_sd_converges_to_the_spectral_multipliers_at_order_two_milling(milling):
    """Milling: the teeth enter and leave between grid points at positions that change with
    the steps, so the error oscillates about C steps^-2: e m^2 stays within a factor 2 over
    three doublings (order 1 or 3 would move it by 2^3 = 8 over them)."""
    steps = np.array([320, 640, 1280, 2560])
    e = _sd_errors(milling, 10000.0, 1e-3, SpeedVariation(0.1, 0.25), steps)
    scaled = e * steps**2.0
    assert scaled.max() / scaled.min() < 2.0, (e, scaled)


@pytest.mark.parametrize("shape", ["sine", "triangle"])
def test_spectral_converges_geometrically_with_the_degree(turning, shape):
    v = SpeedVariation(0.2, 0.5, shape)
    b = 2e-3
    r = [ssv_multipliers(turning, RPM, b, v, degree=p, check=False).spectral_radius for p in (6, 9, 12, 24)]
    e = np.abs(np.array(r[:3]) - r[3])
    assert e[1] < 0.05 * e[0] and e[2] < 0.05 * e[1]  # a decade and more per 3 degrees: geometric


def test_ssv_raises_the_limit_at_a_low_speed_lobe(turning):
    """The classic finding (Insperger & Stepan 2004; Zatarain et al. 2008): at a high lobe
    number the variation breaks the regeneration, so a width unstable at constant speed is
    stable under SSV."""
    b = 1.5e-3  # above the constant-speed limit 2 zeta (1 + zeta) / K_f at this lobe's trough
    const = ssv_multipliers(turning, RPM, b, SpeedVariation(1e-12, 0.5), check=False)
    varied = ssv_multipliers(turning, RPM, b, SpeedVariation(0.2, 0.5), check=False)
    assert const.spectral_radius > 1.0 > varied.spectral_radius


# ============================================================================ time domain
def test_a_simulation_grows_by_the_critical_multiplier_per_period(turning):
    """Newmark (average acceleration, O(h^2)) on the same equation: the envelope's growth per
    period tends to |mu|; its error at h is bounded by the change from h to h/2 (x 4/3, the
    Richardson factor of a second-order method) plus the subdominant multipliers' share."""
    v = SpeedVariation(0.2, 0.5)
    sys = ssv_loop(turning, v, RPM)
    for b in (1e-3, 2e-3):
        mu = ssv_multipliers(turning, RPM, b, v, check=False).spectral_radius
        g1 = simulate_ssv(sys, b, 12, omega_h=0.05).growth()
        g2 = simulate_ssv(sys, b, 12, omega_h=0.025).growth()
        assert abs(g2 - mu) <= 4 / 3 * abs(g1 - g2) + 0.01 * mu, (b, mu, g1, g2)
        assert (g2 > 1.0) == (mu > 1.0)


def test_a_milling_simulation_decays_or_grows_as_the_multipliers_say(milling):
    """The milling cut integrated with its teeth entering and leaving inside Newmark steps
    (first order there): the sign of log |mu| is what is compared, at depths whose |mu| is
    far from 1 (0.08 and 2.9) against the run's error (~0.02 and ~0.1 at this step)."""
    v = SpeedVariation(0.1, 0.25)
    sys = ssv_loop(milling, v, 5000.0)
    for a in (2.5e-3, 4.5e-3):
        mu = ssv_multipliers(milling, 5000.0, a, v, check=False).spectral_radius
        g = simulate_ssv(sys, a, 6).growth()
        assert abs(math.log(mu)) > 1.0 and (g > 1.0) == (mu > 1.0), (a, mu, g)


def test_variable_pitch_at_rva_zero_is_the_constant_speed():
    """A variable pitch's coefficients repeat once a revolution: with RVF = 1/2 the period is
    two revolutions and |mu| = |mu_rev|^2 (Floquet: the map of two periods is X^2)."""
    st = Structure.modal(2 * np.pi * np.array([900.0, 950.0]), [0.02, 0.02], [1e7, 1.2e7], ("x", "y"))
    loop = milling_loop(st, Milling(3, 0.02, 6e8, 2e8, 0.5, 2.0, pitch=(2.0, 2.0, 2 * math.pi - 4.0)))
    ref = multipliers(loop, 8000.0, 5e-4)
    m = ssv_multipliers(loop, 8000.0, 5e-4, SpeedVariation(1e-12, 0.5))
    assert m.spectral_radius == pytest.approx(ref.spectral_radius**2, rel=1e-9)


def test_refused_combinations_are_one_line(turning, milling):
    with pytest.raises(InputError, match="speed"):
        ssv_loop(milling, SpeedVariation(0.1, 0.25))
    with pytest.raises(InputError, match="ratio"):
        ssv_loop(milling, SpeedVariation(0.1, 0.3333), 10000.0)
    with pytest.raises(InputError, match="method"):
        ssv_multipliers(turning, RPM, 1e-3, SpeedVariation(0.1, 0.5), method="euler")  # type: ignore[arg-type]


# ============================================================================ limits
def _tlusty_limit(rpm: float) -> float:
    """The constant-speed limit of the 1-DOF turning benchmark in closed form (Tlusty; Altintas
    2012 ch. 3): on lobe k the chatter frequency w > w_n solves w T = 3 pi + 2 arg G(jw) + 2 pi k
    and b = -1 / (2 K_f Re G); the limit at a speed is the least over the lobes."""
    from scipy.optimize import brentq

    m, k, c, kf = 2.0, 2.0e7, 400.0, 2.0e9
    T = 60.0 / rpm
    G = lambda w: 1.0 / (k - m * w * w + 1j * c * w)  # noqa: E731
    wn = math.sqrt(k / m)
    w = np.linspace(wn * (1 + 1e-9), 3 * wn, 200001)
    eps = 3 * np.pi + 2 * np.angle(G(w))
    best = math.inf
    for lobe in range(0, 200):
        f = w * T - eps - 2 * np.pi * lobe
        idx = np.nonzero(np.sign(f[:-1]) != np.sign(f[1:]))[0]
        for i in idx:
            g = lambda x, k=lobe: x * T - (3 * np.pi + 2 * np.angle(G(x))) - 2 * np.pi * k  # noqa: E731
            r = brentq(g, w[i], w[i + 1])
            best = min(best, -1.0 / (2 * kf * G(r).real))
    return best


def test_the_limit_at_rva_zero_is_the_closed_form_and_the_sweep_runs_the_grid():
    from chatterlab.frequency._floquet_ssv_limit import SsvLimitTask, ssv_limits

    fz = cl.assemble(cl.loads_model(TURNING)).at()
    speeds = [1500.0, 6000.0]
    res = ssv_limits(fz, speeds, [0.0, 0.2], [0.5], width_max=4e-3, scan=8, rtol=1e-7)
    for i, s in enumerate(speeds):
        # Brent to rtol 1e-7 on a spectral radius exact to ~1e-10: 1e-6 covers both
        assert res.b_lim[i, 0, 0] == pytest.approx(_tlusty_limit(s), rel=1e-6)
    assert res.speed_unit == "rpm" and res.limit_name == "b_lim"
    # the classic finding at the low speed: the variation raises the limit
    assert res.gain()[0, 1, 0] > 1.5
    import pickle

    task = SsvLimitTask.of(fz, width_max=4e-3, scan=8)
    assert pickle.loads(pickle.dumps(task))(6000.0, 0.0, 0.5)["b_lim"] == pytest.approx(
        res.b_lim[1, 0, 0], rel=1e-6
    )


def test_limits_at_listed_points_are_the_grid_s_serial_or_in_parallel():
    """ssv_limits_at (the mesh check's searches twice as fine) runs the grid's
    own task at listed points: the same search, so the same numbers bit for
    bit, in any order, serially or in two worker processes; bad points are
    refused before any work, as the grid's are."""
    from chatterlab.frequency import ssv_limits, ssv_limits_at

    fz = cl.assemble(cl.loads_model(TURNING)).at()
    opts = dict(width_max=4e-3, scan=4)
    grid = ssv_limits(fz, [1500.0, 6000.0], [0.0, 0.2], [0.5], **opts)
    pts = [(6000.0, 0.2, 0.5), (1500.0, 0.0, 0.5), (6000.0, 0.0, 0.5)]
    want = [grid.b_lim[1, 1, 0], grid.b_lim[0, 0, 0], grid.b_lim[1, 0, 0]]
    assert ssv_limits_at(fz, pts, **opts).tolist() == want
    assert ssv_limits_at(fz, pts, jobs=2, backend="loky", **opts).tolist() == want
    assert ssv_limits_at(fz, [], **opts).size == 0
    with pytest.raises(InputError, match="speed"):
        ssv_limits_at(fz, [(-1.0, 0.0, 0.5)], **opts)


def test_the_limits_are_a_result(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import json

    import matplotlib.pyplot as plt
    import xarray as xr

    from chatterlab.frequency._floquet_ssv_limit import SsvLimits

    b = np.array([[[1e-3, np.inf]], [[2e-3, 3e-3]]]).transpose(0, 2, 1)  # (speeds, rva, rvf)
    r = SsvLimits(
        np.array([1000.0, 2000.0]), np.array([0.0, 0.1]), np.array([0.5]), b.reshape(2, 2, 1), np.ones((2, 2, 1)),
        np.ones((2, 2, 1)), "sine", "spectral", 5e-3, 10,
    )  # fmt: skip
    p = r.to_netcdf(tmp_path / "s.nc")
    with xr.open_dataset(p) as ds:
        assert np.array_equal(ds["b_lim"].values, r.b_lim)
        assert ds["b_lim"].attrs["units"] == "m"
    json.loads(r.to_json())
    assert r.to_csv(tmp_path / "s.csv").read_text().splitlines()[0].startswith("speed [rpm]")
    fig, ax = plt.subplots()
    assert r.plot(ax=ax) is ax
    plt.close(fig)
    assert "> 5" in r.table()


# ============================================================================ the model file
_BASE = TURNING.split("[process]")[0] + '[process]\nkind = "turning"\nrpm = 3000\n'


def test_the_model_file_ssv_table_and_its_errors():
    from chatterlab.errors import ChatterlabError

    m = cl.loads_model(_BASE + '[ssv]\nshape = "triangle"\nrva = 0.1\nrvf = 0.5\n', source="t.toml")
    assert SpeedVariation.of_model(m) == SpeedVariation(0.1, 0.5, "triangle")
    assert SpeedVariation.of_model(cl.loads_model(_BASE, source="t.toml")) is None
    assert cl.loads_model(_BASE + "[ssv]\nrva = 0.1\nrvf = 0.5\n").ssv.shape == "sine"
    bad = {
        "rva = 1.5\nrvf = 0.5": "rva",
        "rva = 0.1\nrvf = 0": "rvf",
        "rva = 0.1\nrvf = 20": "rvf",
        "rva = 0.1": "rvf",
        'shape = "square"\nrva = 0.1\nrvf = 0.5': "shape",
        "rva = 0.1\nrvf = 0.5\nrfv = 2": "rfv",
    }
    for text, word in bad.items():
        with pytest.raises(ChatterlabError) as e:
            cl.loads_model(_BASE + "[ssv]\n" + text + "\n", source="t.toml")
        msg = str(e.value)
        assert "\n" not in msg and "t.toml" in msg and "[ssv]" in msg and word in msg, msg
