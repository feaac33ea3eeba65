"""The forced vibration of a stable milling cut (issue 22 item 3), measured:
the fixed point of the one-period map by both Floquet discretisations (the
spectral elements and the semi-discretisation) against a time simulation run
to the steady state, at equal accuracy, in one run.

Run from the repository root::

    python benchmarks/bench_sle.py                 # 5 interleaved repeats, label "current"
    python benchmarks/bench_sle.py --repeat 7 --label after

The case: ``studies/sle/benchmark_1dof_y.toml`` (the Insperger-Stepan
benchmark, flexible normal to the wall), down-milling at a_e/D = 0.05,
f_z = 0.1 mm, at a few (rpm, a_p) inside the stable region.  The accuracy
is the largest distance of the orbit (the tool's y over one revolution, on
the simulation's grid) from the reference (the spectral fixed point at degree
30), relative to the orbit's amplitude; the target ``--accuracy`` (default 1e-3).

* spectral fixed point: :func:`chatterlab.frequency.forced_response`
  (``check=False``) at the lowest explicit collocation degree reaching the
  target -- the set-up of the discretisation, the fixed point, the orbit and
  the SLE;
* semi-discretisation fixed point: the same call with ``method="sdm"`` at the
  fewest steps per period of 40 x 2^(k/2) (even) reaching the target (first
  order in time, error ~ steps^-2: the multipliers' monodromy with the static
  force as its affine term);
* time domain: :func:`chatterlab.time.simulate_milling` (the Newmark core,
  nonlinear model with the feed) from rest, with the smallest steps per tooth
  period of 40 x 2^k reaching the target at steady state and revolutions
  enough that the transient has decayed below a tenth of it
  (|mu|^(N n_rev) <= accuracy / 10, mu the critical multiplier).

Wall-clock min and median of the interleaved repeats, CPU time beside them,
one BLAS thread, /proc/loadavg before and after (LOADED when the 1-min load
is above 1: the machine is shared); stored in
``benchmarks/results/sle.json`` under ``runs[<label>]``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
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

from chatterlab.frequency import forced_response
from chatterlab.frequency._forced import _orbit, _sd_orbit, _setup, static_load
from chatterlab.lobes import milling_loop_of
from chatterlab.time import Integration, simulate_milling

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "sle.json"
MODEL = ROOT / "studies" / "sle" / "benchmark_1dof_y.toml"
FEED = 1e-4
CASES = ((8000.0, 1e-3), (12000.0, 1e-3), (22000.0, 1e-3))  # (rpm, a_p m): stable cuts


def _sim(loop: Any, rpm: float, a: float, m: int, revs: int) -> Any:
    M, C, K = loop.M, loop.C, loop.K
    return simulate_milling(
        (M, C, K), loop.milling, rpm, a, feed=FEED, tool_point=loop.J,
        integration=Integration(periods=revs, steps_per_period=m),
    )  # fmt: skip


def _error_of(sm: Any, a: float, load: np.ndarray, t: np.ndarray, y: np.ndarray) -> float:
    ref = _orbit(sm, a, load, t)[:, 1]
    return float(np.max(np.abs(y - ref)) / np.max(np.abs(ref)))


#: the semi-discretisation's steps per period tried: 40 x 2^(k/2), even
SD_STEPS = tuple(2 * round(20 * 2 ** (k / 2)) for k in range(13))
ROUTES = ("spectral", "sdm", "time_domain")


def plan(loop: Any, rpm: float, a: float, accuracy: float) -> dict[str, Any]:
    """The degree, the steps and the time grid that reach ``accuracy``, with what each reached."""
    ref_sm = _setup(loop, rpm, a, 30, 1e-12)
    load = static_load(ref_sm, FEED)
    mu = ref_sm.radius(a)
    N = loop.milling.teeth
    revs = int(math.ceil(math.log(accuracy / 10.0) / math.log(mu) / N)) + 2
    t_rev = np.linspace(0.0, 60.0 / rpm, 400, endpoint=False) + 1.0  # one revolution, any phase
    degree, err_fp = None, math.nan
    for p in range(4, 31):
        r = forced_response(loop, rpm, a, FEED, degree=p, check=False)
        sm = _setup(loop, rpm, a, p, 1e-12)
        y = _orbit(sm, a, static_load(sm, FEED), t_rev)[:, 1]
        err_fp = _error_of(ref_sm, a, load, t_rev, y)
        if err_fp <= accuracy:
            degree = p
            break
    assert r.verdict == "stable"
    steps, err_sd = None, math.nan
    for k in SD_STEPS:
        orbit, _, _ = _sd_orbit(loop, rpm, a, FEED, k)
        err_sd = _error_of(ref_sm, a, load, t_rev, orbit(t_rev)[:, 1])
        if err_sd <= accuracy:
            steps = k
            break
    sd = forced_response(loop, rpm, a, FEED, method="sdm", steps=steps, check=False)
    assert sd.verdict == "stable"
    m, err_t = None, math.nan
    for k in range(8):
        mm = 40 * 2**k
        sim = _sim(loop, rpm, a, mm, revs)
        n = N * mm
        err_t = _error_of(ref_sm, a, load, sim.t[-n:], sim.y[-n:])
        if err_t <= accuracy:
            m = mm
            break
    return {"degree": degree, "fixed_point_error": err_fp, "sd_steps": steps, "sd_error": err_sd,
            "sd_sle_m": sd.sle, "steps_per_period": m, "revolutions": revs, "time_error": err_t,
            "spectral_radius": mu, "sle_m": r.sle}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--label", default="current")
    ap.add_argument("--accuracy", type=float, default=1e-3)
    args = ap.parse_args()
    from threadpoolctl import threadpool_limits

    load_before = loadavg()
    loaded = float(load_before.split()[0]) > 1.0 if load_before != "n/a" else False
    print(f"load before: {load_before}" + ("  LOADED" if loaded else ""))
    loop = milling_loop_of(cl.assemble(cl.load_model(MODEL)).at())
    rows = []
    with threadpool_limits(1):
        for rpm, a in CASES:
            p = plan(loop, rpm, a, args.accuracy)
            wall: dict[str, list[float]] = {k: [] for k in ROUTES}
            cpu: dict[str, list[float]] = {k: [] for k in ROUTES}
            for _ in range(args.repeat):  # interleaved
                for key in ROUTES:
                    w0, c0 = time.perf_counter(), time.process_time()
                    if key == "spectral":
                        forced_response(loop, rpm, a, FEED, degree=p["degree"], check=False)
                    elif key == "sdm":
                        forced_response(loop, rpm, a, FEED, method="sdm", steps=p["sd_steps"], check=False)
                    else:
                        _sim(loop, rpm, a, p["steps_per_period"], p["revolutions"])
                    wall[key].append(time.perf_counter() - w0)
                    cpu[key].append(time.process_time() - c0)
            row = {"rpm": rpm, "depth_m": a, **p}
            for key in wall:
                row[key] = {"wall_min_s": min(wall[key]), "wall_median_s": statistics.median(wall[key]),
                            "cpu_median_s": statistics.median(cpu[key])}  # fmt: skip
            med = {k: row[k]["wall_median_s"] for k in ROUTES}
            row["time_over_spectral_median"] = med["time_domain"] / med["spectral"]
            row["time_over_sdm_median"] = med["time_domain"] / med["sdm"]
            row["sdm_over_spectral_median"] = med["sdm"] / med["spectral"]
            rows.append(row)
            print(
                f"{rpm:7.0f} rpm a_p {a * 1e3:.2g} mm |mu| {p['spectral_radius']:.3f}:"
                f" spectral degree {p['degree']} (error {p['fixed_point_error']:.1e})"
                f" {med['spectral'] * 1e3:.1f} ms (min {row['spectral']['wall_min_s'] * 1e3:.1f});"
                f" sdm {p['sd_steps']} steps (error {p['sd_error']:.1e}) {med['sdm'] * 1e3:.1f} ms"
                f" (min {row['sdm']['wall_min_s'] * 1e3:.1f});"
                f" time domain m = {p['steps_per_period']}, {p['revolutions']} rev (error {p['time_error']:.1e})"
                f" {med['time_domain']:.3f} s (min {row['time_domain']['wall_min_s']:.3f})"
            )
    load_after = loadavg()
    print(f"load after: {load_after}")
    doc = json.loads(OUT.read_text()) if OUT.exists() else {"benchmark": "bench_sle", "runs": {}}
    doc["runs"][args.label] = {
        "commit": commit(),
        "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "python": platform.python_version(),
        "cpus": os.cpu_count(),
        "repeats": args.repeat,
        "accuracy": args.accuracy,
        "load_before": load_before,
        "load_after": load_after,
        "loaded": loaded or float(load_after.split()[0]) > 1.0 if load_after != "n/a" else loaded,
        "cases": rows,
    }
    OUT.write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {OUT.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
