"""The faster Floquet lobes (issue 26): the factored monodromy, the automatic
degree, the batched search and Newton's crossing, each against a slower or
independent route to a derived tolerance, and work counted instead of timed.

The benchmark is Insperger & Stepan's 1-DOF milling model (Int. J. Numer.
Meth. Engng 61 (2004) 117-141): N = 2, Kt = 6e8, Kn = 2e8 N/m^2, 922 Hz,
zeta = 0.011, m = 0.03993 kg, down-milling.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import brentq

import chatterlab.lobes._milling_search as search
from chatterlab.frequency import DEGREE, SpectralMonodromy
from chatterlab.frequency._floquet import auto_degree, spectral_mesh
from chatterlab.frequency._floquet_spectral import P_MIN
from chatterlab.lobes import milling_lobes
from chatterlab.process import Milling, milling_loop
from chatterlab.structure import Structure

WN, ZETA, MASS, KT, KN = 2 * np.pi * 922.0, 0.011, 0.03993, 6e8, 2e8
EPS = np.finfo(float).eps


def loop(immersion: float, teeth: int = 2, **kw: object):
    st = Structure.single_dof(MASS, WN, ZETA)
    return milling_loop(st, Milling.from_immersion(teeth, 0.02, KT, KN, immersion, "down", **kw))  # type: ignore[arg-type]


# ---------------------------------------------------------------------------- the factored form
@pytest.mark.parametrize(
    "immersion,rpm,teeth,pitch",
    [(1.0, 7000.0, 2, ()), (0.05, 15000.0, 2, ()), (0.3, 9000.0, 3, (1.9, 2.3, 2 * np.pi - 4.2))],
    ids=["full", "low", "variable-pitch"],
)
def test_derivative_and_unit_depths_of_the_factored_monodromy(immersion, rpm, teeth, pitch):
    """X(a) = X0 + a P (I + a K)^-1 Q: its derivative P (I + a K)^-2 Q is exact (a central
    difference agrees to its own truncation c h^2, estimated from two steps), and at every flip
    and fold depth of unit_depths X has the multiplier -1 or +1 (Sylvester's identity)."""
    sm = SpectralMonodromy(loop(immersion, teeth, pitch=pitch), rpm, None, tol=1e-10)
    a = 1.3e-3
    X, dX = sm._batch(np.array([a]), True)
    assert dX is not None
    fd = {h: (sm.monodromy(a + h) - sm.monodromy(a - h)) / (2 * h) for h in (4e-5, 2e-5, 1e-5)}
    # central differences err by c2 h^2 + c4 h^4: Richardson's (4 D(h) - D(2h)) / 3 leaves 16 c4 h^4 ...
    r1 = (4 * fd[1e-5] - fd[2e-5]) / 3
    r2 = (4 * fd[2e-5] - fd[4e-5]) / 3
    # ... which the pair at 2h has 16 times, so |r1 - r2| = 15 |error of r1|; 2 x that bound for the
    # next term's share, and the round-off of X (condition ~1e3) divided by the step
    noise = 1e3 * EPS * np.abs(X).max() / 1e-5
    err = np.abs(r1 - dX[0]).max()
    assert err <= 2 * np.abs(r1 - r2).max() / 15 + noise, (err, np.abs(r1 - r2).max(), noise)
    assert err <= 1e-6 * np.abs(dX).max()  # so the derivative is confirmed to 1e-6 of its size
    for z in (-1.0, 1.0):
        for a_z in sm.unit_depths(z, 0.01):
            mu = sm.at(a_z)
            # the eigenvalue nearest z moves by cond * eps |X|; the Sylvester root is itself found to
            # eps |nu| relative, i.e. the multiplier to |dmu/da| eps a: 1e-6 covers both with room
            assert np.min(np.abs(mu - z)) < 1e-6, (z, a_z, np.min(np.abs(mu - z)))


def _pencil_multipliers(sm: SpectralMonodromy, a: float) -> tuple[np.ndarray, float]:
    """The 0.2.0 route, written here: the N x N collocation pencil U(a) X = V(a) X_old of a
    1-DOF uniform-pitch cut (x = (q, q'); continuity at node 0 through the free gap; at nodes
    1..p, D x / L - A x + a B h(t_k) (q_k - q_k^old) = 0), velocities in units of the mode's
    frequency, solved densely; its nonzero eigenvalues, largest first, and cond U(a)."""
    lp, mill, mesh = sm.structure, sm.milling, sm.mesh
    w = WN  # states (q, q' / w) and every collocation row over w: the pencil's columns balanced
    A = lp.state_matrix * np.array([1.0, w])[None, :] / np.array([1.0, w])[:, None] / w
    S = mesh.a.size
    nn = mesh.deg + 1
    off = np.r_[0, np.cumsum(nn)] * 2
    N = int(off[-1])
    U0, U1, V0, V1 = (np.zeros((N, N)) for _ in range(4))
    m = float(lp.M[0, 0])
    for s in range(S):
        p = int(mesh.deg[s])
        k = np.arange(p + 1)
        x = -np.cos(np.pi * k / p)
        c = np.r_[2.0, np.ones(p - 1), 2.0] * (-1.0) ** k
        D = np.outer(c, 1 / c) / (x[:, None] - x[None, :] + np.eye(p + 1))
        D -= np.diag(D.sum(axis=1))
        L = mesh.b[s] - mesh.a[s]
        t = mesh.a[s] + L * (x + 1) / 2
        h = mill.directional_on(t, sm.rpm, 0.5 * (mesh.a[s] + mesh.b[s])).sum(axis=-3)[:, 0, 0]
        o = int(off[s])
        U0[o : o + 2, o : o + 2] = np.eye(2)
        prev = int(off[s - 1] + 2 * mesh.deg[s - 1]) if s else int(off[S - 1] + 2 * mesh.deg[S - 1])
        gap = mesh.a[s] - mesh.b[s - 1] if s else mesh.a[0] + mesh.T - mesh.b[S - 1]
        E = sla.expm(A * w * gap)
        (U0 if s else V0)[o : o + 2, prev : prev + 2] += -E if s else E
        for i in range(1, p + 1):
            r = o + 2 * i
            for j in range(p + 1):
                U0[r : r + 2, o + 2 * j : o + 2 * j + 2] += (2 * D[i, j] / (L * w)) * np.eye(2)
            U0[r : r + 2, r : r + 2] -= A
            U1[r + 1, r] += h[i] / (m * w * w)
            V1[r + 1, r] += h[i] / (m * w * w)
    mu = sla.eigvals(V0 + a * V1, U0 + a * U1)
    mu = mu[np.isfinite(mu) & (np.abs(mu) > 1e-12)]
    return mu[np.argsort(-np.abs(mu))], float(np.linalg.cond(U0 + a * U1))


@pytest.mark.parametrize(
    "immersion,rpm,degree", [(1.0, 9000.0, None), (0.05, 15000.0, None), (0.5, 7000.0, 12)]
)
def test_factored_form_is_the_collocation_pencil(immersion, rpm, degree):
    """The factored monodromy's multipliers are the pencil's (the same discretisation, eliminated
    differently): equal to the pencil's round-off, cond(U) eps, matched each to the nearest."""
    sm = SpectralMonodromy(loop(immersion), rpm, degree, tol=1e-9)
    a = 1.1e-3
    ref, cond = _pencil_multipliers(sm, a)
    mu = sm.at(a)
    tol = 10 * cond * EPS
    assert tol < 1e-5  # a test that can fail: the pencil resolves the multipliers
    for r in ref[:6]:
        assert np.min(np.abs(mu - r)) <= tol * max(1.0, abs(r)), (r, np.min(np.abs(mu - r)), tol)


def test_batched_tangents_are_the_single_ones():
    """A batch of depths gives the numbers of the depths one by one (the same LAPACK calls on
    stacked matrices): equal to round-off of the eigenproblem."""
    sm = SpectralMonodromy(loop(0.05), 10000.0, None, tol=1e-8)
    a = np.linspace(1e-4, 4e-3, 7)
    batch = sm.tangents(a)
    for x, (mu, dmu) in zip(a, batch, strict=True):
        mu1, dmu1 = sm.tangents(np.array([x]))[0]
        np.testing.assert_allclose(mu, mu1, rtol=0, atol=1e-12)
        np.testing.assert_allclose(dmu, dmu1, rtol=1e-8, atol=1e-9 * np.abs(dmu1).max())


def test_newton_crossing_is_brents_root():
    """The Hopf limit refined by Newton's method on |mu| equals Brent's root of rho - 1 on the
    same discretisation to the tolerance asked (rtol a) plus Brent's own xtol."""
    sm = SpectralMonodromy(loop(1.0), 6000.0, None, tol=1e-9, depth_hint=1e-3)
    c = search.certified_crossing(sm, 0.01, 40, 1e-10)
    assert c.status == "crossing" and c.kind == "hopf"
    lo = c.depth * (1 - 1e-2)
    root = brentq(lambda x: sm.radius(x) - 1.0, lo, c.depth * (1 + 1e-2), xtol=1e-14, rtol=4 * EPS)
    assert abs(c.depth - root) <= 1e-10 * root + 1e-14


def test_newton_converges_quadratically_in_few_evaluations():
    """Newton's iterates on |mu| - 1 (a smooth function of a_p at a simple crossing): from a
    scan bracket of 0.25 mm the error falls as e_{k+1} ~ C e_k^2, so 1e-10 is reached in at most
    four evaluations (C e_0 ~ 1e-2: 1e-2 -> 1e-4 -> 1e-8 -> 1e-16); bisection needs 22."""
    sm = SpectralMonodromy(loop(1.0), 6000.0, None, tol=1e-9, depth_hint=1e-3)
    seen: list[float] = []

    def data(a: float):
        seen.append(a)
        return sm.tangent(a)

    c = search.certified_crossing(sm, 0.01, 40, 1e-10)
    lo = 0.25e-3 * math.floor(c.depth / 0.25e-3)
    root = search._newton(data, lo, lo + 0.25e-3, 1e-10)
    assert abs(root - c.depth) <= 1e-10 * c.depth
    assert len(seen) - 2 <= 4, seen  # the two bracket ends, then the iterates


# ---------------------------------------------------------------------------- the automatic degree
def test_auto_degree_follows_the_bessel_bound():
    """auto_degree gives the smallest q with (e omega L / 4 q)^q <= tol (Chebyshev coefficients of
    e^{i omega t} on an element ~ J_q(omega L / 2) <= (e omega L / 4 q)^q), plus its margin of
    1 + omega L / 10 degrees, never below P_MIN; it grows with omega L and the accuracy asked."""

    def bound(q: int, wl: float, tol: float) -> bool:
        base = 4 * q / (math.e * wl)
        return base > 1 and q * math.log(base) >= math.log(1 / tol)

    for wl in (0.5, 5.0, 20.0, 40.0):
        for tol in (1e-6, 1e-9):
            p = auto_degree(wl, tol)
            q = p - 1 - math.ceil(wl / 10.0)
            q0 = next(x for x in range(4, 200) if bound(x, wl, tol))  # the smallest
            assert p == max(P_MIN, q0 + 1 + math.ceil(wl / 10.0))
            if p > P_MIN:
                assert q == q0
    assert auto_degree(40.0, 1e-9) > auto_degree(20.0, 1e-9) > auto_degree(5.0, 1e-9)
    assert auto_degree(20.0, 1e-11) > auto_degree(20.0, 1e-7)


def test_one_high_degree_element_needs_fewer_multipliers_than_fixed_degree_16():
    """Where the period holds several oscillations (full immersion, 5000 rpm: omega T = 35),
    p-refinement of one element resolves them with about pi points per wavelength where
    sub-elements of degree 16 and omega L <= 5 use 20: counted, the multipliers (the size of the
    eigenproblem at every depth) fall from 114 to under half, at a limit as accurate as the
    lobes' target (checked in test_auto_mesh_limits_meet_the_target)."""
    lp = loop(1.0)
    fixed = spectral_mesh(lp, 5000.0, DEGREE)
    auto = spectral_mesh(lp, 5000.0, None, depth_hint=0.625e-3, tol=1e-6 / 30)
    k_fixed, k_auto = int(fixed.deg.sum()) + 2, int(auto.deg.sum()) + 2  # r at the nodes, the end state
    assert fixed.a.size == 7 and k_fixed == 114, k_fixed  # 7 elements of omega L <= 5 (omega T = 34.8)
    assert auto.a.size == 1 and k_auto < 0.5 * k_fixed, (k_fixed, k_auto)
    assert SpectralMonodromy(lp, 5000.0, mesh=auto).size == k_auto  # the eigenproblem's size


@pytest.mark.parametrize(
    "immersion,rpm",
    [(1.0, 5000.0), (1.0, 9000.0), (1.0, 12000.0), (1.0, 21000.0), (0.05, 7300.0), (0.05, 18298.05)],
)
def test_auto_mesh_limits_meet_the_target(immersion, rpm):
    """The lobes at the 1e-6 setting (rtol 1e-7: the check must confirm 10 rtol) against the
    0.2.0 discretisation at degree 24 (omega L <= 5, rtol 1e-11, converged to its check): the
    difference is within the target plus the reference's own check, and the auto mesh's check
    estimates it (geometric convergence: the degree + 6 result is far closer, so the change is
    the error, within the root tolerance rtol a)."""
    lp = loop(immersion)
    d = milling_lobes(lp, [rpm], depth_max=0.01, rtol=1e-7)
    ref = milling_lobes(lp, [rpm], depth_max=0.01, rtol=1e-11, degree=24)
    a, r = float(d.a_lim[0]), float(ref.a_lim[0])
    assert d.kind[0] == ref.kind[0] and d.basis[0] == "complete"
    assert abs(a - r) <= 1e-6 * r + 2 * ref.error[0], (a, r, d.error[0])
    assert abs(a - r) <= 2 * d.error[0] + 2 * ref.error[0] + 1e-7 * r, (a, r, d.error[0])


def test_stages_are_sized_for_their_depths_and_merged_when_alike():
    """The automatic mesh is sized for the deepest cut of each depth stage: deeper stages have
    at least the nodes of shallower ones; at low immersion the cut barely stiffens the tool and
    the three stages' meshes are within MERGE of each other (one set-up), at full immersion
    the deepest has more than MERGE times the first's nodes."""
    for imm, merged in ((0.05, True), (1.0, False)):
        lp = loop(imm)
        nodes = [
            int(spectral_mesh(lp, 9000.0, None, depth_hint=h, tol=1e-8).deg.sum())
            for h in (0.625e-3, 2.5e-3, 1e-2)
        ]
        assert nodes == sorted(nodes)
        assert (nodes[-1] <= search.MERGE * nodes[0]) == merged, nodes


# ---------------------------------------------------------------------------- work, counted
def test_work_per_speed_is_counted():
    """The complete search's work at the 1e-6 setting on 11 speeds, counted: evaluations of the
    multipliers and their derivatives at most 1.3 times those of the same search on the 0.2.0
    mesh (explicit degree 16, one stage): the stages re-evaluate their first depth and the
    batched scan a few depths past the limit, Newton saves Brent's evaluations; and one
    set-up per stage and check."""
    rpm = np.linspace(5000.0, 25000.0, 11)
    setups = [0]
    init = SpectralMonodromy.__init__

    def counted(self, *a, **k):
        setups[0] += 1
        init(self, *a, **k)

    SpectralMonodromy.__init__ = counted  # type: ignore[method-assign]
    try:
        for imm in (0.05, 1.0):
            setups[0] = 0
            d = milling_lobes(loop(imm), rpm, depth_max=0.01, rtol=1e-7)
            auto = setups[0]
            fixed = milling_lobes(loop(imm), rpm, depth_max=0.01, rtol=1e-7, degree=DEGREE)
            assert d.evaluations <= 1.3 * fixed.evaluations, (d.evaluations, fixed.evaluations)
            assert auto <= rpm.size * (3 + 1) + d.meta["refined"] * 2, auto
    finally:
        SpectralMonodromy.__init__ = init  # type: ignore[method-assign]


# ---------------------------------------------------------------------------- what is unchanged
def test_explicit_degree_is_the_old_discretisation():
    """An explicit degree keeps the 0.2.0 mesh (sub-elements with omega L <= 5), whose limit is
    its exact flip depth: the same as SpectralMonodromy's default to round-off."""
    lp = loop(0.05)
    d = milling_lobes(lp, [15000.0], depth_max=0.01, degree=DEGREE, check=False)
    flips = SpectralMonodromy(lp, 15000.0).unit_depths(-1.0, 0.01)
    assert d.kind[0] == "flip" and d.a_lim[0] == pytest.approx(flips[0], rel=1e-12)


# ---------------------------------------------------------------------------- the adaptive steps
def test_interval_test_passes_a_turning_multiplier_and_fails_one_that_bends_out():
    """The interval test bounds the first-order path mu + mu' t (t in [0, h]) by its ends'
    moduli (|mu + mu' t| is convex in t) plus the miss of the linear prediction at the other end.
    A multiplier turning on the circle |mu| = 0.95 by w h = 0.2 rad passes, although it moves
    |mu'| h = 0.19 > 1 - |mu| (the triangle inequality's test failed it): its linear path
    reaches 0.95 sqrt(1 + 0.04) = 0.969 and the miss is ~0.95 (w h)^2 / 2 = 0.019.  One whose
    modulus bends out to 1.01 and back within the interval, |mu(t)| = 0.95 + 4 (0.06) t (h - t) / h^2
    at a fixed angle, fails from both ends (its slope there, 0.24 / h, points out of the circle)."""
    h, w = 1.0, 0.2
    others = (np.array([0.1 + 0.0j]), np.array([0.0 + 0.0j]))

    def end(mu: complex, dmu: complex) -> tuple[np.ndarray, np.ndarray]:
        return np.r_[mu, others[0]], np.r_[dmu, others[1]]

    turn = [end(0.95 * np.exp(1j * w * t), 1j * w * 0.95 * np.exp(1j * w * t)) for t in (0.0, h)]
    assert abs(turn[0][1][0]) * h > 1 - 0.95  # the old test's first-order move exceeds the gap
    assert search._interval_safe(turn[0], turn[1], h, None)
    phase = np.exp(0.7j)
    bump = [end(0.95 * phase, s * 0.24 / h * phase) for s in (1.0, -1.0)]
    assert not search._interval_safe(bump[0], bump[1], h, None)


@pytest.mark.parametrize("immersion", [0.05, 1.0])
def test_adaptive_steps_leave_no_instability_below_the_limit(immersion):
    """The adaptive search's limit on a fixed discretisation against brute force (no
    derivatives, no steps): the spectral radius on 300 uniform depths below the limit is < 1
    at every one, and at a Hopf limit > 1 one part in 1e4 past it (|mu| moves by its slope
    ~1e3 /m x 1e-4 a_lim there, far above the root's rtol 1e-10); a flip limit is the exact
    flip depth of unit_depths.  Seven speeds across the benchmark's range."""
    lp = loop(immersion)
    for rpm in np.linspace(5000.0, 25000.0, 7):
        sm = SpectralMonodromy(lp, float(rpm), None, tol=1e-8, depth_hint=5e-3)
        c = search.certified_crossing(sm, 0.01, 40, 1e-10)
        assert c.status == "crossing", (rpm, c)
        rho = np.array([sm.radius(x) for x in c.depth * np.arange(1, 300) / 300])
        assert np.all(rho < 1.0), (rpm, c.depth * (1 + np.nonzero(rho >= 1.0)[0][:3]) / 300)
        if c.kind == "hopf":
            assert sm.radius(c.depth * (1 + 1e-4)) > 1.0, rpm
        else:
            z = -1.0 if c.kind == "flip" else 1.0
            assert c.depth == sm.unit_depths(z, 0.01)[0], rpm


@pytest.mark.parametrize("immersion,rpm", [(1.0, 7000.0), (0.05, 15000.0)])
def test_shifted_solve_by_woodbury_is_the_plain_solve(immersion, rpm):
    """(X0 - z I)^-1 P for z = +-1 by the d x d Woodbury solve (X0 reads only the carried end
    state) equals the k x k solve to the latter's backward error: eps times the condition
    number of X0 - z I, times the size of the solution (a factor 10 for the matrix products)."""
    sm = SpectralMonodromy(loop(immersion), rpm, None, tol=1e-10)
    for z in (-1.0, 1.0):
        A = sm.X0 - z * np.eye(sm.k)
        plain = np.linalg.solve(A, sm.P)
        fast = sm._shifted_solve(z, sm.P)
        bound = 10 * EPS * np.linalg.cond(A) * np.abs(plain).max()
        assert np.abs(fast - plain).max() <= bound, (np.abs(fast - plain).max(), bound)
