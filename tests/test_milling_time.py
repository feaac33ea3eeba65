"""Milling in the time domain (issue 12, item 5): the Newmark scheme with the
rotating cutting force, the tooth leaving the cut and multiple regeneration.

The oracles:

* linear runs: the growth per period of the Poincare samples equals ln|mu| of
  the critical Floquet multiplier, computed here by an independent
  first-order semi-discretisation (Insperger, Stepan & Turi 2008) of the
  1-DOF benchmark of Insperger & Stepan (N = 2, K_t = 6e8 N/m^2,
  K_n = 2e8 N/m^2, f_n = 922 Hz, zeta = 0.011, m = 0.03993 kg, down-milling);
  the tolerance is the sum of both discretisation errors, each estimated from
  three resolutions (the geometric tail of the differences);
* the fitted convergence order of the scheme (2, with the entry of a tooth
  off the step grid);
* the generic Newmark solver (:func:`chatterlab.time.newmark`) integrating the
  same linear equation: the same numbers to round-off;
* the limit of zero depth: the forced response to the static cutting force,
  whose Fourier series is closed-form, and the static forces of
  :meth:`Milling.tooth_forces`;
* runout on a rigid tool: the chip of each tooth is the closed-form minimum
  over the previous passes (one tooth cuts the whole feed per revolution);
* below the limit the nonlinear run converges to a periodic orbit, above it
  it saturates (the linear run at the same depth grows); the flip orbit's
  frequency is a half harmonic of the tooth passing frequency;
* bad input: one line, InputError.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.process._milling import Milling
from chatterlab.time import CallbackProblem, Initial, Integration, newmark
from chatterlab.time._milling import MillingSimulation, default_steps_per_period, simulate_milling

# ----------------------------------------------------------------------------- the benchmark


@pytest.fixture(autouse=True, scope="module")
def _one_blas_thread():
    """Small dense products only: one BLAS thread (a threaded BLAS on a loaded
    2-core machine made this module 4x slower; results agree to round-off)."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(1):
        yield


MASS = 0.03993
WN = 2.0 * math.pi * 922.0
ZETA = 0.011
KT, KN = 6e8, 2e8
ONE_DOF = ([[MASS]], [[2.0 * ZETA * MASS * WN]], [[MASS * WN**2]])


def cutter(immersion: float, **kw) -> Milling:
    return Milling.from_immersion(2, 0.02, KT, KN, immersion, "down", **kw)


# ----------------------------------------------------------------------------- independent reference


def _mean_h(t0: float, t1: float, mill: Milling, omega: float) -> np.ndarray:
    """Exact mean over [t0, t1] of each tooth's h_j(t) = g_j sin(phi_j) (K_t cos + K_n sin)(phi_j)
    (Insperger & Stepan's 1-DOF coefficient), phi_j = omega t - lag_j, from its primitive."""

    def prim(p: float) -> float:
        return KT * math.sin(p) ** 2 / 2.0 + KN * (p / 2.0 - math.sin(2.0 * p) / 4.0)

    out = np.zeros(mill.teeth)
    for j, lag in enumerate(mill.lags):
        a = omega * t0 - lag
        b = omega * t1 - lag
        k0 = math.floor((a - mill.exit) / (2 * math.pi)) + 1
        for k in range(k0, math.floor((b - mill.entry) / (2 * math.pi)) + 1):
            lo = max(a, mill.entry + 2 * math.pi * k)
            hi = min(b, mill.exit + 2 * math.pi * k)
            if hi > lo:
                out[j] += prim(hi - 2 * math.pi * k) - prim(lo - 2 * math.pi * k)
    return out / (b - a)


def sd_revolution_multiplier(mill: Milling, rpm: float, ap: float, k: int) -> complex:
    """Critical multiplier over one revolution of the 1-DOF benchmark with any
    pitch, by first-order semi-discretisation with k steps per revolution; the
    delays pitch_j / Omega must be multiples of the step (k a multiple of the
    pitch's denominator).  Same scheme as :func:`sd_multiplier` with one
    delayed term per tooth."""
    m_, c_, k_ = MASS, 2.0 * ZETA * MASS * WN, MASS * WN**2
    omega = 2.0 * math.pi * rpm / 60.0
    dt = 2.0 * math.pi / omega / k
    lag_steps = mill.pitches / (2 * math.pi) * k
    assert np.allclose(lag_steps, np.round(lag_steps), atol=1e-9), "delays off the SD grid"
    kd = np.round(lag_steps).astype(int)
    dim = int(kd.max()) + 2  # (x_i, v_i, x_{i-1}, ..., x_{i-kmax})
    col = {d: (d + 1 if d >= 1 else 0) for d in range(int(kd.max()) + 1)}  # x_{i-d} in the state
    Phi = np.eye(dim)
    for i in range(k):
        hb = _mean_h(i * dt, (i + 1) * dt, mill, omega)
        aug = np.zeros((4, 4))
        aug[:2, :2] = [[0.0, 1.0], [-(k_ + ap * hb.sum()) / m_, -c_ / m_]]
        aug[1, 2] = 1.0
        aug[2, 3] = 1.0
        E = expm(aug * dt)
        new = np.empty_like(Phi)
        new[:2] = E[:2, :2] @ Phi[:2]
        for j, d in enumerate(kd):  # x(t - d_j) linear between x_{i-d} and x_{i-d+1}
            w = ap * hb[j] / m_
            new[:2] += w * np.outer(E[:2, 2] - E[:2, 3] / dt, Phi[col[d]])
            new[:2] += w * np.outer(E[:2, 3] / dt, Phi[col[d - 1]])
        new[2] = Phi[0]
        new[3:] = Phi[2 : dim - 1]
        Phi = new
    ev = np.linalg.eigvals(Phi)
    return complex(ev[np.argmax(np.abs(ev))])


