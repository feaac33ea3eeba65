"""The forced vibration of a stable milling cut and its surface location error
(chatterlab.frequency._forced), against mathematics:

* the 1-DOF closed form of Schmitz & Mann (2006), written here on its own:
  on the tau-periodic orbit the regenerative term vanishes, so the motion is
  the sum over the tooth-passing harmonics of the FRF times the Fourier
  coefficients of the static cutting force, which are integrals of
  exponentials over the arc, in closed form;
* the steady state of the time-domain simulation (simulate_milling, the
  Newmark core) converging to the fixed point at the scheme's order 2;
* the fixed point converging geometrically in the collocation degree;
* invariants: no feed and no edge force -> no vibration; a tool flexible
  along the feed only -> no SLE; the rigid tool's wall has the feed marks'
  cusps R - sqrt(R^2 - f_z^2/4); an unstable cut gets no SLE.

References: T. L. Schmitz, B. P. Mann, Int. J. Mach. Tools Manuf. 46 (2006)
1369-1377; T. Insperger et al., J. Manuf. Sci. Eng. 128 (2006) 913-920.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from chatterlab.errors import InputError
from chatterlab.frequency import forced_response, surface_location
from chatterlab.frequency._forced import _orbit, _setup, static_load
from chatterlab.process import Milling, milling_loop
from chatterlab.structure import Structure
from chatterlab.time import Integration, simulate_milling

# the Insperger-Stepan benchmark's mode (studies/milling/benchmark_1dof.toml), here along y
MASS, FN, ZETA = 0.03993, 922.0, 0.011
WN = 2 * math.pi * FN
KS = MASS * WN**2
KT, KN, FZ = 6.0e8, 2.0e8, 1.0e-4


def _structure(axis: str = "y") -> Structure:
    return Structure(
        np.eye(1) * MASS, np.eye(1) * 2 * ZETA * MASS * WN, np.eye(1) * KS, (axis,), f"1-DOF {axis}"
    )


def _loop(mode: str, immersion: float = 0.05, axis: str = "y", **kw: float) -> object:
    return milling_loop(_structure(axis), Milling.from_immersion(2, 0.02, KT, KN, immersion, mode, **kw))


def _schmitz_mann(milling: Milling, rpm: float, feed: float, harmonics: int) -> tuple[float, float]:
    """y at the generation instant from the Fourier series of the force times the FRF
    (1-DOF along y), and a bound of the series' tail beyond ``harmonics``.

    Per unit depth, one tooth at phi in the arc pushes the tool along y by
    F_y = K_t f_z s^2 + K_te s - K_n f_z s c - K_ne c (s, c = sin, cos phi;
    the force -(K_t h + K_te) t - (K_n h + K_ne) n with h = f_z s).  As
    sum_q c_q e^{i q phi}, its tau-periodic sum over the teeth has the
    coefficients F_k = (N / 2 pi) sum_q c_q int_entry^exit e^{i (q - k N) phi} dphi,
    and y(t) = sum_k G(i k N Omega) F_k e^{i k N Omega t}, G = 1/(k - m w^2 + i c w).
    """
    N = milling.teeth
    Om = 2 * math.pi * rpm / 60.0
    a, b = milling.entry, milling.exit
    kt, kn, kte, kne = milling.Kt, milling.Kn, milling.Kte, milling.Kne
    c = {
        0: kt * feed / 2,
        2: -kt * feed / 4 - kn * feed / 4j,
        -2: -kt * feed / 4 + kn * feed / 4j,
        1: kte / 2j - kne / 2,
        -1: -kte / 2j - kne / 2,
    }
    k = np.arange(-harmonics, harmonics + 1)
    Fk = np.zeros(k.size, dtype=complex)
    for q, cq in c.items():
        nu = (q - k * N).astype(float)
        safe = np.where(nu == 0, 1.0, nu)
        integral = np.where(nu == 0, b - a, (np.exp(1j * nu * b) - np.exp(1j * nu * a)) / (1j * safe))
        Fk += N / (2 * math.pi) * cq * integral
    w = k * N * Om
    G = 1.0 / (KS - MASS * w**2 + 1j * 2 * ZETA * MASS * WN * w)
    phi_s = math.pi if milling.exit >= math.pi - 1e-12 else 0.0
    y = float(np.real(np.sum(G * Fk * np.exp(1j * k * N * phi_s))))
    # tail: |F_k| <= (N / 2 pi) sum |c_q| 2 / (|k| N - 2), |G| <= 1 / (m w^2 - k_s): both sides
    # of sum_{|k| > K} ~ 2 (N/pi) sum|c_q| / (m N^3 Om^2) * 1/(2 K^2)
    csum = sum(abs(v) for v in c.values())
    K = harmonics
    tail = 2 * (N / math.pi) * csum / (MASS * (N * Om) ** 2 * (K * N - 2)) / (2 * K**2) * (1 + 1e-3)
    return y, tail


@pytest.mark.parametrize(
    "mode, immersion, rpm, edge",
    [
        ("down", 0.05, 10000.0, (0.0, 0.0)),
        ("up", 0.05, 10000.0, (2e4, 1e4)),
        ("down", 0.5, 5000.0, (2e4, 1e4)),
    ],
)
def test_sle_equals_the_closed_form_of_schmitz_and_mann(
    mode: str, immersion: float, rpm: float, edge: tuple
) -> None:
    loop = _loop(mode, immersion, Kte=edge[0], Kne=edge[1])
    r = forced_response(loop, rpm, 0.2e-3, FZ)
    assert r.verdict == "stable"
    y_cf, tail = _schmitz_mann(loop.milling, rpm, FZ, 200_000)
    # per unit depth the force scales with a_p; the SLE of a wall at phi_s is -n . r with
    # n = (0, -1) at pi (down), (0, 1) at 0 (up)
    sle_cf = 0.2e-3 * y_cf * (1.0 if mode == "down" else -1.0)
    # tolerance: the series' tail bound, the fixed point's own convergence check (degree
    # raised), and the round-off of the series' 4e5 terms (each ~ |sle| eps)
    tol = 0.2e-3 * tail + 10 * r.error + 4e5 * 2.3e-16 * abs(sle_cf)
    assert abs(r.sle - sle_cf) <= tol, (r.sle, sle_cf, tol)
    assert abs(r.sle) > 1e3 * tol  # a real number to compare, not round-off


def test_fixed_point_is_the_steady_state_of_the_time_simulation_at_order_two() -> None:
    """Newmark's average-acceleration rule is second order: the steady state's
    distance to the fixed point falls by ~4 per halving of the step."""
    M, C, K = _structure().M, _structure().C, _structure().K
    mil = Milling.from_immersion(2, 0.02, KT, KN, 0.05, "up", Kte=2e4, Kne=1e4)
    loop = milling_loop(_structure(), mil)
    rpm, a = 10000.0, 0.2e-3
    sm = _setup(loop, rpm, a, None, 1e-12)
    assert sm.radius(a) < 0.9  # 120 tooth periods: the transient below 0.9^120 ~ 3e-6 of the orbit
    load = static_load(sm, FZ)
    errors = []
    steps = (40, 80, 160)
    for m in steps:
        sim = simulate_milling(
            (M, C, K), mil, rpm, a, feed=FZ, tool_point=np.array([[0.0], [1.0]]),
            integration=Integration(periods=60, steps_per_period=m),
        )  # fmt: skip
        n = 2 * m  # the last revolution
        y = _orbit(sm, a, load, sim.t[-n:])[:, 1]
        errors.append(np.max(np.abs(sim.y[-n:] - y)) / np.max(np.abs(y)))
    order = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    # second order, with the pre-asymptotic (w h)^4 term at w h = 0.22 .. 0.05 (the last slope 1.92)
    assert 1.7 <= order <= 2.3, (order, errors)
    assert errors[-1] < 2e-2


def test_variable_pitch_fixed_point_is_the_simulated_steady_state() -> None:
    """A variable pitch regenerates on its orbit (period: the revolution), and each tooth's
    static chip is the feed since the tooth before it, f_z p_j N / 2 pi: the general cut's
    collocation with the load, against the Newmark steady state at order 2.  The depth is
    small (0.01 mm) so that the vibration (0.3 um) stays well inside the chip and no tooth
    leaves the material (simulate_milling's fraction_out_of_cut is 0), the linear model's
    premise."""
    M, C, K = _structure().M, _structure().C, _structure().K
    mil = Milling.from_immersion(2, 0.02, KT, KN, 0.3, "up", pitch=(math.radians(160), math.radians(200)))
    loop = milling_loop(_structure(), mil)
    rpm, a = 10000.0, 1e-5
    sm = _setup(loop, rpm, a, None, 1e-12)
    assert sm.radius(a) < 0.7  # 80 revolutions: the transient below 0.7^80 ~ 4e-13
    load = static_load(sm, FZ)
    errors = []
    steps = (40, 80, 160)
    for m in steps:
        sim = simulate_milling(
            (M, C, K), mil, rpm, a, feed=FZ, tool_point=np.array([[0.0], [1.0]]),
            integration=Integration(periods=80, steps_per_period=m),
        )  # fmt: skip
        assert sim.fraction_out_of_cut == 0.0
        n = 2 * m
        y = _orbit(sm, a, load, sim.t[-n:])[:, 1]
        errors.append(np.max(np.abs(sim.y[-n:] - y)) / np.max(np.abs(y)))
    order = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert 1.8 <= order <= 2.2, (order, errors)  # measured 2.01, 1.98
    r = forced_response(loop, rpm, a, FZ)
    assert r.sle == min(r.sle_teeth) and abs(r.sle_teeth[0] - r.sle_teeth[1]) > 1e-3 * abs(r.sle)


def test_fixed_point_converges_geometrically_in_the_degree() -> None:
    loop = _loop("down", 0.5, Kte=2e4, Kne=1e4)
    ref = forced_response(loop, 5000.0, 0.2e-3, FZ, degree=30, check=False)
    errs = [
        abs(forced_response(loop, 5000.0, 0.2e-3, FZ, degree=p, check=False).sle - ref.sle) / abs(ref.sle)
        for p in (5, 7, 9, 11, 13)
    ]
    # geometric (faster): every two degrees at least a decade, down to 1e-8
    assert all(e2 < 0.1 * e1 for e1, e2 in zip(errs, errs[1:], strict=False)), errs
    assert errs[-1] < 1e-8


def test_no_feed_no_edge_force_no_vibration() -> None:
    r = forced_response(_loop("down"), 10000.0, 0.2e-3, 0.0)
    assert r.verdict == "stable"
    assert np.all(r.y == 0.0) and r.sle == 0.0 and r.peak_to_valley == 0.0


def test_a_tool_flexible_along_the_feed_leaves_no_sle() -> None:
    """At phi_s = pi the wall's normal is y: vibration along x moves the edge along the wall."""
    r = forced_response(_loop("down", axis="x"), 10000.0, 0.2e-3, FZ)
    assert r.verdict == "stable"
    assert np.max(np.abs(r.x)) > 1e-7
    assert abs(r.sle) <= 1e-15 * np.max(np.abs(r.x))  # sin(pi) in double precision ~ 1.2e-16


def test_a_tool_without_vibration_leaves_the_feed_marks() -> None:
    """Cutting coefficients 1e10 times smaller: the tool stays on its path (vibration
    ~1e-17 m), and the wall's profile is the trochoids' cusps, depth R - sqrt(R^2 - f_z^2/4)
    for circular arcs; the trochoid (the feed speed v_f against the edge's R Omega: the
    arcs' spacing varies along them by f_z / (pi R)) changes it by that much relative."""
    loop = milling_loop(_structure(), Milling.from_immersion(2, 0.02, KT * 1e-10, KN * 1e-10, 0.05, "down"))
    r = forced_response(loop, 10000.0, 0.2e-3, FZ)
    R = 0.01
    cusp = R - math.sqrt(R**2 - FZ**2 / 4)
    assert abs(r.sle) < 1e-15
    assert abs(r.peak_to_valley - cusp) <= cusp * (2 * FZ / (math.pi * R) + 1e-3), (r.peak_to_valley, cusp)


def test_an_unstable_cut_gets_no_sle() -> None:
    loop = _loop("down", 0.5)
    r = forced_response(loop, 5000.0, 5e-3, FZ)
    assert r.verdict == "unstable" and r.multipliers.spectral_radius > 1
    assert math.isnan(r.sle) and np.all(np.isnan(r.y))
    s = surface_location(loop, [5000.0, 5200.0], 5e-3, FZ, check=False)
    assert s.verdict == ["unstable", "unstable"] and np.all(np.isnan(s.sle))


def test_bad_input_one_line() -> None:
    with pytest.raises(InputError, match="feed per tooth"):
        forced_response(_loop("down"), 10000.0, 0.2e-3, -1.0)
    mil = Milling(2, 0.02, KT, KN, 0.5, 2.0)
    with pytest.raises(InputError, match="no wall"):
        forced_response(milling_loop(_structure(), mil), 10000.0, 0.2e-3, FZ)
    with pytest.raises(InputError, match="straight teeth"):
        forced_response(
            milling_loop(_structure(), Milling(2, 0.02, KT, KN, 0.5, math.pi, helix=0.5)), 1e4, 1e-4, FZ
        )


def test_two_dof_benchmark_fixed_point_is_the_simulated_steady_state() -> None:
    """studies/milling/benchmark_2dof.toml (x and y, the feed force along x as well):
    both coordinates of the orbit, from the model file, against Newmark at order 2
    (measured slopes 2.02, 2.01)."""
    from pathlib import Path

    import chatterlab as cl
    from chatterlab.lobes import milling_loop_of

    model = cl.load_model(Path(__file__).resolve().parents[1] / "studies" / "milling" / "benchmark_2dof.toml")
    loop = milling_loop_of(cl.assemble(model).at())
    rpm, a = 12000.0, 0.5e-3
    sm = _setup(loop, rpm, a, None, 1e-12)
    assert sm.radius(a) < 0.85  # 120 tooth periods: the transient below 0.85^120 ~ 3e-9
    load = static_load(sm, FZ)
    errors = []
    steps = (40, 80, 160)
    for m in steps:
        sim = simulate_milling(
            (loop.M, loop.C, loop.K), loop.milling, rpm, a, feed=FZ, tool_point=loop.J,
            integration=Integration(periods=60, steps_per_period=m),
        )  # fmt: skip
        n = loop.milling.teeth * m
        r = _orbit(sm, a, load, sim.t[-n:])
        errors.append(
            max(np.max(np.abs(sim.x[-n:] - r[:, 0])), np.max(np.abs(sim.y[-n:] - r[:, 1])))
            / np.max(np.abs(r))
        )
    order = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert 1.8 <= order <= 2.2, (order, errors)
