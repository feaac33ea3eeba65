"""Modal models ([[mode]] tables): the receptance is the modal sum, and bad
tables get one line naming the field (issue 12, item 2)."""

from __future__ import annotations

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.errors import ModelError

MODAL = """
[[mode]]
id = "x1"
frequency_hz = 922.0
damping_ratio = 0.011
mass = 0.03993
direction = "tool.x"

[[mode]]
id = "x2"
frequency_hz = 1450.0
damping_ratio = 0.03
stiffness = 4.0e6
direction = "tool.x"

[[mode]]
id = "y1"
frequency_hz = 1100.0
damping_ratio = 0.02
stiffness = 2.0e6
shape = { "tool.y" = 1.0, "tool.x" = 0.3 }

[[point]]
id = "tip"
coords = { x = "tool.x", y = "tool.y" }

[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = 6e8
force_angle_deg = 20

[process]
kind = "turning"
rpm = 10000
"""


def _modal_sum(omega: np.ndarray, i: str, j: str) -> np.ndarray:
    """Ewins (2000) eq. 2.58: H_ij = sum_k phi_ik phi_jk / (k_k - w^2 m_k + j w c_k)."""
    modes = [  # (f_hz, zeta, k or None, m or None, shape)
        (922.0, 0.011, None, 0.03993, {"tool.x": 1.0}),
        (1450.0, 0.03, 4.0e6, None, {"tool.x": 1.0}),
        (1100.0, 0.02, 2.0e6, None, {"tool.y": 1.0, "tool.x": 0.3}),
    ]
    H = np.zeros(omega.shape, complex)
    for f, z, k, m, shape in modes:
        wn = 2 * np.pi * f
        k = k if k is not None else m * wn**2
        m = k / wn**2
        H += shape.get(i, 0.0) * shape.get(j, 0.0) / (k - omega**2 * m + 2j * z * np.sqrt(k * m) * omega)
    return H


def test_receptance_is_the_modal_sum():
    frozen = cl.assemble(cl.loads_model(MODAL)).at()
    omega = 2 * np.pi * np.linspace(0.0, 3000.0, 301)
    spec = {"x": "tip.x", "y": "tip.y"}
    r = cl.frf(frozen, omega, inputs=list(spec.values()), outputs=list(spec.values()))
    for a, i in enumerate(spec):
        for b, j in enumerate(spec):
            ref = _modal_sum(omega, f"tool.{i}", f"tool.{j}")
            got = r.data[a, b]
            # a 3x3 diagonal solve per frequency: round-off ~ cond * eps, cond <= k_max / (2 zeta k_min) ~ 1e3
            np.testing.assert_allclose(got, ref, rtol=1e-11, atol=1e-11 * np.abs(ref).max())


def test_natural_frequencies_and_damping_are_the_table():
    md = cl.modes(cl.assemble(cl.loads_model(MODAL)).at())
    np.testing.assert_allclose(np.sort(md.omega / (2 * np.pi)), [922.0, 1100.0, 1450.0], rtol=1e-12)


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        ("stiffness = 4.0e6", "stiffness = -4.0e6"),
        ("mass = 0.03993", "mass = 0.0"),
        ("damping_ratio = 0.03", "damping_ratio = 1.5"),
        ("frequency_hz = 1450.0", "frequency_hz = 0.0"),
        ('shape = { "tool.y" = 1.0, "tool.x" = 0.3 }', 'shape = { "tool.y" = 0.0 }'),
        ("mass = 0.03993", "mass = 0.03993\nstiffness = 1.0e6"),
    ],
)
def test_bad_mode_tables_name_the_field(edit, field):
    text = MODAL.replace(edit, field, 1)
    with pytest.raises(ModelError) as e:
        cl.loads_model(text)
    msg = str(e.value)
    assert "\n" not in msg and "mode." in msg
    name = field.split("=")[0].strip().split("\n")[0]
    assert name in msg or "stiffness" in msg


def test_a_point_naming_an_unknown_shape_coordinate():
    with pytest.raises(ModelError, match=r"tool\.z.*not in the \[\[mode\]\] shapes"):
        cl.loads_model(MODAL.replace('coords = { x = "tool.x", y = "tool.y" }', 'coords = { x = "tool.z" }'))


def test_modal_and_matrices_do_not_mix():
    extra = '\n[matrices]\ncoordinates = ["q"]\nM = [[1.0]]\nK = [[1.0]]\n'
    with pytest.raises(ModelError, match=r"cannot be combined with matrices"):
        cl.loads_model(MODAL + extra)


def test_an_undamped_mode_is_refused_by_the_lobes_not_a_crash():
    """A pole on the imaginary axis makes the receptance infinite there; the
    lobe engine says so in one line (it raised LinAlgError inside the
    boundary solver before)."""
    from chatterlab.errors import InputError
    from chatterlab.lobes import lobes

    fz = cl.assemble(cl.loads_model(MODAL.replace("damping_ratio = 0.011", "damping_ratio = 0.0"))).at()
    with pytest.raises(InputError, match=r"undamped or unstable mode at 922 Hz") as e:
        lobes(fz, np.linspace(5000.0, 9000.0, 5), width_max=0.005)
    assert "\n" not in str(e.value)
