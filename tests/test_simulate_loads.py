"""External loads and prescribed motion of given coordinates in the time
domain (Eq. 2.19), against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.time import Excitation, Integration
from chatterlab.time._simulate import simulate

M, K, C = 1.0, 1.0e7, 189.7  # the shared 1-DOF tool: 503.3 Hz, zeta = 3 %


@pytest.fixture(scope="module")
def system():
    return cl.assemble(cl.loads_model(turning_text(mass=M, stiffness=K, damping=C)))


def _steady_amplitude(sim, name: str, w: float) -> float:
    """Amplitude of the last 20 periods by least squares on sin/cos."""
    t, x = sim.t, sim.data[name]
    m = t >= t[-1] - 20 * 2 * np.pi / w
    A = np.column_stack([np.sin(w * t[m]), np.cos(w * t[m]), np.ones(m.sum())])
    c = np.linalg.lstsq(A, x[m], rcond=None)[0]
    return float(np.hypot(c[0], c[1]))


def _warped(w: float, h: float) -> float:
    """Average-acceleration Newmark answers a harmonic input of frequency w
    exactly as the continuous system answers (2/h) tan(w h / 2)."""
    return 2.0 / h * np.tan(w * h / 2.0)


def test_harmonic_load_gives_the_receptance(system):
    w, F, h = 2 * np.pi * 400.0, 100.0, 2e-5
    sim = simulate(
        system,
        feedback="none",
        delay=0.01,
        position=None,
        outputs=["tool.x"],
        integration=Integration(duration=0.4, step=h),
        excitation=Excitation(cutting_forces=False, loads={"tool.x": lambda t: F * np.sin(w * t)}),
    )
    wt = _warped(w, h)
    exact = F / abs(K - M * wt**2 + 1j * C * wt)
    # 20 periods after 0.3 s: the free transient (decay 95 1/s) is below 1e-12 of it
    assert _steady_amplitude(sim, "tool.x", w) == pytest.approx(exact, rel=1e-6)


def test_base_excitation_gives_the_transmissibility(system):
    w, Y, h = 2 * np.pi * 300.0, 1e-6, 2e-5

    def ground(t):
        return Y * np.sin(w * t), Y * w * np.cos(w * t), -Y * w**2 * np.sin(w * t)

    sim = simulate(
        system,
        feedback="none",
        delay=0.01,
        outputs=["tool.x"],
        integration=Integration(duration=0.4, step=h),
        excitation=Excitation(cutting_forces=False, ground_motion={"ground.x": ground}),
    )
    wt = _warped(w, h)
    # m x'' + c (x' - y') + k (x - y) = 0: |X / Y| = |k + j c w| / |k - m w^2 + j c w|
    exact = Y * abs(K + 1j * C * wt) / abs(K - M * wt**2 + 1j * C * wt)
    assert _steady_amplitude(sim, "tool.x", w) == pytest.approx(exact, rel=1e-6)


def test_ground_motion_reaches_the_cut_through_the_coupling(system):
    """The regenerative coupling to the ground sees the ground's motion
    (Eq. 2.27).  With y(t) = Y (1 - cos wt) for t >= 0 (at rest before), the
    relative coordinate z = x - y obeys
        m z'' + c z' + k z = -m y'' - K_f b [z(t) - z(t - T)],
    i.e. the same closed loop without ground motion under the load -m y''.
    The two runs differ only by Newmark's O(h^2) error on the sampled y:
    the difference must be second order in h."""
    w, Y, T = 2 * np.pi * 300.0, 1e-6, 0.01

    def ground(t):
        on = t >= 0  # right-continuous at the start, as the integrator expects
        c, s_ = np.cos(w * t), np.sin(w * t)
        return np.where(on, Y * (1 - c), 0.0), np.where(on, Y * w * s_, 0.0), np.where(on, Y * w**2 * c, 0.0)

    def gap(h: float) -> tuple[float, float, object]:
        common = dict(delay=T, outputs=["tool.x"], width=2e-4, integration=Integration(duration=0.1, step=h))
        moved = Excitation(cutting_forces=False, ground_motion={"ground.x": ground})
        a = simulate(system, feedback="pdo", excitation=moved, **common)
        z = a.data["tool.x"] - ground(a.t)[0]
        pushed = Excitation(cutting_forces=False, loads={"tool.x": lambda t: -M * ground(t)[2]})
        b = simulate(system, feedback="pdo", excitation=pushed, **common)
        return float(np.max(np.abs(z - b.data["tool.x"]))), float(np.max(np.abs(z))), a

    g1, zmax, a = gap(2e-5)
    g2, _, _ = gap(1e-5)
    # measured 2.4e-4 and 6.0e-5 of max|z| ((w h)^2 / 12 = 1.2e-4 and 3.0e-5)
    assert g1 < 1e-3 * zmax
    assert 3.5 < g1 / g2 < 4.5  # second order
    # and the ground terms of the coupling matter: without the cut the answer differs
    c = simulate(
        system,
        feedback="none",
        delay=T,
        outputs=["tool.x"],
        width=0.0002,
        excitation=Excitation(ground_motion={"ground.x": ground}, cutting_forces=False),
        integration=Integration(duration=0.1, step=2e-05),
    )
    assert np.max(np.abs(c.data["tool.x"] - a.data["tool.x"])) > 0.05 * zmax


def test_bad_loads_and_ground_motion(system):
    with pytest.raises(InputError, match="not a given coordinate"):
        simulate(
            system,
            feedback="none",
            delay=0.01,
            integration=Integration(duration=0.01),
            excitation=Excitation(ground_motion={"tool.x": lambda t: (t, t, t)}),
        )
    with pytest.raises(InputError, match="unknown point"):
        simulate(
            system,
            feedback="none",
            delay=0.01,
            integration=Integration(duration=0.01),
            excitation=Excitation(loads={"nowhere.x": lambda t: t}),
        )
    with pytest.raises(InputError, match=r"\(q, q_dot, q_ddot\)"):
        simulate(
            system,
            feedback="none",
            delay=0.01,
            integration=Integration(duration=0.01),
            excitation=Excitation(ground_motion={"ground.x": lambda t: t}),
        )
