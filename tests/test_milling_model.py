"""Milling in the model file: [process] kind = "milling" and the
model = "milling" coupling (issue 12, items 1 and 7; bad input)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.errors import ModelError
from chatterlab.process import Milling

ROOT = Path(__file__).resolve().parents[1]
ONE = ROOT / "studies" / "milling" / "benchmark_1dof.toml"
TWO = ROOT / "studies" / "milling" / "benchmark_2dof.toml"


def _cutter(model: cl.Model) -> Milling:
    c = model.process.milling
    return Milling(c.teeth, c.diameter, c.Kt, c.Kn, c.entry, c.exit, pitch=c.pitch)


def test_down_milling_angles_are_insperger_stepan():
    """Down-milling at a_e/D: phi_st = arccos(2 a_e/D - 1), phi_ex = pi (Insperger & Stepan 2004)."""
    c = cl.load_model(ONE).process.milling
    assert c.entry == pytest.approx(math.acos(2 * 0.05 - 1), rel=1e-15)
    assert c.exit == math.pi


def test_coupling_is_the_average_of_the_periodic_matrix():
    """A milling model's coupling feeds the frequency-domain engines the
    cutter's averaged directional matrix (chatterlab.process.Milling.zoa, its
    closed form) at the depth of cut, D_P = a_p H0 and D_O = -a_p H0 in the
    feed/normal plane, and that is the mean of H(t) over a period by quadrature."""
    from chatterlab.process import closed_loop

    m = cl.load_model(TWO)
    mill = _cutter(m)
    a_p = 2e-3
    loop = closed_loop(cl.assemble(m).at(), width=a_p, speed=10000.0)
    np.testing.assert_array_equal(loop.Dl_P[:2, :2], a_p * mill.zoa())
    np.testing.assert_array_equal(loop.Dl_O[:2, :2], -a_p * mill.zoa())
    assert not np.any(loop.Dl_P[2]) and not np.any(loop.Dl_P[:, 2]) and not np.any(loop.Dl_V)
    H0_model = loop.Dl_P[:2, :2] / a_p
    # midpoint rule over one tooth period of the piecewise-smooth H(t): error ~ jumps * dt / period,
    # two jumps of |H| <= (Kt + Kn) per period at 2e5 points: < 1e-5 relative
    rpm = 10000.0
    tau = mill.tooth_period(rpm)
    n = 200_000
    t = (np.arange(n) + 0.5) * tau / n
    Hm = mill.directional(t, rpm).sum(axis=1).mean(axis=0)
    np.testing.assert_allclose(Hm, H0_model, atol=2 * 2 * (6e8 + 2e8) / n)


def test_delay_is_the_tooth_period():
    p = cl.load_model(ONE).process
    assert p.speed_unit == "rpm"
    assert p.delay(10000.0) == pytest.approx(60 / (2 * 10000), rel=1e-15)
    assert p.speed_for_delay(p.delay(7321.0)) == pytest.approx(7321.0, rel=1e-14)


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("teeth = 2", "teeth = 0", "teeth"),
        ("teeth = 2", "teeth = 2.5", "teeth"),
        ("radial_immersion = 0.05", "radial_immersion = 1.2", "radial_immersion"),
        ("radial_immersion = 0.05", "radial_immersion = 0.0", "radial_immersion"),
        ('milling = "down"', 'milling = "climb"', "milling"),
        ("radial_immersion = 0.05\n", "entry_deg = 170.0\nexit_deg = 120.0\n", "exit_deg"),
        ("radial_immersion = 0.05\n", "radial_immersion = 0.05\npitch_deg = [170.0, 180.0]\n", "pitch_deg"),
        ("Kt = 6.0e8", "Kt = -6.0e8", "Kt"),
        ("mass = 0.03993", "mass = -0.03993", "mass"),
    ],
)
def test_bad_milling_input_names_the_field(old, new, field):
    text = ONE.read_text()
    assert old in text
    if field == "exit_deg":
        text = text.replace('milling = "down"\n', "")
    with pytest.raises(ModelError) as e:
        cl.loads_model(text.replace(old, new, 1))
    msg = str(e.value)
    assert "\n" not in msg
    assert field in msg


def test_milling_coupling_needs_a_milling_process():
    text = ONE.read_text()
    start = text.index("\n[process]")
    with pytest.raises(ModelError, match=r'model = "milling" needs \[process\] kind = "milling"'):
        cl.loads_model(text[:start] + '[process]\nkind = "turning"\nrpm = 1000.0\n')


def test_variable_pitch_is_read_in_radians():
    text = ONE.read_text().replace(
        "radial_immersion = 0.05\n", "radial_immersion = 0.05\npitch_deg = [160.0, 200.0]\n"
    )
    c = cl.loads_model(text).process.milling
    np.testing.assert_allclose(c.pitch, np.radians([160.0, 200.0]), rtol=1e-15)
