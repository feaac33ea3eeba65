"""The plane Timoshenko element (interdependent interpolation, Friedman &
Kosmatka 1993) and the rigid-body point maps, with mathematics as the oracle:
closed-form element matrices, the strain energy of the shape functions,
rigid-body motions, the exact cantilever deflection under an end load and
the exact Timoshenko cantilever frequency from its transcendental frequency
equation (Huang 1961; Han, Benaroya & Wei 1999).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.optimize
from hypothesis import given, settings
from hypothesis import strategies as st

import chatterlab as cl
from chatterlab.structure._elements import (
    beam_local_mass,
    beam_local_stiffness,
    beam_matrices,
    beam_point_matrix,
    beam_rotation,
    beam_shape,
    rigid_point_matrix,
    shear_parameter,
)

EPS = np.finfo(float).eps
BEND = [1, 2, 4, 5]  # (v1, th1, v2, th2) in the local (u1, v1, th1, u2, v2, th2)

# a stocky test section: phi = 12EI/(kappa G A L^2) of order 1, so shear matters
E, NU, RHO, KAPPA = 2.1e11, 0.3, 7850.0, 5.0 / 6.0
G = E / (2 * (1 + NU))


def _sec(b: float = 0.05, h: float = 0.1) -> dict[str, float]:
    return {"E": E, "G": G, "A": b * h, "I": b * h**3 / 12, "kappa": KAPPA}


# --------------------------------------------------------------------------- shape functions


@pytest.mark.parametrize("phi", [0.0, 0.37, 4.0])
def test_shape_functions_interpolate_nodal_values(phi):
    L = 0.7
    Nv = beam_shape(np.array([0.0, 1.0]), L, phi)
    Np = beam_rotation(np.array([0.0, 1.0]), L, phi)
    # v(0) = v1, v(L) = v2, psi(0) = th1, psi(L) = th2: exact identities of
    # polynomials with O(1) coefficients, so round-off (a few eps) only.
    np.testing.assert_allclose(Nv, [[1, 0, 0, 0], [0, 0, 1, 0]], atol=10 * EPS)
    np.testing.assert_allclose(Np, [[0, 1, 0, 0], [0, 0, 0, 1]], atol=10 * EPS)


@pytest.mark.parametrize("phi", [0.0, 0.37, 4.0])
@pytest.mark.parametrize("order", [1, 2])
def test_shape_derivatives_match_central_differences(phi, order):
    L = 0.7
    xi = np.linspace(0.1, 0.9, 9)
    hx = 1e-4  # step in x (m).  The functions are cubics (v) and quadratics
    # (psi), so the central difference of the order-(k-1) derivative has the
    # error h^2/6 * (its third derivative), at most h^2/6 * 12/L^3 * L ~ 6e-8
    # relative to the O(1/L^k) values; round-off eps/h ~ 2e-12.  Bound: 1e-7.
    for fn in (beam_shape, beam_rotation):
        exact = fn(xi, L, phi, order)
        up = fn(xi + hx / L, L, phi, order - 1)
        dn = fn(xi - hx / L, L, phi, order - 1)
        fd = (up - dn) / (2 * hx)
        scale = np.abs(exact).max()
        np.testing.assert_allclose(fd, exact, atol=1e-7 * scale)


@pytest.mark.parametrize("phi", [0.05, 0.37, 4.0])
def test_shear_strain_is_constant_and_stiffness_is_the_strain_energy(phi):
    """Interdependent interpolation: the shape functions solve the homogeneous
    Timoshenko equations, so the shear strain gamma = v' - psi is constant and
    the bending moment EI psi' linear along the element; the stiffness matrix
    is the strain energy  K = int EI psi'^T psi' + kappa G A gamma^T gamma dx."""
    s = _sec()
    L = math.sqrt(12 * s["E"] * s["I"] / (s["kappa"] * s["G"] * s["A"] * phi))  # the length giving phi
    ph = shear_parameter(s["E"], s["I"], s["kappa"], s["G"], s["A"], L)
    assert ph == pytest.approx(phi, rel=1e-12)  # the formula 12EI/(kGAL^2), to round-off
    x, w = np.polynomial.legendre.leggauss(6)  # exact for the degree <= 4 integrands
    x, w = 0.5 * (x + 1), 0.5 * w
    gam = beam_shape(x, L, ph, 1) - beam_rotation(x, L, ph, 0)
    # gamma of each shape function takes one value at all points: round-off of
    # O(1/L) values, relative 1e-13.
    np.testing.assert_allclose(gam, np.broadcast_to(gam[0], gam.shape), atol=1e-13 * np.abs(gam).max())
    # psi'' is constant too (bending moment linear)
    d2 = beam_rotation(x, L, ph, 2)
    np.testing.assert_allclose(d2, np.broadcast_to(d2[0], d2.shape), rtol=0, atol=1e-13 * np.abs(d2).max())
    dpsi = beam_rotation(x, L, ph, 1)
    K = L * (s["E"] * s["I"] * (dpsi.T * w) @ dpsi + s["kappa"] * s["G"] * s["A"] * (gam.T * w) @ gam)
    Kel = beam_local_stiffness(s["E"], s["G"], s["A"], s["I"], s["kappa"], L)
    # Gauss quadrature is exact here; the difference is summation round-off
    # (relative 1e-14 of the largest entry).
    np.testing.assert_allclose(Kel[np.ix_(BEND, BEND)], K, atol=1e-13 * np.abs(K).max())
    # axial part EA/L [[1,-1],[-1,1]]
    EA_L = s["E"] * s["A"] / L
    np.testing.assert_allclose(Kel[np.ix_([0, 3], [0, 3])], EA_L * np.array([[1, -1], [-1, 1]]), rtol=1e-15)
    # no axial-bending coupling in local axes (exact zeros)
    assert np.all(Kel[np.ix_([0, 3], BEND)] == 0.0)


@pytest.mark.parametrize("phi", [0.0, 0.37, 4.0])
def test_mass_matrix_equals_closed_form(phi):
    """The consistent mass of the Timoshenko element in closed form
    (Przemieniecki, Theory of Matrix Structural Analysis, 1968, the beam
    with shear deformation and rotary inertia; the same matrices follow from
    the shape functions of Friedman & Kosmatka 1993): translational rho A
    part and rotary rho I part, polynomials in phi over (1 + phi)^2."""
    rho, A, I, L = RHO, 0.005, 4.2e-6, 0.6
    p = phi
    f = 1.0 / (1.0 + p) ** 2
    # fmt: off
    t = np.array(
        [
            [70 * p * p + 147 * p + 78, (35 * p * p + 77 * p + 44) * L / 4, 35 * p * p + 63 * p + 27, -(35 * p * p + 63 * p + 26) * L / 4],
            [0, (7 * p * p + 14 * p + 8) * L * L / 4, (35 * p * p + 63 * p + 26) * L / 4, -(7 * p * p + 14 * p + 6) * L * L / 4],
            [0, 0, 70 * p * p + 147 * p + 78, -(35 * p * p + 77 * p + 44) * L / 4],
            [0, 0, 0, (7 * p * p + 14 * p + 8) * L * L / 4],
        ]
    )
    r = np.array(
        [
            [6 / 5, (1 / 10 - p / 2) * L, -6 / 5, (1 / 10 - p / 2) * L],
            [0, (2 / 15 + p / 6 + p * p / 3) * L * L, (-1 / 10 + p / 2) * L, (-1 / 30 - p / 6 + p * p / 6) * L * L],
            [0, 0, 6 / 5, (-1 / 10 + p / 2) * L],
            [0, 0, 0, (2 / 15 + p / 6 + p * p / 3) * L * L],
        ]
    )

    # fmt: on

    def sym(a):
        return np.triu(a) + np.triu(a, 1).T

    ref = rho * A * L / 210 * f * sym(t) + rho * I / L * f * sym(r)
    m = beam_local_mass(rho, A, I, L, phi)
    # 4-point Gauss is exact for the degree-6 integrands: round-off only
    # (relative 1e-15 of the largest entry; 1e-13 leaves room for summation).
    np.testing.assert_allclose(m[np.ix_(BEND, BEND)], ref, atol=1e-13 * np.abs(ref).max())
    np.testing.assert_allclose(
        m[np.ix_([0, 3], [0, 3])], rho * A * L / 6 * np.array([[2, 1], [1, 2]]), rtol=1e-15
    )
    if phi == 0.0:
        # Euler-Bernoulli limit: the classical 420 matrix (rho A L/420)[156, 22L, 54, -13L; ...]
        # fmt: off
        eb = rho * A * L / 420 * sym(np.array([[156, 22 * L, 54, -13 * L], [0, 4 * L * L, 13 * L, -3 * L * L],
                                               [0, 0, 156, -22 * L], [0, 0, 0, 4 * L * L]]))
        # fmt: on
        trans = rho * A * L / 210 * sym(t)
        np.testing.assert_allclose(trans, eb, atol=1e-14 * np.abs(eb).max())


# --------------------------------------------------------------------------- rigid-body motions


def _rigid_motions(xy: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Columns: x translation, y translation, small rotation about centre, for
    nodes at rows of xy (global (u, v, theta) per node)."""
    out = np.zeros((3 * len(xy), 3))
    for k, p in enumerate(xy):
        out[3 * k : 3 * k + 3, :] = rigid_point_matrix(p - centre)
    return out


