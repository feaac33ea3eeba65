"""Benchmark of the sweep engine (chatterlab.sweep._engine): speed-up, per-task overhead, memory.

Run from the repository root::

    python benchmarks/bench_sweep.py            # everything (about a minute on 2 cores)
    python benchmarks/bench_sweep.py --quick    # smaller sizes

It prints:

1. **speed-up** of the loky backend with 2 workers over the serial backend for
   200 CPU-bound numpy tasks of about 50 ms each (target >= 1.8x), with the
   loky executor cold (first call: worker start-up included) and warm;
2. **overhead per task** for tiny tasks: a plain Python loop vs the serial
   engine vs loky with 2 workers;
3. **memory** of a 10^6-point sweep of a trivial function streamed to a
   netCDF file (``out=``), measured in a fresh child process: peak RSS of the
   driver process (and of the workers) vs the size of the result arrays, and
   the Python allocation peak (tracemalloc) vs what a list of per-task dicts
   would hold.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

try:
    import chatterlab  # noqa: F401
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from chatterlab.sweep._engine import Grid, sweep


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


def calibrate(target: float = 0.050) -> int:
    reps = 10
    while True:  # on CPU time, so that outside load does not shorten the tasks
        dt = busy(0.0, reps)["cpu"]
        if dt > 0.02:
            return max(1, round(reps * target / dt))
        reps *= 2


def bench_speedup(n_tasks: int, repeat: int) -> None:
    reps = calibrate()
    f = functools.partial(busy, reps=reps)
    g = Grid({"i": np.arange(float(n_tasks))})
    outs = {"y": "", "wall": "s", "cpu": "s"}
    per_task = min(busy(0.0, reps)["cpu"] for _ in range(5))
    print(f"\n1. speed-up: {n_tasks} tasks of {1e3 * per_task:.0f} ms CPU (numpy sin/cos), best of {repeat}")

    def run(backend: str) -> tuple[float, object]:
        t = time.perf_counter()
        r = sweep(f, g, outputs=outs, backend=backend, jobs=2, progress=False)  # type: ignore[arg-type]
        return time.perf_counter() - t, r

    t_cold, cold = run("loky")  # first call: starts the loky workers
    t_ser, t_par = np.inf, np.inf
    for _ in range(repeat):  # interleaved, so that a burst of outside load hits both
        dt, ser = run("serial")
        t_ser = min(t_ser, dt)
        dt, par = run("loky")
        if dt < t_par:
            t_par, best = dt, par
    same = np.array_equal(ser["y"], par["y"]) and np.array_equal(ser["y"], cold["y"])  # type: ignore[index]
    work = float(np.sum(best["wall"]))  # type: ignore[index]
    share = float(np.sum(best["cpu"])) / work  # type: ignore[index]
    busy_frac = work / (2 * t_par)
    print(f"   serial            {t_ser:7.2f} s")
    print(
        f"   loky x2 (cold)    {t_cold:7.2f} s   speed-up {t_ser / t_cold:.2f}x  (includes worker start-up)"
    )
    print(f"   loky x2 (warm)    {t_par:7.2f} s   speed-up {t_ser / t_par:.2f}x  (target >= 1.8x)")
    print(f"   workers busy      {100 * busy_frac:6.1f} %  of 2 x wall time (engine idle/overhead: the rest)")
    print(
        f"   CPU share         {100 * share:6.1f} %  of task wall time actually on a CPU (< 100: contention)"
    )
    print(f"   => speed-up on 2 idle cores ~ {2 * busy_frac:.2f}x  (2 x busy fraction)")
    print(f"   results bit-identical: {same}")


def bench_overhead(n_tasks: int) -> None:
    values = np.linspace(0.0, 1.0, n_tasks)
    g = Grid({"x": values})
    print(f"\n2. overhead per task: {n_tasks} tiny tasks (func returns {{'y': x}})")
    t = time.perf_counter()
    sink = [tiny(x=v) for v in values.tolist()]
    t_loop = time.perf_counter() - t
    del sink
    t = time.perf_counter()
    sweep(tiny, g, outputs={"y": ""}, backend="serial", progress=False)
    t_ser = time.perf_counter() - t
    sweep(tiny, g, outputs={"y": ""}, backend="loky", jobs=2, progress=False)  # warm the workers
    t = time.perf_counter()
    sweep(tiny, g, outputs={"y": ""}, backend="loky", jobs=2, progress=False)
    t_loky = time.perf_counter() - t
    us = 1e6 / n_tasks
    print(f"   plain loop        {us * t_loop:6.2f} us/task")
    print(f"   engine serial     {us * t_ser:6.2f} us/task   (overhead {us * (t_ser - t_loop):+.2f} us/task)")
    print(f"   engine loky x2    {us * t_loky:6.2f} us/task   (wall time / tasks, warm workers)")


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
    naive_bytes = tracemalloc.get_traced_memory()[0] * n / naive_n
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


def bench_memory(n: int) -> None:
    print(f"\n3. memory: {n} points of a trivial function, 2 outputs, streamed to netCDF (loky x2)")
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
    print(f"   list of per-task dicts   {d['naive_bytes'] * mb:8.1f} MB   (what is *not* held; extrapolated)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="smaller sizes")
    ap.add_argument("--only", choices=["speedup", "overhead", "memory"], help="run one part")
    ap.add_argument("--memory-child", nargs=2, metavar=("N", "OUT"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.memory_child:
        memory_child(int(args.memory_child[0]), args.memory_child[1], naive_n=100_000)
        return
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"cpu count {os.cpu_count()}, load average {load:.2f} (other processes skew the timings)")
    if args.only in (None, "speedup"):
        bench_speedup(60 if args.quick else 200, repeat=1 if args.quick else 3)
    if args.only in (None, "overhead"):
        bench_overhead(20_000 if args.quick else 200_000)
    if args.only in (None, "memory"):
        bench_memory(100_000 if args.quick else 1_000_000)


if __name__ == "__main__":
    main()
