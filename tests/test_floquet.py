"""Floquet multipliers and lobes of milling (chatterlab.frequency._floquet,
chatterlab.lobes._milling): convergence orders fitted, independent methods
agreeing, and the reductions to a constant-coefficient (turning-like) problem.

The benchmark is Insperger & Stepan's 1-DOF milling model (2004): N = 2,
Kt = 6e8 N/m^2, Kn = 2e8 N/m^2, f_n = 922 Hz, zeta = 0.011, m = 0.03993 kg,
down-milling.
"""

from __future__ import annotations

import numpy as np
import pytest

from chatterlab.errors import InputError
from chatterlab.frequency import SpectralMonodromy, multipliers, sdm_monodromy
from chatterlab.lobes import milling_lobes
from chatterlab.process import Milling, milling_loop
from chatterlab.structure import Structure

KT, KN = 6e8, 2e8
WN = 2 * np.pi * 922.0
MASS = 0.03993
ZETA = 0.011


def one_dof() -> Structure:
    return Structure.single_dof(MASS, WN, ZETA)


def two_dof(fy: float = 922.0) -> Structure:
    k = MASS * WN**2
    ky = MASS * (2 * np.pi * fy) ** 2
    return Structure.modal([WN, 2 * np.pi * fy], [ZETA, ZETA], [k, ky], ("x", "y"), "2-DOF")


def cutter(immersion: float, teeth: int = 2, **kw: object) -> Milling:
    return Milling.from_immersion(teeth, 0.02, KT, KN, immersion, "down", **kw)  # type: ignore[arg-type]


def top(mu: np.ndarray) -> complex:
    return complex(mu[np.argmax(np.abs(mu))])


@pytest.mark.parametrize(
    "immersion,rpm,depth", [(1.0, 10000.0, 1e-3), (1.0, 5000.0, 5e-4), (0.05, 10000.0, 1e-3)]
)
def test_sdm_converges_at_order_two_toward_the_spectral_reference(immersion, rpm, depth):
    st, m = one_dof(), cutter(immersion)
    ref = SpectralMonodromy(milling_loop(st, m), rpm, 24).at(depth)[0]
    steps = np.array([40, 80, 160, 320])
    err = [
        abs(top(np.linalg.eigvals(sdm_monodromy(milling_loop(st, m), rpm, depth, s))) - ref) for s in steps
    ]
    slope = np.polyfit(np.log(steps), np.log(err), 1)[0]
    # first-order SDM is second order in the step (Insperger, Stepan & Turi 2008); the next
    # term of the error is O(h^3), i.e. a relative O(h) = O(1/40) change of the fitted slope
    assert slope == pytest.approx(-2.0, abs=0.15), (slope, err)
    # and the reference is converged far below the finest SDM error
    ref2 = SpectralMonodromy(milling_loop(st, m), rpm, 30).at(depth)[0]
    assert abs(ref2 - ref) < 1e-3 * min(err)


def test_spectral_converges_geometrically():
    st, m = one_dof(), cutter(1.0)
    rpm, depth = 12000.0, 1e-3
    ref = SpectralMonodromy(milling_loop(st, m), rpm, 30, elements=4).at(depth)[0]
    degrees = np.array([6, 8, 10, 12])
    err = np.array(
        [
            abs(SpectralMonodromy(milling_loop(st, m), rpm, int(p), elements=4).at(depth)[0] - ref)
            for p in degrees
        ]
    )
    # geometric: log(err) falls linearly in the degree, at least a decade per 2 degrees here
    # (an algebraic order q would give a ratio (12/10)^q, i.e. q > 12 for the same fall)
    assert np.all(err[1:] / err[:-1] < 0.1), err
    assert err[-1] < 1e-7


