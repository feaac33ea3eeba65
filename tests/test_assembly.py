"""Assembly: W(s) of Eq. 2.6 against direct substitution of the element
kinematics, its s-derivatives against finite differences, the reduced
A*, B*, C* of Eqs. 2.16-2.18 against T^T X T built independently, and the
symmetry and spring stiffness of the assembled matrices.

The independent construction (``direct_map``) uses only the model's items and
the element functions: a dependent node of an attachment moves with its body
through a rigid arm, and a contact point moves like the material point of the
beam under it (``beam_point_matrix``), at the along-track position of the
followed body's centre.  It never calls W(s) or the constraint rows.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import chatterlab as cl
from chatterlab.model._items import DIRECTIONS, GROUND
from chatterlab.structure._elements import beam_point_matrix, rigid_point_matrix, rotation3

EPS = np.finfo(float).eps


# --------------------------------------------------------------------------- the independent map


def _xy(model: cl.Model, item: str) -> np.ndarray:
    return np.array(model.item(item).xy if hasattr(model.item(item), "xy") else model.item(item).centre)


def _track_point(model: cl.Model, contact, s: float):
    """(beam, element node ids, xy_i, xy_j, xi, rate) under a contact at s,
    computed from node positions and the [movable] table only."""
    mv = model.movable
    body = model.item(contact.follows)
    centre = np.array(body.centre) + (s - mv.position) * np.array(mv.direction)
    beams = [model.item(b) for b in contact.beams]
    p0 = _xy(model, beams[0].nodes[0])
    e = _xy(model, beams[0].nodes[1]) - p0
    e = e / np.linalg.norm(e)
    x = float((centre - p0) @ e) + contact.shift
    rate = float(np.array(mv.direction) @ e)
    lengths = [float(np.linalg.norm(_xy(model, b.nodes[1]) - _xy(model, b.nodes[0]))) for b in beams]
    if contact.outside == "clamp" and not 0.0 <= x <= sum(lengths):
        x, rate = min(max(x, 0.0), sum(lengths)), 0.0
    start = 0.0
    for k, (b, Lb) in enumerate(zip(beams, lengths, strict=True)):
        if x <= start + Lb or k == len(beams) - 1:
            d = x - start
            h = Lb / b.elements
            j = min(int(d / h), b.elements - 1)
            ids = [b.nodes[0]] + [f"{b.id}#{m}" for m in range(1, b.elements)] + [b.nodes[1]]
            a = _xy(model, b.nodes[0])
            return b, (ids[j], ids[j + 1]), a + j * h * e, a + (j + 1) * h * e, (d - j * h) / h, rate
        start += Lb
    raise AssertionError("off the track")  # pragma: no cover


def direct_map(sy: cl.System, s: float | None, order: int = 0) -> np.ndarray:
    """T (n, n_i) with q = T q_i (order 0), or d^k T / ds^k (order k = 1, 2),
    by direct substitution of the element kinematics."""
    model = sy.model
    idx = sy.index
    ni = len(sy.i)
    col = {int(k): c for c, k in enumerate(sy.i)}
    rows0: dict[str, np.ndarray] = {}  # coordinate triples of items, order 0

    def triple(item: str) -> np.ndarray:
        if item == GROUND:
            return np.zeros((3, ni))
        if item in rows0:
            return rows0[item]
        out = np.zeros((3, ni))
        for r, dname in enumerate(DIRECTIONS):
            k = idx[f"{item}.{dname}"]
            if k in col:
                out[r, col[k]] = 1.0
        return out

    for att in model.attachments:
        body_xy = np.zeros(2) if att.body == GROUND else np.array(model.item(att.body).centre)
        rows0[att.node] = rigid_point_matrix(_xy(model, att.node) - body_xy) @ triple(att.body)

    s_ = model.movable.position if s is None and model.movable else s
    T = np.zeros((sy.n, ni))
    for c in model.contacts:
        beam, (na, nb), xy_i, xy_j, xi, rate = _track_point(model, c, s_)
        sec = beam.section
        P = beam_point_matrix(
            xy_i, xy_j, xi, c.offset, E=sec.E, G=sec.G, A=sec.A, I=sec.I, kappa=sec.kappa, order=order
        )[0]
        rc = (rate**order) * P @ np.vstack([triple(na), triple(nb)])
        if order == 0:
            rows0[c.id] = rc
        else:
            T[[idx[f"{c.id}.{d}"] for d in DIRECTIONS], :] = rc
    if order:
        return T
    for item in {nm.rpartition(".")[0] for nm in sy.names} - {GROUND}:
        T[[idx[f"{item}.{d}"] for d in DIRECTIONS], :] = triple(item)
    return T


@pytest.fixture(scope="module")
def shaper(shaper_path) -> cl.System:
    return cl.assemble(cl.load_model(shaper_path))


# positions (m) of the slide: rfe6 on shear-1 (0.6, 0.65), exactly on the
# joint n2 (0.75), on shear-2 (0.85, 1.1); rfe5 waiting clamped at the
# workpiece end (0.57) and running along it (0.6 .. 1.1)
POSITIONS = [0.57, 0.6, 0.65, 0.75, 0.85, 1.1]


# --------------------------------------------------------------------------- W(s)


def test_shaper_dependent_coordinates_are_the_contacts_and_clamped_nodes(shaper):
    assert set(shaper.names_d) == {f"{i}.{d}" for i in ("rfe5", "rfe6", "n1", "n8") for d in DIRECTIONS}
    assert set(shaper.names_g) == {f"ground.{d}" for d in DIRECTIONS}


@pytest.mark.parametrize("s", POSITIONS)
def test_W_equals_direct_substitution(shaper, s):
    """q_d = W(s) q_i by Eq. 2.6 equals the contact points' and the clamped
    nodes' motion computed directly, for random q_i."""
    rng = np.random.default_rng(20240601)
    T = direct_map(shaper, s)
    W = shaper.W(s)
    np.testing.assert_allclose(T[shaper.i], np.eye(len(shaper.i)), atol=0)  # sanity of the map
    for _ in range(5):
        qi = rng.standard_normal(len(shaper.i))
        qd_direct = T[shaper.d] @ qi
        # W comes from a normal-equation solve with W_d^T W_d built from unit
        # and element-map blocks (condition ~ 10); the error is round-off,
        # ~1e-15 of |q|, bounded here by 1e-12.
        np.testing.assert_allclose(W @ qi, qd_direct, atol=1e-12 * np.abs(qi).max() * 10)


