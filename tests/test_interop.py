"""python-control interop: an LTI system standing in for the structure gives
the same lobes and closed-loop response as the equivalent model, with the
exact delay (python-control has only Pade approximations)."""

from __future__ import annotations

import control  # a dependency of chatterlab (pyproject): an import error fails, never skips
import numpy as np
import pytest
from conftest import turning_text

import chatterlab as cl
from chatterlab.errors import InputError
from chatterlab.frequency._frf import frequencies, frf
from chatterlab.lobes._control import closed_loop_lti, coupling_matrices, lobes_lti, lti_plant
from chatterlab.lobes._diagram import lobes
from chatterlab.process import closed_loop

MASS, STIFF, DAMP, KF = 2.0, 2.0e7, 400.0, 2.0e9
TURNING = turning_text(mass=MASS, stiffness=STIFF, damping=DAMP, Kf=KF)


@pytest.fixture(scope="module")
def turning():
    m = cl.loads_model(TURNING)
    return m, cl.assemble(m).at()


@pytest.mark.parametrize("form", ["tf", "ss"])
def test_lti_lobes_equal_model_lobes(turning, form):
    m, fz = turning
    rpm = np.linspace(2500.0, 11000.0, 150)
    ref = lobes(fz, rpm, width_max=0.05, verify=0)
    sys = control.tf([1.0], [MASS, DAMP, STIFF])
    if form == "ss":
        sys = control.tf2ss(sys)
    DP, DV, DO, bref = coupling_matrices(m.couplings[0])
    got = lobes_lti(sys, rpm, process=m.process, DP=DP, DV=DV, DO=DO, width_ref=bref, width_max=0.05)
    # both are the same exact boundary, refined to round-off: agreement ~1e-12 measured
    assert np.max(np.abs(got.b_lim / ref.b_lim - 1)) < 1e-9
    zeta = DAMP / (2 * np.sqrt(STIFF * MASS))
    assert got.absolute_minimum["width"] == pytest.approx(2 * STIFF * zeta * (1 + zeta) / KF, rel=1e-9)


def test_lti_closed_loop_equals_model_closed_loop(turning):
    m, fz = turning
    w = frequencies(300.0, 800.0, 200)
    fb = closed_loop(fz, width=5e-4, speed=6000.0)
    a = frf(fb, w, inputs="tool.x", outputs="tool.x")
    DP, DV, DO, bref = coupling_matrices(m.couplings[0])
    b = closed_loop_lti(
        control.tf([1.0], [MASS, DAMP, STIFF]),
        w,
        width=5e-4,
        delay=fb.delay,
        width_ref=bref,
        DP=DP,
        DV=DV,
        DO=DO,
    )
    # same algebra on a 1x1 system: agreement to round-off
    assert np.max(np.abs(a.data - b.data)) < 1e-12 * np.abs(a.data).max()


def test_two_dof_state_space_plant_matches_model():
    # a 2-DOF tool (x and y modes) cut by an oriented regenerative force
    text = """
[[body]]
id = "tool"
mass = 1.5
inertia = 1.0
centre = [0.0, 0.0]
[[support]]
body = "tool"
fix = ["rz"]
[[spring]]
id = "k"
a = "tool"
b = "ground"
c1 = 1.0e7
c2 = 2.5e7
d1 = 150.0
d2 = 300.0
[[coupling]]
id = "cut"
a = "tool"
b = "ground"
model = "regenerative"
Kf = 1.5e9
force_angle_deg = 70.0
normal_angle_deg = 30.0
width_ref = 0.001
[process]
kind = "turning"
rpm = 3000
"""
    m = cl.loads_model(text)
    fz = cl.assemble(m).at()
    rpm = np.linspace(3000.0, 9000.0, 80)
    ref = lobes(fz, rpm, width_max=0.05, verify=0)
    A = np.array(
        [[0, 0, 1, 0], [0, 0, 0, 1], [-1e7 / 1.5, 0, -150 / 1.5, 0], [0, -2.5e7 / 1.5, 0, -300 / 1.5]]
    )
    B = np.array([[0, 0], [0, 0], [1 / 1.5, 0], [0, 1 / 1.5]])
    C = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    ss = control.ss(A, B, C, np.zeros((2, 2)))
    DP, DV, DO, bref = coupling_matrices(m.couplings[0])
    got = lobes_lti(
        ss,
        rpm,
        process=m.process,
        DP=DP[:2, :2],
        DV=DV[:2, :2],
        DO=DO[:2, :2],
        width_ref=bref,
        width_max=0.05,
    )
    fin = np.isfinite(ref.b_lim)
    assert fin.any()
    assert np.max(np.abs(got.b_lim[fin] / ref.b_lim[fin] - 1)) < 1e-8


def test_bad_lti_input():
    with pytest.raises(InputError, match="as many inputs as outputs"):
        lti_plant(control.ss(-1.0, [[1.0, 1.0]], [[1.0]], [[0.0, 0.0]]), DO=[[1.0]], width_ref=1e-3)
    with pytest.raises(InputError, match="expected a python-control LTI"):
        lti_plant("not a system", DO=[[1.0]], width_ref=1e-3)
    with pytest.raises(InputError, match="DO must be 1x1"):
        lti_plant(control.tf([1.0], [1.0, 1.0, 1.0]), DO=np.eye(2), width_ref=1e-3)
    with pytest.raises(InputError, match="width_ref"):
        lti_plant(control.tf([1.0], [1.0, 1.0, 1.0]), DO=[[1.0]], width_ref=0.0)