def sd_multiplier(mill: Milling, rpm: float, ap: float, k: int) -> complex:
    """Critical multiplier of the 1-DOF benchmark by first-order semi-
    discretisation with k steps per period (Insperger, Stepan & Turi, J. Sound
    Vib. 313 (2008) 334-341): on each step the coefficients are their mean and
    the delayed displacement is linear between its two grid values; each step
    is solved exactly (augmented matrix exponential)."""
    m_, c_, k_ = MASS, 2.0 * ZETA * MASS * WN, MASS * WN**2
    omega = 2.0 * math.pi * rpm / 60.0
    dt = 2.0 * math.pi / (mill.teeth * omega) / k
    dim = k + 2  # (x_i, v_i, x_{i-1}, ..., x_{i-k})
    Phi = np.eye(dim)
    for i in range(k):
        hb = _mean_h(i * dt, (i + 1) * dt, mill, omega).sum()
        aug = np.zeros((4, 4))
        aug[:2, :2] = [[0.0, 1.0], [-(k_ + ap * hb) / m_, -c_ / m_]]
        aug[1, 2] = ap * hb / m_
        aug[2, 3] = 1.0
        E = expm(aug * dt)
        # the step map: (x, v) from E, the stored displacements shift by one
        new = np.empty_like(Phi)
        new[:2] = E[:2, :2] @ Phi[:2] + np.outer(E[:2, 2] - E[:2, 3] / dt, Phi[dim - 1])
        new[:2] += np.outer(E[:2, 3] / dt, Phi[dim - 2])
        new[2] = Phi[0]
        new[3:] = Phi[2 : dim - 1]
        Phi = new
    ev = np.linalg.eigvals(Phi)
    return complex(ev[np.argmax(np.abs(ev))])


def tail_bound(d1: float, d2: float) -> float:
    """Bound on the error of the finest of three results whose successive
    differences are d1, d2 (the step halved each time): if the differences keep
    shrinking by at least rho = min(d1/d2, 2) -- order >= 1 -- the remaining
    error is at most the geometric tail d2 / (rho - 1), i.e. d2 once the
    observed ratio is 2 or more.  The observed ratio must exceed 1
    (converging), else the comparison would be vacuous."""
    assert d1 > d2 > 0 or d1 == d2 == 0, f"not converging: differences {d1:.3g}, {d2:.3g}"
    return 0.0 if d2 == 0 else d2 / (min(d1 / d2, 2.0) - 1.0)


def richardson(values: list[float]) -> tuple[float, float]:
    """Finest of three values (the step halved each time) and its error bound
    (:func:`tail_bound`)."""
    return values[2], tail_bound(abs(values[1] - values[0]), abs(values[2] - values[1]))


# ----------------------------------------------------------------------------- linear runs vs Floquet

CASES = [
    # immersion, rpm, a_p: the type of the critical multiplier (from the SD reference)
    pytest.param(0.05, 10000.0, 5e-3, id="ae0.05-flip-unstable"),
    pytest.param(0.05, 5000.0, 3e-3, id="ae0.05-hopf-unstable"),
    pytest.param(1.0, 25000.0, 2e-3, id="ae1-stable"),
    pytest.param(1.0, 20000.0, 3e-3, id="ae1-flip-unstable"),
]


@pytest.mark.parametrize(("immersion", "rpm", "ap"), CASES)
def test_linear_growth_per_period_is_ln_of_the_floquet_multiplier(immersion, rpm, ap):
    mill = cutter(immersion)
    td = [
        simulate_milling(
            ONE_DOF, mill, rpm, ap, nonlinear=False, integration=Integration(steps_per_period=m, periods=40)
        )
        for m in (100, 200, 400)
    ]
    sd = [sd_multiplier(mill, rpm, ap, k) for k in (40, 80, 160)]
    g_td, err_td = richardson([r.growth_per_period for r in td])
    g_sd, err_sd = richardson([math.log(abs(mu)) for mu in sd])
    # the Poincare estimate itself: the fit on the last half against the last quarter
    err_fit = td[-1].growth_error
    assert abs(g_td - g_sd) <= err_td + err_sd + err_fit, (g_td, g_sd, err_td, err_sd, err_fit)
    # the same kind of multiplier, and the same multiplier in the complex plane
    mu_td, mu_sd = td[-1].multiplier, sd[-1]
    assert abs(mu_td - mu_sd) <= (err_td + err_sd + err_fit) * abs(mu_sd) + abs(mu_td - td[-2].multiplier), (
        mu_td,
        mu_sd,
    )
    flip = abs(mu_sd.imag) < 1e-9 and mu_sd.real < 0
    expect = "stable" if abs(mu_sd) < 1 else ("flip chatter" if flip else "Hopf chatter")
    assert td[-1].verdict == expect, td[-1].reason
    assert td[-1].status == "ok"


def modal_tool() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A modal model as a CutPro user types it: three modes (922, 1100, 3000 Hz;
    zeta 1.1, 2, 3 %; modal stiffness 1.34, 2, 8 MN/m) along 0, 60 and 90 deg
    in the x-y plane; P holds the mode shapes at the tool point."""
    f = np.array([922.0, 1100.0, 3000.0])
    zeta = np.array([0.011, 0.02, 0.03])
    k = np.array([1.34e6, 2.0e6, 8.0e6])
    w = 2 * np.pi * f
    m = k / w**2
    ang = np.radians([0.0, 60.0, 90.0])
    return np.diag(m), np.diag(2 * zeta * w * m), np.diag(k), np.vstack([np.cos(ang), np.sin(ang)])


def two_dof() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The benchmark's parameters in x and in y."""
    M, C, K = (np.eye(2) * np.asarray(a)[0, 0] for a in ONE_DOF)
    return M, C, K, np.eye(2)