@settings(max_examples=60, deadline=None)
@given(s=st.floats(0.55, 1.15))
def test_W_equals_direct_substitution_anywhere_in_the_range(shaper, s):
    """Property form over the whole movable range (run-in, both shear beams,
    coasting): W(s) = direct map, to round-off (see above)."""
    T = direct_map(shaper, s)[shaper.d]
    np.testing.assert_allclose(shaper.W(s), T, atol=1e-12 * max(1.0, np.abs(T).max()))


def test_W_on_the_track_joint_is_continuous(shaper):
    """At the joint n2 (s = 0.75) the contact rfe6 passes from shear-1 to
    shear-2; W is continuous there (both beams give node n2's motion carried
    by the same rigid offset), while W' jumps (different elements)."""
    d = 1e-7
    Wm, W0, Wp = shaper.W(0.75 - d), shaper.W(0.75), shaper.W(0.75 + d)
    scale = np.abs(shaper.W(0.75, 1)).max()
    # a jump would be O(1); a continuous W changes by |W'| d ~ 1e-6 here
    assert np.abs(Wp - Wm).max() <= 2 * d * scale
    assert np.abs(W0 - Wm).max() <= 2 * d * scale
    W1m, W1p = shaper.W(0.75 - 1e-3, 1), shaper.W(0.75 + 1e-3, 1)
    assert np.abs(W1p - W1m).max() > 1e-3 * scale  # W' does jump: the test above is not vacuous


@pytest.mark.parametrize("s", [0.6, 0.65, 0.85, 1.05])
def test_W_derivatives_equal_direct_substitution(shaper, s):
    """W'(s), W''(s) equal d/ds and d^2/ds^2 of the direct map, built from
    beam_point_matrix(order=1, 2) times (ds_track/ds)^k."""
    d = shaper.d
    for order in (1, 2):
        Wk = shaper.W(s, order)
        Tk = direct_map(shaper, s, order)[d]
        # both are products of O(1..100) shape-function values: round-off
        np.testing.assert_allclose(Wk, Tk, atol=1e-11 * max(1.0, np.abs(Tk).max()))