@settings(max_examples=40, deadline=None)
@given(
    angle=st.floats(-math.pi, math.pi),
    L=st.floats(0.05, 3.0),
    h=st.floats(0.005, 0.5),
)
def test_global_element_has_three_rigid_body_modes(angle, L, h):
    """For any orientation and section: K r = 0 for the three rigid motions
    of the plane, and the kinetic energy of a rigid motion is that of the
    rigid bar (mass rho A L; inertia about the middle rho A L^3/12 + rho I L)."""
    b = 0.04
    A, I = b * h, b * h**3 / 12
    xy_i = np.array([0.3, -0.2])
    xy_j = xy_i + L * np.array([math.cos(angle), math.sin(angle)])
    M, Ld, K = beam_matrices(xy_i, xy_j, E=E, G=G, A=A, I=I, kappa=KAPPA, rho=RHO, eta=1e7)
    mid = 0.5 * (xy_i + xy_j)
    R = _rigid_motions(np.array([xy_i, xy_j]), mid)
    # K r = 0 holds through exact identities between the entries of K, each
    # entry carrying the round-off of T^T K_loc T (sums of <= 9 products with
    # |cos|, |sin| <= 1: <= 10 eps max|K|) and r the rounding of the arms
    # (eps max|r|); the 6-term row sums of K r then give
    # |K r| <= 6 (10 + 1 + 1) eps max|K| max|r| < 100 eps max|K| max|r|.
    # No condition number enters: max|K| already bounds every entry, so
    # the spread EA/L vs EI/L^3 does not amplify anything.  (The former
    # bound, 1e-9 = 4.5e6 eps, assumed it did.)  Measured <= 3.3 eps over
    # 3000 random elements of this strategy's range.
    scale = np.abs(K).max() * np.abs(R).max()
    assert np.abs(K @ R).max() <= 100 * EPS * scale
    T = R.T @ M @ R  # rigid-body mass matrix about the middle
    expect = np.diag([RHO * A * L, RHO * A * L, RHO * A * L**3 / 12 + RHO * I * L])
    # exact identities of the polynomial shape functions, so round-off only:
    # each entry of R^T M R sums 36 products of entries of M (each within
    # ~10 eps of max|M|, as K above) and of R (within eps): <= 36 x 12 eps
    # max|M| max|r|^2 < 500 eps of that scale (measured <= 15 eps)
    np.testing.assert_allclose(T, expect, rtol=0, atol=500 * EPS * np.abs(M).max() * np.abs(R).max() ** 2)
    # Kelvin-Voigt damping: L = (eta/E) K exactly
    np.testing.assert_allclose(Ld, (1e7 / E) * K, rtol=1e-15, atol=0)
    # symmetry survives the transformation (round-off)
    np.testing.assert_allclose(K, K.T, atol=1e-15 * np.abs(K).max())
    np.testing.assert_allclose(M, M.T, atol=1e-15 * np.abs(M).max())


