"""Generate the tap-test example's "measured" files (seeded; the output is
committed, so this script documents how it was made and checks that it
still makes the same files).

The machine behind the files is a chatterlab plane model per bending
direction (x and y differ only in the spindle bearings' stiffness):

* spindle: a rigid body (6 kg, 0.03 kg m^2) on a bearing spring-damper to
  the ground;
* holder: a steel Timoshenko beam (40 mm, 80 mm overhang) clamped in the
  spindle (an attachment), ending at the coupling point;
* tool: a solid carbide Timoshenko beam (12 mm, 60 mm overhang), joined to
  the holder by a spring-damper joint (translational and rotational).

Files (frequencies 100 Hz .. 5 kHz every 2 Hz, receptance in m/N):

* ``tool_point.csv``: the tool-point FRF (tool.x, tool.y) with 2 %
  relative complex Gaussian noise on xx and yy; the cross FRFs xy, yx were
  not "measured" and are written as 0 (the machine's x and y are
  uncoupled);
* ``holder_x.csv``, ``holder_y.csv``: the spindle-holder alone (tool
  removed) at the coupling point, the 2 x 2 receptance of displacement and
  slope (``holder.x``/``holder.tx`` for bending in x, ``holder.y``/
  ``holder.ty`` in y) to force and moment, 2 % noise on every entry.  A tap
  test measures the displacement/force entry only; the slope entries come
  from a model of the holder or from finite differences
  (chatterlab.structure.rotations_from_translations, docs/tap-test.md);
* ``truth.json``: the machine's parameters and its modes in the band (the
  answer the walkthrough's fit is checked against).

Run ``python studies/tap_test/generate.py`` to regenerate (``--check`` to
compare with the committed files instead).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

HERE = Path(__file__).resolve().parent
SEED = 20261128
NOISE = 0.02  # relative complex noise, E|e|^2 = NOISE^2
F_LO, F_HI, DF = 100.0, 5000.0, 2.0  # Hz

SPINDLE = {"mass": 6.0, "inertia": 0.03, "x": -0.12}
BEARING = {"x": (1.2e8, 8.0e7, 900.0, 60.0), "y": (1.5e8, 8.0e7, 900.0, 60.0)}  # k, k_rot, c, c_rot
HOLDER = {"length": 0.06, "diameter": 0.05, "E": 2.1e11, "nu": 0.3, "rho": 7850.0, "elements": 6}
TOOL = {"length": 0.06, "diameter": 0.012, "E": 6.0e11, "nu": 0.22, "rho": 14500.0, "elements": 8}
JOINT = {"k": 6.0e7, "k_rot": 3.0e5, "c": 250.0, "c_rot": 1.5}


def _beam(id_: str, n1: str, n2: str, p: dict[str, float]) -> dict[str, Any]:
    d, nu = p["diameter"], p["nu"]
    return {
        "id": id_,
        "nodes": [n1, n2],
        "E": p["E"],
        "nu": nu,
        "rho": p["rho"],
        "A": math.pi * d**2 / 4,
        "I": math.pi * d**4 / 64,
        "kappa": 6 * (1 + nu) / (7 + 6 * nu),
        "elements": int(p["elements"]),
    }


def machine(direction: str, *, tool: bool = True, tool_length: float | None = None) -> Any:
    """The plane model of one bending direction (holder alone with
    ``tool=False``); the coupling point is node ``h1`` at x = 0, the tool
    tip node ``tip``."""
    from chatterlab.model import build_model

    k, kr, c, cr = BEARING[direction]
    L = TOOL["length"] if tool_length is None else tool_length
    raw: dict[str, Any] = {
        "model": {"name": f"tap-test machine, {direction} bending" + ("" if tool else ", holder alone")},
        "body": [
            {
                "id": "spindle",
                "mass": SPINDLE["mass"],
                "inertia": SPINDLE["inertia"],
                "centre": [SPINDLE["x"], 0.0],
            }
        ],
        "node": [{"id": "nose", "at": [-HOLDER["length"], 0.0]}, {"id": "h1", "at": [0.0, 0.0]}],
        "beam": [_beam("holder", "nose", "h1", HOLDER)],
        "attachment": [{"node": "nose", "body": "spindle"}],
        "spring": [
            {
                "id": "bearing",
                "a": "spindle",
                "b": "ground",
                "c1": 1e9,
                "c2": k,
                "c6": kr,
                "d1": 2000.0,
                "d2": c,
                "d6": cr,
            }
        ],
    }
    if tool:
        raw["node"] += [{"id": "base", "at": [0.0, 0.0]}, {"id": "tip", "at": [L, 0.0]}]
        raw["beam"].append(_beam("tool", "base", "tip", TOOL))
        raw["spring"].append(
            {
                "id": "joint",
                "a": "h1",
                "b": "base",
                "c1": 1e10,
                "d1": 2000.0,  # no undamped axial mode (a pole on the imaginary axis)
                "c2": JOINT["k"],
                "c6": JOINT["k_rot"],
                "d2": JOINT["c"],
                "d6": JOINT["c_rot"],
            }
        )
    return build_model(raw, source=f"studies/tap_test/generate.py ({direction})")


def frequency_grid() -> np.ndarray:
    return 2 * np.pi * np.arange(F_LO, F_HI + DF / 2, DF)


def noise(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    return NOISE * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)


def make() -> dict[str, Any]:
    """The three FRFs and the truth (nothing written)."""
    from chatterlab.structure import FRF, assemble, receptance

    rng = np.random.default_rng(SEED)
    w = frequency_grid()
    tip = np.zeros((2, 2, w.size), complex)
    truth: dict[str, Any] = {"noise": NOISE, "band_hz": [F_LO, F_HI], "modes": {}}
    holders = {}
    for j, d in enumerate(("x", "y")):
        full = assemble(machine(d)).at()
        Ht = receptance(full, ["tip.y"], ["tip.y"], w).data[0, 0]
        tip[j, j] = Ht * (1 + noise(rng, Ht.shape))
        # the modes in the band that the tool point sees (the axial mode has no
        # residue at tip.y): peak contribution |R| / |Re lam| above 1e-3 of the largest
        cm = full.complex_modes
        r = (full.dof("tip.y") @ cm.phi) ** 2
        peak = np.abs(r) / np.maximum(np.abs(cm.lam.real), 1e-300)
        keep = (cm.lam.imag > 0) & (np.abs(cm.lam) <= 2 * np.pi * F_HI) & (peak > 1e-3 * peak.max())
        lam = cm.lam[keep]
        truth["modes"][d] = {
            "frequency_hz": [float(abs(x) / (2 * np.pi)) for x in lam],
            "damping": [float(-x.real / abs(x)) for x in lam],
        }
        hold = assemble(machine(d, tool=False)).at()
        HA = receptance(hold, ["h1.y", "h1.rz"], ["h1.y", "h1.rz"], w).matrices
        HA = np.moveaxis(HA * (1 + noise(rng, HA.shape)), 0, -1)  # the noise drawn per frequency, as ever
        names = (f"holder.{d}", f"holder.t{d}")
        holders[d] = FRF.from_arrays(w, HA, names, names, source=f"holder_{d}.csv")
    tool_point = FRF.from_arrays(w, tip, ("tool.x", "tool.y"), ("tool.x", "tool.y"), source="tool_point.csv")
    truth.update(
        {"spindle": SPINDLE, "bearing": BEARING, "holder": HOLDER, "tool": TOOL, "joint": JOINT, "seed": SEED}
    )
    return {"tool_point": tool_point, "holder_x": holders["x"], "holder_y": holders["y"], "truth": truth}


def write(out: Path = HERE) -> None:
    data = make()
    for name in ("tool_point", "holder_x", "holder_y"):
        data[name].to_csv(out / f"{name}.csv")
    (out / "truth.json").write_text(json.dumps(data["truth"], indent=1) + "\n")


if __name__ == "__main__":
    if "--check" in sys.argv:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            write(Path(tmp))
            same = all(
                (Path(tmp) / f).read_bytes() == (HERE / f).read_bytes()
                for f in ("tool_point.csv", "holder_x.csv", "holder_y.csv", "truth.json")
            )
        print("files are up to date" if same else "files differ: run generate.py")
        sys.exit(0 if same else 1)
    write()
    print(json.dumps(make()["truth"]["modes"], indent=1))
