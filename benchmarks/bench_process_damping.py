"""Process damping (issue 22 item 1), measured: the lobes with the
speed-dependent term against the same lobes without it -- what the coupling
of the width and the delay through the cutting speed costs.

Run from the repository root::

    python benchmarks/bench_process_damping.py              # 5 interleaved repeats, label "current"
    python benchmarks/bench_process_damping.py --repeat 7 --label after

What is timed, in one run, interleaved (plain, damped, plain, damped, ...),
every route with one BLAS thread (threadpoolctl), ``lobes(..., verify=0)``:

* ``turning``: the 1-DOF turning tool of ``studies/process_damping.py``,
  300 spindle speeds 150 .. 3000 rpm (geometric), widths to 20 mm, without
  the table and with C_pd = 2e5 N/m (D = 50 mm);
* ``shaper``: the traverse shaper (``studies/traverse_shaper/model.toml`` at
  s = 0.85 m), 300 work speeds 0.1 .. 1 m/s, widths to 1 mm, without and with
  ``[process_damping] C_pd = 3e5`` on its cut.

The damped diagram's accuracy is recorded beside its cost: for the turning
tool its largest relative difference from the D-subdivision written out
speed by speed (tests/test_process_damping.py's oracle) at 12 of the speeds,
for the shaper from constant-gain boundaries built at 12 speeds' own gains.
Wall-clock min and median of the repeats of this run, the CPU time beside
them, /proc/loadavg before and after; the run is stored in
``benchmarks/results/process_damping.json`` under ``runs[<label>]``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

try:
    import chatterlab as cl
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import chatterlab as cl

from _common import loadavg_text as loadavg
from _common import source_commit as commit

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "process_damping.json"
sys.path.insert(0, str(ROOT / "studies"))
import process_damping as study  # noqa: E402


def cases() -> dict[str, dict[str, Any]]:
    shaper = (ROOT / "studies/traverse_shaper/model.toml").read_text()
    folder = ROOT / "studies/traverse_shaper"
    return {
        "turning": {
            "plain": cl.loads_model(study.model_text(None), source="turning"),
            "damped": cl.loads_model(study.model_text(), source="turning"),
            "speeds": np.geomspace(150.0, 3000.0, 300),
            "width_max": 0.02,
            "position": None,
        },
        "shaper": {
            "plain": cl.loads_model(shaper, source="shaper", base_dir=folder),
            "damped": cl.loads_model(
                shaper + "\n[process_damping]\nC_pd = 3e5\n", source="shaper", base_dir=folder
            ),
            "speeds": np.linspace(0.1, 1.0, 300),
            "width_max": 1e-3,
            "position": 0.85,
        },
    }


def run_once(c: dict[str, Any], which: str) -> tuple[float, float, Any]:
    t0, c0 = time.perf_counter(), time.process_time()
    d = cl.lobes(c[which], c["speeds"], width_max=c["width_max"], position=c["position"], verify=0)
    return time.perf_counter() - t0, time.process_time() - c0, d


def accuracy(name: str, c: dict[str, Any], d: Any) -> float:
    """Largest relative difference of the damped envelope from an
    independent exact route at 12 of the speeds."""
    idx = np.linspace(0, c["speeds"].size - 1, 12).round().astype(int)
    if name == "turning":
        sys.path.insert(0, str(ROOT / "tests"))
        from test_process_damping import exact_turning_limit

        ref = np.array([exact_turning_limit(v, study.C_PD)[0] for v in c["speeds"][idx]])
    else:
        from chatterlab.lobes._diagram import Boundary
        from chatterlab.lobes._envelope import Boundary as ConstantBoundary
        from chatterlab.lobes._plant import Plant

        bd = Boundary(cl.assemble(c["damped"]).at(c["position"]), width_max=c["width_max"])
        p, T = bd.plant, d.delay[idx]
        ref = []
        for Ti, gi in zip(T, bd.term.gain(T), strict=True):
            plant = Plant(p.H, p.poles, p.Dl_P, p.Dl_V + gi * bd.term.W, p.Dl_O, p.residues)
            ref.append(
                ConstantBoundary(None, width_max=c["width_max"], plant=plant).envelope(np.array([Ti]))[0][0]
            )
        ref = np.array(ref)
    got = d.b_lim[idx]
    both = np.isfinite(ref) & np.isfinite(got)
    if np.any(np.isfinite(ref) != np.isfinite(got)):
        return math.inf
    return float(np.max(np.abs(got[both] / ref[both] - 1))) if np.any(both) else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--label", default="current")
    args = ap.parse_args()
    from threadpoolctl import threadpool_limits

    out: dict[str, Any] = {}
    with threadpool_limits(1):
        for name, c in cases().items():
            run_once(c, "plain")  # warm: imports, caches of the structure
            times: dict[str, list[tuple[float, float]]] = {"plain": [], "damped": []}
            load0 = loadavg()
            last: dict[str, Any] = {}
            for _ in range(args.repeat):
                for which in ("plain", "damped"):
                    w, cpu, d = run_once(c, which)
                    times[which].append((w, cpu))
                    last[which] = d
            load1 = loadavg()
            rec: dict[str, Any] = {"speeds": int(c["speeds"].size), "load": f"{load0} -> {load1}"}
            for which, tt in times.items():
                wall = np.array([t[0] for t in tt])
                cpu = np.array([t[1] for t in tt])
                rec[which] = {
                    "wall_min_s": float(wall.min()),
                    "wall_median_s": float(np.median(wall)),
                    "cpu_min_s": float(cpu.min()),
                    "lobes": len(last[which].lobes),
                    "min_b_lim_mm": float(np.nanmin(last[which].b_lim) * 1e3),
                }
            rec["cost_min"] = rec["damped"]["wall_min_s"] / rec["plain"]["wall_min_s"]
            rec["cost_median"] = rec["damped"]["wall_median_s"] / rec["plain"]["wall_median_s"]
            rec["cost_cpu_min"] = rec["damped"]["cpu_min_s"] / rec["plain"]["cpu_min_s"]
            rec["cells"] = int(last["damped"].meta["process_damping"]["cells"])
            rec["damped_max_rel_error"] = accuracy(name, c, last["damped"])
            out[name] = rec
            print(
                f"{name}: plain {rec['plain']['wall_min_s']:.3f} s, damped {rec['damped']['wall_min_s']:.3f} s"
                f" (min; x {rec['cost_min']:.2f}, median x {rec['cost_median']:.2f}, CPU x {rec['cost_cpu_min']:.2f});"
                f" {rec['cells']} gain cells; damped envelope within {rec['damped_max_rel_error']:.1e} of the exact route"
            )
    doc = json.loads(OUT.read_text()) if OUT.exists() else {"runs": {}}
    doc["runs"][args.label] = {
        "commit": commit(),
        "repeats": args.repeat,
        "python": platform.python_version(),
        "cpus": os.cpu_count(),
        "cases": out,
    }
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {OUT.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
