"""A measured FRF as the structure of a model ([frf], issue 13 item 2): the
model's [process] and [[coupling]] on the FRF's coordinates give the same
lobes as the measured-FRF engine called directly; bad tables are one line."""

from __future__ import annotations

import numpy as np
import pytest

import chatterlab as cl
from chatterlab.errors import InputError, ModelError
from chatterlab.lobes._measured import lobes_measured, lobes_model_frf
from chatterlab.structure import FRF

# the 1-DOF turning tool of docs/model-format.md: m = 1 kg, k = 1e7 N/m, zeta = 3 %
M, K, ZETA = 1.0, 1.0e7, 0.03


def _write_frf(folder, name="tool.csv"):
    f = np.arange(100.0, 1500.0 + 1e-9, 1.0)
    w = 2 * np.pi * f
    H = 1.0 / (K - M * w**2 + 2j * ZETA * np.sqrt(K * M) * w)
    FRF.from_arrays(f, H, ("tool.x",), ("tool.x",), hz=True).to_csv(folder / name)
    return folder / name


MODEL = """
[frf]
file = "tool.csv"

[[point]]
id = "tip"
coords = { x = "tool.x" }

[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = 2.0e9

[process]
kind = "turning"
rpm = 3000.0
"""


def test_frf_model_equals_the_measured_engine(tmp_path):
    path = _write_frf(tmp_path)
    (tmp_path / "m.toml").write_text(MODEL)
    model = cl.load_model(tmp_path / "m.toml")
    rpm = np.linspace(2000.0, 6000.0, 41)
    got = lobes_model_frf(model, rpm, width_max=0.005)
    ref = lobes_measured(
        FRF.read(path), rpm, process=model.process, width_max=0.005, Kf=2.0e9, coordinates=["tool.x"]
    )
    # the same plant and engine; D_P = (Kf b_ref) / b_ref differs from Kf by at most two roundings, and
    # b_lim ~ 1/Kf, so the two agree to a few ulp plus the envelope refinement's stopping tolerance
    # (both refined to round-off by the same iterations)
    np.testing.assert_allclose(got.b_lim, ref.b_lim, rtol=1e-12)
    assert np.array_equal(got.claim, ref.claim)
    # and the classical minimum of a 1-DOF tool, 2 k zeta (1 + zeta) / Kf (Tlusty), within the 1 Hz grid's
    # first-order bound (docs/measured-frf.md: ~1e-6 relative at 1 Hz)
    assert got.absolute_minimum["width"] == pytest.approx(2 * K * ZETA * (1 + ZETA) / 2.0e9, rel=1e-5)


def test_frf_model_bad_input(tmp_path):
    _write_frf(tmp_path)
    cases = {
        'file = "missing.csv"': ("file", "missing.csv"),
        'file = "../tool.csv"': ("file", "outside"),
    }
    for new, (field, word) in cases.items():
        (tmp_path / "m.toml").write_text(MODEL.replace('file = "tool.csv"', new))
        with pytest.raises(ModelError) as e:
            cl.load_model(tmp_path / "m.toml")
        msg = str(e.value)
        assert "\n" not in msg and "[frf]" in msg and field in msg and word in msg
    (tmp_path / "m.toml").write_text(MODEL.replace('coords = { x = "tool.x" }', 'coords = { x = "tool.y" }'))
    with pytest.raises(ModelError, match=r"tool\.y"):
        cl.load_model(tmp_path / "m.toml")
    body = '\n[[body]]\nid = "b"\nmass = 1.0\ninertia = 1.0\ncentre = [0.0, 0.0]\n'
    (tmp_path / "m.toml").write_text(MODEL + body)
    with pytest.raises(ModelError, match=r"\[frf\].*remove body"):
        cl.load_model(tmp_path / "m.toml")
    (tmp_path / "m.toml").write_text(MODEL.replace('b = "ground"', 'b = "tip"'))
    model = cl.load_model(tmp_path / "m.toml")
    with pytest.raises(InputError, match=r'to "ground"'):
        lobes_model_frf(model, np.array([3000.0]))


def test_frf_model_cannot_be_assembled(tmp_path):
    _write_frf(tmp_path)
    (tmp_path / "m.toml").write_text(MODEL)
    with pytest.raises(InputError, match=r"measured FRF"):
        cl.assemble(cl.load_model(tmp_path / "m.toml"))
