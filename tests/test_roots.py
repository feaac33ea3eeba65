"""Characteristic roots (chatterlab.frequency._roots) and the RHP winding count
(chatterlab.frequency._winding), checked against mathematics:

* the scalar DDE x' = a x + b x(t - tau): Lambert-W closed form;
* no delay: the quadratic eigenvalue problem (scipy's generalized eig of the
  companion pencil) and the SDOF closed form;
* 1-DOF regenerative turning: the Tlusty boundary (a root exactly on the axis),
  0.9 / 1.1 of it stable / unstable, the minimum b_lim = 2 k zeta (1 + zeta) / K_f;
* random small systems: sign of the spectral abscissa vs the argument principle;
* the long-delay case (tau = 1.5 s, ~120 chatter periods per delay):
  spectral windows vs branch enumeration vs winding count.

Tolerances.  Every reported root is polished by Newton's method on
det Delta, which converges quadratically, so roots are exact to a few ulps of
|lambda| times the condition of the root; we ask 1e-10 relative (1e-9 on
long delays, where |lambda| tau ~ 1e3 amplifies roundoff in exp(-lambda tau)).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy.special import lambertw

from chatterlab.errors import InputError
from chatterlab.frequency._roots import (
    RootsResult,
    characteristic_roots,
    chebyshev_nodes,
    make_first_order_system,
    make_system,
    newton_refine,
)
from chatterlab.frequency._winding import WindingResult, rhp_count


def _rhp_from_roots(roots: np.ndarray) -> int:
    """RHP count with multiplicity of conjugates, from upper-half-plane roots."""
    rhp = roots[roots.real > 0]
    return int(2 * rhp.size - np.sum(rhp.imag == 0))


def _lambert_roots(a: float, b: float, tau: float, count: int) -> np.ndarray:
    ks = np.arange(-60, 61)
    lam = np.array([a + lambertw(b * tau * np.exp(-a * tau), k) / tau for k in ks])
    lam = lam[lam.imag >= -1e-12]
    lam = np.where(np.abs(lam.imag) < 1e-14, lam.real + 0j, lam)
    _, first = np.unique(np.round(lam, 9), return_index=True)  # W_0 and W_-1 may coincide
    lam = lam[first]
    return lam[np.lexsort((lam.imag, -lam.real))][:count]


# ---------------------------------------------------------------------------
# scalar DDE: Lambert W
# ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "a, b, tau",
    [
        (-1.0, 0.5, 1.0),  # real rightmost root, stable
        (0.5, -2.0, 1.0),  # complex rightmost pair, unstable
        (-1.0, -3.0, 10.0),  # long delay
        (0.1, -0.5, 50.0),  # very long delay, two real roots
        (-2.0, 1.5, 0.05),  # short delay: principal branch far right
    ],
)
@pytest.mark.parametrize("method", ["spectral", "branch"])
def test_scalar_dde_matches_lambert_w(a: float, b: float, tau: float, method: str) -> None:
    res = characteristic_roots(make_first_order_system([[a]], [[b]], tau), count=6, method=method)
    exact = _lambert_roots(a, b, tau, 6)
    assert res.status == "converged", res.message
    assert res.roots.shape == exact.shape
    # Newton-polished: ~1e-10 relative (see module docstring)
    np.testing.assert_allclose(res.roots, exact, rtol=1e-10, atol=1e-10 / tau)
    assert res.abscissa == pytest.approx(exact[0].real, rel=1e-10, abs=1e-12)
    if method == "spectral":
        assert res.method in ("spectral", "spectral-windowed")
        assert res.n_nodes[1] > res.n_nodes[0] > 0


def test_scalar_dde_factored_delay_matrix() -> None:
    """A1 given as factors (U, V) is the same equation."""
    a, b, tau = -0.3, -1.2, 4.0
    r1 = characteristic_roots(make_first_order_system([[a]], [[b]], tau), count=5)
    r2 = characteristic_roots(make_first_order_system([[a]], ([[b]], [[1.0]]), tau), count=5)
    np.testing.assert_allclose(r1.roots, r2.roots, rtol=1e-12)


# ---------------------------------------------------------------------------
# no delay: quadratic eigenvalue problem
# ---------------------------------------------------------------------------
def test_no_delay_equals_companion_eigenvalues() -> None:
    rng = np.random.default_rng(3)
    n = 4
    A = rng.standard_normal((n, n))
    M = A @ A.T + n * np.eye(n)
    B = rng.standard_normal((n, n))
    K = B @ B.T * 100 + np.eye(n)
    C = 0.05 * (M + K / 100)
    DP = 0.3 * rng.standard_normal((n, n))
    DV = 0.01 * rng.standard_normal((n, n))
    res = characteristic_roots(make_system(M, C, K, DP=DP, DV=DV), count=2 * n)
    # generalized companion pencil  [0 I; -(K-DP) -(C-DV)] x = lam [I 0; 0 M] x
    Z, Id = np.zeros((n, n)), np.eye(n)
    Apen = np.block([[Z, Id], [-(K - DP), -(C - DV)]])
    Bpen = np.block([[Id, Z], [Z, M]])
    ev = sla.eig(Apen, Bpen, right=False)
    ev = ev[ev.imag >= -1e-12]
    ev = ev[np.lexsort((ev.imag, -ev.real))]
    assert res.method == "eig" and res.status == "converged"
    np.testing.assert_allclose(res.roots, ev[: res.roots.size], rtol=1e-10)
    # zero DO and DO=None are the same problem
    res0 = characteristic_roots(make_system(M, C, K, DP=DP, DV=DV, DO=np.zeros((n, n)), tau=0.1), count=2 * n)
    np.testing.assert_allclose(res0.roots, res.roots, rtol=1e-12)


def test_sdof_closed_form() -> None:
    m, k, zeta = 2.0, 8.0e5, 0.03
    wn = np.sqrt(k / m)
    c = 2 * zeta * wn * m
    res = characteristic_roots(make_system([[m]], [[c]], [[k]]), count=3)
    exact = -zeta * wn + 1j * wn * np.sqrt(1 - zeta**2)
    assert res.roots.size == 1  # only one root in the upper half plane exists
    assert "only 1 roots exist" in res.message
    np.testing.assert_allclose(res.roots[0], exact, rtol=1e-13)
    assert res.damping_ratio[0] == pytest.approx(zeta, rel=1e-12)
    assert res.frequency_hz[0] == pytest.approx(wn * np.sqrt(1 - zeta**2) / (2 * np.pi))
    assert res.abscissa == pytest.approx(-zeta * wn)


# ---------------------------------------------------------------------------
# 1-DOF regenerative turning (Tlusty)
# ---------------------------------------------------------------------------
M1, K1, Z1, KF = 1.5, 2.0e7, 0.025, 2.0e9  # kg, N/m, -, N/m^2
C1 = 2 * Z1 * np.sqrt(K1 * M1)
WN = np.sqrt(K1 / M1)


def _G(w: np.ndarray) -> np.ndarray:
    return 1.0 / (K1 - M1 * w**2 + 1j * C1 * w)


def _turning(b: float) -> dict[str, np.ndarray]:
    """m x'' + c x' + k x = -K_f b (x - x(t - tau)).

    In the sign convention of Eq. 2.25 (E = D_P q + D_O q(t - tau) on the
    right-hand side): D_P = -K_f b and D_O = +K_f b.
    """
    return {"DP": np.array([[-KF * b]]), "DO": np.array([[KF * b]])}


def _tlusty_point(w: float, lobe: int) -> tuple[float, float]:
    """(b_lim, tau) at chatter frequency w: Re condition and phase condition."""
    G = _G(np.array(w))
    b_lim = -1.0 / (2.0 * KF * G.real)
    # 1 - exp(-j w tau) = -1/(K_f b G)  =>  exp(-j w tau) = -conj(G)^2/|G|^2
    phase = np.angle(-(np.conj(G) ** 2) / abs(G) ** 2)
    tau = (np.mod(-phase, 2 * np.pi) + 2 * np.pi * lobe) / w
    return float(b_lim), float(tau)


def test_turning_sign_convention() -> None:
    """char_matrix equals the scalar characteristic function of the turning model."""
    b, tau = 1e-3, 0.01
    lam = np.array([3.0 + 2000j, -10 + 50j])
    D = make_system([[M1]], [[C1]], [[K1]], tau=tau, **_turning(b)).delta(lam)[:, 0, 0]
    expect = M1 * lam**2 + C1 * lam + K1 + KF * b * (1 - np.exp(-lam * tau))
    np.testing.assert_allclose(D, expect, rtol=1e-14)
    Dp = make_system([[M1]], [[C1]], [[K1]], tau=tau, **_turning(b)).ddelta(lam)[:, 0, 0]
    expect_p = 2 * M1 * lam + C1 + KF * b * tau * np.exp(-lam * tau)
    np.testing.assert_allclose(Dp, expect_p, rtol=1e-14)


@pytest.mark.parametrize("lobe", [0, 3, 40])
def test_tlusty_boundary(lobe: int) -> None:
    # chatter frequency at the minimum of b_lim(w): w = wn sqrt(1 + 2 zeta)
    wc = WN * np.sqrt(1 + 2 * Z1)
    b_lim, tau = _tlusty_point(wc, lobe)
    M, C, K = [[M1]], [[C1]], [[K1]]
    res = characteristic_roots(make_system(M, C, K, tau=tau, **_turning(b_lim)), count=4)
    assert res.status == "converged", res.message
    # a root on the imaginary axis at w_c; Newton-exact, so ~1e-10 relative
    k = np.argmin(np.abs(res.roots - 1j * wc))
    assert abs(res.roots[k].imag - wc) < 1e-8 * wc
    assert abs(res.roots[k].real) < 1e-8 * wc
    assert abs(res.abscissa) < 1e-8 * wc
    w0 = rhp_count(make_system(M, C, K, tau=tau, **_turning(b_lim)))
    assert w0.status == "marginal", w0.message
    for factor, stable in ((0.9, True), (1.1, False)):
        r = characteristic_roots(make_system(M, C, K, tau=tau, **_turning(factor * b_lim)), count=4)
        w = rhp_count(make_system(M, C, K, tau=tau, **_turning(factor * b_lim)))
        assert r.stable is stable, r
        assert w.status == "converged", w.message
        assert (w.count == 0) is stable
        assert w.count == _rhp_from_roots(r.roots) or w.count > 2 * r.roots.size - 1


def test_tlusty_minimum_b_lim() -> None:
    # Re G < 0 only above wn; b_lim is minimal at wn sqrt(1 + 2 zeta)
    w = np.linspace(1.001 * WN, 1.2 * WN, 200_001)
    b = -1.0 / (2.0 * KF * _G(w).real)
    closed = 2 * K1 * Z1 * (1 + Z1) / KF
    # grid spacing 1e-6 wn; b_lim is quadratic at its minimum -> ~1e-9 relative
    assert b.min() == pytest.approx(closed, rel=1e-9)
    assert w[np.argmin(b)] == pytest.approx(WN * np.sqrt(1 + 2 * Z1), rel=1e-5)
    # and the root solver agrees: at the minimum b_lim the abscissa is ~0 for
    # the lobe through w_c, negative just below
    b_lim, tau = _tlusty_point(WN * np.sqrt(1 + 2 * Z1), 2)
    assert b_lim == pytest.approx(closed, rel=1e-12)


# ---------------------------------------------------------------------------
# random small systems: roots vs argument principle
# ---------------------------------------------------------------------------
@st.composite
def small_systems(draw: st.DrawFn) -> dict:
    n = draw(st.integers(1, 4))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    M = A @ A.T + n * np.eye(n)
    B = rng.standard_normal((n, n))
    kscale = 10 ** draw(st.floats(0, 4))
    K = (B @ B.T + n * np.eye(n)) * kscale
    Cq = rng.standard_normal((n, n))
    C = Cq @ Cq.T * draw(st.floats(1e-3, 0.3)) * np.sqrt(kscale)
    r = draw(st.integers(1, min(n, 2)))
    g = np.sqrt(kscale) * draw(st.floats(0.05, 3.0))
    DO = (rng.standard_normal((n, r)) * g, rng.standard_normal((n, r)) * g)
    DP = rng.standard_normal((n, n)) * kscale * draw(st.floats(0, 0.2))
    tau = 10 ** draw(st.floats(-2, 0.3))
    return {"M": M, "C": C, "K": K, "DP": DP, "DO": DO, "tau": tau}


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(small_systems())
def test_abscissa_sign_agrees_with_winding(sys: dict) -> None:
    res = characteristic_roots(make_system(**sys), count=3)
    assert res.status == "converged", res.message
    scale = float(np.max(np.abs(res.roots))) + 1.0 / sys["tau"]
    # too close to marginal for a sign decision in floating point
    assume(abs(res.abscissa) > 1e-6 * scale)
    w = rhp_count(make_system(**sys))
    if w.status != "converged":
        # an honest "not converged" only for the sample cap (a pole so lightly
        # damped, zeta ~ 1e-4, that the Lipschitz bound needs > MAX_SAMPLES
        # intervals): never a wrong count
        assert "samples" in w.message, w.message
        return
    assert (w.count == 0) == (res.abscissa < 0), (res, w)
    # the roots found right of the axis are all counted by the winding number
    assert w.count >= _rhp_from_roots(res.roots)


# ---------------------------------------------------------------------------
# convergence check, Newton, result object
# ---------------------------------------------------------------------------
def _structure(n: int, seed: int, gain: float):
    """Random structure with modes 50-300 Hz, 2-5 % damping, rank-2 cutting."""
    rng = np.random.default_rng(seed)
    w = 2 * np.pi * np.sort(rng.uniform(50, 300, n))
    z = rng.uniform(0.02, 0.05, n)
    Phi = np.linalg.qr(rng.standard_normal((n, n)))[0] * rng.uniform(0.5, 2, n)
    Pi = np.linalg.inv(Phi)
    M = Pi.T @ Pi
    K = Pi.T @ np.diag(w**2) @ Pi
    C = Pi.T @ np.diag(2 * z * w) @ Pi
    M, K, C = (0.5 * (X + X.T) for X in (M, K, C))
    a = rng.standard_normal((n, 2))
    b = rng.standard_normal((n, 2))
    return {"M": M, "C": C, "K": K, "DP": -gain * a @ b.T, "DO": (gain * a, b)}


def test_roots_stable_under_refinement_and_are_roots() -> None:
    rng = np.random.default_rng(7)
    n = 3
    A = rng.standard_normal((n, n))
    M = A @ A.T + np.eye(n)
    K = np.diag([1e4, 3e4, 9e4])
    C = 0.02 * K / 100
    DO = (rng.standard_normal((n, 1)) * 100, rng.standard_normal((n, 1)) * 100)
    tau = 0.2
    res = characteristic_roots(make_system(M, C, K, DO=DO, tau=tau), count=6)
    assert res.status == "converged"
    for N in (res.n_nodes[1] + 20, 2 * res.n_nodes[1]):
        fine = characteristic_roots(make_system(M, C, K, DO=DO, tau=tau), count=6, n_nodes=N)
        np.testing.assert_allclose(fine.roots, res.roots, rtol=1e-10)
    # each root makes Delta singular: sigma_min / sigma_max at roundoff level
    s = np.linalg.svd(make_system(M, C, K, DO=DO, tau=tau).delta(res.roots), compute_uv=False)
    assert np.all(s[:, -1] / s[:, 0] < 1e-12)


def test_too_coarse_discretisation_is_a_status_not_an_exception() -> None:
    # N = 3 cannot resolve 6 roots of a delay of 30 periods
    res = characteristic_roots(make_first_order_system([[-0.1]], [[-1.0]], 30.0), count=6, n_nodes=3)
    assert isinstance(res, RootsResult)
    assert res.status == "not_converged"
    assert res.message


def test_newton_refine_from_perturbed_roots() -> None:
    kw = _turning(2e-3)
    res = characteristic_roots(make_system([[M1]], [[C1]], [[K1]], tau=0.003, **kw), count=3)
    lam, ok = newton_refine(res.roots * (1 + 1e-4), make_system([[M1]], [[C1]], [[K1]], tau=0.003, **kw))
    assert np.all(ok)
    np.testing.assert_allclose(lam, res.roots, rtol=1e-12)


def test_result_table_and_fields() -> None:
    res = characteristic_roots(make_first_order_system([[0.5]], [[-2.0]], 1.0), count=3)
    text = str(res)
    assert "Hz" in text and "abscissa" in text and res.method in text
    assert len(text.splitlines()) == 3 + 3
    np.testing.assert_allclose(res.frequency_hz, res.roots.imag / (2 * np.pi))
    np.testing.assert_allclose(res.damping_ratio, -res.roots.real / np.abs(res.roots))
    assert np.all(np.diff(res.roots.real) <= 0)
    with pytest.raises(ValueError):
        res.roots[0] = 0  # frozen arrays


def test_chebyshev_differentiation_is_exact_on_polynomials() -> None:
    theta, D = chebyshev_nodes(12, 0.7)
    assert theta[0] == 0 and theta[-1] == pytest.approx(-0.7)
    p = 3 * theta**5 - theta**2 + 2
    np.testing.assert_allclose(D @ p, 15 * theta**4 - 2 * theta, atol=1e-10)


def test_dense_and_factored_DO_agree() -> None:
    s = _structure(6, 2, 300.0)
    U, V = s["DO"]
    dense = dict(s, DO=U @ V.T)
    r1 = characteristic_roots(make_system(**s, tau=0.02), count=5)
    r2 = characteristic_roots(make_system(**dense, tau=0.02), count=5)
    assert make_system(**dense, tau=0.02).r == 2
    np.testing.assert_allclose(r1.roots, r2.roots, rtol=1e-9)


# ---------------------------------------------------------------------------
# long delay: shaper-like tau = 1.5 s, ~120 chatter periods per delay
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("gain", [300.0, 3000.0])
def test_long_delay_spectral_branch_winding_agree(gain: float) -> None:
    s = _structure(10, 1, gain)
    tau = 1.5
    spec = characteristic_roots(make_system(**s, tau=tau), count=6)
    br = characteristic_roots(make_system(**s, tau=tau), count=6, method="branch")
    w = rhp_count(make_system(**s, tau=tau))
    assert spec.status == "converged" and br.status == "converged"
    assert spec.method == "spectral-windowed" and br.method == "branch"
    # chatter near 50-300 Hz: |Im lam| tau ~ 5e2..3e3 -> 1e-9 relative
    np.testing.assert_allclose(spec.roots, br.roots, rtol=1e-9)
    assert w.status == "converged"
    assert (w.count == 0) == (spec.abscissa < 0)
    assert w.count >= _rhp_from_roots(spec.roots)
    # work counters instead of a wall-clock bound: the windows and nodes needed
    # (measured 5 and 3 windows for gains 300 and 3000; (N, N2) = (48, 72))
    assert spec.n_windows <= 8 and spec.n_nodes == (48, 72)
    # the history oscillates: omega tau of the rightmost root in the hundreds
    assert abs(spec.roots[0].imag) * tau > 100


@pytest.mark.slow
def test_long_delay_n40_work() -> None:
    s = _structure(40, 3, 1000.0)
    spec = characteristic_roots(make_system(**s, tau=1.5), count=6)
    br = characteristic_roots(make_system(**s, tau=1.5), count=6, method="branch")
    assert spec.status == "converged"
    np.testing.assert_allclose(spec.roots, br.roots, rtol=1e-9)
    assert spec.n_windows <= 8 and spec.n_nodes == (48, 72)  # measured 4 windows


# ---------------------------------------------------------------------------
# winding details
# ---------------------------------------------------------------------------
def test_winding_no_delay_and_unstable_open_loop() -> None:
    # open loop unstable (negative damping), no delay: count from eigenvalues
    w = rhp_count(make_system([[1.0]], [[-0.2]], [[4.0]]))
    assert isinstance(w, WindingResult)
    assert w.count == 2 and w.open_loop_count == 2
    # a delayed feedback that leaves it unstable: direct and factored agree
    kw = {"DO": [[0.5]], "tau": 0.7}
    a = rhp_count(make_system([[1.0]], [[-0.2]], [[4.0]], **kw))
    b = rhp_count(make_system([[1.0]], [[-0.2]], [[4.0]], **kw), direct=True)
    r = characteristic_roots(make_system([[1.0]], [[-0.2]], [[4.0]], **kw), count=4)
    assert a.count == b.count == _rhp_from_roots(r.roots)
    assert a.open_loop_count == 2


def test_winding_direct_matches_factored_on_structure() -> None:
    s = _structure(5, 4, 2000.0)
    a = rhp_count(make_system(**s, tau=0.05))
    b = rhp_count(make_system(**s, tau=0.05), direct=True)
    assert a.status == b.status == "converged"
    assert a.count == b.count


# ---------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, word",
    [
        ({"DO": [[1.0]], "tau": 0.0}, "tau"),
        ({"DO": [[1.0]], "tau": -1.0}, "tau"),
        ({"DO": [[1.0]]}, "tau"),
        ({"DO": [[1.0]], "tau": float("nan")}, "tau"),
        ({"DP": [[1.0, 0.0], [0.0, 1.0]]}, "DP"),
        ({"DO": ([[1.0, 2.0]], [[1.0]]), "tau": 1.0}, "DO"),
        ({"DV": [[np.inf]]}, "DV"),
    ],
)
def test_bad_input_raises(kwargs: dict, word: str) -> None:
    with pytest.raises(InputError, match=word):
        make_system([[1.0]], [[0.1]], [[4.0]], **kwargs)


@pytest.mark.parametrize("func", [characteristic_roots, rhp_count])
def test_loose_matrices_are_refused_with_the_way_to_build_a_system(func) -> None:
    # the root methods take one value (issue 19): loose matrices name the builder
    with pytest.raises(InputError, match=r"make_system\(M, C, K"):
        func(np.eye(1))


def test_bad_input_other() -> None:
    with pytest.raises(InputError, match="count"):
        characteristic_roots(make_system([[1.0]], [[0.1]], [[4.0]]), count=0)
    with pytest.raises(InputError, match="M"):
        characteristic_roots(make_system([[1.0, 2.0], [0.0, 1.0]], np.eye(2), np.eye(2)))
    with pytest.raises(InputError, match="M"):
        characteristic_roots(make_system([[-1.0]], [[0.1]], [[4.0]]))
    with pytest.raises(InputError, match="K"):
        characteristic_roots(make_system([[1.0]], [[0.1]], [[np.nan]]))
    with pytest.raises(InputError, match="C"):
        characteristic_roots(make_system(np.eye(2), np.eye(3), np.eye(2)))
    with pytest.raises(InputError, match="method"):
        characteristic_roots(make_system([[1.0]], [[0.1]], [[4.0]], DO=[[1.0]], tau=1.0), method="x")
    with pytest.raises(InputError, match="tau"):
        characteristic_roots(make_first_order_system([[0.0]], [[1.0]], 0.0))
    with pytest.raises(InputError, match="omega_max"):
        rhp_count(make_system([[1.0]], [[0.1]], [[4.0]], DO=[[1.0]], tau=1.0), omega_max=-1.0)
    assert issubclass(InputError, ValueError)
