"""Frequency response functions (chatterlab.frequency._frf) against mathematics.

Oracles: the closed-form receptance of a single degree of freedom,
1/(k - m w^2 + j c w); the exact conversions mobility = j w receptance and
accelerance = -w^2 receptance; Maxwell-Betti reciprocity of a symmetric
structure; python-control evaluating an independent state-space / transfer
function model; Sylvester's determinant identity; and, for the modal route,
the direct solve (its exact counterpart).

Accuracy found when these tests were written (shaper = studies/traverse_shaper):

* SDOF, direct and modal: ~1e-16 relative;
* shaper reciprocity: 1.5e-13 of the largest entry at each frequency;
* shaper modal (all complex modes, the default since 0.2) vs direct, 1-300
  Hz: 5.5e-11 of each FRF's peak; against an extended-precision refined
  solve (benchmarks/bench_frf.py) the direct route is off by 7.5e-11 and
  the modal one by 4.6e-11;
* shaper modal truncated at 4 x 300 Hz + residual (``modes_above=4.0``,
  the default before 0.2): 5.2e-7; without the residual 3.1e-4;
* closed loop by Woodbury vs direct: 3e-7 (pd), 6e-8 (pdo) on the raw pencil,
  1.2e-11 and 1.8e-11 (all modes) on the balanced one;
* loop_determinant vs det(I - G D) on the full 36 x 36 matrices: 4e-13;
  modal (all modes) vs direct 1.2e-11.

Round-off tolerances on the shaper are derived, not guessed: a solve that is
exact for the data perturbed componentwise by eps (A, B, C and D(s) each
entry within a relative eps, which is also how they are stored) has
|dH| <= eps |rows| |Z^-1| (|s|^2|A| + |s||B| + |C| + |D|) |Z^-1 cols|
(Skeel's condition; :func:`round_off_bound`).  On the shaper this is
5.9e-10 of the peak open loop and 1.1e-10 closed loop (c), over 1-300 Hz;
the two routes compared are each within it, so they differ by at most
twice it.  The modal route's floor is set by the eigenvalues of the lightly
damped modes (an error d lambda shifts a peak by d lambda / |Re lambda|,
|Re lambda| = 0.098 rad/s for the first shaper mode, zeta = 2e-4); on the
raw pencil QZ lost 4e-8 rad/s (a 2.8e-7 floor), the balanced pencil of
complex_modes stays inside the bound above.  The tolerances that say "1e-6"
bound the truncation error of kept modes + residual, a deterministic
property of the model, not round-off.
"""

from __future__ import annotations

import control  # a dependency of chatterlab (pyproject): an import error fails, never skips
import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.frequency._frf import FRF, frequencies, frf, loop_determinant
from chatterlab.process import closed_loop

# ----------------------------------------------------------------------------- models

M, K, ZETA = 1.0, 1.0e7, 0.03
C = float(2 * ZETA * np.sqrt(K * M))  # viscous damping giving exactly zeta


def sdof_text(m: float = M, k: float = K, c: float = C) -> str:
    """The 1-DOF turning tool of docs/model-format.md (x free, regenerative
    coupling to the ground)."""
    return turning_text(mass=m, stiffness=k, damping=c, name="sdof")


def sdof_receptance(omega: np.ndarray, m: float = M, k: float = K, c: float = C) -> np.ndarray:
    return 1.0 / (k - m * omega**2 + 1j * c * omega)


@pytest.fixture(scope="module")
def sdof() -> cl.FrozenSystem:
    return cl.assemble(cl.loads_model(sdof_text())).at()


@pytest.fixture(scope="module")
def shaper(shaper_path) -> cl.FrozenSystem:
    return cl.assemble(cl.load_model(shaper_path)).at()


#: contact point, tool tip and two structural coordinates of the shaper
POINTS = ["rfe5.x", "rfe5.y", "tool.x", "tool.y", "slide.rz", "frame.x"]
CONTACT = ["rfe5.x", "rfe5.y", "tool.x", "tool.y"]