@pytest.mark.parametrize(
    ("structure", "immersion", "rpm", "ap", "m"),
    [
        pytest.param("1dof", 0.05, 10000.0, 5e-3, 100, id="1dof-flip"),
        pytest.param("2dof", 0.1, 10000.0, 0.5e-3, 100, id="2dof-stable"),
        pytest.param("modal", 0.05, 10000.0, 1e-3, 200, id="modal-stable"),
        pytest.param("modal", 0.3, 8000.0, 1e-3, 200, id="modal-hopf"),
        pytest.param("1dof", -0.05, 12500.0, 3e-3, 100, id="1dof-up-milling"),
    ],
)
def test_linear_growth_equals_the_spectral_floquet_reference(structure, immersion, rpm, ap, m):
    """Against chatterlab.frequency.multipliers (spectral-element collocation of
    the monodromy operator, converged to ~1e-10: its own check is in the
    tolerance): the 1-DOF, the 2-DOF x/y benchmark (two pairs of multipliers
    near each other) and a three-mode modal model.  Tolerance: the time
    domain's error from m, 2m, 4m (the tail of its differences) + the fit's + the reference's."""
    from chatterlab.frequency import multipliers
    from chatterlab.process import milling_loop
    from chatterlab.structure import Structure

    if structure == "1dof":
        M, C, K = (np.asarray(a, dtype=float) for a in ONE_DOF)
        P = np.array([[1.0], [0.0]])
    else:
        M, C, K, P = two_dof() if structure == "2dof" else modal_tool()
    # a negative immersion stands for up-milling
    mill = cutter(immersion) if immersion > 0 else Milling.from_immersion(2, 0.02, KT, KN, -immersion, "up")
    ref = multipliers(milling_loop(Structure(M, C, K), mill, P), rpm, ap)
    td = [
        simulate_milling(
            (M, C, K),
            mill,
            rpm,
            ap,
            tool_point=P,
            nonlinear=False,
            integration=Integration(steps_per_period=k, periods=40),
        )
        for k in (m, 2 * m, 4 * m)
    ]
    g_td, err_td = richardson([r.growth_per_period for r in td])
    g_ref = math.log(abs(ref.critical))
    tol = err_td + td[-1].growth_error + ref.error
    assert abs(g_td - g_ref) <= tol, (g_td, g_ref, err_td, td[-1].growth_error, ref.error)
    expect = "stable" if ref.stable else {"flip": "flip chatter", "hopf": "Hopf chatter"}[ref.kind]
    assert td[-1].verdict == expect, td[-1].reason


@pytest.mark.parametrize(
    ("rpm", "ap"), [pytest.param(10000.0, 5e-3, id="hopf-unstable"), pytest.param(7500.0, 3e-3, id="stable")]
)
def test_variable_pitch_growth_per_revolution_is_ln_of_the_floquet_multiplier(rpm, ap):
    """Pitch 144 deg / 216 deg: two delays.  The steps per tooth period
    m = 101, 202, 404 put the delays 0.8 m and 1.2 m steps off the grid (Hermite
    interpolation); the SD reference uses 80, 160, 320 steps per revolution,
    where they fall on its grid.  The samples are once per revolution."""
    vp = Milling.from_immersion(2, 0.02, KT, KN, 0.05, "down", pitch=(0.8 * math.pi, 1.2 * math.pi))
    td = [
        simulate_milling(
            ONE_DOF, vp, rpm, ap, nonlinear=False, integration=Integration(steps_per_period=m, periods=40)
        )
        for m in (101, 202, 404)
    ]
    assert math.isclose(td[-1].sample_period, 60.0 / rpm, rel_tol=1e-12)
    sd = [sd_revolution_multiplier(vp, rpm, ap, k) for k in (80, 160, 320)]
    g_td, err_td = richardson([r.growth_per_period for r in td])
    g_sd, err_sd = richardson([math.log(abs(mu)) for mu in sd])
    err_fit = td[-1].growth_error
    assert abs(g_td - g_sd) <= err_td + err_sd + err_fit, (g_td, g_sd, err_td, err_sd, err_fit)
    mu_td, mu_sd = td[-1].multiplier, sd[-1]
    assert abs(mu_td - mu_sd) <= (err_td + err_sd + err_fit) * abs(mu_sd) + abs(mu_td - td[-2].multiplier)
    assert td[-1].verdict == ("stable" if abs(mu_sd) < 1 else "Hopf chatter")


def test_sd_reference_over_a_revolution_is_the_tooth_period_one_to_the_power_n():
    """The two references agree on a uniform pitch: mu_rev = mu_tau^N (the
    coefficients are tau-periodic), same steps per tooth period."""
    mill = cutter(0.05)
    mu_tau = sd_multiplier(mill, 10000.0, 5e-3, 40)
    mu_rev = sd_revolution_multiplier(mill, 10000.0, 5e-3, 80)
    assert abs(mu_rev - mu_tau**2) <= 1e-9 * abs(mu_rev)


def test_chatter_frequency_of_a_linear_run_matches_the_multiplier_angle():
    """A growing Hopf run: the spectral peak is (arg mu / 2 pi + k) / T for some k,
    within the spectral resolution."""
    r = simulate_milling(
        ONE_DOF,
        cutter(0.05),
        5000.0,
        0.003,
        nonlinear=False,
        integration=Integration(steps_per_period=200, periods=60),
    )
    assert r.verdict == "Hopf chatter"
    T = r.sample_period
    frac = math.atan2(r.multiplier.imag, r.multiplier.real) / (2 * math.pi)
    k = round(r.chatter_frequency * T - frac)
    resolution = 2.0 / (r.t[-1] / 2.0)
    candidates = [(frac + k) / T, (-frac + round(r.chatter_frequency * T + frac)) / T]
    assert min(abs(r.chatter_frequency - f) for f in candidates) <= resolution
    # and it is near the natural frequency (regenerative chatter): within its half-power band x 10
    assert abs(r.chatter_frequency - 922.0) < 0.2 * 922.0


