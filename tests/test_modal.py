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
from chatterlab.model import DIRECTIONS

E, NU, RHO, KAPPA = 2.1e11, 0.3, 7850.0, 5.0 / 6.0
G = E / (2 * (1 + NU))


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
    # a true zero comes out at round-off, |lambda| ~ eps * max lambda (measured
    # 4e-17); the smallest elastic eigenvalue (EI/L^3 scale over EA/h_e scale)
    # is 2.6e-7 of the largest here, so 1e-12 separates them
    tol = 1e-12 * k.max()
    assert np.sum(np.abs(k) < tol) == 3
    assert k.min() > -tol  # semi-definite
    assert np.sort(k)[3] > 100 * tol  # and a clear gap to the elastic ones
    c = np.linalg.eigvalsh(fz.C)
    assert np.sum(np.abs(c) < 1e-12 * c.max()) == 3


def test_rigid_modes_are_the_plane_motions(free_beam):
    """The reported rigid modes span x and y translation and rotation: every
    node's (u, v, theta) in them is a rigid motion u = x0 - theta y,
    v = y0 + theta x."""
    md = cl.modes(free_beam, rigid="report")
    R = md.rigid_shapes
    names = free_beam.names_i
    assert (
        np.abs(R.T @ free_beam.at().C @ R).max()
        < 1e-6 * np.abs(free_beam.at().C).max() * np.abs(R).max() ** 2
    )
    # node positions along the beam (2 m at 20 deg) from the beam's node list
    ang = math.radians(20.0)
    pos = {
        "a": (0.0, 0.0),
        "b": (2.0 * math.cos(ang), 2.0 * math.sin(ang)),
        **{f"beam#{j}": (j / 16 * 2.0 * math.cos(ang), j / 16 * 2.0 * math.sin(ang)) for j in range(1, 16)},
    }
    for k in range(3):
        q = dict(zip(names, R[:, k], strict=True))
        th = q["a.rz"]
        x0, y0 = q["a.x"], q["a.y"]
        for nd, (x, y) in pos.items():
            # mass-normalised shapes are ~1/sqrt(m) ~ 0.1; round-off 1e-12 of that
            assert q[f"{nd}.rz"] == pytest.approx(th, abs=1e-10)
            assert q[f"{nd}.x"] == pytest.approx(x0 - th * y, abs=1e-10)
            assert q[f"{nd}.y"] == pytest.approx(y0 + th * x, abs=1e-10)


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
    w2 = sorted([(p - disc) / (2 * m * J), (p + disc) / (2 * m * J), kx / m])
    # a 3x3 generalised eigenproblem: round-off ~1e-15 relative
    np.testing.assert_allclose(md.omega**2, w2, rtol=1e-12)
    # mode shapes: in a vertical/rocking mode theta / y = (m w^2 - S) / ((k2 - k1) a)
    names = md.frozen.names
    iy, ir, ix = names.index("block.y"), names.index("block.rz"), names.index("block.x")
    for k in range(3):
        phi = md.shapes[:, k]
        if abs(md.omega[k] ** 2 - kx / m) < 1e-9 * kx / m:
            assert abs(phi[iy]) < 1e-12 and abs(phi[ir]) < 1e-12
            assert abs(phi[ix]) == pytest.approx(1 / math.sqrt(m), rel=1e-12)  # mass-normalised
        else:
            assert abs(phi[ix]) < 1e-12
            ratio = (m * md.omega[k] ** 2 - S) / ((k2 - k1) * a)
            assert phi[ir] / phi[iy] == pytest.approx(ratio, rel=1e-9)
    np.testing.assert_allclose(md.shapes.T @ md.frozen.A @ md.shapes, np.eye(3), atol=1e-12)


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
    np.testing.assert_allclose(md.omega**2, sorted([c1 / m, c2 / m, c6 / J]), rtol=1e-12)
    k1 = int(np.argmin(np.abs(md.omega**2 - c1 / m)))
    u = md.point_shapes("puck")[:2, k1]
    e = np.array([math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))])
    # parallel to e: |u x e| = 0 to round-off of the eigenvector (~1e-15 / sqrt(m))
    assert abs(u[0] * e[1] - u[1] * e[0]) < 1e-12
    assert abs(u @ e) == pytest.approx(1 / math.sqrt(m), rel=1e-12)


def test_modal_damping_ratio_of_proportional_damping():
    """Dampers d = alpha_k c on every spring make L = beta K: zeta = beta w / 2."""
    m, J, a, k1, k2, kx, beta = 120.0, 9.0, 0.4, 2.0e6, 5.0e6, 3.0e6, 2.0e-4
    text = BLOCK.format(m=m, J=J, a=a, ma=-a, k1=k1, k2=k2, kx=kx)
    text = text.replace(f"c2 = {k1}\n", f"c2 = {k1}\nd2 = {beta * k1}\n")
    text = text.replace(f"c2 = {k2}\n", f"c2 = {k2}\nd2 = {beta * k2}\n")
    text = text.replace(f"c1 = {kx}\n", f"c1 = {kx}\nd1 = {beta * kx}\n")
    md = cl.modes(cl.assemble(cl.loads_model(text)))
    np.testing.assert_allclose(md.damping_ratio, beta * md.omega / 2, rtol=1e-12)


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
    lam = scipy.linalg.eigh(K[np.ix_(keep, keep)], M[np.ix_(keep, keep)], eigvals_only=True)
    # the same LAPACK problem; file round trips (repr, Matrix Market text with
    # 16+ digits) keep the matrices to ~1e-16: 1e-12 relative
    np.testing.assert_allclose(md.omega, np.sqrt(lam), rtol=1e-12)
    np.testing.assert_allclose(md.shapes.T @ M[np.ix_(keep, keep)] @ md.shapes, np.eye(keep.size), atol=1e-12)
    return md


def test_matrix_model_inline():
    M, Lm, K = _matrices()
    names = ", ".join(f'"{c}"' for c in COORDS)
    text = f"[matrices]\ncoordinates = [{names}]\nM = {_rows(M)}\nL = {_rows(Lm)}\nK = {_rows(K)}\n"
    md = _check_modes(cl.loads_model(text), M, K)
    # damping ratio phi^T L phi / (2 w) with L = 1e-4 K + 0.5 M: 1e-4 w/2 + 0.5/(2 w)
    np.testing.assert_allclose(md.damping_ratio, 1e-4 * md.omega / 2 + 0.5 / (2 * md.omega), rtol=1e-10)
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
    assert str(p) in msg and "M: must be 5x5" in msg and "(5, 4)" in msg


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