@pytest.mark.parametrize("s", [0.65, 0.85])
def test_W_derivatives_match_central_differences(shaper, s):
    """Inside one element W(s) is a cubic in s (the beam's shape functions).
    So the central difference D_h = (W(s+h) - W(s-h)) / 2h = W' + h^2 W'''/6
    exactly: its error is O(h^2) with ratio exactly 4 between h and h/2, and
    the Richardson value (4 D_{h/2} - D_h)/3 is W' to round-off
    (eps |W| / h ~ 1e-12).  The second difference is exact for a cubic, so
    it equals W'' to round-off (eps |W| / h^2 ~ 1e-11 for h = 1e-2 m).
    Steps stay inside the elements: the nearest element end is >= 0.05 m away."""
    h = 2e-3
    W0, W1, W2 = shaper.W(s), shaper.W(s, 1), shaper.W(s, 2)

    def D(hh):
        return (shaper.W(s + hh) - shaper.W(s - hh)) / (2 * hh)

    e1, e2 = np.abs(D(h) - W1).max(), np.abs(D(h / 2) - W1).max()
    assert e1 > 1e-10 * np.abs(W1).max()  # truncation error well above round-off
    assert e1 / e2 == pytest.approx(4.0, rel=1e-3)  # O(h^2): ratio 4 (round-off ~1e-8 relative)
    rich = (4 * D(h / 2) - D(h)) / 3
    np.testing.assert_allclose(rich, W1, atol=1e-9 * np.abs(W1).max())
    hh = 1e-2
    D2 = (shaper.W(s + hh) - 2 * W0 + shaper.W(s - hh)) / hh**2
    np.testing.assert_allclose(D2, W2, atol=1e-8 * np.abs(W2).max())


def test_clamped_contact_waits_at_the_track_end(shaper):
    """rfe5 (outside = "clamp") at s = 0.57 is 0.03 m before the workpiece:
    it sits at the workpiece's first node (xi = 0) and does not move with s."""
    rows = [shaper.names_d.index(f"rfe5.{d}") for d in DIRECTIONS]
    assert np.all(shaper.W(0.57, 1)[rows] == 0.0)
    assert np.all(shaper.W(0.57, 2)[rows] == 0.0)
    np.testing.assert_allclose(shaper.W(0.57)[rows], shaper.W(0.59)[rows], atol=1e-15)
    np.testing.assert_allclose(shaper.W(0.57)[rows], shaper.W(0.60)[rows], atol=1e-13)


# a beam track subdivided into 3 elements, clamped at its first node; a
# carriage on springs moves above it and a contact follows it
SUBDIVIDED = """
[movable]
bodies = ["carriage"]
position = 0.5
range = [0.05, 1.2]

[[body]]
id = "carriage"
mass = 20.0
inertia = 0.3
centre = [0.5, 0.2]

[[node]]
id = "p"
at = [0.0, 0.0]
[[node]]
id = "q"
at = [1.2, 0.0]

[[beam]]
id = "rail"
nodes = ["p", "q"]
E = 2.1e11
nu = 0.3
rho = 7850.0
A = 0.01
I = 8.3333e-6
elements = 3

[[support]]
node = "p"

[[contact]]
id = "touch"
beams = ["rail"]
follows = "carriage"
offset = 0.05

[[spring]]
id = "carriage-rail"
a = { body = "carriage", offset = [0.0, -0.15] }
b = "touch"
c1 = 1.0e7
c2 = 2.0e7
c6 = 1.0e5

[[spring]]
id = "carriage-ground"
a = "carriage"
b = "ground"
c1 = 1.0e6
"""


@pytest.mark.parametrize("s", [0.1, 0.35, 0.5, 0.95, 1.15])
def test_W_on_a_subdivided_beam(s):
    """The contact runs over sub-elements 1, 2, 3 of the rail (0.4 m each);
    the first one's left node is supported (given), the others carry the
    internal nodes rail#1, rail#2."""
    sy = cl.assemble(cl.loads_model(SUBDIVIDED))
    assert {"rail#1.y", "rail#2.rz"} <= set(sy.names_i)
    for order in (0, 1, 2):
        T = direct_map(sy, s, order)[sy.d]
        np.testing.assert_allclose(sy.W(s, order), T, atol=1e-12 * max(1.0, np.abs(T).max()))
    h = 1e-3  # >= 0.05 m from the element ends at these s
    D = (sy.W(s + h) - sy.W(s - h)) / (2 * h)
    W1 = sy.W(s, 1)
    # truncation h^2/6 |W'''| with |W'''| <= 12 (1/h_e^3)(1 + offset...) ~ 2e2: < 1e-4 absolute
    np.testing.assert_allclose(D, W1, atol=1e-4)


# --------------------------------------------------------------------------- reduced matrices


