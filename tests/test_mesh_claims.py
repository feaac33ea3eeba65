"""Claims of stability against a mesh check that establishes nothing, and
the figures' marks of the check (review of the session's mesh changes).

Oracles: the verdict rules themselves (docs/lobes.md, "The discretisation
error of a result"): only a limit on both meshes bounds its error (Eq. M3),
so a limit at the ceiling on one mesh only, or a NaN (the lobes establish
nothing there), can never confirm a verdict; only ``inf`` on the finer mesh
(no limit below its ceiling either) confirms a claim of no chatter.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from chatterlab.model import load_model

SHAPER = "studies/traverse_shaper/model.toml"
TOOL = "studies/milling/tool_cantilever.toml"


def _ssv_result():
    """Three speeds at one (RVA, RVF): a limit at the first, none below the
    ceiling at the other two (claims of no chatter)."""
    from chatterlab.frequency._floquet_ssv_limit import SsvLimits

    b = np.array([3e-4, math.inf, math.inf]).reshape(3, 1, 1)
    return SsvLimits(
        np.array([1.0, 2.0, 3.0]), np.array([0.1]), np.array([0.5]), b, np.full(b.shape, 100.0),
        np.zeros(b.shape), "sine", "spectral", 1e-3, 4,
    )  # fmt: skip


@pytest.fixture(scope="module")
def shaper():
    return load_model(SHAPER)


@pytest.mark.parametrize("limit, fine", [(math.nan, 2e-4), (2e-4, math.nan), (math.nan, math.nan)])
def test_a_limit_that_establishes_nothing_decides_nothing(shaper, limit, fine):
    from chatterlab.model._mesh import width_verdict

    verdict, line = width_verdict(shaper, 1e-4, limit, fine)
    assert verdict == "undetermined"
    assert "establish nothing at this speed" in line and "nan" not in line


@pytest.mark.parametrize("limit, fine", [(math.inf, 2e-4), (2e-4, math.inf)])
def test_a_limit_at_the_ceiling_on_one_mesh_only_has_no_bound(shaper, limit, fine):
    """Width below both limits (stable on both meshes), but one of them is
    the ceiling: the limit's error 2 |b_{h/2} - b_h| is unbounded, the
    verdict undetermined, and the line says why in numbers (no 'nan%')."""
    from chatterlab.model._mesh import width_verdict

    verdict, line = width_verdict(shaper, 1e-4, limit, fine)
    assert verdict == "undetermined"
    assert "no limit below the ceiling on" in line and "0.2 mm on the other" in line
    assert "nan" not in line and "inf" not in line


def test_both_at_the_ceiling_and_a_bounded_margin_still_decide(shaper):
    from chatterlab.model._mesh import width_verdict

    assert width_verdict(shaper, 1e-4, math.inf, math.inf)[0] == "stable"
    # margin 1e-4 against a bound 2 |2.1e-4 - 2e-4| = 2e-5: confirmed
    assert width_verdict(shaper, 1e-4, 2e-4, 2.1e-4)[0] == "stable"
    assert width_verdict(shaper, 3e-4, 2e-4, 2.1e-4)[0] == "unstable"


def test_ssv_a_claim_the_finer_mesh_establishes_nothing_about_is_undetermined(shaper):
    """ssv_check: a point with no limit below the ceiling is confirmed only
    by inf on the finer mesh; a NaN there (its search established nothing)
    leaves it undetermined, as a finite limit does."""
    from chatterlab.cli._mesh_checks import ssv_check

    inf = math.inf
    res = _ssv_result()
    fine = {1.0: 3.1e-4, 2.0: math.nan, 3.0: inf}
    out, rec = ssv_check(shaper, res, lambda pts: [fine[s] for s, _, _ in pts])
    assert np.isnan(out.b_lim[1, 0, 0]) and np.isinf(out.b_lim[2, 0, 0])
    assert rec["mesh_undetermined_points"] == 1
    assert "twice as fine nothing established at speed 2" in rec["mesh"]
    assert "the other" not in rec["mesh"]  # every point was checked


def test_the_figures_carry_the_mark_of_an_unchecked_mesh():
    """The single diagram's bottom note, a milling diagram's note, and an
    atlas's legend: 'not estimated' / 'not checked' where the mesh check was
    not run (mesh_estimated = 0), nothing of it on a model without beams."""
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from chatterlab.lobes import lobes
    from chatterlab.plot._lobe_panel import mesh_claim, mesh_note

    assert mesh_claim({"mesh_estimated": 0}) == "not checked"
    assert mesh_claim({"mesh_free_points_fine_limited": 2}) == "not confirmed"
    assert mesh_claim({"mesh_free_speeds_fine_limited": 0}) == "" and mesh_claim(None) == ""
    _, ax = plt.subplots()
    mesh_note(ax, {})
    assert ax.get_title(loc="right") == ""
    plt.close("all")

    ml = lobes(load_model(TOOL), np.array([8000.0, 12000.0]))  # Floquet, mesh_error=False
    assert ml.meta["mesh_estimated"] == 0
    ax = ml.plot()
    assert ax.get_title(loc="right") == "beam mesh: discretisation error not estimated"
    plt.close("all")


def test_the_ssv_and_runout_figures_mark_what_they_do_not_claim(shaper):
    """plot_ssv marks the points with no limit below the ceiling and the
    undetermined ones (they were dropped: a figure of empty axes), and
    plot_runout the speeds without an amplitude (chatter, undetermined);
    both carry the mesh note of a model with beams."""
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    from types import SimpleNamespace

    import matplotlib.pyplot as plt

    from chatterlab.cli._mesh_checks import ssv_check
    from chatterlab.plot._sle import plot_runout

    inf = math.inf
    res = _ssv_result()
    out, _ = ssv_check(shaper, res, lambda pts: [{1.0: 3.1e-4, 2.0: 2e-4, 3.0: inf}[s] for s, _, _ in pts])
    ax = out.plot()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "no limit below the ceiling" in labels and "undetermined" in labels
    assert "1 undetermined on a mesh twice as fine" in ax.get_title(loc="right")
    plt.close("all")

    run = SimpleNamespace(
        speeds=np.array([1000.0, 2000.0, 3000.0]), amplitude=np.array([1e-8, np.nan, np.nan]),
        verdict=["stable", "unstable", "undetermined"], eccentricity=1e-5, width=1e-4,
        mesh={"mesh_beam_elements": 6, "mesh_amplitude_error_bound_max": 0.04, "mesh_undetermined_speeds": 1},
    )  # fmt: skip
    ax = plot_runout(run)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "chatter (no response)" in labels and "undetermined" in labels
    assert ax.get_title(loc="right") == (
        "beam mesh of 6 elements; amplitude within 4%; 1 undetermined on a mesh twice as fine"
    )
    plt.close("all")
