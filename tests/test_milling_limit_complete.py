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

from chatterlab.frequency import SpectralMonodromy, ToolStructure
from chatterlab.lobes import milling_lobes
from chatterlab.process import Milling

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


def one_dof() -> tuple[ToolStructure, Milling]:
    return ToolStructure.single_dof(MASS, WN, ZETA), Milling.from_immersion(2, 0.02, KT, KN, 0.05, "down")


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
    ml = milling_lobes(st, mill, [18298.05], depth_max=0.01)
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
    ml = milling_lobes(st, mill, [rpm], depth_max=0.01, check=False)
    edges = SpectralMonodromy(st, mill, rpm).unit_depths(-1.0, 0.01)
    assert edges.size == 2 and edges[1] - edges[0] < 0.05 * edges[0]
    assert ml.kind[0] == "flip" and ml.a_lim[0] == pytest.approx(edges[0], rel=1e-12)
    lo, bar_lo = sdm_extrapolated(rpm, edges[0] * (1 - 2e-2))
    mid, bar_mid = sdm_extrapolated(rpm, 0.5 * (edges[0] + edges[1]))
    assert lo < 1.0 - 3 * bar_lo and mid > 1.0 + 3 * bar_mid, (lo, mid)


def test_flip_speeds_around_the_lens_agree_with_sdm():
    """Across the lens (18100-18298 rpm, two flip edges each) the limit is the lower edge and the
    SDM says stable just below it and unstable just above."""
    st, mill = one_dof()
    rpm = np.array([18150.0, 18250.0, 18298.0])
    ml = milling_lobes(st, mill, rpm, depth_max=0.01, check=False)
    for r, a, k in zip(rpm, ml.a_lim, ml.kind, strict=True):
        assert k == "flip"
        below, b1 = sdm_extrapolated(r, a * (1 - 1e-3))
        above, b2 = sdm_extrapolated(r, a * (1 + 1e-3))
        assert below < 1.0 - 3 * b1 and above > 1.0 + 3 * b2, (r, a, below, above)


def _dense_first(st: ToolStructure, mill: Milling, rpm: float, top: float, n: int) -> float:
    """First depth of a uniform n-point scan up to top where the spectral radius is >= 1 (inf if none)."""
    sm = SpectralMonodromy(st, mill, rpm)
    for a in top * np.arange(1, n + 1) / n:
        if sm.radius(a) >= 1.0:
            return float(a)
    return float("inf")


@pytest.mark.parametrize(
    "name,rpm",
    [("2dof", 9000.0), ("2dof", 16000.0), ("2dof", 21500.0), ("pitch", 7000.0), ("pitch", 14000.0)],
)
def test_two_dof_and_variable_pitch_against_a_dense_scan(name, rpm):
    """2-DOF benchmark (922 Hz in x and y) and a 3-tooth variable-pitch cutter: no sample of a
    dense scan (step depth_max/2000) below a_lim is unstable, and the first unstable sample is
    within one dense step above it."""
    k = MASS * WN**2
    if name == "2dof":
        st = ToolStructure.modal([WN, WN], [ZETA, ZETA], [k, k], [[1, 0], [0, 1]], "2-DOF")
        mill = Milling.from_immersion(2, 0.02, KT, KN, 0.05, "down")
    else:
        st = ToolStructure.single_dof(MASS, WN, ZETA)
        mill = Milling.from_immersion(3, 0.02, KT, KN, 0.1, "down", pitch=(1.9, 2.3, 2 * np.pi - 4.2))
    top, n = 0.01, 2000
    ml = milling_lobes(st, mill, [rpm], depth_max=top, check=False)
    assert ml.basis[0] == "complete"
    first = _dense_first(st, mill, rpm, top, n)
    if np.isfinite(ml.a_lim[0]):
        assert ml.a_lim[0] <= first * (1 + 1e-9)
        assert first - ml.a_lim[0] <= top / n * (1 + 1e-9) or ml.kind[0] != "hopf"
    else:
        assert not np.isfinite(first)
