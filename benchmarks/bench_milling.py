"""Benchmark of the milling lobes (issue 12): the spectral-element Floquet
method against first-order semi-discretisation (SDM) with 40 steps, the
method peers use.

Run from the repository root::

    python benchmarks/bench_milling.py             # 201 speeds, both immersions
    python benchmarks/bench_milling.py --quick     # 41 speeds

The problem is Insperger & Stepan's 1-DOF benchmark (N = 2, Kt = 6e8,
Kn = 2e8 N/m^2, 922 Hz, zeta = 0.011, m = 0.03993 kg, down-milling) at
a_e/D = 0.05 and 1, over 5000-25000 rpm, depths to 10 mm.  Everything below
is measured in this run, single-threaded BLAS, with the load averages:

1. **spectral** ``milling_lobes(method="spectral")``: Brent to rtol 1e-8 on
   the spectral radius after a 40-depth scan, with the convergence check of
   every limit (degree + 6); timed ``--repeat`` times interleaved with 3
   (min and median);
2. **its accuracy**, measured: on every 10th speed a reference with degree
   28 (+6 for its check) and rtol 1e-11; the largest relative deviation;
3. **SDM m = 40, the same search** (scan + Brent to rtol 1e-4, which is far
   below its own ~1 % error): the competent use of the peers' method;
4. **SDM m = 40 on a grid** of 201 speeds x ``--grid-depths`` depths with
   the boundary read between grid depths (what the published SDM codes do,
   a contour of the spectral radius); measured, not extrapolated;
5. the accuracy of 3 and 4 against the reference (largest and median
   relative error);
6. **the 2-core sweep**: the spectral lobes as a sweep over the speeds with
   the loky backend, 2 workers, vs the serial backend (warm, interleaved
   repeats, min of each);
7. memory: the Python allocation peak (tracemalloc, in a separate run on 11
   speeds: tracing slows Python several times, so no timing is traced) of 1
   and 3, and the process's peak RSS.

Numbers go to ``benchmarks/results/bench_milling.json``.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import resource
import sys
import time
import tracemalloc
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402

try:
    import chatterlab  # noqa: F401
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from chatterlab.frequency import sdm_monodromy  # noqa: E402
from chatterlab.lobes import milling_lobes  # noqa: E402
from chatterlab.process import (
    Milling,  # noqa: E402
    milling_loop,  # noqa: E402
)
from chatterlab.structure import Structure  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
LOADED = 0.5


def structure() -> Structure:
    return Structure.single_dof(0.03993, 2 * np.pi * 922.0, 0.011)


def cutter(immersion: float) -> Milling:
    return Milling.from_immersion(2, 0.02, 6e8, 2e8, immersion, "down")


def load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def timed(f: Any, f_small: Any) -> tuple[Any, float, int]:
    """Run ``f`` timed (no tracing: tracemalloc slows Python code several
    times), then ``f_small`` (the same on 11 speeds) under tracemalloc for
    the allocation peak, which does not grow with the number of speeds."""
    t = time.perf_counter()
    out = f()
    dt = time.perf_counter() - t
    tracemalloc.start()
    f_small()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return out, dt, peak


def sdm_grid(st: Structure, m: Milling, rpm: np.ndarray, depths: np.ndarray) -> np.ndarray:
    """The peers' way: the spectral radius of SDM m = 40 on a (speed, depth)
    grid, the boundary read between the first unstable grid depth and the one
    below it (linear interpolation of rho - 1)."""
    out = np.full(rpm.size, np.inf)
    for i, r in enumerate(rpm):
        prev_a, prev_f = 0.0, -1.0
        for a in depths:
            ev = np.linalg.eigvals(sdm_monodromy(milling_loop(st, m), float(r), float(a), 40))
            f = float(np.max(np.abs(ev))) - 1.0
            if f >= 0:
                out[i] = prev_a + (a - prev_a) * (-prev_f) / (f - prev_f)
                break
            prev_a, prev_f = float(a), f
    return out


def _one_speed(rpm: float, immersion: float) -> dict[str, float]:
    L = milling_lobes(milling_loop(structure(), cutter(immersion)), np.array([rpm]), depth_max=0.01)
    return {"a_lim": float(L.a_lim[0])}


def sweep_speedup(rpm: np.ndarray, immersion: float, repeat: int) -> dict[str, Any]:
    from chatterlab.sweep import Grid, sweep

    grid = Grid({"rpm": rpm})
    f = functools.partial(_one_speed, immersion=immersion)
    outs = {"a_lim": "m"}
    sweep(f, grid, outputs=outs, jobs=2, backend="loky", progress=False)  # warm the workers
    ts: dict[str, list[float]] = {"serial": [], "loky2": []}
    res = {}
    for _ in range(repeat):
        for b in ("serial", "loky"):
            t = time.perf_counter()
            r = sweep(f, grid, outputs=outs, jobs=2 if b == "loky" else 1, backend=b, progress=False)  # type: ignore[arg-type]
            ts["serial" if b == "serial" else "loky2"].append(time.perf_counter() - t)
            res[b] = np.asarray(r.data["a_lim"])
    same = bool(np.array_equal(res["serial"], res["loky"]))
    return {
        "serial_s": {"min": min(ts["serial"]), "median": float(np.median(ts["serial"]))},
        "loky2_s": {"min": min(ts["loky2"]), "median": float(np.median(ts["loky2"]))},
        "speedup_min": min(ts["serial"]) / min(ts["loky2"]),
        "bit_identical": same,
        "load": load(),
    }


def run(n_speeds: int, grid_depths: int, repeat: int) -> dict[str, Any]:
    rpm = np.linspace(5000.0, 25000.0, n_speeds)
    st = structure()
    report: dict[str, Any] = {
        "machine": platform.platform(),
        "cpus": os.cpu_count(),
        "speeds": n_speeds,
        "load_start": load(),
    }
    for imm in (0.05, 1.0):
        m = cutter(imm)
        key = f"ae/D={imm:g}"
        print(f"--- a_e/D = {imm:g}, {n_speeds} speeds 5000-25000 rpm, depths to 10 mm (load {load()})")
        few = rpm[:: max(1, n_speeds // 10)]
        # interleaved repeats of the two searches (the machine is shared: min and median)
        t_sps: list[float] = []
        t_sds: list[float] = []
        for _ in range(repeat):
            t = time.perf_counter()
            sp = milling_lobes(milling_loop(st, m), rpm, depth_max=0.01, rtol=1e-8)
            t_sps.append(time.perf_counter() - t)
            t = time.perf_counter()
            sd = milling_lobes(milling_loop(st, m), rpm, method="sdm", steps=40, rtol=1e-4)
            t_sds.append(time.perf_counter() - t)
        t_sp, t_sd = min(t_sps), min(t_sds)
        _, _, mem_sp = timed(
            lambda: None,
            lambda m=m, few=few: milling_lobes(milling_loop(st, m), few, depth_max=0.01, rtol=1e-8),
        )
        _, _, mem_sd = timed(
            lambda: None,
            lambda m=m, few=few: milling_lobes(milling_loop(st, m), few, method="sdm", steps=40, rtol=1e-4),
        )
        est = float(np.nanmax(sp.error / sp.a_lim))
        print(
            f"spectral: min {t_sp:.2f} s, median {np.median(t_sps):.2f} s of {repeat}, {sp.evaluations} evaluations"
            f" ({sp.meta.get('refined', 0)} speeds refined), alloc peak {mem_sp / 1e6:.1f} MB,"
            f" own error estimate <= {est:.1e} relative"
        )
        sub = np.arange(0, n_speeds, 10)
        ref = milling_lobes(milling_loop(st, m), rpm[sub], depth_max=0.01, rtol=1e-11, degree=28)
        with np.errstate(invalid="ignore"):  # inf - inf where both say stable to 10 mm
            dev = float(np.nanmax(np.abs(sp.a_lim[sub] - ref.a_lim) / ref.a_lim))
            e_sd = np.abs(sd.a_lim[sub] - ref.a_lim) / ref.a_lim
        print(
            f"  measured against degree 28 / rtol 1e-11 on {sub.size} speeds: max relative deviation {dev:.1e}"
        )
        print(
            f"SDM m=40, same search: min {t_sd:.2f} s, median {np.median(t_sds):.2f} s, {sd.evaluations} monodromies,"
            f" alloc peak {mem_sd / 1e6:.1f} MB; error vs reference max {np.nanmax(e_sd):.1e},"
            f" median {np.nanmedian(e_sd):.1e}"
        )
        depths = 0.01 * np.arange(1, grid_depths + 1) / grid_depths
        t = time.perf_counter()
        g = sdm_grid(st, m, rpm, depths)
        t_grid = time.perf_counter() - t
        with np.errstate(invalid="ignore"):
            e_g = np.abs(g[sub] - ref.a_lim) / ref.a_lim
        print(
            f"SDM m=40 on a {n_speeds} x {grid_depths} grid: {t_grid:.2f} s; error vs reference max"
            f" {np.nanmax(e_g):.1e}, median {np.nanmedian(e_g):.1e}"
        )
        print(
            f"ratios: SDM same search / spectral {t_sd / t_sp:.1f}x, SDM grid / spectral {t_grid / t_sp:.1f}x"
            f" (load {load()})"
        )
        report[key] = {
            "spectral_s": t_sp,
            "spectral_s_all": t_sps,
            "sdm40_search_s_all": t_sds,
            "spectral_refined_speeds": sp.meta.get("refined", 0),
            "spectral_evaluations": sp.evaluations,
            "spectral_alloc_peak_MB": mem_sp / 1e6,
            "spectral_error_estimate_max_rel": est,
            "spectral_deviation_from_reference_max_rel": dev,
            "sdm40_search_s": t_sd,
            "sdm40_search_alloc_peak_MB": mem_sd / 1e6,
            "sdm40_search_error_max_rel": float(np.nanmax(e_sd)),
            "sdm40_search_error_median_rel": float(np.nanmedian(e_sd)),
            "sdm40_grid_depths": grid_depths,
            "sdm40_grid_s": t_grid,
            "sdm40_grid_error_max_rel": float(np.nanmax(e_g)),
            "sdm40_grid_error_median_rel": float(np.nanmedian(e_g)),
            "ratio_sdm_search": t_sd / t_sp,
            "ratio_sdm_grid": t_grid / t_sp,
            "a_lim_mm_every_10th": (ref.a_lim * 1e3).tolist(),
            "kind_every_10th": ref.kind.tolist(),
            "load": load(),
        }
        print("2-core sweep of the spectral lobes (serial vs loky x2, warm) ...")
        sw = sweep_speedup(rpm, imm, repeat)
        print(
            f"  serial {sw['serial_s']['min']:.2f} s, loky x2 {sw['loky2_s']['min']:.2f} s: speed-up"
            f" {sw['speedup_min']:.2f}x, identical {sw['bit_identical']} (load {sw['load']})"
        )
        report[key]["sweep"] = sw
    report["peak_rss_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3
    report["load_end"] = load()
    report["LOADED"] = max(report["load_start"][0], report["load_end"][0]) > LOADED
    print(f"peak RSS {report['peak_rss_MB']:.0f} MB; LOADED = {report['LOADED']} (1-min load above {LOADED})")
    return report


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="41 speeds instead of 201")
    ap.add_argument("--grid-depths", type=int, default=50, help="depths of the SDM grid (default 50: 0.2 mm)")
    ap.add_argument("--repeat", type=int, default=3, help="repeats of the sweep timing")
    args = ap.parse_args()
    rep = run(41 if args.quick else 201, args.grid_depths, args.repeat)
    out = ROOT / "benchmarks" / "results" / "bench_milling.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(rep, indent=1) + "\n")
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
