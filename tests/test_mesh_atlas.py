"""The discretisation error of a stability atlas of a model with beams
(``chatterlab lobes --positions``; chatterlab/cli/_lobes.py ``_atlas_mesh``;
docs/lobes.md, Eqs. M1-M5).

Oracle: the same atlas of the shaper's ``converged`` variant (62 beam
elements, whose own change on a mesh twice as fine is printed with it): the
bound printed for the paper's mesh (6 elements) must cover the true error of
its worst case, less the converged atlas's own bound.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from chatterlab.cli import main

SHAPER = "studies/traverse_shaper/model.toml"
GRID = ["--speed", "0.1", "1.0", "--points", "40", "--width-max", "1", "--positions", "0.6", "0.85", "2"]


def atlas(tmp_path, capsys, *extra: str) -> tuple[str, dict]:
    out = tmp_path / f"atlas{len(extra)}.nc"
    code = main(["lobes", SHAPER, *extra, *GRID, "--quiet", "--jobs", "1", "--out", str(out)])
    assert code == 0
    with xr.open_dataset(out) as ds:
        attrs = dict(ds.attrs)
        attrs["b_lim"] = ds["b_lim"].values
    return capsys.readouterr().out, attrs


def test_the_worst_case_bound_covers_the_converged_atlas(tmp_path, capsys):
    text, a = atlas(tmp_path, capsys)
    _, c = atlas(tmp_path, capsys, "--variant", "converged")
    assert a["mesh_beam_elements"] == 6 and a["mesh_fine_beam_elements"] == 12
    assert c["mesh_beam_elements"] == 62
    worst, conv = float(np.nanmin(a["b_lim"])), float(np.nanmin(c["b_lim"]))
    conv_err = c["mesh_worst_error_bound"] * conv
    assert abs(worst - conv) <= a["mesh_worst_error_bound"] * worst + conv_err
    # each position's line shows its minimum twice as fine, the attribute the same numbers
    lines = [s for s in text.splitlines() if s.lstrip().startswith("position")]
    assert len(lines) == 2 and all("twice as fine:" in s for s in lines)
    assert np.nanmin(a["mesh_position_min_fine_m"]) == a["mesh_fine_worst_m"]
    assert "worst-case b_lim" in text and text.rstrip().endswith("--variant converged")
