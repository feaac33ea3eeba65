"""The discretisation error of milling lobes of a tool with beams
(chatterlab/cli/_milling.py ``_with_mesh_error``; docs/milling.md, "The beam
mesh"; docs/lobes.md, Eqs. M1-M5), and the Floquet search where a free
multiplier is zero in floating point.

Oracle: the end mill of studies/milling/tool_cantilever.toml refined
3, 6, ..., 96 elements.  Its limit at 8000 rpm converges at order 2
(changes 6.4e-6, 1.2e-6, 2.8e-7, 6.9e-8, 1.7e-8 mm... ratios 4-5), so the
96-element value is a reference whose own error, by Eq. M3 at p = 1, is at
most 2 |a_96 - a_48|; the bound the command prints for the 3-element mesh
must cover |a_3 - a_96| less that.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from chatterlab.cli import main
from chatterlab.cli._milling import _structure
from chatterlab.lobes._milling import milling_lobes
from chatterlab.model._reader import load_model

TOOL = "studies/milling/tool_cantilever.toml"
CEILING = 0.1087  # m: the command's own ceiling for these speeds (three times the ZOA limit)


def limit(elements: int, rpm: float) -> float:
    """a_lim (m) of the end mill refined to ``elements`` beam elements."""
    m = load_model(TOOL)
    while m.beam_elements < elements:
        m = m.with_finer_mesh()
    assert m.beam_elements == elements
    S, _, _ = _structure(m, None)
    return float(milling_lobes(S, np.array([rpm]), depth_max=CEILING).b_lim[0])


@pytest.fixture(scope="module")
def reference() -> tuple[float, float]:
    """The 96-element limit at 8000 rpm and the bound of its own error (Eq. M3, p = 1)."""
    a48, a96 = limit(48, 8000.0), limit(96, 8000.0)
    return a96, 2.0 * abs(a96 - a48)


def test_the_search_without_the_rates_at_zero_finds_the_limit(reference, monkeypatch):
    """Where a kept mode's free multiplier is 0 in floating point (the end
    mill at 12 elements on some LAPACK builds: whether it underflows is
    round-off), C_d is singular, the projection of the rates at a = 0
    (C_d^-1) does not exist, and the search takes the plain rates (it raised
    LinAlgError before).  Forced here on every mesh the search builds, so
    the test holds on any BLAS: the limit lies within the mesh bound of the
    reference."""
    from chatterlab.frequency import SpectralMonodromy

    calls: list[int] = []

    def plain(self):
        calls.append(1)
        return None

    monkeypatch.setattr(SpectralMonodromy, "_tangent_free", plain)
    a12 = limit(12, 8000.0)
    assert calls  # the search asked for the rates, and went on without them
    monkeypatch.undo()
    a24 = limit(24, 8000.0)
    ref, ref_err = reference
    assert abs(a12 - ref) <= 2.0 * abs(a24 - a12) + ref_err


def test_a_zero_free_multiplier_gives_no_rates_at_zero(monkeypatch):
    """The guard itself: the free map of the 12-element search with its
    first state decoupled (row and column 0 of C_d zero) has the multiplier
    0 exactly (LAPACK's balancing isolates it), and the rates at a = 0 are
    declined, not computed from a singular C_d."""
    import copy

    from chatterlab.frequency import SpectralMonodromy

    seen: list = []
    original = SpectralMonodromy._tangent_free

    def spy(self):
        seen.append(self)
        return original(self)

    monkeypatch.setattr(SpectralMonodromy, "_tangent_free", spy)
    limit(12, 8000.0)
    monkeypatch.undo()
    sm = copy.copy(seen[0])
    X0 = sm.X0.copy()
    X0[0, : sm.d] = 0.0
    X0[: sm.d, 0] = 0.0
    sm.X0 = X0
    assert 0.0 in np.linalg.eigvals(X0[: sm.d, : sm.d])
    assert SpectralMonodromy._tangent_free(sm) is None


def test_lobes_prints_the_bound_of_the_smallest_limit(tmp_path, capsys, reference):
    """The line names the speed checked, the limit there on 6 elements and
    the bound, which covers the true error of the 3-element limit; the netCDF
    file carries the same numbers."""
    out = tmp_path / "m.nc"
    code = main(["lobes", TOOL, "--speed", "8000", "12000", "--points", "3", "--quiet", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0
    line = next(s for s in text.splitlines() if "mesh:" in s)
    assert "3 beam elements" in line and "a_lim at 8000 rpm" in line and "not computed twice as fine" in line
    with xr.open_dataset(out) as ds:
        at = ds.attrs
        a3 = float(ds["a_lim"].sel(speed=8000.0))
    assert at["mesh_beam_elements"] == 3 and at["mesh_fine_beam_elements"] == 6
    assert at["mesh_check_speed_rpm"] == 8000.0
    ref, ref_err = reference
    # the same search on the finer mesh; its ceiling (from 3 speeds) sets other depth stages, so the two
    # agree to the convergence check's target, 1e-6 relative each
    assert at["mesh_fine_min_m"] == pytest.approx(limit(6, 8000.0), rel=2e-6)
    assert abs(a3 - ref) <= at["mesh_min_error_bound"] * a3 + ref_err


def test_a_claim_of_no_chatter_is_searched_again_on_the_finer_mesh(capsys):
    """Below every limit (a 5 mm ceiling, the limits are 10.8-15.5 mm) each
    speed claims stability up to the ceiling: all are searched twice as fine."""
    code = main(["lobes", TOOL, "--speed", "8000", "12000", "--points", "3", "--quiet", "--width-max", "5"])
    text = capsys.readouterr().out
    assert code == 0
    assert "the 3 speeds with no a_lim below the ceiling have none on the mesh twice as fine either" in text


def test_a_tool_without_beams_gets_no_mesh_line(capsys):
    code = main(["lobes", "studies/milling/benchmark_1dof.toml", "--speed", "10000", "12000", "--points", "3",
                 "--quiet"])  # fmt: skip
    assert code == 0 and "mesh:" not in capsys.readouterr().out


@pytest.mark.parametrize(
    ("width_mm", "expected"), [(5.0, "stable"), (10.8, "undetermined"), (12.0, "unstable")]
)
def test_roots_judges_a_milling_cut_on_both_meshes(capsys, width_mm, expected):
    """10.8 mm at 8000 rpm lies between the limit on 6 elements (10.7966 mm)
    and on 3 (10.8029 mm), and above the converged 10.7950 mm: the 3-element
    mesh's "stable" was wrong, and it is now undetermined; cuts far from the
    limit keep their verdict (the margin ln|mu|/T against twice its change)."""
    import json

    code = main(["roots", TOOL, "--width", str(width_mm), "--speed", "8000", "--format", "json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and doc["verdict"] == expected and doc["mesh"]["verdict"] == expected
    assert doc["mesh"]["beam_elements"] == 3 and doc["mesh"]["fine_beam_elements"] == 6


def test_python_lobes_of_a_beam_tool_checks_its_mesh_on_request():
    """The library route: without mesh_error the summary says the error was
    not estimated; with it, the command's facts (the limit at 8000 rpm on
    6 elements, as the command finds it with the same ceiling)."""
    import chatterlab as cl

    m = load_model(TOOL)
    rpm = np.array([8000.0, 12000.0])
    plain = cl.lobes(m, rpm, width_max=CEILING)
    assert "discretisation error was not estimated" in plain.summary()
    est = cl.lobes(m, rpm, width_max=CEILING, mesh_error=True)
    assert est.meta["mesh_check_speed_rpm"] == 8000.0
    assert est.meta["mesh_fine_min_m"] == limit(6, 8000.0)  # the same search, ceiling and mesh
    assert "a_lim at 8000 rpm" in est.summary()
