"""Tests of the Newmark integrator (chatterlab.time._newmark) and signal post-processing
(chatterlab.time._signals).

Mathematics is the oracle: closed-form responses, the exact discrete solution
of the average-acceleration scheme (it is the trapezoidal rule, so its
amplification factor is the Cayley transform z = (1 + s h/2)/(1 - s h/2)),
scipy's solve_ivp at tight tolerance (with the method of steps for the delay
equations) and the characteristic roots of the delay equation.  Every
tolerance is justified next to it; the measured values (this machine, numpy
2.4 / scipy 1.17) are quoted as "measured".
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from chatterlab.errors import InputError
from chatterlab.time._newmark import (
    CallbackProblem,
    ConstantProblem,
    NewmarkOptions,
    NewmarkStabilityWarning,
    PiecewiseProblem,
    TimeResponse,
    newmark,
)
from chatterlab.time._signals import amplitude_spectrum, growth_rate, peaks

# --------------------------------------------------------------------------- helpers


def sdof(m: float, c: float, k: float, **kw) -> ConstantProblem:
    return ConstantProblem([[m]], [[c]], [[k]], **kw)


def observed_orders(errors: list[float]) -> np.ndarray:
    """log2 of successive error ratios for steps h, h/2, h/4, ..."""
    e = np.asarray(errors)
    return np.log2(e[:-1] / e[1:])


def sweep_h(problem, t_span, h0, levels=4, **kw) -> tuple[list[TimeResponse], list[float]]:
    """Runs at h0/2^l recorded on the coarse grid (record_every = 2^l)."""
    runs = [newmark(problem, t_span, h0 / 2**l, record_every=2**l, **kw) for l in range(levels)]
    for r in runs:
        assert r.status == "ok", r.message
        np.testing.assert_allclose(r.t, runs[0].t, rtol=0, atol=1e-12)
    return runs, [h0 / 2**l for l in range(levels)]


def method_of_steps(rhs_delayed, y0, history_q, T, n_intervals, n):
    """Reference solution of y' = F(t, y, q(t - T)) by the method of steps.

    Interval [iT, (i+1)T] is integrated with DOP853 (rtol 1e-12) using the
    dense output of the previous interval (7th-order interpolant) as the
    delayed input; the first interval reads ``history_q``.  Returns q(t) for an
    array of times.
    """
    sols = []
    y = np.asarray(y0, dtype=float)
    for i in range(n_intervals):
        prev = sols[-1] if sols else None

        def delayed(t, prev=prev):
            return prev.sol(t - T)[:n] if prev is not None else history_q(t - T)

        s = solve_ivp(
            lambda t, y: rhs_delayed(t, y, delayed(t)),
            (i * T, (i + 1) * T),
            y,
            method="DOP853",
            rtol=1e-12,
            atol=1e-15,
            dense_output=True,
        )
        assert s.success
        sols.append(s)
        y = s.y[:, -1]

    def q(t):
        t = np.asarray(t, dtype=float)
        idx = np.minimum((t / T).astype(int), n_intervals - 1)
        out = np.empty((n, t.size))
        for j in range(n_intervals):
            sel = idx == j
            if sel.any():
                out[:, sel] = sols[j].sol(t[sel])[:n]
        return out

    return q


def rightmost_root(m, c, k, g, T):
    """Rightmost root of m s^2 + c s + k - g exp(-s T) = 0 by Newton from a grid.

    Independent oracle: Newton started from 3 x 121 points covering
    Re s in {-5, 0, 5}, Im s in [0, 6 w_n]; converged roots (|f| < 1e-8 k)
    are collected and the one of largest real part returned.
    """
    wn = math.sqrt(k / m)
    best = None
    for w0 in np.linspace(0.0, 6 * wn, 121):
        for s0 in (-5.0, 0.0, 5.0):
            s = complex(s0, w0)
            for _ in range(80):
                e = np.exp(-s * T)
                step = (m * s * s + c * s + k - g * e) / (2 * m * s + c + g * T * e)
                s -= step
                if abs(step) < 1e-14 * max(1.0, abs(s)):
                    break
            if abs(m * s * s + c * s + k - g * np.exp(-s * T)) < 1e-8 * k and s.imag > -1e-9:
                if best is None or s.real > best.real:
                    best = s
    assert best is not None
    return best


# --------------------------------------------------------------------------- SDOF


def test_undamped_sdof_exact_discrete_solution_energy_and_period():
    # Average acceleration is the trapezoidal rule on [x, v]: the exact discrete
    # solution is x_k = x0 cos(k th) + v0/w sin(k th), th = 2 atan(w h / 2):
    # no amplitude error, period elongation w h / (2 atan(w h/2)).
    w, h, n_steps = 2 * np.pi * 10.0, 0.008, 10_000  # w h = 0.503: visible elongation (2.1 %)
    x0, v0 = 1.0, 20.0
    r = newmark(sdof(1.0, 0.0, w * w), (0.0, n_steps * h), h, q0=[x0], v0=[v0])
    assert r.status == "ok" and r.n_steps == n_steps
    th = 2 * np.arctan(w * h / 2)
    k = np.arange(n_steps + 1)
    x_exact = x0 * np.cos(k * th) + v0 / w * np.sin(k * th)
    amp = math.hypot(x0, v0 / w)
    # round-off only (1e4 steps of ~eps/(w h)^2 each): measured 1.6e-12
    assert np.max(np.abs(r.q[0] - x_exact)) < 1e-10 * amp
    # energy conserved to round-off over 1e4 steps (measured 2.7e-12 relative)
    energy = 0.5 * r.v[0] ** 2 + 0.5 * w * w * r.q[0] ** 2
    assert np.max(np.abs(energy / energy[0] - 1)) < 1e-10
    # period measured from the data: a sampled sinusoid obeys x[k+1] + x[k-1] = 2 cos(th) x[k];
    # least squares for cos(th) -> the measured period ratio equals the formula to 2e-16
    x = r.q[0]
    cos_th = np.dot(x[1:-1], x[2:] + x[:-2]) / (2 * np.dot(x[1:-1], x[1:-1]))
    ratio_measured = w * h / np.arccos(cos_th)
    ratio_formula = w * h / (2 * np.arctan(w * h / 2))
    assert abs(ratio_measured - ratio_formula) < 1e-10
    assert ratio_formula - 1 > 0.02  # and the elongation is really there (2.09 %)
    # zero crossings (linear interpolation, error O((w h)^2) per crossing but
    # fitted over ~640 periods) confirm the elongated period: measured 6e-10
    s = np.sign(x)
    i = np.nonzero(s[:-1] * s[1:] < 0)[0]
    tz = r.t[i] - x[i] * (r.t[i + 1] - r.t[i]) / (x[i + 1] - x[i])
    period = 2 * np.polyfit(np.arange(tz.size), tz, 1)[0]
    assert abs(period / (2 * np.pi / w) / ratio_formula - 1) < 1e-6


def damped_closed_form(m, c, k, x0, v0, F=0.0, Om=0.0):
    """x(t) of m x'' + c x' + k x = F sin(Om t), underdamped."""
    wn = math.sqrt(k / m)
    z = c / (2 * m * wn)
    wd = wn * math.sqrt(1 - z * z)
    Gc = 1.0 / (k - m * Om**2 + 1j * c * Om)  # particular: Im(F G e^{j Om t})
    xp0 = (F * Gc).imag
    vp0 = (F * Gc * 1j * Om).imag
    a = x0 - xp0
    b = (v0 - vp0 + z * wn * a) / wd

    def x(t):
        return (F * Gc * np.exp(1j * Om * t)).imag + np.exp(-z * wn * t) * (
            a * np.cos(wd * t) + b * np.sin(wd * t)
        )

    return x