@pytest.mark.parametrize("s", [0.65, 0.85])
def test_reduced_matrices_equal_projection(shaper, s):
    """A* = T^T M T, B* = T^T L T, C* = T^T K T (Eqs. 2.16-2.18 at rest)
    with T the direct map; given coordinates are zero."""
    T = direct_map(shaper, s)
    A, B, C = shaper.reduce(s)
    for X, Xs in ((shaper.M, A), (shaper.L, B), (shaper.K, C)):
        ref = T.T @ X @ T
        # sums of products of O(1) maps with the matrix: round-off ~1e-15 of |X|
        np.testing.assert_allclose(Xs, ref, atol=1e-12 * np.abs(X).max())
    fz = shaper.at(s)
    np.testing.assert_array_equal(fz.A, A)
    np.testing.assert_array_equal(fz.C, C)


def _check_moving_terms(sy: cl.System, s: float) -> tuple[np.ndarray, np.ndarray]:
    """With q = T(s) q_i and s moving at velocity v, acceleration a:
    q' = T q_i' + T' v q_i, q'' = T q_i'' + 2 T' v q_i' + (T'' v^2 + T' a) q_i,
    so projecting M q'' + L q' + K q on T:
        B*(v) - B*(0) = 2 T^T M T' v = 2 (M_id + W^T M_dd) W' v,
        C*(v, a) - C*(0) = T^T L T' v + T^T M (T'' v^2 + T' a)
    (Eqs. 2.17-2.18, with T', T'' from the direct map).  Returns (dB, dC)."""
    T, T1, T2 = (direct_map(sy, s, k) for k in (0, 1, 2))
    M, L = sy.M, sy.L
    v, a = -0.5, 3.0
    A0, B0, C0 = sy.reduce(s)
    A1, B1, C1 = sy.reduce(s, velocity=v, acceleration=a)
    np.testing.assert_array_equal(A1, A0)  # the inertia does not depend on the motion
    dB = 2 * T.T @ M @ T1 * v
    dC = T.T @ L @ T1 * v + T.T @ M @ (T2 * v**2 + T1 * a)
    # round-off on top of the B*(0), C*(0) magnitudes (relative 1e-15; 1e-11 with margin)
    np.testing.assert_allclose(B1 - B0, dB, atol=1e-11 * np.abs(B0).max())
    np.testing.assert_allclose(C1 - C0, dC, atol=1e-11 * np.abs(C0).max())
    # the same in the paper's partitioned notation
    i, d = sy.i, sy.d
    W, W1 = sy.W(s), sy.W(s, 1)
    paper = 2 * (M[np.ix_(i, d)] + W.T @ M[np.ix_(d, d)]) @ W1 * v
    np.testing.assert_allclose(B1 - B0, paper, atol=1e-11 * np.abs(B0).max())
    # several positions at once give the same as one by one
    _, Bs, Cs = sy.reduce(np.array([s, s + 0.01]), velocity=v, acceleration=a)
    np.testing.assert_allclose(Bs[0], B1, rtol=0, atol=1e-12 * np.abs(B1).max())
    np.testing.assert_allclose(Cs[0], C1, rtol=0, atol=1e-12 * np.abs(C1).max())
    return dB, dC


@pytest.mark.parametrize("s", [0.65, 0.85])
def test_moving_slide_terms_vanish_for_the_shaper(shaper, s):
    """Only the contact coordinates have W' != 0, and the shaper's contacts
    (RFE 5, 6) are massless and carry no damper: every extra term of
    Eqs. 2.17-2.18 is then exactly zero, B*(v) = B*(0), C*(v, a) = C*(0)."""
    dB, dC = _check_moving_terms(shaper, s)
    assert np.abs(dB).max() == 0.0 and np.abs(dC).max() == 0.0


@pytest.mark.parametrize("s", [0.35, 0.95])
def test_moving_slide_terms_with_mass_and_damping_on_the_contact(s):
    """Non-vacuous check of Eqs. 2.17-2.18: the subdivided-rail model with a
    damper on the contact's spring (L_id W' v != 0) and, put into the
    assembled M by hand, a mass on the contact's coordinates (M_dd W' != 0)."""
    from dataclasses import replace

    text = SUBDIVIDED.replace("c6 = 1.0e5\n", "c6 = 1.0e5\nd1 = 400.0\nd2 = 900.0\nd6 = 5.0\n")
    sy = cl.assemble(cl.loads_model(text))
    M = np.array(sy.M)
    k = [sy.index[f"touch.{d}"] for d in DIRECTIONS]
    M[k, k] += (2.0, 2.0, 0.01)
    sy = replace(sy, M=M)
    dB, dC = _check_moving_terms(sy, s)
    assert np.abs(dB).max() > 1e-3 * np.abs(sy.reduce(s)[1]).max()  # the terms are really there
    assert np.abs(dC).max() > 0.0


