"""Transient simulation of Eq. (2.28): the moving slide, the delayed loop.

Every check has mathematics as the oracle:

* a force travelling over a simply supported beam (Fryba's series);
* the steady state of a harmonic force (the FRF, at the frequency the
  trapezoidal rule actually sees);
* the growth rate of a regenerative 1-DOF turning model (the rightmost
  characteristic root, and the exact root of the discrete scheme) and its
  trajectory (an independent method-of-steps integration with scipy);
* the structure-exploiting reductions (Eq. 2.6 and Eqs. 2.16-2.18 by brute
  force, W' and W'' by finite differences);
* bad input: one clear error, and exit status 2 on the command line.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.cli._main import main
from chatterlab.errors import InputError
from chatterlab.process._kinematics import kinematics_for
from chatterlab.structure._assembly import MovingReduction
from chatterlab.time import Excitation, Initial, Integration
from chatterlab.time._newmark import ConstantProblem, NewmarkOptions, newmark
from chatterlab.time._simulate import ParametricProblem, simulate

# ----------------------------------------------------------------------------- models

TURNING = turning_text(forces=(200.0, 0.0, 0.0))


def moving_load_text(L: float, b: float, h: float, elements: int, v: float, F: float) -> str:
    """A simply supported beam (pin at X = 0, roller at X = L) and a carriage
    held by a [[support]] that travels along it at speed v; a contact on the
    beam follows the carriage and a coupling to the ground pushes it down
    with the desired force F (no feedback: terms "none").  kappa = 1e6 makes
    the Timoshenko element an Euler-Bernoulli one (rotary inertia remains)."""
    return f"""
