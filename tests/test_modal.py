"""Modal analysis against closed forms: rigid-body modes of a free-free beam,
a rigid body on springs, proportional damping, and matrix-level models whose
modes must equal scipy.linalg.eigh of the given matrices.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.io
import scipy.linalg
import scipy.sparse

import chatterlab as cl
from chatterlab.errors import InputError, ModelError
from chatterlab.model._items import DIRECTIONS

E, NU, RHO, KAPPA = 2.1e11, 0.3, 7850.0, 5.0 / 6.0
G = E / (2 * (1 + NU))
EPS = np.finfo(float).eps


# --------------------------------------------------------------------------- round-off bounds
#
# modes() solves C phi = lambda A phi with LAPACK (scipy.linalg.eigh): the
# Cholesky reduction A = L L^T, Ct = L^-1 C L^-T, psi = L^T phi, and a
# backward-stable symmetric eigensolver, whose results are exact for Ct + E
# with ||E|| <= p(n) eps ||Ct|| = p(n) eps lambda_max (LAPACK Users' Guide,
# 3rd ed., sec. 4.7; p(n) "a modestly growing function of n", taken as n).
# Hence, with no tuned number anywhere:
#   eigenvalues (Weyl):            |d lambda_k| <= n eps lambda_max;
#   eigenvectors (Davis-Kahan sin-theta): the computed span of a cluster of
#     eigenvalues is within the angle  n eps lambda_max / gap  of the true
#     span, measured in the mass inner product <x, y> = x^T A y (the metric
#     of psi), gap = distance from the cluster to every other eigenvalue.
# lambda_max / gap is the condition number of the invariant subspace.  Inside
# a degenerate cluster (the three rigid motions of a free body, repeated
# frequencies) individual eigenvectors are not determined at all -- any
# A-orthonormal basis of the span is right, and which one LAPACK returns
# depends on the BLAS and its threads -- so only the span is compared, by
# principal angles (scipy.linalg.subspace_angles); for a single mode the span
# is a line, which also makes the comparison blind to the sign of phi.
# LAPACK's guaranteed bound (sec. 4.10) adds the Cholesky reduction's error, a
# factor ||A^-1|| ||A|| sqrt(kappa(A)) that is O(1) useless here; it does not
# apply to null vectors of C (A's round-off moves no vector with C phi = 0)
# and, for these well-scaled models, is measured far below eps lambda_max.


def eigenvalue_tol(lam: np.ndarray) -> float:
    """Absolute round-off bound on computed eigenvalues ``lam`` (all n of them)."""
    lam = np.asarray(lam, dtype=float)
    return lam.size * EPS * float(np.abs(lam).max())


def span_angle_tol(lam: np.ndarray, cluster) -> float:
    """Round-off bound (rad, mass metric) on the angle between the computed and
    the true span of the eigenvectors ``cluster`` (indices into ``lam``, all n
    eigenvalues of the pencil)."""
    lam = np.asarray(lam, dtype=float)
    inside = np.zeros(lam.size, dtype=bool)
    inside[np.asarray(cluster)] = True
    gap = float(np.abs(lam[~inside][:, None] - lam[inside][None, :]).min())
    return eigenvalue_tol(lam) / gap


def mass_angle(X: np.ndarray, Y: np.ndarray, A: np.ndarray) -> float:
    """Largest principal angle (rad) between span(X) and span(Y) in the inner
    product x^T A y (A symmetric positive definite)."""
    Lt = np.linalg.cholesky(A).T
    X, Y = np.asarray(X).reshape(A.shape[0], -1), np.asarray(Y).reshape(A.shape[0], -1)
    return float(scipy.linalg.subspace_angles(Lt @ X, Lt @ Y).max())


def assert_within(actual: np.ndarray, expected: np.ndarray, rtol: np.ndarray) -> None:
    """|actual - expected| <= rtol |expected| elementwise, rtol an array of bounds."""
    err = np.abs(np.asarray(actual) - expected) / np.abs(expected)
    assert np.all(err <= rtol), f"relative error {err} exceeds the bound {rtol}"


def quad_form_tol(Phi: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Relative round-off bound on each phi^T X phi (columns phi of Phi):
    n eps |phi|^T |X| |phi| / |phi^T X phi| (Higham, Accuracy and Stability
    of Numerical Algorithms, 2nd ed., sec. 3.1, for the two dot products)."""
    n = X.shape[0]
    num = np.einsum("ik,ij,jk->k", np.abs(Phi), np.abs(X), np.abs(Phi))
    return 2 * n * EPS * num / np.abs(np.einsum("ik,ij,jk->k", Phi, X, Phi))


