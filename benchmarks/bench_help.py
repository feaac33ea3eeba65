"""Benchmark: ``chatterlab --help`` against a bare ``python -c pass``, in the same run.

Run from the repository root::

    python benchmarks/bench_help.py              # about half a minute on 2 idle cores
    python benchmarks/bench_help.py --repeat 5

Every case is a fresh interpreter started as a user starts it (wall time of
the whole process, start-up included):

* ``python -c pass``: the floor, what any Python command costs on this
  machine (the interpreter and its site-packages' start-up hooks);
* ``chatterlab --help`` and ``chatterlab lobes -h``: the installed console
  script (beside ``sys.executable``; ``python -m chatterlab.cli`` where there
  is none);
* ``python -c "import numpy"``: what ``--help`` cost before the command line
  was parsed first (issue 20, item 8: it imported numpy, and more, before
  parsing), for scale.

The goal is ``chatterlab --help`` within 2x ``python -c pass`` (min over the
repeats).  The cases run interleaved, each round every case once in turn, so
that a burst of outside load hits all alike; min and median wall times are
printed with the load average (``os.getloadavg``) before and after, and runs
with a 1-minute load above 0.5 are flagged LOADED (the machine has 2 cores).
Everything goes to ``benchmarks/results/bench_help.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from _common import loadavg as load

ROOT = Path(__file__).resolve().parents[1]
LOADED = 0.5  # 1-minute load average above which a timing is flagged
GOAL = 2.0  # chatterlab --help / python -c pass, min over the repeats


def chatterlab_command() -> list[str]:
    """The installed console script, else the module."""
    script = Path(sys.executable).with_name("chatterlab")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "chatterlab.cli"]


def wall(cmd: list[str]) -> float:
    t = time.perf_counter()
    r = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=ROOT)
    dt = time.perf_counter() - t
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({r.returncode}): {r.stderr.decode()[-500:]}")
    return dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--repeat", type=int, default=20, help="timing repeats (>= 5), interleaved over the cases"
    )
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "bench_help.json"))
    args = ap.parse_args()
    rep = max(5, args.repeat)

    cl = chatterlab_command()
    cases: dict[str, list[str]] = {
        "python -c pass": [sys.executable, "-c", "pass"],
        "chatterlab --help": [*cl, "--help"],
        "chatterlab lobes -h": [*cl, "lobes", "-h"],
        'python -c "import numpy"': [sys.executable, "-c", "import numpy"],
    }
    for cmd in cases.values():  # warm the file cache, untimed
        wall(cmd)
    l0 = load()
    print(
        f"python {platform.python_version()}, {os.cpu_count()} CPUs, {rep} repeats, load average"
        f" {l0[0]:.2f} {l0[1]:.2f} {l0[2]:.2f}"
        + ("  (LOADED: timings inflated by other processes)" if l0[0] > LOADED else "")
    )
    times: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(rep):
        for name, cmd in cases.items():
            times[name].append(wall(cmd))
    l1 = load()

    floor = min(times["python -c pass"])
    floor_med = statistics.median(times["python -c pass"])
    print(
        f"\n   {'case':28s} {'min ms':>8s} {'median ms':>10s} {'x pass (min)':>13s} {'x pass (median)':>16s}"
    )
    rows: dict[str, Any] = {}
    for name, ts in times.items():
        mn, md = min(ts), statistics.median(ts)
        rows[name] = {
            "command": cases[name],
            "min_s": mn,
            "median_s": md,
            "times_s": ts,
            "ratio_to_pass_min": mn / floor,
            "ratio_to_pass_median": md / floor_med,
        }
        print(f"   {name:28s} {mn * 1e3:8.1f} {md * 1e3:10.1f} {mn / floor:13.2f} {md / floor_med:16.2f}")
    ratio = rows["chatterlab --help"]["ratio_to_pass_min"]
    loaded = bool(max(l0[0], l1[0]) > LOADED)
    verdict = "met" if ratio <= GOAL else "NOT met"
    print(
        f"\nchatterlab --help / python -c pass = {ratio:.2f} (min), goal <= {GOAL:g}: {verdict};"
        f" load average after {l1[0]:.2f} {l1[1]:.2f} {l1[2]:.2f}" + (" LOADED" if loaded else "")
    )
    try:
        sys.path.insert(0, str(ROOT))
        from chatterlab._version import __version__
    except ImportError:
        __version__ = "unknown"
    result = {
        "benchmark": "bench_help",
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "chatterlab": __version__,
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "load_average_start": list(l0),
        "load_average_end": list(l1),
        "loaded_threshold": LOADED,
        "loaded": loaded,
        "repeats": rep,
        "goal": f"chatterlab --help <= {GOAL:g} x python -c pass (min)",
        "ratio_help_to_pass_min": ratio,
        "ratio_help_to_pass_median": rows["chatterlab --help"]["ratio_to_pass_median"],
        "goal_met": ratio <= GOAL,
        "cases": rows,
    }
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