[model]
name = "moving force on a simply supported beam"
[movable]
bodies = ["carriage"]
position = 0.0
range = [0.0, {L!r}]
[[body]]
id = "carriage"
mass = 1.0
inertia = 1.0
centre = [0.0, 0.5]
[[support]]
id = "hold"
body = "carriage"
[[node]]
id = "a"
at = [0.0, 0.0]
[[node]]
id = "b"
at = [{L!r}, 0.0]
[[beam]]
id = "beam"
nodes = ["a", "b"]
A = {b * h!r}
I = {b * h**3 / 12!r}
E = 2.1e11
nu = 0.3
rho = 7850.0
kappa = 1.0e6
elements = {elements}
[[support]]
id = "pin"
node = "a"
fix = ["x", "y"]
[[support]]
id = "roller"
node = "b"
fix = ["y"]
[[contact]]
id = "wheel"
beams = ["beam"]
follows = "carriage"
[[point]]
id = "mid"
beam = "beam"
distance = {L / 2!r}
[[coupling]]
id = "load"
a = "wheel"
b = "ground"
model = "matrices"
width_ref = 1.0
forces = [0.0, {-F!r}, 0.0]
DP = [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
[process]
kind = "shaping"
speed = {v!r}
return_speed = {v!r}
run_in = 0.0
cut = {L!r}
coast = 0.0
start = 0.0
direction = 1
"""


@pytest.fixture(scope="module")
def turning():
    return cl.assemble(cl.loads_model(TURNING))


@pytest.fixture(scope="module")
def shaper(shaper_path):
    return cl.assemble(cl.load_model(shaper_path))


@pytest.fixture(scope="module")
def shaper_damped(shaper_path):
    """The shaper with a damper in the slide/shear joint (on RFE 6, a
    moving contact): the terms L_id W' and W^T L_dd W' of Eq. 2.18 are on."""
    m = cl.load_model(
        shaper_path,
        overrides={
            "spring.slide-shear.d1": 2.0e4,
            "spring.slide-shear.d2": 3.0e4,
            "spring.slide-shear.d6": 1.0e3,
        },
    )
    return cl.assemble(m)


# ----------------------------------------------------------------------------- moving load


def fryba(x: float, t: np.ndarray, *, L, EI, rhoA, v, F, r2=0.0, modes=200) -> np.ndarray:
    """Deflection (downwards) of a simply supported Euler-Bernoulli beam under
    a force F moving at speed v from x = 0 at t = 0, undamped, at rest before
    (Fryba, Vibration of Solids and Structures under Moving Loads, ch. 1):

        w = sum_j 2F/(rho A L) sin(j pi x/L) [sin(W_j t) - (W_j/w_j) sin(w_j t)] / (w_j^2 - W_j^2)

    with W_j = j pi v/L, w_j = (j pi/L)^2 sqrt(EI/(rho A)).  ``r2 = I/A``
    adds the rotary inertia (Rayleigh beam: modal mass and w_j^2 divided by
    1 + (j pi/L)^2 r2; the mode shapes stay sines)."""
    w = np.zeros_like(t)
    for j in range(1, modes + 1):
        k = j * math.pi / L
        e = 1.0 + k * k * r2
        wj = k * k * math.sqrt(EI / (rhoA * e))
        Wj = j * math.pi * v / L
        w += (
            2.0
            * F
            / (rhoA * L * e)
            * math.sin(k * x)
            * (np.sin(Wj * t) - Wj / wj * np.sin(wj * t))
            / (wj * wj - Wj * Wj)
        )
    return w


def test_moving_force_on_a_simply_supported_beam():
    """The midspan deflection under a travelling force equals Fryba's series.

    Beam 1 m x 0.05 x 0.01 m steel (L/h = 100), 20 elements, force 100 N at
    5 m/s: f1 = 23.5 Hz, the force crosses in 0.2 s = 4.7 periods, the
    dynamic increment is 8 % of the static deflection.  The force is the
    coupling's desired force on a contact that follows the carriage, so it
    acts through J_i(t) = J W(t): the test exercises W(t) along the whole
    beam (20 elements, every joint crossed).

    Error budget (relative to max |w| = 2.57 mm), at h = 1e-4 s:
    * Euler-Bernoulli vs. the element's rotary inertia: (pi r/L)^2 = 8e-5
      shifts w_1 by 4e-5, i.e. 1.2e-3 rad of phase over the crossing on the
      dynamic part: ~1.5e-4 (measured: the Rayleigh series removes it);
    * Newmark: (w_j h)^2/12 period error, and the higher modes (w h ~ 1 for
      j >= 10) distorted: measured 2.2e-4 against the Rayleigh series,
      1.0e-4 at h = 5e-5 s;
    * mesh (20 cubic elements: w_1 error ~1e-8) and series truncation
      (200 modes: the static part converges as j^-4): negligible.
    Tolerances: 1e-3 against Euler-Bernoulli (measured 3.7e-4), 5e-4
    against the Rayleigh series (measured 2.2e-4).
    """
    L, b, h, N, v, F = 1.0, 0.05, 0.01, 20, 5.0, 100.0
    sy = cl.assemble(cl.loads_model(moving_load_text(L, b, h, N, v, F)))
    sim = simulate(
        sy,
        feedback="none",
        width=1.0,
        outputs=["mid.y"],
        integration=Integration(duration=L / v, step=0.0001),
    )
    assert sim.status == "ok"
    assert sim.meta["coefficients"] == "polynomial"
    t, y = sim.t, sim.data["mid.y"]
    E, A, I, rho = 2.1e11, b * h, b * h**3 / 12, 7850.0
    w_eb = -fryba(L / 2, t, L=L, EI=E * I, rhoA=rho * A, v=v, F=F)
    w_r = -fryba(L / 2, t, L=L, EI=E * I, rhoA=rho * A, v=v, F=F, r2=I / A)
    scale = np.abs(w_eb).max()
    assert scale == pytest.approx(2.571e-3, rel=1e-3)  # 1.08 x the static F L^3/(48 EI)
    err_eb = np.abs(y - w_eb).max() / scale
    err_r = np.abs(y - w_r).max() / scale
    assert err_eb < 1e-3, err_eb
    assert err_r < 5e-4, err_r
    # the force really travels: under the load at t the beam deflects most near x = v t
    assert np.argmin(y) > 0.3 * t.size


def test_moving_force_direct_path_agrees():
    """The direct (per-step low-rank) evaluation gives the same history as
    the per-segment polynomials, to rounding."""
    sy = cl.assemble(cl.loads_model(moving_load_text(1.0, 0.05, 0.01, 8, 5.0, 100.0)))
    kw = dict(feedback="none", width=1.0, outputs=["mid.y"])
    a = simulate(sy, **kw, integration=Integration(duration=0.05, step=2e-4, method="polynomial")).data[
        "mid.y"
    ]
    b = simulate(sy, **kw, integration=Integration(duration=0.05, step=2e-4, method="direct")).data["mid.y"]
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-11 * np.abs(b).max())


def test_ce_feedback_on_a_moving_contact_equals_a_travelling_spring_damper():
    """The CE terms of Eq. 2.27 with a moving contact, J_i^T D_P J_i,
    J_i^T D_V J_i (q_i') and J_i^T D_V dJ_i/dt (q_i), against the same
    spring-damper written as a structural [[spring]] between the contact and
    the carriage (its damping enters Eqs. 2.17-2.18 through L and W', checked
    above against the brute-force projection).  The two code paths must give
    the same history to rounding; without the dJ_i/dt term they would differ
    by ~10 % (v W' ~ 15 w against q' ~ 150 w at 5 m/s)."""
    base = moving_load_text(1.0, 0.05, 0.01, 10, 5.0, 100.0).replace(
        "centre = [0.0, 0.5]", "centre = [0.0, 0.0]"
    )
    load = base[base.index("[[coupling]]") : base.index("[process]")]
    c, d = 2.0e5, 80.0
    spring = f"""
[[spring]]
id = "dash"
a = "wheel"
b = "carriage"
c1 = {c!r}
c2 = {c!r}
d1 = {d!r}
d2 = {d!r}
"""
    coupling = f"""
[[coupling]]
id = "load"
a = "wheel"
b = "carriage"
model = "matrices"
width_ref = 1.0
forces = [0.0, -100.0, 0.0]
DP = [[{c!r}, 0.0, 0.0], [0.0, {c!r}, 0.0], [0.0, 0.0, 0.0]]
DV = [[{d!r}, 0.0, 0.0], [0.0, {d!r}, 0.0], [0.0, 0.0, 0.0]]
"""
    text_a = base.replace(load, load.replace('b = "ground"', 'b = "carriage"') + spring)
    text_b = base.replace(load, coupling)
    kw = dict(width=1.0, outputs=["mid.y", "wheel.y"], integration=Integration(duration=0.2, step=1e-4))
    a = simulate(cl.assemble(cl.loads_model(text_a)), feedback="none", **kw)
    b = simulate(cl.assemble(cl.loads_model(text_b)), feedback="pd", **kw)
    for name in ("mid.y", "wheel.y"):
        scale = np.abs(a.data[name]).max()
        np.testing.assert_allclose(b.data[name], a.data[name], rtol=0, atol=1e-9 * scale)
    # the same without the dJ/dt term (the damper seen as moving with the beam)
    sy_b = cl.assemble(cl.loads_model(text_b))
    kin = kinematics_for(sy_b.model.process)
    pb = ParametricProblem(sy_b, kin, width=1.0, terms="pd", method="direct")
    tt = np.array([0.05, 0.1, 0.15])
    parts = pb._parts_direct(kin.state(tt)[0])
    assert np.abs(parts["Cce1"]).max() > 1e-3 * np.abs(parts["Cce0"]).max()


# ----------------------------------------------------------------------------- harmonic force

HARMONIC = """
[model]
name = "three masses"
[matrices]
coordinates = ["x1", "x2", "x3"]
M = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.5]]
K = [[3.0e5, -1.0e5, 0.0], [-1.0e5, 2.0e5, -1.0e5], [0.0, -1.0e5, 1.5e5]]
L = [[60.0, -10.0, 0.0], [-10.0, 40.0, -10.0], [0.0, -10.0, 30.0]]
"""


@pytest.mark.parametrize("f_hz, h", [(40.0, 1e-4), (40.0, 2e-3), (63.0, 1e-3), (120.0, 2.5e-3)])
def test_harmonic_steady_state_equals_frf(f_hz, h):
    """Steady state under F sin(w t) equals |G(j w~)| with w~ = (2/h) tan(w h/2).

    The average-acceleration Newmark scheme is the trapezoidal rule on the
    first-order form, i.e. the bilinear map s = (2/h)(z - 1)/(z + 1): a
    sampled sine of frequency w is answered exactly as the continuous system
    answers w~ (the frequency warping; equivalently the free period
    elongation w h/(2 atan(w h/2))).  So amplitude and phase equal those of
    the FRF at w~ to rounding (tolerance 1e-7, the transient having decayed
    by e^-20 at least), and differ from the FRF at w by the warping.
    """
    from chatterlab.frequency._frf import frf

    fz = cl.assemble(cl.loads_model(HARMONIC)).at(None)
    w = 2 * math.pi * f_hz
    row_in = fz.dof("x2")
    row_out = fz.dof("x3")
    prob = ConstantProblem(fz.A, fz.B, fz.C, force=lambda t: np.outer(np.sin(w * t), row_in))
    # slowest decay: the least damped mode
    lam = np.linalg.eigvals(
        np.block(
            [[np.zeros((3, 3)), np.eye(3)], [-np.linalg.solve(fz.A, fz.C), -np.linalg.solve(fz.A, fz.B)]]
        )
    )
    t_settle = 20.0 / np.min(-lam.real)
    t_end = t_settle + 10 * 2 * math.pi / w
    r = newmark(prob, (0.0, t_end), h, outputs=row_out[None, :])
    sel = r.t > t_settle
    X = np.column_stack([np.sin(w * r.t[sel]), np.cos(w * r.t[sel])])
    c, *_ = np.linalg.lstsq(X, r.q[0, sel], rcond=None)
    got = complex(c[0], c[1])
    wt = (2.0 / h) * math.tan(w * h / 2.0)
    G = frf(fz, np.array([w, wt]), inputs="x2", outputs="x3").data[0, 0]
    # x(t) = |G| sin(w t + arg G) = Im(G e^{j w t}) -> sin coefficient Re G, cos coefficient Im G
    np.testing.assert_allclose(got, G[1], rtol=1e-7)
    warp = abs(abs(G[1]) / abs(G[0]) - 1.0)
    if (w * h) ** 2 / 12 > 1e-3:
        assert abs(abs(got) / abs(G[0]) - 1.0) > 0.5 * warp > 1e-4


# ----------------------------------------------------------------------------- regenerative 1-DOF


def discrete_root(fz, fb, lam: complex, h: float, N: int) -> complex:
    """The root z of the Newmark (trapezoidal) characteristic equation of
    A q'' + (B - D_V) q' + (C - D_P) q = D_O q(t - N h) near e^{lam h}:
    det(s~^2 A + s~ (B - D_V) + C - D_P - D_O z^-N) = 0, s~ = (2/h)(z-1)/(z+1).
    Returns the equivalent continuous root log(z)/h."""

    def f(z: complex) -> complex:
        s = (2.0 / h) * (z - 1.0) / (z + 1.0)
        return complex(np.linalg.det(s * s * fz.A + s * (fz.B - fb.DV) + fz.C - fb.DP - fb.DO * z ** (-N)))

    z = complex(np.exp(lam * h))
    for _ in range(60):
        d = 1e-7 * abs(z)
        dz = -f(z) / ((f(z + d) - f(z - d)) / (2 * d))
        z += dz
        if abs(dz) < 1e-15 * abs(z):
            break
    return complex(np.log(z) / h)


@pytest.fixture(scope="module")
def boundary(turning):
    from chatterlab.lobes._diagram import lobes

    fz = turning.at(None)
    ld = lobes(fz, np.array([3000.0]), width_max=0.01)
    b_lim = float(ld.b_lim[0])
    # the classical boundary of this tool at 3000 rpm lies above 2 k zeta (1 + zeta)/Kf = 0.31 mm
    assert 0.31e-3 < b_lim < 0.5e-3
    return fz, b_lim


@pytest.mark.parametrize("factor", [0.8, 1.2])
def test_growth_rate_equals_rightmost_root(turning, boundary, factor):
    """Envelope growth of a long simulate(..., delay=T) run = Re of the
    rightmost characteristic root, on both sides of b_lim.

    Two oracles: (i) the exact root of the discrete scheme (Tustin map with
    the delay z^-N exact, N = T/h): the measured rate matches it to 2e-3 1/s
    (the extrema envelope of one dominant root; measured < 5e-4);
    (ii) the continuous root: the scheme moves it by O(h^2) -- 0.21 1/s at
    h = T/1000 and 0.05 1/s at T/2000, ratio 4 -- and the Richardson value
    (4 sigma(h/2) - sigma(h))/3 matches it to 0.01 1/s (measured 5e-4).
    """
    from chatterlab.frequency._stability import stability
    from chatterlab.process import closed_loop as feedback

    fz, b_lim = boundary
    T = 0.02
    b = factor * b_lim
    st = stability(fz, width=b, delay=T)
    assert st.verdict == ("stable" if factor < 1 else "unstable")
    lam = complex(st.roots.roots[0])
    fb = feedback(fz, width=b, delay=T)
    rates = []
    for N in (1000, 2000):
        h = T / N
        sim = simulate(
            turning,
            feedback="pdo",
            width=b,
            delay=T,
            outputs=["tip.x"],
            integration=Integration(duration=1.0, step=h),
        )
        g = sim.growth("tip.x", skip=0.2)
        assert g.r2 > 0.999
        assert g.classification == ("decaying" if factor < 1 else "growing")
        lam_h = discrete_root(fz, fb, lam, h, N)
        assert abs(g.rate - lam_h.real) < 2e-3, (g.rate, lam_h.real)
        rates.append(g.rate)
    e1, e2 = rates[0] - lam.real, rates[1] - lam.real
    assert 3.5 < e1 / e2 < 4.5
    assert abs(e1) < 0.3
    richardson = (4 * rates[1] - rates[0]) / 3
    assert abs(richardson - lam.real) < 0.01


def test_trajectory_matches_method_of_steps(turning, boundary):
    """Against scipy's DOP853 (rtol 1e-11) with the method of steps: on
    each delay interval the delayed term is the previous interval's dense
    output.  Tool at 1.2 b_lim, static force switched on at t = 0, zero
    history, three delays (32 oscillations at 533 Hz).

    Newmark's phase error of the 533 Hz oscillation is (w h)^2/12 w t:
    0.019 rad at h = T/2000 after 3T; on the response (static part
    included) the measured error is 2.0e-3 of max |x|, and halving h
    divides it by 4 (second order).  Tolerance 5e-3 and a ratio in [3.5, 4.5].
    """
    from scipy.integrate import solve_ivp

    fz, b_lim = boundary
    T, b = 0.02, 1.2 * b_lim
    m, c, k = float(fz.A[0, 0]), float(fz.B[0, 0]), float(fz.C[0, 0])
    Kb = 2.0e9 * b
    F0 = 200.0 * b / 0.001
    sols: list = []
    y0 = [0.0, 0.0]
    for j in range(3):
        prev = sols[-1] if sols else None

        def rhs(t, y, prev=prev):
            xd = prev.sol(t - T)[0] if prev is not None else 0.0
            return [y[1], (F0 - c * y[1] - (k + Kb) * y[0] + Kb * xd) / m]

        s = solve_ivp(
            rhs, (j * T, (j + 1) * T), y0, method="DOP853", rtol=1e-11, atol=1e-16, dense_output=True
        )
        sols.append(s)
        y0 = s.y[:, -1]

    def ref(t: np.ndarray) -> np.ndarray:
        idx = np.minimum((t / T).astype(int), 2)
        return np.array([sols[i].sol(ti)[0] for i, ti in zip(idx, t, strict=True)])

    errs = []
    for N in (1000, 2000):
        sim = simulate(
            turning,
            feedback="pdo",
            width=b,
            delay=T,
            outputs=["tip.x"],
            integration=Integration(duration=3 * T, step=T / N),
        )
        x, r = sim.data["tip.x"], ref(sim.t)
        errs.append(np.abs(x - r).max() / np.abs(r).max())
    assert errs[1] < 5e-3, errs
    assert 3.5 < errs[0] / errs[1] < 4.5, errs
    # the CE's relative displacement is the tool displacement (b = ground)
    np.testing.assert_allclose(sim.data["cut.1"], sim.data["tip.x"], rtol=0, atol=1e-18)


def test_static_deflection_under_the_desired_force(turning):
    """Without the delayed term the tool settles at F0/(k + D_P) (case b),
    F0/k without feedback (case a)."""
    b, T = 0.3e-3, 0.02
    F0 = 200.0 * b / 0.001
    for fb, stiff in (("none", 1.0e7), ("pd", 1.0e7 + 2.0e9 * b)):
        sim = simulate(
            turning,
            feedback=fb,
            width=b,
            delay=T,
            outputs=["tip.x"],
            integration=Integration(duration=0.4, step=T / 200),
        )
        assert sim.data["tip.x"][-1] == pytest.approx(F0 / stiff, rel=1e-6)


# ----------------------------------------------------------------------------- reductions


def _stroke_positions(sy) -> np.ndarray:
    lo, hi = sy.model.movable.range
    s = np.linspace(lo, hi, 241)
    # every joint and track end of both contacts, exactly
    joints = []
    for c in sy._contacts:
        for x in [e.start for e in c.elements] + [c.track_length]:
            sj = c.s_ref + (x - c.x_ref) / c.rate
            if lo <= sj <= hi:
                joints.append(sj)
    return np.unique(np.concatenate([s, joints]))


def _with_contact_mass(sy):
    """The shaper with mass on the contact coordinates (not expressible in a
    model file: a contact is massless), so that the inertia terms
    2 (M_id + W^T M_dd) W' and (M_id + W^T M_dd) W'' of Eqs. 2.17-2.18 are
    non-zero."""
    M = np.array(sy.M)
    for name, m in (("rfe5", 3.0), ("rfe6", 5.0)):
        for a, val in (("x", m), ("y", m), ("rz", 0.01 * m)):
            M[sy.index[f"{name}.{a}"], sy.index[f"{name}.{a}"]] += val
    k5, k6 = sy.index["rfe5.x"], sy.index["rfe6.y"]
    M[k5, k6] = M[k6, k5] = 0.5  # and a coupling between the two contacts
    M.setflags(write=False)
    return dataclasses.replace(sy, M=M)


@pytest.mark.parametrize("variant", ["damper", "contact-mass"])
def test_fast_reduction_equals_eq_2_6_path(shaper_damped, variant):
    """MovingReduction (contact rows of W as beam point maps, low-rank
    updates) = Eq. 2.6 for W, W', W'' followed by Eqs. 2.16-2.18, along the
    whole stroke (every joint and track end included) for the work and the
    return speed; the speed-dependent parts compared on their own scale."""
    sy = shaper_damped if variant == "damper" else _with_contact_mass(shaper_damped)
    fr = MovingReduction(sy)
    assert fr.ok
    s = _stroke_positions(sy)
    W0, W1, W2 = sy.W_derivatives(s)
    for v in (-0.5, 2.0):
        A, B, C, R0, R1 = fr.reduce(s, np.full(s.size, v))
        A2, B2, C2 = sy.reduced_matrices(W0, W1 * v, W2 * v * v)
        As, Bs, Cs = sy.reduced_matrices(W0, 0 * W1, 0 * W2)  # the speed-independent parts
        for X, Y, Z in ((A, A2, As), (B, B2, Bs), (C, C2, Cs)):
            np.testing.assert_allclose(X, Y, rtol=0, atol=1e-12 * np.abs(Y).max())
            dY = Y - Z
            if np.any(dY):
                np.testing.assert_allclose(X - Z, dY, rtol=0, atol=1e-9 * np.abs(dY).max())
        # the speed terms are really there
        assert np.abs(C2 - Cs).max() > 1e-9 * np.abs(Cs).max()
        if variant == "contact-mass":
            assert np.abs(B2 - Bs).max() > 1.0  # 2 (M_id + W^T M_dd) W' v: ~10 N s/m
        np.testing.assert_allclose(R0, W0[:, fr.pos_v], rtol=0, atol=1e-13)
        np.testing.assert_allclose(R1, v * W1[:, fr.pos_v], rtol=0, atol=1e-12)


def test_reduction_equals_the_projection_of_the_decoupled_system(shaper_damped):
    """Eqs. 2.16-2.18 are T^T (M T'' + L T' + K T) for q = T(t) q_i,
    T = [I; W]: A* = T^T M T, B* = T^T L T + 2 T^T M dT/dt,
    C* = T^T K T + T^T L dT/dt + T^T M d2T/dt2 -- built here by brute force
    over all coordinates (given ones dropped), on the model with contact mass."""
    sy = _with_contact_mass(shaper_damped)
    s = np.array([0.57, 0.7, 0.85, 1.05, 1.13])
    v = -0.5
    W0, W1, W2 = sy.W_derivatives(s)
    A, B, C = sy.reduced_matrices(W0, W1 * v, W2 * v * v)
    ni = len(sy.i)
    for k in range(s.size):
        T = np.zeros((sy.n, ni))
        T[sy.i, np.arange(ni)] = 1.0
        T[sy.d] = W0[k]
        Td = np.zeros_like(T)
        Td[sy.d] = W1[k] * v
        Tdd = np.zeros_like(T)
        Tdd[sy.d] = W2[k] * v * v
        np.testing.assert_allclose(A[k], T.T @ sy.M @ T, atol=1e-10 * np.abs(A[k]).max())
        np.testing.assert_allclose(
            B[k], T.T @ sy.L @ T + 2 * T.T @ sy.M @ Td, atol=1e-10 * np.abs(B[k]).max()
        )
        np.testing.assert_allclose(
            C[k], T.T @ sy.K @ T + T.T @ sy.L @ Td + T.T @ sy.M @ Tdd, atol=1e-10 * np.abs(C[k]).max()
        )


def test_W_derivatives_equal_finite_differences(shaper):
    """W' and W'' from the differentiated constraints (Eq. 2.6 and its
    derivatives) equal central differences of W.  Inside an element W is a
    cubic in s, so the second difference is exact and the first has the
    error delta^2 W'''/6: with delta = 1e-3 m the tolerances are set by
    rounding (eps |W| / delta^2 ~ 1e-10 |W|) and by that term (1e-6 |W'|)."""
    d = 1e-3
    s = np.array([0.57, 0.63, 0.72, 0.81, 0.93, 1.02, 1.08, 1.13])
    W0, W1, W2 = shaper.W_derivatives(s)
    Wp, Wm = shaper.W_derivatives(s + d)[0], shaper.W_derivatives(s - d)[0]
    np.testing.assert_allclose(W1, (Wp - Wm) / (2 * d), rtol=0, atol=1e-6 * np.abs(W1).max())
    np.testing.assert_allclose(W2, (Wp - 2 * W0 + Wm) / d**2, rtol=0, atol=1e-6 * np.abs(W2).max())
    assert np.abs(W2).max() > 0


@pytest.mark.parametrize("terms", ["none", "pd", "pdo"])
def test_polynomial_coefficients_equal_the_direct_ones(shaper_damped, terms):
    """The per-segment polynomials of ParametricProblem equal the direct
    evaluation at every step of two stroke cycles, left limits at the
    events included (relative 1e-10 of each matrix)."""
    kin = kinematics_for(shaper_damped.model.process)
    sy = _with_contact_mass(shaper_damped)
    pp = ParametricProblem(sy, kin, width=0.003, terms=terms, method="polynomial")
    pd = ParametricProblem(sy, kin, width=0.003, terms=terms, method="direct")
    # the generic path (Eq. 2.6 for W, W', W'' at every step), used when constraints tie
    # other coordinates to a contact: checked on a few hundred steps
    pg = ParametricProblem(sy, kin, width=0.003, terms=terms, method="generic")
    tg = kin.grid_unit / 7 * np.arange(1, 106)
    for X, Y in zip(pg.matrices(tg), pd.matrices(tg), strict=True):
        if Y is None:
            assert X is None
            continue
        np.testing.assert_allclose(X, Y, rtol=0, atol=1e-10 * np.abs(Y).max())
    np.testing.assert_allclose(
        pg.force(tg), pd.force(tg), rtol=0, atol=1e-10 * np.abs(pd.force(tg)).max() + 1e-300
    )
    h = kin.grid_unit / 37
    t = h * np.arange(1, int(2 * kin.cycle / h) + 1)
    ev = np.array(kin.breakpoints(2 * kin.cycle))
    t = np.sort(np.concatenate([t, ev - 1e-9 * h]))
    for j0 in range(0, t.size, 1500):
        tt = t[j0 : j0 + 1500]
        Ma, Md = pp.matrices(tt), pd.matrices(tt)
        for X, Y in zip(Ma, Md, strict=True):
            if Y is None:
                assert X is None
                continue
            np.testing.assert_allclose(X, Y, rtol=0, atol=1e-10 * max(np.abs(Y).max(), 1e-300))
        Fa, Fd = pp.force(tt), pd.force(tt)
        np.testing.assert_allclose(Fa, Fd, rtol=0, atol=1e-10 * max(np.abs(Fd).max(), 1e-300))
    assert pp.method_used == {"polynomial"}
    assert len(pp.poly.segments) >= 4  # rfe5: before/on/after the workpiece, rfe6: two shear elements


def test_first_pass_of_case_c_equals_case_b(shaper):
    """With a zero history the delayed term is zero during the first stroke
    cycle, so case (c) repeats case (b) there; they part on the second pass."""
    kw = dict(integration=Integration(duration=1.75, step=1.5 / 3000))
    b = simulate(shaper, feedback="pd", **kw)
    c = simulate(shaper, feedback="pdo", **kw)
    first = b.t < 1.5 - 1e-9
    x_b, x_c = b.data["rfe5.y"], c.data["rfe5.y"]
    np.testing.assert_allclose(x_c[first], x_b[first], rtol=0, atol=1e-12 * np.abs(x_b).max())
    second = b.in_cut & (b.t > 1.5)
    assert np.abs(x_c[second] - x_b[second]).max() > 1e-3 * np.abs(x_b[second]).max()


# ----------------------------------------------------------------------------- outputs


def test_outputs_and_files(turning, tmp_path):
    sim = simulate(
        turning,
        feedback="pdo",
        width=0.0003,
        delay=0.02,
        outputs=["tip.x", "tool.rz"],
        integration=Integration(duration=0.05, step=0.0001),
    )
    assert list(sim.data) == ["tip.x", "tool.rz", "cut.1", "cut.2"]
    assert sim.units["tool.rz"] == "rad" and sim.units["tip.x"] == "m"
    assert np.all(sim.data["tool.rz"] == 0.0)  # held by the support
    sim.to_csv(tmp_path / "a.csv")
    rows = (tmp_path / "a.csv").read_text().splitlines()
    assert len(rows) == sim.t.size + 1 and rows[0].startswith("t [s],position [m],in_cut")
    # round-trip exact: every number is the shortest decimal of its double
    cols = np.loadtxt(tmp_path / "a.csv", delimiter=",", skiprows=1, usecols=range(8))
    np.testing.assert_array_equal(cols[:, 0], sim.t)
    np.testing.assert_array_equal(cols[:, 4], sim.data["tip.x"])
    assert rows[0].endswith(",status") and rows[-1].endswith(",ok")
    from chatterlab.io import read_dataset

    ds = read_dataset(sim.to_netcdf(str(tmp_path / "a.nc")))
    np.testing.assert_array_equal(ds["tip_x"].values, sim.data["tip.x"])
    assert ds["tip_x"].attrs["long_name"] == "tip.x" and ds["tool_rz"].attrs["units"] == "rad"
    assert ds.attrs["status"] == "ok" and ds.attrs["feedback"] == "pdo"
    f_hz, amp = sim.spectrum("tip.x", window="all")
    assert f_hz[0] == 0 and amp.shape == f_hz.shape


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(delay=0.001, step=0.01), "larger than the delay"),
        (dict(duration=-1.0), "duration must be > 0"),
        (dict(duration=0.0), "duration must be > 0"),
        (dict(step=0.0), "step must be > 0"),
        (dict(step=-1e-5), "step must be > 0"),
        (dict(step=float("nan")), "step must be > 0"),
        (dict(duration=0.01, step=0.02, feedback="pd"), "longer than the duration"),
        (dict(outputs=["nope.x"]), "unknown point 'nope'"),
        (dict(outputs=["tip.q"]), "not POINT.DIR"),
        (dict(width=-1.0), "width must be > 0"),
        (dict(width=0.0), "width must be > 0"),
        (dict(feedback="pid"), "feedback must be one of"),
        (dict(passes=0), "periods must be > 0"),
        (dict(passes=-1.5), "periods must be > 0"),
        (dict(speed=-1.0), "speed must be > 0 rpm"),
        (
            dict(delay=10.0, step=1e-6, duration=1e-3, options=NewmarkOptions(max_history_bytes=10**6)),
            "max_history_bytes",
        ),
    ],
)
def test_bad_input_is_one_clear_error(turning, kw, match):
    moved = {"duration": "duration", "step": "step", "passes": "periods", "options": "scheme"}
    integration = {moved[k]: kw.pop(k) for k in list(kw) if k in moved}
    with pytest.raises(InputError, match=match):
        simulate(turning, **kw, integration=Integration(**integration))


def test_unknown_output_is_refused_before_the_run(turning, monkeypatch):
    import sys

    sm = sys.modules["chatterlab.time._simulate"]

    def boom(*a, **k):  # pragma: no cover - must not be reached
        raise AssertionError("integrated before checking the outputs")

    monkeypatch.setattr(sm, "newmark", boom)
    with pytest.raises(InputError, match="unknown point"):
        simulate(turning, outputs=["nope.x"], integration=Integration(duration=1.0))


def test_stroke_outside_the_movable_range(shaper_path):
    m = cl.load_model(shaper_path)
    sy = cl.assemble(m)
    with pytest.raises(InputError, match="outside the movable range|movable range"):
        simulate(sy, position=2.0, integration=Integration(duration=0.01))


@pytest.mark.parametrize(
    "args, match",
    [
        (["--step", "0"], "step must be > 0"),
        (["--step=-1e-4"], "step must be > 0"),
        (["--duration", "-1"], "duration must be > 0"),
        (["--passes", "0"], "passes must be >= 1"),
        (["--output", "nope.x", "--duration", "0.01"], "unknown point"),
        (["--speed=-3000"], "speed must be > 0"),
        (["--delay", "0.001", "--step", "0.01"], "larger than the delay"),
        (["--delay", "1000", "--step", "1e-6", "--duration", "1e-3"], "max_history_bytes"),
    ],
)
def test_cli_exits_2_with_one_line(capsys, tmp_path, args, match):
    path = tmp_path / "turning.toml"
    path.write_text(TURNING)
    code = main(["simulate", str(path), "--quiet", *args])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("chatterlab: error:") and match in lines[0]


def test_the_0_2_keywords_still_work_and_warn(turning):
    """The keywords of 0.2 go into the option objects (one release, with a
    DeprecationWarning that names the new form): the same run, bit for bit."""
    with pytest.warns(DeprecationWarning, match=r"duration= -> integration=Integration\(duration=...\)"):
        old = simulate(
            turning, width=2e-4, delay=0.01, duration=0.05, step=1e-4, q0={"tool.x": 1e-6}, forces=False
        )
    new = simulate(
        turning, width=2e-4, delay=0.01, integration=Integration(duration=0.05, step=1e-4),
        initial=Initial(q0={"tool.x": 1e-6}), excitation=Excitation(cutting_forces=False),
    )  # fmt: skip
    np.testing.assert_array_equal(old.data["tool.x"], new.data["tool.x"])
    assert old.meta == new.meta
    with pytest.raises(TypeError, match="unexpected keyword argument 'durations'"):
        simulate(turning, durations=1.0)
    with pytest.raises(InputError, match="integration must be a Integration"):
        simulate(turning, integration=NewmarkOptions())


def test_the_parametric_problem_is_a_value(shaper):
    """Its span is given when it is built (was written into its private
    attribute by simulate); nothing sets an attribute afterwards."""
    kin = kinematics_for(shaper.model.process)
    p = ParametricProblem(shaper, kin, width=0.002, t_end=2 * kin.cycle)
    assert p.breakpoints() == tuple(kin.breakpoints(2 * kin.cycle))
    assert ParametricProblem(shaper, kin, width=0.002).breakpoints() == ()
    with pytest.raises(AttributeError, match="immutable"):
        p.t_end = 1.0