def normalisation_tol(n: int, A: np.ndarray) -> float:
    """Round-off bound on |Phi^T A Phi - I| for mass-normalised Phi = L^-T Psi:
    Psi is orthonormal to n eps, and the triangular back-substitution is
    exact for L + dL with |dL| <= n eps |L|, a relative change of the
    quadratic form of at most 2 n eps kappa(L), kappa(L) = sqrt(kappa(A))."""
    return n * EPS * (1.0 + 2.0 * math.sqrt(np.linalg.cond(A)))


# --------------------------------------------------------------------------- free-free beam


@pytest.fixture
def free_beam(beam_model_text):
    # slender (h/L = 0.01), 16 elements, at 20 degrees so that x and y mix
    return cl.assemble(cl.loads_model(beam_model_text(2.0, 0.02, elements=16, clamp=None, angle_deg=20.0)))


def test_free_free_beam_reports_three_rigid_body_modes(free_beam):
    md = cl.modes(free_beam, rigid="report")
    assert len(md.rigid) == 3
    assert md.rigid_shapes.shape == (free_beam.at().n, 3)
    # the first elastic mode: Euler-Bernoulli free-free 4.73004^2 sqrt(EI/(rho A L^4));
    # the Timoshenko correction is ~ -(beta L)^2 (r/L)^2 (1 + E/kappa G)/2 ~ -4e-4
    # and the 16-element discretisation error ~ +1e-6: measured -3.6e-4; 1e-3 bounds it
    L, h, b = 2.0, 0.02, 0.05
    A, I = b * h, b * h**3 / 12
    w_eb = 4.73004074**2 * math.sqrt(E * I / (RHO * A * L**4))
    assert md.omega[0] == pytest.approx(w_eb, rel=1e-3)
    assert md.omega[0] < w_eb  # shear and rotary inertia lower it


def test_free_free_beam_is_refused_by_default(free_beam):
    with pytest.raises(ModelError) as info:
        cl.modes(free_beam)
    msg = str(info.value)
    assert isinstance(info.value, ValueError)
    assert "not held by the foundation" in msg and "3 rigid-body mode(s)" in msg
    # the floating part is named: the beam's nodes a, b or its internal nodes beam#k
    assert any(p in msg for p in ("beam#", " a (", " b ("))
    assert "[[support]]" in msg  # and the fix


def test_free_free_beam_matrices(free_beam):
    """M, K (all coordinates) and A*, C* symmetric; M positive definite on
    the structure's coordinates (the ground's three are given and massless);
    K positive semi-definite with exactly three zero eigenvalues (the plane's
    rigid motions)."""
    sy = free_beam
    for X in (sy.M, sy.K):
        np.testing.assert_allclose(X, X.T, atol=1e-14 * np.abs(X).max())
    fz = sy.at()
    for X in (fz.A, fz.C):
        np.testing.assert_allclose(X, X.T, atol=1e-14 * np.abs(X).max())
    keep = np.setdiff1d(np.arange(sy.n), sy.g)
    np.testing.assert_array_equal(keep, sy.i)  # no constraints: independent = not given
    m = np.linalg.eigvalsh(sy.M[np.ix_(keep, keep)])
    assert m.min() > 0
    k = np.linalg.eigvalsh(sy.K[np.ix_(keep, keep)])
    # a true zero comes out at round-off, |lambda| <= n eps max lambda (Weyl
    # and a backward-stable eigvalsh; here 1.1e-14 of the largest, measured
    # 4e-17); the smallest elastic eigenvalue (EI/L^3 scale over EA/h_e scale)
    # is 2.6e-7 of the largest, far above it
    tol = eigenvalue_tol(k)
    assert np.sum(np.abs(k) < tol) == 3
    assert k.min() > -tol  # semi-definite
    assert np.sort(k)[3] > 1e6 * tol  # and a clear gap to the elastic ones
    c = np.linalg.eigvalsh(fz.C)
    assert np.sum(np.abs(c) < eigenvalue_tol(c)) == 3


