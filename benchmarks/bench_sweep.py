"""Benchmark of the sweep engine (chatterlab.sweep._engine): speed-up, per-task overhead, memory.

Run from the repository root::

    python benchmarks/bench_sweep.py            # everything (about a minute and a half on 2 cores)
    python benchmarks/bench_sweep.py --quick    # smaller sizes

Everything printed is measured in this run (nothing is derived from busy
fractions or extrapolated), repeated ``--repeat`` times (>= 5) with serial
and parallel runs interleaved, min and median reported, with the load
average (``os.getloadavg``) before and after; a 1-minute load above 0.5 is
flagged LOADED (the machine has 2 cores, so outside load caps the speed-up).

1. **speed-up** of the loky backend with 2 workers over the serial backend
   on the same sweep, for two workloads: 100 CPU-bound numpy tasks of ~20 ms
   (no BLAS) and a real chatterlab sweep (rightmost characteristic root of
   the shaper on a 6 x 12 width x speed grid: issue 26's 72-point sweep, BLAS-heavy); the loky executor
   cold (first call: worker start-up included) and warm; results checked
   bit-identical.  BLAS is checked single-threaded inside the serial backend
   and the loky workers (threadpoolctl, from within the tasks);
2. **overhead per task** for tiny tasks: a plain Python loop vs the serial
   engine vs loky with 2 workers;
3. **memory** of a 10^6-point sweep of a trivial function streamed to a
   netCDF file (``out=``), measured once in a fresh child process: peak RSS
   of the driver process (and of the workers) vs the size of the result
   arrays, and the Python allocation peak (tracemalloc) vs what a list of
   10^6 per-task dicts holds (measured).

Numbers go to ``benchmarks/results/bench_sweep.json``.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

try:
    import chatterlab  # noqa: F401
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _common import load1 as load
from _common import loadavg
from _common import source_commit as _commit

from chatterlab.sweep._engine import Grid, sweep

ROOT = Path(__file__).resolve().parents[1]
LOADED = 0.5  # 1-minute load average above which a timing is flagged (2 cores)


def busy(i: float, reps: int) -> dict[str, float]:
    """CPU-bound numpy work (no BLAS, so no hidden threads): ~reps * 0.15 ms.

    Also returns its own wall and CPU time, to tell engine idling from CPU
    contention by other processes.
    """
    t, c = time.perf_counter(), time.process_time()
    x = np.linspace(0.0, 1.0, 20_000) + i
    for _ in range(reps):
        x = np.sin(x) * 0.5 + np.cos(x) * 0.5
    return {"y": float(x.sum()), "wall": time.perf_counter() - t, "cpu": time.process_time() - c}


def tiny(x: float) -> dict[str, float]:
    return {"y": x}


def trivial(a: float, b: float) -> dict[str, float]:
    return {"s": a + b, "p": a * b}


def blas_threads(i: float) -> dict[str, float]:
    """The largest BLAS/OpenMP thread count threadpoolctl sees where this runs."""
    from threadpoolctl import threadpool_info

    return {"threads": float(max((d["num_threads"] for d in threadpool_info()), default=0))}


def abscissa(width: float, speed: float, frozen: object) -> dict[str, float]:
    """A real chatterlab task (BLAS-heavy): the rightmost characteristic root
    of the shaper's closed loop, case c."""
    from chatterlab.frequency._stability import stability

    st = stability(frozen, width=width, speed=speed, terms="pdo", winding=False)  # type: ignore[arg-type]
    return {"abscissa": float(st.abscissa)}


def calibrate(target: float = 0.020) -> int:
    reps = 10
    while True:  # on CPU time, so that outside load does not shorten the tasks
        dt = busy(0.0, reps)["cpu"]
        if dt > 0.02:
            return max(1, round(reps * target / dt))
        reps *= 2


def stats(times: list[float], l0: float, l1: float) -> dict[str, Any]:
    return {
        "min_s": min(times),
        "median_s": float(np.median(times)),
        "times_s": times,
        "load_before": l0,
        "load_after": l1,
        "loaded": bool(max(l0, l1) > LOADED),
    }


def fmt(rec: dict[str, Any]) -> str:
    return (
        f"min {rec['min_s']:7.3f} s, median {rec['median_s']:7.3f} s"
        f"  (load {rec['load_before']:.2f}->{rec['load_after']:.2f}{' LOADED' if rec['loaded'] else ''})"
    )


