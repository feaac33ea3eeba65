"""The discretisation error of ``recommend``, ``absorber``, ``active``,
``sensitivity`` and ``risk`` on a model with beams (chatterlab/model/_mesh.py;
docs/lobes.md, Eqs. M1-M5).

Oracles from mathematics, not recordings:

* the cut 0.2 mm wide at 0.1 m/s is stable on the shaper's paper mesh and
  unstable on a converged one (the converged variant's limit there is
  0.195 mm): recommended at that speed and width it is not reported stable;
* a cut far below every mesh's limit (20 % of it, the converged variant's
  limit included) is confirmed on the mesh twice as fine;
* the converged variant's limit lies within the bound the coarse mesh
  reports for its own limit (Eq. M3: |b_h - b| <= 2 |b_{h/2} - b_h|);
* a model without beams: what the command writes is what the library
  gives, nothing added.
"""

from __future__ import annotations

import json

import numpy as np

import chatterlab as cl
from chatterlab.cli import main
from chatterlab.lobes import lobes

SHAPER = "studies/traverse_shaper/model.toml"
TURNING = "studies/process_damping/turning.toml"


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def _attrs(path) -> dict:
    return json.loads(path.read_text())["attrs"]


# ---------------------------------------------------------------------------- recommend


def test_recommend_at_the_oracle_cut_is_undetermined(tmp_path, capsys):
    """0.2 mm (the tool's largest depth, margin 0) at 0.1 m/s: the roots on
    the paper's mesh say stable, the limit on h (0.204 mm) is above the cut
    by less than its error bound (twice its change to 0.272 mm on h/2), and
    the converged variant's (0.195 mm) is below it: the cut is undetermined,
    the status 1, the file says so."""
    out = tmp_path / "r.json"
    code, text, err = run(
        capsys, "recommend", SHAPER, "--speed", "0.0998", "0.1", "--points", "3", "--max-depth", "0.2",
        "--margin", "0", "--refine", "0", "--count", "1", "--width-max", "1", "--out", str(out),
    )  # fmt: skip
    assert code == 1 and "or on the mesh twice as fine" in err
    row = next(ln for ln in text.splitlines() if ln.strip().startswith("1 "))
    assert row.split()[-1] == "undetermined"
    assert "check: stable: rightmost root" in text  # the roots alone would have claimed it
    assert "mesh: stable on this mesh and on one twice as fine, but the limit is within" in text
    a = _attrs(out)
    assert a["mesh_beam_elements"] == 6 and a["mesh_fine_beam_elements"] == 12
    assert json.loads(a["mesh_verdicts"]) == ["undetermined"] and a["mesh_undetermined"] == 1
    data = json.loads(out.read_text())["data"]
    assert data["speed"]["values"] == [0.1]
    assert data["verdict"]["values"] == [3.0]  # VERDICTS.index("undetermined")
    # the converged limit lies within the coarse limit's bound (Eq. M3)
    b_h = data["b_lim"]["values"][0]
    conv = lobes(cl.load_model(SHAPER, variant="converged"), np.array([0.1]), width_max=1e-3, verify=0)
    bound = json.loads(a["mesh_limit_error_bound"])[0] * b_h
    assert abs(float(conv.b_lim[0]) - b_h) <= bound
    assert float(conv.b_lim[0]) < 0.2e-3  # and the cut is unstable there: undetermined was right


def test_recommend_far_below_the_limit_is_confirmed(capsys):
    """0.04 mm (the tool's largest depth) at 0.1 m/s: a fifth of the limit,
    far below it on every mesh (the converged variant's limit included), so
    the finer mesh confirms it and the note bounds the limit's error."""
    import dataclasses

    from chatterlab.cli._recommend import mesh_checked
    from chatterlab.selection import Machine, recommend

    model = cl.load_model(SHAPER)
    mach = dataclasses.replace(model.machine or Machine(), max_depth=0.04e-3)
    rec = recommend(model, np.array([0.0998, 0.0999, 0.1]), machine=mach, count=1, refine=0, width_max=1e-3)
    assert rec.speed[0] == 0.1
    checked = mesh_checked(rec, model, None, {})
    assert checked.verdict[0] == "stable" and rec.verdict[0] == "stable"
    assert "also stable on a mesh twice as fine" in checked.check[0]
    assert checked.meta["mesh_undetermined"] == 0
    assert checked.notes[-1].startswith("mesh: 6 beam elements; twice as fine, the b_lim at the 1")
    assert "every cut confirmed on it" in checked.notes[-1]
    bound = json.loads(checked.meta["mesh_limit_error_bound"])[0] * float(rec.limit[0])
    assert float(rec.limit[0]) - float(rec.width[0]) > bound
    conv = lobes(cl.load_model(SHAPER, variant="converged"), rec.speed, width_max=1e-3, verify=0)
    assert abs(float(conv.b_lim[0]) - float(rec.limit[0])) <= bound
    assert float(conv.b_lim[0]) > float(rec.width[0])


def test_recommend_without_beams_is_unchanged(tmp_path, capsys):
    """A model without beams: the command's file is the library's, byte for
    byte, and its summary the library's (but the run time)."""
    from chatterlab.cli._recommend import mesh_checked
    from chatterlab.selection import recommend

    model = cl.load_model(TURNING)
    assert not model.beams
    out = tmp_path / "t.json"
    code, text, _ = run(capsys, "recommend", TURNING, "--speed", "500", "3000", "--points", "40",
                        "--count", "2", "--refine", "1", "--out", str(out))  # fmt: skip
    rec = recommend(model, np.linspace(500, 3000, 40), count=2, refine=1)
    assert mesh_checked(rec, model, None, {}) is rec
    assert code == 0 and out.read_text() == rec.to_json()
    assert text.splitlines()[:-1] == rec.summary().splitlines()[:-1]
    assert "mesh" not in text
