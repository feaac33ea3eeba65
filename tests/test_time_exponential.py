"""The exponential step map of a time-invariant delayed loop
(chatterlab.time.exponential, simulate(..., integrator="exponential")).

Oracles: an independent integration of the same delay equation (scipy's
DOP853 at rtol 1e-12 / 1e-10 by the method of steps, its history the dense
output of the previous delay interval), the closed-form step response of a
damped oscillator (no delay: the step map is exact), and the rightmost
characteristic root of the loop (chatterlab.frequency.characteristic_roots,
a different algorithm: collocation of the generator plus Newton)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.frequency import characteristic_roots, make_system
from chatterlab.time import ConstantProblem, Initial, Integration, exponential, simulate
from chatterlab.time._simulate import constant_loop

sys.path.insert(0, str(Path(__file__).parent))
from conftest import turning_text  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

# the 1-DOF turning tool of tests/conftest.py at b = 0.6 mm, T = 0.02 s (3000 rpm)
M1, K1, C1 = 1.0, 1.0e7, 189.7
KB = 2.0e9 * 6e-4
T1 = 0.02


def _method_of_steps(A, B, C, G, T, f0, q0, t_end, rtol):
    """DOP853 on x' = L x + N q(t - T) + c, interval by interval, the history
    the previous interval's dense output (zero before t = 0); returns q(t)."""
    n = A.shape[0]
    Ai = np.linalg.inv(A)
    L = np.block([[np.zeros((n, n)), np.eye(n)], [-Ai @ C, -Ai @ B]])
    N = np.vstack([np.zeros((n, n)), Ai @ G])
    c = np.r_[np.zeros(n), Ai @ f0]
    y = np.r_[q0, np.zeros(n)]
    scale = max(np.abs(q0).max(), np.abs(np.linalg.solve(C - G, f0)).max())
    sols, a = [], 0.0
    while a < t_end - 1e-12 * T:
        b = min(a + T, t_end)
        prev = sols[-1] if sols else None
        if prev is None:

            def f(t, y):
                return L @ y + c
        else:

            def f(t, y, prev=prev):
                return L @ y + N @ prev(t - T)[:n] + c

        s = solve_ivp(f, (a, b), y, method="DOP853", rtol=rtol, atol=rtol * 1e-3 * scale, dense_output=True)
        assert s.success
        sols.append(s.sol)
        y, a = s.y[:, -1], b

    def q(t):
        k = np.minimum((np.asarray(t) / T).astype(int), len(sols) - 1)
        out = np.empty((n, t.size))
        for i, sol in enumerate(sols):
            sel = k == i
            if sel.any():
                out[:, sel] = sol(t[sel])[:n]
        return out

    return q


@pytest.fixture(scope="module")
def turning():
    """The 1-DOF problem and its reference over 0.1 s (5 delays) from q0 = 1 um."""
    A, B, C, G = (np.array([[x]]) for x in (M1, C1, K1 + KB, KB))
    prob = ConstantProblem(A, B, C, G=G, delay=T1)
    ref = _method_of_steps(A, B, C, G, T1, np.zeros(1), np.array([1e-6]), 0.1, 1e-12)
    return prob, ref


def _rel_error(r, ref, rows=None):
    y_ref = ref(r.t) if rows is None else rows @ ref(r.t)
    return float((np.abs(r.q - y_ref).max(axis=1) / np.abs(y_ref).max(axis=1)).max())


@pytest.mark.parametrize("degree", [3, 5])
def test_declared_order_is_the_fitted_convergence_slope(turning, degree):
    """Order p + 1: the error against DOP853 (rtol 1e-12, its own error ~1e-11,
    below 1e-3 of the smallest error fitted) falls as h^(p+1).  The steps
    (14 to 40 per period of the 534 Hz chatter) are in the asymptotic range:
    the next term of the error, relative to the leading one, is O(w h) ~ 0.2
    to 0.45 over the range, so the local slope differs from p + 1 by at most
    about d ln(1 + 0.45)/d ln h ... 0.45 -> bounded by 0.5 over the fit."""
    prob, ref = turning
    ms = np.array([128, 160, 200, 256, 320])
    errs = [_rel_error(exponential(prob, (0.0, 0.1), [1e-6], h=T1 / m, degree=degree), ref) for m in ms]
    assert min(errs) > 1e-9  # the reference's error (~1e-11) is negligible
    slope = -np.polyfit(np.log(ms), np.log(errs), 1)[0]
    assert abs(slope - (degree + 1)) < 0.5, (slope, errs)