def test_assembled_matrices_are_symmetric(shaper):
    for X in (shaper.M, shaper.L, shaper.K):
        np.testing.assert_allclose(X, X.T, atol=1e-14 * np.abs(X).max())
    for s in (0.6, 0.85, 1.1):
        A, B, C = shaper.reduce(s)
        for X in (A, B, C):
            # W^T X W products of symmetric X: symmetric to round-off
            np.testing.assert_allclose(X, X.T, atol=1e-13 * np.abs(X).max())
        # positive definite means above round-off: eigvalsh's eigenvalues are
        # within n eps max|lambda| (Weyl; here 8e-15 relative), so a smaller
        # one could be a zero.  Measured: C*'s smallest is 2.7e-5 of its largest.
        m = np.linalg.eigvalsh(A)
        assert m.min() > A.shape[0] * EPS * m.max()  # every coordinate carries mass
        w = np.linalg.eigvalsh(C)
        assert w.min() > C.shape[0] * EPS * w.max()  # held by the foundation


# --------------------------------------------------------------------------- springs


def _body_on_spring(spring: str) -> cl.System:
    text = f'[[body]]\nid = "puck"\nmass = 4.0\ninertia = 0.5\ncentre = [0.3, -0.2]\n\n[[spring]]\nid = "s"\n{spring}'
    return cl.assemble(cl.loads_model(text))


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, -75.0, 90.0])
def test_rotated_spring_stiffness(angle_deg):
    """A spring at the centre with axes rotated by alpha: K = R diag(c1, c2) R^T
    for the translations (R the rotation by alpha), c6 for the rotation."""
    c1, c2, c6 = 3.0e6, 1.0e5, 2.0e3
    sy = _body_on_spring(
        f'a = "puck"\nb = "ground"\nc1 = {c1}\nc2 = {c2}\nc6 = {c6}\nangle_deg = {angle_deg}\n'
    )
    R = rotation3(np.radians(angle_deg))
    ref = R @ np.diag([c1, c2, c6]) @ R.T
    k = [sy.index[f"puck.{d}"] for d in DIRECTIONS]
    # trigonometric round-off: 1e-15 of c1
    np.testing.assert_allclose(sy.K[np.ix_(k, k)], ref, atol=1e-12 * c1)
    e1 = np.array([np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))])
    np.testing.assert_allclose(sy.K[np.ix_(k[:2], k[:2])] @ e1, c1 * e1, atol=1e-12 * c1)


def test_offset_spring_couples_translation_and_rotation():
    """A horizontal spring c1 at arm (0, -h) below the centre: the point moves
    u = x + h theta (small rotation), so K = c1 [[1, h], [h, h^2]] on (x, rz)."""
    c1, h = 2.0e6, 0.25
    sy = _body_on_spring(f'a = {{ body = "puck", offset = [0.0, {-h}] }}\nb = "ground"\nc1 = {c1}\n')
    kx, ky, kr = (sy.index[f"puck.{d}"] for d in DIRECTIONS)
    K = sy.K
    np.testing.assert_allclose(K[np.ix_([kx, kr], [kx, kr])], c1 * np.array([[1, h], [h, h * h]]), rtol=1e-15)
    assert K[ky, ky] == 0.0 and K[kx, ky] == 0.0


def test_spring_damping_assembles_like_stiffness():
    sy = _body_on_spring(
        'a = "puck"\nb = "ground"\nc1 = 1.0e6\nd1 = 50.0\nd2 = 70.0\nd6 = 3.0\nangle_deg = 20.0\n'
    )
    k = [sy.index[f"puck.{d}"] for d in DIRECTIONS]
    R = rotation3(np.radians(20.0))
    np.testing.assert_allclose(sy.L[np.ix_(k, k)], R @ np.diag([50.0, 70.0, 3.0]) @ R.T, atol=1e-12 * 70)