@pytest.mark.parametrize("forced", [False, True], ids=["free", "forced"])
def test_damped_sdof_closed_form_second_order(forced):
    m, k = 2.0, 2.0 * (2 * np.pi * 3.0) ** 2
    c = 2 * 0.05 * math.sqrt(k * m)
    F, Om = (5.0, 2 * np.pi * 2.2) if forced else (0.0, 0.0)
    force = (lambda t: (F * np.sin(Om * t))[:, None]) if forced else None
    exact = damped_closed_form(m, c, k, 0.01, -0.3, F, Om)
    runs, hs = sweep_h(sdof(m, c, k, force=force), (0.0, 2.0), 0.01, q0=[0.01], v0=[-0.3])
    scale = np.max(np.abs(exact(runs[0].t)))
    errs = [np.max(np.abs(r.q[0] - exact(r.t))) / scale for r in runs]
    orders = observed_orders(errs)
    # global error C h^2 (w h = 0.19 .. 0.024, asymptotic regime): measured orders
    # 1.998, 1.999, 2.000 (free) and 2.003, 2.001, 2.000 (forced)
    assert np.all(np.abs(orders - 2.0) < 0.1), orders
    # max error relative to the largest |x|: measured 2.4e-2 at h = 0.01 (w h = 0.19,
    # mostly the (w h)^2/12 period error accumulated over 6 periods), 3.8e-4 at h/8
    assert errs[-1] < 5e-4


def test_harmonic_steady_state_amplitude_and_its_newmark_error():
    # After the transient, the trapezoidal rule's response to sampled F sin(W t)
    # is exactly |G(j W~)| with the bilinear-warped frequency W~ = (2/h) tan(W h/2)
    # (z = e^{jWh}, s~ = (2/h)(z-1)/(z+1)): that quantifies the Newmark error of the
    # steady-state amplitude relative to the exact |G(jW)| = 1/|k - m W^2 + j c W|.
    m, wn, zeta, F = 1.0, 2 * np.pi * 10.0, 0.05, 3.0
    k, c = m * wn**2, 2 * zeta * m * wn
    W = 2 * np.pi * 9.0  # near resonance: the most sensitive place
    h = 1e-3
    r = newmark(sdof(m, c, k, force=lambda t: (F * np.sin(W * t))[:, None]), (0.0, 14.0), h, q0=[0.0])
    sel = r.t >= 12.0  # transient ~ exp(-zeta wn t) = exp(-37.7) = 4e-17 by then
    basis = np.column_stack([np.cos(W * r.t[sel]), np.sin(W * r.t[sel])])
    coef, *_ = np.linalg.lstsq(basis, r.q[0, sel], rcond=None)
    amp = math.hypot(*coef)
    exact = F / abs(k - m * W**2 + 1j * c * W)
    Ww = (2 / h) * math.tan(W * h / 2)
    discrete = F / abs(k - m * Ww**2 + 1j * c * Ww)
    # the discrete prediction holds to round-off (measured 5e-15 relative)
    assert abs(amp / discrete - 1) < 1e-9
    # and the Newmark amplitude error is what the warping predicts: here +0.18 %,
    # (W h)^2/12 = 2.7e-4 times the resonance sensitivity d ln|G| / d ln W (6.8 at 0.9 w_n)
    newmark_err = amp / exact - 1
    assert abs(newmark_err - (discrete / exact - 1)) < 1e-9
    assert 1e-3 < abs(newmark_err) < 5e-3
    # far from resonance the same step gives a much smaller amplitude error (1.1e-6)
    W2 = 2 * np.pi * 2.0
    Ww2 = (2 / h) * math.tan(W2 * h / 2)
    err2 = abs(k - m * W2**2 + 1j * c * W2) / abs(k - m * Ww2**2 + 1j * c * Ww2) - 1
    assert abs(err2) < 1e-4


# --------------------------------------------------------------------------- MDOF


