"""The sweep quantities of milling models (issue 12, item 7): a-lim and
spectral-radius at a grid point are the Floquet engine's numbers, so a
stability chart over (rpm, a_e/D) is a set of traced limits, not a contour
of a coarse grid."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.frequency import multipliers
from chatterlab.lobes import milling_lobes, milling_loop_of
from chatterlab.quantities import QuantityTask
from chatterlab.sweep import Grid, sweep

ROOT = Path(__file__).resolve().parents[1]
ONE = ROOT / "studies" / "milling" / "benchmark_1dof.toml"


def test_a_lim_over_speed_and_immersion_is_the_traced_limit():
    model = cl.load_model(ONE)
    task = QuantityTask(model, "a-lim", width_max=0.01, aliases={"ae": "process.radial_immersion"})
    g = Grid({"speed": [9000.0, 18000.0], "ae": [0.05, 1.0]})
    res = sweep(task, g, outputs=task.outputs, backend="serial", progress=False)
    for j, ae in enumerate((0.05, 1.0)):
        m = model.with_parameter("process.radial_immersion", ae)
        ref = milling_lobes(milling_loop_of(cl.assemble(m).at()), np.array([9000.0, 18000.0]),
                            depth_max=0.01)  # fmt: skip
        # the same computation at each point (Brent to rtol 1e-8): equal to round-off
        np.testing.assert_allclose(np.asarray(res.data["a_lim"])[:, j], ref.a_lim, rtol=1e-12)


def test_spectral_radius_is_the_floquet_multiplier():
    model = cl.load_model(ONE)
    task = QuantityTask(model, "spectral-radius", fixed={"width": 2e-3})
    out = task(speed=18000.0)
    r = multipliers(milling_loop_of(cl.assemble(model).at()), 18000.0, 2e-3)
    assert out["spectral_radius"] == r.spectral_radius and out["kind"] == 2.0 and out["stable"] == 0.0


def test_milling_quantities_refuse_other_models(shaper_path):
    task = QuantityTask(cl.load_model(shaper_path), "a-lim")
    with pytest.raises(InputError, match=r"for milling models"):
        task(speed=0.5)


@pytest.mark.parametrize("quantity", ["stable", "rightmost-root", "b-lim", "min-b-lim"])
def test_the_time_averaged_quantities_are_refused_on_a_milling_model(quantity):
    """At 9147.7 rpm and 10.77 mm the benchmark's averaged loop is stable
    (rightmost root -4.8 1/s) while its Floquet multiplier is -1.72 (flip
    chatter): a quantity of the averaged loop would call a chattering cut
    stable, so it is refused before any work, naming the two that are not."""
    with pytest.raises(InputError, match="spectral-radius.*a-lim"):
        QuantityTask(cl.load_model(ONE), quantity, fixed={"width": 10.77e-3})
    r = multipliers(milling_loop_of(cl.assemble(cl.load_model(ONE)).at()), 9147.7, 10.77e-3)
    assert r.spectral_radius > 1.5  # the cut the averaged loop called stable chatters
