"""Milling lobes whose defaults find the lobes (issue 20, item 3).

A realistic end mill (4 flutes, half immersion, modes at 650 and 780 Hz)
has limits of tens of mm: a fixed 20 mm ceiling called several speeds "no
instability up to 20 mm".  The default ceiling now comes from the problem --
three times the largest limit of the zeroth-order approximation over the
speeds -- so every limit is found; when most speeds still end at a ceiling
the user set, the summary says so and names the option; the speeds of one
diagram can be split among processes (the same diagram, bit for bit) and
report their progress.
"""

from __future__ import annotations

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.lobes import milling_lobes, milling_loop_of

END_MILL = """
[model]
name = "4-flute end mill, 50 % immersion"

[[mode]]
id = "x1"
frequency_hz = 650.0
damping_ratio = 0.03
stiffness = 2.0e7
direction = "tool.x"

[[mode]]
id = "y1"
frequency_hz = 780.0
damping_ratio = 0.03
stiffness = 2.5e7
direction = "tool.y"

[[point]]
id = "tip"
coords = { x = "tool.x", y = "tool.y" }

[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "milling"

[process]
kind = "milling"
rpm = 10000.0
teeth = 4
diameter = 0.016
Kt = 7.0e8
Kn = 2.1e8
radial_immersion = 0.5
milling = "down"
"""

#: speeds where a 20 mm ceiling misses the limit of this tool (found by the scan of 30 speeds 3000-15000 rpm)
RPM = np.array([9620.0, 10448.0, 12000.0])


@pytest.fixture(scope="module")
def loop():
    return milling_loop_of(cl.assemble(cl.loads_model(END_MILL)).at())


def test_the_default_ceiling_comes_from_the_averaged_problem_and_finds_every_limit(loop):
    fixed = milling_lobes(loop, RPM, depth_max=0.02)
    assert np.any(~np.isfinite(fixed.a_lim))  # the old default misses some
    d = milling_lobes(loop, RPM)
    zoa = milling_lobes(loop, RPM, method="zoa", depth_max=1.0)
    # three times the largest zeroth-order limit: the same D-subdivision, so the same number
    assert d.width_max == pytest.approx(
        3 * np.nanmax(np.where(np.isfinite(zoa.a_lim), zoa.a_lim, np.nan)), rel=1e-12
    )
    assert np.all(np.isfinite(d.a_lim)) and np.all(d.a_lim < d.width_max)
    # where both searches found a limit it is the same one (the ceiling only widens the search)
    both = np.isfinite(fixed.a_lim)
    np.testing.assert_allclose(d.a_lim[both], fixed.a_lim[both], rtol=1e-7)
    assert "three times the largest zeroth-order limit" in d.summary()


def test_most_speeds_at_a_low_ceiling_are_named(loop):
    d = milling_lobes(loop, RPM, depth_max=0.005)
    assert np.all(~np.isfinite(d.a_lim))
    assert "most speeds (3 of 3) end at the ceiling 5 mm: raise it with --width-max" in d.summary()


def test_speeds_split_among_processes_give_the_same_diagram_and_report_progress(loop):
    seen: list[float] = []
    serial = milling_lobes(loop, RPM, depth_max=0.05, progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == 1.0 and len(seen) == RPM.size
    parallel = milling_lobes(loop, RPM, depth_max=0.05, jobs=2)
    for name in ("b_lim", "chatter_hz", "multiplier", "error", "certified"):
        np.testing.assert_array_equal(getattr(parallel, name), getattr(serial, name), err_msg=name)
    assert list(parallel.kind) == list(serial.kind) and list(parallel.basis) == list(serial.basis)
