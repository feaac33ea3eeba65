"""Process kinematics of the time domain: the shaper's stroke cycle, the
in-cut windows, the delay, the step grid, and the contact point clamped at
the workpiece ends.

Oracle: the stroke is piecewise linear and its event times follow from the
distances and speeds by hand (run-in, cut, coast at v_w, return at v_l).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.process._kinematics import ShapingKinematics, SteadyKinematics, kinematics_for


@pytest.fixture(scope="module")
def shaper(shaper_path):
    return cl.assemble(cl.load_model(shaper_path))


@pytest.fixture(scope="module")
def kin(shaper) -> ShapingKinematics:
    k = kinematics_for(shaper.model.process)
    assert isinstance(k, ShapingKinematics)
    return k


def test_cycle_is_the_delay(kin):
    # stroke S = 0.05 + 0.5 + 0.05 = 0.6 m; T = S/v_w + S/v_l = 1.2 + 0.3 s
    assert kin.stroke == pytest.approx(0.6, abs=1e-15)
    assert kin.cycle == pytest.approx(1.5, rel=1e-15)
    assert kin.delay == kin.cycle
    assert kin.events() == pytest.approx((0.1, 1.1, 1.2, 1.5), rel=1e-14)
    assert kin.range == pytest.approx((0.55, 1.15), abs=1e-15)
    # another speed: T = 0.6/v + 0.6/2
    kf = ShapingKinematics(1.15, -1.0, 0.05, 0.5, 0.05, 0.25, 2.0)
    assert kf.cycle == pytest.approx(0.6 / 0.25 + 0.3, rel=1e-15)


def test_position_and_velocity_by_hand(kin):
    t = np.array([0.0, 0.05, 0.1, 0.6, 1.1, 1.15, 1.2, 1.35, 1.5, 1.5 + 0.6])
    s, v, cut, cd = kin.state(t)
    # work stroke towards -X at 0.5 m/s from s = 1.15, return at 2 m/s from s = 0.55
    s_hand = [1.15, 1.125, 1.10, 0.85, 0.60, 0.575, 0.55, 0.85, 1.15, 0.85]
    v_hand = [-0.5, -0.5, -0.5, -0.5, -0.5, -0.5, 2.0, 2.0, -0.5, -0.5]
    np.testing.assert_allclose(s, s_hand, atol=1e-12)
    np.testing.assert_allclose(v, v_hand, atol=0)
    # in the cut on [0.1, 1.1) (right-continuous: entry included, exit excluded)
    assert cut.tolist() == [False, False, True, True, False, False, False, False, False, True]
    np.testing.assert_allclose(cd[cut], [0.0, 0.25, 0.25], atol=1e-12)
    assert np.all(np.isnan(cd[~cut]))


def test_state_is_piecewise_linear_and_periodic(kin):
    rng = np.random.default_rng(1)
    t = rng.uniform(0.0, 10.0, 2000)
    s, v, cut, cd = kin.state(t)
    lo, hi = kin.range
    assert np.all((s >= lo - 1e-12) & (s <= hi + 1e-12))
    # ds/dt = v away from the events (a forward difference of a linear piece)
    dt = 1e-7
    s2, _, _, _ = kin.state(t + dt)
    ev = np.array(kin.events())
    far = (
        np.min(np.abs(np.mod(t, kin.cycle)[:, None] - np.concatenate([[0.0], ev])[None, :]), axis=1) > 2 * dt
    )
    np.testing.assert_allclose((s2 - s)[far] / dt, v[far], rtol=1e-6)
    # one cycle later: the same state (the delay T brings the tool back over the same point)
    s3, v3, cut3, cd3 = kin.state(t + kin.cycle)
    np.testing.assert_allclose(s3, s, atol=1e-12)
    assert np.array_equal(cut3[far], cut[far])
    # the distance in the cut is how far the slide has travelled since the entry
    np.testing.assert_allclose(cd[cut], np.abs(s[cut] - (kin.start - 0.05)), atol=1e-12)
    assert np.all((cd[cut] >= 0) & (cd[cut] < kin.cut))


def test_breakpoints_are_the_events_of_every_cycle(kin):
    bp = np.array(kin.breakpoints(3.0))
    expect = np.sort(np.concatenate([np.array(kin.events()) + k * kin.cycle for k in range(2)]))
    np.testing.assert_allclose(bp, expect[expect <= 3.0], atol=1e-12)
    assert np.all(np.diff(bp) > 0)


@pytest.mark.parametrize(
    "params, unit",
    [
        ((0.05, 0.5, 0.05, 0.5, 2.0), 0.1),  # the paper's stroke: events 0.1, 1.1, 1.2, 1.5 s
        ((0.03, 0.41, 0.07, 0.37, 1.9), 1.0 / 7030.0),  # 3/37, 44/37, 51/37, 51/37 + 51/190 s
        ((0.0, 0.5, 0.0, 0.5, 2.0), 0.25),  # no run-in, no coasting: 1.0, 1.25 s
    ],
)
def test_grid_unit_puts_every_event_on_the_step_grid(params, unit):
    k = ShapingKinematics(0.0, 1.0, *params)
    u = k.grid_unit
    assert u == pytest.approx(unit, rel=1e-9)
    for e in k.events():
        assert abs(e / u - round(e / u)) < 1e-9 * max(1.0, e / u)
    # the step simulate() picks: unit / ceil(unit / h) for any h
    for h in (1e-4, 2.1e-4, 1.4e-3):
        step = u / math.ceil(u / h)
        assert step <= h
        for e in k.events():
            assert abs(e / step - round(e / step)) < 1e-6


def test_incommensurate_events_keep_the_cycle_on_the_grid():
    k = ShapingKinematics(0.0, 1.0, 0.05, 0.5 / math.sqrt(2.0), 0.05, 0.5, 2.0)
    assert k.grid_unit == k.cycle


@pytest.mark.parametrize("n_per_unit", [1, 7, 493, 500, 4999])
def test_state_is_right_continuous_on_the_step_grid(kin, n_per_unit):
    """A step k h meant to land on an event sees the state after it, even
    when k h rounds to one unit in the last place below the event time."""
    h = kin.grid_unit / n_per_unit
    for c in range(3):
        for e, (cut_after, v_after) in zip(
            kin.events(), [(True, -0.5), (False, -0.5), (False, 2.0), (False, -0.5)], strict=True
        ):
            k = round((c * kin.cycle + e) / h)
            s, v, cut, _ = kin.state(np.array([k * h]))
            assert bool(cut[0]) is cut_after and v[0] == v_after, (c, e, k * h)
            # and just before it, the state before the event
            s, v, cut, _ = kin.state(np.array([k * h - 1e-9 * h]))
            assert bool(cut[0]) is (e == kin.events()[1]), (c, e)


def test_default_step_lands_on_the_events(shaper, kin):
    from chatterlab.time._simulate import simulate

    sim = simulate(shaper, feedback="none", duration=0.2)
    for e in kin.events():
        assert abs(e / sim.step - round(e / sim.step)) < 1e-9
    # the tool enters the cut exactly on a step and the force is off before it
    assert sim.response.attrs["breakpoints"][0] == pytest.approx(0.1, abs=1e-12)
    before = sim.t < 0.1 - 1e-12
    assert np.all(sim.data["rfe5.x"][before] == 0.0)
    assert np.any(sim.data["rfe5.x"][~before] != 0.0)


def test_steady_kinematics():
    k = SteadyKinematics(0.85, 0.02)
    s, v, cut, cd = k.state(np.linspace(0, 1, 11))
    assert np.all(s == 0.85) and np.all(v == 0) and np.all(cut) and np.all(np.isnan(cd))
    k0 = SteadyKinematics(None, 0.02)
    assert np.all(np.isnan(k0.state(np.zeros(3))[0]))


def test_kinematics_for(shaper):
    proc = shaper.model.process
    assert isinstance(kinematics_for(proc), ShapingKinematics)
    assert kinematics_for(proc, speed=0.25).delay == pytest.approx(0.6 / 0.25 + 0.3)
    held = kinematics_for(proc, position=0.85)
    assert isinstance(held, SteadyKinematics) and held.delay == pytest.approx(1.5)
    given = kinematics_for(proc, delay=0.01)
    assert isinstance(given, SteadyKinematics) and given.delay == 0.01 and given.position is None
    with pytest.raises(InputError, match="speed must be > 0"):
        kinematics_for(proc, speed=-1.0)
    with pytest.raises(InputError, match="speed must be > 0"):
        kinematics_for(proc, speed=0.0)
    with pytest.raises(InputError, match="either the speed or the delay"):
        kinematics_for(proc, speed=0.5, delay=0.1)
    with pytest.raises(InputError, match="delay must be > 0"):
        kinematics_for(proc, delay=-0.1)
    with pytest.raises(InputError, match="no \\[process\\]"):
        kinematics_for(None)


def test_contact_point_waits_at_the_workpiece_end(shaper):
    """rfe5 (outside = "clamp") sits at the workpiece end during run-in and
    coasting: its rows of W do not change there and dW/ds is zero, while
    rfe6 keeps following the slide along the shear."""
    d = list(shaper.d)
    r5 = [d.index(shaper.index[f"rfe5.{a}"]) for a in ("x", "y", "rz")]
    r6 = [d.index(shaper.index[f"rfe6.{a}"]) for a in ("x", "y", "rz")]
    # the workpiece runs from X = 0.60 to 1.10: run-in is s in (1.10, 1.15], coasting [0.55, 0.60)
    for s_end, s_outside in (([1.10, 1.12, 1.15], [1.12, 1.15]), ([0.60, 0.58, 0.55], [0.58, 0.55])):
        W = shaper.W(np.array(s_end))
        np.testing.assert_array_equal(W[1:][:, r5], np.broadcast_to(W[0, r5], W[1:][:, r5].shape))
        assert not np.allclose(W[0, r6], W[1, r6])
        assert np.all(shaper.W(np.array(s_outside), order=1)[:, r5] == 0.0)
        assert np.all(shaper.W(np.array(s_outside), order=2)[:, r5] == 0.0)
    # on the workpiece the contact moves: W' is not zero
    assert np.any(shaper.W(0.85, order=1)[r5] != 0.0)