@pytest.mark.parametrize("rtol", [1e-2, 1e-3, 1e-4])
def test_error_control_meets_rtol_on_one_dof(turning, rtol):
    prob, ref = turning
    r = exponential(prob, (0.0, 0.1), [1e-6], rtol=rtol)
    assert r.ok
    assert r.attrs["error_estimate"] <= rtol
    assert r.attrs["steps_per_delay"] * r.h == pytest.approx(T1, rel=1e-12)  # the step it chose, reported
    assert _rel_error(r, ref) <= rtol


@pytest.fixture(scope="module")
def shaper():
    """The traverse shaper held at its default position, cutting continuously at T = 0.1 s
    (b = 2 mm, 36 coordinates): the matrices simulate integrates, and their reference over
    0.2 s from rest under the cutting force (DOP853, rtol 1e-10)."""
    system = cl.assemble(cl.load_model(ROOT / "studies" / "traverse_shaper" / "model.toml"))
    A, B, C, G, T = constant_loop(system, delay=0.1)
    from chatterlab.process._kinematics import kinematics_for
    from chatterlab.time._simulate import ParametricProblem, _output_map

    prob = ParametricProblem(
        system, kinematics_for(system.model.process, delay=0.1), width=0.002, terms="pdo"
    )
    f0 = np.array(prob.force(np.array([0.0]))[0])
    rows = np.vstack([_output_map(system, "rfe5.x"), _output_map(system, "rfe5.y")])
    rows = prob.maps(np.array([0.0]), rows)[0]
    ref = _method_of_steps(A, B, C, G, T, f0, np.zeros(A.shape[0]), 0.2, 1e-10)
    return system, rows, ref


@pytest.mark.parametrize("rtol", [1e-2, 1e-3])
def test_error_control_meets_rtol_on_the_shaper(shaper, rtol):
    system, rows, ref = shaper
    sim = simulate(
        system,
        delay=0.1,
        outputs=["rfe5.x", "rfe5.y"],
        integration=Integration(duration=0.2, integrator="exponential", rtol=rtol),
    )
    r = sim.response
    assert r.attrs["method"] == "exponential" and r.attrs["error_estimate"] <= rtol
    y = np.vstack([sim.data["rfe5.x"], sim.data["rfe5.y"]])
    y_ref = rows @ ref(sim.t)
    err = float((np.abs(y - y_ref).max(axis=1) / np.abs(y_ref).max(axis=1)).max())
    assert err <= rtol
    assert "exponential step map of order 6" in sim.meta["step_rule"]


def test_without_delay_the_step_map_is_exact():
    """No delayed term, a constant force: Eq. (4) is exact at every step
    (rounding only): the closed-form step response of a damped oscillator."""
    m, c, k, F = 2.0, 30.0, 8.0e5, 10.0
    wn = math.sqrt(k / m)
    z = c / (2 * math.sqrt(k * m))
    wd = wn * math.sqrt(1 - z * z)
    r = exponential(ConstantProblem([[m]], [[c]], [[k]], force=[F]), (0.0, 0.2), h=1e-3)
    t = r.t
    exact = F / k * (1 - np.exp(-z * wn * t) * (np.cos(wd * t) + z * wn / wd * np.sin(wd * t)))
    assert np.abs(r.q[0] - exact).max() <= 1e-12 * F / k * t.size  # rounding, per step
    assert r.a[0] == pytest.approx((F - c * r.v[0] - k * r.q[0]) / m, rel=1e-12, abs=1e-9)


