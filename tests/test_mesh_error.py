"""The discretisation error reported with every result of a model with beams
(chatterlab/model/_mesh.py, chatterlab/lobes/_mesh_error.py; docs/lobes.md,
"The discretisation error of a result", Eqs. M1-M5).

Oracles from mathematics, not recordings:

* a Timoshenko cantilever, whose first natural frequency is the root of the
  closed-form frequency equation (tests/test_elements.py,
  ``timoshenko_cantilever_omega``): the reported bound 2|d| covers the true
  error of the coarse mesh, and, since the element converges at order p = 2
  there, it exceeds it by the factor 2 (1 - 2^-p) = 3/2 in the asymptotic
  regime (Eq. M4: between 1 and 2 for any p >= 1);
* the bundled shaper: the bound of its minimum covers the error against the
  Richardson estimate of the mesh convergence study (0.194886 mm, the
  conforming family; docs/lobes.md, "Mesh convergence of the bundled shaper");
* the verdict at 0.2 mm, 0.1 m/s, stable on the paper's mesh and unstable on
  a converged one, is not reported stable;
* a model without beams gets nothing new.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_elements import KAPPA, RHO, E, G, timoshenko_cantilever_omega

import chatterlab as cl
from chatterlab._examples import example_path
from chatterlab.cli import main
from chatterlab.lobes._diagram import lobes
from chatterlab.lobes._mesh_error import with_mesh_error
from chatterlab.model._mesh import P_MIN, MeshEstimate, bound_factor, limit_line, mesh_verdict, width_verdict

SHAPER = "studies/traverse_shaper/model.toml"
#: the conforming family's Richardson estimate of the minimum b_lim (m) and
#: the size of its own last correction, |R - f_{k=4}| (the study's table:
#: 0.194886 and 0.194879 mm), which a bound must allow for
RICHARDSON, RICHARDSON_ERROR = 0.194886e-3, 0.007e-6
#: the main job's speeds and ceiling
SPEEDS, WIDTH_MAX = np.linspace(0.1, 1.0, 300), 1e-3


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


# ---------------------------------------------------------------------------- the estimate itself


def test_bound_factor_is_one_over_one_minus_two_to_minus_p():
    """Eq. M3: 2 at p = 1, 4/3 at p = 2, -> 1 as p grows; p <= 0 refused."""
    assert bound_factor(1.0) == 2.0 and P_MIN == 1.0
    assert bound_factor(2.0) == pytest.approx(4 / 3, rel=1e-15)
    with pytest.raises(ValueError):
        bound_factor(0.0)


def test_estimate_is_exact_for_a_pure_power_law():
    """f_h = f + C h^p with p >= 1 (Eq. M1 without its remainder): the
    bound with p = P_MIN is >= the true error, and equal to it at p = 1."""
    f, C = 3.0, -0.7
    for p in (1.0, 1.5, 2.0, 4.0):
        for h in (1.0, 0.1):
            e = MeshEstimate(f + C * h**p, f + C * (h / 2) ** p)
            true = abs(C) * h**p
            assert e.bound >= true * (1 - 1e-12)
            assert e.bound / true == pytest.approx(2 * (1 - 2.0**-p), rel=1e-9)  # Eq. M4


def test_no_estimate_where_a_limit_is_at_the_ceiling():
    e = MeshEstimate(np.array([1.0, np.inf]), np.array([1.1, 2.0]))
    assert np.isfinite(e.bound[0]) and np.isnan(e.bound[1])


# ---------------------------------------------------------------------------- cantilever oracle


@pytest.mark.parametrize("n", [1, 2, 4, 8])
def test_bound_covers_the_true_error_of_a_timoshenko_cantilever(beam_model_text, n):
    """Stocky cantilever (h/L = 0.25, shear matters): the first frequency on
    n elements against the exact Timoshenko root.  The element converges
    monotonically at order 2 (tests/test_elements.py), so the reported bound
    is >= the true error (p >= 1, Eq. M3) and at most twice it (Eq. M4: the
    ratio 2 (1 - 2^-p) < 2); at order 2 exactly the ratio is 3/2."""
    L, h, b = 1.0, 0.25, 0.05
    A, I = b * h, b * h**3 / 12
    exact = timoshenko_cantilever_omega(E, G, KAPPA, RHO, A, I, L) / (2 * np.pi)
    model = cl.loads_model(beam_model_text(L, h, elements=n))
    fine = model.with_finer_mesh()
    assert [bb.elements for bb in fine.beams] == [2 * n]
    f_h = cl.modes(cl.assemble(model), count=1).frequency_hz[0]
    f_h2 = cl.modes(cl.assemble(fine), count=1).frequency_hz[0]
    e = MeshEstimate(f_h, f_h2)
    true = abs(f_h - exact)
    assert true <= e.bound < 2 * true
    if n >= 4:  # asymptotic: the h^4 part is < 1 % of the h^2 part (test_elements.py)
        assert e.bound / true == pytest.approx(1.5, abs=0.02)


def test_modes_cli_reports_the_bound_per_frequency(beam_model_text, tmp_path, capsys):
    """``chatterlab modes --format json``: error_bound_hz covers the true error
    of each of the three lowest bending frequencies of a cantilever on 4
    elements (modes 1-3: the same argument, each exact root from the
    frequency equation)."""
    L, h, b = 1.0, 0.25, 0.05
    A, I = b * h, b * h**3 / 12
    path = tmp_path / "beam.toml"
    path.write_text(beam_model_text(L, h, elements=4))
    code, out, _ = run(capsys, "modes", str(path), "--count", "6", "--format", "json")
    assert code == 0
    doc = json.loads(out)
    mesh = doc["mesh"]
    assert mesh["beam_elements"] == 4 and mesh["fine_beam_elements"] == 8 and mesh["order"] == P_MIN
    f = np.array([m["frequency_hz"] for m in doc["modes"]])
    bending = [
        timoshenko_cantilever_omega(E, G, KAPPA, RHO, A, I, L, mode=k) / (2 * np.pi) for k in (1, 2, 3)
    ]
    for fe in bending:
        k = int(np.argmin(np.abs(f - fe)))  # the axial mode sits among them
        assert abs(f[k] - fe) <= mesh["error_bound_hz"][k]
    code, out, _ = run(capsys, "modes", str(path), "--count", "3")
    assert "df(h/2)" in out and "err <=" in out and out.count("\n") == 6  # title, mesh line, header, 3 rows


# ---------------------------------------------------------------------------- the shaper


def test_shaper_frequency_bounds_against_the_converged_mesh(capsys):
    """The seven lowest frequencies of the paper's mesh against the converged
    variant, allowing for the converged variant's own error (its bound,
    Eq. M3, on its own refinement).  Modes 1-4 and 6 are inside their bound.
    Modes 5 and 7 are not: on 1, 2, 4, 8 elements per beam mode 5 moves by
    -0.57, -0.70, -0.84 Hz (the changes grow: the mesh of one and two
    elements is pre-asymptotic for it, Eq. M1 does not hold yet), and the
    bound is low by a factor 1.9 (mode 5) and 1.07 (mode 7).  This pins the
    documented limitation (docs/lobes.md, "What it assumes"): the estimate is
    a bound only in the asymptotic range."""
    docs = {}
    for variant in (None, "converged"):
        argv = ["modes", SHAPER, "--count", "7", "--format", "json"] + (
            ["--variant", variant] if variant else []
        )
        code, out, _ = run(capsys, *argv)
        assert code == 0
        docs[variant] = json.loads(out)
    f = np.array([m["frequency_hz"] for m in docs[None]["modes"]])
    fc = np.array([m["frequency_hz"] for m in docs["converged"]["modes"]])
    bound = np.array(docs[None]["mesh"]["error_bound_hz"])
    own = np.array(docs["converged"]["mesh"]["error_bound_hz"])
    # the oracle's own error is below 1/20 of each bound (measured 1/12000 to 1/44): it decides no case
    assert np.all(own < 0.05 * bound)
    covered = np.abs(f - fc) <= bound + own
    assert covered.tolist() == [True, True, True, True, False, True, False]


@pytest.fixture(scope="module")
def shaper_diagram():
    model = cl.load_model(SHAPER)
    fz = cl.assemble(model).at()
    return with_mesh_error(lobes(fz, SPEEDS, width_max=WIDTH_MAX, verify=0), fz)


def test_shaper_minimum_bound_covers_the_richardson_value(shaper_diagram):
    """The paper's mesh: min b_lim 0.17779 mm, 0.19140 mm twice as fine
    (the study's N = 1 and N = 2 rows); the bound 2|d| = 15.3 % covers the
    true error, 9.6 % against the Richardson estimate (whose own
    uncertainty is allowed for), and the 16-element value 0.194576 mm."""
    d = shaper_diagram
    m = d.meta
    b_h = d.absolute_minimum["width"]
    assert b_h == pytest.approx(0.177791e-3, rel=1e-5)
    assert m["mesh_fine_absolute_min_m"] == pytest.approx(0.191404e-3, rel=1e-5)
    assert m["mesh_beam_elements"] == 6 and m["mesh_fine_beam_elements"] == 12 and m["mesh_order"] == 1.0
    bound = m["mesh_absolute_min_error_bound"] * b_h
    assert bound == pytest.approx(2 * (m["mesh_fine_absolute_min_m"] - b_h), rel=1e-12)
    assert abs(b_h - RICHARDSON) + RICHARDSON_ERROR <= bound
    assert abs(b_h - 0.194576e-3) <= bound
    assert "discretisation error of this diagram's minimum <= 15.3%" in m["mesh"]
    assert "min b_lim 0.1914 mm (+7.7%)" in m["mesh"]
    assert m["mesh"] in d.summary()


@pytest.fixture(scope="module")
def converged_diagram():
    model = cl.load_model(SHAPER, variant="converged")
    fz = cl.assemble(model).at()
    return with_mesh_error(lobes(fz, SPEEDS, width_max=WIDTH_MAX, verify=0), fz)


def test_the_envelope_change_is_no_bound_per_speed(shaper_diagram, converged_diagram):
    """docs/lobes.md, "What it assumes": per speed, 2|d| of the paper's mesh
    covers the error against the converged variant (allowing its stated 1 %)
    at most speeds but not at all (measured 257 of 297): where another
    lobe sets the envelope on h/2, Eq. M1 fails at that speed.  So the
    envelope is reported as a change, never as a bound."""
    fine = lobes(
        cl.assemble(cl.load_model(SHAPER).with_finer_mesh()).at(), SPEEDS, width_max=WIDTH_MAX, verify=0
    )
    b, ref = shaper_diagram.b_lim, converged_diagram.b_lim
    e = MeshEstimate(b, fine.b_lim)
    both = np.isfinite(e.bound) & np.isfinite(ref)
    covered = e.bound[both] >= np.abs(b[both] - ref[both]) - 0.01 * ref[both]
    assert 0.5 * both.sum() < covered.sum() < both.sum()
    assert (
        "envelope moves by" in shaper_diagram.meta["mesh"]
        and "envelope <=" not in shaper_diagram.meta["mesh"]
    )


def test_converged_variant_reports_a_small_error(converged_diagram):
    """The shipped converged mesh (stated tolerance 1 %): its minimum moves by
    far less than 1 % twice as fine, and the bound covers its error against
    the Richardson value (measured -0.012 %)."""
    d = converged_diagram
    b_h = d.absolute_minimum["width"]
    bound = d.meta["mesh_absolute_min_error_bound"] * b_h
    assert d.meta["mesh_absolute_min_error_bound"] < 0.01
    assert abs(b_h - RICHARDSON) <= bound + RICHARDSON_ERROR
    assert "--variant converged" not in d.meta["mesh"]  # it is the one in use
    # from another variant it would change more than the mesh: not advised
    printed = cl.load_model(SHAPER, variant="printed")
    verdict, line = mesh_verdict(printed, "stable", -1.0, "unstable", 0.1)
    assert verdict == "undetermined" and "--variant" not in line and "elements = N" in line


def test_lobes_cli_prints_the_mesh_line_and_writes_the_attributes(tmp_path, capsys):
    xr = pytest.importorskip("xarray")
    out = tmp_path / "lobes.nc"
    code, text, _ = run(
        capsys,
        "lobes",
        SHAPER,
        "--speed",
        "0.1",
        "1.0",
        "--width-max",
        "1",
        "--verify",
        "0",
        "--out",
        str(out),
    )
    assert code == 0
    lines = [ln for ln in text.splitlines() if ln.strip().startswith("mesh:")]
    assert len(lines) == 1 and lines[0].strip().startswith(
        "mesh: 6 beam elements; twice as fine: min b_lim 0.1914"
    )
    with xr.open_dataset(out) as ds:
        a = ds.attrs
        assert int(a["mesh_beam_elements"]) == 6 and int(a["mesh_fine_beam_elements"]) == 12
        assert float(a["mesh_fine_absolute_min_m"]) == pytest.approx(0.191404e-3, rel=1e-5)
        assert float(a["mesh_absolute_min_error_bound"]) == pytest.approx(
            2 * float(a["mesh_absolute_min_change"])
        )
        assert 0 < float(a["mesh_envelope_change_median"]) <= float(a["mesh_envelope_change_max"])
        assert a["mesh"] == lines[0].strip()


def test_the_line_without_a_minimum_on_one_of_the_meshes():
    """inf on either mesh: no bound, and the line says which (no number made up)."""
    from chatterlab.lobes._mesh_error import mesh_line

    model = cl.load_model(SHAPER)
    base = {"mesh_envelope_change_median": float("nan"), "mesh_envelope_change_max": float("nan")}
    for b_h, b_h2, words in ((np.inf, np.inf, "no b_lim below the ceiling"), (np.inf, 2e-4, "not converged")):
        e = MeshEstimate(b_h, b_h2)
        meta = {
            **base,
            "mesh_fine_absolute_min_m": b_h2,
            "mesh_absolute_min_change": float(e.relative_change),
            "mesh_absolute_min_error_bound": float(e.relative_bound),
            "mesh_envelope_speeds": 0,
        }
        line = mesh_line(meta, model)
        assert words in line and "<=" not in line and "nan" not in line


# ---------------------------------------------------------------------------- verdicts


def test_the_verdict_that_flips_under_refinement_is_undetermined(capsys):
    """0.2 mm at 0.1 m/s: stable on the paper's mesh (margin -0.0024 1/s) and
    on one twice as fine (-0.0166 1/s), unstable from 8 elements on
    (mesh_convergence.py); the margin is within 2|d| = 0.029 1/s of zero,
    so the claim of stability does not survive."""
    code, out, _ = run(capsys, "roots", SHAPER, "--width", "0.2", "--speed", "0.1", "--format", "json")
    assert code == 0
    doc = json.loads(out)
    assert doc["verdict"] == "undetermined"
    assert doc["mesh"]["coarse_verdict"] == "stable" and doc["mesh"]["fine_verdict"] == "stable"
    assert doc["mesh"]["abscissa_error_bound_per_s"] >= abs(doc["abscissa_per_s"])
    assert "refine the beams or use the converged variant" in doc["mesh"]["line"]
    code, out, _ = run(capsys, "roots", SHAPER, "--width", "0.2", "--speed", "0.1")
    assert (
        out.startswith("verdict: undetermined")
        and sum(ln.strip().startswith("mesh:") for ln in out.splitlines()) == 1
    )
    # the converged mesh decides it: unstable (b_lim 0.1952 mm there), and the finer mesh agrees
    code, out, _ = run(
        capsys,
        "roots",
        SHAPER,
        "--variant",
        "converged",
        "--width",
        "0.2",
        "--speed",
        "0.1",
        "--format",
        "json",
    )
    assert json.loads(out)["verdict"] == "unstable"


def test_a_clear_verdict_stands_with_its_mesh_line(capsys):
    """0.1 mm at 0.1 m/s, half the limit on every mesh: stable, and says why."""
    code, out, _ = run(capsys, "roots", SHAPER, "--width", "0.1", "--speed", "0.1", "--format", "json")
    doc = json.loads(out)
    assert doc["verdict"] == "stable"
    assert doc["mesh"]["fine_verdict"] == "stable"
    assert doc["mesh"]["abscissa_error_bound_per_s"] < abs(doc["abscissa_per_s"])


class _M:  # the fields mesh_verdict reads
    beams = (type("B", (), {"elements": 1})(),)
    beam_elements = 1
    raw = json.dumps({"variant": {"converged": {}}})
    variant = None


@pytest.mark.parametrize(
    ("coarse", "fine", "expected"),
    [
        (("stable", -1.0), ("unstable", 0.1), "undetermined"),  # the finer mesh contradicts it
        (("unstable", 0.5), ("stable", -0.1), "undetermined"),
        (("stable", -1.0), ("stable", -1.1), "stable"),  # 2|d| = 0.2 < 1
        (("stable", -0.1), ("stable", -0.2), "undetermined"),  # 2|d| = 0.2 >= 0.1
        (("undetermined", np.nan), ("stable", -1.0), "undetermined"),
    ],
)
def test_mesh_verdict_rules(coarse, fine, expected):
    verdict, line = mesh_verdict(_M(), coarse[0], coarse[1], fine[0], fine[1])
    assert verdict == expected and line.startswith("mesh: ") and "\n" not in line


@pytest.mark.parametrize(
    ("width", "limit", "fine", "expected"),
    [
        (1.0, 2.0, 2.1, "stable"),  # margin 1 > 2|d| = 0.2
        (1.0, 2.0, 1.5, "undetermined"),  # margin 1 <= 2|d| = 1: inside the bound
        (1.0, 2.0, 0.9, "undetermined"),  # the finer mesh contradicts it
        (3.0, 2.0, 2.1, "unstable"),  # past both limits by more than 0.2
        (2.05, 2.0, 2.1, "undetermined"),  # unstable on h, stable on h/2
        (2.15, 2.0, 2.1, "undetermined"),  # unstable on both, but 0.15 <= 0.2
        (1.0, np.inf, 2.0, "undetermined"),  # a limit on one mesh only: no bound
        (1.0, np.inf, np.inf, "stable"),  # the ceiling claim is the caller's
    ],
)
def test_width_verdict_rules(width, limit, fine, expected):
    """A cut is claimed stable (or unstable) only when the finer mesh agrees and
    the limit's error bound, 2|d| (Eq. M3 at p = 1), is below its distance to the cut."""
    verdict, line = width_verdict(_M(), width, limit, fine)
    assert verdict == expected and line.startswith("mesh: ") and "\n" not in line


def test_limit_line_states_the_change_and_the_bound():
    """0.2 -> 0.21 mm: +5.0 %, bound 2 x 5 % = 10.0 %; at the ceiling no bound is claimed."""
    line = limit_line(_M(), "a_lim", 0.2e-3, 0.21e-3)
    assert "a_lim 0.21 mm (+5.0%)" in line and "<= 10.0%" in line and "--variant converged" in line
    assert "not converged" in limit_line(_M(), "a_lim", 0.2e-3, np.inf)
    assert "not converged" in limit_line(_M(), "a_lim", np.inf, 0.2e-3)
    assert "no estimate" in limit_line(_M(), "a_lim", np.inf, np.inf)


def test_python_lobes_says_when_the_error_was_not_estimated():
    """The Python entry point on a model with beams: without mesh_error the
    summary says the error was not estimated (no silent omission); with it,
    the same facts as the command line (the minimum twice as fine, 0.19140 mm)."""
    fz = cl.assemble(cl.load_model(SHAPER)).at(0.85)
    plain = cl.lobes.lobes(fz, SPEEDS[::10], width_max=WIDTH_MAX, verify=0)
    assert "discretisation error was not estimated" in plain.summary()
    assert "mesh_beam_elements" not in plain.meta
    est = cl.lobes.lobes(fz, SPEEDS[::10], width_max=WIDTH_MAX, verify=0, mesh_error=True)
    assert est.meta["mesh_fine_absolute_min_m"] == pytest.approx(0.191404e-3, rel=1e-5)
    assert "twice as fine: min b_lim 0.1914 mm" in est.summary()
    assert (
        "not estimated"
        in cl.lobes(cl.load_model(SHAPER), SPEEDS[::10], width_max=WIDTH_MAX, verify=0).summary()
    )


# ---------------------------------------------------------------------------- no beams


def test_a_model_without_beams_is_unchanged(capsys):
    """A 1-DOF turning tool (no [[beam]]): no mesh line, no attributes, the
    same verdict document."""
    model = cl.load_model(example_path("damped_turning.toml"))
    assert not model.beams and model.with_finer_mesh() is model
    fz = cl.assemble(model).at()
    d = lobes(fz, np.linspace(500, 3000, 20), width_max=5e-3, verify=0)
    assert with_mesh_error(d, fz) is d
    code, out, _ = run(
        capsys,
        "roots",
        "example:damped_turning.toml",
        "--width",
        "0.5",
        "--speed",
        "1500",
        "--format",
        "json",
    )
    assert "mesh" not in json.loads(out)
    code, out, _ = run(capsys, "modes", "example:damped_turning.toml")
    assert "df(h/2)" not in out and "mesh:" not in out


def test_the_figure_says_what_the_mesh_costs(shaper_diagram):
    """The lobe figure of a model with beams carries the mesh's line (right
    of the bottom panel's title), with the numbers of the diagram's meta; a
    diagram without the estimate draws none."""
    import dataclasses

    import matplotlib

    matplotlib.use("Agg")
    from chatterlab.plot import plot_lobes

    m = shaper_diagram.meta
    axes = plot_lobes(shaper_diagram)
    note = axes[-1].get_title(loc="right")
    assert f"beam mesh of {m['mesh_beam_elements']} elements" in note
    assert f"within {m['mesh_absolute_min_error_bound']:.0%}" in note
    assert f"moves {m['mesh_envelope_change_median']:.0%}" in note
    # a claim of no chatter at the ceiling that the finer mesh does not confirm: its legend entry says so
    assert m["mesh_free_speeds_fine_limited"] > 0
    labels = [t.get_text() for t in axes[0].get_legend().get_texts()]
    assert any("ceiling\n(not confirmed on a mesh twice as fine)" in t for t in labels)
    bare = dataclasses.replace(shaper_diagram, meta={k: v for k, v in m.items() if not k.startswith("mesh")})
    assert plot_lobes(bare)[-1].get_title(loc="right") == ""