def chain3():
    M = np.diag([1.0, 2.0, 1.5])
    k1, k2, k3 = 1e4, 2e4, 1.5e4
    K = np.array([[k1 + k2, -k2, 0], [-k2, k2 + k3, -k3], [0, -k3, k3]])
    C = np.array([[5.0 + 2.0, -2.0, 0.0], [-2.0, 2.0, 0.0], [0.0, 0.0, 0.0]])  # non-proportional
    C[1:, 1:] += 3.0 * np.array([[1, -1], [-1, 1]])
    return M, C, K


def test_mdof_time_invariant_matches_solve_ivp():
    M, C, K = chain3()
    Fa = np.array([0.0, 0.0, 10.0])
    force = lambda t: np.outer(np.sin(20.0 * t), Fa)  # noqa: E731
    q0, v0 = np.array([1e-3, 0.0, -2e-3]), np.array([0.0, 0.1, 0.0])
    Minv = np.linalg.inv(M)

    def rhs(t, y):
        return np.concatenate([y[3:], Minv @ (Fa * np.sin(20.0 * t) - C @ y[3:] - K @ y[:3])])

    ref = solve_ivp(
        rhs, (0, 1.0), np.concatenate([q0, v0]), method="DOP853", rtol=1e-12, atol=1e-15, dense_output=True
    )
    runs, hs = sweep_h(ConstantProblem(M, C, K, force=force), (0.0, 1.0), 2e-3, levels=3, q0=q0, v0=v0)
    scale = np.max(np.abs(ref.y[:3]))
    errs = [np.max(np.abs(r.q - ref.sol(r.t)[:3])) / scale for r in runs]
    # modes at 40, 126, 200 rad/s: w_max h = 0.4 .. 0.1, asymptotic; measured orders 1.973, 1.989
    assert np.all(np.abs(observed_orders(errs) - 2.0) < 0.1), errs
    # measured 5.5e-2 at h = 2e-3 and 3.6e-3 at h = 5e-4: the (w h)^2/12 phase error of the
    # 200 rad/s mode accumulated over its 32 periods (0.1^2/12 * 200 = 0.17 rad... x its share)
    assert errs[-1] < 5e-3
    # velocities converge at the same order (measured 1.958, 1.999)
    errs_v = [np.max(np.abs(r.v - ref.sol(r.t)[3:])) for r in runs]
    assert np.all(np.abs(observed_orders(errs_v) - 2.0) < 0.1), errs_v


