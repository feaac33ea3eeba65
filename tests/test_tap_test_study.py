"""The tap-test walkthrough (studies/tap_test) runs, quickly, and its
numbers hold: the fit finds the machine's modes, the lobes from the file,
from the fitted model and from the true machine agree within what the
noise allows, and the coupled prediction of a new overhang matches the true
machine.  The walkthrough's figures go to a temporary folder."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

STUDY = Path(__file__).resolve().parents[1] / "studies" / "tap_test"
NOISE = 0.02  # the files' relative complex noise (generate.py)


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    sys.path.insert(0, str(STUDY))
    try:
        import walkthrough
    finally:
        sys.path.pop(0)
    out = tmp_path_factory.mktemp("figures")
    res = walkthrough.run(out, quick=True)
    res["_figures"] = sorted(p.name for p in out.glob("tap_test_*.png"))
    return res


def test_files_are_what_generate_makes():
    # the committed files are the seeded generator's output (byte for byte)
    sys.path.insert(0, str(STUDY))
    try:
        import generate
    finally:
        sys.path.pop(0)
    data = generate.make()
    committed = json.loads((STUDY / "truth.json").read_text())
    fresh = json.loads(json.dumps(data["truth"]))
    # The modes come from LAPACK's eigensolver and H from its linear solves:
    # backward stable, so another BLAS may change the last digits (seen:
    # 1e-12 relative).  Each quantity is a simple eigenvalue of a 30-DOF model
    # whose eigenvector condition is below 1e3 and whose receptance solves
    # have condition below 1e4 in the band: forward error < 1e4 * n * eps
    # ~ 1e-10.  1e-9 relative holds on any BLAS and still catches a changed
    # seed, noise level or model (those move the numbers by >= 1e-3).
    for d in ("x", "y"):
        for key in ("frequency_hz", "damping"):
            np.testing.assert_allclose(fresh["modes"][d][key], committed["modes"][d][key], rtol=1e-9)
    assert {k: v for k, v in fresh.items() if k != "modes"} == {
        k: v for k, v in committed.items() if k != "modes"
    }
    from chatterlab.structure import FRF

    frf = FRF.read(STUDY / "tool_point.csv")
    np.testing.assert_allclose(frf.data, data["tool_point"].data, rtol=1e-9, atol=0)


def test_the_csv_round_trip_is_exact(tmp_path):
    # 17 significant digits in the file: what is written is read back bit for bit
    sys.path.insert(0, str(STUDY))
    try:
        import generate
    finally:
        sys.path.pop(0)
    from chatterlab.structure import FRF

    tp = generate.make()["tool_point"]
    tp.to_csv(tmp_path / "tool_point.csv")
    np.testing.assert_array_equal(FRF.read(tmp_path / "tool_point.csv").data, tp.data)


def test_figures_are_drawn(result):
    assert result["_figures"] == [
        "tap_test_coupling.png",
        "tap_test_fit.png",
        "tap_test_frf.png",
        "tap_test_lobes.png",
        "tap_test_stabilisation.png",
    ]


def test_fit_finds_the_machine_modes(result):
    # One pole per isolated mode (657 Hz in x, 734 Hz in y) and one for the
    # tool's x and y modes, 0.5 Hz apart with a 50 Hz half-power width (one
    # pole to the LSFD).  The isolated ones within 4.5 standard deviations of
    # the maximum-likelihood fit (tests/test_modal_fit.py: the estimator
    # attains the Cramer-Rao bound; seeded data, p ~ 1e-5 of a chance miss);
    # the upper residual's model error (weighted error 0.024 against the
    # noise's 0.020: sqrt(0.024^2 - 0.020^2) = 0.013) is below the noise.  The
    # merged pole: within the x-y split plus 4.5 sd of either true mode.
    assert result["n_modes"] == 3
    rows = result["fit_errors"]
    iso = [r for r in rows if r["f_true"] < 1000.0]
    assert len(iso) == 2
    for r in iso:
        assert abs(r["df_z"]) < 4.5 and abs(r["dzeta_z"]) < 4.5, r
    tool = [r for r in rows if r["f_true"] > 2000.0]
    split = abs(tool[0]["f_true"] - tool[1]["f_true"])
    for r in tool:
        sd = abs(r["f_fit"] - r["f_true"]) / max(abs(r["df_z"]), 1e-300)
        assert abs(r["f_fit"] - r["f_true"]) <= split + 4.5 * sd, r
    q = result["fit_quality"]
    # weighted rms error of an adequate model = the noise (2N residuals, a few
    # dozen parameters): between the noise and 1.5 x (model error < noise)
    assert NOISE * 0.95 < q["weighted_error"] < 1.5 * NOISE
    # ... and over the full band, where the constant upper residual cannot
    # stand for the 6.3 and 7.4 kHz modes, the same number says so
    assert result["weighted_error_full_band"] > 3 * NOISE


def test_lobes_from_file_fit_and_truth_agree(result):
    # Tlusty: b_lim = -1 / (2 K_f Re G); a relative error e of G moves b by at
    # most e |G| / |Re G|, and at the lobe minimum of a dominant mode
    # |G| / |Re G| ~ sqrt(2) (phase -135 deg).  Noise: 2 % per point, so 3
    # sigma at the minimum is 3 x 0.02 x sqrt(2) = 8.5 %.  The fitted model
    # smooths the same data: no worse.
    bound = 3 * NOISE * math.sqrt(2)
    t = result["turning_min_mm"]
    assert abs(t["frf"] / t["true"] - 1) < bound
    assert abs(t["fit"] / t["true"] - 1) < bound
    m = result["milling_min_mm"]
    assert abs(m["fit"] / m["frf"] - 1) < bound


def test_joint_and_new_overhang(result):
    J = result["joint"]
    for k, name in enumerate(("k", "k_rot", "c", "c_rot")):
        got, true = J[name]
        assert abs(got - true) < 4.5 * J["std"][k], (name, got, true, J["std"][k])
    e = result["coupling_error"]
    # smoothing the holder by its modal fit: the coupled tool point's error
    # falls at least sqrt(N / p) / 3 ~ 3 x below the raw holder's (N ~ 1200
    # frequencies, p ~ 30 parameters: the fit averages the noise down by
    # sqrt(N / p) ~ 6)
    for L in ("60 mm", "75 mm"):
        assert e[f"{L}, fitted holder"]["rms"] < e[f"{L}, raw holder"]["rms"] / 3
    # the new overhang's lobe minimum moves with Re G: error <= sqrt(2) x the
    # coupled FRF's largest relative error (previous test's argument)
    n = result["new_overhang_min_mm"]
    assert abs(n["rcsa"] / n["true"] - 1) <= math.sqrt(2) * e["75 mm, fitted holder"]["max"]
    assert n["true"] < 0.5 * n["measured_60"]  # a longer tool chatters at much smaller widths