def peak_relative_error(a: np.ndarray, ref: np.ndarray) -> float:
    """max over (o, i) of max_w |a - ref| / max_w |ref|: the error relative
    to each FRF's own peak (a pointwise relative error is meaningless at an
    antiresonance, where |ref| -> 0)."""
    err = np.abs(a - ref).max(axis=-1)
    return float((err / np.abs(ref).max(axis=-1)).max())


def skeel(frozen, om: np.ndarray, rows: np.ndarray, fb=None) -> tuple[np.ndarray, np.ndarray]:
    """(H, dH), each (n_freq, n_rows, n_rows): H = R Z^-1 R^T and
    dH = eps |R| |Z^-1| |Z| |Z^-1 R^T|, the first-order error bound of a
    solve that is exact for data perturbed componentwise by a relative eps
    (Skeel's condition), Z = s^2 A + s B + C - D(s), |Z| = |s|^2|A| +
    |s||B| + |C| + |D(s)|."""
    s = 1j * om[:, None, None]
    Z = s**2 * frozen.A + s * frozen.B + frozen.C
    Za = np.abs(s) ** 2 * np.abs(frozen.A) + np.abs(s) * np.abs(frozen.B) + np.abs(frozen.C)
    if fb is not None:
        D = fb(1j * om)
        Z, Za = Z - D, Za + np.abs(D)
    Zi = np.linalg.inv(Z)
    X = Zi @ rows.T
    return rows @ X, np.finfo(float).eps * (np.abs(rows) @ np.abs(Zi) @ Za @ np.abs(X))


def round_off_bound(frozen, om: np.ndarray, points: list[str], fb=None) -> float:
    """The Skeel bound relative to each FRF's peak: max over (o, i) of
    max_w dH_oi / max_w |H_oi|."""
    H, dH = skeel(frozen, om, np.array([frozen.dof(p) for p in points]), fb)
    return float((dH.max(axis=0) / np.abs(H).max(axis=0)).max())


# ----------------------------------------------------------------------------- SDOF


def sdof_omega() -> np.ndarray:
    wn = np.sqrt(K / M)
    # 0, below, exactly at and above resonance, and far above
    return np.sort(np.concatenate([[0.0, wn], np.linspace(1.0, 5 * wn, 2001)]))


@pytest.mark.parametrize("method", ["direct", "modal"])
def test_sdof_receptance_closed_form(sdof, method):
    """H(jw) = 1/(k - m w^2 + j c w), direct and by complex modes.  The 1x1
    solve is exact to a few ulps (1e-14; measured 4e-16).  The modal sum of
    the two complex modes cancels partly (each term is ~w/w_d times the sum
    far above resonance, and the residues are ~1/zeta larger than the
    static value): 1e-11 (measured 5e-13)."""
    om = sdof_omega()
    h = frf(sdof, om, inputs="tip.x", outputs="tip.x", method=method)
    assert h.data.shape == (1, 1, om.size)
    rtol = 1e-14 if method == "direct" else 1e-11
    np.testing.assert_allclose(h.data[0, 0], sdof_receptance(om), rtol=rtol, atol=0)
    # the same through the named accessor and another name of the same point
    np.testing.assert_array_equal(h["tip.x", "tip.x"], h.data[0, 0])
    h2 = frf(sdof, om, inputs="tool.x", outputs="tool.x", method=method)
    np.testing.assert_allclose(h2.data, h.data, rtol=1e-14)


def test_sdof_peak_and_static_value(sdof):
    """Static compliance 1/k exactly, and |H| at w_n equal to 1/(c w_n)."""
    wn = np.sqrt(K / M)
    h = frf(sdof, np.array([0.0, wn]), inputs="tip.x", outputs="tip.x")
    assert h.data[0, 0, 0] == pytest.approx(1.0 / K, rel=1e-14)
    assert h.data[0, 0, 1] == pytest.approx(1.0 / (1j * C * wn), rel=1e-12)