def test_growth_rate_is_the_rightmost_root():
    """A run long enough for every other root to fade: the peaks of q grow as
    exp(sigma t), sigma = Re of the rightmost characteristic root.  Between two
    peaks one period apart the ratio of a damped sinusoid is exactly
    exp(sigma 2 pi / w); what can move the fitted slope: the next root's
    share, below exp(-(sigma_1 - sigma_2) t_a) at the fit's start t_a, the
    integration error (rtol relative to the largest value, 1e-6 here, so at
    most rtol exp(sigma span) relative to an earlier peak) and the
    peak's location on the grid (parabolic refinement, relative error
    ~(w h)^4 / 48 ~ 1e-6 at 50 steps per period); each moves log(peak) by
    at most that much, so the slope over the fit's span by at most twice the
    sum over the span."""
    width = 4.0e-4  # just above the limit: a slowly growing chatter root, the next 20 1/s lower
    kb = 2.0e9 * width
    sysd = make_system([[M1]], [[C1]], [[K1 + kb]], DO=[[kb]], tau=T1)
    roots = characteristic_roots(sysd, count=2).roots
    s1, s2 = roots[0].real, roots[1].real
    w1 = abs(roots[0].imag)
    t_a = 6.0 / (s1 - s2) * math.log(10.0)  # next root down by 1e-6
    t_b = t_a + 0.5
    prob = ConstantProblem([[M1]], [[C1]], [[K1 + kb]], G=[[kb]], delay=T1)
    r = exponential(prob, (0.0, t_b), [1e-6], rtol=1e-6)
    q, t, h = r.q[0], r.t, r.h
    i = np.nonzero((q[1:-1] > q[:-2]) & (q[1:-1] >= q[2:]) & (t[1:-1] > t_a))[0] + 1
    a, b, c = q[i - 1], q[i], q[i + 1]
    peak = b - (a - c) ** 2 / (8.0 * (a - 2 * b + c))  # parabola's top
    tp = t[i] + h * (a - c) / (2.0 * (a - 2 * b + c))
    sigma = np.polyfit(tp, np.log(peak), 1)[0]
    steps = 2 * math.pi / (w1 * h)
    tol = (
        2.0 * (1e-6 + 1e-6 * math.exp(abs(s1) * (t_b - t_a)) + (2 * math.pi / steps) ** 4 / 48) / (t_b - t_a)
    )
    assert abs(sigma - s1) <= tol, (sigma, s1, tol)


def test_newmark_stays_selectable_and_the_default():
    """Newmark is the default and named explicitly gives the same run; over
    the first delay (no feedback yet: the oscillator of stiffness k + K_f b
    swinging from q0) Newmark's average acceleration differs from the exact
    free vibration by its phase error only, (w h)^2/12 per radian, so by at most
    q0 * (w t)(w h)^2/12 after t; the exponential run is within 1e-6 of exact."""
    tool = cl.assemble(cl.loads_model(turning_text()))
    kw = dict(width=6e-4, delay=T1, outputs="tool.x", initial=Initial(q0={"tool.x": 1e-6}))
    h = 1e-4
    default = simulate(tool, integration=Integration(duration=0.06, step=h), **kw)
    named = simulate(tool, integration=Integration(duration=0.06, step=h, integrator="newmark"), **kw)
    assert np.array_equal(default.data["tool.x"], named.data["tool.x"])
    assert "gamma" in default.response.attrs
    expo = simulate(tool, integration=Integration(duration=0.06, integrator="exponential", rtol=1e-6), **kw)
    assert expo.response.attrs["method"] == "exponential"
    w = math.sqrt((K1 + KB) / M1)
    sel = default.t <= T1
    y_e = np.interp(default.t[sel], expo.t, expo.data["tool.x"])  # exponential's record: its own grid
    diff = np.abs(default.data["tool.x"][sel] - y_e).max()
    interp = 1e-6 * (w * expo.step) ** 2 / 8  # linear interpolation of the exponential record
    assert diff <= 1e-6 * (w * T1 * (w * h) ** 2 / 12 + 1e-6) + interp