def test_code_paths_agree_constant_callback_piecewise_chunks_workers():
    # The time-invariant path (factor once) and the time-varying path (batched
    # inverses per chunk, in worker threads) are the same algebra: agreement to
    # round-off, for any chunk size and worker count.
    M, C, K = chain3()
    G = -0.2 * K
    T = 0.0123
    Fa = np.array([1.0, -2.0, 3.0])
    force = lambda t: np.outer(np.cos(7.0 * t), Fa)  # noqa: E731
    kw = dict(q0=[1e-3, 0, 0], v0=[0, 0.01, 0], history=lambda t: np.outer(np.sin(t), [1e-3, 0, 0]))
    ref = newmark(ConstantProblem(M, C, K, force=force, G=G, delay=T), (0, 0.5), 1e-4, **kw)
    cb = CallbackProblem(3, M, C, K, G=G, delay=T, force=force, vectorized=True)
    scale = np.max(np.abs(ref.q))
    for chunk, workers in [(None, 2), (7, 0), (64, 1), (1000, 3), (5000, 2)]:
        r = newmark(cb, (0, 0.5), 1e-4, options=NewmarkOptions(chunk=chunk, workers=workers), **kw)
        assert r.status == "ok"
        assert np.max(np.abs(r.q - ref.q)) < 1e-11 * scale  # measured ~1e-14
        assert np.max(np.abs(r.a - ref.a)) < 1e-9 * np.max(np.abs(ref.a))
    # outputs selection and record_every pick the same numbers
    sel = newmark(cb, (0, 0.5), 1e-4, outputs=[2, 0], record_every=10, **kw)
    np.testing.assert_allclose(sel.q, ref.q[[2, 0], ::10], rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(sel.t, ref.t[::10], rtol=0, atol=1e-12)
    rel = newmark(cb, (0, 0.5), 1e-4, outputs={"rel": [1.0, 0.0, -1.0]}, **kw)
    assert rel.names == ("rel",)
    np.testing.assert_allclose(rel.q[0], ref.q[0] - ref.q[2], rtol=0, atol=1e-11 * scale)
    # a piecewise problem whose pieces are all equal is the constant problem
    cp = ConstantProblem(M, C, K, force=force, G=G, delay=T)
    pw = PiecewiseProblem([0.1, 0.3], [cp, cp, cp])
    r = newmark(pw, (0, 0.5), 1e-4, **kw)
    assert np.max(np.abs(r.q - ref.q)) < 1e-11 * scale


def test_piecewise_switch_equals_restart_and_keeps_order_two():
    # A switch on the step grid is crossed with the left limits and a restart of the
    # acceleration: identical (to round-off) to stopping at t_b and restarting with the
    # second system, and second order against solve_ivp run piece by piece.  (Without
    # the restart the trapezoid of a jumping acceleration costs h/2 * jump in v:
    # first order, measured 1.80, 1.73, 1.52 before the restart was added.)
    M, C, K = chain3()
    p1 = ConstantProblem(M, C, K, force=[0.0, 0.0, 5.0])
    p2 = ConstantProblem(M, 2 * C, 1.3 * K, force=[1.0, 0.0, 0.0])
    h, tb = 1e-3, 0.2
    both = newmark(PiecewiseProblem([tb], [p1, p2]), (0, 0.5), h, q0=[1e-3, 0, 0])
    a = newmark(p1, (0, tb), h, q0=[1e-3, 0, 0])
    b = newmark(p2, (tb, 0.5), h, q0=a.q[:, -1], v0=a.v[:, -1])
    ib = round(tb / h)
    np.testing.assert_allclose(both.q[:, : ib + 1], a.q, rtol=0, atol=1e-15)
    np.testing.assert_allclose(both.q[:, ib:], b.q, rtol=0, atol=1e-13 * np.max(np.abs(b.q)))
    assert both.attrs["breakpoints"] == pytest.approx((tb,))
    f1, f2 = np.array([0.0, 0.0, 5.0]), np.array([1.0, 0.0, 0.0])
    Minv = np.linalg.inv(M)
    ivp = dict(method="DOP853", rtol=1e-12, atol=1e-15, dense_output=True)
    s1 = solve_ivp(
        lambda t, y: np.r_[y[3:], Minv @ (f1 - C @ y[3:] - K @ y[:3])],
        (0, tb),
        np.r_[1e-3, 0, 0, 0, 0, 0],
        **ivp,
    )
    s2 = solve_ivp(
        lambda t, y: np.r_[y[3:], Minv @ (f2 - 2 * C @ y[3:] - 1.3 * K @ y[:3])],
        (tb, 0.5),
        s1.y[:, -1],
        **ivp,
    )

    def ref(t):
        return np.where(t < tb, s1.sol(np.minimum(t, tb))[:3], s2.sol(np.maximum(t, tb))[:3])

    runs, _ = sweep_h(PiecewiseProblem([tb], [p1, p2]), (0, 0.5), 2e-3, q0=[1e-3, 0, 0])
    scale = np.max(np.abs(ref(runs[0].t)))
    errs = [np.max(np.abs(r.q - ref(r.t))) / scale for r in runs]
    assert np.all(np.abs(observed_orders(errs) - 2.0) < 0.1), errs  # measured 2.007, 2.007, 1.997
    # a switch off the grid is integrated (first order there) and reported
    off = newmark(PiecewiseProblem([tb + 3e-4], [p1, p2]), (0, 0.5), h, q0=[1e-3, 0, 0])
    assert off.status == "ok" and "not on the step grid" in off.message


# --------------------------------------------------------------------------- time-varying


def test_time_varying_mathieu_and_all_coefficients_second_order():
    # A(t) x'' + B(t) x' + C(t) x = f(t) with every coefficient varying (Mathieu-type
    # stiffness 4 + 1.5 cos 2t), reference solve_ivp DOP853 rtol 1e-12.
    A = lambda t: 1.0 + 0.3 * np.sin(t)  # noqa: E731
    B = lambda t: 0.1 + 0.05 * np.cos(3 * t)  # noqa: E731
    Cs = lambda t: 4.0 + 1.5 * np.cos(2 * t)  # noqa: E731
    f = lambda t: 0.3 * np.sin(1.3 * t)  # noqa: E731
    prob = CallbackProblem(
        1,
        lambda t: A(t)[:, None, None],
        lambda t: B(t)[:, None, None],
        lambda t: Cs(t)[:, None, None],
        force=lambda t: f(t)[:, None],
        vectorized=True,
    )
    ref = solve_ivp(
        lambda t, y: [y[1], (f(t) - B(t) * y[1] - Cs(t) * y[0]) / A(t)],
        (0, 10.0),
        [1.0, 0.0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-14,
        dense_output=True,
    )
    runs, _ = sweep_h(prob, (0.0, 10.0), 0.04, q0=[1.0], options=NewmarkOptions(chunk=50))
    errs = [np.max(np.abs(r.q[0] - ref.sol(r.t)[0])) for r in runs]
    orders = observed_orders(errs)
    assert np.all(np.abs(orders - 2.0) < 0.1), (errs, orders)  # measured 1.998, 1.999, 2.000
    # measured 6.7e-3 at h = 0.04 and 1.06e-4 at h = 5e-3 (|x| <= 1.2)
    assert errs[-1] < 2e-4
    # the per-time (non-vectorised) adapter gives the same numbers
    scalar = CallbackProblem(
        1, lambda t: [[A(t)]], lambda t: [[B(t)]], lambda t: [[Cs(t)]], force=lambda t: [f(t)]
    )
    r = newmark(scalar, (0.0, 10.0), 0.04, q0=[1.0])
    np.testing.assert_allclose(r.q, runs[0].q, rtol=0, atol=1e-13)


# --------------------------------------------------------------------------- delay


def test_delay_scalar_matches_method_of_steps_second_order():
    m, wn = 1.0, 2 * np.pi * 5
    k, c, g, T, x0 = wn**2, 2 * 0.02 * wn, -180.0, 0.05, 1e-3
    hist = lambda t: x0 * np.cos(wn * np.asarray(t))  # noqa: E731
    ref = method_of_steps(
        lambda t, y, qd: [y[1], (g * qd[0] - c * y[1] - k * y[0]) / m],
        [x0, 0.0],
        lambda t: np.atleast_1d(hist(t)),
        T,
        4,
        1,
    )
    prob = sdof(m, c, k, G=[[g]], delay=T)
    # T/h = 37.3, 74.6, 149.2, 298.4: never a whole number, so q(t - T) is always
    # Hermite-interpolated between stored steps
    runs, _ = sweep_h(prob, (0.0, 3.9 * T), T / 37.3, q0=[x0], history=lambda t: hist(t)[:, None])
    errs = [np.max(np.abs(r.q[0] - ref(r.t)[0])) / x0 for r in runs]
    orders = observed_orders(errs)
    # the O(h^4) interpolation does not spoil order 2: measured 2.0001, 1.9998, 2.0000
    assert np.all(np.abs(orders - 2.0) < 0.1), (errs, orders)
    assert errs[0] < 2e-3 and errs[-1] < 2e-5  # measured 9.3e-4 and 1.4e-5
    # a whole number of steps per delay (T/h = 50, no interpolation) converges the same way
    r50 = newmark(prob, (0.0, 3.9 * T), T / 50, q0=[x0], history=lambda t: hist(t)[:, None])
    e50 = np.max(np.abs(r50.q[0] - ref(r50.t)[0])) / x0
    assert e50 < errs[0] * (37.3 / 50) ** 2 * 1.2


def test_delay_time_varying_mdof_matches_method_of_steps():
    # 2 DOF, A(t), C(t), G(t) all varying, delay 0.03 s, zero history (the delayed
    # force switches on at t = T, like the regenerative force when the tool re-enters
    # its own track): the method of steps integrates across that jump exactly
    # (interval boundaries); Newmark treats t0 + T as a breakpoint (left limit, then
    # restart of the acceleration) and converges at order 2 when T/h is whole.
    T = 0.03
    M0 = np.array([[1.0, 0.1], [0.1, 0.5]])
    K0 = np.array([[4e3, -1e3], [-1e3, 2e3]])
    K1 = np.array([[5e2, 0.0], [0.0, -3e2]])
    B0 = np.array([[2.0, -0.5], [-0.5, 1.0]])
    G0 = np.array([[-300.0, 100.0], [0.0, -150.0]])

    def mats(t):
        t = np.atleast_1d(t)
        s = np.sin(3 * t)[:, None, None]
        A = M0 * (1 + 0.2 * s)
        C = K0 + np.cos(5 * t)[:, None, None] * K1
        G = G0 * (1 + 0.3 * np.sin(7 * t)[:, None, None])
        return A, np.broadcast_to(B0, A.shape), C, G

    class Problem:
        n = 2
        names = ("x", "y")

        def matrices(self, t):
            return mats(t)

        def force(self, t):
            return np.outer(np.sin(40 * t), [1.0, 0.5])

        def delay(self):
            return T

    def rhs(t, y, qd):
        A, B, C, G = (m[0] for m in mats(t))
        f = np.sin(40 * t) * np.array([1.0, 0.5])
        return np.concatenate([y[2:], np.linalg.solve(A, f + G @ qd - B @ y[2:] - C @ y[:2])])

    q0 = np.array([1e-3, -5e-4])
    ref = method_of_steps(rhs, np.concatenate([q0, [0.0, 0.0]]), lambda t: np.zeros(2), T, 5, 2)
    runs, _ = sweep_h(Problem(), (0.0, 4.9 * T), T / 20, levels=4, q0=q0, options=NewmarkOptions(chunk=40))
    assert runs[0].names == ("x", "y")
    assert runs[0].attrs["breakpoints"] == pytest.approx((T,))
    scale = np.max(np.abs(ref(runs[-1].t)))
    errs = [np.max(np.abs(r.q - ref(r.t))) / scale for r in runs]
    orders = observed_orders(errs)
    # measured orders 1.999, 2.000, 2.000; errors 7.8e-3 (h = T/20) .. 1.2e-4 (T/160)
    assert np.all(np.abs(orders - 2.0) < 0.1), (errs, orders)
    assert errs[-1] < 3e-4
    # T/h not whole: the jump falls inside a step (first-order error there, measured
    # orders 2.47, 0.64, 2.31 for T/h = 23.7 .. 189.6), which the message reports
    r = newmark(Problem(), (0.0, 4.9 * T), T / 23.7, q0=q0)
    assert "not on the step grid" in r.message
    assert np.max(np.abs(r.q - ref(r.t))) / scale < 1e-2


@pytest.mark.parametrize("g", [-180.0, 60.0], ids=["unstable", "stable"])
def test_growth_rate_equals_rightmost_root(g):
    # m x'' + c x' + k x = g x(t - T); with w_n T = pi/2 the delayed term acts as a
    # damper whose sign follows g: g = -180 -> Re s = +1.96 1/s, g = +60 -> -1.67 1/s
    # (stability boundary near g = -55).  The next roots are at Re s < -90 1/s,
    # gone after the skipped 1.5 s.
    m, wn, T = 1.0, 2 * np.pi * 5, 0.05
    k, c = wn**2, 2 * 0.02 * wn
    root = rightmost_root(m, c, k, g, T)
    r = newmark(sdof(m, c, k, G=[[g]], delay=T), (0.0, 6.0), 5e-4, q0=[1e-3])
    est = r.growth(0, t_min=1.5)  # fit from 1.5 s (a quarter of the run)
    # discretisation error of the rate O((w h)^2) ~ 1e-5 relative, envelope
    # estimator exact for a single exponential mode: measured 5.7e-5 / 6.4e-5 relative;
    # tolerance 1 % as specified for the estimator
    assert abs(est.rate - root.real) < 0.01 * abs(root.real), (est, root)
    assert est.classification == ("growing" if root.real > 0 else "decaying")
    assert est.r2 > 0.999
    # the oscillation frequency is the root's imaginary part too (spectrum peak)
    f, a = r.spectrum(0, window=(1.5, np.inf), pad=8)
    fp, _ = peaks(f, a, 1)
    assert abs(2 * np.pi * fp[0] - root.imag) < 0.05 * 2 * np.pi / 4.5  # < 5 % of a bin (meas. 0.06 %)


@pytest.mark.parametrize("g", [-180.0, 60.0], ids=["unstable", "stable"])
def test_growth_rate_equals_chatterlab_roots(g):
    # our own module, not an optional one: a failing import is a failure, not a skip
    from chatterlab.frequency import _roots as roots_mod

    m, wn, T = 1.0, 2 * np.pi * 5, 0.05
    k, c = wn**2, 2 * 0.02 * wn
    res = roots_mod.characteristic_roots(roots_mod.make_system([[m]], [[c]], [[k]], DO=[[g]], tau=T), count=3)
    sigma = float(np.real(res.roots[0]))
    # both oracles agree with each other...
    assert abs(sigma - rightmost_root(m, c, k, g, T).real) < 1e-8
    # ...and with the simulation (same 1 % tolerance as above)
    r = newmark(sdof(m, c, k, G=[[g]], delay=T), (0.0, 6.0), 5e-4, q0=[1e-3])
    assert abs(r.growth(0, t_min=1.5).rate - sigma) < 0.01 * abs(sigma)
    # the deprecated name keeps its old meaning (skip: a fraction of the run)
    with pytest.warns(DeprecationWarning, match="use growth"):
        old = r.growth_rate(0, skip=0.25)
    assert old == r.growth(0, t_min=1.5)


def test_history_forms_agree():
    m, k, c, g, T = 1.0, 1e3, 1.0, -50.0, 0.02
    prob = sdof(m, c, k, G=[[g]], delay=T)
    base = newmark(prob, (0, 0.2), 1e-3, q0=[1e-3], history=np.array([1e-3]))
    f = newmark(prob, (0, 0.2), 1e-3, q0=[1e-3], history=lambda t: np.full((t.size, 1), 1e-3))
    th = np.linspace(-0.05, 0.0, 11)
    s = newmark(prob, (0, 0.2), 1e-3, q0=[1e-3], history=(th, np.full((11, 1), 1e-3)))
    np.testing.assert_allclose(f.q, base.q, rtol=0, atol=1e-18)
    np.testing.assert_allclose(s.q, base.q, rtol=0, atol=1e-15)
    zero = newmark(prob, (0, 0.2), 1e-3, q0=[1e-3])  # default zero history differs
    assert np.max(np.abs(zero.q - base.q)) > 1e-6
    # a delay of exactly one step is allowed (T = h)
    one = newmark(sdof(m, c, k, G=[[g]], delay=1e-3), (0, 0.05), 1e-3, q0=[1e-3])
    assert one.status == "ok"


def test_history_memory_is_bounded_by_the_delay_not_the_run():
    # 5e4 steps with T/h = 100: the stored history is ~T/h + chunk rows (a few 10 kB),
    # far below the 1.6 MB a full record of q, v, a would take; the output is thinned.
    prob = sdof(1.0, 0.5, 1e3, G=[[-20.0]], delay=0.01)
    opts = NewmarkOptions(max_history_bytes=200_000, max_output_bytes=100_000)
    r = newmark(prob, (0, 5.0), 1e-4, q0=[1e-3], record_every=100, options=opts)
    assert r.status == "ok" and r.n_steps == 50_000 and r.q.shape == (1, 501)
    ref = newmark(prob, (0, 5.0), 1e-4, q0=[1e-3])
    np.testing.assert_array_equal(r.q, ref.q[:, ::100])


# --------------------------------------------------------------------------- status


def test_divergence_is_a_status_with_the_time():
    # negative damping: x ~ exp(0.5 t) cos(...): |x| passes 1e-3 * e^{0.5 t} = limit at
    # t = 2 ln(limit/1e-3); with limit 1e3 that is ~27.6 s (first crossing slightly later
    # as the envelope is only touched at the peaks)
    r = newmark(
        sdof(1.0, -1.0, 100.0), (0.0, 100.0), 0.01, q0=[1e-3], options=NewmarkOptions(divergence_limit=1e3)
    )
    assert r.status == "diverged"
    assert "diverged at t =" in r.message
    t_div = float(r.message.split("t = ")[1].split(" s")[0])
    assert 27.0 < t_div < 29.5
    assert r.t[-1] < t_div and np.all(np.abs(r.q) <= 1e3) and np.all(np.isfinite(r.q))
    # an overflow to inf/nan (no RuntimeWarning escapes) is reported the same way
    r2 = newmark(
        sdof(1.0, -400.0, 1.0), (0.0, 50.0), 0.01, q0=[1.0], options=NewmarkOptions(divergence_limit=1e308)
    )
    assert r2.status == "diverged" and np.all(np.isfinite(r2.q))


def test_interrupt_and_callback_stop_return_partial_results():
    M, C, K = chain3()
    prob = CallbackProblem(3, M, C, K, force=[0, 0, 1.0])
    full = newmark(prob, (0, 1.0), 1e-3, options=NewmarkOptions(chunk=100))
    calls = []

    def progress(frac):
        calls.append(frac)
        if len(calls) == 3:
            raise KeyboardInterrupt

    part = newmark(prob, (0, 1.0), 1e-3, options=NewmarkOptions(chunk=100), progress=progress)
    assert part.status == "interrupted" and "interrupted" in part.message
    assert part.n_steps == 300 and part.t.size == 301
    np.testing.assert_array_equal(part.q, full.q[:, :301])
    assert calls == pytest.approx([0.1, 0.2, 0.3])

    def stop_after_half(t, q, v, a):
        assert q.shape == (3,)
        return t >= 0.5 - 1e-12

    stopped = newmark(prob, (0, 1.0), 1e-3, options=NewmarkOptions(chunk=100), callback=stop_after_half)
    assert stopped.status == "stopped" and stopped.n_steps == 500
    np.testing.assert_array_equal(stopped.q, full.q[:, :501])


def test_conditionally_stable_parameters_warn_and_nonsense_is_refused():
    with pytest.warns(NewmarkStabilityWarning, match="conditionally stable"):
        r = newmark(
            sdof(1.0, 0.0, 1.0), (0, 1.0), 0.1, q0=[1.0], options=NewmarkOptions(gamma=0.5, beta=1 / 6)
        )  # linear acceleration
    assert "not unconditionally stable" in r.message
    assert NewmarkOptions().unconditionally_stable
    assert NewmarkOptions(gamma=0.6, beta=0.3025).unconditionally_stable
    with pytest.raises(InputError, match="beta must be > 0"):
        NewmarkOptions(beta=0.0)
    with pytest.raises(InputError, match="gamma must be >= 1/2"):
        NewmarkOptions(gamma=0.4)
    with pytest.raises(InputError, match="chunk"):
        NewmarkOptions(chunk=0)
    # numerical damping of gamma > 1/2 (order 1): amplitude decays, no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = newmark(
            sdof(1.0, 0.0, 1.0), (0, 200.0), 0.5, q0=[1.0], options=NewmarkOptions(gamma=0.6, beta=0.3025)
        )
    # numerical damping ratio ~ (gamma - 1/2) w h / 2 = 0.025: exp(-0.025 * 190) ~ 0.01
    assert np.abs(r.q[0, -20:]).max() < 0.05


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(h=0.02), r"h = 0\.02 s is larger than the delay T = 0\.01 s"),
        (dict(t_span=(1.0, 0.5)), "duration t1 - t0 must be > 0"),
        (dict(t_span=(0.0, 0.0)), "duration t1 - t0 must be > 0"),
        (dict(h=0.0), r"h \(time step\) must be a finite number > 0"),
        (dict(h=-1e-3), r"h \(time step\) must be a finite number > 0"),
        (dict(h=float("nan")), r"h \(time step\)"),
        (dict(h=2.0), "longer than the duration"),
        (dict(q0=[1.0, 2.0]), r"q0 must have shape \(1,\)"),
        (dict(v0=[float("nan")]), "v0 contains NaN"),
        (dict(t_span=(0.0, float("inf"))), "t_span must be finite"),
        (dict(record_every=0), "record_every"),
        (dict(outputs=[3]), "outputs"),
        (dict(history=np.zeros(2)), "history"),
        (dict(history=lambda t: np.zeros((t.size, 2))), r"history\(t\) must return shape"),
        (
            dict(options=NewmarkOptions(max_history_bytes=10_000), h=1e-5),
            r"needs \d+ stored steps .*max_history_bytes.*larger step h",
        ),
        (dict(options=NewmarkOptions(max_output_bytes=1000)), "record_every"),
    ],
)
def test_bad_input_raises_input_error(kwargs, match):
    args = dict(problem=sdof(1.0, 0.1, 100.0, G=[[-1.0]], delay=0.01), t_span=(0.0, 1.0), h=1e-3, q0=[1e-3])
    args.update(kwargs)
    with pytest.raises(InputError, match=match):
        newmark(**args)


