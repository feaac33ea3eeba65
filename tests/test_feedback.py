"""The cutting process as feedback in the closed loop (chatterlab.process._loop) against the paper.

Oracles: Eqs. 3.7-3.9 with the Table 3 coefficients ("grasso" CE of the
traverse shaper), the definition D(s) = -(b/b_ref) J^T Dl(s) J of Eq. 2.23
with J built here from the point maps, the regenerative preset
D_P = K_f b f n^T, D_O = -D_P, and the process kinematics (shaping:
T = L/v_w + L/v_l with the stroke L = run_in + cut + coast; turning:
T = 60/n).

The matrices are products of the file's numbers with b/b_ref and with the
point maps, so the tolerances are a few ulps (1e-15 relative for a scale
factor, 1e-12 of the largest entry where J^T (.) J sums over 36
coordinates).
"""

from __future__ import annotations

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.process import ClosedLoop, closed_loop, delay_for

# Table 3 (b = 2 mm)
K1, K2, K3, K4, K5, K6, K7, K8 = 625.4, 2097.0, 3.8e6, -703.0, 1.6e6, 1355.0, 3.8e6, 1.6e6
DV_PAPER = np.array([[K1, K4, 0.0], [K2, K6, 0.0], [0.0, 0.0, 0.0]])  # Eq. 3.7
DP_PAPER = np.array([[0.0, K3, 0.0], [0.0, K5, 0.0], [0.0, 0.0, 0.0]])  # Eq. 3.8
DO_PAPER = np.array([[0.0, -K7, 0.0], [0.0, -K8, 0.0], [0.0, 0.0, 0.0]])  # Eq. 3.9


@pytest.fixture(scope="module")
def shaper(shaper_path) -> cl.FrozenSystem:
    return cl.assemble(cl.load_model(shaper_path)).at()


def regenerative_text(fa: float = 0.0, na: float = 0.0, kf: float = 2.0e9, kv: float = 0.0) -> str:
    """A body free in x and y with a regenerative CE to the ground."""
    return f"""
[[body]]
id = "tool"
mass = 1.0
inertia = 1.0e-3
centre = [0.0, 0.0]
[[support]]
body = "tool"
fix = ["rz"]
[[spring]]
id = "holder"
a = "tool"
b = "ground"
c1 = 1.0e7
c2 = 2.0e7
d1 = 200.0
d2 = 300.0
[[coupling]]
id = "cut"
a = "tool"
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = {kf!r}
Kv = {kv!r}
force_angle_deg = {fa!r}
normal_angle_deg = {na!r}
[process]
kind = "turning"
rpm = 3000.0
"""


# ----------------------------------------------------------------------------- the shaper CE


def test_shaper_ce_matrices_are_eqs_3_7_to_3_9(shaper):
    """At b = 2 mm (= width_ref, factor exactly 1) the CE matrices are
    Eqs. 3.7-3.9 with Table 3, exactly."""
    (cm,) = shaper.couplings()
    assert cm.id == "cut" and cm.width_ref == 0.002
    np.testing.assert_array_equal(cm.DV, DV_PAPER)
    np.testing.assert_array_equal(cm.DP, DP_PAPER)
    np.testing.assert_array_equal(cm.DO, DO_PAPER)
    np.testing.assert_array_equal(cm.forces, [3260.0, 1240.0, 0.0])  # F_z, F_y (Eq. 3.10)
    fb = closed_loop(shaper, width=0.002, speed=0.5, terms="pdo")
    np.testing.assert_array_equal(fb.Dl_V, DV_PAPER)
    np.testing.assert_array_equal(fb.Dl_P, DP_PAPER)
    np.testing.assert_array_equal(fb.Dl_O, DO_PAPER)