def test_rigid_point_matrix_is_small_rotation_about_the_centre():
    # a point at arm (ax, ay): u = x - ay theta, v = y + ax theta (theta x r)
    P = rigid_point_matrix(np.array([0.3, -0.2]))
    np.testing.assert_array_equal(P, [[1, 0, 0.2], [0, 1, 0.3], [0, 0, 1]])


@pytest.mark.parametrize("angle_deg", [0.0, 35.0, -120.0])
@pytest.mark.parametrize("offset", [0.0, 0.04, -0.1])
def test_beam_point_moves_rigidly_with_a_rigid_beam(angle_deg, offset):
    """Under a rigid motion of the element, every material point (on or off
    the axis) moves like the point of a rigid body: beam_point_matrix P(xi,
    offset) @ r equals rigid_point_matrix(arm) for its position."""
    a = math.radians(angle_deg)
    L = 0.8
    e = np.array([math.cos(a), math.sin(a)])
    n = np.array([-e[1], e[0]])
    xy_i = np.array([1.0, 0.5])
    xy_j = xy_i + L * e
    s = _sec()
    xi = np.linspace(0.0, 1.0, 7)
    P = beam_point_matrix(xy_i, xy_j, xi, offset, **s)
    c = np.array([0.2, 0.1])
    R = _rigid_motions(np.array([xy_i, xy_j]), c)
    for k, x in enumerate(xi):
        pos = xy_i + x * L * e + offset * n
        # exact polynomial identities: round-off, 1e-13 absolute on O(1) entries
        np.testing.assert_allclose(P[k] @ R, rigid_point_matrix(pos - c), atol=1e-13)
    # nodes: P(0, 0) selects node i's (u, v, theta), P(1, 0) node j's
    P0 = beam_point_matrix(xy_i, xy_j, np.array([0.0, 1.0]), 0.0, **s)
    np.testing.assert_allclose(P0[0], np.eye(3, 6), atol=1e-15)
    np.testing.assert_allclose(P0[1], np.eye(3, 6, 3), atol=1e-15)