def test_bad_problems_raise_input_error():
    with pytest.raises(InputError, match="must be 2x2 like M"):
        ConstantProblem(np.eye(2), np.eye(3), np.eye(2))
    with pytest.raises(InputError, match="G is given but delay is None"):
        ConstantProblem(np.eye(2), np.eye(2), np.eye(2), G=np.eye(2))
    with pytest.raises(InputError, match="force"):
        newmark(ConstantProblem(np.eye(2), np.eye(2), np.eye(2), force=lambda t: np.zeros(3)), (0, 1), 0.1)
    bad_shape = CallbackProblem(2, np.eye(2), np.eye(2), lambda t: np.eye(3))
    with pytest.raises(InputError, match=r"C\(t\) must return shape \(2, 2\)"):
        newmark(bad_shape, (0, 1), 0.1)
    nan_later = CallbackProblem(1, [[1.0]], [[0.0]], lambda t: [[1.0 if t < 0.5 else np.nan]])
    with pytest.raises(InputError, match=r"C has NaN/inf entries at t = 0\.5"):
        newmark(nan_later, (0, 1), 0.1)
    with pytest.raises(InputError, match="A.t0. is singular"):
        newmark(ConstantProblem(np.zeros((1, 1)), [[0.0]], [[1.0]]), (0, 1), 0.1)
    with pytest.raises(InputError, match="problem must provide"):
        newmark(object(), (0, 1), 0.1)


