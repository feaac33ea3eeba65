"""The milling limit is complete (issue 18, part 1): no unstable band of
depth hides between the scan depths.

The independent route is written here: Insperger & Stepan's first-order
semi-discretisation (Int. J. Numer. Meth. Engng 61 (2004) 117-141;
Insperger, Stepan & Turi, J. Sound Vib. 313 (2008) 334-341) of the 1-DOF
benchmark, on a grid aligned with the tooth's entry and exit (mc steps in
the cut, the free flight in one exact step), so its error is a clean
O(mc^-2) and Richardson's extrapolation from mc and 2 mc leaves O(mc^-3);
the tolerance of each comparison is the extrapolation's own change between
(mc, 2 mc) and (2 mc, 4 mc).  For the 2-DOF and variable-pitch tools the
route is a brute-force dense depth scan of the spectral radius (no pencil,
no derivatives, no bisection: independent of the search under test).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import brentq

from chatterlab.frequency import DEGREE, SpectralMonodromy
from chatterlab.lobes import milling_lobes
from chatterlab.process import Milling, milling_loop
from chatterlab.structure import Structure

WN, ZETA, MASS, KT, KN = 2 * np.pi * 922.0, 0.011, 0.03993, 6e8, 2e8


def sdm_radius(rpm: float, a: float, mc: int, ae: float = 0.05, teeth: int = 2) -> float:
    """Spectral radius of the 1-DOF down-milling benchmark by first-order SDM, mc steps in the cut."""
    T = 60.0 / (rpm * teeth)
    om = 2 * np.pi * rpm / 60
    phst, phex = np.arccos(2 * ae - 1), np.pi
    tc = (phex - phst) / om
    steps = [tc / mc] * mc + [T - tc]
    m = len(steps)

    def F(ph: float) -> float:  # antiderivative of sin(ph) (Kt cos(ph) + Kn sin(ph))
        return KT * np.sin(ph) ** 2 / 2 + KN * (ph / 2 - np.sin(2 * ph) / 4)

    Phi = np.eye(m + 2)  # state (x_i, v_i, x_{i-1}, ..., x_{i-m}); the delay T is m steps
    t = 0.0
    for k, dt in enumerate(steps):
        h = (F(phst + om * (t + dt)) - F(phst + om * t)) / (om * dt) if k < mc else 0.0
        A = np.array([[0.0, 1.0], [-(WN**2) - a * h / MASS, -2 * ZETA * WN]])
        Z = np.zeros((6, 6))
        Z[:2, :2], Z[:2, 2:4], Z[2:4, 4:] = A, np.eye(2), np.eye(2)
        E = sla.expm(Z * dt)
        P, F1, F2 = E[:2, :2], E[:2, 2:4], E[:2, 4:]
        b = np.array([0.0, a * h / MASS])
        top = P @ Phi[:2] + np.outer((F1 - F2 / dt) @ b, Phi[1 + m]) + np.outer((F2 / dt) @ b, Phi[m])
        Phi = np.vstack([top, Phi[:1], Phi[2 : 1 + m]])
        t += dt
    return float(np.max(np.abs(np.linalg.eigvals(Phi))))


def sdm_extrapolated(rpm: float, a: float, mc: int = 20) -> tuple[float, float]:
    """Richardson's (4 rho_2m - rho_m)/3 and its change from the next pair (its error bar)."""
    r = [sdm_radius(rpm, a, mc * f) for f in (1, 2, 4)]
    e1, e2 = (4 * r[1] - r[0]) / 3, (4 * r[2] - r[1]) / 3
    return e2, abs(e2 - e1)


def one_dof() -> tuple[Structure, Milling]:
    return Structure.single_dof(MASS, WN, ZETA), Milling.from_immersion(2, 0.02, KT, KN, 0.05, "down")


def sdm_edge(rpm: float, lo: float, hi: float) -> tuple[float, float]:
    """The depth in [lo, hi] where the extrapolated SDM radius is 1, and its error bar (m)."""
    root = brentq(lambda a: sdm_extrapolated(rpm, a)[0] - 1.0, lo, hi, xtol=1e-12)
    d = 1e-7
    slope = (sdm_extrapolated(rpm, root + d)[0] - sdm_extrapolated(rpm, root - d)[0]) / (2 * d)
    return root, sdm_extrapolated(rpm, root)[1] / abs(slope)


def test_issue_18_flip_band_between_scan_depths_is_the_limit():
    """18298.05 rpm: the flip band [1.82, 1.995] mm lies between the scan depths 1.75 and 2.0 mm;
    the old search printed 7.457 mm (Hopf).  The limit is the band's lower edge, as the
    independent SDM puts it, to the SDM's own error bar plus the spectral check's error."""
    st, mill = one_dof()
    ml = milling_lobes(milling_loop(st, mill), [18298.05], depth_max=0.01)
    assert ml.kind[0] == "flip" and ml.basis[0] == "complete"
    edge, bar = sdm_edge(18298.05, 1.75e-3, 1.905e-3)
    assert abs(ml.a_lim[0] - edge) <= 3 * bar + ml.error[0] + 1e-9 * edge, (ml.a_lim[0], edge, bar)
    assert ml.a_lim[0] == pytest.approx(1.818e-3, abs=1e-6)
    # and the band is unstable in its middle by the independent route
    mid, bar_mid = sdm_extrapolated(18298.05, 1.905e-3)
    assert mid - 1.0 > 3 * bar_mid


