"""Benchmark of the time domain (chatterlab.time.simulate on chatterlab.time.newmark).

Run from the repository root::

    python benchmarks/bench_newmark.py           # everything (a few minutes)
    python benchmarks/bench_newmark.py --quick   # fewer repetitions

It prints, all measured in this run, and writes to
``benchmarks/results/bench_newmark.json``:

1. **throughput**: steps per second of ``simulate(shaper, feedback="pdo")`` --
   the traverse shaper (36 independent coordinates) with the slide moving
   through its stroke cycles (W(t), dW/dt, d2W/dt2), the cutting process on
   with all feedback terms and the delayed term -- at the default step, the
   paper's step and h = 1e-4 s; min and median of repeated runs, with the
   coefficients by per-segment polynomials (default) and directly, and with
   the integrator's worker threads on and off;
2. (withdrawn) the equal-accuracy comparison with solve_ivp gave solve_ivp a
   right-hand side calling chatterlab's per-time-point coefficient
   evaluation (524 us a call against ~40 us for precomputed matrices) and
   ran Newmark on two threads against one (issue 26); it is measured fairly,
   for Newmark and the exponential step map, by ``benchmarks/bench_time.py``;
3. the **machine load** (1-minute load average) before and after each part
   -- other jobs on the 2 cores slow everything, threads most; the JSON
   flags a run that started at a load above 0.5 per core as ``loaded``
   (the later loads include the benchmark's own threads).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import statistics
import sys
from pathlib import Path
from typing import Any

import numpy as np

try:
    import chatterlab  # noqa: F401
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import loadavg

import chatterlab as cl
from chatterlab.time import Integration, NewmarkOptions, simulate

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "traverse_shaper" / "model.toml"
OUT = ROOT / "benchmarks" / "results" / "bench_newmark.json"
#: 1-minute load average per core above which a timing is flagged as taken on a loaded machine
LOADED = 0.5


def stats(walls: list[float]) -> dict[str, Any]:
    return {"min_s": min(walls), "median_s": statistics.median(walls), "runs_s": walls}


# =========================================================================== 1. throughput


def throughput(system: cl.System, reps: int) -> list[dict[str, Any]]:
    print("\n1. throughput: simulate(shaper, feedback='pdo', passes=2), steps/s of the integration")
    print(
        f"   {'step h [s]':>12} {'coefficients':>12} {'workers':>7} {'steps':>7} {'best':>8} {'median':>8}  (steps/s from the min and median wall)"
    )
    cases = [
        (None, "auto", 2),
        (None, "auto", 0),
        (None, "direct", 2),
        (1.4e-3, "auto", 2),
        (1e-4, "auto", 2),
    ]
    rows = []
    for step, method, workers in cases:
        walls, n, h = [], 0, 0.0
        la = list(loadavg())
        for _ in range(reps):
            sim = simulate(
                system,
                feedback="pdo",
                integration=Integration(
                    periods=2, step=step, method=method, scheme=NewmarkOptions(workers=workers)
                ),
            )
            walls.append(sim.response.wall_time)
            n, h = sim.response.n_steps, sim.step
        s = stats(walls)
        print(f"   {h:12.4g} {method:>12} {workers:7d} {n:7d} {n / s['min_s']:8.0f} {n / s['median_s']:8.0f}")
        rows.append({"step_s": h, "coefficients": method, "workers": workers, "steps": n,
                     "steps_per_s_best": n / s["min_s"], "steps_per_s_median": n / s["median_s"],
                     "integration_wall": s, "load_average_before": la})  # fmt: skip
    return rows


# =========================================================================== main


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, default=None, help="timed runs of each case (default 5, quick 3)")
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args()
    reps = args.repeats or (3 if args.quick else 5)
    load0 = list(loadavg())
    print(f"before: load average {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f} on {os.cpu_count()} cores")
    system = cl.assemble(cl.load_model(MODEL))
    simulate(system, feedback="pdo", integration=Integration(duration=0.05))  # warm-up (imports, modes)
    result: dict[str, Any] = {
        "benchmark": "bench_newmark",
        "date_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "chatterlab": chatterlab.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "quick": args.quick,
        "repeats": reps,
        "model": str(MODEL.relative_to(ROOT)),
        "load_average_start": load0,
        "loaded_threshold_per_core": LOADED,
    }
    result["throughput"] = throughput(system, reps)
    result["load_average_end"] = list(loadavg())
    # the load before the benchmark starts: the later ones include its own one or two busy threads
    result["loaded"] = bool(load0[0] > LOADED * (os.cpu_count() or 1))
    result["note_on_loads"] = "loads after the start include this benchmark's own 1-2 busy threads"
    print(
        f"\nafter: load average {result['load_average_end'][0]:.2f}"
        + (" (LOADED machine)" if result["loaded"] else "")
    )
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
