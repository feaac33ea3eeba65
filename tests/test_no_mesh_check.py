"""``chatterlab lobes --no-mesh-check``: the check on a mesh twice as fine
skipped (it doubles an atlas's cost), and every output saying so.

Oracle: the option removes the check and nothing else, so each limit is
bit-identical to the same run with the check (the check reads the coarse
results and never changes them); the summary, the file's ``mesh`` and
``mesh_estimated`` attributes and the figure (bottom panel's note, the
legend of a no-chatter claim) say the error was not estimated; a model
without beams is unchanged.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from chatterlab.cli import main

SHAPER = "studies/traverse_shaper/model.toml"
TOOL = "studies/milling/tool_cantilever.toml"
NOT_ESTIMATED = "its discretisation error was not estimated (--no-mesh-check"


def _run(capsys, args: list[str]) -> tuple[int, str]:
    code = main(args)
    return code, capsys.readouterr().out


def _attrs_and(path, name: str) -> tuple[dict, np.ndarray]:
    with xr.open_dataset(path) as ds:
        return dict(ds.attrs), ds[name].values.copy()


def test_single_diagram_without_the_check_says_so_and_keeps_every_limit(tmp_path, capsys):
    job = ["lobes", SHAPER, "--speed", "0.8", "0.9", "--points", "30", "--width-max", "1", "--verify", "0"]
    code, checked = _run(capsys, [*job, "--out", str(tmp_path / "a.nc")])
    assert code == 0 and "twice as fine: min b_lim" in checked
    code, text = _run(capsys, [*job, "--out", str(tmp_path / "b.nc"), "--no-mesh-check"])
    assert code == 0
    line = next(s for s in text.splitlines() if "mesh:" in s)
    assert "6 beam elements" in line and NOT_ESTIMATED in line and "twice as fine" not in line
    a, ba = _attrs_and(tmp_path / "a.nc", "b_lim")
    b, bb = _attrs_and(tmp_path / "b.nc", "b_lim")
    np.testing.assert_array_equal(ba, bb)
    assert b["mesh_estimated"] == 0 and NOT_ESTIMATED in b["mesh"]
    assert not any(k.startswith("mesh_fine") for k in b) and "mesh_fine_beam_elements" in a


def test_the_figure_says_the_mesh_was_not_checked(tmp_path):
    """Legend of the no-chatter claims and the bottom panel's note: 0.8-0.9
    m/s on 200 speeds holds 8 with no b_lim below a 1 mm ceiling (the
    shaper's docs figure marks them), so the claim's legend entry is drawn."""
    pytest.importorskip("matplotlib")
    from chatterlab.lobes import lobes
    from chatterlab.model import load_model
    from chatterlab.plot import headless, plot_lobes
    from chatterlab.structure import assemble

    d = lobes(assemble(load_model(SHAPER)).at(None), np.linspace(0.8, 0.9, 200), width_max=1e-3, verify=0)
    assert d.meta["mesh_estimated"] == 0  # without mesh_error=True: not estimated
    assert np.isinf(d.b_lim).any()  # a claim of no chatter below the ceiling is drawn
    with headless():
        axes = plot_lobes(d, title="t")
    fig = np.ravel(axes)[0].figure
    legend = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]
    assert any("not checked on a mesh twice as fine" in t for t in legend), legend
    titles = [ax.get_title(loc="right") for ax in fig.axes]
    assert "beam mesh: discretisation error not estimated" in titles


def test_atlas_without_the_check_keeps_every_limit(tmp_path, capsys):
    job = ["lobes", SHAPER, "--speed", "0.15", "0.2", "--points", "8", "--width-max", "1"]
    job += ["--positions", "0.7", "0.85", "2", "--quiet", "--jobs", "1"]
    code, checked = _run(capsys, [*job, "--out", str(tmp_path / "a.nc")])
    assert code == 0 and "twice as fine:" in checked
    code, text = _run(capsys, [*job, "--out", str(tmp_path / "b.nc"), "--no-mesh-check"])
    assert code == 0 and NOT_ESTIMATED in text and "twice as fine" not in text
    a, ba = _attrs_and(tmp_path / "a.nc", "b_lim")
    b, bb = _attrs_and(tmp_path / "b.nc", "b_lim")
    np.testing.assert_array_equal(ba, bb)
    assert b["mesh_estimated"] == 0 and not any(k.startswith("mesh_fine") for k in b)
    assert "mesh_fine_worst_m" in a


def test_milling_without_the_check_keeps_every_limit(tmp_path, capsys):
    job = ["lobes", TOOL, "--speed", "8000", "12000", "--points", "3", "--quiet"]
    code, checked = _run(capsys, [*job, "--out", str(tmp_path / "a.nc")])
    assert code == 0 and "twice as fine" in checked
    code, text = _run(capsys, [*job, "--out", str(tmp_path / "b.nc"), "--no-mesh-check"])
    assert code == 0
    line = next(s for s in text.splitlines() if "mesh:" in s)
    assert "3 beam elements" in line and NOT_ESTIMATED in line
    _, aa = _attrs_and(tmp_path / "a.nc", "a_lim")
    b, ab = _attrs_and(tmp_path / "b.nc", "a_lim")
    np.testing.assert_array_equal(aa, ab)
    assert b["mesh_estimated"] == 0


@pytest.mark.parametrize(
    "source",
    [
        ["studies/milling/benchmark_1dof.toml"],
        [
            "--frf",
            "studies/tap_test/tool_point.csv",
            "--teeth",
            "3",
            "--kt",
            "6e8",
            "--kn",
            "2e8",
            "--immersion",
            "0.5",
        ],
    ],
    ids=["no beams", "measured FRF"],
)
def test_the_option_is_refused_where_there_is_nothing_to_skip(source, tmp_path, capsys):
    """A model without beams or a measured FRF has no mesh to check: the
    option is refused (one line, exit 2, nothing written), not ignored."""
    out = tmp_path / "x.nc"
    code = main(
        [
            "lobes",
            *source,
            "--speed",
            "8000",
            "12000",
            "--points",
            "5",
            "--quiet",
            "--no-mesh-check",
            "--out",
            str(out),
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--no-mesh-check" in err[0] and "drop it" in err[0]
    assert not out.exists()
