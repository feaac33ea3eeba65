"""FE-scale tools in the Floquet lobes (issue 26): the structure's high modes
respond quasi-statically through their exact static compliance at the tool
(chatterlab.frequency.split_structure), decided automatically where the
whole structure's discretisation is too large, with the split's error
estimated at every limit and reported.

Oracles: the whole structure integrated in time on a size where both run
(the split's error against its estimate, whose accuracy follows from the
modes' compliance shares and frequencies), the static compliance in closed
form, and the 302-coordinate end mill of studies/milling/tool_cantilever.toml
computed without any hand reduction.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.frequency import SpectralMonodromy, multipliers
from chatterlab.frequency._floquet import needs_split, split_frequency, split_structure
from chatterlab.lobes import milling_lobes, milling_loop_of
from chatterlab.process import Milling, milling_loop
from chatterlab.structure import Structure

ROOT = Path(__file__).resolve().parents[1]
TOOL = ROOT / "studies" / "milling" / "tool_cantilever.toml"
WN, ZETA, MASS, KT, KN = 2 * np.pi * 922.0, 0.011, 0.03993, 6e8, 2e8
K1 = MASS * WN**2


def three_modes(immersion: float = 1.0):
    """The benchmark's mode at the tool plus two stiff ones (5 and 11 kHz) carrying 1/20 and
    1/60 of its compliance: modal coordinates, the tool's x their sum."""
    w = 2 * np.pi * np.array([922.0, 5000.0, 11000.0])
    k = K1 * np.array([1.0, 20.0, 60.0])
    st = Structure.modal(w, [ZETA, 0.02, 0.02], k, ("m1", "m2", "m3"), "3 modes")
    J = np.array([[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]])
    return milling_loop(st, Milling.from_immersion(2, 0.02, KT, KN, immersion, "down"), J)


def test_split_keeps_the_static_compliance_exactly():
    """The quasi-static rest is the exact static compliance of the modes above the split:
    1/k2 + 1/k3 for the modal model (closed form), and the kept modes' plus the rest's is
    J K^-1 J^T of the whole structure to round-off."""
    lp = three_modes()
    qs = split_structure(lp, 3000.0)
    assert qs.kept == 1
    np.testing.assert_allclose(qs.compliance, [[1 / (20 * K1) + 1 / (60 * K1)]], rtol=1e-12)
    whole = lp.J @ np.linalg.solve(lp.K, lp.J.T)  # J K^-1 J^T
    np.testing.assert_allclose(1 / K1 + qs.compliance[0, 0], whole[0, 0], rtol=1e-12)
    # the significant modes carry >= 5 % of the compliance: only the first (1/20 / 1.067 = 4.7 %)
    assert split_frequency(lp) == pytest.approx(4 * 922.0, rel=1e-9)


@pytest.mark.parametrize("immersion,rpm", [(1.0, 15000.0), (0.05, 15000.0)])
def test_split_limit_against_the_whole_structure_within_its_estimate(immersion, rpm):
    """The limit with modes 2 and 3 quasi-static against the whole structure integrated in time
    (150 multipliers: both run).  The estimate is the change when mode 2 is integrated too, so
    it measures mode 2's part E2 of the error; mode 3's part E3 is left, smaller by its
    compliance share and frequency: E3/E2 ~ (1/60)/(1/20) (5/11)^2 = 0.07.  So the true error is
    the estimate within 20 % (plus the discretisations' own errors, from their checks)."""
    lp = three_modes(immersion)
    full = milling_lobes(lp, [rpm], depth_max=0.01, rtol=1e-10, split=None)
    part = milling_lobes(lp, [rpm], depth_max=0.01, rtol=1e-10, split=3688.0)
    assert part.meta["split_kept"] == 1 and "split" not in full.meta
    a, r = float(part.a_lim[0]), float(full.a_lim[0])
    est = part.meta["split_error_max_rel"] * a
    disc = float(full.error[0]) + float(part.error[0]) - est  # the degree checks' parts
    assert est > 0 and abs(abs(a - r) - est) <= 0.2 * est + 2 * disc + 1e-9 * r, (a, r, est, disc)
    assert part.error[0] >= est  # the split's estimate is in the error the diagram reports


def test_auto_split_only_where_the_structure_is_too_large():
    """'auto' splits where the whole structure's automatic mesh would exceed SPLIT_SIZE
    multipliers at the slowest speed: the 3-mode tool at 5000 rpm (11 kHz over a 6 ms period),
    not at 25000 rpm; never the 1-DOF benchmark (no mode above its split)."""
    lp = three_modes()
    assert needs_split(lp, 5000.0, 0.01, 1e-8) == pytest.approx(4 * 922.0)
    assert needs_split(lp, 25000.0, 1e-3, 1e-8) is None
    one = milling_loop(
        Structure.single_dof(MASS, WN, ZETA), Milling.from_immersion(2, 0.02, KT, KN, 1.0, "down")
    )
    assert split_frequency(one) is None


def fe_tool(immersion: float, elements: int = 100):
    text = TOOL.read_text()
    text = re.sub(r"^elements = \d+", f"elements = {elements}", text, flags=re.M)
    text = re.sub(r"^radial_immersion = [0-9.e+-]+", f"radial_immersion = {immersion!r}", text, flags=re.M)
    return milling_loop_of(cl.assemble(cl.loads_model(text)).at())


def test_a_302_coordinate_end_mill_without_hand_reduction():
    """The beam end mill in 100 Timoshenko elements (302 coordinates, poles to 64 kHz): 0.2.0
    refused it at every speed (over 4000 collocation unknowns).  Its lobes now come from the
    unreduced loop: its three modes below 10.5 kHz integrated, the rest quasi-static; every
    discretisation set up is small (counted), the limit complete, and its error estimate (the
    split's check and the degree check) reported in the diagram."""
    lp = fe_tool(1.0)
    assert lp.n == 302
    sizes: list[int] = []
    init = SpectralMonodromy.__init__

    def counted(self, *a, **k):
        init(self, *a, **k)
        sizes.append(self.size)

    SpectralMonodromy.__init__ = counted  # type: ignore[method-assign]
    try:
        d = milling_lobes(lp, [25000.0], depth_max=0.01)
    finally:
        SpectralMonodromy.__init__ = init  # type: ignore[method-assign]
    assert d.basis[0] == "complete" and d.kind[0] in ("hopf", "flip") and np.isfinite(d.a_lim[0])
    assert d.meta["split_kept"] == 3 and "3 of 302 modes" in d.resolution
    assert 0 < d.meta["split_error_max_rel"] <= d.error[0] / d.a_lim[0] < 1e-2
    # the search's discretisations and the degree check: at most 3 modes x 2 states + 2 per node
    assert max(sizes[:-1]) < 150 and len(sizes) <= 6, sizes


def test_multipliers_of_the_fe_tool_split_automatically():
    """multipliers() on the unreduced end mill at one speed and depth: split automatically, its
    error the degree check plus the split's, and the verdict the lobes' (stable just below the
    limit's depth by more than the error)."""
    lp = fe_tool(1.0)
    r = multipliers(lp, 25000.0, 1e-3)
    assert "quasi-static" in r.resolution and np.isfinite(r.error) and r.error < 1e-2