def test_mobility_and_accelerance(sdof, shaper):
    """mobility = j w H, accelerance = -w^2 H (exact products: 1e-15), both
    from frf(kind=...) and from FRF.as_kind, and the round trip back."""
    om = sdof_omega()
    H = sdof_receptance(om)
    mob = frf(sdof, om, inputs="tip.x", outputs="tip.x", kind="mobility")
    acc = frf(sdof, om, inputs="tip.x", outputs="tip.x", kind="accelerance")
    np.testing.assert_allclose(mob.data[0, 0], 1j * om * H, rtol=1e-12, atol=0)
    np.testing.assert_allclose(acc.data[0, 0], -(om**2) * H, rtol=1e-12, atol=0)
    assert (mob.kind, mob.unit) == ("mobility", "m/(N s)")
    assert (acc.kind, acc.unit) == ("accelerance", "m/(N s^2)")
    # conversions between the three on a MIMO shaper FRF
    oms = frequencies(1.0, 300.0, 301)
    rec = frf(shaper, oms, inputs=CONTACT, outputs=CONTACT)
    np.testing.assert_allclose(rec.as_kind("mobility").data, 1j * oms * rec.data, rtol=1e-15)
    np.testing.assert_allclose(rec.as_kind("accelerance").data, -(oms**2) * rec.data, rtol=1e-15)
    back = rec.as_kind("accelerance").as_kind("mobility").as_kind("receptance")
    np.testing.assert_allclose(back.data, rec.data, rtol=1e-14)
    direct_acc = frf(shaper, oms, inputs=CONTACT, outputs=CONTACT, kind="accelerance")
    np.testing.assert_allclose(direct_acc.data, rec.as_kind("accelerance").data, rtol=1e-15)


# ----------------------------------------------------------------------------- shaper


def test_reciprocity_on_the_shaper(shaper):
    """A*, B*, C* of the frozen shaper are symmetric, so H_ij = H_ji
    (Maxwell-Betti) between any two points/directions.  Both entries come
    from one LU solve of a matrix with condition ~1e5: 1e-10 of the largest
    entry at each frequency (measured 1.5e-13)."""
    om = frequencies(1.0, 300.0, 1500)
    h = frf(shaper, om, inputs=POINTS, outputs=POINTS)
    H = h.data
    scale = np.abs(H).max(axis=(0, 1))
    asym = np.abs(H - H.transpose(1, 0, 2)) / scale
    assert asym.max() < 1e-10
    # and a one-input / one-output call gives the same entry
    one = frf(shaper, om, inputs="tool.x", outputs="rfe5.y")
    np.testing.assert_allclose(one.data[0, 0], h["rfe5.y", "tool.x"], rtol=1e-12)


def test_modal_all_modes_matches_direct_to_round_off(shaper):
    """The default modal route sums all 72 complex modes (no truncation), so
    it and the direct solve differ by round-off only: within twice the
    componentwise condition bound (round_off_bound: 7e-10 of the peak on
    this grid; measured 5.5e-11), and 1e4 times closer than the truncated
    route (4 x fmax + residual: 5.2e-7)."""
    om = frequencies(1.0, 300.0, 3000)
    direct = frf(shaper, om, inputs=CONTACT, outputs=CONTACT)
    modal = frf(shaper, om, inputs=CONTACT, outputs=CONTACT, method="modal")
    bound = round_off_bound(shaper, om, CONTACT)
    assert 1e-11 < bound < 1e-8  # the shaper's conditioning, as documented above
    assert peak_relative_error(modal.data, direct.data) < 2 * bound
    trunc = frf(shaper, om, inputs=CONTACT, outputs=CONTACT, method="modal", modes_above=4.0)
    assert peak_relative_error(trunc.data, direct.data) > 100 * bound
    for bad in (0.0, -1.0, float("nan"), True, "4"):
        with pytest.raises(cl.InputError, match="modes_above"):
            frf(shaper, om, inputs=CONTACT, outputs=CONTACT, method="modal", modes_above=bad)
    # a NumPy factor is a factor: the truncated route, as with a float
    np.testing.assert_array_equal(
        frf(shaper, om, inputs=CONTACT, outputs=CONTACT, method="modal", modes_above=np.float64(4.0)).data,
        trunc.data,
    )