def test_rigid_modes_are_the_plane_motions(free_beam):
    """The reported rigid modes span x and y translation and rotation: the
    span of the motions u = x0 - theta y, v = y0 + theta x, theta of every
    node (principal angles in the mass metric, within the round-off bound of
    the block comment at the top)."""
    fz = free_beam.at()
    md = cl.modes(free_beam, rigid="report")
    R = md.rigid_shapes
    # the three rigid modes are one triple eigenvalue 0: only their span is
    # defined, and it is compared with the span of the exact rigid motions
    lam = scipy.linalg.eigh(fz.C, fz.A, eigvals_only=True)  # independent of modes()
    rigid = np.arange(3)
    # node positions along the beam (2 m at 20 deg) from the beam's node list
    ang = math.radians(20.0)
    pos = {
        "a": (0.0, 0.0),
        "b": (2.0 * math.cos(ang), 2.0 * math.sin(ang)),
        **{f"beam#{j}": (j / 16 * 2.0 * math.cos(ang), j / 16 * 2.0 * math.sin(ang)) for j in range(1, 16)},
    }
    # columns: x translation, y translation, rotation about the origin
    motions = np.zeros((fz.n, 3))
    for r, name in enumerate(free_beam.names_i):
        node, _, d = name.rpartition(".")
        x, y = pos[node]
        motions[r] = {"x": (1.0, 0.0, -y), "y": (0.0, 1.0, x), "rz": (0.0, 0.0, 1.0)}[d]
    # tolerance n eps lambda_max / lambda_4 (block comment above): 51 eps x
    # 7.4e5 = 8.3e-9 rad; measured 6.7e-11 (gvd; 6.3e-11 gv/gvx).  The former
    # entrywise check at an absolute 1e-10 failed by 1.5e-10 on some BLAS.
    tol = span_angle_tol(lam, rigid)
    assert mass_angle(R, motions, fz.A) <= tol
    assert tol < 1e-7  # the bound is sharp enough to tell the plane motions apart
    # ...and the rotation of a beam 0.1 % longer (arms 0.1 % off) is far outside it
    is_rz = np.array([name.endswith(".rz") for name in free_beam.names_i])
    stretched = motions.copy()
    stretched[~is_rz, 2] *= 1.001
    assert mass_angle(R, stretched, fz.A) > 1e3 * tol
    # the rigid modes' Rayleigh quotients (phi^T A phi = 1) are zero eigenvalues:
    # within n eps lambda_max (measured 6.8e-8 against 2.3e-4)
    assert np.abs(R.T @ fz.C @ R).max() <= eigenvalue_tol(lam)
    np.testing.assert_allclose(R.T @ fz.A @ R, np.eye(3), rtol=0, atol=normalisation_tol(fz.n, fz.A))


# --------------------------------------------------------------------------- rigid body on springs

BLOCK = """
[[body]]
id = "block"
mass = {m}
inertia = {J}
centre = [0.0, 0.0]

[[spring]]
id = "left"
a = {{ body = "block", offset = [{ma}, 0.0] }}
b = {{ body = "ground", offset = [{ma}, 0.0] }}
c2 = {k1}

[[spring]]
id = "right"
a = {{ body = "block", offset = [{a}, 0.0] }}
b = {{ body = "ground", offset = [{a}, 0.0] }}
c2 = {k2}

[[spring]]
id = "side"
a = "block"
b = "ground"
c1 = {kx}
"""