@pytest.mark.parametrize("order", [1, 2])
def test_beam_point_derivative_along_the_beam(order):
    """beam_point_matrix(order=k) is d^k/dx^k of the point map along the beam
    (x in metres).  Central differences of order k-1 with step h = 1e-4 m:
    the map is a cubic in x, so the truncation error is h^2/6 max|P'''|
    (< 1e-8 * 1e2 here); round-off is eps |P| / h ~ 1e-11."""
    xy_i, xy_j = np.array([0.0, 0.0]), np.array([0.48, 0.64])  # L = 0.8 at 53 deg
    L = 0.8
    s = _sec()
    xi = np.array([0.15, 0.5, 0.85])
    h = 1e-4
    P = beam_point_matrix(xy_i, xy_j, xi, 0.05, order=order, **s)
    up = beam_point_matrix(xy_i, xy_j, xi + h / L, 0.05, order=order - 1, **s)
    dn = beam_point_matrix(xy_i, xy_j, xi - h / L, 0.05, order=order - 1, **s)
    np.testing.assert_allclose((up - dn) / (2 * h), P, atol=1e-6 * np.abs(P).max())


# --------------------------------------------------------------------------- cantilever statics


def _tip(model: cl.Model, load: np.ndarray) -> np.ndarray:
    """Static solve C* q_i = f with the load (Fx, Fy, Mz) at node b;
    returns (u, v, theta) of node b."""
    fz = cl.assemble(model).at()
    Tb = fz.point("b")  # (3, n_i) map q_i -> (u, v, theta) of node b
    f = Tb.T @ load  # virtual work: generalised force of a point load
    q = np.linalg.solve(fz.C, f)
    return Tb @ q