@pytest.mark.parametrize(
    "structure", [one_dof(), two_dof(), two_dof(1100.0)], ids=["1dof", "2dof", "2dof-x-y"]
)
def test_constant_coefficients_are_the_turning_engine(structure):
    # slotting with 4 teeth: sum_j H_j(t) = (N/4) [[Kn, Kt], [-Kt, Kn]] for all t (the periodic
    # parts of sin 2phi, cos 2phi cancel over the two teeth in the cut), so milling is the
    # autonomous DDE of the averaged matrix, which the D-subdivision engine solves
    m = cutter(1.0, teeth=4)
    t = (np.arange(997) + 0.5) * 0.02 / 997  # off the breakpoints, where the open windows drop a tooth
    H = m.directional(t, 7000.0).sum(axis=-3)
    np.testing.assert_allclose(H, np.broadcast_to(m.zoa(), H.shape), rtol=0, atol=1e-6 * KT)
    np.testing.assert_allclose(m.zoa(), [[KN, KT], [-KT, KN]], rtol=1e-15)
    rpm = np.array([3000.0, 4100.0, 5200.0, 7700.0, 12000.0])
    dmax = 0.01 if structure.n == 1 else 1e-3  # the 2-DOF limits are 20-200 um
    fl = milling_lobes(milling_loop(structure, m), rpm, method="spectral", depth_max=dmax)
    zo = milling_lobes(milling_loop(structure, m), rpm, method="zoa", depth_max=dmax)
    assert np.all(np.isfinite(fl.a_lim))
    # the Floquet limits are refined to rtol 1e-8 and converged (their own check) to < 1e-8;
    # the engine's boundary is refined to ~1e-9 relative: 1e-7 leaves a margin of 10 on both
    assert np.all(fl.error < 1e-8 * fl.a_lim), fl.error / fl.a_lim
    np.testing.assert_allclose(fl.a_lim, zo.a_lim, rtol=1e-7)
    # and the multipliers are exp(j w_c tau) on the unit circle at the engine's chatter frequency:
    # the Floquet frequency is the member of the family (arg mu + 2 pi k)/tau nearest a pole
    np.testing.assert_allclose(fl.chatter_hz, zo.chatter_hz, rtol=1e-6)


def test_zoa_misses_the_flip_lobes_at_low_immersion():
    st, m = one_dof(), cutter(0.05)
    rpm = np.linspace(13000.0, 17000.0, 9)
    fl = milling_lobes(milling_loop(st, m), rpm, method="spectral", depth_max=0.01)
    zo = milling_lobes(milling_loop(st, m), rpm, method="zoa", depth_max=0.01)
    flip = fl.kind == "flip"
    assert np.count_nonzero(flip) >= 3, fl.kind
    # where the Floquet limit is a flip, ZOA (which has no period doubling) claims a depth at
    # least 30 % deeper, or none below 10 mm
    assert np.all(~np.isfinite(zo.a_lim[flip]) | (zo.a_lim[flip] > 1.3 * fl.a_lim[flip])), (
        fl.a_lim,
        zo.a_lim,
    )
    # the flip multiplier is real and negative
    assert np.all(np.abs(np.angle(fl.multiplier[flip])) > np.pi - 1e-6)


def test_lobes_sdm_and_spectral_agree_within_the_sdm_error():
    st, m = one_dof(), cutter(1.0)
    # two speeds, one on a Hopf and one near a flip lobe (four speeds at 80/160 steps took 265 s of the
    # suite's 650 s; at 50/100 steps the extrapolation's error is 3-10 % of its bound, measured)
    rpm = np.array([6000.0, 14000.0])
    sp = milling_lobes(milling_loop(st, m), rpm, method="spectral", depth_max=0.01)
    s50 = milling_lobes(milling_loop(st, m), rpm, method="sdm", steps=50, depth_max=0.01)
    s100 = milling_lobes(milling_loop(st, m), rpm, method="sdm", steps=100, depth_max=0.01)
    # SDM's error falls 4x per doubling: Richardson's extrapolation removes the h^2 term, the
    # rest is O(h^3): bounded by the change from 50 to 100 steps divided by 4
    rich = (4 * s100.a_lim - s50.a_lim) / 3
    bound = np.abs(s100.a_lim - s50.a_lim) / 4
    assert np.all(np.abs(rich - sp.a_lim) <= bound), (rich, sp.a_lim, bound)
    assert np.all(np.abs(s100.a_lim - sp.a_lim) > np.abs(rich - sp.a_lim))