def test_modal_with_residual_matches_direct_below_the_kept_modes(shaper):
    """Band 1-300 Hz; modes_above = 4 keeps the complex modes with
    |lambda| <= 4 x 300 Hz: 17 pairs, the highest at 1055 Hz, the first
    dropped at 1290 Hz, so the band ends at 0.28 of the highest kept mode
    and 0.23 of the lowest dropped one.  The residual (exact Taylor series
    of the dropped modes to s^2) leaves an O((w/|lambda|)^3) error:
    1e-6 of each FRF's peak (measured 5.2e-7, all of it truncation: the
    eigenvalue floor is 3.7e-11, module docstring).  Without the
    residual the error is set by the dropped modes' static flexibility:
    more than 100x larger (measured 3.1e-4)."""
    om = frequencies(1.0, 300.0, 3000)
    direct = frf(shaper, om, inputs=CONTACT, outputs=CONTACT)
    modal = frf(shaper, om, inputs=CONTACT, outputs=CONTACT, method="modal", modes_above=4.0)
    bare = frf(shaper, om, inputs=CONTACT, outputs=CONTACT, method="modal", modes_above=4.0, residual=False)
    e_res = peak_relative_error(modal.data, direct.data)
    e_bare = peak_relative_error(bare.data, direct.data)
    assert e_res < 1e-6
    assert e_bare > 100 * e_res
    assert e_bare > 1e-4
    # pointwise, relative to the largest entry of H at the same frequency
    # (this includes the low-level tail near 300 Hz): 1e-4 (measured 2.6e-5)
    # against 7e-2 without the residual
    scale = np.abs(direct.data).max(axis=(0, 1))
    assert (np.abs(modal.data - direct.data).max(axis=(0, 1)) / scale).max() < 1e-4
    assert (np.abs(bare.data - direct.data).max(axis=(0, 1)) / scale).max() > 1e-2
    assert modal.method == "modal" and direct.method == "direct"


@pytest.mark.parametrize("terms", ["pd", "pdo", "o"])
def test_closed_loop_modal_woodbury_matches_direct(shaper, terms):
    """Closed loop at b = 2 mm, v = 0.5 m/s: the modal route corrects the
    open-loop modal FRF through the Woodbury identity in the 3 CE
    coordinates; the direct route solves (s^2 A + s B + C - D(s)) x = f.
    With all modes (the default) only round-off remains: within twice the
    closed-loop condition bound (round_off_bound, about 1e-10 here;
    measured 1.2e-11 pd, 1.8e-11 pdo, 1.1e-11 o).  With modes up to
    8 x 300 Hz + residual the truncation adds to it (measured 1.7e-10,
    9.0e-9, 8.3e-10): 1e-6 of the peak, the bound of the open-loop
    truncation test below."""
    om = frequencies(1.0, 300.0, 2000)
    fb = closed_loop(shaper, width=0.002, speed=0.5, terms=terms)
    direct = frf(fb, om, inputs=CONTACT, outputs=CONTACT)
    every = frf(fb, om, inputs=CONTACT, outputs=CONTACT, method="modal")
    trunc = frf(fb, om, inputs=CONTACT, outputs=CONTACT, method="modal", modes_above=8.0)
    assert direct.closed_loop and direct.terms == terms and direct.width == 0.002
    assert peak_relative_error(every.data, direct.data) < 2 * round_off_bound(shaper, om, CONTACT, fb)
    assert peak_relative_error(trunc.data, direct.data) < 1e-6
    # the feedback changes the response (not a vacuous comparison)
    open_ = frf(shaper, om, inputs=CONTACT, outputs=CONTACT)
    assert peak_relative_error(direct.data, open_.data) > 0.1


def test_closed_loop_pd_equals_the_modified_structure(shaper):
    """Without the delay, closing the loop is the same as solving with
    B* - D_V and C* - D_P (Eq. 2.1): frf(closed loop pd) against an open-loop
    solve of that modified structure computed here.  Same arithmetic up to
    the order of the operations: 1e-10 of the peak (measured 1.5e-12)."""
    om = frequencies(1.0, 300.0, 600)
    fb = closed_loop(shaper, width=0.002, speed=0.5, terms="pd")
    h = frf(fb, om, inputs=CONTACT, outputs=CONTACT)
    rows = np.array([shaper.dof(p) for p in CONTACT])
    ref = np.empty_like(h.data)
    for k, w in enumerate(om):
        s = 1j * w
        Z = s * s * shaper.A + s * (shaper.B - fb.DV) + shaper.C - fb.DP
        ref[:, :, k] = rows @ np.linalg.solve(Z, rows.T)
    assert peak_relative_error(h.data, ref) < 1e-10


