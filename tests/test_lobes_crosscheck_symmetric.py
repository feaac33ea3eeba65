"""Symmetric tools against routes that know nothing of the lobe engine (issue 18,
part 3), in the style of tests/test_lobes_crosscheck.py.

For every envelope point b_lim(T) the rightmost characteristic root
(spectral collocation + Newton) lies left of the axis at (1 - 1e-6) b_lim
and right of it at (1 + 1e-6) b_lim, and the argument principle counts no
root right of the axis at 0.5 b_lim; every ``inf`` is confirmed at the width
ceiling by both (``_check_diagram`` of test_lobes_crosscheck, whose
tolerance argument holds here: the critical root moves by
~1e-6 b dsigma/db ~ 1e-5 1/s, the roots are Newton-exact to ~1e-10 1/s).
Symmetric tools have double roots, so the count at 0.5 b_lim is taken where
the old sampling of the phase could alias a 2 pi turn.

The tools (modal models, D_P = -D_O in the tool plane):

* identical modes in x and y, D_O = -K_f I (the loop decouples into two
  equal 1-DOF loops, computed once);
* the same with k_y = 1.001 k_x (two 1-DOF loops);
* identical modes along axes at 30 deg to x (the commutant finds the rotated
  blocks);
* modes at 30 deg with k_y = 1.001 k_x and an anisotropic cut (D_O = -K_f
  diag(1, 1.001)): it does not decouple, the rank-two resultant is searched
  with its near-double widths;
* a round tool under a swirling cut, D_O = -K_f (I + 0.3 J) with J the
  quarter turn: equal modes, but the eigenvalues of D_O are a complex pair,
  so the blocks are not split and the two families are distinct.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_lobes_crosscheck import _check_diagram

import chatterlab as cl
from chatterlab.lobes._diagram import lobes

K = 1.0e7
ZETA = 0.02
FN = 100.0
KFW = 2.0e6  # K_f at width_ref = 1 mm, N/m


def _tool(angle_deg: float, asym: float, DO: np.ndarray) -> str:
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    ky = K * (1 + asym)

    def rows(X: np.ndarray) -> str:
        Z = np.zeros((3, 3))
        Z[:2, :2] = X
        return "[" + ", ".join("[" + ", ".join(repr(float(x)) for x in r) + "]" for r in Z) + "]"

    return f"""
[model]
name = "symmetric tool {angle_deg} deg, asymmetry {asym}"
[[mode]]
id = "u1"
frequency_hz = {FN!r}
damping_ratio = {ZETA!r}
stiffness = {K!r}
shape = {{ "tool.x" = {c!r}, "tool.y" = {s!r} }}
[[mode]]
id = "u2"
frequency_hz = {FN * math.sqrt(1 + asym)!r}
damping_ratio = {ZETA / math.sqrt(1 + asym)!r}
stiffness = {ky!r}
shape = {{ "tool.x" = {-s!r}, "tool.y" = {c!r} }}
[[point]]
id = "tip"
coords = {{ x = "tool.x", y = "tool.y" }}
[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "matrices"
width_ref = 0.001
DP = {rows(-DO)}
DO = {rows(DO)}
[process]
kind = "turning"
rpm = 8250.0
"""


I2 = np.eye(2)
J = np.array([[0.0, -1.0], [1.0, 0.0]])
TOOLS = {
    "symmetric": (0.0, 0.0, -KFW * I2),
    "0.1% asymmetric": (0.0, 1e-3, -KFW * I2),
    "symmetric, rotated 30 deg": (30.0, 0.0, -KFW * I2),
    "0.1% asymmetric, rotated, anisotropic cut": (30.0, 1e-3, -KFW * np.diag([1.0, 1.001])),
    "round tool, swirling cut": (0.0, 0.0, -KFW * (I2 + 0.3 * J)),
}


@pytest.mark.parametrize("name", list(TOOLS))
def test_symmetric_tool_envelope_equals_bisection(name):
    fz = cl.assemble(cl.loads_model(_tool(*TOOLS[name]))).at()
    rpm = np.linspace(2000.0, 12000.0, 9)
    d = lobes(fz, rpm, width_max=0.02)
    assert d.band_certified
    assert all(c["agrees"] for c in d.checks), d.checks
    n_fin, _ = _check_diagram(fz, d)
    assert n_fin == rpm.size
