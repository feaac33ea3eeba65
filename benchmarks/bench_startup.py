"""Benchmark: the README's main job against its floor, in the same run (issue 26).

Run from the repository root::

    python benchmarks/bench_startup.py                  # about a minute on 2 idle cores
    python benchmarks/bench_startup.py --repeat 9 --label after

Two cases, each a fresh interpreter started as a user starts it, interleaved
(each round every case once in turn, so that a burst of outside load hits
both alike):

* **main job**: the README's first command, ``chatterlab lobes
  studies/traverse_shaper/model.toml --speed 0.1 1.0 --width-max 1 --out
  shaper_lobes.nc --plot shaper_lobes.png`` (in a temporary folder);
* **floor**: ``python -c "import numpy, scipy, matplotlib"`` plus drawing and
  saving an empty figure of the main job's own size (its PNG's pixels at its
  130 dpi): what any Python program that computes with numpy/scipy and saves
  a figure of that size costs on this machine.

Both run with compiled bytecode, as an installed package runs: pip compiles
every module at install time, and a source checkout writes its
``__pycache__`` on the first run -- unless ``PYTHONDONTWRITEBYTECODE`` is set,
as it is on the shared benchmark machine, where the main job then compiled
chatterlab's ~100 modules from source on every run (0.3 s of CPU that no user
pays, and the floor, all of whose modules come compiled with their wheels,
did not pay either).  The children get a fresh ``PYTHONPYCACHEPREFIX`` (a
temporary folder; the source tree is not written) filled by the warm-up run
of each case.

For each: wall time (the whole process, start-up included), CPU time
(user + system of the child, ``os.wait4``) and peak RSS, min and median over
the repeats; the goal is main job <= 2 x floor.  The 1-minute load average
before and after; above 1 (2 cores) the run is flagged LOADED.  Results go to
``benchmarks/results/startup.json`` under ``--label`` (runs by label, so a
before and an after sit side by side); ``benchmarks/report.py`` puts them on
docs/performance.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from _common import load1, loadavg
from _common import source_commit as commit

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "startup.json"
LOADED = 1.0  # 1-minute load average above which a run is flagged (2 cores)
GOAL = 2.0  # main job / floor
DPI = 130  # the main job's savefig dpi (chatterlab.plot.savefig)


def chatterlab_command() -> list[str]:
    """The installed console script, else the module."""
    script = Path(sys.executable).with_name("chatterlab")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "chatterlab.cli"]


def run(cmd: list[str], cwd: Path, env: dict[str, str]) -> dict[str, Any]:
    """Wall and CPU seconds and peak RSS (MB) of one child process."""
    t = time.perf_counter()
    p = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t
    out = p.stdout.read().decode() if p.stdout else ""
    err = p.stderr.read().decode() if p.stderr else ""
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}): {err[-800:]}")
    return {"wall": wall, "cpu": ru.ru_utime + ru.ru_stime, "rss_mb": ru.ru_maxrss / 1024, "stdout": out}


def png_size(path: Path) -> tuple[int, int]:
    """Width and height (pixels) from a PNG's IHDR chunk."""
    head = path.read_bytes()[:24]
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def summary(samples: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k in ("wall", "cpu"):
        xs = [s[k] for s in samples]
        out |= {f"{k}_min_s": min(xs), f"{k}_median_s": statistics.median(xs), f"{k}_s": xs}
    out["peak_rss_mb"] = max(s["rss_mb"] for s in samples)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=7, help="timing repeats (>= 5), interleaved over the cases")
    ap.add_argument(
        "--label", default="current", help="the run's name in the results file (before, after, ...)"
    )
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args()
    rep = max(5, args.repeat)
    tmp = Path(tempfile.mkdtemp(prefix="bench_startup_"))
    # compiled bytecode for both cases, as an installed package has (see the docstring)
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPYCACHEPREFIX=str(tmp / "pycache"))
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    try:
        model = ROOT / "studies" / "traverse_shaper" / "model.toml"
        job = [*chatterlab_command(), "lobes", str(model), "--speed", "0.1", "1.0", "--width-max", "1"]
        job += ["--out", "shaper_lobes.nc", "--plot", "shaper_lobes.png"]
        warm = run(job, tmp, env)  # warms the file cache; gives the figure's size
        w, h = png_size(tmp / "shaper_lobes.png")
        floor_code = (
            "import numpy, scipy, matplotlib; import matplotlib.pyplot as plt; "
            f"fig = plt.figure(figsize=({w / DPI!r}, {h / DPI!r}), dpi={DPI}); "
            f"fig.savefig('empty.png', dpi={DPI})"
        )
        floor = [sys.executable, "-c", floor_code]
        run(floor, tmp, env)
        cases = {"floor": floor, "main job": job}
        load0 = list(loadavg())
        print(f"load {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}; figure {w} x {h} px; {rep} repeats")
        samples: dict[str, list[dict[str, Any]]] = {k: [] for k in cases}
        for i in range(rep):
            for name, cmd in cases.items():
                samples[name].append(run(cmd, tmp, env))
            print(
                f"  round {i + 1}: "
                + ", ".join(
                    f"{n} {s[-1]['wall']:.2f} s wall {s[-1]['cpu']:.2f} s CPU" for n, s in samples.items()
                )
                + f"  (load {load1():.2f})"
            )
        load_end = list(loadavg())
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    res = {k: summary(v) for k, v in samples.items()}
    m = re.search(r"absolute minimum \(all speeds\): ([0-9.]+ mm)", warm["stdout"])
    res["main job"]["result"] = f"absolute minimum b_lim {m.group(1)}" if m else ""
    res["main job"]["command"] = "chatterlab " + " ".join(job[len(chatterlab_command()) :])
    res["floor"]["command"] = f'python -c "{floor_code}"'
    ratios = {
        f"{k}_{s}": res["main job"][f"{k}_{s}_s"] / res["floor"][f"{k}_{s}_s"]
        for k in ("wall", "cpu")
        for s in ("min", "median")
    }
    loaded = max(load0[0], load_end[0]) > LOADED
    run_rec = {
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "commit": commit(),
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "figure_px": [w, h],
        "bytecode": "compiled (a fresh PYTHONPYCACHEPREFIX, filled by each case's warm-up run)",
        "repeats": rep,
        "load_average_start": load0,
        "load_average_end": load_end,
        "loaded": loaded,
        "goal": f"main job <= {GOAL:g} x floor",
        "ratios": ratios,
        "goal_met_cpu": ratios["cpu_min"] <= GOAL,
        "goal_met_wall": ratios["wall_min"] <= GOAL,
        "cases": res,
    }
    path = Path(args.out)
    data = json.loads(path.read_text()) if path.is_file() else {}
    data.setdefault("benchmark", "bench_startup (issue 26, README main job)")
    data.setdefault("runs", {})[args.label] = run_rec
    path.write_text(json.dumps(data, indent=2) + "\n")
    for k in ("floor", "main job"):
        r = res[k]
        print(
            f"{k:9s} wall {r['wall_min_s']:.2f} / {r['wall_median_s']:.2f} s, CPU {r['cpu_min_s']:.2f} / "
            f"{r['cpu_median_s']:.2f} s (min / median), peak RSS {r['peak_rss_mb']:.0f} MB"
        )
    print(
        f"main job / floor: wall {ratios['wall_min']:.2f} / {ratios['wall_median']:.2f}, "
        f"CPU {ratios['cpu_min']:.2f} / {ratios['cpu_median']:.2f} (goal <= {GOAL:g})"
        + ("  LOADED" if loaded else "")
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