def check_blas() -> dict[str, Any]:
    """BLAS threads inside the serial backend and inside the loky workers."""
    try:
        import threadpoolctl  # noqa: F401
    except ImportError:
        print("   threadpoolctl not installed: BLAS threads in the workers not checked")
        return {"checked": False}
    g = Grid({"i": np.arange(4.0)})
    ser = sweep(blas_threads, g, outputs={"threads": ""}, backend="serial", progress=False)
    par = sweep(blas_threads, g, outputs={"threads": ""}, backend="loky", jobs=2, progress=False)
    from threadpoolctl import threadpool_info

    here = max((d["num_threads"] for d in threadpool_info()), default=0)
    out = {
        "checked": True,
        "driver": int(here),
        "serial_backend": int(np.max(ser["threads"])),
        "loky_workers": int(np.max(par["threads"])),
    }
    ok = out["serial_backend"] == 1 and out["loky_workers"] == 1
    print(
        f"   BLAS threads: driver {here}, serial backend {out['serial_backend']},"
        f" loky workers {out['loky_workers']}  ({'single-threaded in the sweep: ok' if ok else 'NOT single-threaded'})"
    )
    return out


def bench_speedup(workloads: dict[str, tuple[Any, Grid, dict[str, str], str]], repeat: int) -> dict[str, Any]:
    """Serial vs loky x2 wall time of the same sweep, measured: one cold loky
    call (worker start-up), then ``repeat`` interleaved rounds of serial and
    warm loky, so that a burst of outside load hits both."""
    print(f"\n1. measured speed-up, loky x2 over serial, {repeat} interleaved repeats (min and median)")
    blas = check_blas()
    out: dict[str, Any] = {"blas_threads": blas}
    for name, (f, g, outs, what) in workloads.items():

        def run(backend: str, f=f, g=g, outs=outs) -> tuple[float, Any]:
            t = time.perf_counter()
            r = sweep(f, g, outputs=outs, backend=backend, jobs=2, progress=False)  # type: ignore[arg-type]
            return time.perf_counter() - t, r

        l0 = load()
        t_cold, cold = run("loky")  # first call: starts the loky workers
        ts: dict[str, list[float]] = {"serial": [], "loky": []}
        res: dict[str, Any] = {}
        for _ in range(repeat):
            for b in ("serial", "loky"):
                dt, res[b] = run(b)
                ts[b].append(dt)
        l1 = load()
        key = next(iter(outs))
        same = bool(
            np.array_equal(res["serial"][key], res["loky"][key], equal_nan=True)
            and np.array_equal(res["serial"][key], cold[key], equal_nan=True)
        )
        ser, par = stats(ts["serial"], l0, l1), stats(ts["loky"], l0, l1)
        r_min, r_med = ser["min_s"] / par["min_s"], ser["median_s"] / par["median_s"]
        print(f"   {name}: {g.size} tasks, {what}")
        print(f"     serial           {fmt(ser)}")
        print(f"     loky x2 (warm)   {fmt(par)}")
        print(f"     loky x2 (cold)   {t_cold:7.3f} s  (first call, worker start-up included)")
        print(
            f"     MEASURED speed-up {r_min:.2f}x (min/min), {r_med:.2f}x (median/median),"
            f" {ser['min_s'] / t_cold:.2f}x cold; results bit-identical: {same}"
        )
        out[name] = {
            "tasks": g.size,
            "task": what,
            "serial": ser,
            "loky2_warm": par,
            "loky2_cold_s": t_cold,
            "speedup_min": r_min,
            "speedup_median": r_med,
            "speedup_cold": ser["min_s"] / t_cold,
            "bit_identical": same,
            # this (driver) process's peak so far: it computes chunks too
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        }
    return out


