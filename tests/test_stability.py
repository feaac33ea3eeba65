"""Stability verdicts (chatterlab.frequency._stability: characteristic roots + argument
principle) against closed forms.

Oracles:

* the 1-DOF regenerative turning tool m x'' + c x' + k x = -K_f b (x - x(t-T)),
  whose stability boundary is Tlusty's: for w above w_n,
  b_lim(w) = -1/(2 K_f Re G(jw)), G = 1/(k - m w^2 + j c w), on the delays
  T = (eps(w) + 2 pi k)/w, eps = 3 pi + 2 arg G(jw) (k = 0, 1, ...);
  the boundary at one T is the smallest of these widths (computed here
  independently with scipy's brentq);
* the delay-free cases, whose roots are those of a quadratic;
* for random structures with a rank-1 regenerative coupling
  (D_P = K_f b f n^T, D_O = -D_P), the generalisation of Tlusty's bound: no
  width below b_min = -1/(2 K_f min_w Re[n^T H(jw) f]) (H the CE
  receptance) can be unstable, whatever T; and the two routes of stability()
  must agree.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import turning_text as _turning_text
from hypothesis import HealthCheck, assume, event, given, note, settings
from hypothesis import strategies as st
from scipy.optimize import brentq, minimize_scalar

import chatterlab as cl
from chatterlab.frequency._stability import MARGINAL_TOL, Stability, stability
from chatterlab.process import closed_loop

M, K, ZETA, KF = 1.0, 1.0e7, 0.03, 2.0e9
C = float(2 * ZETA * np.sqrt(K * M))
WN = float(np.sqrt(K / M))


def turning_text(rpm: float = 3000.0) -> str:
    """docs/model-format.md's 1-DOF turning tool (m = 1 kg, k = 1e7 N/m,
    zeta = 3 %, K_f = 2e9 N/m^2)."""
    return _turning_text(mass=M, stiffness=K, damping=C, Kf=KF, rpm=rpm)


def G(w: float | np.ndarray) -> complex | np.ndarray:
    return 1.0 / (K - M * w**2 + 1j * C * w)


def tlusty(T: float, kmax: int = 60) -> tuple[float, float, int]:
    """(b_lim, w_c, k) of the 1-DOF tool at delay T: the smallest width over
    the lobes k whose phase condition w T = eps(w) + 2 pi k has a root
    above w_n (there Re G < 0; eps falls from 2 pi to pi while w T rises,
    so the root is unique and bracketed by [w_n, 2 pi (k + 1)/T])."""

    def eps(w: float) -> float:
        return 3 * np.pi + 2 * float(np.angle(G(w)))

    best = (np.inf, np.nan, -1)
    k0 = max(0, int(np.ceil(WN * T / (2 * np.pi) - 1)))
    for k in range(k0, k0 + kmax):
        lo, hi = WN * (1 + 1e-13), 2 * np.pi * (k + 1) / T + 1.0
        if lo * T - eps(lo) - 2 * np.pi * k >= 0:
            continue
        w = brentq(lambda x, k=k: x * T - eps(x) - 2 * np.pi * k, lo, hi, xtol=1e-15 * hi, rtol=1e-15)
        b = -1.0 / (2 * KF * float(np.real(G(w))))
        if b < best[0]:
            best = (b, w, k)
    return best


@pytest.fixture(scope="module")
def turning() -> cl.FrozenSystem:
    return cl.assemble(cl.loads_model(turning_text())).at()


# ----------------------------------------------------------------------------- the Tlusty boundary


@pytest.mark.parametrize("rpm", [1500.0, 3000.0, 7000.0, 12000.0])
def test_root_on_the_axis_at_the_tlusty_boundary(turning, rpm):
    """At b = b_lim and T = 60/n the rightmost root is j w_c.  b_lim and w_c
    come from brentq to ~1e-15; the root is simple, and Newton-refined roots
    are exact to ~1e-13 relative, so |Re lambda| <= 1e-9 w_c and
    |Im lambda - w_c| <= 1e-9 w_c leave a wide margin (measured
    |Re lambda| <= 1.2e-13 1/s, i.e. 4e-17 w_c; Im to 4e-16).  The verdict
    is "marginal" (|Re| below MARGINAL_TOL |lambda|)."""
    T = 60.0 / rpm
    b, wc, k = tlusty(T)
    assert np.isfinite(b) and b > 2 * K * ZETA * (1 + ZETA) / KF * (1 - 1e-12)
    s = stability(turning, width=b, speed=rpm)
    lam = s.roots.roots[0]
    assert abs(lam.real) <= 1e-9 * wc
    assert abs(lam.imag - wc) <= 1e-9 * wc
    assert s.verdict == "marginal"
    assert s.chatter_hz == pytest.approx(wc / (2 * np.pi), rel=1e-9)
    assert s.delay == pytest.approx(T, rel=1e-15)
    # the other roots are strictly stable
    assert np.all(s.roots.roots[1:].real < -1e-3)


@pytest.mark.parametrize("rpm", [1500.0, 3000.0, 7000.0, 12000.0])
@pytest.mark.parametrize("factor, expected", [(0.9, "stable"), (1.1, "unstable")])
def test_ten_percent_inside_and_outside_the_boundary(turning, rpm, factor, expected):
    """0.9 b_lim stable, 1.1 b_lim unstable, and the argument principle
    agrees with the roots (its count: 0, resp. one conjugate pair = 2)."""
    b, wc, _ = tlusty(60.0 / rpm)
    s = stability(turning, width=factor * b, speed=rpm)
    assert s.verdict == expected, s.message
    assert s.agree is True, s.message
    assert s.winding.count == (0 if expected == "stable" else 2)
    # the rightmost root stays close to the boundary frequency
    assert abs(s.chatter_hz - wc / (2 * np.pi)) < 0.05 * wc / (2 * np.pi)
    assert (s.abscissa < 0) == (expected == "stable")


def test_absolute_minimum_width_is_unconditionally_stable(turning):
    """Below 2 k zeta (1 + zeta)/K_f (0.309 mm) no delay gives chatter: 0.98
    of it is stable at delays spread over several lobes."""
    b = 0.98 * 2 * K * ZETA * (1 + ZETA) / KF
    for T in (0.004, 0.0117, 0.02, 0.0431):
        s = stability(turning, width=b, delay=T)
        assert s.verdict == "stable" and s.agree is True, s.message


# ----------------------------------------------------------------------------- delay-free cases


def test_no_feedback_gives_the_structural_roots(turning):
    """terms="none": the roots of m s^2 + c s + k, -zeta w_n + j w_n sqrt(1 - zeta^2)
    (1e-12 relative: a 2 x 2 eigenproblem)."""
    s = stability(turning, width=1e-3, delay=0.02, terms="none")
    ref = -ZETA * WN + 1j * WN * np.sqrt(1 - ZETA**2)
    assert s.roots.roots[0] == pytest.approx(ref, rel=1e-12)
    assert s.verdict == "stable" and s.delay is None


def test_proportional_feedback_stiffens(turning):
    """terms="pd" with the regenerative preset: D_P only, m s^2 + c s + k + K_f b."""
    b = 0.5e-3
    s = stability(turning, width=b, delay=0.02, terms="pd")
    k2 = K + KF * b
    ref = -C / (2 * M) + 1j * np.sqrt(k2 / M - (C / (2 * M)) ** 2)
    assert s.roots.roots[0] == pytest.approx(ref, rel=1e-12)
    assert s.verdict == "stable" and s.agree is True


def test_shaper_case_b_is_stable_and_both_routes_agree(shaper_path):
    """The paper's case (b) (P + D, no delay) at b = 2 mm: stable (the
    derivative terms K1, K6 add damping), roots and argument principle agree."""
    fz = cl.assemble(cl.load_model(shaper_path)).at()
    s = stability(fz, width=0.002, speed=0.5, terms="pd")
    assert s.verdict == "stable" and s.agree is True, s.message
    assert -1.0 < s.abscissa < 0.0  # measured -0.106 1/s: lightly damped
    assert isinstance(s, Stability)
    d = s.to_dict()
    assert d["verdict"] == "stable" and d["terms"] == "pd" and len(d["roots"]) == len(s.roots.roots)
    assert "verdict: stable" in s.table()


# ----------------------------------------------------------------------------- property-based


def random_structure_text(p: dict) -> str:
    """One or two rigid bodies on springs, a regenerative CE from a point on
    the last body to the ground, force and normal at arbitrary angles."""
    text = f"""
