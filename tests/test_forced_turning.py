"""Turning: the forced response to an eccentric workpiece (chatterlab.frequency
runout_response), a harmonic force K_f h_0 e at the spindle frequency Omega
through the regenerative closed loop.

The 1-DOF closed form (chatterlab.frequency._forced, Eq. 5):
X(w) = G(i w) F / (1 + b K_f (1 - e^{-i w T}) G(i w)), G = 1/(k - m w^2 + i c w);
at w = Omega, Omega T = 2 pi, so the delay term vanishes: the runout repeats
every revolution and is not regenerated, |X| = K_f h_0 e |G(i Omega)|.
Checked against the closed loop's FRF (the loop's own delay term in it, away
from Omega) and against a Newmark simulation of the loop, whose steady
amplitude converges to it at order 2; and runout_response's own complex
result (amplitude and phase) against the simulated steady state of a loop
with process damping, whose term at Omega it keeps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.frequency import frf, runout_response
from chatterlab.time import Excitation, Integration

MASS, STIFF, DAMP, KF = 1.0, 1.0e7, 189.7, 2.0e9  # turning_text's defaults
B, E, H0 = (
    2e-4,
    20e-6,
    1e-4,
)  # width of cut (stable at 3000 rpm: its roots have Re < -33 1/s), eccentricity, feed


def G(w: np.ndarray | float) -> np.ndarray:
    return 1.0 / (STIFF - MASS * np.asarray(w) ** 2 + 1j * DAMP * np.asarray(w))


@pytest.fixture(scope="module")
def system():
    return cl.assemble(cl.loads_model(turning_text(), source="turning.toml"))


def test_runout_is_not_regenerated(system) -> None:
    rpm = np.array([1500.0, 3000.0, 4500.0, 6000.0])
    loop = cl.closed_loop(system.at(), width=B, speed=3000.0)
    r = runout_response(loop, rpm, E, H0, KF, inputs="tip.x", outputs="tip.x")
    Om = 2 * np.pi * rpm / 60.0
    closed = KF * H0 * E * np.abs(G(Om))
    # one linear solve per speed against the same formula: round-off (the solve's ~1e-15
    # times the condition of k - m w^2 + i c w near resonance, < 1e3 here)
    np.testing.assert_allclose(r.amplitude, closed, rtol=1e-12)
    # the loop is closed: away from Omega its delay term is in the FRF, as Eq. (5) says
    T = 60.0 / 3000.0
    w = 1.1 * 2 * np.pi * 3000.0 / 60.0
    H = frf(loop, np.array([w]), inputs="tip.x", outputs="tip.x").data[0, 0, 0]
    loop_cf = G(w) / (1 + KF * B * (1 - np.exp(-1j * w * T)) * G(w))
    assert abs(H - loop_cf) <= 1e-12 * abs(loop_cf)
    assert abs(loop_cf - G(w)) > 1e-3 * abs(G(w))  # ... and differs from the open loop's there


def test_runout_response_equals_the_simulated_steady_state_at_order_two(system) -> None:
    n, F = 3000.0, KF * H0 * E
    Om = 2 * np.pi * n / 60.0
    X = F * abs(G(Om))
    errors = []
    steps = (4e-4, 2e-4, 1e-4)
    for h in steps:
        sim = cl.simulate(
            system, width=B, speed=n, outputs="tip.x", integration=Integration(duration=3.0, step=h),
            excitation=Excitation(cutting_forces=False, loads={"tip.x": lambda t: F * np.cos(Om * t)}),
        )  # fmt: skip
        x = np.asarray(sim.history("tip.x"))
        # after 2 s the transient (decay rate >= 33 1/s, the loop's abscissa) is below e^-66
        sel = sim.t > 2.0
        A = np.c_[np.cos(Om * sim.t[sel]), np.sin(Om * sim.t[sel]), np.ones(sel.sum())]
        c = np.linalg.lstsq(A, x[sel], rcond=None)[0]
        errors.append(abs(math.hypot(c[0], c[1]) - X) / X)
    order = np.log2(errors[0] / errors[1]), np.log2(errors[1] / errors[2])
    # Newmark's average acceleration: second order (its period error (w h)^2/12)
    assert all(1.8 <= o <= 2.2 for o in order), (order, errors)
    assert errors[-1] < 1e-5


def test_bad_input(system) -> None:
    loop = cl.closed_loop(system.at(), width=B, speed=3000.0)
    with pytest.raises(InputError, match="eccentricity"):
        runout_response(loop, [3000.0], -1.0, H0, KF, inputs="tip.x", outputs="tip.x")
    with pytest.raises(InputError, match="spindle speed"):
        runout_response(loop, [0.0], E, H0, KF, inputs="tip.x", outputs="tip.x")


def test_a_chattering_turning_cut_gets_no_response(system) -> None:
    """b = 2 mm is above the unconditional limit 2 zeta (1 + zeta) k / K_f = 0.31 mm
    (zeta = c / (2 sqrt(k m)) = 0.030): at 3000 rpm it chatters."""
    loop = cl.closed_loop(system.at(), width=2e-3, speed=3000.0)
    r = runout_response(loop, [3000.0], E, H0, KF, inputs="tip.x", outputs="tip.x")
    assert r.verdict == ["unstable"] and math.isnan(r.amplitude[0])


def test_runout_response_amplitude_and_phase_are_the_simulated_steady_state_with_process_damping() -> None:
    """The second route for the API's own result: runout_response's complex response
    X = |X| e^{i phase} against the steady state of a Newmark simulation of the same model
    (studies/process_damping.py, C_pd = 2e5 N/m) under the force F cos(Omega t), at 0.9 of the
    natural frequency where the phase is well away from 0.  With process damping the loop keeps
    the term i Omega b C_pd / V at Omega (the delay's vanishes): X differs from the open
    structure's F G(i Omega) by 4e-4 relative, so the comparison sees the loop, not only G.

    The fitted complex amplitude approaches X at Newmark's order 2 (measured 2.01, 2.00), and
    Richardson's (4 X(h/2) - X(h)) / 3 removes the h^2 term: what is left is the scheme's
    (omega h)^4 term, (0.028)^4 = 6e-7, times the response's sensitivity to frequency near
    the resonance, d ln|G| / d ln omega = 2 r^2 / (1 - r^2) = 8.5 at r = 0.9: 5e-6, asserted
    with 2e-5, twenty times below the process-damping term it must resolve."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(
        "process_damping_study", Path(__file__).resolve().parents[1] / "studies" / "process_damping.py"
    )
    st = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(st)
    model = cl.assemble(cl.loads_model(st.model_text(st.C_PD), source="turning_pd.toml"))
    b = 2e-4  # below the unconditional limit 2 zeta (1 + zeta) k / K_f = 0.65 mm
    wn = math.sqrt(st.STIFF / st.MASS)
    n = 0.9 * wn * 60.0 / (2.0 * math.pi)
    Om = 2.0 * math.pi * n / 60.0
    loop = cl.closed_loop(model.at(), width=b, speed=n)
    r = runout_response(loop, [n], E, H0, st.KF, inputs="tool.x", outputs="tool.x")
    assert r.verdict == ["stable"]
    X = r.amplitude[0] * np.exp(1j * r.phase[0])
    open_loop = r.force / (st.STIFF - st.MASS * Om**2 + 1j * st.DAMP * Om)
    assert abs(X - open_loop) >= 10 * 2e-5 * abs(X)  # the loop's term is there to be seen (4e-4)
    fitted = []
    for h in (4e-5, 2e-5, 1e-5):
        sim = cl.simulate(
            model, width=b, speed=n, outputs="tool.x", integration=Integration(duration=0.4, step=h),
            excitation=Excitation(cutting_forces=False, loads={"tool.x": lambda t: r.force * np.cos(Om * t)}),
        )  # fmt: skip
        assert sim.meta["process_damping"].startswith("linear")
        # after 0.25 s the transient (decay rate >= zeta omega_n = 100 1/s) is below e^-25
        sel = sim.t > 0.25
        x = np.asarray(sim.history("tool.x"))[sel]
        A = np.c_[np.cos(Om * sim.t[sel]), np.sin(Om * sim.t[sel]), np.ones(sel.sum())]
        c = np.linalg.lstsq(A, x, rcond=None)[0]
        fitted.append(c[0] - 1j * c[1])  # x = Re(X e^{i Omega t}) = c0 cos + c1 sin
    err = [abs(v - X) / abs(X) for v in fitted]
    order = np.log2(err[0] / err[1]), np.log2(err[1] / err[2])
    assert all(1.8 <= o <= 2.2 for o in order), (order, err)
    rich = (4 * fitted[2] - fitted[1]) / 3
    assert abs(rich - X) <= 2e-5 * abs(X), (rich, X)
