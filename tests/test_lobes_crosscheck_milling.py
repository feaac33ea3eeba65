"""The milling limits against routes that know nothing of the search (issue 18, part 1).

For the 1-DOF benchmark (Insperger & Stepan) every limit a_lim is checked by
the semi-discretisation written in tests/test_milling_limit_complete.py (grid
aligned with the cut, Richardson-extrapolated from 20, 40 and 80 steps in
the cut): stable at (1 - 1e-3) a_lim and unstable at (1 + 1e-3) a_lim, each
by more than three times the extrapolation's own change.  Why 1e-3 can be
resolved: |mu| moves by a_lim |d|mu|/da| 1e-3, 1e-5..1e-3 on these limits,
while the extrapolated SDM changes by < 1e-7 between (20, 40) and (40, 80).
Below each limit, 200 uniform depths of the brute-force spectral radius
(below) must all be stable: the limit is the first crossing.

The 2-DOF benchmark and a 3-tooth variable-pitch cutter are checked by a
brute-force depth scan of the spectral radius (no pencil, no derivatives, no
bisection): no sample of 100 uniform depths below a_lim is unstable, the
radius exceeds 1 just above it (1 + 1e-4), and an inf is confirmed at 200
depths up to the ceiling.  The points include the flip lenses and their
tips (bands narrower than the scan step), the fold lobes of the variable
pitch, Hopf limits and an inf.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_milling_limit_complete import KN, KT, MASS, WN, ZETA, sdm_extrapolated

from chatterlab.frequency import SpectralMonodromy
from chatterlab.lobes import milling_lobes
from chatterlab.process import Milling, milling_loop
from chatterlab.structure import Structure

#: 1-DOF, a_e/D = 0.05: Hopf and flip lobes, the flip lens of issue 18 (18100-18298 rpm) and its tip
ONE_DOF_RPM = [5000.0, 8000.0, 10000.0, 12000.0, 15000.0, 18150.0, 18250.0, 18298.05, 18298.25, 22000.0]


def test_one_dof_limits_against_the_semi_discretisation():
    st = Structure.single_dof(MASS, WN, ZETA)
    mill = Milling.from_immersion(2, 0.02, KT, KN, 0.05, "down")
    ml = milling_lobes(milling_loop(st, mill), ONE_DOF_RPM, depth_max=0.01)
    assert set(ml.basis) == {"complete"}
    assert {"hopf", "flip"} <= set(ml.kind)
    bad = []
    for r, a, k in zip(ml.speed, ml.a_lim, ml.kind, strict=True):
        if not np.isfinite(a):
            top, bar = sdm_extrapolated(r, 0.01)
            if not top < 1.0 - 3 * bar:
                bad.append((r, "inf", top))
            continue
        # nothing unstable below: the brute-force scan of the spectral radius (200 depths)
        sm = SpectralMonodromy(milling_loop(st, mill), r)
        if any(sm.radius(x) >= 1.0 for x in a * np.arange(1, 200) / 200):
            bad.append((r, a, k, "unstable below"))
        below, b1 = sdm_extrapolated(r, a * (1 - 1e-3))
        above, b2 = sdm_extrapolated(r, a * (1 + 1e-3))
        if not (below < 1.0 - 3 * b1 and above > 1.0 + 3 * b2):
            bad.append((r, a, k, below, above))
    assert not bad, bad


def _brute(st: Structure, mill: Milling, rpm: float, a: float, top: float) -> list[str]:
    sm = SpectralMonodromy(milling_loop(st, mill), rpm)
    if not np.isfinite(a):
        rho = [sm.radius(x) for x in top * np.arange(1, 201) / 200]
        return [] if max(rho) < 1.0 else [f"{rpm}: inf but rho {max(rho)}"]
    rho = np.array([sm.radius(x) for x in a * np.arange(1, 100) / 100])
    out = []
    if np.any(rho >= 1.0):
        out.append(f"{rpm}: unstable below a_lim {a} at {a * (np.nonzero(rho >= 1)[0][0] + 1) / 100}")
    if not sm.radius(a * (1 + 1e-4)) > 1.0:
        out.append(f"{rpm}: stable above a_lim {a}")
    return out


@pytest.mark.parametrize("tool", ["2dof", "pitch"])
def test_two_dof_and_variable_pitch_against_a_brute_force_scan(tool):
    k = MASS * WN**2
    if tool == "2dof":
        st = Structure.modal([WN, WN], [ZETA, ZETA], [k, k], ("x", "y"), "2-DOF")
        mill = Milling.from_immersion(2, 0.02, KT, KN, 0.05, "down")
        # Hopf, the flip lens at 18635-18700 rpm (tip 18635.49) and inf at 25000 rpm
        rpm = [10000.0, 15000.0, 18635.5869, 18640.0, 18700.0, 20000.0, 25000.0]
    else:
        st = Structure.single_dof(MASS, WN, ZETA)
        mill = Milling.from_immersion(3, 0.02, KT, KN, 0.1, "down", pitch=(1.9, 2.3, 2 * np.pi - 4.2))
        # fold lobes (5200, 6400), a flip near a lens tip (5606.26), Hopf (5100, 5700)
        rpm = [5100.0, 5200.0, 5606.2606, 5700.0, 6400.0]
    ml = milling_lobes(milling_loop(st, mill), rpm, depth_max=0.01, check=False)
    assert set(ml.basis) == {"complete"}
    if tool == "pitch":
        assert {"fold", "flip", "hopf"} <= set(ml.kind), ml.kind
    bad = [m for r, a in zip(ml.speed, ml.a_lim, strict=True) for m in _brute(st, mill, r, a, 0.01)]
    assert not bad, bad