def bench_overhead(n_tasks: int, repeat: int) -> dict[str, Any]:
    values = np.linspace(0.0, 1.0, n_tasks)
    g = Grid({"x": values})
    print(
        f"\n2. overhead per task: {n_tasks} tiny tasks (func returns {{'y': x}}), {repeat} interleaved repeats"
    )
    sweep(tiny, g, outputs={"y": ""}, backend="loky", jobs=2, progress=False)  # warm the workers
    routes = {
        "plain loop": lambda: [tiny(x=v) for v in values.tolist()],
        "engine serial": lambda: sweep(tiny, g, outputs={"y": ""}, backend="serial", progress=False),
        "engine loky x2": lambda: sweep(tiny, g, outputs={"y": ""}, backend="loky", jobs=2, progress=False),
    }
    ts: dict[str, list[float]] = {k: [] for k in routes}
    l0 = load()
    for _ in range(repeat):
        for k, fn in routes.items():
            t = time.perf_counter()
            fn()
            ts[k].append(time.perf_counter() - t)
    l1 = load()
    us = 1e6 / n_tasks
    out: dict[str, Any] = {"tasks": n_tasks}
    for k, v in ts.items():
        rec = stats(v, l0, l1)
        rec["us_per_task_min"] = us * rec["min_s"]
        rec["us_per_task_median"] = us * rec["median_s"]
        out[k] = rec
        print(
            f"   {k:16s} {rec['us_per_task_min']:6.2f} us/task min, {rec['us_per_task_median']:6.2f} median"
            f"  (load {l0:.2f}->{l1:.2f}{' LOADED' if rec['loaded'] else ''})"
        )
    return out


