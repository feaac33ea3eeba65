"""A structural model through the milling path (issue 12): a rigid tool on a
spring is the 1-DOF benchmark exactly, so its Floquet lobes from the
structural model file equal those of the modal model file; a beam model is
reduced to the modes that matter with its FRF error stated."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from conftest import turning_text

import chatterlab as cl
from chatterlab.lobes import milling_lobes, milling_loop_of, reduce_structure

ROOT = Path(__file__).resolve().parents[1]
ONE = ROOT / "studies" / "milling" / "benchmark_1dof.toml"
BEAM = ROOT / "studies" / "milling" / "tool_cantilever.toml"

M, F, Z = 0.03993, 922.0, 0.011
W = 2 * math.pi * F


def _rigid_tool(process: str) -> str:
    """conftest's 1-DOF tool (a body free along x on a spring-damper) with
    the benchmark's mass, stiffness and damping, cut by a milling coupling."""
    text = turning_text(mass=M, stiffness=M * W * W, damping=2 * Z * M * W)
    head = text[: text.index("[[coupling]]")]
    return head + '[[coupling]]\nid = "cut"\na = "tip"\nb = "ground"\nmodel = "milling"\n' + process


def test_rigid_tool_on_a_spring_is_the_modal_benchmark():
    text = ONE.read_text()
    process = text[text.index("\n[process]") :]
    structural = cl.loads_model(_rigid_tool(process))
    modal = cl.load_model(ONE)
    rpm = np.array([9000.0, 18000.0])
    a = [
        milling_lobes(milling_loop_of(cl.assemble(m).at()), rpm, depth_max=0.01) for m in (structural, modal)
    ]
    # the same 1-DOF equation in other coordinates: equal to Brent's tolerance (rtol 1e-8)
    np.testing.assert_allclose(a[0].a_lim, a[1].a_lim, rtol=2e-8)
    assert list(a[0].kind) == list(a[1].kind)


def test_beam_tool_is_reduced_with_its_error_stated():
    fz = cl.assemble(cl.load_model(BEAM)).at()
    S = milling_loop_of(fz)
    R, info = reduce_structure(S)
    assert R.n < S.n and info.kept == 3 and info.rigid == 1  # the planar tool's axis held rigid
    # the reported error is the reduced FRF's against the full structure's, both directions
    w = 2 * np.pi * np.linspace(0.0, info.f_keep / 2, 400)
    err = np.max(np.abs(S.frf(w) - R.frf(w))) / np.max(np.abs(S.frf(w)))
    assert info.frf_error == err and err < 1e-3
    # the first bending modes are kept exactly (a Ritz basis holding them)
    lam_full = np.sort(np.abs(np.linalg.eigvals(S.state_matrix).imag))
    lam_red = np.sort(np.abs(np.linalg.eigvals(R.state_matrix).imag))
    f1 = lam_full[lam_full > 0][0]
    assert abs(lam_red[lam_red > 0][0] - f1) < 1e-6 * f1


def test_matrix_level_model_is_the_modal_benchmark():
    """The 2-DOF benchmark written as [matrices] (x and y coordinates, M, L, K) gives the modal
    file's multipliers: the same equation, so the same numbers to round-off."""
    from chatterlab.frequency import multipliers

    modal = cl.load_model(ROOT / "studies" / "milling" / "benchmark_2dof.toml")
    k, c = M * W * W, 2 * Z * M * W
    text = modal.text[modal.text.index("\n[process]") :]
    matrices = f"""
[matrices]
coordinates = ["tx", "ty"]
M = [[{M!r}, 0.0], [0.0, {M!r}]]
L = [[{c!r}, 0.0], [0.0, {c!r}]]
K = [[{k!r}, 0.0], [0.0, {k!r}]]

[[point]]
id = "tip"
coords = {{ x = "tx", y = "ty" }}

[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "milling"
"""
    mat = cl.loads_model(matrices + text)
    r = [multipliers(milling_loop_of(cl.assemble(m).at()), 12000.0, 1e-3) for m in (mat, modal)]
    # the modal file's modal mass is k / w^2 = M to within one rounding of (2 pi 922)^2: a few ulp
    assert abs(r[0].spectral_radius - r[1].spectral_radius) < 1e-12
    assert r[0].kind == r[1].kind