def test_rigid_body_on_springs_closed_form():
    """A body (m, J) on vertical springs k1 at x = -a and k2 at x = +a and a
    horizontal spring kx at its centre:
      horizontal  w^2 = kx / m;
      vertical/rocking  det([[k1+k2 - m w^2, (k2-k1) a], [(k2-k1) a, (k1+k2) a^2 - J w^2]]) = 0,
      i.e.  m J w^4 - (m (k1+k2) a^2 + J (k1+k2)) w^2 + 4 k1 k2 a^2 = 0."""
    m, J, a, k1, k2, kx = 120.0, 9.0, 0.4, 2.0e6, 5.0e6, 3.0e6
    model = cl.loads_model(BLOCK.format(m=m, J=J, a=a, ma=-a, k1=k1, k2=k2, kx=kx))
    md = cl.modes(cl.assemble(model))
    S = k1 + k2
    p, q = m * S * a * a + J * S, 4 * k1 * k2 * a * a
    disc = math.sqrt(p * p - 4 * m * J * q)
    w2 = np.array(sorted([(p - disc) / (2 * m * J), (p + disc) / (2 * m * J), kx / m]))
    # LAPACK's n eps lambda_max, plus the closed form's own round-off (the
    # quadratic formula: ~8 roundings of terms <= p / mJ = w2_1 + w2_2);
    # measured 0.23 eps lambda_max
    closed = 8 * EPS * (p / (m * J))
    np.testing.assert_allclose(md.omega**2, w2, rtol=0, atol=eigenvalue_tol(w2) + closed)
    # mode shapes, each a line (distinct eigenvalues): in the horizontal mode
    # (x); in a vertical/rocking mode (y, theta) with theta / y = (m w^2 - S) / ((k2 - k1) a)
    fz = md.frozen
    names = fz.names
    iy, ir, ix = names.index("block.y"), names.index("block.rz"), names.index("block.x")
    for k in range(3):
        expect = np.zeros(3)
        if w2[k] == kx / m:
            expect[ix] = 1.0
        else:
            expect[iy], expect[ir] = 1.0, (m * w2[k] - S) / ((k2 - k1) * a)
        # span-angle bound n eps lambda_max / gap_k (block comment at the top):
        # 3 eps x 1.4e5 / 1.7e4 = 25 eps; plus the expected line's own
        # round-off, a few roundings amplified by the cancellations p - disc
        # (2.2x) and m w2 - S (3.6x): < 32 eps.  Measured <= 1.1 eps.
        tol = span_angle_tol(w2, [k]) + 32 * EPS
        assert mass_angle(md.shapes[:, k], expect, fz.A) <= tol
    np.testing.assert_allclose(
        md.shapes.T @ fz.A @ md.shapes, np.eye(3), rtol=0, atol=normalisation_tol(3, fz.A)
    )


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 117.0])
def test_rigid_body_on_a_rotated_spring(angle_deg):
    """A body on one spring at its centre with axes rotated by alpha, c1 != c2:
    frequencies sqrt(c1/m), sqrt(c2/m), sqrt(c6/J) whatever alpha, and the c1
    mode translates along (cos alpha, sin alpha)."""
    m, J, c1, c2, c6 = 50.0, 2.0, 8.0e6, 2.0e6, 1.0e5
    text = (
        f'[[body]]\nid = "puck"\nmass = {m}\ninertia = {J}\ncentre = [1.0, 2.0]\n'
        f'[[spring]]\nid = "s"\na = "puck"\nb = "ground"\nc1 = {c1}\nc2 = {c2}\nc6 = {c6}\nangle_deg = {angle_deg}\n'
    )
    md = cl.modes(cl.assemble(cl.loads_model(text)))
    lam = np.sort([c1 / m, c2 / m, c6 / J])
    # LAPACK's n eps lambda_max plus one rounding in each c / m (measured <= 2.5 eps relative)
    np.testing.assert_allclose(md.omega**2, lam, rtol=EPS, atol=eigenvalue_tol(lam))
    k1 = int(np.argmin(np.abs(lam - c1 / m)))
    e = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg)), 0.0])
    # the c1 mode is the line through (cos alpha, sin alpha, 0) in (x, y, rz):
    # span-angle bound 3 eps x 1.6e5 / 1.1e5 ~ 1e-15 rad, plus cos/sin round-off
    fz = md.frozen
    assert fz.names == ("puck.x", "puck.y", "puck.rz")
    assert mass_angle(md.shapes[:, k1], e, fz.A) <= span_angle_tol(lam, [k1]) + 2 * EPS
    # the body's point moves with its coordinates: the same shape, mass-normalised
    u = md.point_shapes("puck")[:, k1]
    np.testing.assert_array_equal(u, md.shapes[:, k1])
    assert abs(u @ fz.A @ u - 1.0) <= normalisation_tol(3, fz.A)