def _proc_status(key: str) -> float | None:
    """VmRSS / VmHWM of this process in MB (Linux), else None."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return None


def _reset_peak_rss() -> bool:
    """Reset VmHWM to the current RSS (Linux >= 4.0), so the peak is that of the sweep."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def memory_child(n: int, out: str, naive_n: int) -> None:
    """Runs in a fresh process: stream an n-point sweep to ``out`` and report memory."""
    import tracemalloc

    side = int(round(n**0.5))
    g = Grid({"a": np.linspace(0.0, 1.0, side), "b": np.linspace(1.0, 2.0, n // side)})
    # warm up imports and the loky executor so the baseline includes them
    sweep(trivial, Grid({"a": [0.0], "b": [1.0]}), outputs={"s": "", "p": ""}, jobs=2, progress=False)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    reset = _reset_peak_rss()
    cur0 = _proc_status("VmRSS")
    tracemalloc.start()
    t = time.perf_counter()
    r = sweep(trivial, g, outputs={"s": "", "p": ""}, jobs=2, out=out, progress=False)
    wall = time.perf_counter() - t
    _, peak_py = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    hwm = _proc_status("VmHWM") if reset else None
    ok = r.ok and bool(np.all(np.asarray(r["s"]) == g["a"].values[:, None] + g["b"].values[None, :]))
    del r
    from joblib.externals.loky import get_reusable_executor

    get_reusable_executor().shutdown(wait=True)
    rss_workers = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss

    # what per-task Python objects would cost: a list of result dicts (measured on naive_n)
    tracemalloc.start()
    pts = g["a"].values.tolist()
    naive = [trivial(a=pts[i % side], b=1.0 + i * 1e-9) for i in range(naive_n)]
    naive_bytes = tracemalloc.get_traced_memory()[0]
    tracemalloc.stop()
    del naive
    print(
        json.dumps(
            {
                "n": g.size,
                "wall": wall,
                "ok": ok,
                "rss_before_kb": rss0,
                "rss_current_mb": cur0,
                "hwm_sweep_mb": hwm,
                "rss_peak_kb": rss1,
                "rss_workers_kb": rss_workers,
                "tracemalloc_peak": peak_py,
                "result_bytes": 2 * 8 * g.size,
                "naive_bytes": naive_bytes,
                "file_bytes": os.path.getsize(out),
            }
        )
    )


def bench_memory(n: int) -> dict[str, Any]:
    print(
        f"\n3. memory: {n} points of a trivial function, 2 outputs, streamed to netCDF (loky x2), measured once"
    )
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "big.nc")
        cmd = [sys.executable, __file__, "--memory-child", str(n), out]
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
        res = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True)
    d = json.loads(res.stdout.strip().splitlines()[-1])
    mb = 1 / 2**20
    print(
        f"   wall time                {d['wall']:8.2f} s  ({1e6 * d['wall'] / d['n']:.2f} us/point)  ok={d['ok']}"
    )
    print(
        f"   result arrays (2 x f8)   {d['result_bytes'] * mb:8.1f} MB   netCDF file {d['file_bytes'] * mb:.1f} MB"
    )
    if d["hwm_sweep_mb"] is not None:  # Linux: peak reset just before the sweep
        before, peak = d["rss_current_mb"], d["hwm_sweep_mb"]
    else:  # ru_maxrss: a high-water mark since start (inherited across fork on Linux)
        before, peak = d["rss_before_kb"] / 1024, d["rss_peak_kb"] / 1024
    print(f"   driver RSS before        {before:8.1f} MB   (numpy, scipy, joblib imported; workers started)")
    print(
        f"   driver RSS peak          {peak:8.1f} MB   (+{peak - before:.1f} MB during the sweep and the write)"
    )
    print(f"   worker RSS peak          {d['rss_workers_kb'] / 1024:8.1f} MB")
    print(f"   Python alloc peak        {d['tracemalloc_peak'] * mb:8.1f} MB   (tracemalloc, driver)")
    print(
        f"   list of per-task dicts   {d['naive_bytes'] * mb:8.1f} MB   (what is *not* held; measured, same n)"
    )
    return d


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes")
    ap.add_argument("--only", choices=["speedup", "overhead", "memory"], help="run one part")
    ap.add_argument("--repeat", type=int, default=5, help="interleaved repeats (>= 5)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "bench_sweep.json"))
    ap.add_argument("--memory-child", nargs=2, metavar=("N", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.memory_child:
        memory_child(int(args.memory_child[0]), args.memory_child[1], naive_n=int(args.memory_child[0]))
        return
    rep = max(5, args.repeat)
    load0 = loadavg()
    print(
        f"cpu count {os.cpu_count()}, load average {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}"
        + (
            "  (LOADED: other processes share the 2 cores; the speed-up is bounded by what is left)"
            if load0[0] > LOADED
            else ""
        )
    )
    result: dict[str, Any] = {
        "benchmark": "bench_sweep",
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "numpy": np.__version__,
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "load_average_start": list(load0),
        "commit": _commit(),
        "loaded_threshold": LOADED,
        "repeats": rep,
    }
    if args.only in (None, "speedup"):
        import chatterlab as cl

        reps = calibrate()
        per_task = min(busy(0.0, reps)["cpu"] for _ in range(5))
        n_busy = 40 if args.quick else 100
        fz = cl.assemble(cl.load_model(ROOT / "studies" / "traverse_shaper" / "model.toml")).at()
        # issue 26's sweep row: 72 points, 6 widths x 12 speeds
        g_cl = Grid({"width": np.linspace(0.0005, 0.002, 6), "speed": np.linspace(0.25, 1.0, 12)})
        workloads = {
            "numpy": (
                functools.partial(busy, reps=reps),
                Grid({"i": np.arange(float(n_busy))}),
                {"y": "", "wall": "s", "cpu": "s"},
                f"numpy sin/cos of {1e3 * per_task:.0f} ms CPU each (no BLAS)",
            ),
            "chatterlab": (
                functools.partial(abscissa, frozen=fz),
                g_cl,
                {"abscissa": "1/s"},
                "shaper rightmost root, case c, 6 widths 0.5-2 mm x 12 speeds 0.25-1 m/s (BLAS: eig, LU)",
            ),
        }
        if args.quick:
            workloads.pop("chatterlab")
        result["speedup"] = bench_speedup(workloads, rep)
    if args.only in (None, "overhead"):
        result["overhead"] = bench_overhead(20_000 if args.quick else 200_000, rep)
    if args.only in (None, "memory"):
        result["memory"] = bench_memory(100_000 if args.quick else 1_000_000)
    result["load_average_end"] = list(loadavg())
    loaded = load0[0] > LOADED or result["load_average_end"][0] > LOADED
    for part in ("speedup", "overhead"):
        for v in result.get(part, {}).values():
            if isinstance(v, dict):
                loaded = (
                    loaded
                    or any(isinstance(x, dict) and x.get("loaded") for x in v.values())
                    or bool(v.get("loaded"))
                )
    result["loaded"] = bool(loaded)
    if args.only and Path(args.out).is_file():
        # one part rerun: the other parts' earlier measurements stay, with their own dates
        kept = json.loads(Path(args.out).read_text())
        for part in ("speedup", "overhead", "memory"):
            if part != args.only and part in kept:
                result[part] = kept[part]
                result.setdefault("kept_from_earlier_run", {})[part] = kept.get("date_utc", "")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    print(
        f"\nload average at the end {result['load_average_end'][0]:.2f}"
        + (
            " -- LOADED machine: a 2-worker speed-up cannot reach 2x while other processes use the cores"
            if loaded
            else ""
        )
        + f"; wrote {args.out}"
    )


if __name__ == "__main__":
    main()