def test_second_order_convergence_with_the_tooth_entering_between_steps():
    """x(t_end) at m = 200 .. 1600 steps per tooth period: the differences fall
    by 4 per halving (fitted slope 2).  At a_e/D = 0.05 the tooth enters at
    phi = 2.69 rad, off the grid: a first-order treatment of that jump would
    give slope 1."""
    mill = cutter(0.05)
    ms = [200, 400, 800, 1600]
    ends = []
    for m in ms:
        r = simulate_milling(
            ONE_DOF,
            mill,
            5000.0,
            0.002,
            nonlinear=False,
            integration=Integration(steps_per_period=m, periods=4),
            initial=Initial(q0=[0.0], v0=[0.001]),
        )
        ends.append(np.array([r.x[-1], r.vx[-1] / WN]))
    diffs = [np.linalg.norm(ends[i] - ends[i + 1]) for i in range(len(ends) - 1)]
    slope = -np.polyfit(np.log(ms[:-1]), np.log(diffs), 1)[0]
    # the asymptotic ratio of a second-order method is 4 (slope 2); the next
    # term, O(1/m) relative, is below 1/200 x a few: +-0.15 on the slope
    assert abs(slope - 2.0) < 0.15, (slope, diffs)


def test_linear_mode_equals_the_generic_newmark_solver():
    """The 2-DOF benchmark (same parameters in x and y), full immersion (the
    teeth enter and leave on the grid): the generic solver integrating
    M q'' + C q' + (K + a_p H(t)) q = a_p H(t) q(t - tau) gives the same numbers,
    to round-off (1000 steps, growth x 1e8: relative 1e-9 allows 1e-16 x
    1000 steps x the amplification of the round-off by the growth)."""
    M, C, K = (np.eye(2) * np.asarray(a)[0, 0] for a in ONE_DOF)
    mill = cutter(1.0)
    rpm, ap, m = 20000.0, 1e-3, 50
    tau = mill.tooth_period(rpm)
    h = tau / m
    r = simulate_milling(
        (M, C, K),
        mill,
        rpm,
        ap,
        nonlinear=False,
        integration=Integration(steps_per_period=m, periods=10),
        initial=Initial(q0=[0, 0], v0=[0.001, 0.002]),
    )
    eps = 1e-11 * h  # right-continuous coefficients (the solver takes left limits at breakpoints)

    def H(t):
        return ap * mill.directional(np.asarray(t) + eps, rpm).sum(axis=-3)

    prob = CallbackProblem(
        2, M, C, lambda t: K + H(t), G=H, delay=tau, vectorized=True, breakpoints=np.arange(0, 21) * tau
    )
    ref = newmark(prob, (0.0, r.t[-1]), h, v0=[1e-3, 2e-3])
    assert ref.q.shape[1] == r.t.size
    scale = np.max(np.abs(r.x))
    assert scale > 1e-3  # it grew by orders of magnitude: the comparison is not of zeros
    assert np.max(np.abs(ref.q[0] - r.x)) <= 1e-9 * scale
    assert np.max(np.abs(ref.q[1] - r.y)) <= 1e-9 * np.max(np.abs(r.y))


# ----------------------------------------------------------------------------- forced response


def _static_fourier(mill: Milling, ap: float, fz: float, l: np.ndarray) -> np.ndarray:
    """f_l = (1/2pi) int_entry^exit f(phi) e^{-i l phi} dphi for the static
    F_x(phi) = -a_p f_z (K_t sin cos + K_n sin^2) of one tooth, closed form
    (sin cos = sin 2phi / 2, sin^2 = (1 - cos 2phi) / 2)."""

    def integral(beta: np.ndarray) -> np.ndarray:  # int_a^b e^{i beta phi} dphi
        a, b = mill.entry, mill.exit
        out = np.empty(beta.shape, dtype=complex)
        z = beta == 0
        out[z] = b - a
        bb = beta[~z]
        out[~z] = (np.exp(1j * bb * b) - np.exp(1j * bb * a)) / (1j * bb)
        return out

    l = l.astype(float)
    sin2 = (integral(2 - l) - integral(-2 - l)) / 2j  # int sin(2 phi) e^{-i l phi}
    cos2 = (integral(2 - l) + integral(-2 - l)) / 2.0
    integral = KT * sin2 / 2.0 + KN * (integral(-l) - cos2) / 2.0
    return -ap * fz * integral / (2.0 * math.pi)