@pytest.mark.parametrize("b", [0.5e-3, 1.0e-3, 3.0e-3, 7.5e-3])
def test_shaper_ce_scales_linearly_with_width(shaper, b):
    """Every matrix and the static force scale with b/b_ref (one product:
    1e-15 relative)."""
    f = b / 0.002
    fb = closed_loop(shaper, width=b, speed=0.5, terms="pdo")
    np.testing.assert_allclose(fb.Dl_V, f * DV_PAPER, rtol=1e-15, atol=0)
    np.testing.assert_allclose(fb.Dl_P, f * DP_PAPER, rtol=1e-15, atol=0)
    np.testing.assert_allclose(fb.Dl_O, f * DO_PAPER, rtol=1e-15, atol=0)
    ref = closed_loop(shaper, width=0.002, speed=0.5, terms="pdo")
    for X, Xr in ((fb.DP, ref.DP), (fb.DV, ref.DV), (fb.DO, ref.DO)):
        np.testing.assert_allclose(X, f * Xr, rtol=1e-14, atol=1e-14 * np.abs(Xr).max())
    np.testing.assert_allclose(fb.force, f * ref.force, rtol=1e-14, atol=1e-12)
    assert fb.width == b


def test_global_feedback_is_minus_Jt_Dl_J(shaper):
    """D(s) = D_P + s D_V + D_O e^{-sT} = -J^T Dl(s) J (Eq. 2.23) with J the
    relative displacement tool - rfe5 in CE axes (angle 0: global axes),
    built here from the point maps.  J^T X J sums over the CE coordinates:
    1e-12 of the largest entry (measured: identical, the same products)."""
    fb = closed_loop(shaper, width=0.002, speed=0.5, terms="pdo")
    J = shaper.point("tool") - shaper.point("rfe5")
    np.testing.assert_allclose(fb.J, J, rtol=0, atol=1e-14)
    scale = np.abs(fb.DP).max()
    np.testing.assert_allclose(fb.DP, -J.T @ DP_PAPER @ J, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(fb.DV, -J.T @ DV_PAPER @ J, rtol=0, atol=1e-12 * np.abs(fb.DV).max())
    np.testing.assert_allclose(fb.DO, -J.T @ DO_PAPER @ J, rtol=0, atol=1e-12 * scale)
    T = fb.delay
    for s in (0.0, 2j * np.pi * 76.3, 3.0 + 500j, np.array([1j, 10j, 100j])):
        Dl = (
            DP_PAPER
            + np.multiply.outer(s, DV_PAPER)
            + np.multiply.outer(np.exp(-np.asarray(s) * T), DO_PAPER)
        )
        ref = -np.swapaxes(J, 0, 1) @ Dl @ J
        np.testing.assert_allclose(fb(s), ref, rtol=0, atol=1e-12 * np.abs(ref).max())
        np.testing.assert_allclose(fb(s), -fb.J.T @ fb.Dl(s) @ fb.J, rtol=0, atol=1e-12 * np.abs(ref).max())
    # the static force: J^T P0 (generalised forces of F_z, F_y)
    np.testing.assert_allclose(fb.force, J.T @ np.array([3260.0, 1240.0, 0.0]), rtol=1e-14, atol=1e-9)


def test_delayed_matrix_is_rank_one_and_factored(shaper):
    """Only the chip thickness is regenerated: D_O has rank 1 and the factors
    satisfy U V^T = D_O, both to round-off bounds derived below."""
    fb = closed_loop(shaper, width=0.002, speed=0.5, terms="pdo")
    assert fb.U.shape == (shaper.n, 1) and fb.V.shape == (shaper.n, 1)
    eps, k = np.finfo(float).eps, fb.J.shape[0]
    # D_O = -J^T O J with O = Dl_O of rank one: the computed O (one rounding
    # per entry) and the two products (inner dimension k = 3 m) differ from an
    # exact rank-one matrix by |E| <= (2 k + 1) eps |J|^T |O| |J| (Higham,
    # Accuracy and Stability of Numerical Algorithms, sec. 3.5), so by Weyl
    # sigma_2 <= ||E||_2, plus the SVD's own n eps sigma_1.  Measured 0.19 eps
    # ||S||_2 (the former bound, 1e-12 sigma_1, was 4500 eps).
    S = np.abs(fb.J).T @ np.abs(fb.Dl_O) @ np.abs(fb.J)
    sv = np.linalg.svd(fb.DO, compute_uv=False)
    assert sv[1] <= (2 * k + 1) * eps * np.linalg.norm(S, 2) + shaper.n * eps * sv[0]
    # U V^T = J^T (u s v^T) J against J^T O J: the same bound on each entry,
    # plus the SVD of the 3m x 3m O (k eps ||O||) carried through |J|^T |J|
    # (measured 0.017 eps max S)
    JJ = np.abs(fb.J).T @ np.abs(fb.J)
    atol = (2 * k + 1) * eps * S + k * eps * np.linalg.norm(fb.Dl_O, 2) * JJ
    assert np.all(np.abs(fb.U @ fb.V.T - fb.DO) <= atol)


@pytest.mark.parametrize(
    "terms, on",
    [("none", ""), ("pd", "PV"), ("pdo", "PVO"), ("o", "O")],
)
def test_terms_switch_the_paper_cases(shaper, terms, on):
    """Cases (a) none, (b) pd, (c) pdo, and delayed-only: the switched-off
    matrices are zero, the others as in case (c)."""
    full = closed_loop(shaper, width=0.002, speed=0.5, terms="pdo")
    fb = closed_loop(shaper, width=0.002, speed=0.5, terms=terms)
    for key, X, Xf in (("P", fb.DP, full.DP), ("V", fb.DV, full.DV), ("O", fb.DO, full.DO)):
        if key in on:
            np.testing.assert_array_equal(X, Xf)
        else:
            assert not np.any(X)
    assert fb.is_zero == (terms == "none")
    assert fb.terms == terms
    # the delay is only carried when the delayed term is on
    assert (fb.delay is not None) == ("O" in on)
    assert fb.U.shape[1] == (1 if "O" in on else 0)


# ----------------------------------------------------------------------------- regenerative preset


@pytest.mark.parametrize("fa, na", [(0.0, 0.0), (70.0, 30.0), (-25.0, 110.0), (200.0, -45.0)])
def test_regenerative_preset(fa, na):
    """D_P = K_f b f n^T, D_O = -D_P, D_V = K_v b f n^T with
    f = (cos a_f, sin a_f, 0), n = (cos a_n, sin a_n, 0): K_f and K_v are per
    unit width, so the result does not depend on width_ref (1e-14)."""
    kf, kv, b = 2.0e9, 3.0e5, 1.3e-3
    fz = cl.assemble(cl.loads_model(regenerative_text(fa, na, kf, kv))).at()
    fb = closed_loop(fz, width=b, delay=0.02, terms="pdo")
    f = np.array([np.cos(np.radians(fa)), np.sin(np.radians(fa)), 0.0])
    n = np.array([np.cos(np.radians(na)), np.sin(np.radians(na)), 0.0])
    ref = kf * b * np.outer(f, n)
    atol = 1e-14 * kf * b
    np.testing.assert_allclose(fb.Dl_P, ref, rtol=0, atol=atol)
    np.testing.assert_allclose(fb.Dl_O, -ref, rtol=0, atol=atol)
    np.testing.assert_allclose(fb.Dl_V, kv * b * np.outer(f, n), rtol=0, atol=1e-14 * kv * b)
    np.testing.assert_array_equal(fb.DO, -fb.DP)
    # the tool (point a) on the ground (b): J is the tool's (x, y) map
    np.testing.assert_allclose(fb.DP, -ref[:2, :2], rtol=0, atol=atol)


def test_regenerative_sdof_equation_of_motion():
    """With f = n = x the closed loop is m x'' + c x' + k x = -K_f b (x - x(t-T)):
    Delta(s) = s^2 A + s(B - D_V) + C - D_P - D_O e^{-sT} must be
    m s^2 + c s + k + K_f b (1 - e^{-sT}), i.e. D_P = -K_f b, D_O = +K_f b
    on tool.x and nothing else."""
    fz = cl.assemble(cl.loads_model(regenerative_text(0.0, 0.0))).at()
    b = 0.4e-3
    fb = closed_loop(fz, width=b, delay=0.02)
    kfb = 2.0e9 * b
    ix = fz.names.index("tool.x")
    assert fb.DP[ix, ix] == pytest.approx(-kfb, rel=1e-15)
    assert fb.DO[ix, ix] == pytest.approx(kfb, rel=1e-15)
    assert np.count_nonzero(fb.DP) == 1


# ----------------------------------------------------------------------------- speed -> delay


def test_shaping_delay_is_one_stroke_cycle(shaper):
    """T = L/v_w + L/v_l with L = run_in + cut + coast = 0.6 m, v_l = 2 m/s:
    the paper's operating point v_w = 0.5 m/s gives 1.2 + 0.3 = 1.5 s."""
    proc = shaper.model.process
    L = proc.run_in + proc.cut + proc.coast
    assert L == pytest.approx(0.6, rel=1e-15)
    assert closed_loop(shaper, width=0.002, speed=0.5).delay == pytest.approx(1.5, rel=1e-15)
    assert delay_for(proc, speed=0.5) == pytest.approx(1.5, rel=1e-15)
    for v in (0.1, 0.25, 1.0, 3.0):
        assert delay_for(proc, speed=v) == pytest.approx(L / v + L / 2.0, rel=1e-15)
        assert proc.speed_for_delay(delay_for(proc, speed=v)) == pytest.approx(v, rel=1e-14)
    # the default speed is the file's (0.5 m/s), an explicit delay wins
    assert delay_for(proc) == pytest.approx(1.5, rel=1e-15)
    assert closed_loop(shaper, width=0.002, delay=0.7).delay == 0.7
    assert proc.min_delay == pytest.approx(0.3, rel=1e-15)


@pytest.mark.parametrize("rpm", [60.0, 1000.0, 3000.0, 12345.0])
def test_turning_delay_is_one_revolution(rpm):
    fz = cl.assemble(cl.loads_model(regenerative_text())).at()
    assert closed_loop(fz, width=1e-3, speed=rpm).delay == pytest.approx(60.0 / rpm, rel=1e-15)
    assert closed_loop(fz, width=1e-3).delay == pytest.approx(0.02, rel=1e-15)  # the file's 3000 rpm


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("width", [0.0, -1e-3, float("nan"), float("inf"), "2", True])
def test_bad_width(shaper, width):
    with pytest.raises(cl.InputError, match="width"):
        closed_loop(shaper, width=width, speed=0.5)


@pytest.mark.parametrize(
    "kw", [{"delay": 0.0}, {"delay": -1.0}, {"delay": float("nan")}, {"speed": 0.0}, {"speed": -0.5}]
)
def test_bad_delay_or_speed(shaper, kw):
    with pytest.raises(cl.InputError, match="delay|speed"):
        closed_loop(shaper, width=0.002, **kw)


def test_other_bad_arguments(shaper):
    with pytest.raises(cl.InputError, match="either speed or delay"):
        closed_loop(shaper, width=0.002, speed=0.5, delay=1.5)
    with pytest.raises(cl.InputError, match="terms"):
        closed_loop(shaper, width=0.002, speed=0.5, terms="pid")
    with pytest.raises(cl.InputError, match="unknown coupling 'chip'"):
        closed_loop(shaper, width=0.002, speed=0.5, couplings=["chip"])


def test_model_without_coupling_or_process():
    """No [[coupling]]: no feedback at all.  No [process]: a speed cannot be
    turned into a delay, and the delayed term needs one."""
    text = regenerative_text()
    no_coupling = text.split("[[coupling]]")[0] + '[process]\nkind = "turning"\nrpm = 3000.0\n'
    fz = cl.assemble(cl.loads_model(no_coupling)).at()
    with pytest.raises(cl.InputError, match=r"no \[\[coupling\]\]"):
        closed_loop(fz, width=1e-3, delay=0.01)
    no_process = text.split("[process]")[0]
    fz = cl.assemble(cl.loads_model(no_process)).at()
    with pytest.raises(cl.InputError, match=r"no \[process\]"):
        closed_loop(fz, width=1e-3, speed=3000.0)
    with pytest.raises(cl.InputError, match="needs a delay"):
        closed_loop(fz, width=1e-3)
    # without the delayed term no delay is needed
    fb = closed_loop(fz, width=1e-3, terms="pd")
    assert isinstance(fb, ClosedLoop) and fb.delay is None
