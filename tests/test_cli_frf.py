"""``chatterlab lobes --frf FILE`` (issue 13, item 2): lobes from a measured
FRF with or without a model file, turning and milling (ZOA); the command
prints what the engine computes, and bad input is one line with status 2
and nothing written."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from conftest import assert_clean_error

import chatterlab as cl
from chatterlab.cli import main
from chatterlab.lobes._measured import lobes_measured
from chatterlab.process import Milling
from chatterlab.structure import FRF

K, M, ZETA = 1.0e7, 1.0, 0.03  # a 503 Hz, 3 % tool point


def _sdof(f_hz):
    w = 2 * np.pi * f_hz
    return 1.0 / (K - M * w**2 + 2j * ZETA * np.sqrt(K * M) * w)


@pytest.fixture
def tap(tmp_path):
    f = np.arange(100.0, 1500.0 + 1e-9, 1.0)
    FRF.from_arrays(f, _sdof(f), ("tool.x",), ("tool.x",), hz=True).to_csv(tmp_path / "tap.csv")
    return tmp_path / "tap.csv"


@pytest.fixture
def tap_xy(tmp_path):
    f = np.arange(100.0, 1500.0 + 1e-9, 1.0)
    H = np.zeros((2, 2, f.size), complex)
    H[0, 0] = _sdof(f)
    H[1, 1] = _sdof(f)
    FRF.from_arrays(f, H, ("tool.x", "tool.y"), ("tool.x", "tool.y"), hz=True).to_csv(tmp_path / "tap_xy.csv")
    return tmp_path / "tap_xy.csv"


def _read_csv(path):
    with open(path) as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    return rows[0], rows[1:]


def test_turning_from_a_file_without_a_model(tap, tmp_path, capsys):
    out = tmp_path / "l.csv"
    code = main(["lobes", "--frf", str(tap), "--kf", "2e9", "--speed", "2000", "6000", "--points", "21",
                 "--width-max", "2", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    head, rows = _read_csv(out)
    col = head.index("b_lim [m]")
    got = np.array([float(r[col]) for r in rows])
    assert {r[head.index("claim")] for r in rows} == {"boundary in the measured band (outside it unknown)"}
    ref = lobes_measured(
        FRF.read(tap),
        np.linspace(2000.0, 6000.0, 21),
        process=cl.loads_model('[[body]]\nid="b"\nmass=1.0\ninertia=1.0\ncentre=[0.0,0.0]\n'
                               '[process]\nkind="turning"\nrpm=3000.0\n').process,
        width_max=0.002,
        Kf=2e9,
    )  # fmt: skip
    # the CSV holds b_lim with 9 significant digits (half a unit in the last: 5e-9 relative); the CLI's
    # D_P = (Kf b_ref)/b_ref differs from Kf by two roundings at most, far below that
    np.testing.assert_allclose(got, ref.b_lim, rtol=5e-9)


def test_milling_zoa_from_a_2x2_file(tap_xy, capsys):
    code = main(["lobes", "--frf", str(tap_xy), "--teeth", "2", "--kt", "6e8", "--kn", "2e8", "--immersion",
                 "1.0", "--speed", "5000", "20000", "--points", "31", "--width-max", "20"])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == 0, err
    # slotting with N = 2 against Altintas & Budak's (1995) closed form: det[I + Lambda [A0] G(jw)] = 0,
    # Lambda = -1 / eig([A0] G), a_lim = -2 pi Lambda_R (1 + kappa^2) / (N K_t), kappa = Lambda_I / Lambda_R,
    # minimised over w.  Their [A0] = (1/2)[alpha] is the integral over the arc, without the N / 2 pi of
    # the mean H0 (chatterlab.process.Milling.zoa): [A0] = -(2 pi / N)(2 / K_t) H0
    mill = Milling.from_immersion(2, 1.0, 6e8, 2e8, 1.0, "down")
    A0 = -(2 * np.pi / 2) * 2 * mill.zoa() / 6e8
    f = np.linspace(400.0, 800.0, 40001)
    Lam = -1.0 / np.array([np.linalg.eigvals(A0 * _sdof(fi)) for fi in f])
    a = -2 * np.pi * Lam.real * (1 + (Lam.imag / Lam.real) ** 2) / (2 * 6e8)
    a_min = np.min(a[a > 0])
    line = [ln for ln in out.splitlines() if "absolute minimum" in ln][0]
    got_mm = float(line.split(":")[1].split("mm")[0])
    # printed to 4 significant digits (5e-4 relative); the closed form's 0.01 Hz grid near a 3 % mode: < 1e-6
    assert got_mm == pytest.approx(a_min * 1e3, rel=6e-4)


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        ([], ["--kf", "--teeth"]),
        (["--teeth", "2", "--kt", "6e8"], ["--kn", "--immersion"]),
        (["--teeth", "2", "--kt", "6e8", "--kn", "2e8", "--immersion", "0.5"], ["2 x 2"]),
    ],
)
def test_bad_frf_cuts_are_one_line(tap, tmp_path, capsys, extra, words):
    out = tmp_path / "never.csv"
    code = main(["lobes", "--frf", str(tap), "--speed", "2000", "6000", "--out", str(out), *extra])
    assert_clean_error(code, capsys.readouterr().err, *words)
    assert not out.exists()


def test_a_missing_frf_file_is_one_line(tmp_path, capsys):
    code = main(["lobes", "--frf", str(tmp_path / "nope.csv"), "--kf", "2e9", "--speed", "2000", "6000"])
    assert_clean_error(code, capsys.readouterr().err, "nope.csv")


def test_lobes_without_model_or_frf_says_what_to_give(capsys):
    code = main(["lobes", "--speed", "2000", "6000"])
    assert_clean_error(code, capsys.readouterr().err, "model file", "--frf")