def test_zero_depth_limit_is_the_forced_response_to_the_static_force():
    """a_p -> 0: the regenerative coupling vanishes relative to the static force
    (both scale with a_p, the coupling once more), so x(t) is the steady
    response of the 1-DOF to the periodic static force, a Fourier series with
    closed-form coefficients.  Tolerance: the Newmark error (tail of the
    differences from m, 2m, 4m) + the coupling, bounded by a_p N (K_t^2 + K_n^2)^(1/2) x 2 max|r| x max|G|
    relative, + the transient exp(-zeta w_n t) left after 60 revolutions."""
    mill = cutter(0.05)
    rpm, ap, fz = 10000.0, 1e-10, 1e-4
    runs = [
        simulate_milling(
            ONE_DOF, mill, rpm, ap, feed=fz, integration=Integration(steps_per_period=m, periods=60)
        )
        for m in (100, 200, 400)
    ]
    r = runs[-1]
    omega = 2 * math.pi * rpm / 60.0
    N = mill.teeth
    l = N * np.arange(-2000, 2001)  # the tail beyond is O(1/l^3): < 1e-6 relative
    c_l = N * _static_fourier(mill, ap, fz, l)
    k_, c_, m_ = MASS * WN**2, 2 * ZETA * MASS * WN, MASS
    G = 1.0 / (k_ - m_ * (l * omega) ** 2 + 1j * c_ * l * omega)
    coarse = runs[0]
    last = coarse.t >= coarse.t[-1] - 60.0 / rpm  # the last revolution, on the coarse grid
    t = coarse.t[last]
    on = [run.x[:: 2**i][last] for i, run in enumerate(runs)]  # every run at those times
    assert np.array_equal(runs[2].t[::4], coarse.t)
    x_ss = np.real(np.exp(1j * np.outer(t, l * omega)) @ (c_l * G))
    scale = np.max(np.abs(x_ss))
    # Newmark error of the finest run, bounded by the tail of its differences
    err_newmark = tail_bound(np.max(np.abs(on[1] - on[0])), np.max(np.abs(on[2] - on[1])))
    x_fine = on[2]
    Gmax = 1.0 / (2 * ZETA * k_ * math.sqrt(1 - ZETA**2))
    coupling = ap * N * math.hypot(KT, KN) * 2.0 * Gmax
    transient = math.exp(-ZETA * WN * t[0]) * 2.0
    tol = err_newmark + (coupling + transient) * scale
    assert np.max(np.abs(x_fine - x_ss)) <= tol, (np.max(np.abs(x_fine - x_ss)), tol, scale)
    assert err_newmark < 0.05 * scale  # the test says something: the error is small against the response
    # the forces are the static ones of Milling.tooth_forces, to the coupling
    phi = mill.tooth_angles(r.t, rpm)
    F = mill.tooth_forces(phi, fz * np.sin(phi), ap).sum(axis=-2)
    Fscale = np.max(np.abs(F))
    dyn = ap * N * math.hypot(KT, KN) * 2.0 * np.max(np.abs(r.x))
    assert np.max(np.abs(r.Fx - F[:, 0])) <= dyn + 1e-12 * Fscale
    assert np.max(np.abs(r.Fy - F[:, 1])) <= dyn + 1e-12 * Fscale
    assert r.verdict == "stable" and r.fraction_out_of_cut == 0.0


def test_runout_on_a_rigid_tool_one_tooth_cuts_the_feed_per_revolution():
    """Rigid tool (a_p -> 0): chip_j = min_k (k f_z sin phi + rho_j - rho_{j-k})
    (Eq. 2).  With rho_0 - rho_1 = 2 f_z, tooth 1 never cuts and tooth 0 cuts
    2 f_z sin phi; with 0.5 f_z both cut, min(f_z s + 0.5 f_z, 2 f_z s) and
    f_z s - 0.5 f_z."""
    mill = cutter(1.0)
    fz = 1e-4
    for delta in (2.0 * fz, 0.5 * fz):
        r = simulate_milling(
            ONE_DOF,
            mill,
            10000.0,
            1e-12,
            feed=fz,
            runout=[delta, 0.0],
            integration=Integration(steps_per_period=100, periods=3),
        )
        phi = mill.tooth_angles(r.t, 10000.0)
        s = np.sin(phi[:, 0])
        arc0 = mill.in_cut(phi[:, 0])
        arc1 = mill.in_cut(phi[:, 1])
        s1 = np.sin(phi[:, 1])
        h0 = np.minimum(fz * s + delta, 2 * fz * s)
        h1 = np.minimum(fz * s1 - delta, 2 * fz * s1)
        tol = 1e-12 * fz + 4 * np.max(np.abs(r.x))  # the deflection enters twice per pass
        late = r.t > 60.0 / 10000.0  # after the first revolution (the surface before t = 0 is ideal)
        assert np.max(np.abs(r.chip[0][arc0 & late] - h0[arc0 & late])) <= tol
        assert np.max(np.abs(r.chip[1][arc1 & late] - np.maximum(h1[arc1 & late], 0.0))) <= tol
        if delta >= fz:
            assert np.all(r.chip[1][late] == 0.0)
        # the sample period is the revolution with runout
        assert math.isclose(r.sample_period, 60.0 / 10000.0, rel_tol=1e-12)


def test_variable_pitch_on_a_rigid_tool_each_tooth_cuts_the_feed_of_its_pitch():
    """Rigid tool, pitch 144 / 216 deg: chip_j = N f_z (pitch_j / 2 pi) sin phi_j
    (the feed travelled since the preceding tooth); the delays are off the
    grid (Hermite), the deflection bounds the error."""
    vp = Milling.from_immersion(2, 0.02, KT, KN, 1.0, "down", pitch=(0.8 * math.pi, 1.2 * math.pi))
    fz, rpm = 1e-4, 10000.0
    r = simulate_milling(
        ONE_DOF, vp, rpm, 1e-12, feed=fz, integration=Integration(steps_per_period=101, periods=3)
    )
    phi = vp.tooth_angles(r.t, rpm)
    expect = 2 * fz * vp.pitches / (2 * math.pi) * np.sin(phi)
    arc = vp.in_cut(phi)
    tol = 1e-12 * fz + 4 * np.max(np.abs(r.x))
    assert np.max(np.abs(r.chip.T[arc] - expect[arc])) <= tol
    assert np.max(expect[:, 1][arc[:, 1]]) > 1.1 * fz  # the longer pitch (1.2 f_z per pass) cuts more


# ----------------------------------------------------------------------------- nonlinear runs