# --------------------------------------------------------------------------- result object


def test_time_response_csv_and_plot(tmp_path):
    r = newmark(sdof(1.0, 0.1, 100.0), (0, 0.1), 0.01, q0=[1.0], outputs={"tip": 0})
    p = r.to_csv(tmp_path / "r.csv", fields=("q", "v"))
    data = np.loadtxt(p, delimiter=",", skiprows=1, usecols=(0, 1, 2))
    assert open(p).readline().strip() == "t [s],q:tip,v:tip,status"
    assert all(line.endswith(",ok") for line in open(p).read().splitlines()[1:])
    np.testing.assert_array_equal(data[:, 0], r.t)
    np.testing.assert_array_equal(data[:, 1], r.q[0])
    from chatterlab.io import _netcdf as netcdf  # our own module: an import error fails the test

    back = netcdf.read_netcdf(r.to_netcdf(tmp_path / "r.nc"))
    np.testing.assert_array_equal(back.data["q"][0], r.q)
    np.testing.assert_array_equal(back.coords["time"][0], r.t)
    assert back.attrs["output_names"] == "tip" and back.attrs["status"] == "ok"
    import matplotlib  # a dependency of chatterlab, never skipped

    matplotlib.use("Agg")
    ax = r.plot("tip")
    assert ax.get_xlabel() == "t [s]"
    # the figure draws the response itself, not just labelled axes
    (line,) = ax.get_lines()
    np.testing.assert_array_equal(line.get_xdata(), r.t)
    np.testing.assert_array_equal(line.get_ydata(), r.q[0])
    assert line.get_label() == "tip"
    import matplotlib.pyplot as plt

    plt.close("all")