def test_modal_damping_ratio_of_proportional_damping():
    """Dampers d = alpha_k c on every spring make L = beta K: zeta = beta w / 2."""
    m, J, a, k1, k2, kx, beta = 120.0, 9.0, 0.4, 2.0e6, 5.0e6, 3.0e6, 2.0e-4
    text = BLOCK.format(m=m, J=J, a=a, ma=-a, k1=k1, k2=k2, kx=kx)
    text = text.replace(f"c2 = {k1}\n", f"c2 = {k1}\nd2 = {beta * k1}\n")
    text = text.replace(f"c2 = {k2}\n", f"c2 = {k2}\nd2 = {beta * k2}\n")
    text = text.replace(f"c1 = {kx}\n", f"c1 = {kx}\nd1 = {beta * kx}\n")
    md = cl.modes(cl.assemble(cl.loads_model(text)))
    # zeta = phi^T B* phi / 2 w with B* = beta C* (to one rounding of each
    # beta c): phi^T C* phi = lambda to n eps lambda_max, plus the quadratic
    # form's own round-off (measured: at most 1/12 of this bound)
    rtol = eigenvalue_tol(md.omega**2) / md.omega**2 + quad_form_tol(md.shapes, md.frozen.B) + 2 * EPS
    assert_within(md.damping_ratio, beta * md.omega / 2, rtol)


def test_count_and_argument_checks():
    model = cl.loads_model(BLOCK.format(m=1.0, J=1.0, a=0.5, ma=-0.5, k1=1.0, k2=2.0, kx=3.0))
    sy = cl.assemble(model)
    assert len(cl.modes(sy, count=2)) == 2
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InputError):
            cl.modes(sy, count=bad)
    with pytest.raises(InputError):
        cl.modes(sy, rigid="ignore")


# --------------------------------------------------------------------------- matrix-level models

N = 5
COORDS = [f"q{k}" for k in range(1, N + 1)]