# ----------------------------------------------------------------------------- python-control


def test_to_control_gives_the_same_response(shaper):
    """FRF.to_control() is a control.FrequencyResponseData holding our data
    at our frequencies: evaluating it there returns the data bit for bit."""
    om = frequencies(1.0, 300.0, 200)
    h = frf(shaper, om, inputs=["rfe5.x", "tool.y"], outputs=CONTACT)
    frd = h.to_control()
    assert isinstance(frd, control.FrequencyResponseData)
    assert (frd.noutputs, frd.ninputs) == (4, 2)
    np.testing.assert_array_equal(frd.omega, om)
    np.testing.assert_array_equal(frd.eval(om), h.data)
    np.testing.assert_array_equal(frd.frequency_response(om).complex, h.data)
    # one point, as a complex scalar for a SISO response
    siso = frf(shaper, om, inputs="rfe5.y", outputs="rfe5.y")
    assert siso.to_control().eval(om[17]) == siso.data[0, 0, 17]


def test_python_control_sdof_transfer_function_matches(sdof):
    """control.tf([1], [m, c, k]) and the equivalent state space, evaluated
    at jw by python-control, against our receptance: both evaluate the same
    rational function, 1e-12 relative for the polynomial (measured 1e-16),
    1e-10 for the state space and for our modal route (measured 9e-15 and
    5e-13)."""
    om = sdof_omega()[1:]  # (python-control sorts the frequencies it is given)
    ours = frf(sdof, om, inputs="tip.x", outputs="tip.x").data[0, 0]
    tf = control.tf([1.0], [M, C, K])
    np.testing.assert_allclose(tf(1j * om), ours, rtol=1e-12)
    ss = control.ss([[0.0, 1.0], [-K / M, -C / M]], [[0.0], [1.0 / M]], [[1.0, 0.0]], [[0.0]])
    np.testing.assert_allclose(ss.frequency_response(om).complex, ours, rtol=1e-10)
    mod = frf(sdof, om, inputs="tip.x", outputs="tip.x", method="modal").data[0, 0]
    np.testing.assert_allclose(tf(1j * om), mod, rtol=1e-10)


def test_python_control_state_space_of_the_shaper_matches(shaper):
    """The shaper as a 72-state control.ss (x = [q, q'], A = [[0, I],
    [-A*^-1 C*, -A*^-1 B*]]) evaluated by python-control at jw, against our
    direct FRF: open loop and closed loop P+D (B* - D_V, C* - D_P).  Two
    different linear solves of systems with condition ~1e5 (first-order
    form ~1e7): 1e-8 of the peak (measured ~1e-11)."""
    om = frequencies(1.0, 300.0, 400)
    rows = np.array([shaper.dof(p) for p in CONTACT])
    n = shaper.n

    def state_space(B: np.ndarray, C: np.ndarray):
        Ainv = np.linalg.inv(shaper.A)
        a = np.block([[np.zeros((n, n)), np.eye(n)], [-Ainv @ C, -Ainv @ B]])
        b = np.vstack([np.zeros((n, len(CONTACT))), Ainv @ rows.T])
        c = np.hstack([rows, np.zeros((len(CONTACT), n))])
        return control.ss(a, b, c, np.zeros((len(CONTACT), len(CONTACT))))

    ours = frf(shaper, om, inputs=CONTACT, outputs=CONTACT)
    theirs = state_space(shaper.B, shaper.C).frequency_response(om).complex
    assert peak_relative_error(theirs, ours.data) < 1e-8
    fb = closed_loop(shaper, width=0.002, speed=0.5, terms="pd")
    ours_cl = frf(fb, om, inputs=CONTACT, outputs=CONTACT)
    theirs_cl = state_space(shaper.B - fb.DV, shaper.C - fb.DP).frequency_response(om).complex
    assert peak_relative_error(theirs_cl, ours_cl.data) < 1e-8


# ----------------------------------------------------------------------------- loop determinant


