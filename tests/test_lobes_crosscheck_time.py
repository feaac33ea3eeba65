"""The lobes cross-checked in the time domain (issue 18): at envelope points
of the shaper and of random structures, runs at 0.98 and 1.02 b_lim by both
schemes (Newmark at the default step from the chatter band; the default
exponential step map at its step for rtol; the verdict with its error bar)
never contradict the rightmost characteristic root: the bar covers it, a
claimed class has its sign, and where the rate is large enough to decide in
the run (the random structures, |sigma| ~ 1 1/s) the class is the root's.

The shaper's envelope at s = 0.85 m grows or decays by only ~0.005 1/s at
+-2 % of b_lim (its modes are damped at zeta ~ 2e-4): a 2 s run cannot
decide that, and the verdict must say so (undetermined, or the root's
class) instead of guessing.  About a minute and a half on one core.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_time_verdicts import (
    assert_honest,
    assert_step_resolves_the_rightmost_root,
    frozen_roots,
    random_3dof,
)

import chatterlab as cl
from chatterlab.lobes import lobes
from chatterlab.time import Excitation, Initial, Integration
from chatterlab.time._simulate import simulate


def _envelope_points(system, speeds, position=None):
    d = lobes(system.at(position), np.asarray(speeds, dtype=float), width_max=0.02, verify=0)
    assert d.band_certified
    return [(float(T), float(b)) for T, b in zip(d.delay, d.b_lim, strict=True) if np.isfinite(b)]


def _check(system, T, b, factor, output, duration, position=None, decided=True, integrator="newmark"):
    roots = frozen_roots(system, factor * b, T, position)
    assert (roots.roots[0].real > 0) == (factor > 1)
    sim = simulate(
        system,
        width=factor * b,
        delay=T,
        position=position,
        outputs=output,
        roots=roots,
        integration=Integration(duration=duration, integrator=integrator),
        initial=Initial(q0={output: 1e-06}, history="constant"),
        excitation=Excitation(cutting_forces=False),
    )
    if integrator == "newmark":  # Newmark's step rule (the exponential map's is its own error estimate)
        assert_step_resolves_the_rightmost_root(system, sim, roots, position)
    else:
        assert sim.response.attrs["method"] == "exponential"
    v = sim.verdict(output)
    assert_honest(v, roots, rightmost=decided)
    if decided:
        assert v.classification == ("growing" if factor > 1 else "decaying"), v.message
    return v


@pytest.fixture(scope="module")
def shaper(shaper_path):
    return cl.assemble(cl.load_model(shaper_path))


@pytest.mark.parametrize("integrator", ["newmark", "auto"])
@pytest.mark.parametrize("factor", [0.98, 1.02])
def test_shaper_envelope_point_in_the_time_domain(shaper, factor, integrator):
    """v = 10 m/s (T = 0.36 s, b_lim 0.667 mm, chatter at 76.2 Hz)."""
    ((T, b),) = _envelope_points(shaper, [10.0], 0.85)
    v = _check(shaper, T, b, factor, "rfe5.y", 2.0, 0.85, decided=False, integrator=integrator)
    assert v.classification in ("undetermined", "steady", "growing" if factor > 1 else "decaying")


@pytest.mark.parametrize("integrator", ["newmark", "auto"])
@pytest.mark.parametrize("seed", [3, 7])
@pytest.mark.parametrize("factor", [0.98, 1.02])
def test_random_structure_envelope_points_in_the_time_domain(seed, factor, integrator):
    sy = cl.assemble(cl.loads_model(random_3dof(seed)))
    f1 = np.sqrt(np.min(np.linalg.eigvals(np.linalg.solve(sy.at().A, sy.at().C)).real)) / (2 * np.pi)
    pts = _envelope_points(sy, [2.0 / f1, 7.0 / f1])
    for T, b in pts:
        _check(sy, T, b, factor, "tip.x", 1.5, integrator=integrator)


def test_confirmation_of_a_turning_diagram(tmp_path):
    """lobes.confirm simulates the 1-DOF turning tool at 0.7 and 1.4 b_lim of
    its envelope: the frequency-domain diagram (D-subdivision, an independent
    method) says which side decays, the runs must agree; the confirmation is
    a result of the one protocol (files that read back, a plot on the Axes
    given)."""
    import json

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from conftest import turning_text

    from chatterlab.io import Result, read_dataset
    from chatterlab.lobes import confirm

    tool = cl.assemble(cl.loads_model(turning_text()))
    d = lobes(tool.at(None), np.array([2500.0, 3000.0, 3500.0]), width_max=0.02, verify=0)
    conf = confirm(tool, d, count=1, periods=20, min_duration=0.3)
    assert isinstance(conf, Result) and len(conf.rows) == 2 and conf.agrees, conf.table()
    assert {r["classification"] for r in conf.rows} == {"stable", "unstable"}
    ds = read_dataset(conf.to_netcdf(tmp_path / "c.nc"))
    np.testing.assert_array_equal(ds["growth_rate"].values, [r["growth_rate"] for r in conf.rows])
    assert ds["speed"].attrs["units"] == "rpm" and list(ds["expected"].values) == [
        0.0,
        1.0,
    ]  # stable, unstable
    assert json.loads(conf.to_json())["data"]["width"]["units"] == "m"
    fig, ax = plt.subplots()
    assert conf.plot(ax=ax) is ax and len(ax.collections) == 2
    plt.close("all")