CASES = {
    # name: (L, h) with b = 0.05; phi = 12EI/(kappa G A L^2) = (E/kappa G) (h/L)^2 per element
    "stocky": (0.5, 0.25),  # h/L = 0.5: shear deflection ~ 20 % of bending
    "slender": (2.0, 0.02),  # h/L = 0.01: shear deflection ~ 3e-4 of bending
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("elements", [1, 3, 8])
@pytest.mark.parametrize("clamp", ["support", "ground"])
@pytest.mark.parametrize("angle_deg", [0.0, 30.0])
def test_timoshenko_cantilever_tip_deflection_is_exact(beam_model_text, case, elements, clamp, angle_deg):
    """Tip load P across the beam: v = PL^3/(3EI) + PL/(kappa G A) and
    psi = PL^2/(2EI); tip moment M0: v = M0 L^2/(2EI), psi = M0 L/(EI); axial
    load N: u = NL/(EA).  The interdependent element is exact for end loads,
    so these hold to round-off for any number of elements."""
    L, h = CASES[case]
    b = 0.05
    A, I = b * h, b * h**3 / 12
    model = cl.loads_model(beam_model_text(L, h, b=b, elements=elements, clamp=clamp, angle_deg=angle_deg))
    a = math.radians(angle_deg)
    e = np.array([math.cos(a), math.sin(a), 0.0])
    n = np.array([-math.sin(a), math.cos(a), 0.0])
    P, M0, N = 1.0e4, 2.0e3, 5.0e5
    # the relative error of a linear solve is ~ cond(C*) eps; cond grows as
    # (L/h)^2 (axial vs bending) times elements^2..^4: <= ~1e8 for the slender
    # 8-element beam, so 1e-8 relative is the round-off bound with margin.
    tol = 1e-8
    w = _tip(model, P * n)
    v_exact = P * L**3 / (3 * E * I) + P * L / (KAPPA * G * A)
    assert w @ n == pytest.approx(v_exact, rel=tol)
    assert w[2] == pytest.approx(P * L**2 / (2 * E * I), rel=tol)
    assert abs(w @ e) <= tol * v_exact  # no axial motion under a transverse load
    w = _tip(model, M0 * np.array([0.0, 0.0, 1.0]))
    assert w @ n == pytest.approx(M0 * L**2 / (2 * E * I), rel=tol)
    assert w[2] == pytest.approx(M0 * L / (E * I), rel=tol)
    w = _tip(model, N * e)
    assert w @ e == pytest.approx(N * L / (E * A), rel=tol)


def test_shear_deflection_is_what_separates_stocky_from_slender(beam_model_text):
    """Guard that the stocky case really tests shear: its shear part PL/(kGA)
    is about 20 % of the bending part PL^3/(3EI), so an Euler-Bernoulli
    element would fail the exactness test above by that much."""
    L, h = CASES["stocky"]
    A, I = 0.05 * h, 0.05 * h**3 / 12
    ratio = (L / (KAPPA * G * A)) / (L**3 / (3 * E * I))
    assert 0.15 < ratio < 0.25


# --------------------------------------------------------------------------- cantilever dynamics


def timoshenko_cantilever_omega(E, G, kappa, rho, A, I, L, mode=1):
    """Exact angular frequency (rad/s) of a clamped-free Timoshenko beam.

    The beam equations  kGA(v'' - psi') + rho A w^2 v = 0,
    EI psi'' + kGA(v' - psi) + rho I w^2 psi = 0  have solutions e^{lambda x}
    with mu = lambda^2 a root of
        EI kGA mu^2 + (EI rho A + rho I kGA) w^2 mu + rho A w^2 (rho I w^2 - kGA) = 0,
    one positive (alpha^2) and one negative (-beta^2) below the cut-off
    frequency sqrt(kGA / (rho I)).  With v = cosh, sinh, cos, sin and the
    matching psi, the clamped-free conditions v(0) = psi(0) = 0,
    EI psi'(L) = 0, kGA (v'(L) - psi(L)) = 0 give a 4x4 determinant whose
    zeros are the natural frequencies (Huang, J. Appl. Mech. 28, 1961;
    Han, Benaroya & Wei, J. Sound Vib. 225(5), 935-988, 1999, Sec. 6).
    """
    kGA = kappa * G * A

    def det(w: float) -> float:
        a = E * I * kGA
        b = (E * I * rho * A + rho * I * kGA) * w * w
        c = rho * A * w * w * (rho * I * w * w - kGA)  # < 0 below the cut-off
        disc = math.sqrt(b * b - 4 * a * c)
        al = math.sqrt(-2 * c / (b + disc))  # mu = alpha^2 > 0, written without cancellation
        be = math.sqrt((b + disc) / (2 * a))  # mu = -beta^2 < 0
        raw = rho * A * w * w
        ka = (kGA * al * al + raw) / (kGA * al)  # psi = ka sinh for v = cosh
        mb = (raw - kGA * be * be) / (kGA * be)  # psi = mb sin for v = cos

        def basis(x):
            ch, sh, co, si = math.cosh(al * x), math.sinh(al * x), math.cos(be * x), math.sin(be * x)
            v = np.array([ch, sh, co, si])
            psi = np.array([ka * sh, ka * ch, mb * si, -mb * co])
            moment = E * I * np.array([ka * al * ch, ka * al * sh, mb * be * co, mb * be * si])
            # shear force kGA (v' - psi), simplified with the first equation so
            # that a stiff shear (large kGA) brings no cancellation
            shear = -raw * np.array([sh / al, ch / al, si / be, -co / be])
            return v, psi, moment, shear

        v0, p0, _, _ = basis(0.0)
        _, _, mL, qL = basis(L)
        return float(np.linalg.det(np.array([v0, p0, mL / (E * I), qL / raw])))

    w_eb = 1.87510407**2 * math.sqrt(E * I / (rho * A * L**4))  # shear and rotary inertia lower it
    w_cut = math.sqrt(kGA / (rho * I))  # above it the second root mu changes sign too
    grid = np.linspace(0.05 * w_eb, min(40 * w_eb, 0.999 * w_cut), 4000)
    found = 0
    prev = det(grid[0])
    for k in range(1, len(grid)):
        cur = det(grid[k])
        if prev * cur < 0:
            found += 1
            if found == mode:
                return scipy.optimize.brentq(det, grid[k - 1], grid[k], xtol=1e-13 * w_eb, rtol=4 * EPS)
        prev = cur
    raise AssertionError("root not bracketed below the cut-off frequency")  # pragma: no cover


def _fe_first_bending(beam_model_text, L, h, n, G_factor=None):
    text = beam_model_text(L, h, elements=n)
    if G_factor is not None:
        text = text.replace("nu = 0.3\n", f"G = {E * G_factor!r}\n")
    md = cl.modes(cl.assemble(cl.loads_model(text)), count=1)
    return float(md.omega[0])


def test_exact_frequency_equation_reduces_to_euler_bernoulli():
    """Oracle check: with shear made rigid and rotary inertia negligible the
    Timoshenko root tends to 1.87510407^2 sqrt(EI/(rho A L^4)); the residual
    relative gap is the rotary-inertia correction, of order (h/L)^2."""
    b, h, L = 0.05, 0.002, 1.0
    A, I = b * h, b * h**3 / 12
    w = timoshenko_cantilever_omega(E, 1e6 * E, KAPPA, RHO, A, I, L)
    w_eb = 1.87510407**2 * math.sqrt(E * I / (RHO * A * L**4))
    assert w < w_eb  # rotary inertia lowers it
    assert w == pytest.approx(w_eb, rel=5 * (h / L) ** 2)


def test_slender_cantilever_approaches_euler_bernoulli(beam_model_text):
    """h/L = 0.02: the Timoshenko correction to the first frequency is of
    order (h/L)^2 (measured -3.2e-4), and 8 elements are within 1e-5 of the
    exact Timoshenko value (measured 2.9e-6)."""
    L, h, b = 1.0, 0.02, 0.05
    A, I = b * h, b * h**3 / 12
    w_ex = timoshenko_cantilever_omega(E, G, KAPPA, RHO, A, I, L)
    w_eb = 1.87510407**2 * math.sqrt(E * I / (RHO * A * L**4))
    assert w_ex < w_eb  # shear flexibility and rotary inertia both lower it
    assert abs(w_ex / w_eb - 1) < 1e-3
    w_fe = _fe_first_bending(beam_model_text, L, h, 8)
    assert w_fe > w_ex  # a consistent-mass Galerkin model bounds the eigenvalue from above
    assert w_fe / w_ex - 1 < 1e-5


def test_stocky_cantilever_converges_at_rate_two_with_predicted_constant(beam_model_text):
    """First bending frequency of a stocky cantilever (h/L = 0.25) against the
    exact Timoshenko value, for n = 1..32 elements.

    The element's shear strain is constant per element, so it approximates
    the mode's varying shear strain (kGA gamma' = -rho A w^2 v) with an O(h)
    error; the eigenvalue error is the energy of that error,
        d(w^2)/w^2 ~ kGA (h^2/12) |gamma'|^2 / (w^2 rho A |v|^2) = rho w^2 h^2 / (12 kappa G),
    i.e.  dw/w ~ (rho / (24 kappa G)) (w L / n)^2 :  rate 2, with a known
    constant.  (The cubic-Hermite rate 4 shows only when shear is negligible;
    see the next test.)  Measured: slope -2.00 between n = 8 and 32, and
    n^2 dw/w at n = 32 is 0.987 of the predicted constant.
    """
    L, h, b = 1.0, 0.25, 0.05
    A, I = b * h, b * h**3 / 12
    w_ex = timoshenko_cantilever_omega(E, G, KAPPA, RHO, A, I, L)
    assert 0.9 < w_ex / (1.87510407**2 * math.sqrt(E * I / (RHO * A * L**4))) < 0.97  # shear matters (0.954)
    ns = np.array([1, 2, 4, 8, 16, 32])
    err = np.array([_fe_first_bending(beam_model_text, L, h, int(n)) / w_ex - 1 for n in ns])
    assert np.all(err > 0)  # upper bounds (Rayleigh-Ritz with consistent mass)
    assert np.all(np.diff(err) < 0)  # monotone convergence
    slope = np.polyfit(np.log(ns[3:]), np.log(err[3:]), 1)[0]
    # asymptotic regime n >= 8: the h^4 part is < 1 % of the h^2 part, so the
    # fitted slope is -2 within 0.05 (measured -2.006)
    assert -2.05 < slope < -1.95
    const = RHO / (24 * KAPPA * G) * (w_ex * L) ** 2
    # the leading-term prediction; the neglected rotary-inertia and h^4 terms
    # are O(1 %) at n = 32 (measured ratio 0.987), so 5 % is a safe band
    assert err[-1] * ns[-1] ** 2 / const == pytest.approx(1.0, abs=0.05)


def test_shear_rigid_cantilever_converges_at_rate_four(beam_model_text):
    """With G = 1000 E (phi -> 0) the element is the cubic Hermite beam with
    consistent mass (plus rotary inertia), whose eigenvalue error is O(h^4)
    (Strang & Fix, An Analysis of the Finite Element Method, Sec. 6.3:
    2(k + 1 - m) = 4 for cubics, m = 2).  Measured slope -3.97 between n = 4
    and 16; the band [3.7, 4.2] allows the pre-asymptotic curvature."""
    L, h, b = 1.0, 0.1, 0.05
    A, I = b * h, b * h**3 / 12
    w_ex = timoshenko_cantilever_omega(E, 1e3 * E, KAPPA, RHO, A, I, L)
    ns = np.array([4, 8, 16])
    err = np.array([_fe_first_bending(beam_model_text, L, h, int(n), G_factor=1e3) / w_ex - 1 for n in ns])
    slope = np.polyfit(np.log(ns), np.log(err), 1)[0]
    assert -4.2 < slope < -3.7


def test_slender_cantilever_pre_asymptotic_rate_is_near_four(beam_model_text):
    """h/L = 0.02: the shear term's constant (rho/(24 kappa G)) (w L)^2 is
    ~1.3e-5, so for n <= 8 the h^4 bending term dominates: measured slopes
    -3.3, -3.8, -3.6 (n = 1..8), fitted -3.6."""
    L, h = 1.0, 0.02
    b = 0.05
    A, I = b * h, b * h**3 / 12
    w_ex = timoshenko_cantilever_omega(E, G, KAPPA, RHO, A, I, L)
    ns = np.array([1, 2, 4, 8])
    err = np.array([_fe_first_bending(beam_model_text, L, h, int(n)) / w_ex - 1 for n in ns])
    slope = np.polyfit(np.log(ns), np.log(err), 1)[0]
    assert -4.1 < slope < -3.2


def _ss_timoshenko_omega(n: int, L: float, A: float, I: float) -> float:
    """Exact bending frequency n of a simply supported Timoshenko beam
    (Timoshenko 1921): v = sin(kx), psi = Psi cos(kx), k = n pi / L satisfy
    v = 0 and EI psi' = 0 at both ends, and the beam equations give
        det [[rho A w^2 - kGA k^2, kGA k], [kGA k, rho I w^2 - EI k^2 - kGA]] = 0,
    a quadratic in w^2 whose lower root is the bending frequency."""
    k, kGA = n * math.pi / L, KAPPA * G * A
    a = RHO * A * RHO * I
    b = -(RHO * A * (E * I * k * k + kGA) + RHO * I * kGA * k * k)
    c = kGA * k * k * (E * I * k * k + kGA) - (kGA * k) ** 2
    return math.sqrt((-b - math.sqrt(b * b - 4 * a * c)) / (2 * a))


def test_simply_supported_beam_against_the_closed_form(beam_model_text):
    """A stocky beam on a pin (fix x, y) and a roller (fix y), 32 elements:
    bending modes 1-3 against the closed form with the error predicted by the
    constant-shear-strain argument above, dw/w = rho w^2 h_e^2 / (24 kappa G)
    (measured 0.95-0.98 of it), and the first axial mode (fixed-free bar,
    w = pi c / (2L)) with the linear consistent-mass error (k h_e)^2 / 24.
    This also exercises partial [[support]] fix lists."""
    L, h, b, n = 1.0, 0.25, 0.05, 32
    A, I = b * h, b * h**3 / 12
    text = beam_model_text(L, h, b=b, elements=n).replace('node = "a"\n', 'node = "a"\nfix = ["x", "y"]\n')
    text += '\n[[support]]\nid = "roller"\nnode = "b"\nfix = ["y"]\n'
    om = cl.modes(cl.assemble(cl.loads_model(text)), count=4).omega
    w_axial = math.pi / (2 * L) * math.sqrt(E / RHO)
    bending = [w for w in om if abs(w / w_axial - 1) > 1e-2]
    axial = [w for w in om if abs(w / w_axial - 1) <= 1e-2]
    assert len(axial) == 1 and len(bending) == 3
    he = L / n
    for mode, w in enumerate(bending, start=1):
        w_ex = _ss_timoshenko_omega(mode, L, A, I)
        predicted = RHO * w_ex**2 * he**2 / (24 * KAPPA * G)
        # leading-order error model; higher-order terms are O((k h_e)^2) ~ 1-10 % of it
        assert 0.85 < (w / w_ex - 1) / predicted < 1.05
    predicted = (math.pi / (2 * L) * he) ** 2 / 24
    # linear elements with consistent mass: w_h^2 = w^2 (1 + (k h)^2/12 + O(h^4)); measured 1.0000 of it
    assert (axial[0] / w_axial - 1) / predicted == pytest.approx(1.0, abs=1e-3)


@pytest.mark.parametrize("elements", [1, 3])
@pytest.mark.parametrize("x", [0.13, 0.3, 0.5])
def test_cantilever_interior_points_are_exact(beam_model_text, elements, x):
    """Inside the elements too, the shape functions are the exact static
    solution under an end load: for the tip load P, the section rotation is
    psi(x) = P (L x - x^2/2) / EI and the deflection
    v(x) = P (L x^2/2 - x^3/6) / EI + P x / (kappa G A); a material point at
    transverse offset y0 moves axially by -y0 psi(x).  Read through a
    [[point]] on the beam (FrozenSystem.point), stocky beam, round-off only."""
    L, h, b = 0.5, 0.25, 0.05
    A, I = b * h, b * h**3 / 12
    y0 = h / 2
    text = beam_model_text(L, h, b=b, elements=elements)
    text += f'\n[[point]]\nid = "p"\nbeam = "beam"\ndistance = {x}\noffset = {y0}\n'
    fz = cl.assemble(cl.loads_model(text)).at()
    P = 1.0e4
    q = np.linalg.solve(fz.C, fz.point("b").T @ np.array([0.0, P, 0.0]))
    u, v, th = fz.point("p") @ q
    psi = P * (L * x - x * x / 2) / (E * I)
    v_ex = P * (L * x * x / 2 - x**3 / 6) / (E * I) + P * x / (KAPPA * G * A)
    # condition of the stocky model ~1e4: 1e-10 relative is round-off with margin
    assert th == pytest.approx(psi, rel=1e-10)
    assert v == pytest.approx(v_ex, rel=1e-10)
    assert u == pytest.approx(-y0 * psi, rel=1e-10)