@pytest.mark.parametrize("terms", ["pd", "pdo", "o"])
def test_loop_determinant_is_sylvester(shaper, terms):
    """loop_determinant works in the 3 CE coordinates (det(I + J G J^T Dl));
    Sylvester's identity says it equals det(I - G D) on the full 36 x 36
    matrices, computed here from an explicit inverse.  |det| is between 0.15
    and 4.8 on this band, the LU of a matrix with condition ~1e5 loses 5
    digits at most: 1e-10 relative (measured 4e-13).  The modal evaluation
    (all modes) differs from the direct one by round-off in G = J Z^-1 J^T
    only: |d det / det| = |tr((I + G Dl)^-1 dG Dl)| <= tr(|(I + G Dl)^-1|
    |dG| |Dl|) with |dG| twice the Skeel bound of each route, at each
    frequency, plus 64 eps for the 3 x 3 products and determinant and the
    partial cancellation of the 72-term modal sum off resonance (|det| ~ 1
    here).  Measured: 8e-12 to 1.2e-11 of det, at most 0.7 of the bound."""
    om = frequencies(1.0, 300.0, 150)
    fb = closed_loop(shaper, width=0.002, speed=0.5, terms=terms)
    ours = loop_determinant(fb, om)
    ref = np.empty(om.size, complex)
    for k, w in enumerate(om):
        s = 1j * w
        G = np.linalg.inv(s * s * shaper.A + s * shaper.B + shaper.C)
        ref[k] = np.linalg.det(np.eye(shaper.n) - G @ fb(s))
    np.testing.assert_allclose(ours, ref, rtol=1e-10)
    direct = loop_determinant(fb, om)
    G, dG = skeel(shaper, om, fb.J)
    Dl = fb.Dl(1j * om)
    Minv = np.linalg.inv(np.eye(fb.J.shape[0]) + G @ Dl)
    bound = np.trace(np.abs(Minv) @ (2 * dG) @ np.abs(Dl), axis1=1, axis2=2) + 64 * np.finfo(float).eps
    modal = loop_determinant(fb, om, method="modal")
    assert np.all(np.abs(modal / direct - 1) <= bound)
    assert bound.max() < 1e-8  # and the bound says something
    # not trivially 1: the loop matters
    assert np.abs(ref - 1).max() > 0.1


def test_loop_determinant_sdof_closed_form(sdof):
    """1-DOF regenerative turning: det = 1 + K_f b (1 - e^{-jwT}) G(jw)."""
    b, T = 0.4e-3, 0.02
    fb = closed_loop(sdof, width=b, delay=T)
    om = sdof_omega()[1:]
    ref = 1 + 2.0e9 * b * (1 - np.exp(-1j * om * T)) * sdof_receptance(om)
    np.testing.assert_allclose(loop_determinant(fb, om), ref, rtol=1e-12)


# ----------------------------------------------------------------------------- FRF object


def test_frf_metadata_and_peaks(shaper):
    """Labels and the parabolic peak refinement: the open-loop rfe5.x peak
    is the first mode (76.28 Hz).  The grid step (0.1 Hz) is three times
    the half-power bandwidth (2 zeta f = 0.03 Hz), so the parabola on log|H|
    cannot do much better than the nearest grid point: within half a step,
    0.05 Hz (measured 0.014 Hz)."""
    om = frequencies(1.0, 300.0, 2991)
    h = frf(shaper, om, inputs="rfe5.x", outputs="rfe5.x")
    assert isinstance(h, FRF) and not h.closed_loop and h.label == "open loop"
    assert h.position == pytest.approx(0.85)
    f1 = cl.modes(shaper.system, count=1).frequency_hz[0]
    (fpk, apk), *_ = h.peaks()
    assert abs(fpk - f1) < 0.05
    np.testing.assert_allclose(h.frequency_hz, om / (2 * np.pi))
    d = h.to_dict()
    assert d["quantity"] == "receptance" and d["outputs"] == ["rfe5.x"] and len(d["real"][0][0]) == om.size


# ----------------------------------------------------------------------------- bad input


