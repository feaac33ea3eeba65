"""The natural-frequency unit-slip warning: a structure whose fundamental is
above 100 kHz (a mass typed in tonnes-per-gram, a stiffness in N/mm typed as
N/m x 1e6) is warned of; a finely meshed beam model is not, though its
highest (mesh) modes are megahertz (the bundled shaper's converged variant:
2.2 MHz at the top, 76 Hz at the bottom)."""

from __future__ import annotations

from pathlib import Path

from conftest import turning_text

from chatterlab.cli import main

SHAPER = Path(__file__).resolve().parents[1] / "studies" / "traverse_shaper" / "model.toml"


def test_a_fundamental_above_100_khz_is_warned_of(tmp_path, capsys):
    # m = 1e-6 kg on k = 1e7 N/m, lightly damped: f = sqrt(k/m) / 2 pi = 503 kHz
    p = tmp_path / "slip.toml"
    p.write_text(turning_text(mass=1e-6, damping=1e-3))
    main(["frf", str(p), "--input", "tip.x", "--output", "tip.x"])
    err = capsys.readouterr().err
    assert "lowest natural frequency is 5.03e+05 Hz, above 100 kHz" in err, err


def test_a_fine_beam_mesh_is_not_a_unit_slip(capsys):
    main(["frf", str(SHAPER), "--variant", "converged", "--input", "rfe5.x", "--output", "rfe5.x"])
    err = capsys.readouterr().err
    assert "100 kHz" not in err, err
