"""Mesh convergence of the traverse shaper's stability lobes.

The model file gives each Timoshenko beam one element (the paper's six DFEs);
``elements = N`` on a ``[[beam]]`` divides it into N equal elements.  This
study refines two families of meshes and fits the observed order of
convergence of the minimum limit width b_lim, its chatter frequency and
b_lim at fixed work speeds (case (c), pdo feedback, central position):

* **uniform**: every beam in N = 1, 2, 4, 8, 16, 32 elements.  The springs of
  Table 2 and the two moving contacts sit *inside* elements.  A point force
  makes the Timoshenko shear strain jump; the element's shear strain is
  constant (``structure/_elements.py``), so the element that holds the jump
  misses an energy of order (jump)^2 h: the error falls as h^1, not the
  element's h^2 (``tests/test_elements.py``: rate 2 for a smooth mode).
* **conforming**: k times the coarsest mesh that puts a node under every
  spring and, at the central position, under both contacts (:data:`CONFORMING`:
  table 8, bed-1 2, bed-2 12, workpiece 10, shear-1 and shear-2 5 elements);
  k = 1, 2, 4: the jump falls on a node, and the rate is the element's 2.

The observed order p from three meshes h, h/2, h/4 is
``log2((f_h - f_{h/2}) / (f_{h/2} - f_{h/4}))``; the Richardson estimate of
the converged value is ``f_{h/4} + (f_{h/4} - f_{h/2}) / (2^p - 1)``.

The conforming mesh k = 1 has the minimum b_lim within 0.07 % of the
Richardson estimate but its envelope only within 3.9 %: the lobes of the
higher modes, at 1.2-2 times the minimum, converge more slowly, and of the
six beams only refining the table and bed-1 moves them (each alone, twice
as fine: 3.9 % -> 2.2 % and 2.8 %; any other beam: no change).  The
``converged`` variant of ``model.toml`` is therefore the conforming mesh
with the table and bed-1 three times as fine (table 24, bed-1 6 elements:
204 coordinates instead of 36), and its stated tolerance is 1 % of b_lim,
for the minimum and for the envelope at every speed of the main job's
grid, against the conforming family's Richardson estimate.

Run: ``python studies/traverse_shaper/mesh_convergence.py`` (about a minute on
one core; prints the tables that docs/lobes.md, "Mesh convergence of the
bundled shaper", shows).  ``tests/test_mesh_convergence.py`` checks the
orders and the tolerance.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

import chatterlab as cl
from chatterlab.lobes import lobes

HERE = Path(__file__).resolve().parent
MODEL = HERE / "model.toml"
#: the main job's speed grid (README: --speed 0.1 1.0, 300 points), m/s
SPEEDS = np.linspace(0.1, 1.0, 300)
#: speeds at which b_lim is tabulated, m/s (nearest points of SPEEDS)
PROBES = (0.1, 0.4, 0.7, 1.0)
WIDTH_MAX = 1e-3  # m, as the main job's --width-max 1 (mm)
#: the coarsest mesh with a node under every load, elements per beam: the
#: springs of Table 2 (the finest spacing 0.05 m, on the workpiece and bed-2)
#: and, at the central position s = 0.85 m, the contacts (the workpiece's at
#: 0.25 m, the shear's at 0.60 m along its track)
CONFORMING = {"shear-1": 5, "shear-2": 5, "workpiece": 10, "table": 8, "bed-1": 2, "bed-2": 12}
#: the variant of MODEL whose mesh is shipped as converged
VARIANT = "converged"
UNIFORM_N = (1, 2, 4, 8, 16, 32)
CONFORMING_K = (1, 2, 4)
#: the stated tolerance of the shipped mesh, relative to the Richardson
#: estimate: its minimum b_lim and its envelope at every speed of the main
#: job's grid
TOLERANCE = 0.01


def mesh(model: cl.Model, counts: dict[str, int]) -> cl.Model:
    """``model`` with its beams in ``counts[beam]`` elements."""
    return model.with_parameters({f"beam.{b}.elements": int(n) for b, n in counts.items()})


def uniform(model: cl.Model, n: int) -> dict[str, int]:
    return {b.id: n for b in model.beams}


def conforming(k: int) -> dict[str, int]:
    """The conforming mesh k: :data:`CONFORMING` times k."""
    return {b: k * n for b, n in CONFORMING.items()}


def shipped() -> cl.Model:
    """The model with the shipped converged mesh (the variant)."""
    return cl.load_model(MODEL, variant=VARIANT)


def measure(model: cl.Model, speeds: np.ndarray = SPEEDS) -> dict[str, Any]:
    """The lobes of ``model`` (no argument-principle checks: they confirm the
    envelope, they do not change it) and their cost."""
    frozen = cl.assemble(model).at()
    t = time.process_time()
    d = lobes(frozen, speeds, width_max=WIDTH_MAX, terms="pdo", verify=0)
    cpu = time.process_time() - t
    am = d.absolute_minimum
    return {
        "coordinates": frozen.structure.M.shape[0],
        "b_min": float(am["width"]),
        "chatter_hz": float(am["chatter_hz"]),
        "b_lim": np.asarray(d.b_lim, float),
        "cpu_s": cpu,
    }


def observed_order(f: np.ndarray) -> np.ndarray:
    """Observed order from the last three values of a halving sequence
    (axis 0); NaN where the differences change sign (not yet asymptotic)."""
    d1, d2 = f[-2] - f[-3], f[-1] - f[-2]
    with np.errstate(divide="ignore", invalid="ignore"):
        r = d1 / d2
        return np.where(r > 1, np.log2(np.abs(r)), np.nan)


def richardson(f: np.ndarray, p: float | np.ndarray) -> np.ndarray:
    """Richardson estimate from the last two values of a halving sequence
    (inf where the last value is inf: no lobe below the ceiling)."""
    with np.errstate(invalid="ignore"):
        return np.where(np.isfinite(f[-1]), f[-1] + (f[-1] - f[-2]) / (2.0**p - 1.0), f[-1])


def run(
    uniform_n: tuple[int, ...] = UNIFORM_N, conforming_k: tuple[int, ...] = CONFORMING_K
) -> dict[str, Any]:
    base = cl.load_model(MODEL)
    out: dict[str, Any] = {"uniform": {}, "conforming": {}}
    for n in uniform_n:
        out["uniform"][n] = measure(mesh(base, uniform(base, n)))
    for k in conforming_k:
        out["conforming"][k] = measure(mesh(base, conforming(k)))
    out["shipped"] = measure(shipped())
    for fam in ("uniform", "conforming"):
        rows = list(out[fam].values())
        bmin = np.array([r["b_min"] for r in rows])
        fhz = np.array([r["chatter_hz"] for r in rows])
        blim = np.array([r["b_lim"] for r in rows])
        p = float(observed_order(bmin))
        out[fam + "_order"] = {"b_min": p, "chatter_hz": float(observed_order(fhz))}
        out[fam + "_richardson"] = {
            "b_min": float(richardson(bmin, p)),
            "chatter_hz": float(richardson(fhz, out[fam + "_order"]["chatter_hz"])),
        }
    # the envelope at every speed: Richardson with the family's order of the
    # minimum (per-speed orders are noisy where a lobe's flank is steep)
    rows = list(out["conforming"].values())
    blim = np.array([r["b_lim"] for r in rows])
    out["conforming_richardson"]["b_lim"] = richardson(blim, out["conforming_order"]["b_min"])
    return out


def envelope_error(b_lim: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, int]:
    """|b_lim / ref - 1| at the speeds where both have a limit below the
    ceiling, and the number of speeds where only one has (a lobe's tip
    crossing the ceiling ``WIDTH_MAX``)."""
    both = np.isfinite(b_lim) & np.isfinite(ref)
    return np.abs(b_lim[both] / ref[both] - 1), int(np.sum(np.isfinite(b_lim) != np.isfinite(ref)))


def report(r: dict[str, Any]) -> str:
    idx = [int(np.argmin(np.abs(SPEEDS - v))) for v in PROBES]
    head = "  mesh          coords  min b_lim (mm)  chatter (Hz)  " + "  ".join(
        f"b_lim@{SPEEDS[i]:.2f}" for i in idx
    )
    lines = []
    for fam, key in (("uniform", "N"), ("conforming", "k")):
        lines += [f"{fam} meshes ({key} = elements per beam)" if fam == "uniform" else f"{fam} meshes", head]
        for m, row in r[fam].items():
            lines.append(
                f"  {key} = {m:<9d} {row['coordinates']:6d}  {row['b_min'] * 1e3:14.6f}  {row['chatter_hz']:12.4f}  "
                + "  ".join(f"{row['b_lim'][i] * 1e3:10.5f}" for i in idx)
                + f"   ({row['cpu_s']:.2f} s CPU)"
            )
        o, rr = r[fam + "_order"], r[fam + "_richardson"]
        lines.append(
            f"  observed order: min b_lim {o['b_min']:.2f}, chatter frequency {o['chatter_hz']:.2f}; "
            f"Richardson: {rr['b_min'] * 1e3:.6f} mm, {rr['chatter_hz']:.4f} Hz"
        )
    ref = r["conforming_richardson"]
    lines.append("against the conforming family's Richardson estimate:")
    for name, row in (
        ("shipped 'converged' variant", r["shipped"]),
        ("conforming k = 1", r["conforming"].get(1)),
        ("conforming k = 2", r["conforming"].get(2)),
        ("one element per beam (the paper's)", r["uniform"].get(1)),
    ):
        if row is None:
            continue
        env, ceiling = envelope_error(row["b_lim"], ref["b_lim"])
        lines.append(
            f"  {name}: min b_lim {row['b_min'] / ref['b_min'] - 1:+.3%}, chatter frequency "
            f"{row['chatter_hz'] / ref['chatter_hz'] - 1:+.4%}; envelope at {env.size} of the {SPEEDS.size} speeds: "
            f"median {np.median(env):.3%}, max {env.max():.3%}, {np.mean(env <= TOLERANCE):.1%} within {TOLERANCE:.0%}"
            + (
                f" ({ceiling} speed(s) where a lobe's tip crosses the {WIDTH_MAX * 1e3:g} mm ceiling)"
                if ceiling
                else ""
            )
        )
    lines += [
        f"  uniform family's Richardson min b_lim: {r['uniform_richardson']['b_min'] / ref['b_min'] - 1:+.3%}",
        f"  stated tolerance of the shipped mesh ({r['shipped']['coordinates']} coordinates, "
        f"{r['shipped']['cpu_s']:.2f} s CPU): {TOLERANCE:.0%} of b_lim, minimum and envelope",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    print(report(run()))