def test_bad_points_and_directions(shaper):
    om = frequencies(1.0, 10.0, 5)
    with pytest.raises(cl.InputError, match="unknown point 'nowhere'"):
        frf(shaper, om, inputs="nowhere.x", outputs="tool.x")
    with pytest.raises(cl.InputError, match="not POINT.DIRECTION"):
        frf(shaper, om, inputs="tool.z", outputs="tool.x")
    with pytest.raises(cl.InputError, match="not POINT.DIRECTION"):
        frf(shaper, om, inputs="tool.x", outputs="tool")
    with pytest.raises(cl.InputError, match="at least one"):
        frf(shaper, om, inputs=[], outputs="tool.x")
    with pytest.raises(cl.InputError, match="kind"):
        frf(shaper, om, inputs="tool.x", outputs="tool.x", kind="compliance")
    with pytest.raises(cl.InputError, match="method"):
        frf(shaper, om, inputs="tool.x", outputs="tool.x", method="fast")


def test_a_fixed_direction_is_refused(sdof):
    with pytest.raises(cl.InputError, match="does not move"):
        frf(sdof, np.array([1.0]), inputs="tip.y", outputs="tip.x")


@pytest.mark.parametrize(
    "omega", [np.array([]), np.array([-1.0, 2.0]), np.array([1.0, np.nan]), np.ones((2, 2))]
)
def test_bad_omega_arrays(sdof, omega):
    with pytest.raises(cl.InputError, match="omega"):
        frf(sdof, omega, inputs="tip.x", outputs="tip.x")


@pytest.mark.parametrize(
    "args, match",
    [
        ((10.0, 5.0, 100), "empty"),
        ((10.0, 10.0, 100), "empty"),
        ((-1.0, 5.0, 100), "fmin"),
        ((1.0, -5.0, 100), "fmax"),
        ((1.0, float("inf"), 100), "fmax"),
        ((1.0, 5.0, 1), "points"),
        ((1.0, 5.0, 2.5), "points"),
    ],
)
def test_bad_frequency_ranges(args, match):
    with pytest.raises(cl.InputError, match=match):
        frequencies(*args)
    with pytest.raises(ValueError):  # InputError is a ValueError
        frequencies(*args)


def test_frequencies_in_hz_out_in_rad_s():
    w = frequencies(1.0, 10.0, 10)
    np.testing.assert_allclose(w, 2 * np.pi * np.arange(1.0, 11.0))
    w = frequencies(1.0, 1000.0, 4, spacing="log")
    np.testing.assert_allclose(w / (2 * np.pi), [1.0, 10.0, 100.0, 1000.0])
    with pytest.raises(cl.InputError, match="log"):
        frequencies(0.0, 10.0, 10, spacing="log")


# ----------------------------------------------------------------------------- the paper's cases


def _peaks(frozen, fb, point: str, om: np.ndarray, mag: np.ndarray, n: int = 4) -> list[tuple[float, float]]:
    """The n largest local maxima of ``mag`` = |H(point, point)| on the grid
    ``om``, each refined on a 401-point grid between its neighbours (step
    1/200 of the grid step, 1.2e-4 Hz here, 1/250 of the narrowest
    half-power bandwidth, so the amplitude is exact to ~1e-5): [(Hz, m/N)],
    largest first."""
    k = np.nonzero((mag[1:-1] > mag[:-2]) & (mag[1:-1] >= mag[2:]))[0] + 1
    out = []
    for j in k[np.argsort(-mag[k])][: 2 * n]:
        fine = np.linspace(om[j - 1], om[j + 1], 401)
        m = np.abs(frf(fb, fine, inputs=point, outputs=point).data[0, 0])
        out.append((float(fine[m.argmax()] / (2 * np.pi)), float(m.max())))
    return sorted(out, key=lambda p: -p[1])[:n]


def _near(peaks: list[tuple[float, float]], lo: float, hi: float) -> tuple[float, float]:
    """The largest peak with frequency in [lo, hi] Hz."""
    sel = [p for p in peaks if lo <= p[0] <= hi]
    assert sel, (lo, hi, peaks)
    return max(sel, key=lambda p: p[1])


