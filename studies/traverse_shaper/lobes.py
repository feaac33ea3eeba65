"""Stability of the traverse shaper: lobes, the atlas along the stroke, and
the paper's feedback cases compared.

* case (c) -- proportional + ideal derivative + delayed feedback (Table 3,
  Eq. 3.7-3.9): the regenerative lobes b_lim(v_w) at the central position;
* case (b) -- proportional + ideal derivative only (inner modulation, no
  regeneration): stability does not depend on speed; its critical width is
  found by bisection on the delay-free characteristic roots;
* the atlas: b_lim over work speed x slide position, and its worst case.

Run: ``python studies/traverse_shaper/lobes.py`` (prints the numbers and
writes ``docs/figures/shaper_lobes.png``, ``shaper_lobes_zoom.png`` and
``shaper_atlas.png``).
``tests/test_studies.py`` checks the numbers.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

import chatterlab as cl
from chatterlab.lobes._diagram import lobes

HERE = Path(__file__).resolve().parent
MODEL = HERE / "model.toml"


def case_b_limit(frozen: cl.FrozenSystem, b_hi: float = 0.5, tol: float = 1e-4) -> float:
    """Smallest width (m) at which the P+D closed loop (no delay) loses
    stability, by bisection on the sign of the rightmost root (inf if stable
    up to ``b_hi``)."""
    from chatterlab.frequency._stability import stability

    def unstable(b: float) -> bool:
        return stability(frozen, width=b, terms="pd", winding=False).abscissa > 0

    if not unstable(b_hi):
        return float("inf")
    lo, hi = 0.0, b_hi
    while hi - lo > tol * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
    return hi


def run(speeds: np.ndarray | None = None, positions: np.ndarray | None = None, jobs: int = 2) -> dict:
    """Compute the study's numbers (and keep the result objects)."""
    v = np.linspace(0.1, 1.0, 300) if speeds is None else speeds
    pos = np.linspace(0.6, 1.1, 6) if positions is None else positions
    model = cl.load_model(MODEL)
    system = cl.assemble(model)
    frozen = system.at()
    diagram = lobes(frozen, v, width_max=1e-3, terms="pdo", verify=1)
    b_case_b = case_b_limit(frozen)
    from chatterlab.quantities._tasks import AtlasTask
    from chatterlab.sweep._engine import sweep

    task = AtlasTask(model, 1e-3, tuple(float(x) for x in v))
    atlas = sweep(
        task,
        {"position": (pos, "m"), "speed": (v, "m/s")},
        outputs={"b_lim": "m", "chatter_frequency": "Hz"},
        jobs=jobs,
        chunk_size=v.size,
        progress=False,
    )
    per_position = np.nanmin(atlas.data["b_lim"], axis=1)
    return {
        "diagram": diagram,
        "atlas": atlas,
        "process": model.process,
        "b_lim_min": diagram.minimum["width"],
        "b_lim_min_speed": diagram.minimum["speed"],
        "chatter_hz": diagram.minimum["chatter_hz"],
        "absolute_min": diagram.absolute_minimum["width"],
        "case_b_limit": b_case_b,
        "positions": pos,
        "per_position_min": per_position,
        "verified": diagram.verified,
    }


def report(r: dict) -> str:
    lines = [
        r["diagram"].summary(),
        f"case (b), P+D without regeneration: stable up to b = {r['case_b_limit'] * 1e3:.4g} mm (any speed)",
        "minimum b_lim along the stroke (case c):",
    ]
    for p, b in zip(r["positions"], r["per_position_min"], strict=True):
        lines.append(f"  s = {p:5.3f} m: {b * 1e3:.4g} mm")
    return "\n".join(lines)


def plot(r: dict, outdir: Path) -> list[Path]:
    """Draw the lobes (with case (b)'s limit for reference), a zoom computed
    on its own speed range, and the atlas; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    from chatterlab.plot import plot_atlas, plot_lobes, savefig

    d = r["diagram"]
    bb = r["case_b_limit"]
    refs = {}
    if np.isfinite(bb) and bb < d.width_max:
        refs[f"case (b), P + D without regeneration: {bb * 1e3:.3g} mm at any speed"] = bb
    name = "traverse shaper (studies/traverse_shaper/model.toml)"
    out = [outdir / "shaper_lobes.png", outdir / "shaper_lobes_zoom.png", outdir / "shaper_atlas.png"]
    savefig(plot_lobes(d, title=f"{name}, case (c): stability lobes", references=refs), str(out[0]))
    # a diagram of its own over a narrow range: every lobe resolved, numbered, verified
    frozen = cl.assemble(cl.load_model(MODEL)).at()
    zoom = lobes(frozen, np.linspace(0.49, 0.51, 400), width_max=d.width_max, terms="pdo", verify=4)
    savefig(plot_lobes(zoom, title=f"{name}, case (c): lobes at 0.49-0.51 m/s", references=refs), str(out[1]))
    savefig(
        plot_atlas(r["atlas"], r["process"], model=name, width_max=d.width_max, terms=d.terms),
        str(out[2]),
    )
    return out


if __name__ == "__main__":
    sys.path.insert(0, str(HERE.parent))
    from _figures import figures_dir

    out = figures_dir(__doc__.splitlines()[0])
    res = run()
    print(report(res))
    for f in plot(res, out) if out is not None else []:
        print(f"wrote {f}")