# --------------------------------------------------------------------------- signals


def test_amplitude_spectrum_sine_peak_height_and_frequency():
    fs, dur = 1000.0, 2.0
    t = np.arange(int(fs * dur)) / fs
    a1, f1, a2, f2 = 0.3, 73.3, 0.05, 180.0  # 73.3 Hz is off the 0.5 Hz bin grid
    x = 2.0 + a1 * np.sin(2 * np.pi * f1 * t + 0.4) + a2 * np.cos(2 * np.pi * f2 * t)
    f, amp = amplitude_spectrum(t, x, pad=1)
    # on-bin tone: exact height with the coherent-gain correction
    i2 = np.argmin(np.abs(f - f2))
    assert abs(amp[i2] - a2) < 1e-3 * a2
    # off-bin tone without padding: the raw bin suffers scalloping (Hann, 0.4 bin: -9.9 %)
    i1 = np.argmin(np.abs(f - f1))
    assert amp[i1] < 0.95 * a1
    # with the default zero padding (pad=4, 0.125 Hz grid) the raw peak is within 1 %
    # (worst case over the bin position measured 0.93 %) and peaks() refines it by a
    # parabola on log |X| (the Hann lobe is nearly Gaussian near its top): worst case
    # over the position measured 9e-5 in height and 1e-4 Hz
    f4, amp4 = amplitude_spectrum(t, x)
    fr, ar = peaks(f4, amp4, 2, fmin=1.0, refine=False)
    assert abs(ar[0] / a1 - 1) < 0.01
    fp, ap = peaks(f4, amp4, 2, fmin=1.0)
    assert abs(fp[0] - f1) < 1e-3 and abs(ap[0] / a1 - 1) < 1e-3
    assert abs(fp[1] - f2) < 1e-3 and abs(ap[1] / a2 - 1) < 1e-3
    # detrend removes the offset: nothing left at DC
    assert amp4[0] < 1e-3
    # a rectangular window of a whole number of periods is exact as well
    fb, ab = amplitude_spectrum(t, np.sin(2 * np.pi * 50.0 * t), window=None, pad=1, detrend=False)
    assert abs(ab[np.argmin(np.abs(fb - 50.0))] - 1.0) < 1e-12