def test_below_the_limit_the_samples_converge_to_a_forced_periodic_orbit():
    """a_e/D = 0.05, 10000 rpm, 2 mm: |mu| = 0.53 by SD; the nonlinear run with
    feed converges (every tooth stays in the cut)."""
    mill = cutter(0.05)
    assert abs(sd_multiplier(mill, 10000.0, 2e-3, 40)) < 0.6
    r = simulate_milling(
        ONE_DOF, mill, 10000.0, 0.002, feed=0.0001, integration=Integration(steps_per_period=100, periods=60)
    )
    assert r.verdict == "stable", r.reason
    d = np.linalg.norm(np.diff(r.poincare[:, :2], axis=0), axis=1)
    assert d[-1] < 1e-6 * d[0]
    assert r.fraction_out_of_cut == 0.0
    assert np.all(r.chip >= 0.0)


@pytest.mark.parametrize(
    ("rpm", "ap", "kind"),
    [
        pytest.param(10000.0, 5e-3, "flip chatter", id="flip"),
        pytest.param(5000.0, 3e-3, "Hopf chatter", id="hopf"),
    ],
)
def test_above_the_limit_the_tool_leaves_the_cut_and_the_orbit_saturates(rpm, ap, kind):
    mill = cutter(0.05)
    nl = simulate_milling(
        ONE_DOF, mill, rpm, ap, feed=0.0001, integration=Integration(steps_per_period=100, periods=120)
    )
    lin = simulate_milling(
        ONE_DOF, mill, rpm, ap, nonlinear=False, integration=Integration(steps_per_period=100, periods=120)
    )
    n = nl.t.size
    q3, q4 = slice(n // 2, 3 * n // 4), slice(3 * n // 4, n)
    # bounded: over the last quarter a linear orbit multiplies by exp(ln|mu| P),
    # P the periods in a quarter (> 1e4 here); the saturated one stays within 20 %
    P = (n // 4) * nl.h / nl.sample_period
    assert lin.growth_per_period * P > math.log(1e4)
    ratio = np.ptp(nl.x[q4]) / np.ptp(nl.x[q3])
    # the test separates a saturated orbit (ratio -> 1; measured 0.998 and 1.001) from the growth of
    # the linear run over the same quarter (> 1e4, asserted above): it fails if the amplitude still
    # grows or decays by a fifth in a quarter of the run, i.e. if the tool never left the cut
    assert 1 / 1.2 < ratio < 1.2, ratio
    assert nl.status == "ok"
    assert nl.verdict == kind, nl.reason
    assert lin.verdict == kind, lin.reason
    assert 0.0 < nl.fraction_out_of_cut < 1.0
    assert np.all(nl.chip >= 0.0) and np.nanmin(nl.would_be_chip) < 0.0
    # the Poincare map rotates by theta = 2 pi f_c T per period (a closed curve) or
    # jumps between two points (theta = pi): successive differences have the
    # correlation cos(theta).  Independent of the spectrum's verdict: it reads
    # the samples only.  Tolerance 0.1: the cross terms of a finite window are
    # below 2 / (P |sin theta|) ~ 0.02 for P = 120 and the orbit is not a pure
    # sinusoid (its harmonics rotate by 2 theta, ...)
    p = nl.poincare[nl.poincare.shape[0] // 2 :, :2]
    d = np.diff(p, axis=0)
    corr = np.sum(d[1:] * d[:-1]) / math.sqrt(np.sum(d[1:] ** 2) * np.sum(d[:-1] ** 2))
    theta = 2 * math.pi * nl.chatter_frequency * nl.sample_period
    assert abs(corr - math.cos(theta)) < 0.1, (corr, theta)
    if kind == "flip chatter":
        assert corr < -0.9


def test_the_chip_is_the_minimum_over_the_recorded_passes():
    """In a chattering run with runout (teeth leaving the material), every
    recorded chip equals Eq. (2) rebuilt from the recorded tool path: pass k of
    tooth j is k m grid steps back, made by tooth j - k, with the feed k f_z
    (uniform pitch, so exact grid values).  Checks the bookkeeping of passes,
    tooth order and runout against the outputs."""
    mill = cutter(0.05)
    m, fz, rho = 60, 1e-4, np.array([2e-5, -1e-5])
    r = simulate_milling(
        ONE_DOF,
        mill,
        10000.0,
        0.005,
        feed=fz,
        runout=rho,
        passes=6,
        integration=Integration(steps_per_period=m, periods=40),
    )
    assert 0.1 < r.fraction_out_of_cut < 0.9
    phi = mill.tooth_angles(r.t, 10000.0)
    xy = np.stack([r.x, r.y], axis=1)
    n = r.t.size
    cand = np.full((6, n, 2), np.inf)
    for k in range(1, 7):
        past = np.zeros((n, 2))
        past[k * m :] = xy[: n - k * m]  # the nominal path before t = 0
        for j in range(2):
            nj = np.stack([np.sin(phi[:, j]), np.cos(phi[:, j])], axis=1)
            cand[k - 1, :, j] = (
                k * fz * nj[:, 0] + rho[j] - rho[(j - k) % 2] + np.sum(nj * (xy - past), axis=1)
            )
    expect = cand.min(axis=0).T
    arc = ~np.isnan(r.would_be_chip)
    assert np.all(arc[mill.in_cut(phi).T])  # recorded wherever the tooth is in the arc
    scale = fz + np.max(np.abs(xy))
    assert np.max(np.abs(r.would_be_chip[arc] - expect[arc])) <= 1e-12 * scale


def test_second_order_with_teeth_leaving_the_material_and_edge_forces():
    """Full immersion, 25000 rpm, 2 mm (stable), runout 0.05 mm = f_z / 2 and
    edge forces: the tooth with the smaller radius leaves the material where
    f_z sin(phi) < f_z / 2 and its edge force jumps there.  Those instants are
    located (h_j linear in the step -> 0) and the step split: the periodic
    orbit converges at second order (differences shrink by 4 per halving; an
    unlocated jump of the edge force would give 2, first order)."""
    mill = Milling.from_immersion(2, 0.02, KT, KN, 1.0, "down", Kte=2e4, Kne=1e4)
    ms = [100, 200, 400, 800]
    runs = [
        simulate_milling(
            ONE_DOF,
            mill,
            25000.0,
            0.002,
            feed=0.0001,
            runout=[5e-05, 0.0],
            integration=Integration(steps_per_period=m, periods=60),
        )
        for m in ms
    ]
    assert runs[-1].verdict == "stable" and 0.05 < runs[-1].fraction_out_of_cut < 0.5
    assert "located" in runs[-1].message
    last = runs[0].t >= runs[0].t[-1] - 60.0 / 25000.0
    x = [r.x[:: 2**i][last] for i, r in enumerate(runs)]
    diffs = [np.max(np.abs(x[i + 1] - x[i])) for i in range(len(x) - 1)]
    slope = -np.polyfit(np.log(ms[:-1]), np.log(diffs), 1)[0]
    assert abs(slope - 2.0) < 0.15, (slope, diffs)


def test_the_saturated_flip_orbit_converges_with_the_step():
    """The period-two orbit above the limit is a numerical object that
    converges: its two Poincare branches and its peak-to-peak amplitude at
    m = 200, 400, 800 differ by shrinking amounts, and the tail bound of the
    finest is below 1 % of the amplitude.  (The orbit is not exactly
    period-two -- a small quasi-periodic part -- so the ratios of these
    averages are erratic, 2 to 11, not the clean 4 of a periodic orbit.)"""
    out = []
    for m in (200, 400, 800):
        r = simulate_milling(
            ONE_DOF,
            cutter(0.05),
            10000.0,
            0.005,
            feed=0.0001,
            integration=Integration(steps_per_period=m, periods=120),
        )
        assert r.verdict == "flip chatter"
        p = r.poincare[-20:, 0]
        out.append(
            [
                max(p[::2].mean(), p[1::2].mean()),
                min(p[::2].mean(), p[1::2].mean()),
                np.ptp(r.x[-r.t.size // 4 :]),
            ]
        )
    out = np.array(out)
    amp = out[-1, 2]
    for col in range(3):
        err = tail_bound(abs(out[1, col] - out[0, col]), abs(out[2, col] - out[1, col]))
        assert err < 0.01 * amp, (col, out[:, col], err, amp)


# ----------------------------------------------------------------------------- paths, files, verdict rules


def test_a_diverged_linear_run_keeps_its_verdict():
    """Full immersion, 20000 rpm, 5 mm: |mu| = 2.6 (SD), the linear run passes
    the divergence limit 1e12 m after ~45 tooth periods; the samples it has
    still show the growth and the flip."""
    mill = cutter(1.0)
    mu = sd_multiplier(mill, 20000.0, 5e-3, 40)
    assert abs(mu) > 2 and mu.real < 0 and abs(mu.imag) < 1e-9
    r = simulate_milling(
        ONE_DOF,
        mill,
        20000.0,
        0.005,
        nonlinear=False,
        integration=Integration(steps_per_period=100, periods=60),
    )
    assert r.status == "diverged" and "diverged" in r.reason
    assert r.verdict == "flip chatter"
    assert r.growth_per_period > math.log(2.0)


def test_frozen_system_with_named_tool_point_is_the_matrix_path():
    text = (
        '[matrices]\ncoordinates = ["tx", "ty"]\n'
        f"M = [[{MASS!r}, 0.0], [0.0, {MASS!r}]]\n"
        f"K = [[{MASS * WN**2!r}, 0.0], [0.0, {MASS * WN**2!r}]]\n"
        f"L = [[{2 * ZETA * MASS * WN!r}, 0.0], [0.0, {2 * ZETA * MASS * WN!r}]]\n"
    )
    frozen = cl.assemble(cl.loads_model(text)).at()
    M, C, K = (np.eye(2) * np.asarray(a)[0, 0] for a in ONE_DOF)
    kw = dict(feed=1e-4, integration=Integration(steps_per_period=60, periods=5))
    a = simulate_milling(frozen, cutter(0.5), 12000.0, 1e-3, tool_point=("tx", "ty"), **kw)
    b = simulate_milling((M, C, K), cutter(0.5), 12000.0, 1e-3, tool_point=np.eye(2), **kw)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-14 * np.max(np.abs(b.x)))
    np.testing.assert_allclose(a.Fy, b.Fy, rtol=0, atol=1e-12 * np.max(np.abs(b.Fy)))


def test_short_run_is_undetermined_and_the_default_step_follows_the_period_error():
    mill = cutter(0.05)
    r = simulate_milling(ONE_DOF, mill, 10000.0, 0.002, feed=0.0001, integration=Integration(periods=5))
    assert r.verdict == "undetermined" and "too short" in r.reason
    m = default_steps_per_period(ONE_DOF, mill, 10000.0, 2e-3)
    assert r.steps_per_period == m
    # (w_max h)^2 / 12 <= 1e-3 with w_max^2 = w_n^2 + a_p N |K| / m
    w_max = math.sqrt(WN**2 + 2e-3 * 2 * math.hypot(KT, KN) / MASS)
    assert (w_max * r.h) ** 2 / 12 <= 1e-3 < (w_max * r.h * m / (m - 1)) ** 2 / 12


def test_csv_and_plot(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    r = simulate_milling(
        ONE_DOF,
        cutter(0.05),
        10000.0,
        0.002,
        feed=0.0001,
        integration=Integration(steps_per_period=40, periods=3),
    )
    assert isinstance(r, MillingSimulation)
    p = tmp_path / "mill.csv"
    r.to_csv(p)
    head = p.read_text().splitlines()[0].split(",")
    data = np.loadtxt(p, delimiter=",", skiprows=1, usecols=range(len(head) - 1))  # the last: status
    # t, x, y, vx, vy, Fx, Fy and one chip per tooth (TimeHistory's writer: round-trip exact)
    assert data.shape == (r.t.size, 7 + r.chip.shape[0])
    np.testing.assert_array_equal(data[:, head.index("x [m]")], r.x)
    nc = r.to_netcdf(tmp_path / "mill.nc")
    from chatterlab.io import read_dataset

    ds = read_dataset(nc)
    np.testing.assert_array_equal(ds["x"].values, r.x)
    assert ds.attrs["verdict"] == r.verdict
    axes = r.plot()
    assert len(axes) == 3
    import json

    import matplotlib.pyplot as plt

    mine = [plt.figure().add_subplot() for _ in range(3)]
    assert list(r.plot(ax=mine, lw=1.5)) == mine  # drawn where asked, the style passed on
    assert mine[0].get_lines()[0].get_linewidth() == 1.5
    np.testing.assert_array_equal(mine[1].get_lines()[0].get_ydata(), r.Fx)
    one = r.plot(["x", "Fx"])  # the shared TimeHistory.plot for named histories
    assert [ln.get_label() for ln in one.get_lines()] == ["x", "Fx"]
    back = json.loads(r.to_json(tmp_path / "mill.json"))
    np.testing.assert_array_equal(back["data"]["x"]["values"], r.x)
    assert back["attrs"]["verdict"] == r.verdict
    plt.close("all")


def test_the_cut_gives_the_grid_and_the_delays():
    """The speed becomes the grid and the delays in one place, the process:
    h is its tooth period over m, the Poincare period its period, and the
    time module converts no speed itself (no 60 / (N n) or 2 pi / Omega in its
    source)."""
    import re
    from pathlib import Path

    import chatterlab.time as tm

    vp = Milling.from_immersion(3, 0.02, KT, KN, 0.5, "down", pitch=(1.5, 2.0, 2 * math.pi - 3.5))
    for mill, m in ((cutter(0.05), 50), (vp, 41)):
        r = simulate_milling(
            ONE_DOF, mill, 9000.0, 1e-3, feed=1e-4, integration=Integration(steps_per_period=m, periods=3)
        )
        assert r.h == mill.tooth_period(9000.0) / m
        assert r.sample_period == pytest.approx(mill.period(9000.0), rel=1e-14)
        assert r.tooth_passing_frequency == 1.0 / mill.tooth_period(9000.0)
    src = "\n".join(p.read_text() for p in Path(tm.__file__).parent.glob("*.py"))
    for conversion in (
        r"60(\.0)?\s*/",
        r"/\s*60(\.0)?\b",
        r"(2\.0 \* math\.pi|TWO_PI|2 \* math\.pi)\s*/\s*omega",
    ):
        assert not re.search(conversion, src), conversion


def test_a_milling_run_is_the_core_run():
    """The milling run goes through the Newmark core's loop: its progress
    callback (Integration.progress, the core's) is called per chunk, and a
    KeyboardInterrupt from it stops the run with the steps done kept
    (status "interrupted"), as for every time integration."""
    seen: list[float] = []

    def progress(f: float) -> None:
        seen.append(f)
        if len(seen) == 3:
            raise KeyboardInterrupt

    r = simulate_milling(
        ONE_DOF, cutter(0.05), 10000.0, 2e-3, feed=1e-4,
        integration=Integration(steps_per_period=40, periods=10, progress=progress),
    )  # fmt: skip
    assert r.status == "interrupted" and 0 < seen[-1] < 1
    assert r.t.size - 1 == round(seen[-1] * 10 * 2 * 40)
    assert np.all(np.isfinite(r.x)) and r.verdict == "undetermined"


def test_the_0_2_keywords_still_work_and_warn():
    mill = cutter(0.05)
    with pytest.warns(DeprecationWarning, match="revolutions= -> integration=Integration"):
        old = simulate_milling(ONE_DOF, mill, 10000.0, 2e-3, feed=1e-4, steps_per_period=40, revolutions=3)
    new = simulate_milling(
        ONE_DOF, mill, 10000.0, 2e-3, feed=1e-4, integration=Integration(steps_per_period=40, periods=3)
    )
    np.testing.assert_array_equal(old.x, new.x)
    with pytest.raises(TypeError, match="unexpected keyword argument 'revolution'"):
        simulate_milling(ONE_DOF, mill, 10000.0, 2e-3, revolution=3)
    with pytest.raises(InputError, match="history"):
        simulate_milling(ONE_DOF, mill, 10000.0, 2e-3, initial=Initial(history="constant"))


@pytest.mark.parametrize(
    ("kw", "words"),
    [
        (dict(steps_per_period=0), ("steps_per_period",)),
        (dict(steps_per_period=-3), ("steps_per_period",)),
        (dict(steps_per_period=2.5), ("steps_per_period",)),
        (dict(depth=-1e-3), ("depth",)),
        (dict(runout=[1e-6, 0.0, 0.0]), ("runout", "2")),
        (dict(rpm=0.0), ("rpm",)),
        (dict(revolutions=1e9), ("revolutions", "GiB")),
        (dict(feed=-1e-4), ("feed",)),
    ],
)
def test_bad_input_is_one_line(kw, words):
    args = dict(rpm=10000.0, depth=1e-3)
    args.update({k: kw.pop(k) for k in ("rpm", "depth") if k in kw})
    with pytest.raises(InputError) as info:
        simulate_milling(ONE_DOF, cutter(0.05), args["rpm"], args["depth"], **kw)
    msg = str(info.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg
