"""Process damping in the Floquet engines of milling (issue 22 item 1): the
rubbing teeth's periodic velocity feedback -a_p C_pd / V W(t) r' in the
spectral-element and the semi-discretisation monodromies and the milling
lobes (docs/process-damping.md, Eq. 4).

Oracles: C_pd = 0 is today's engine bit for bit; the semi-discretisation
converges to the spectral reference at its order two with the term on, and
the term moves the multiplier by far more than that error; in slotting with
four teeth sum_j W_j(t) = I and sum_j H_j(t) are constant, so milling is an
autonomous DDE: its damped limit is the 1-DOF boundary solved here from its
two real equations and the damped constant-coefficient (ZOA) limit of
lobes/_damped.py; the damped limit rises at low speed.

The benchmark is Insperger & Stepan's 1-DOF milling model (2004): Kt = 6e8,
Kn = 2e8 N/m^2, f_n = 922 Hz, zeta = 0.011, m = 0.03993 kg.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

import chatterlab as cl
from chatterlab.frequency import SpectralMonodromy, multipliers, sdm_monodromy
from chatterlab.lobes import milling_lobes
from chatterlab.process import Milling, milling_loop
from chatterlab.process._damping import milling_rubbing
from chatterlab.structure import Structure

ROOT = Path(__file__).resolve().parents[1]
KT, KN = 6e8, 2e8
WN = 2 * np.pi * 922.0
MASS = 0.03993
ZETA = 0.011
D = 0.02  # m, the cutter's diameter: V = pi D n / 60
C_PD = 2e4  # N/m: at 2000 rpm g = C_pd / V = 9.5e3 N s/m^2, a_p g ~ 3 c at a_p = 0.5 mm


def one_dof() -> Structure:
    return Structure.single_dof(MASS, WN, ZETA)


def cutter(immersion: float, teeth: int = 2) -> Milling:
    return Milling.from_immersion(teeth, D, KT, KN, immersion, "down")


def top(mu: np.ndarray) -> complex:
    return complex(mu[np.argmax(np.abs(mu))])


def damped_model(teeth: int, immersion: float, C_pd: float | None) -> cl.Model:
    text = (ROOT / "studies/milling/benchmark_2dof.toml").read_text()
    text = text.replace("teeth = 2", f"teeth = {teeth}").replace(
        "radial_immersion = 0.05", f"radial_immersion = {immersion}"
    )
    if C_pd is not None:
        text += f"\n[process_damping]\nC_pd = {C_pd}\n"
    return cl.loads_model(text, source="mill.toml")


# ----------------------------------------------------------------------------- the term itself
def test_the_rubbing_term_at_a_speed():
    loop = milling_loop(one_dof(), cutter(1.0, 4), C_pd=C_PD)
    rpm = 3000.0
    g, rub = milling_rubbing(loop, rpm)
    assert g == C_PD / (np.pi * D * rpm / 60.0)
    # the rubbing teeth: the directional matrices of K_t = 0, K_n = 1, r_j r_j^T with
    # r = (sin phi, cos phi); in slotting with 4 teeth their sum is the identity at every instant
    t = (np.arange(499) + 0.3) * 0.02 / 499  # off the breakpoints (every 5 ms at 3000 rpm)
    W = rub.directional(t, rpm)
    phi = rub.tooth_angles(t, rpm)
    cut = rub.in_cut(phi)
    r = np.stack([np.sin(phi), np.cos(phi)], axis=-1)
    np.testing.assert_allclose(W, cut[..., None, None] * r[..., :, None] * r[..., None, :], atol=1e-15)
    np.testing.assert_allclose(W.sum(axis=-3), np.broadcast_to(np.eye(2), (t.size, 2, 2)), atol=1e-14)
    assert milling_rubbing(milling_loop(one_dof(), cutter(1.0, 4)), rpm) is None


def test_C_pd_zero_is_todays_engine_bit_for_bit():
    model = damped_model(2, 0.5, 0.0)
    plain = damped_model(2, 0.5, None)
    fz, fz0 = cl.assemble(model).at(), cl.assemble(plain).at()
    from chatterlab.lobes import milling_loop_of

    loop, loop0 = milling_loop_of(fz), milling_loop_of(fz0)
    assert loop.damping is None
    for method in ("spectral", "sdm"):
        a = multipliers(loop, 6000.0, 3e-4, method=method, check=False)
        b = multipliers(loop0, 6000.0, 3e-4, method=method, check=False)
        assert np.array_equal(a.mu, b.mu), method
    # and a loop whose term is present with C_pd = 0 takes the same route (no term added)
    damped = milling_loop(one_dof(), cutter(0.5), C_pd=1.0)
    zero = replace(damped, damping=replace(damped.damping, term=replace(damped.damping.term, C_pd=0.0)))
    X0 = SpectralMonodromy(milling_loop(one_dof(), cutter(0.5)), 6000.0, 12).monodromy(3e-4)
    assert np.array_equal(SpectralMonodromy(zero, 6000.0, 12).monodromy(3e-4), X0)
    assert np.array_equal(
        sdm_monodromy(zero, 6000.0, 3e-4, 40),
        sdm_monodromy(milling_loop(one_dof(), cutter(0.5)), 6000.0, 3e-4, 40),
    )


# ----------------------------------------------------------------------------- SD against spectral
@pytest.mark.parametrize("immersion,teeth", [(1.0, 2), (0.5, 4)])
def test_sdm_converges_at_order_two_to_the_damped_spectral_reference(immersion, teeth):
    st, m = one_dof(), cutter(immersion, teeth)
    loop = milling_loop(st, m, C_pd=C_PD)
    rpm, depth = 5000.0, 5e-4
    ref = top(SpectralMonodromy(loop, rpm, 24).at(depth))
    # the reference is converged far below the SD errors (degree 24 against 30)
    ref2 = top(SpectralMonodromy(loop, rpm, 30).at(depth))
    steps = np.array([40, 80, 160])
    err = np.array([abs(top(np.linalg.eigvals(sdm_monodromy(loop, rpm, depth, s))) - ref) for s in steps])
    assert abs(ref2 - ref) < 1e-3 * err.min()
    slope = np.polyfit(np.log(steps), np.log(err), 1)[0]
    # first-order SD is second order in the step (Insperger, Stepan & Turi 2008) for the damping term
    # too (its step mean is exact, as the cutting term's); the O(h^3) next term changes the fitted
    # slope by a relative O(1/40) per step
    assert slope == pytest.approx(-2.0, abs=0.15), (slope, err)
    # the term matters here: the multiplier moves by more than 10 times the coarsest SD error, so a
    # method that dropped it could not converge to the reference
    plain = top(SpectralMonodromy(milling_loop(st, m), rpm, 24).at(depth))
    assert abs(plain - ref) > 10 * err[-1], (abs(plain - ref), err)
    assert abs(ref) < abs(plain)  # the flanks damp


# ----------------------------------------------------------------------------- slotting: constant coefficients
def exact_limit(rpm: float, teeth: int = 4) -> float:
    """The 1-DOF (x) tool in slotting with 4 teeth: sum_j H_j = Kn on x and sum_j W_j = 1, so
    m x'' + c x' + k x = -a_p [Kn (x - x(t - tau)) + g x'], tau = 60 / (N n), g = C_pd / V.
    On the boundary s = j w: R + a Kn (1 - cos w tau) = 0 and c w + a (Kn sin w tau + w g) = 0
    (R = k - m w^2); eliminating a leaves f(w) = c w Kn (1 - cos) - R (Kn sin + w g) = 0, whose
    roots above w_n give a = -R / (Kn (1 - cos)) > 0; the limit is the smallest."""
    k, c = MASS * WN**2, 2 * ZETA * MASS * WN
    tau = 60.0 / (teeth * rpm)
    g = C_PD / (np.pi * D * rpm / 60.0)

    def f(w: float) -> float:
        th = w * tau
        R = k - MASS * w * w
        return c * w * KN * (1 - np.cos(th)) - R * (KN * np.sin(th) + w * g)

    w = np.linspace(WN * (1 + 1e-9), 3 * WN, 40001)  # 40 points per period 2 pi / tau of the sinusoid
    fw = np.array([f(x) for x in w])
    best = np.inf
    for i in np.nonzero(np.sign(fw[:-1]) != np.sign(fw[1:]))[0]:
        wr = brentq(f, w[i], w[i + 1], xtol=1e-14 * WN, rtol=4 * np.finfo(float).eps)
        a = -(k - MASS * wr * wr) / (KN * (1 - np.cos(wr * tau)))
        if a > 0:
            best = min(best, a)
    return best


def test_slotting_four_teeth_damped_limit_is_the_exact_boundary_and_rises_at_low_speed():
    rpm = np.array([1500.0, 2500.0, 4000.0, 7000.0, 12000.0])
    loop = milling_loop(one_dof(), cutter(1.0, 4), C_pd=C_PD)
    fl = milling_lobes(loop, rpm, method="spectral", depth_max=0.02)
    ref = np.array([exact_limit(r) for r in rpm])
    assert np.all(fl.basis == "complete"), fl.basis
    # the Floquet limits are refined to rtol 1e-8 and checked converged below that; the boundary
    # here is solved to round-off (brentq in w): 1e-7 leaves a factor 10
    np.testing.assert_allclose(fl.a_lim, ref, rtol=1e-7)
    assert fl.meta["process_damping"]["C_pd"] == C_PD
    # the damped constant-coefficient engine (lobes/_damped.py, the averaged route) agrees too
    zo = milling_lobes(loop, rpm, method="zoa", depth_max=0.02)
    assert zo.meta["process_damping"]["C_pd"] == C_PD
    np.testing.assert_allclose(fl.a_lim, zo.a_lim, rtol=1e-7)
    # the limit rises at low speed: above the undamped limit everywhere, and above the lowest lobe
    # bottom at each speed's own gain g = C_pd / V, Tlusty's minimum with the damping c + a g (the
    # smaller root of Kn a = w_n (c + a g)(1 + (c + a g) / (2 sqrt(k m))), docs Eq. 9), which rises like 1/V
    plain = milling_lobes(milling_loop(one_dof(), cutter(1.0, 4)), rpm, method="spectral", depth_max=0.02)
    assert np.all(fl.a_lim > plain.a_lim), fl.a_lim / plain.a_lim
    k, c, km = MASS * WN**2, 2 * ZETA * MASS * WN, 2 * np.sqrt(MASS**2 * WN**2)
    g = C_PD / (np.pi * D * rpm / 60.0)
    # w_n (c + a g)^2 / km + w_n (c + a g) - Kn a = 0, a quadratic in a
    qa, qb, qc = WN * g**2 / km, WN * (2 * c * g / km + g) - KN, WN * (c * c / km + c)
    bottom = (-qb - np.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)
    b0 = 2 * k * ZETA * (1 + ZETA) / KN  # without the flanks (g = 0)
    assert np.all(fl.a_lim >= bottom * (1 - 1e-7)), fl.a_lim / bottom
    assert np.all(np.diff(bottom) < 0) and bottom[0] > 1.5 * b0, bottom / b0
    # the trend of Eq. 10: (a - a0) / a0 = V* / V + O(1/V^2), V* = (1 + 2 zeta) w_n C_pd / Kn
    V = np.pi * D * rpm / 60.0
    Vs = (1 + 2 * ZETA) * WN * C_PD / KN
    ratio = (bottom - b0) / b0 * V / Vs
    # tends to 1 as V grows, its deviation O(V* / V) (0.05 at 12000 rpm) falling with the speed
    assert np.all(np.diff(ratio) < 0) and np.all(ratio > 1) and ratio[-1] - 1 < 2 * Vs / V[-1], ratio


def test_the_model_route_two_dof_slotting_floquet_equals_the_damped_zoa():
    model = damped_model(4, 1.0, C_PD)
    rpm = np.array([2000.0, 5000.0, 9000.0])
    fl = cl.lobes(model, rpm, width_max=0.005)
    zo = cl.lobes(model, rpm, width_max=0.005, method="zoa", verify=0)
    assert fl.method == "spectral" and "process_damping" in fl.meta and "process_damping" in zo.meta
    np.testing.assert_allclose(fl.b_lim, zo.b_lim, rtol=1e-7)
    plain = cl.lobes(damped_model(4, 1.0, None), rpm, width_max=0.005)
    assert np.all(fl.b_lim > plain.b_lim)


def test_low_immersion_damped_limit_rises_at_low_speed():
    # the coefficients are far from constant (a_e / D = 0.05, two teeth): no averaged oracle, but the
    # flanks only damp, so every limit rises, and the more the slower the cut (g = C_pd / V)
    rpm = np.array([3000.0, 6000.0, 12000.0])
    loop = milling_loop(one_dof(), cutter(0.05), C_pd=C_PD)
    fl = milling_lobes(loop, rpm, method="spectral", depth_max=0.02)
    plain = milling_lobes(milling_loop(one_dof(), cutter(0.05)), rpm, method="spectral", depth_max=0.02)
    assert np.all(fl.a_lim > plain.a_lim), fl.a_lim / plain.a_lim
    # and at one speed the limit rises with C_pd
    half = milling_lobes(milling_loop(one_dof(), cutter(0.05), C_pd=C_PD / 2), rpm[:1], depth_max=0.02)
    assert plain.a_lim[0] < half.a_lim[0] < fl.a_lim[0], (plain.a_lim[0], half.a_lim[0], fl.a_lim[0])


# ----------------------------------------------------------------------------- quasi-static split
def test_the_quasi_static_modes_velocity_is_damped_too():
    # a tool with a stiff high mode in x (20 % of the static compliance) split off quasi-statically:
    # in slotting with 4 teeth the cut's and the flanks' total coefficients are constant, so the
    # nodal forces do not jump and the split's only error is the high mode's neglected dynamic
    # amplification ~ (w / w_2)^2; the flanks damp the quasi-static velocity G dF/dt too, so with
    # the term the split converges as without it (without G dF/dt its error rises from 2.2e-4 to 4.1e-4
    # when the mode's frequency doubles: measured)
    from chatterlab.frequency._floquet_spectral import split_structure

    k = MASS * WN**2
    m = cutter(1.0, 4)
    J = np.array([[1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    rpm, a = 5000.0, 2e-4
    errs = {}
    for f2 in (6000.0, 12000.0):
        st = Structure.modal(
            [WN, 2 * np.pi * f2, WN], [ZETA, 0.02, ZETA], [k, 5 * k, k], ("x", "x2", "y"), "3"
        )
        for C_pd in (0.0, C_PD):
            loop = milling_loop(st, m, J, C_pd=C_pd)
            full = top(SpectralMonodromy(loop, rpm, None, depth_hint=a, tol=1e-12).at(a))
            qs = split_structure(loop, 3000.0)
            assert qs.kept == 2
            split = top(SpectralMonodromy(loop, rpm, None, depth_hint=a, tol=1e-12, quasi_static=qs).at(a))
            errs[f2, C_pd] = abs(split - full)
    for f2 in (6000.0, 12000.0):  # the damped split is as good as the undamped one
        assert errs[f2, C_PD] < 1.5 * errs[f2, 0.0], errs
    # and its error falls with the high mode's frequency like (w / w_2)^2: 4 per doubling ideally,
    # 3.7 measured (the next term of the amplification, (w / w_2)^4, and the mode's damping 2 zeta w / w_2)
    assert errs[6000.0, C_PD] > 2.5 * errs[12000.0, C_PD], errs