@pytest.mark.parametrize("sigma", [2.0, -2.0])
@pytest.mark.parametrize("method", ["extrema", "hilbert"])
def test_growth_rate_of_known_exponential(sigma, method):
    t = np.arange(0, 5.0, 1e-3)
    x = 0.7 + np.exp(sigma * t) * np.sin(2 * np.pi * 7.3 * t + 0.3)  # with a static offset
    est = growth_rate(t, x, method=method)
    # measured: extrema 4e-8 / 6e-8 relative (exact for this signal up to the parabolic
    # refinement of the sampled extremes), hilbert 2.6e-4 / 4e-6 (edge trimming)
    assert abs(est.rate - sigma) < 0.01 * abs(sigma), est
    assert est.classification == ("growing" if sigma > 0 else "decaying")
    assert est.r2 > 0.999


def test_growth_rate_classification_and_undetermined():
    t = np.arange(0, 4.0, 1e-3)
    steady = growth_rate(t, np.sin(2 * np.pi * 5 * t) * (1 + 1e-3 * t))
    assert steady.classification == "steady" and abs(steady.rate) < 1e-2
    # 0.01 1/s over the 3.2 s window: factor 1.03 < 1.05 -> steady; tol=0.01 -> growing
    slow = np.exp(0.01 * t) * np.sin(2 * np.pi * 5 * t)
    assert growth_rate(t, slow).classification == "steady"
    assert growth_rate(t, slow, tol=0.01).classification == "growing"
    flat = growth_rate(t, 1.0 + 0 * t)
    assert flat.classification == "undetermined" and math.isnan(flat.rate)
    with pytest.raises(InputError, match="uniformly spaced"):
        growth_rate(np.r_[0, 1, 3, 4, 5, 6, 7, 8, 9], np.zeros(9))


# --------------------------------------------------------------------------- the one core


def test_hermite_interpolation_is_exact_for_cubics_and_written_once():
    """The core's cubic Hermite weights reproduce any cubic from its values
    and slopes at two steps (to rounding), their error on a smooth history
    falls as h^4; and the formula exists once in the package (newmark's
    delay off the grid and the milling cut's passes both read it)."""
    from pathlib import Path

    import chatterlab
    from chatterlab.time._core import hermite_weights

    rng = np.random.default_rng(7)
    c = rng.normal(size=4)
    p = np.polynomial.Polynomial(c)
    dp = p.deriv()
    t0, h = 0.3, 0.7
    s = np.linspace(0.0, 1.0, 11)
    w0, w1, w2, w3 = hermite_weights(s, h)
    got = w0 * p(t0) + w1 * dp(t0) + w2 * p(t0 + h) + w3 * dp(t0 + h)
    np.testing.assert_allclose(got, p(t0 + s * h), rtol=0, atol=1e-14 * np.abs(c).sum() * 4)
    errs = []
    for hh in (0.1, 0.05, 0.025):
        w0, w1, w2, w3 = hermite_weights(0.37, hh)
        errs.append(abs(w0 * np.sin(0.2) + w1 * np.cos(0.2) + w2 * np.sin(0.2 + hh) + w3 * np.cos(0.2 + hh)
                        - np.sin(0.2 + 0.37 * hh)))  # fmt: skip
    assert 14 < errs[0] / errs[1] < 18 and 14 < errs[1] / errs[2] < 18  # 2^4
    src = [q.read_text() for q in Path(chatterlab.__file__).parent.rglob("*.py")]
    assert sum(t.count("2 * s3 - 3 * s2 + 1") for t in src) == 1


def test_a_delay_is_placed_on_the_grid_once():
    """delay_on_grid: d = whole + rem, rem = 0 within 1e-9 (relative) of a
    whole number of steps, so the delayed value is a stored step."""
    from chatterlab.time._core import delay_on_grid

    d = np.array([5.0, 5.0 + 1e-12, 5.0 - 1e-12, 5.25, 1.0, 123.999999, 1e6 + 1e-4])
    whole, rem = delay_on_grid(d)
    assert whole.tolist() == [5, 5, 5, 5, 1, 123, 1000000]
    assert rem[[0, 1, 2, 4, 6]].tolist() == [0.0] * 5
    assert rem[3] == 0.25 and rem[5] == pytest.approx(0.999999, abs=1e-9)
    np.testing.assert_allclose(whole + rem, d, rtol=1e-9)


def test_problems_are_values():
    """A problem is immutable: nothing sets its attributes after it is built."""
    p = ConstantProblem([[1.0]], [[0.1]], [[4.0]])
    with pytest.raises(AttributeError, match="immutable"):
        p.K = np.array([[5.0]])
    cb = CallbackProblem(1, [[1.0]], [[0.0]], [[1.0]])
    with pytest.raises(AttributeError, match="immutable"):
        del cb.n
    pw = PiecewiseProblem([1.0], [p, p])
    with pytest.raises(AttributeError, match="immutable"):
        pw.pieces = []