def test_shaper_cases_a_b_c_closed_loop_receptance(shaper):
    """The paper's three cases at b = 2 mm, v = 0.5 m/s (T = 1.5 s): the
    closed-loop receptance at the tool/workpiece contact point, rfe5.x/rfe5.x
    and rfe5.y/rfe5.y, 1-300 Hz on a 0.025 Hz grid (finer than the 0.67 Hz
    ripple 1/T of case c), peaks refined on a finer grid.

    Measured (Hz, m/N):

    ====  ==================  ==================  ==================  ==================
    case  x: largest peak     x near 76 Hz        y: largest peak     y near 83 Hz
    ====  ==================  ==================  ==================  ==================
    a     76.278  2.236e-5    76.278  2.236e-5    83.340  9.18e-6     83.340  9.18e-6
    b     76.136  2.041e-5    76.136  2.041e-5    76.136  2.85e-6     84.032  1.39e-6
    c     243.131 3.92e-6     76.156  3.30e-6     243.131 1.89e-5     83.297  4.13e-6
    ====  ==================  ==================  ==================  ==================

    (Open loop near 243 Hz: 2.23e-6 at 241.87 Hz in y.)  The paper (spectra of
    the simulated transient, its own structural model): 74 Hz in both
    directions (a); 69 Hz, ~40 % lower in x and the y peak almost gone (b);
    a new peak at 78 Hz (c).  Robust facts asserted here: (a) the peaks are
    the structure's first two modes; (b) P + D shifts the x peak down and
    lowers it a little (-9 %), and removes most of the 83 Hz y peak (-85 %,
    > 50 % asserted), which stops being the largest in y; (c) the delayed
    term lowers the 76 Hz x peak by 85 % (> 50 % asserted) and makes a new
    largest peak near 243 Hz in both directions, in y 8x the open loop there
    (> 3x asserted).
    Note that at this operating point the closed loop (c) is unstable
    (rightmost root +0.405 1/s at 83.9 Hz, see benchmarks/bench_frf.py), so
    (c) is the closed-loop receptance on the axis, not a steady state."""
    om = frequencies(1.0, 300.0, 11961)
    f1, f2 = cl.modes(shaper.system, count=2).frequency_hz
    res = {}
    for case, terms in (("a", "none"), ("b", "pd"), ("c", "pdo")):
        fb = closed_loop(shaper, width=0.002, speed=0.5, terms=terms)
        pts = ["rfe5.x", "rfe5.y"]
        mag = np.abs(frf(fb, om, inputs=pts, outputs=pts).data)
        res[case] = {p: _peaks(shaper, fb, p, om, mag[i, i]) for i, p in enumerate(pts)}
    print("\nshaper, b = 2 mm, v = 0.5 m/s: receptance peaks at the contact point (Hz, m/N)")
    for case in "abc":
        for p in ("rfe5.x", "rfe5.y"):
            print(f"  ({case}) {p}/{p}: " + ", ".join(f"{f:8.3f} Hz {a:.3e}" for f, a in res[case][p]))
    ax, ay = res["a"]["rfe5.x"], res["a"]["rfe5.y"]
    bx, by = res["b"]["rfe5.x"], res["b"]["rfe5.y"]
    cx, cy = res["c"]["rfe5.x"], res["c"]["rfe5.y"]
    # (a) the structure: modes 1 and 2 (peak within 0.01 Hz of the natural
    # frequency: the half-power bandwidths are 0.03 and 0.08 Hz)
    assert abs(ax[0][0] - f1) < 0.01 and abs(ay[0][0] - f2) < 0.01
    # (b) x: the 76 Hz peak moves down and drops a little
    a76, b76 = _near(ax, 70, 80), _near(bx, 70, 80)
    assert b76[0] < a76[0] and 0.5 * a76[1] < b76[1] < a76[1]
    # (b) y: the 83 Hz peak drops by more than half and is no longer the largest
    a83, b83 = _near(ay, 80, 90), _near(by, 80, 90)
    assert b83[1] < 0.5 * a83[1]
    assert not 80 <= by[0][0] <= 90
    # (c) x: the 76 Hz peak drops by more than half
    assert _near(cx, 70, 80)[1] < 0.5 * a76[1]
    # (c): a new largest peak near 243 Hz, in y far above the open loop there
    assert 230 < cy[0][0] < 250 and 230 < cx[0][0] < 250
    open_243 = np.abs(
        frf(shaper, frequencies(230.0, 250.0, 8001), inputs="rfe5.y", outputs="rfe5.y").data
    ).max()
    assert cy[0][1] > 3 * open_243