[[body]]
id = "a"
mass = {p["m1"]!r}
inertia = {p["J1"]!r}
centre = [0.0, 0.0]
[[spring]]
id = "base"
a = {{ body = "a", offset = [{p["ox"]!r}, -0.05] }}
b = "ground"
c1 = {p["k1"]!r}
c2 = {p["k2"]!r}
c6 = {p["k6"]!r}
d1 = {p["d1"]!r}
d2 = {p["d2"]!r}
d6 = {p["d6"]!r}
angle_deg = {p["sa"]!r}
"""
    tip = "a"
    if p["two"]:
        tip = "b"
        text += f"""
[[body]]
id = "b"
mass = {p["m2"]!r}
inertia = {p["J2"]!r}
centre = [0.1, 0.0]
[[spring]]
id = "joint"
a = {{ body = "a", offset = [0.05, 0.0] }}
b = {{ body = "b", offset = [-0.05, 0.0] }}
c1 = {p["kj"]!r}
c2 = {p["kj"]!r}
c6 = {p["kj6"]!r}
d1 = {p["dj"]!r}
d2 = {p["dj"]!r}
d6 = {p["dj6"]!r}
"""
    text += f"""
[[coupling]]
id = "cut"
a = {{ body = "{tip}", offset = [{p["cx"]!r}, {p["cy"]!r}] }}
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = {p["Kf"]!r}
force_angle_deg = {p["fa"]!r}
normal_angle_deg = {p["na"]!r}
[process]
kind = "delay"
delay = 0.01
"""
    return text


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(np.log(lo), np.log(hi)).map(lambda x: float(np.exp(x)))


structures = st.fixed_dictionaries(
    {
        "two": st.booleans(),
        "m1": log_uniform(1.0, 20.0),
        "J1": log_uniform(0.01, 0.5),
        "m2": log_uniform(0.5, 5.0),
        "J2": log_uniform(0.005, 0.05),
        "ox": st.floats(-0.05, 0.05),
        "k1": log_uniform(1e7, 1e8),
        "k2": log_uniform(1e7, 1e8),
        "k6": log_uniform(1e5, 1e6),
        "sa": st.floats(0.0, 90.0),
        "d1": log_uniform(100.0, 2000.0),
        "d2": log_uniform(100.0, 2000.0),
        "d6": log_uniform(1.0, 20.0),
        "kj": log_uniform(1e7, 1e8),
        "kj6": log_uniform(1e5, 1e6),
        "dj": log_uniform(100.0, 1000.0),
        "dj6": log_uniform(1.0, 10.0),
        "cx": st.floats(-0.05, 0.05),
        "cy": st.floats(-0.05, 0.05),
        "Kf": log_uniform(5e8, 3e9),
        "fa": st.floats(-90.0, 90.0),
        "na": st.floats(-90.0, 90.0),
    }
)


def oriented_minimum(fz: cl.FrozenSystem) -> float:
    """K_f min over w of Re[n^T H(jw) f] (1/m) for the rank-1 CE, refined by
    bounded Brent around the best of a log grid (relative accuracy ~1e-8,
    far finer than the 0.8 factor it is used with)."""
    fb = closed_loop(fz, width=1.0, delay=1.0)
    # at b = 1 m the CE matrix is Dl_P = K_f f n^T (|f| = |n| = 1): its SVD
    # gives K_f and the two directions (signs cancel in f n^T); the oriented
    # receptance is Phi = n^T J G J^T f
    u, sv, vt = np.linalg.svd(fb.Dl_P)
    f_vec, n_vec, kf = u[:, 0], vt[0], sv[0]
    a = fb.J.T @ f_vec
    c = fb.J.T @ n_vec

    def phi(w: float | np.ndarray) -> np.ndarray:
        w = np.atleast_1d(np.asarray(w, float))
        s = 1j * w
        Z = s[:, None, None] ** 2 * fz.A + s[:, None, None] * fz.B + fz.C
        return np.real(np.einsum("i,kij,j->k", c, np.linalg.inv(Z), a))

    lam = np.linalg.eigvals(np.linalg.solve(fz.A, fz.C))
    wmin, wmax = np.sqrt(lam.real.min()), np.sqrt(lam.real.max())
    grid = np.geomspace(0.2 * wmin, 3.0 * wmax, 20000)
    vals = phi(grid)
    j = int(np.argmin(vals))
    lo, hi = grid[max(j - 1, 0)], grid[min(j + 1, grid.size - 1)]
    res = minimize_scalar(
        lambda w: float(phi(w)[0]), bounds=(lo, hi), method="bounded", options={"xatol": 1e-12 * hi}
    )
    return min(float(vals[j]), float(res.fun)) * kf


@settings(
    max_examples=25,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
@given(p=structures, factor=log_uniform(0.3, 10.0), T=log_uniform(2e-3, 0.05))
def test_roots_and_argument_principle_agree_on_random_structures(p, factor, T):
    """Random 3- or 6-DOF structures, a regenerative CE at random angles, a
    random delay and a width around the structure's absolute minimum
    b_min = -1/(2 min Re[n^T H f] K_f) (0.3-10 x b_min).  Properties:

    * stability() gives a definite verdict and agree is True (the roots and
      the argument-principle count of right-half-plane roots say the same),
      unless a root sits within 1e-6 |lambda| of the axis (rejected as too
      close to marginal: both routes are then right to call it marginal);
    * below 0.8 b_min the verdict is stable for every delay (Tlusty's bound
      for a rank-1 regenerative CE: det(I - G D) = 1 + K_f b (1 - e^{-jwT})
      n^T H f cannot vanish while 2 K_f b |min Re n^T H f| < 1).
    """
    fz = cl.assemble(cl.loads_model(random_structure_text(p))).at()
    mre = oriented_minimum(fz)  # K_f min Re[n^T H f], 1/m
    if mre < 0:
        b_min = -1.0 / (2.0 * mre)
        width = factor * b_min
    else:  # no frequency with Re < 0: unconditionally stable
        b_min = np.inf
        width = factor * 1e-3
    note(f"b_min = {b_min:.6g} m, width = {width:.6g} m, T = {T:.6g} s, n = {fz.n}")
    s = stability(fz, width=width, delay=T)
    note(s.message)
    near_axis = abs(s.abscissa) <= 1e-6 * abs(s.roots.roots[0]) if len(s.roots.roots) else True
    if near_axis or s.verdict == "marginal" or (s.winding is not None and s.winding.status == "marginal"):
        event("rejected: too close to marginal")
        assume(False)
    event(s.verdict)
    assert s.roots.converged, s.roots.message
    assert s.winding.status == "converged", s.winding.message
    assert s.verdict in ("stable", "unstable"), s.message
    assert s.agree is True, s.message
    if width < 0.8 * b_min or not np.isfinite(b_min):
        assert s.verdict == "stable", s.message


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "kw, match",
    [
        ({"width": 0.0, "delay": 0.02}, "width"),
        ({"width": -1e-3, "delay": 0.02}, "width"),
        ({"width": float("nan"), "delay": 0.02}, "width"),
        ({"width": 1e-3, "delay": 0.0}, "delay"),
        ({"width": 1e-3, "delay": -0.02}, "delay"),
        ({"width": 1e-3, "speed": 0.0}, "speed"),
        ({"width": 1e-3, "speed": 3000.0, "delay": 0.02}, "either"),
        ({"width": 1e-3, "delay": 0.02, "terms": "pid"}, "terms"),
    ],
)
def test_bad_arguments(turning, kw, match):
    with pytest.raises(cl.InputError, match=match):
        stability(turning, **kw)


def test_model_without_coupling_or_process():
    text = turning_text()
    no_coupling = text.split("[[coupling]]")[0] + '[process]\nkind = "turning"\nrpm = 3000.0\n'
    with pytest.raises(cl.InputError, match=r"no \[\[coupling\]\]"):
        stability(cl.assemble(cl.loads_model(no_coupling)).at(), width=1e-3, delay=0.02)
    no_process = text.split("[process]")[0]
    fz = cl.assemble(cl.loads_model(no_process)).at()
    with pytest.raises(cl.InputError, match=r"no \[process\]"):
        stability(fz, width=1e-3, speed=3000.0)
    # an explicit delay needs no process
    assert stability(fz, width=1e-4, delay=0.02).verdict == "stable"


def test_marginal_tolerance_is_relative():
    """The documented axis tolerance (used above) is a small relative number."""
    assert 0 < MARGINAL_TOL <= 1e-6