def _matrices(seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((N, N))
    M = X @ X.T + N * np.eye(N)  # symmetric positive definite
    Y = rng.standard_normal((N, N))
    K = 1e6 * (Y @ Y.T + 0.5 * np.eye(N))
    Lm = 1e-4 * K + 0.5 * M
    return M, Lm, K


def _rows(X: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(repr(float(x)) for x in r) + "]" for r in X) + "]"


def _check_modes(model: cl.Model, M: np.ndarray, K: np.ndarray, keep=None) -> cl.Modes:
    md = cl.modes(cl.assemble(model))
    keep = np.arange(N) if keep is None else np.asarray(keep)
    Mk, Kk = M[np.ix_(keep, keep)], K[np.ix_(keep, keep)]
    lam = scipy.linalg.eigh(Kk, Mk, eigvals_only=True)
    # the file round trips (repr, Matrix Market at 17 digits, npz) are exact,
    # so two solutions of one problem, each within n eps lambda_max (maybe by
    # different LAPACK drivers): d omega / omega <= 2 tol / (2 lambda) + sqrt's
    # rounding (measured: at most 1/12 of this bound)
    assert_within(md.omega, np.sqrt(lam), eigenvalue_tol(lam) / lam + EPS)
    np.testing.assert_allclose(
        md.shapes.T @ Mk @ md.shapes, np.eye(keep.size), rtol=0, atol=normalisation_tol(keep.size, Mk)
    )
    return md


def test_matrix_model_inline():
    M, Lm, K = _matrices()
    names = ", ".join(f'"{c}"' for c in COORDS)
    text = f"[matrices]\ncoordinates = [{names}]\nM = {_rows(M)}\nL = {_rows(Lm)}\nK = {_rows(K)}\n"
    md = _check_modes(cl.loads_model(text), M, K)
    # damping ratio phi^T L phi / (2 w) with L = 1e-4 K + 0.5 M: 1e-4 w/2 + 0.5/(2 w),
    # to the round-off of phi^T K phi = lambda, of phi^T M phi = 1 and of the
    # quadratic form phi^T L phi itself (measured: at most 1/14 of this bound)
    rtol = (
        eigenvalue_tol(md.omega**2) / md.omega**2
        + normalisation_tol(N, M)
        + quad_form_tol(md.shapes, md.frozen.B)
        + 2 * EPS
    )
    assert_within(md.damping_ratio, 1e-4 * md.omega / 2 + 0.5 / (2 * md.omega), rtol)
    # a named coordinate is a response quantity
    row = md.frozen.dof("q2")
    np.testing.assert_array_equal(row, np.eye(N)[1])


def test_matrix_model_with_given_coordinates():
    M, _, K = _matrices()
    names = ", ".join(f'"{c}"' for c in COORDS)
    text = f'[matrices]\ncoordinates = [{names}]\nM = {_rows(M)}\nK = {_rows(K)}\ngiven = ["q2", "q5"]\n'
    _check_modes(cl.loads_model(text), M, K, keep=[0, 2, 3])


def test_matrix_model_npz(tmp_path):
    M, Lm, K = _matrices(7)
    np.savez(tmp_path / "fe.npz", M=M, L=Lm, K=K, coordinates=np.array(COORDS))
    p = tmp_path / "model.toml"
    p.write_text('[matrices]\nfile = "fe.npz"\n')
    model = cl.load_model(p)
    assert model.matrices.coordinates == tuple(COORDS)
    np.testing.assert_array_equal(model.matrices.L, Lm)
    _check_modes(model, M, K)


@pytest.mark.parametrize("sparse", [False, True])
def test_matrix_model_matrix_market(tmp_path, sparse):
    M, _, K = _matrices(11)
    for name, X in (("M", M), ("K", K)):
        scipy.io.mmwrite(
            str(tmp_path / f"{name}.mtx"), scipy.sparse.coo_matrix(X) if sparse else X, precision=17
        )
    names = ", ".join(f'"{c}"' for c in COORDS)
    p = tmp_path / "model.toml"
    p.write_text(f'[matrices]\ncoordinates = [{names}]\nM = "M.mtx"\nK = "K.mtx"\n')
    _check_modes(cl.load_model(p), M, K)


def test_matrix_model_refuses_a_non_symmetric_file(tmp_path):
    M, _, K = _matrices()
    K[0, 3] *= 1.01
    np.savez(tmp_path / "fe.npz", M=M, K=K, coordinates=np.array(COORDS))
    p = tmp_path / "model.toml"
    p.write_text('[matrices]\nfile = "fe.npz"\n')
    with pytest.raises(ModelError) as info:
        cl.load_model(p)
    msg = str(info.value)
    assert str(p) in msg and "[matrices]" in msg and "K: must be symmetric" in msg


def test_matrix_model_refuses_a_wrong_shaped_file(tmp_path):
    M, _, K = _matrices()
    scipy.io.mmwrite(str(tmp_path / "M.mtx"), M[:, :4])
    np.save(tmp_path / "K.npy", K)
    names = ", ".join(f'"{c}"' for c in COORDS)
    p = tmp_path / "model.toml"
    p.write_text(f'[matrices]\ncoordinates = [{names}]\nM = "M.mtx"\nK = "K.npy"\n')
    with pytest.raises(ModelError) as info:
        cl.load_model(p)
    msg = str(info.value)
    # since 6751d12 the shape is judged from the file's header: "M: '.../M.mtx'
    # holds an array of shape (5, 4); a matrix must be square"
    assert str(p) in msg and "[matrices]: M:" in msg and "(5, 4)" in msg and "must be square" in msg


def test_directions_are_x_y_rz():
    assert DIRECTIONS == ("x", "y", "rz")


def test_soft_mounts_on_a_fine_mesh_are_not_mistaken_for_rigid_modes(beam_model_text):
    """A stocky beam in 64 elements on two soft springs (1e3 N/m at each end,
    x and y): its lowest omega^2 is 4e-11 of the largest (short elements are
    stiff), far above the round-off of a true zero (~1e-16) but below the
    former bound 1e-10, which called these mounting modes rigid and refused
    the model.  Against the rigid beam on springs: horizontal and bounce
    omega^2 = 2k/m, rocking omega^2 = 2k (L/2)^2 / J with J = rho A L^3/12 +
    rho I L.  Tolerance 1e-4: round-off of an eigenvalue 4e-11 of the
    largest is ~1e-6 relative (measured <= 9e-6 in omega), and the beam's
    flexibility shifts them by ~k L^3/EI x (a small coefficient) ~ 1e-5."""
    L, h, b, k = 1.0, 0.1, 0.05, 1.0e3
    A, I = b * h, b * h**3 / 12
    text = beam_model_text(L, h, b=b, elements=64, clamp=None)
    for end in ("a", "b"):
        text += f'\n[[spring]]\nid = "mount-{end}"\na = "{end}"\nb = "ground"\nc1 = {k}\nc2 = {k}\n'
    md = cl.modes(cl.assemble(cl.loads_model(text)), count=3)
    m, J = RHO * A * L, RHO * A * L**3 / 12 + RHO * I * L
    expect = np.sqrt(sorted([2 * k / m, 2 * k / m, 2 * k * (L / 2) ** 2 / J]))
    np.testing.assert_allclose(md.omega, expect, rtol=1e-4)
    lam_ratio = (md.omega[0] / cl.modes(cl.assemble(cl.loads_model(text))).omega[-1]) ** 2
    assert lam_ratio < 1e-10  # the case the former bound got wrong


def test_support_of_some_body_coordinates():
    """A body whose rotation is given by a [[support]] (fix = ["rz"]) on an
    x/y spring: two modes, sqrt(c1/m) and sqrt(c2/m)."""
    text = (
        '[[body]]\nid = "puck"\nmass = 4.0\ninertia = 0.5\ncentre = [0.0, 0.0]\n'
        '[[spring]]\nid = "s"\na = "puck"\nb = "ground"\nc1 = 4.0e4\nc2 = 9.0e4\n'
        '[[support]]\nid = "no-spin"\nbody = "puck"\nfix = ["rz"]\n'
    )
    sy = cl.assemble(cl.loads_model(text))
    assert sy.names_i == ("puck.x", "puck.y")
    np.testing.assert_allclose(cl.modes(sy).omega, [100.0, 150.0], rtol=1e-14)


def test_matrix_model_support_of_a_coordinate():
    """[[support]] coordinate = "q3" removes q3 like [matrices] given."""
    M, _, K = _matrices()
    names = ", ".join(f'"{c}"' for c in COORDS)
    text = f'[matrices]\ncoordinates = [{names}]\nM = {_rows(M)}\nK = {_rows(K)}\n[[support]]\ncoordinate = "q3"\n'
    _check_modes(cl.loads_model(text), M, K, keep=[0, 1, 3, 4])
