"""The discretisation error of ``simulate``, ``frf`` and ``sweep`` on a model
with beams (chatterlab/cli/_mesh_checks.py; docs/lobes.md Eqs. M1-M5).

Oracles from mathematics, not recordings:

* the turning-type cut 0.2 mm wide at 0.1 m/s, position 0.85 m, is stable on
  the paper's 6-element mesh and unstable on a converged mesh (it flips at 8
  elements, studies/traverse_shaper/mesh_convergence.py): ``simulate`` must
  not call it "no chatter", and on the converged variant it says chatter,
  confirmed by the finer mesh;
* the sweep's point 0.3 mm at 0.5 m/s is stable on the paper's mesh and
  unstable on the converged one: it must not stay "stable" in the file;
* the bound 2|d| (Eq. M3 at p = 1) covers the error of the paper's mesh
  against the converged variant where the asymptotic regime holds: the
  two lowest resonance peaks of rfe5.x/rfe5.x (frequency and magnitude) and
  the smallest b_lim_min of a position sweep; the third peak (246 Hz) is
  pre-asymptotic (as modes 5 and 7 in tests/test_mesh_error.py) and its
  frequency is *not* covered: pinned so that the documented limitation
  stays true;
* a model without beams calls none of the mesh code and prints and writes
  exactly what it did.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from chatterlab.cli import _mesh_checks, main

SHAPER = "studies/traverse_shaper/model.toml"
FLIP = ["--width", "0.2", "--speed", "0.1", "--position", "0.85"]


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


# ---------------------------------------------------------------------------- simulate


def test_simulate_does_not_call_the_flipping_cut_chatter_free(tmp_path, capsys):
    """0.2 mm, 0.1 m/s: the frozen roots are stable on h and h/2 (margin
    -0.0024 and -0.0166 1/s) but the margin is within 2|d| = 0.029 1/s, so
    the run's verdict is undetermined; a verdict is a result (exit 0, as
    roots).  The netCDF file carries the same facts.  On the converged
    variant: chatter (+0.0018 1/s), and the paper's margin is within its
    bound of it (|-0.0024 - 0.0018| = 0.0041 <= 0.029)."""
    xr = pytest.importorskip("xarray")
    out = tmp_path / "s.nc"
    code, text, _ = run(capsys, "simulate", SHAPER, *FLIP, "--duration", "0.2", "--quiet", "--out", str(out))
    assert code == 0
    lines = [ln.strip() for ln in text.splitlines()]
    assert (
        "verdict: undetermined (the frozen system's rightmost root -0.002354 1/s; no chatter on this" in text
    )
    mesh = [ln for ln in lines if ln.startswith("mesh:")]
    assert len(mesh) == 1 and "refine the beams or use the converged variant" in mesh[0]
    with xr.open_dataset(out) as ds:
        a = ds.attrs
        assert a["mesh_verdict"] == "undetermined" and a["mesh_coarse_verdict"] == "stable"
        assert a["mesh_fine_verdict"] == "stable" and int(a["mesh_beam_elements"]) == 6
        assert float(a["mesh_abscissa_error_bound_per_s"]) >= abs(float(a["mesh_abscissa_per_s"]))
        assert float(a["mesh_abscissa_error_bound_per_s"]) == pytest.approx(
            2 * abs(float(a["mesh_fine_abscissa_per_s"]) - float(a["mesh_abscissa_per_s"])), rel=1e-12
        )
        assert a["mesh"] == mesh[0]
        a_h, bound = float(a["mesh_abscissa_per_s"]), float(a["mesh_abscissa_error_bound_per_s"])
    # the converged variant decides it: chatter, its finer mesh agreeing far beyond its bound; and
    # the paper's mesh's margin is within its bound of the converged one (Eq. M3 holds here)
    out2 = tmp_path / "c.nc"
    code, text, _ = run(
        capsys, "simulate", SHAPER, "--variant", "converged", *FLIP, "--duration", "0.2", "--quiet",
        "--out", str(out2),
    )  # fmt: skip
    assert code == 0
    assert (
        "verdict: chatter (the frozen system's rightmost root +0.001775 1/s, on this mesh and on one" in text
    )
    with xr.open_dataset(out2) as ds:
        a_conv, own = (
            float(ds.attrs["mesh_abscissa_per_s"]),
            float(ds.attrs["mesh_abscissa_error_bound_per_s"]),
        )
        assert ds.attrs["mesh_verdict"] == "unstable" and own < 0.01 * abs(a_conv)
    assert abs(a_h - a_conv) <= bound + own


def test_simulate_on_a_moving_slide_claims_no_check(capsys):
    """The slide moves: there is no frozen system, nothing is computed on a
    finer mesh, and the line says so (never implies a check)."""
    code, text, _ = run(capsys, "simulate", SHAPER, "--feedback", "pd", "--duration", "0.05", "--quiet")
    assert code == 0
    mesh = [ln.strip() for ln in text.splitlines() if ln.strip().startswith("mesh:")]
    assert len(mesh) == 1 and "not estimated (nothing was computed on a finer mesh" in mesh[0]
    assert "verdict:" not in text


# ---------------------------------------------------------------------------- frf


def _peaks(capsys, fmin: str, fmax: str, points: str, variant: str | None) -> dict:
    argv = ["frf", SHAPER, "--input", "rfe5.x", "--output", "rfe5.x", "--format", "json"]
    argv += ["--fmin", fmin, "--fmax", fmax, "--points", points]
    code, out, _ = run(capsys, *argv, *(["--variant", variant] if variant else []))
    assert code == 0
    return json.loads(out)["mesh"]


def test_frf_peak_bounds_cover_the_converged_mesh(capsys):
    """rfe5.x/rfe5.x: the peaks at 76.3 and 83.3 Hz of the paper's mesh are
    within their bounds of the converged variant's (allowing for the
    converged variant's own bound), in frequency and in magnitude; the
    246.4 Hz peak's frequency is not (pre-asymptotic: the documented
    limitation; its magnitude is).  The 241.8 Hz peak of 235-255 Hz climbs
    to the 246 Hz one on the finer mesh: no estimate is made up for it."""
    covered = []
    for rng in (("70", "90", "81"), ("235", "255", "41")):
        coarse_doc, conv_doc = (_peaks(capsys, *rng, v) for v in (None, "converged"))
        assert coarse_doc["beam_elements"] == 6 and coarse_doc["fine_beam_elements"] == 12
        coarse, conv = coarse_doc["pairs"][0]["peaks"], conv_doc["pairs"][0]["peaks"]
        if rng[0] == "235":
            assert coarse[0]["frequency_hz"] == pytest.approx(241.82, abs=0.01)
            assert coarse[0]["fine_frequency_hz"] is None and coarse[0]["frequency_error_bound_hz"] is None
            coarse, conv = coarse[1:], conv[1:]
        assert len(coarse) == len(conv)
        for c, r in zip(coarse, conv, strict=True):
            assert c["frequency_error_bound_hz"] == pytest.approx(
                2 * abs(c["fine_frequency_hz"] - c["frequency_hz"]), rel=1e-12
            )
            # the oracle's own error is below 1/50 of each bound: it decides no case
            assert r["frequency_error_bound_hz"] < 0.02 * c["frequency_error_bound_hz"]
            assert r["magnitude_error_bound"] < 0.02 * c["magnitude_error_bound"]
            f_err = abs(c["frequency_hz"] - r["frequency_hz"])
            m_err = abs(c["magnitude"] - r["magnitude"])
            covered.append(
                (
                    round(c["frequency_hz"]),
                    f_err <= c["frequency_error_bound_hz"] + r["frequency_error_bound_hz"],
                    m_err <= c["magnitude_error_bound"] + r["magnitude_error_bound"],
                )
            )
    assert covered == [(76, True, True), (83, True, True), (246, False, True)]


def test_frf_csv_on_standard_output_stays_a_plain_table(capsys):
    """The mesh lines go to standard error when the table is on standard
    output; the table is the one without them."""
    code, out, err = run(
        capsys, "frf", SHAPER, "--input", "rfe5.x", "--output", "rfe5.x", "--fmin", "70", "--fmax", "90",
        "--points", "5",
    )  # fmt: skip
    assert code == 0 and "mesh" not in out and len(out.splitlines()) == 6
    assert err.startswith("mesh: 6 beam elements; resonance peaks on a mesh twice as fine")
    assert "rfe5.x/rfe5.x: 76.28 Hz -0.0904 Hz (err <= 0.18 Hz)" in err


# ---------------------------------------------------------------------------- sweep


def test_sweep_stable_point_that_flips_is_not_kept_stable(tmp_path, capsys):
    """The docs' sweep: 0.3 mm at 0.5 m/s is the stable point nearest the
    boundary; unstable twice as fine (and on the converged variant, where
    every point of width >= 0.3 mm at 0.5 m/s is unstable): it becomes NaN
    in the file, and the line says which 2 of the 12 points were checked."""
    xr = pytest.importorskip("xarray")
    out = tmp_path / "stable.nc"
    code, text, _ = run(
        capsys, "sweep", SHAPER, "--quantity", "stable", "--grid", "width=0.1:0.4:4",
        "--grid", "speed=0.45:0.55:3", "--out", str(out), "--quiet",
    )  # fmt: skip
    assert code == 0
    assert "checked on a mesh twice as fine at 2 of 12 points" in text
    assert "at width 0.3 mm, speed 0.5: undetermined (stable on this mesh, unstable on a mesh twice" in text
    with xr.open_dataset(out) as ds:
        s = ds["stable"].values
        assert np.isnan(s[2, 1]) and np.isnan(s[3, 1]) and np.nansum(np.isnan(s)) == 2
        assert int(ds.attrs["mesh_points_checked"]) == 2 and int(ds.attrs["mesh_points"]) == 12
        checks = json.loads(ds.attrs["mesh_checks"])
        assert [c["verdict"] for c in checks] == ["undetermined", "undetermined"]
        assert ds.attrs["mesh"] in text


def test_sweep_smallest_limit_bound_covers_the_converged_mesh(tmp_path, capsys):
    """min-b-lim along the stroke: the smallest, at 0.55 m, is 0.14282 mm on
    the paper's mesh, 0.1569 mm twice as fine (bound 19.7 %), 0.16015 mm on
    the converged variant: covered (0.0173 <= 0.0281 mm).  Only that point is
    checked, and the line says so."""
    out = tmp_path / "minb.csv"
    code, text, _ = run(
        capsys, "sweep", SHAPER, "--quantity", "min-b-lim", "--grid", "position=0.55:1.15:7",
        "--width-max", "1", "--out", str(out), "--quiet",
    )  # fmt: skip
    assert code == 0
    line = next(ln.strip() for ln in text.splitlines() if ln.strip().startswith("mesh:"))
    assert "b_lim_min 0.1569 mm (+9.8%), discretisation error of this b_lim_min <= 19.7%" in line
    assert "checked at position 0.55 only" in line and "the other 6 points are this mesh's" in line
    b_h, conv = 0.142816e-3, 0.160154e-3
    assert abs(b_h - conv) <= 0.197 * b_h


# ---------------------------------------------------------------------------- no beams


@pytest.fixture
def no_mesh_code(monkeypatch):
    """Any call into the mesh checks fails the test."""

    def boom(*a, **k):
        raise AssertionError("mesh code called for a model without beams")

    for name in ("simulate_check", "frf_check", "frf_peaks", "sweep_check"):
        monkeypatch.setattr(_mesh_checks, name, boom)


def test_a_model_without_beams_is_unchanged(no_mesh_code, tmp_path, capsys):
    """A 1-DOF turning tool: no mesh code runs; no mesh line; the files hold
    no mesh member or attribute; the FRF's JSON is the FRF's own to_json."""
    xr = pytest.importorskip("xarray")
    import chatterlab as cl
    from chatterlab.frequency._frf import frequencies, frf

    model = "example:damped_turning.toml"
    out = tmp_path / "s.nc"
    code, text, _ = run(
        capsys, "simulate", model, "--width", "0.5", "--speed", "1500", "--duration", "0.05", "--quiet",
        "--out", str(out),
    )  # fmt: skip
    assert code == 0 and "mesh" not in text and "verdict:" not in text
    with xr.open_dataset(out) as ds:
        assert not [k for k in ds.attrs if k.startswith("mesh")]
    code, text, err = run(capsys, "frf", model, "--input", "tool.x", "--output", "tool.x", "--format", "json",
                          "--points", "50")  # fmt: skip
    assert code == 0 and "mesh" not in json.loads(text) and err == ""
    from chatterlab._examples import example_path

    fz = cl.assemble(cl.load_model(example_path("damped_turning.toml"))).at()
    own = frf(fz, frequencies(1.0, 300.0, 50), inputs=["tool.x"], outputs=["tool.x"]).to_json()
    assert text == own + "\n" or text == own
    code, text, err = run(
        capsys,
        "sweep",
        model,
        "--quantity",
        "stable",
        "--grid",
        "width=0.5:1:2",
        "--speed",
        "1500",
        "--quiet",
    )
    assert code == 0 and "mesh" not in text


def test_sweep_of_a_milling_model_with_beams_checks_its_critical_point(capsys):
    """The end mill on 3 beam elements: spectral-radius is judged at the point
    nearest |mu| = 1 with the margin ln|mu| / T (1/s, T the tooth period);
    a-lim at its smallest limit, and where every limit is at the ceiling the
    finer mesh is asked whether it is there too (never a claim unchecked)."""
    tool = "studies/milling/tool_cantilever.toml"
    code, text, _ = run(
        capsys, "sweep", tool, "--quantity", "spectral-radius", "--grid", "width=0.5:3:3", "--speed", "10000",
        "--quiet",
    )  # fmt: skip
    assert code == 0
    assert "mesh: 3 beam elements; checked on a mesh twice as fine at 1 of 3 points" in text
    assert "smallest |ln spectral_radius|" in text and "also stable on a mesh twice as fine" in text
    code, text, _ = run(
        capsys, "sweep", tool, "--quantity", "a-lim", "--grid", "speed=8000:12000:3", "--width-max", "10",
        "--quiet",
    )  # fmt: skip
    assert code == 0
    assert "no a_lim below the ceiling either" in text and "checked at speed 8000 only" in text


# ---------------------------------------------------------------------------- sle


def test_sle_of_a_milling_model_with_beams_is_checked_at_its_critical_speeds(tmp_path, capsys):
    """End mill, a_p = 12 mm, 5000-30000 rpm: the stable speed nearest |mu| = 1
    (20000 rpm, which also has the largest |SLE|) and the unstable one
    (5000 rpm) are computed again twice as fine; both verdicts stand (margins
    far beyond 2|d|, Eq. M3), the line says 2 of 6 speeds, the JSON file
    carries the record; a model without beams gets none of it."""
    out = tmp_path / "sle.json"
    argv = ["sle", "studies/milling/tool_cantilever.toml", "--speed", "5000", "30000", "--points", "6"]
    code, text, _ = run(capsys, *argv, "--width", "12", "--feed", "0.1", "--quiet", "--out", str(out))
    assert code == 1  # one speed chatters: sle's own rule
    assert "checked on a mesh twice as fine at 2 of 6 speeds" in text
    doc = json.loads(out.read_text())
    checks = json.loads(doc["attrs"]["mesh_checks"])
    assert [(c["speed_rpm"], c["verdict"]) for c in checks] == [(20000.0, "stable"), (5000.0, "unstable")]
    for c in checks:
        assert c["margin_error_bound_per_s"] == pytest.approx(
            2 * abs(c["fine_margin_per_s"] - c["margin_per_s"]), rel=1e-12
        )
        assert c["margin_error_bound_per_s"] < abs(c["margin_per_s"])
    assert doc["attrs"]["mesh"] in text
    code, text, _ = run(
        capsys, "sle", "studies/milling/benchmark_1dof.toml", "--speed", "5000", "30000", "--points", "3",
        "--width", "0.5", "--quiet",
    )  # fmt: skip
    assert "mesh" not in text


def test_ssv_of_a_model_with_beams_checks_its_smallest_limit_on_the_finer_mesh(monkeypatch, capsys):
    """ssv on a beam model searches its smallest limit again on the mesh
    twice as fine (tests/test_mesh_ssv_sle.py runs the searches for real).
    The search is stubbed here (0.2 mm on the paper's 6 elements, 0.21 mm on
    12): the line gives the change +5.0 % and the bound 2 |change| = 10.0 %."""
    import numpy as np

    import chatterlab.frequency as freq
    from chatterlab.frequency._floquet_ssv_limit import SsvLimits

    def stub(source, speeds, rva, rvf, **kw):
        shape = (len(speeds), len(rva), len(rvf))
        b = np.full(shape, 2.1e-4 if source.model.beam_elements == 12 else 2e-4)
        return SsvLimits(
            np.asarray(speeds, float), np.asarray(rva, float), np.asarray(rvf, float), b, np.full(shape, 83.0),
            np.ones(shape), "sine", "spectral", 5e-3, 20, "m/s",
        )  # fmt: skip

    def stub_at(source, points, **kw):  # the searches twice as fine, at listed points
        return np.full(len(points), 2.1e-4 if source.model.beam_elements == 12 else 2e-4)

    monkeypatch.setattr(freq, "ssv_limits", stub)
    monkeypatch.setattr(freq, "ssv_limits_at", stub_at)
    code, text, _ = run(capsys, "ssv", SHAPER, "--speed", "3", "--rva", "0", "--rvf", "0.5")
    assert code == 0
    assert text.splitlines()[-1].startswith(
        "mesh: 6 beam elements; twice as fine: b_lim 0.21 mm (+5.0%), discretisation error of this b_lim <= 10.0%"
        " at speed 3 m/s, RVA 0, RVF 0.5, the grid's smallest b_lim"
    )


def test_simulate_of_a_milling_model_with_beams_checks_the_linearised_verdict(tmp_path, capsys):
    """End mill, a_p = 5 mm at 20000 rpm (4 revolutions: the check does not
    depend on the run's length): the linearised cut's |mu| = 0.81 on 3
    elements, the same twice as fine; the margin ln|mu|/T = -140 1/s is far
    beyond its bound 2|d| (Eq. M3), so stable stands; the netCDF file says
    so.  A milling model without beams prints none of it."""
    xr = pytest.importorskip("xarray")
    out = tmp_path / "m.nc"
    code, text, _ = run(
        capsys, "simulate", "studies/milling/tool_cantilever.toml", "--width", "5", "--speed", "20000",
        "--revolutions", "4", "--out", str(out),
    )  # fmt: skip
    assert code == 0
    assert (
        "linearised verdict (Floquet, |mu| = 0.81" in text and "also stable on a mesh twice as fine" in text
    )
    with xr.open_dataset(out) as ds:
        a = ds.attrs
        assert a["mesh_verdict"] == "stable" and int(a["mesh_beam_elements"]) == 3
        assert float(a["mesh_margin_error_bound_per_s"]) == pytest.approx(
            2 * abs(float(a["mesh_fine_margin_per_s"]) - float(a["mesh_margin_per_s"])), rel=1e-12
        )
    code, text, _ = run(
        capsys, "simulate", "studies/milling/benchmark_1dof.toml", "--width", "0.5", "--speed", "18000",
        "--revolutions", "4",
    )  # fmt: skip
    assert "mesh" not in text and "linearised verdict" not in text
