"""The milling process (chatterlab.process.Milling): directional matrices,
their averages, the kinematics of the teeth and the forces, each against an
independent derivation or a published closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from chatterlab.errors import InputError
from chatterlab.process import Milling

# the 1-DOF benchmark of Insperger & Stepan (2004): N = 2, Kt = 6e8, Kn = 2e8 N/m^2
KT, KN = 6e8, 2e8


def cutter(immersion: float = 0.05, mode: str = "down", **kw: object) -> Milling:
    return Milling.from_immersion(2, 0.02, KT, KN, immersion, mode, **kw)  # type: ignore[arg-type]


def test_immersion_angles():
    # a_e/D = 1 (slotting) is 0..pi in both modes; down-milling exits at pi, up-milling enters at 0
    for mode in ("up", "down"):
        m = cutter(1.0, mode)
        assert m.entry == pytest.approx(0.0, abs=1e-15) and m.exit == pytest.approx(math.pi)
    d = cutter(0.5, "down")
    assert d.entry == pytest.approx(math.pi / 2) and d.exit == math.pi
    u = cutter(0.25, "up")
    # cos(exit) = 1 - 2 a_e/D = 0.5
    assert u.entry == 0.0 and u.exit == pytest.approx(math.pi / 3)


def test_xx_entry_is_insperger_stepan_h():
    # Insperger & Stepan (2004), Eq. (3): h(t) = sum_j g_j sin(phi_j) (Kt cos(phi_j) + Kn sin(phi_j)),
    # phi_j = Omega t + j 2 pi / N; the same set of angles as ours for uniform pitch
    m = cutter(0.3, "up")
    rpm = 9000.0
    t = np.linspace(0, 3 * m.period(rpm), 777)
    w = 2 * np.pi * rpm / 60
    phi = w * t[:, None] + np.arange(2) * np.pi
    ph = np.mod(phi, 2 * np.pi)
    g = (ph > m.entry) & (ph < m.exit)
    h = np.sum(g * np.sin(phi) * (KT * np.cos(phi) + KN * np.sin(phi)), axis=1)
    H = m.directional(t, rpm).sum(axis=-3)
    # same formula, rounding only: |H| <= Kt + Kn, a few operations -> 1e-15 relative of that scale
    np.testing.assert_allclose(H[:, 0, 0], h, rtol=0, atol=1e-13 * (KT + KN))


def test_force_linearisation_is_minus_depth_H():
    # the tooth force of a chip h0 + (sin, cos) . dr minus that of h0 is -a_p H dr, exactly (linear in h)
    m = cutter(1.0, "down", Kte=2e4, Kne=1e4)
    rng = np.random.default_rng(1)
    phi = rng.uniform(0.05, 3.0, size=(50, 2))
    h0 = 1e-4
    dr = rng.normal(scale=1e-6, size=(50, 2))
    dh = np.sum(Milling.chip_direction(phi) * dr[:, None, :], axis=-1)
    a = 3e-3
    dF = m.tooth_forces(phi, h0 + dh, a) - m.tooth_forces(phi, np.full_like(phi, h0), a)
    t = phi / m.omega(6000.0)  # time at which tooth 0 is at phi (tooth 1 is read off its own column)
    H0 = m.directional(t[:, 0], 6000.0)[:, 0]
    expect = -a * np.einsum("kij,kj->ki", H0, dr)
    # cancellation of F(h0) ~ a Kt h0 = 180 N: 1e-15 * 180 absolute
    np.testing.assert_allclose(dF[:, 0], expect, rtol=0, atol=1e-12)


def test_tooth_leaving_the_cut_carries_no_force():
    m = cutter(1.0)
    F = m.tooth_forces(np.array([1.0, 1.0, 4.0]), np.array([-1e-5, 1e-5, 1e-5]), 1e-3)
    assert np.all(F[0] == 0) and np.any(F[1] != 0) and np.all(F[2] == 0)


def altintas_A0(m: Milling) -> np.ndarray:
    """[A0] of Altintas & Budak (1995), Eq. (11), with K_r = Kn / Kt."""
    Kr = m.Kn / m.Kt

    def alpha(p: float) -> np.ndarray:
        return 0.5 * np.array(
            [
                [
                    np.cos(2 * p) - 2 * Kr * p + Kr * np.sin(2 * p),
                    -np.sin(2 * p) - 2 * p + Kr * np.cos(2 * p),
                ],
                [
                    -np.sin(2 * p) + 2 * p + Kr * np.cos(2 * p),
                    -np.cos(2 * p) - 2 * Kr * p - Kr * np.sin(2 * p),
                ],
            ]
        )

    return m.teeth / (2 * np.pi) * (alpha(m.exit) - alpha(m.entry))


@pytest.mark.parametrize("immersion,mode", [(0.05, "down"), (1.0, "down"), (0.5, "up"), (0.3, "down")])
def test_zoa_is_altintas_budak_A0(immersion, mode):
    m = cutter(immersion, mode)
    # Altintas: F = (a Kt / 2) [A0] (r(t) - r(t - tau)); ours F = -a H0 (r(t) - r(t - tau))
    np.testing.assert_allclose(-2 * m.zoa() / KT, altintas_A0(m), rtol=0, atol=1e-14)


@pytest.mark.parametrize("immersion,mode", [(0.05, "down"), (0.7, "up")])
def test_zoa_is_the_time_average(immersion, mode):
    m = cutter(immersion, mode, pitch=(math.radians(170), math.radians(190)))
    rpm = 7000.0
    T = m.period(rpm)
    n = 200_000
    t = (np.arange(n) + 0.5) * T / n  # midpoint rule
    H = m.directional(t, rpm).sum(axis=-3).mean(axis=0)
    # midpoint rule on a piecewise smooth integrand: each of the 2N jumps costs at most
    # max|H| * dt, the smooth part O(dt^2): bound 2N (Kt + Kn) / n
    np.testing.assert_allclose(H, m.zoa(), rtol=0, atol=2 * 2 * (KT + KN) / n)


def test_directional_mean_is_exact():
    m = cutter(0.4, "up", pitch=(2.5, 2 * np.pi - 2.5))
    rpm = 5000.0
    T = m.period(rpm)
    rng = np.random.default_rng(3)
    for t0, L in zip(rng.uniform(-T, 2 * T, 6), rng.uniform(0.01 * T, 1.7 * T, 6), strict=True):
        n = 100_000
        t = t0 + (np.arange(n) + 0.5) * L / n
        ref = m.directional(t, rpm).mean(axis=0)
        # as above: at most 2 window edges per tooth and revolution in the interval
        jumps = 2 * (L / T + 1)
        np.testing.assert_allclose(
            m.directional_mean(t0, t0 + L, rpm), ref, rtol=0, atol=jumps * (KT + KN) / n
        )


def test_delays_and_tooth_angles():
    p = (1.9, 2.3, 2 * np.pi - 4.2)
    m = Milling(3, 0.02, KT, KN, 0.2, 2.0, pitch=p)
    rpm = 12000.0
    assert not m.uniform
    d = m.delays(rpm)
    assert d.sum() == pytest.approx(60 / rpm, rel=1e-15)
    assert m.period(rpm) == pytest.approx(60 / rpm)
    # tooth j passes at t + tau_j the angle tooth j-1 had at t
    t = 0.123e-3
    a0 = m.tooth_angles(t, rpm)
    for j in range(3):
        aj = m.tooth_angles(t + d[j], rpm)[j]
        assert abs(np.angle(np.exp(1j * (aj - a0[j - 1])))) < 1e-12
    u = cutter()
    assert u.uniform and u.period(rpm) == pytest.approx(60 / (2 * rpm)) == u.tooth_period(rpm)
    np.testing.assert_allclose(u.delays(rpm), 60 / (2 * rpm), rtol=1e-15)


def test_coefficients_are_smooth_between_breakpoints():
    m = Milling(3, 0.02, KT, KN, 0.2, 2.0, pitch=(1.9, 2.3, 2 * np.pi - 4.2))
    rpm = 12000.0
    T = m.period(rpm)
    tb = m.breakpoints(rpm)
    assert tb.size == 6
    t = np.linspace(0, T, 20001)[:-1]
    g = m.in_cut(m.tooth_angles(t, rpm))
    change = np.nonzero(np.any(g[1:] != g[:-1], axis=1))[0]
    # every change of who is in the cut happens within one sample of a breakpoint
    dt = T / 20000
    for i in change:
        assert np.min(np.abs(tb - t[i])) <= dt * 1.0000001


def test_helix_keeps_the_average_and_smooths():
    m = cutter(0.5, "down", helix=math.radians(30))
    rpm = 8000.0
    T = m.period(rpm)
    n = 100_000
    t = (np.arange(n) + 0.5) * T / n
    H = m.directional(t, rpm, depth=5e-3).sum(axis=-3)
    np.testing.assert_allclose(H.mean(axis=0), m.zoa(), rtol=0, atol=4 * (KT + KN) / n)
    # continuous: the largest jump between samples is O(dt), not O(Kt)
    assert np.max(np.abs(np.diff(H, axis=0))) < 0.01 * KT
    # a shallow cut is the straight-flute cutter: away from the edges the mean over the lag psi
    # differs from H(phi) by at most psi/2 max|H'| <= psi/2 (Kt + Kn)
    t2 = np.array([0.1, 0.2, 0.35, 0.6, 0.75, 0.9]) * T
    depth = 1e-4 * m.diameter / (2 * math.tan(m.helix))  # psi = 1e-4 rad
    psi = m.lag_angle(depth)
    np.testing.assert_allclose(
        m.directional(t2, rpm, depth=depth),
        cutter(0.5, "down").directional(t2, rpm),
        rtol=0,
        atol=psi / 2 * (KT + KN),
    )
    with pytest.raises(InputError, match="depth"):
        m.directional(t2, rpm)


@pytest.mark.parametrize(
    "make,words",
    [
        (lambda: Milling(2, 0.02, KT, KN, 0.5, 3.0, pitch=(3.0, 3.0)), ["pitch", "360"]),
        (lambda: Milling(2, 0.02, KT, KN, 0.5, 3.0, pitch=(3.0,)), ["pitch", "one pitch angle per tooth"]),
        (lambda: Milling(2, 0.02, KT, KN, 2.0, 1.0), ["entry", "exit"]),
        (lambda: Milling(2, 0.02, KT, KN, 0.5, 4.0), ["exit", "[0, pi]"]),
        (lambda: cutter(0.0), ["immersion", "(0, 1]"]),
        (lambda: cutter(1.2), ["immersion", "(0, 1]"]),
        (lambda: cutter(0.5, "climb"), ["mode", "'up' or 'down'"]),
        (lambda: Milling(0, 0.02, KT, KN, 0.5, 3.0), ["teeth", ">= 1"]),
        (lambda: Milling(2, -0.02, KT, KN, 0.5, 3.0), ["diameter", "> 0"]),
        (lambda: Milling(2, 0.02, KT, KN, 0.5, 3.0, helix=1.6), ["helix"]),
        (lambda: Milling(2, 0.02, KT, KN, 0.5, 3.0, pitch=(7.0, -0.7168)), ["pitch[1]", "> 0"]),
    ],
)
def test_bad_input_one_line(make, words):
    with pytest.raises(InputError) as e:
        make()
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_directional_on_is_the_one_sided_limit_at_a_breakpoint():
    m = cutter(1.0, "down")  # teeth enter at 0 and leave at pi, where H has nonzero xy, yy entries
    rpm = 6000.0
    T = m.period(rpm)
    tb = 0.0  # tooth 0 enters, tooth 1 leaves
    eps = 1e-9 * T
    after = m.directional_on(np.array([tb]), rpm, 0.5 * T)[0]
    before = m.directional_on(np.array([T]), rpm, 0.5 * T)[0]
    # the limits from inside the piece (tb, T): H is continuous there, so eps away differs by
    # at most eps * Omega * max|H'| <= eps * Omega * (Kt + Kn)
    tol = eps * m.omega(rpm) * (KT + KN)
    np.testing.assert_allclose(after, m.directional(np.array([tb + eps]), rpm)[0], rtol=0, atol=tol)
    np.testing.assert_allclose(before, m.directional(np.array([T - eps]), rpm)[0], rtol=0, atol=tol)
    # while the open windows drop both teeth exactly at the breakpoint
    assert np.abs(m.directional(np.array([tb]), rpm)[0].sum(axis=0)).max() < 1e-6 * KT
    assert np.abs(after.sum(axis=0)).max() > 0.5 * KT


def test_helix_at_one_helical_pitch_averages_the_teeth():
    # each flute spans one pitch angle at a_p = pi D / (N tan beta): sum_j H_j(t) = H0 at every t
    m = Milling.from_immersion(4, 0.01, KT, KN, 0.3, "up", helix=math.radians(40))
    a_star = math.pi * 0.01 / (4 * math.tan(math.radians(40)))
    t = np.linspace(0, 2 * m.period(7000.0), 501)
    H = m.directional(t, 7000.0, depth=a_star).sum(axis=-3)
    # primitives of size Kt * 2 pi, differenced and divided by psi ~ 1.6: rounding 1e-14 (Kt + Kn)
    np.testing.assert_allclose(H, np.broadcast_to(m.zoa(), H.shape), rtol=0, atol=1e-13 * (KT + KN))