@pytest.mark.parametrize("immersion", [0.2, 0.5], ids=["one-tooth-cuts", "two-teeth-cut"])
def test_variable_pitch_spectral_converges_and_matches_sdm(immersion):
    # N = 4 at 70/110/70/110 deg.  a_e/D = 0.2 sweeps 53 deg < 70 deg: one tooth cuts at a time and
    # a delayed node lands on a node of the preceding tooth's element; a_e/D = 0.5 sweeps 90 deg:
    # two teeth cut at once, and the mesh also has the breakpoints shifted by each delay, so a
    # delayed image never straddles a jump of x''
    p = np.radians([70.0, 110.0, 70.0, 110.0])
    m = Milling.from_immersion(4, 0.02, KT, KN, immersion, "down", pitch=tuple(p))
    st = two_dof(1100.0)
    rpm, depth = 9000.0, 2e-4
    assert not m.uniform and len(set(np.round(m.delays(rpm), 12))) == 2
    mus = [top(SpectralMonodromy(milling_loop(st, m), rpm, deg).at(depth)) for deg in (10, 14, 18, 22)]
    err = np.abs(np.diff(mus))
    # geometric: each 4 degrees gain more than two decades until round-off (cond(U) ~ 1e4: 1e-12)
    assert err[1] < max(1e-2 * err[0], 1e-12) and err[2] < max(1e-2 * err[1], 1e-12), err
    ref = mus[-1]
    mu = [top(np.linalg.eigvals(sdm_monodromy(milling_loop(st, m), rpm, depth, s))) for s in (200, 400)]
    rich = (4 * mu[1] - mu[0]) / 3
    # SDM's h^2 term removed, the rest bounded by the change it made (the extrapolation's own size)
    assert abs(rich - ref) < abs(mu[1] - mu[0]) / 4, (abs(rich - ref), abs(mu[1] - mu[0]))


def test_multipliers_result_and_its_check():
    r = multipliers(milling_loop(one_dof(), cutter(0.05)), 15000.0, 8.3e-3)
    assert r.method == "spectral" and r.kind in ("flip", "hopf", "fold")
    assert r.error < 1e-9
    assert r.spectral_radius == abs(r.critical) and r.stable == (r.spectral_radius < 1)
    s = multipliers(milling_loop(one_dof(), cutter(0.05)), 15000.0, 8.3e-3, method="sdm", steps=40)
    assert abs(s.critical - r.critical) <= 2 * s.error  # SDM's check (40 vs 80 steps) bounds its error
    with pytest.raises(InputError, match="method"):
        multipliers(milling_loop(one_dof(), cutter(0.05)), 15000.0, 1e-3, method="nope")  # type: ignore[arg-type]


def test_zero_depth_is_the_free_structure():
    st, m = one_dof(), cutter(0.3)
    rpm = 8000.0
    T = m.period(rpm)
    mu = SpectralMonodromy(milling_loop(st, m), rpm).at(0.0)
    lam = np.linalg.eigvals(st.state_matrix)
    expect = np.sort(np.abs(np.exp(lam * T)))[::-1]
    np.testing.assert_allclose(np.abs(mu[:2]), expect, rtol=1e-10)


def test_study_milling_benchmark_runs_and_variable_pitch_raises_the_lobe():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "studies" / "milling_benchmark.py"
    spec = importlib.util.spec_from_file_location("milling_benchmark", path)
    assert spec is not None and spec.loader is not None
    mb = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mb)
    res = mb.compute(5, 3, n_pitch=5)
    for imm in (0.05, 1.0):
        sp = res[imm]["spectral"]
        fin = np.isfinite(sp.a_lim)
        # every limit confirmed by its own check to the lobes' target (max(10 rtol, 1e-7))
        assert np.all(sp.error[fin] <= 1e-7 * sp.a_lim[fin]), sp.error / sp.a_lim
    # near the design speed of the 70/110 pitch (omega_c Delta / pi ~ 11000 rpm for ~920 Hz
    # chatter) the regeneration of consecutive teeth cancels: the limit rises several times
    u, v = res["uniform"], res["variable"]
    k = int(np.argmin(np.abs(u.speed - 9500.0)))
    assert u.speed[k] == 9500.0 and v.a_lim[k] > 3 * u.a_lim[k], (u.a_lim, v.a_lim)


def chain(n: int = 12):
    """A 12-mass chain under a half-immersion cutter, its tool point on the last two masses."""
    k, mm = 4e7, 0.05
    K = np.zeros((n, n))
    for i in range(n):
        K[i, i] += k
        if i + 1 < n:
            K[i, i] += k
            K[i, i + 1] -= k
            K[i + 1, i] -= k
    M = np.eye(n) * mm
    J = np.zeros((2, n))
    J[0, -1] = 1.0
    J[1, -2] = 0.6
    return milling_loop(Structure(M, 1e-5 * K + 20 * M, K, name="chain"), cutter(0.5), J)