def test_flip_lens_near_its_tip_is_found():
    """Near the lens tip (18298.27 rpm, where the flip band closes) the band is narrower than
    1 % of its depth; its edges are the exact flip depths, confirmed by the SDM on both sides."""
    st, mill = one_dof()
    rpm = 18298.25
    # the lobes on the discretisation of SpectralMonodromy's default (degree 16, omega L <= 5), so that
    # the limit is its exact flip depth to round-off
    ml = milling_lobes(milling_loop(st, mill), [rpm], depth_max=0.01, check=False, degree=DEGREE)
    edges = SpectralMonodromy(milling_loop(st, mill), rpm).unit_depths(-1.0, 0.01)
    assert edges.size == 2 and edges[1] - edges[0] < 0.05 * edges[0]
    assert ml.kind[0] == "flip" and ml.a_lim[0] == pytest.approx(edges[0], rel=1e-12)
    lo, bar_lo = sdm_extrapolated(rpm, edges[0] * (1 - 2e-2))
    mid, bar_mid = sdm_extrapolated(rpm, 0.5 * (edges[0] + edges[1]))
    assert lo < 1.0 - 3 * bar_lo and mid > 1.0 + 3 * bar_mid, (lo, mid)


def _dense_check(st: Structure, mill: Milling, rpm: float, a_lim: float, n: int) -> None:
    """The brute-force route: the spectral radius on n uniform depths in (0, a_lim) is below 1
    at every one (nothing unstable below the limit at that resolution), and above 1 just past
    the limit (the limit is a crossing, not a touch)."""
    sm = SpectralMonodromy(milling_loop(st, mill), rpm)
    rho = np.array([sm.radius(a) for a in a_lim * np.arange(1, n) / n])
    assert np.all(rho < 1.0), a_lim * np.nonzero(rho >= 1.0)[0][:3] / n
    # one part in 1e4 past the limit: |mu| moves by slope * 1e-4 a_lim (slope ~1e3 1/m, a ~1e-3 m),
    # some 1e-4, far above the multipliers' 1e-10 convergence error
    assert sm.radius(a_lim * (1 + 1e-4)) > 1.0


def _two_dof() -> tuple[Structure, Milling]:
    k = MASS * WN**2
    st = Structure.modal([WN, WN], [ZETA, ZETA], [k, k], ("x", "y"), "2-DOF")
    return st, Milling.from_immersion(2, 0.02, KT, KN, 0.05, "down")


def _variable_pitch() -> tuple[Structure, Milling]:
    mill = Milling.from_immersion(3, 0.02, KT, KN, 0.1, "down", pitch=(1.9, 2.3, 2 * np.pi - 4.2))
    return Structure.single_dof(MASS, WN, ZETA), mill


@pytest.mark.parametrize(
    "tool,rpm,band,kind",
    [
        # 2-DOF benchmark, 0.1 rpm from the tip of the flip lens at 18635.49 rpm: the band
        # [1.0151, 1.0441] mm lies between the scan depths 1.0 and 1.25 mm (old: 1.333 mm, Hopf)
        ("2dof", 18635.5869, (1.0151e-3, 1.0442e-3), "flip"),
        # 3-tooth variable pitch near a lens tip (5606.76 rpm): [2.3783, 2.4529] mm between 2.25
        # and 2.5 mm (old: 3.3405 mm)
        ("pitch", 5606.2606, (2.3782e-3, 2.4529e-3), "flip"),
    ],
)
def test_narrow_bands_near_lens_tips_on_2dof_and_variable_pitch(tool, rpm, band, kind):
    st, mill = _two_dof() if tool == "2dof" else _variable_pitch()
    ml = milling_lobes(milling_loop(st, mill), [rpm], depth_max=0.01, check=False)
    assert ml.kind[0] == kind and ml.basis[0] == "complete", (ml.kind, ml.a_lim)
    a = float(ml.a_lim[0])
    if band is not None:  # the band's lower edge, to the 4 digits quoted
        assert band[0] - 1e-7 <= a <= band[0] + 1e-7 and a < band[1]
    _dense_check(st, mill, rpm, a, 200)


def test_an_undecided_speed_is_undetermined_with_a_lower_bound(monkeypatch):
    """With no evaluations allowed beyond the scan the search cannot decide: the speed says
    'undetermined' and its a_lim is the depth up to which stability was established, below
    the true limit (never above it), in the summary and the CSV."""
    import chatterlab.lobes._milling_search as search

    st, mill = one_dof()
    full = milling_lobes(milling_loop(st, mill), [5000.0], depth_max=0.01, check=False)
    monkeypatch.setattr(search, "MAX_TANGENTS", -40)  # the budget is MAX_TANGENTS + scan
    ml = milling_lobes(milling_loop(st, mill), [5000.0], depth_max=0.01, check=False)
    assert ml.basis[0] == "undetermined" and ml.kind[0] == "undetermined"
    assert ml.a_lim[0] == ml.certified[0] and ml.a_lim[0] < full.a_lim[0]
    assert "undetermined at 1 speed" in ml.summary()
