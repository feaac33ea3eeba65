"""Process damping (issue 22 item 1): the flank's velocity term in the one
closed loop and the D-subdivision with the width and the delay coupled
through the cutting speed.

Oracles: C_pd = 0 is today's engine bit for bit; the 1-DOF turning boundary
solved independently here, speed by speed, from its two real equations; the
lobe points satisfy the characteristic equation; Tlusty's closed-form lobe
bottom with the extra damping b C_pd / V (a quadratic in b) and its 1/V
trend; the constant-gain engine at each speed's own gain for a multi-DOF
model (the shaper); the argument principle at the checked speeds.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

import chatterlab as cl
from chatterlab.errors import ModelError
from chatterlab.lobes._diagram import Boundary
from chatterlab.lobes._envelope import Boundary as ConstantBoundary
from chatterlab.lobes._plant import Plant
from chatterlab.process import closed_loop

ROOT = Path(__file__).resolve().parents[1]
EPS = np.finfo(float).eps


def _study():
    spec = importlib.util.spec_from_file_location(
        "process_damping_study", ROOT / "studies/process_damping.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


ST = _study()
M, K, C, KF, D = ST.MASS, ST.STIFF, ST.DAMP, ST.KF, ST.DIAMETER


def turning(C_pd=ST.C_PD, **kw):
    return cl.loads_model(ST.model_text(C_pd, **kw), source="turning.toml")


# ----------------------------------------------------------------------------- the independent oracle
def exact_turning_limit(rpm: float, C_pd: float, b_max: float = 0.02) -> tuple[float, float]:
    """b_lim (m) and chatter frequency (Hz) of the 1-DOF turning loop
    m x'' + c x' + k x = -K_f b (x - x(t - T)) - b (C_pd / V) x' at one speed,
    by the D-subdivision written out: at s = jw, with R = k - m w^2, I = c w,
    theta = w T, the real and imaginary parts are
        R + b K_f (1 - cos theta) = 0,   I + b (K_f sin theta + w g) = 0,
    g = C_pd / V.  Eliminating b: F(w) = I K_f (1 - cos theta) - R (K_f sin theta + w g) = 0,
    solved on a fine grid by brackets and Brent; b = -R / (K_f (1 - cos theta))."""
    T = 60.0 / rpm
    g = C_pd / (np.pi * D * rpm / 60.0)
    wn = math.sqrt(K / M)

    def F(w):
        R, I, th = K - M * w * w, C * w, w * T
        return I * KF * (1 - np.cos(th)) - R * (KF * np.sin(th) + w * g)

    w = np.linspace(0.5 * wn, 3.0 * wn, 400_001)
    f = F(w)
    best = (np.inf, np.nan)
    for i in np.nonzero(np.sign(f[:-1]) * np.sign(f[1:]) < 0)[0]:
        r = brentq(F, w[i], w[i + 1], xtol=1e-15, rtol=4 * EPS)
        b = -(K - M * r * r) / (KF * (1 - math.cos(r * T)))
        if 0 < b <= b_max and b < best[0]:
            best = (b, r / (2 * np.pi))
    return best


# ----------------------------------------------------------------------------- the model file
def test_fields_units_and_the_indentation_equivalent():
    pd = turning().process_damping
    assert pd.coupling == "cut" and pd.C_pd == ST.C_PD and pd.normal is None and not pd.indentation
    ind = turning(indentation=True).process_damping
    assert ind.indentation
    # the small-vibration equivalent of the indentation force: C_pd = K_sp w^2 / 4 (docs Eq. 6)
    assert ind.C_pd == pytest.approx(ST.K_SP * ST.WEAR_LAND**2 / 4, rel=1e-15)
    assert ind.clearance == pytest.approx(math.radians(ST.CLEARANCE_DEG))
    # a parameter path like any other field: --set, variants, sweeps
    assert turning().with_parameter("process_damping.C_pd", 1e5).process_damping.C_pd == 1e5


BASE = ST.model_text(None)


@pytest.mark.parametrize(
    ("table", "says"),
    [
        ("C_pd = -1.0", "C_pd: must be >= 0"),
        ("C_pd = 1e20", "C_pd: 1e+20 N/m is outside the plausible range"),
        ('C_pd = "big"', "C_pd: must be a number"),
        ("K_sp = 4e13", "give C_pd (N/m) or all of K_sp"),
        ("C_pd = 1e5\nK_sp = 4e13", "give either C_pd (the linear model) or K_sp"),
        ("K_sp = 4e13\nwear_land = 1e-4\nclearance_deg = 95.0", "clearance_deg: must lie in (0, 90) deg"),
        (
            "K_sp = 4e13\nwear_land = 1.0\nclearance_deg = 7.0",
            "wear_land: 1 m is outside the plausible range",
        ),
        ('C_pd = 1e5\ncoupling = "tool"', "coupling: no [[coupling]] has the id 'tool'"),
        ("C_pd = 1e5\nCpd = 2.0", "unknown field 'Cpd'. Did you mean 'C_pd'?"),
    ],
)
def test_bad_fields_are_one_line_errors(table, says):
    with pytest.raises(ModelError) as e:
        cl.loads_model(BASE + "\n[process_damping]\n" + table + "\n", source="m.toml")
    msg = str(e.value)
    assert "\n" not in msg and "[process_damping]" in msg and says in msg, msg


def test_the_process_must_have_a_cutting_speed():
    no_diameter = BASE.replace("[machine]\nworkpiece_diameter = 0.05\n", "")
    with pytest.raises(
        ModelError, match=r"turning needs the workpiece diameter.*\[machine\] workpiece_diameter"
    ):
        cl.loads_model(no_diameter + "\n[process_damping]\nC_pd = 1e5\n")
    delay = no_diameter.replace('kind = "turning"\nrpm = 300', 'kind = "delay"\ndelay = 0.2')
    with pytest.raises(ModelError, match="a delay process does not have"):
        cl.loads_model(delay + "\n[process_damping]\nC_pd = 1e5\n")


def test_cli_refuses_a_bad_table_in_one_line_and_writes_nothing(tmp_path, capsys):
    from chatterlab.cli._main import main

    f = tmp_path / "m.toml"
    f.write_text(BASE + "\n[process_damping]\nC_pd = -3.0\n")
    out = tmp_path / "lobes.csv"
    code = main(["lobes", str(f), "--speed", "300", "600", "--points", "4", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    assert len(err.strip().splitlines()) == 1 and "C_pd: must be >= 0" in err


# ----------------------------------------------------------------------------- the one closed loop
def test_the_term_is_the_papers_ideal_derivative_feedback_with_a_speed_gain():
    fz = cl.assemble(turning()).at()
    b, n = 1.5e-3, 420.0
    loop = closed_loop(fz, width=b, speed=n)
    V = np.pi * D * n / 60.0
    expect = np.zeros((3, 3))
    expect[0, 0] = b * ST.C_PD / V  # along the chip-thickness normal (CE axis 1 here)
    assert np.allclose(loop.Dl_V, expect, rtol=1e-15, atol=0)
    # the loop moved to another width and speed is the loop built there
    moved = loop.at(width=2 * b, delay=60.0 / 777.0)
    fresh = closed_loop(fz, width=2 * b, speed=777.0)
    assert np.allclose(moved.Dl_V, fresh.Dl_V, rtol=4 * EPS, atol=0)
    # and it is in D(s) = -J^T (P + s V + O e^{-sT}) J of every engine
    s = 1j * 3000.0
    assert np.allclose(fresh.D(s), -fresh.J.T @ fresh.Dl(s) @ fresh.J, rtol=1e-14)


def test_zero_C_pd_is_todays_loop_and_diagram_bit_for_bit():
    plain, zero = turning(None), turning(0.0)
    n = np.linspace(300.0, 3000.0, 40)
    a = cl.lobes(plain, n, width_max=0.02, verify=2)
    z = cl.lobes(zero, n, width_max=0.02, verify=2)
    assert np.array_equal(a.b_lim, z.b_lim) and np.array_equal(a.chatter_hz, z.chatter_hz)
    assert "process_damping" not in z.meta
    la = closed_loop(cl.assemble(plain).at(), width=1e-3, speed=500.0)
    lz = closed_loop(cl.assemble(zero).at(), width=1e-3, speed=500.0)
    assert lz.damping is None and all(
        np.array_equal(getattr(la, x), getattr(lz, x)) for x in ("Dl_P", "Dl_V", "Dl_O")
    )


# ----------------------------------------------------------------------------- the coupled D-subdivision
SPEEDS = np.array([185.0, 240.0, 333.0, 520.0, 910.0, 1500.0, 2480.0])


@pytest.fixture(scope="module")
def damped():
    return cl.lobes(turning(), SPEEDS, width_max=0.02, verify=8)


def test_1dof_turning_against_the_exact_d_subdivision_written_out(damped):
    for n, b, f in zip(SPEEDS, damped.b_lim, damped.chatter_hz, strict=True):
        ref, fr = exact_turning_limit(n, ST.C_PD)
        # both solve the same two real equations to round-off; b's sensitivity to the
        # phase theta = w T is |d ln b / d theta| = |sin theta / (1 - cos theta)|, and the
        # phase carries w T eps of round-off: the tolerance is 64 times that product
        th = 2 * np.pi * fr * 60.0 / n
        tol = 64 * EPS * th * abs(math.sin(th) / (1 - math.cos(th))) + 64 * EPS
        assert abs(b / ref - 1) <= tol, (n, b, ref, tol)
        assert abs(f / fr - 1) <= 64 * EPS * th
    assert damped.verified  # the argument principle counts the roots of the exact loop at each check


def test_every_lobe_point_solves_the_characteristic_equation(damped):
    assert damped.lobes
    for lb in damped.lobes:
        s = 2j * np.pi * lb.frequency_hz
        g = ST.C_PD / (np.pi * D * np.asarray(lb.speed) / 60.0)
        res = M * s * s + C * s + K + lb.width * (KF * (1 - np.exp(-s * lb.delay)) + s * g)
        # each term is at most K + b K_f in size; Newton stops at the round-off floor
        # of the phase w T (relative w T eps), amplified by b K_f
        scale = K + lb.width * KF * (1 + np.abs(s * lb.delay))
        assert np.all(np.abs(res) <= 1e3 * EPS * scale), lb.k


def test_the_damped_engine_tends_to_todays_as_C_pd_goes_to_zero():
    n = np.array([260.0, 700.0, 1900.0])
    b0 = cl.lobes(turning(None), n, width_max=0.02, verify=0).b_lim
    b1 = cl.lobes(turning(5e-2), n, width_max=0.02, verify=0).b_lim
    b2 = cl.lobes(turning(1e-1), n, width_max=0.02, verify=0).b_lim
    # the effect of the term is linear in C_pd near 0 (b is smooth in the gain), so the
    # differences double with it: the damped engine's limit at C_pd -> 0 is today's envelope
    ratio = (b2 - b0) / (b1 - b0)
    assert np.all(np.abs(ratio - 2) < 1e-3), ratio  # second order: relative size (b1 - b0)/b0 ~ 1e-7
    assert np.all(b1 > b0)


def test_lobe_bottoms_closed_form_and_the_one_over_V_trend():
    # 1. at one gain the constant-gain engine's absolute minimum is Tlusty's with
    #    zeta = (c + b g) / (2 sqrt(k m)): the root of a quadratic in b (studies/process_damping.py)
    fz = cl.assemble(turning()).at()
    bd = Boundary(fz, width_max=0.02)
    p = bd.plant
    for V in (0.4, 0.8, 2.0):
        g = ST.C_PD / V
        plant = Plant(p.H, p.poles, p.Dl_P, p.Dl_V + g * bd.term.W, p.Dl_O, p.residues)
        got = ConstantBoundary(None, width_max=0.02, plant=plant).absolute_minimum()["width"]
        assert got == pytest.approx(float(ST.bottom(V)), rel=1e-10)
    # 2. the coupled envelope at a speed is the constant-gain envelope at that speed's gain,
    #    so it lies on or above the bottom there, and touches it at the lobe bottoms
    r = ST.run(np.geomspace(150.0, 1200.0, 300))
    fin = np.isfinite(r["damped"].b_lim)
    ratio = r["damped"].b_lim[fin] / r["bottom"][fin]
    assert np.all(ratio >= 1 - 1e-12)
    assert ratio.min() < 1 + 1e-3  # a requested speed near a lobe bottom
    # 3. the published trend: the bottoms rise like 1/V at low speed (Altintas, Eynian &
    #    Onozuka 2008; Budak & Tunc 2010): b - b0 = b0 (1 + 2 zeta) w_n C_pd / (K_f V) + O(1/V^2)
    V = np.array([2.0, 4.0, 8.0, 16.0])
    rise = (ST.bottom(V) - r["b0"]) / r["b0"]
    first = r["V_star"] / V
    assert np.all(np.abs(rise / first - 1) < 3 * first)  # the O(1/V^2) remainder
    # 4. and below ~171 rpm no width up to the ceiling chatters (checked by the argument principle)
    assert 160.0 < r["stable_below_rpm"] < 180.0 and r["damped"].verified


def test_multi_dof_shaper_against_the_constant_gain_engine_at_each_speeds_gain(shaper_path):
    text = shaper_path.read_text() + "\n[process_damping]\nC_pd = 3e5\n"
    model = cl.loads_model(text, source="shaper.toml", base_dir=shaper_path.parent)
    speeds = np.linspace(0.15, 0.95, 9)
    d = cl.lobes(model, speeds, width_max=1e-3, position=0.85, verify=6)
    assert d.verified
    bd = Boundary(cl.assemble(model).at(0.85), width_max=1e-3)
    p = bd.plant
    T = d.delay
    for i, gi in enumerate(bd.term.gain(T)):
        plant = Plant(p.H, p.poles, p.Dl_P, p.Dl_V + gi * bd.term.W, p.Dl_O, p.residues)
        ref = ConstantBoundary(None, width_max=1e-3, plant=plant).envelope(T[i : i + 1])[0][0]
        # the constant-gain engine refines to 1e-14 in w; both are exact boundary points
        assert d.b_lim[i] == pytest.approx(ref, rel=1e-9), speeds[i]


def test_a_sweep_over_C_pd_through_its_parameter_path():
    from chatterlab.quantities import QuantityTask

    task = QuantityTask(turning(), "b-lim", fixed={"speed": 300.0}, width_max=0.02)
    got = [task(**{"process_damping.C_pd": c})["b_lim"] for c in (0.0, 1e5, 2e5)]
    assert got[0] < got[1] < got[2]
    assert got[2] == pytest.approx(exact_turning_limit(300.0, 2e5)[0], rel=1e-10)


# ----------------------------------------------------------------------------- milling (ZOA)
def test_milling_zoa_with_the_rubbing_teeth():
    from chatterlab.process import Milling, milling_loop

    text = (ROOT / "studies/milling/benchmark_2dof.toml").read_text() + "\n[process_damping]\nC_pd = 2e4\n"
    model = cl.loads_model(text, source="mill.toml")
    mill = Milling.from_cut(model.process.milling)
    # W_0 = (N / 2 pi) int r r^T dphi, r = (sin phi, cos phi), written out
    a, e = mill.entry, mill.exit
    Iss = (e - a) / 2 - (math.sin(2 * e) - math.sin(2 * a)) / 4
    Icc = (e - a) / 2 + (math.sin(2 * e) - math.sin(2 * a)) / 4
    Isc = (math.sin(e) ** 2 - math.sin(a) ** 2) / 2
    W0 = mill.teeth / (2 * np.pi) * np.array([[Iss, Isc], [Isc, Icc]])
    rpm, ap = 8000.0, 1e-3
    loop = closed_loop(cl.assemble(model).at(), width=ap, speed=rpm)
    V = np.pi * mill.diameter * rpm / 60.0
    assert np.allclose(loop.Dl_V[:2, :2], ap * 2e4 / V * W0, rtol=1e-14, atol=0)
    ml = milling_loop(
        cl.assemble(model).at().structure,
        Milling.from_cut(model.process.milling, rpm),
        loop.J[:2],
        width=ap,
        C_pd=2e4,
    )
    assert np.allclose(ml.Dl_V, ap * 2e4 / V * W0, rtol=1e-14, atol=0)
    # the averaged (ZOA) diagram: at each speed the constant-gain engine at its own gain
    speeds = np.array([3000.0, 5000.0, 9000.0])
    d = cl.lobes(model, speeds, width_max=0.01, method="zoa", verify=4)
    assert d.method == "zoa" and "process_damping" in d.meta and d.verified
    bd = Boundary(cl.assemble(model).at(), width_max=0.01)
    p = bd.plant
    for i, gi in enumerate(bd.term.gain(d.delay)):
        plant = Plant(p.H, p.poles, p.Dl_P, p.Dl_V + gi * bd.term.W, p.Dl_O, p.residues)
        ref = ConstantBoundary(None, width_max=0.01, plant=plant).envelope(d.delay[i : i + 1])[0][0]
        assert d.b_lim[i] == pytest.approx(ref, rel=1e-9)
    plain = cl.lobes(cl.loads_model(text.split("[process_damping]")[0], source="m"), speeds, width_max=0.01,
                     method="zoa", verify=0)  # fmt: skip
    assert np.all(d.b_lim >= plain.b_lim)


# ----------------------------------------------------------------------------- the other engines
def test_roots_and_frf_of_the_damped_loop():
    from chatterlab.frequency import characteristic_roots

    fz = cl.assemble(turning()).at()
    b, n = 1.2e-3, 250.0
    loop = closed_loop(fz, width=b, speed=n)
    T, g = 60.0 / n, ST.C_PD / (np.pi * D * n / 60.0)
    roots = characteristic_roots(loop, count=4).roots
    for s in roots:
        res = M * s * s + C * s + K + b * (KF * (1 - np.exp(-s * T)) + s * g)
        assert abs(res) <= 1e-9 * (K + b * KF), s
    # the closed-loop receptance at the tool: 1 / (k - m w^2 + j w c + b (K_f (1 - e^{-jwT}) + j w g))
    w = 2 * np.pi * np.linspace(400.0, 700.0, 31)
    H = cl.frf(loop, w, inputs="tool.x", outputs="tool.x").data[0, 0, :]
    ref = 1.0 / (K - M * w**2 + 1j * w * C + b * (KF * (1 - np.exp(-1j * w * T)) + 1j * w * g))
    assert np.allclose(H, ref, rtol=1e-10, atol=0)


# ----------------------------------------------------------------------------- identification of C_pd
def test_fit_recovers_C_pd_from_exact_onsets_and_bounds_it_by_cuts():
    from chatterlab.lobes._fit_damping import fit_process_damping

    n = np.array([195.0, 260.0, 380.0])
    onset = np.array([exact_turning_limit(v, ST.C_PD)[0] for v in n])
    plain = turning(None)  # the fit needs only the structure, the process and the diameter
    fit = fit_process_damping(plain, n, onset, ["onset"] * 3)
    # each critical C_i is the root of b_lim(T_i; C/V_i) = b_i found to 1e-12 in ln g
    assert fit.C_pd == pytest.approx(ST.C_PD, rel=1e-9)
    assert np.allclose(fit.critical, ST.C_PD, rtol=1e-9) and fit.consistent.all()
    # cut tests 3 % either side of the true limit at one speed bracket C_pd
    cuts = fit_process_damping(
        plain, [260.0, 260.0], onset[1] * np.array([0.97, 1.03]), ["stable", "chatter"]
    )
    lo, hi = cuts.interval
    assert lo < ST.C_PD < hi and np.isnan(cuts.std)
    assert lo == pytest.approx(cuts.critical[0]) and hi == pytest.approx(cuts.critical[1])


def test_fit_of_noisy_onsets_is_within_its_standard_error():
    from chatterlab.lobes._fit_damping import fit_process_damping

    rng = np.random.default_rng(22)
    n = np.array([190.0, 215.0, 250.0, 320.0])
    exact = np.array([exact_turning_limit(v, ST.C_PD)[0] for v in n])
    sigma = 0.02 * exact
    fit = fit_process_damping(
        turning(None), n, exact + sigma * rng.standard_normal(n.size), ["onset"] * 4, sigma=sigma
    )
    # the estimate is normal about the truth with the reported standard error to first order:
    # 4 standard errors fail with probability 6e-5 (and the seed is fixed)
    assert abs(fit.C_pd - ST.C_PD) <= 4 * fit.std
    assert 0.001 * ST.C_PD < fit.std < 0.05 * ST.C_PD


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("speed,width,result\n300,1,stable\n", "the header has no 'width_mm' column"),
        ("speed,width_mm,result\n300,1,wobbly\n", "row 2: result must be stable, chatter or onset"),
        ("speed,width_mm,result\n300,-1,stable\n", "row 2: width_mm must be a number > 0"),
        ("speed,width_mm,result\n", "no test row follows"),
        ("speed,width_mm,result,colour\n300,1,stable,red\n", "unknown column(s) colour"),
    ],
)
def test_the_tests_file_is_checked_in_one_line(tmp_path, capsys, text, says):
    from chatterlab.cli._main import main

    cuts, model, out = tmp_path / "cuts.csv", tmp_path / "m.toml", tmp_path / "fit.json"
    cuts.write_text(text)
    model.write_text(BASE)
    code = main(["fit-damping", str(cuts), "--model", str(model), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists() and says in err and len(err.strip().splitlines()) == 1, err


def test_the_tests_file_is_never_an_output(tmp_path, capsys):
    """--out naming the tests file it reads (review: it was replaced by the
    fit's table, exit 0): one line, status 2, the file byte for byte."""
    from chatterlab.cli._main import main

    cuts, model = tmp_path / "cuts.csv", tmp_path / "m.toml"
    cuts.write_bytes((ROOT / "studies/process_damping/cuts.csv").read_bytes())
    model.write_text(BASE)
    before = cuts.read_bytes()
    code = main(["fit-damping", str(cuts), "--model", str(model), "--out", str(cuts)])
    err = capsys.readouterr().err
    assert code == 2 and "is an input of this command" in err and len(err.strip().splitlines()) == 1, err
    assert cuts.read_bytes() == before and sorted(p.name for p in tmp_path.iterdir()) == [
        "cuts.csv",
        "m.toml",
    ]


def test_the_shipped_files_are_what_the_study_writes():
    files = ROOT / "studies/process_damping"
    assert (files / "turning.toml").read_text() == ST.model_text(None)
    assert (files / "cuts.csv").read_text() == ST.cuts_text()


# ----------------------------------------------------------------------------- the indentation model
def test_the_indentation_force_has_the_linear_models_first_harmonic():
    """Eqs. 5-6 of docs/process-damping.md: for u = X sin(w t) the flank's
    force K_sp b A(t) has, in phase with the velocity, the first harmonic of
    C_pd b / V u' with C_pd = K_sp w^2 / 4, up to the two small parameters of
    the linearisation: the wear land against the wave (the surface under the
    land is a sine, not its tangent: relative (w w / V)^2 / 6) and the slope
    of the wave against the clearance (the clearance face's extra triangle:
    X w / (V tan gamma))."""
    from chatterlab.process._damping import flank_interference, indented_area

    K_sp, b, land, gamma, om = ST.K_SP, 1e-3, ST.WEAR_LAND, math.radians(ST.CLEARANCE_DEG), 2 * np.pi * 500.0
    C_pd = K_sp * land**2 / 4
    n = 1000  # samples of a period: the Fourier coefficient of the kinked force to ~1/n^2
    t = np.arange(n) * (2 * np.pi / om) / n
    for V in (5.0, 50.0):
        for X in (1e-8, 1e-7, 1e-6):
            F = []
            for ti in t:
                end = land + 3 * X / math.tan(gamma)  # beyond it the clearance face is above any surface
                xi = np.unique(np.r_[np.linspace(0, land, 201), np.linspace(land, end, 201)])
                u, surf = X * np.sin(om * ti), X * np.sin(om * (ti - xi / V))
                F.append(K_sp * b * indented_area(flank_interference(u, xi, surf, land, gamma), xi))
            first = 2 * np.mean(np.array(F) * np.cos(om * t))
            ratio = first / (C_pd * b / V * om * X)
            bound = (om * land / V) ** 2 / 6 + X * om / (V * math.tan(gamma)) + 2.0 / n**2
            assert abs(ratio - 1) <= bound, (V, X, ratio)
            # and it is a half-wave force: none while the tool moves out of the material
            # (delta = X [theta cos(w t) + theta^2 sin(w t) / 2 + ...] < 0 for cos(w t) < -theta_max)
            assert np.all(np.array(F)[np.cos(om * t) < -om * land / V] == 0.0)


def test_an_onset_off_the_fit_disagrees_and_a_test_above_the_ceiling_is_refused():
    """Review: an onset always 'agreed'.  An onset says C_pd = C_i within its
    width's error: at 1e9 rpm the cut of 2.363 mm is below the limit without
    any damping (C_i = 0), so it cannot agree with a fit of C_pd > 0, while
    the onset that sets the fit agrees.  And a test at or above the width
    ceiling would get the ceiling's coefficient, not its own (the review's
    --width-max 1 fitted 1.1e5 instead of 2e5): refused, naming the test."""
    from chatterlab.errors import InputError
    from chatterlab.lobes._fit_damping import fit_process_damping

    model = cl.load_model(ROOT / "studies/process_damping/turning.toml")
    fit = fit_process_damping(
        model, [1e9, 230.0], [2.363e-3, 1.554e-3], ["onset", "onset"], sigma=[1e-5, 1e-5]
    )
    assert fit.critical[0] == 0.0 and fit.C_pd > 0
    assert fit.consistent.tolist() == [False, True]
    with pytest.raises(InputError, match=r"test 2: its width 3 mm is not below the width ceiling 2\.5 mm"):
        fit_process_damping(model, [230.0, 190.0], [1.554e-3, 3e-3], ["onset", "stable"], width_max=2.5e-3)