def test_reduction_keeps_the_static_compliance_and_all_modes_give_the_structure():
    from chatterlab.lobes import reduce_structure

    st = chain()
    H0 = st.frf(np.array([0.0]))[0].real
    for fmax in (300.0, 2000.0):
        red, info = reduce_structure(st, fmax)
        assert red.n < st.n and red.milling is st.milling
        # Ritz basis with the static residual: the compliance at the tool is exact (round-off of
        # K^-1 with cond(K) ~ 4 n^2 / pi^2 ~ 60: 1e-13 relative)
        np.testing.assert_allclose(
            red.frf(np.array([0.0]))[0].real, H0, rtol=0, atol=1e-12 * np.abs(H0).max()
        )
        assert 0 < info.frf_error < 0.1
    # every mode kept: the same structure, nothing to reduce
    full, info = reduce_structure(st, 1e6)
    assert full.n == st.n and info.frf_error < 1e-10


@pytest.mark.parametrize(
    "make,words",
    [
        (lambda: Structure.modal([WN], [ZETA], [-1e6]), ["mode 1 stiffness", "> 0"]),
        (lambda: Structure.modal([WN], [ZETA], [1e6, 2e6]), ["one value per mode"]),
        (lambda: milling_loop(Structure.single_dof(MASS, WN, ZETA, "z"), cutter(0.5)), ["'x' or 'y'", "J"]),
        (lambda: milling_loop(one_dof(), cutter(0.5), np.ones((3, 1))), ["2 x 1"]),
        (lambda: milling_lobes(milling_loop(one_dof(), cutter(0.5)), np.array([-100.0])), ["rpm", "> 0"]),
        (
            lambda: milling_lobes(milling_loop(one_dof(), cutter(0.5)), np.array([1e4]), method="x"),
            ["method"],
        ),  # type: ignore[arg-type]
    ],
)
def test_bad_input_one_line(make, words):
    with pytest.raises(InputError) as e:
        make()
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_helix_at_one_helical_pitch_is_the_constant_coefficient_delay_equation():
    # at a_p = pi D / (N tan beta) each flute spans one pitch angle, so sum_j H_j(t) is the mean
    # over one pitch of the N teeth = H0 at every t (any immersion): the Floquet multipliers are
    # then exp(lambda tau) of the characteristic roots of the autonomous delay equation, which
    # chatterlab's roots solver finds independently
    from chatterlab.frequency import characteristic_roots, make_system

    st = one_dof()
    m = Milling.from_immersion(4, 0.01, KT, KN, 0.5, "down", helix=np.radians(45.0))
    a_star = np.pi * 0.01 / (4 * np.tan(np.radians(45.0)))
    rpm = 9000.0
    r = multipliers(milling_loop(st, m), rpm, a_star)
    J = milling_loop(st, m).J
    B = J.T @ m.zoa() @ J
    tau = m.tooth_period(rpm)
    roots = characteristic_roots(
        make_system(st.M, st.C, st.K, DP=-a_star * B, DO=a_star * B, tau=tau), count=4
    )
    rho = np.exp(np.max(roots.roots.real) * tau)
    # both converged far below 1e-9 (the spectral check says r.error; the roots are Newton-refined)
    assert r.error < 1e-9
    assert r.spectral_radius == pytest.approx(rho, rel=1e-9)


def test_helix_lobes():
    st = one_dof()
    rpm = np.array([8000.0, 14000.0])
    straight = milling_lobes(milling_loop(st, cutter(0.5)), rpm)
    tiny = milling_lobes(milling_loop(st, cutter(0.5, helix=np.radians(1e-4))), rpm)
    # a lag of 2 a tan(1e-4 deg) / D < 1e-6 rad changes H by less than 1e-6 relative
    np.testing.assert_allclose(tiny.a_lim, straight.a_lim, rtol=1e-5)
    assert list(tiny.kind) == list(straight.kind)
    h = milling_lobes(milling_loop(st, cutter(0.5, helix=np.radians(30.0))), rpm)
    for i in range(rpm.size):  # the limit is where the multiplier of the helical cutter crosses 1
        assert multipliers(
            milling_loop(st, cutter(0.5, helix=np.radians(30.0))), rpm[i], h.a_lim[i]
        ).spectral_radius == (pytest.approx(1.0, abs=1e-7))
    with pytest.raises(InputError, match="helix"):
        milling_lobes(milling_loop(st, cutter(0.5, helix=0.3)), rpm, method="sdm")