def test_W_on_a_track_running_against_the_slide():
    """The same rail with its nodes listed from right to left: the contact's
    along-track coordinate now decreases as s grows (d distance/ds = -1), so
    W' changes sign relative to the track; the direct map and FD agree."""
    text = SUBDIVIDED.replace("at = [0.0, 0.0]", "at = [9.0, 9.0]").replace(
        "at = [1.2, 0.0]", "at = [0.0, 0.0]"
    )
    text = text.replace("at = [9.0, 9.0]", "at = [1.2, 0.0]").replace("offset = 0.05", "offset = -0.05")
    sy = cl.assemble(cl.loads_model(text))
    for s in (0.3, 0.95):
        for order in (0, 1, 2):
            T = direct_map(sy, s, order)[sy.d]
            np.testing.assert_allclose(sy.W(s, order), T, atol=1e-12 * max(1.0, np.abs(T).max()))
        h = 1e-3
        # truncation h^2/6 |W'''| < 1e-4 as in test_W_on_a_subdivided_beam
        np.testing.assert_allclose((sy.W(s + h) - sy.W(s - h)) / (2 * h), sy.W(s, 1), atol=1e-4)


# --------------------------------------------------------------------------- general constraints

GHOST = """
[[body]]
id = "block"
mass = 100.0
inertia = 2.0
centre = [0.0, 0.0]

[[body]]
id = "ghost"
mass = 0.0
inertia = 0.0
centre = [0.0, -0.5]

[[spring]]
id = "s"
a = "ghost"
b = "ground"
c1 = 1.0e6
c2 = 2.0e6
c6 = 3.0e4
d1 = 10.0

[[constraint]]
id = "arm"
dependent = ["ghost.x", "ghost.y", "ghost.rz"]
equations = [
    { "ghost.x" = 1.0, "block.x" = -1.0, "block.rz" = -0.5 },
    { "ghost.y" = 1.0, "block.y" = -1.0 },
    { "ghost.rz" = 1.0, "block.rz" = -1.0 },
]
"""

OFFSET = """
[[body]]
id = "block"
mass = 100.0
inertia = 2.0
centre = [0.0, 0.0]

[[spring]]
id = "s"
a = { body = "block", offset = [0.0, -0.5] }
b = "ground"
c1 = 1.0e6
c2 = 2.0e6
c6 = 3.0e4
d1 = 10.0
"""


def test_massless_body_on_a_constraint_equals_a_rigid_offset():
    """A massless body tied to the block by [[constraint]] equations of a rigid
    arm (u = x + 0.5 theta for the arm (0, -0.5), v = y, theta = theta) is
    the block's point at offset (0, -0.5): the reduced matrices coincide."""
    a = cl.assemble(cl.loads_model(GHOST)).at()
    b = cl.assemble(cl.loads_model(OFFSET)).at()
    assert a.names == b.names == ("block.x", "block.y", "block.rz")
    np.testing.assert_allclose(a.W, [[1, 0, 0.5], [0, 1, 0], [0, 0, 1]], atol=1e-15)
    for X, Y in ((a.A, b.A), (a.B, b.B), (a.C, b.C)):
        np.testing.assert_allclose(X, Y, rtol=1e-14, atol=1e-14 * np.abs(Y).max())


def test_redundant_but_consistent_constraint_is_accepted():
    """An extra equation that repeats another (scaled) changes nothing: Eq. 2.6
    is the least-squares solution, exact when the equations are consistent."""
    text = GHOST.replace(
        '    { "ghost.rz" = 1.0, "block.rz" = -1.0 },\n',
        '    { "ghost.rz" = 1.0, "block.rz" = -1.0 },\n    { "ghost.y" = 2.0, "block.y" = -2.0 },\n',
    )
    W = cl.assemble(cl.loads_model(text)).W()
    np.testing.assert_allclose(W, [[1, 0, 0.5], [0, 1, 0], [0, 0, 1]], atol=1e-14)


def test_body_angle_rotates_point_offsets():
    """A body at 90 degrees: the offset (0.5, 0) in body axes is (0, 0.5) in
    global axes, so a horizontal spring there couples x and rz by -0.5."""
    text = OFFSET.replace("centre = [0.0, 0.0]", "centre = [0.0, 0.0]\nangle_deg = 90.0")
    text = text.replace("offset = [0.0, -0.5]", "offset = [0.5, 0.0]").replace("c2 = 2.0e6\nc6 = 3.0e4\n", "")
    sy = cl.assemble(cl.loads_model(text))
    kx, kr = sy.index["block.x"], sy.index["block.rz"]
    # u = x - 0.5 theta at the global arm (0, 0.5): K = c1 [[1, -0.5], [-0.5, 0.25]]
    np.testing.assert_allclose(
        sy.K[np.ix_([kx, kr], [kx, kr])], 1e6 * np.array([[1, -0.5], [-0.5, 0.25]]), atol=1e-9
    )