def test_bad_input_is_one_line():
    with pytest.raises(InputError, match="integrator must be one of"):
        Integration(integrator="rk4")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="rtol"):
        Integration(rtol=0.0)
    shaper = cl.assemble(cl.load_model(ROOT / "studies" / "traverse_shaper" / "model.toml"))
    with pytest.raises(InputError, match="continuous cut"):
        simulate(shaper, integration=Integration(periods=1, integrator="exponential"))
    from chatterlab.time import CallbackProblem

    moving = CallbackProblem(1, [[1.0]], [[0.0]], lambda t: np.array([[1.0 + t]]))
    with pytest.raises(InputError, match="constant coefficients"):
        exponential(moving, (0.0, 1.0))
    with pytest.raises(InputError, match="degree"):
        exponential(ConstantProblem([[1.0]], [[0.0]], [[1.0]]), (0.0, 1.0), degree=9)


@pytest.mark.parametrize("width", [6e-4, 3e-4])
def test_verdict_of_an_exponential_run_uses_its_order(width):
    """The verdict of an exponential run: its check run at h/2 and Richardson
    for order p + 1 (no Newmark h^2 regime test); the class and the rate
    agree with the rightmost root (certified by characteristic_roots) within
    the verdict's own error bar (2 fit standard errors + the step error) and
    the root's relative error bound; no contradiction."""
    tool = cl.assemble(cl.loads_model(turning_text()))
    kb = 2.0e9 * width
    roots = characteristic_roots(make_system([[M1]], [[C1]], [[K1 + kb]], DO=[[kb]], tau=T1), count=2)
    sim = simulate(
        tool, width=width, delay=T1, outputs="tool.x", roots=roots,
        integration=Integration(duration=1.0, integrator="exponential"), initial=Initial(q0={"tool.x": 1e-6}),
    )  # fmt: skip
    v = sim.verdict("tool.x")
    s1 = roots.roots[0].real
    assert v.check_step == pytest.approx(sim.step / 2)
    assert v.classification == ("growing" if s1 > 0 else "decaying")
    assert abs(v.rate - s1) <= v.fit_error + v.step_error + 1e-6 * abs(roots.roots[0])
    assert not v.contradiction and f"order {sim.response.attrs['order']}" in v.message


def test_a_time_varying_force_is_interpolated_to_the_same_order():
    """A harmonic force (no delay): the step map integrates the force's
    degree-p interpolant over each step, so the error against DOP853 (rtol
    1e-12) falls as h^(p+1) too (fitted slope within 0.5, as for the delay),
    and the error control meets rtol."""
    m, c, k = 1.0, 60.0, 4.0e6
    wf = 2 * math.pi * 150.0

    def force(t):
        return np.sin(wf * np.asarray(t))[:, None]

    prob = ConstantProblem([[m]], [[c]], [[k]], force=force)
    sol = solve_ivp(
        lambda t, y: [y[1], (math.sin(wf * t) - c * y[1] - k * y[0]) / m], (0.0, 0.05), [0.0, 0.0],
        method="DOP853", rtol=1e-12, atol=1e-20, dense_output=True,
    )  # fmt: skip

    def err(r):
        y = sol.sol(r.t)[0]
        return float(np.abs(r.q[0] - y).max() / np.abs(y).max())

    hs = 0.05 / np.array([64, 80, 100, 128, 160])  # 8.5 to 21 steps per period of the force
    errs = [err(exponential(prob, (0.0, 0.05), h=h)) for h in hs]
    slope = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert min(errs) > 1e-10  # the reference (rtol 1e-12) is negligible
    assert abs(slope - 6) < 0.5, (slope, errs)
    r = exponential(prob, (0.0, 0.05), rtol=1e-5)
    assert r.attrs["error_estimate"] <= 1e-5 and err(r) <= 1e-5
