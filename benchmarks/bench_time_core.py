"""Before and after the one Newmark core (issue 19): speed and numbers, in the same run.

Run from the repository root::

    python benchmarks/bench_time_core.py                 # 7 interleaved repeats
    python benchmarks/bench_time_core.py --repeats 5 --before 63e1fc16a90e4a3b9de2b3f1a0637b86a7739835

The "before" code is the commit before the move (``--before``, default the
pre-move commit), checked out by ``git worktree`` into a temporary folder
and removed at the end; "after" is this tree.  Each repeat runs one fresh
interpreter per version, alternately (before, after, before, ...), so that
the load of the shared machine falls on both alike; each interpreter warms
up (imports, the shaper's modes) and then times each case once (wall time of
the call, single-threaded BLAS, the integrator's default worker threads).
The 1-minute load average is read from ``/proc/loadavg`` before every
interpreter.  The cases:

* ``shaper``: the example of docs/time-domain.md section 6, case (c) of the
  paper, b = 2 mm, v_w = 0.5 m/s, 3 stroke cycles at the default step;
* ``turning``: the 1-DOF turning tool of the tests, a continuous cut of 0.4 s
  at h = 1e-4 s from q0 = 1 um (a ConstantProblem, the verdict's path);
* ``milling_flip``: the 1-DOF milling benchmark (Insperger & Stepan), a_e/D =
  0.05 down-milling, 10000 rpm, 5 mm, f_z = 0.1 mm, m = 100, 60 revolutions:
  the teeth leave the cut, period-two chatter (the example of the docs);
* ``milling_linear``: the same, linear, 30 revolutions;
* ``milling_runout``: full immersion, 25000 rpm, 2 mm, runout 0.05 mm and
  edge forces, m = 200, 30 revolutions: the instants a tooth leaves the
  material are located and stepped to;
* ``milling_pitch``: the x/y 2-DOF benchmark, three teeth of variable pitch
  (100, 120, 140 deg, delays off the grid), runout and edge forces, 25
  revolutions.

The first run of each version also saves its trajectories; the largest
difference after - before of every case (absolute, and relative to the
largest value of the history) is written beside the times.  On a shared,
loaded machine the wall times scatter by tens of per cent; ``--instructions
CASE ...`` also counts the machine instructions of one run of those cases
under valgrind's callgrind (two runs minus one, in one interpreter each),
which the load does not change.  Results:
``benchmarks/results/time_core_refactor.json``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from _common import load1 as load

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "time_core_refactor.json"
BEFORE = "63e1fc16a90e4a3b9de2b3f1a0637b86a7739835"
#: the 1-DOF turning tool of the tests (tests/conftest.py turning_text(): 1 kg, 10 MN/m, 3 % damping,
#: Kf = 2e9 N/m^2 at b_ref = 1 mm, 3000 rpm)
TURNING = """
[model]
name = "turning tool, one degree of freedom"
[[body]]
id = "tool"
mass = 1.0
inertia = 1.0e-3
centre = [0.0, 0.0]
[[support]]
id = "guide"
body = "tool"
fix = ["y", "rz"]
[[spring]]
id = "holder"
a = "tool"
b = "ground"
c1 = 10000000.0
d1 = 189.7
[[point]]
id = "tip"
body = "tool"
[[coupling]]
id = "cut"
a = "tip"
b = "ground"
model = "regenerative"
width_ref = 0.001
Kf = 2000000000.0
[process]
kind = "turning"
rpm = 3000.0
"""


# =========================================================================== the worker (one version)


def _cases() -> dict[str, Any]:
    """name -> a function running the case and returning its histories (the
    0.2 keywords, which both versions take: the same call before and after)."""
    import numpy as np

    import chatterlab as cl
    from chatterlab.process._milling import Milling
    from chatterlab.time import simulate, simulate_milling

    shaper = cl.assemble(cl.load_model(str(ROOT / "studies/traverse_shaper/model.toml")))
    tool = cl.assemble(cl.loads_model(TURNING))
    m, fn, zeta = 0.03993, 922.0, 0.011
    wn = 2 * math.pi * fn
    one = ([[m]], [[2 * zeta * m * wn]], [[m * wn**2]])
    two = tuple(np.eye(2) * a[0][0] for a in one)
    c005 = Milling.from_immersion(2, 0.02, 6e8, 2e8, 0.05, "down")
    full = Milling.from_immersion(2, 0.02, 6e8, 2e8, 1.0, "down", Kte=2e4, Kne=1e4)
    pitch = tuple(math.radians(a) for a in (100.0, 120.0, 140.0))
    vp = Milling.from_immersion(3, 0.02, 6e8, 2e8, 0.5, "down", pitch=pitch, Kte=1e4, Kne=5e3)

    def cut(sim: Any) -> dict[str, Any]:
        return {"t": sim.t, "q": sim.response.q, **sim.data}

    def mill(r: Any) -> dict[str, Any]:
        return {"t": r.t, "x": r.x, "y": r.y, "vx": r.vx, "Fx": r.Fx, "Fy": r.Fy, "chip": r.chip}

    return {
        "shaper": lambda: cut(simulate(shaper, feedback="pdo", width=0.002, speed=0.5, passes=3)),
        "turning": lambda: cut(
            simulate(
                tool, width=6e-4, delay=0.02, duration=0.4, step=1e-4, q0={"tool.x": 1e-6}, outputs="tool.x"
            )
        ),
        "milling_flip": lambda: mill(
            simulate_milling(one, c005, 10000.0, 5e-3, feed=1e-4, steps_per_period=100, revolutions=60)
        ),
        "milling_linear": lambda: mill(
            simulate_milling(one, c005, 10000.0, 5e-3, nonlinear=False, steps_per_period=100, revolutions=30)
        ),
        "milling_runout": lambda: mill(
            simulate_milling(
                one, full, 25000.0, 2e-3, feed=1e-4, runout=[5e-5, 0.0], steps_per_period=200, revolutions=30
            )
        ),
        "milling_pitch": lambda: mill(
            simulate_milling(
                two,
                vp,
                12000.0,
                1e-3,
                feed=1e-4,
                runout=[1e-5, 0.0, -5e-6],
                steps_per_period=90,
                revolutions=25,
                tool_point=np.eye(2),
            )  # fmt: skip
        ),
    }


def worker(save: str | None, only: str | None = None, runs: int = 1) -> None:
    """Time every case (or ``only`` that one, ``runs`` times) once after a
    warm-up; print the wall times as JSON (and save the histories to
    ``save``, an .npz)."""
    import time
    import warnings

    import numpy as np
    from threadpoolctl import threadpool_limits

    warnings.simplefilter("ignore", DeprecationWarning)
    with threadpool_limits(1):
        cases = _cases()
        import chatterlab as cl
        from chatterlab.time import simulate

        simulate(cl.assemble(cl.load_model(str(ROOT / "studies/traverse_shaper/model.toml"))), duration=0.05)
        walls, saved = {}, {}
        for name, run in cases.items():
            if only is not None and name != only:
                continue
            for _ in range(runs):
                t0 = time.perf_counter()
                out = run()
                walls[name] = time.perf_counter() - t0
            saved.update({f"{name}/{k}": np.asarray(v) for k, v in out.items()})
    if save:
        np.savez(save, **saved)
    print(json.dumps(walls))


def instructions(tree: Path, case: str) -> float:
    """Machine instructions of one run of ``case`` in the version in ``tree``
    (callgrind's ``Ir`` of two runs minus one, in one interpreter each): a
    cost the load of a shared machine does not change."""
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    counts = []
    for runs in (1, 2):
        cmd = ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null", sys.executable,
               str(Path(__file__).resolve()), "--worker", "--only", case, "--runs", str(runs)]  # fmt: skip
        out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True, cwd=ROOT)
        line = [ln for ln in out.stderr.splitlines() if "Collected" in ln][-1]
        counts.append(float(line.split()[-1]))
    return counts[1] - counts[0]


# =========================================================================== the driver


def run_version(tree: Path, save: str | None) -> tuple[dict[str, float], float]:
    """One interpreter of the version in ``tree``: (wall times, load average before)."""
    la = load()
    env = {**os.environ, "PYTHONPATH": str(tree), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker"] + (["--save", save] if save else [])
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1]), la


def differences(before: str, after: str) -> dict[str, dict[str, float]]:
    """Largest |after - before| of every case's histories, absolute and relative to max |before|."""
    import numpy as np

    a, b = np.load(before), np.load(after)
    out: dict[str, dict[str, float]] = {}
    for key in a.files:
        case = key.split("/")[0]
        x, y = a[key], b[key]
        row = out.setdefault(case, {"max_abs": 0.0, "max_rel": 0.0, "identical": 1.0})
        if x.shape != y.shape:
            row.update(max_abs=math.inf, max_rel=math.inf, identical=0.0)
            continue
        with np.errstate(invalid="ignore"):
            d = float(np.nanmax(np.abs(x - y))) if x.size else 0.0
            s = float(np.nanmax(np.abs(x))) if x.size else 0.0
        row["max_abs"] = max(row["max_abs"], d)
        row["max_rel"] = max(row["max_rel"], d / s if s else d)
        row["identical"] = min(row["identical"], float(np.array_equal(x, y, equal_nan=True)))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", default=BEFORE, help="the commit before the move (default: %(default)s)")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument(
        "--instructions", nargs="*", default=[], metavar="CASE",
        help="also count the machine instructions of these cases under valgrind (slow: minutes each)",
    )  # fmt: skip
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--save", help=argparse.SUPPRESS)
    ap.add_argument("--only", help=argparse.SUPPRESS)
    ap.add_argument("--runs", type=int, default=1, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        worker(args.save, args.only, args.runs)
        return
    import signal

    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # a kill still removes the worktree
    tmp = Path(tempfile.mkdtemp(prefix="time_core_"))
    old = tmp / "before"
    subprocess.run(["git", "worktree", "add", "--detach", str(old), args.before], cwd=ROOT, check=True,
                   capture_output=True)  # fmt: skip
    try:
        times: dict[str, dict[str, list[float]]] = {"before": {}, "after": {}}
        loads: dict[str, list[float]] = {"before": [], "after": []}
        load0 = load()
        print(f"load average {load0:.2f} at the start, {os.cpu_count()} cores; {args.repeats} repeats")
        for rep in range(args.repeats):
            for version, tree in (("before", old), ("after", ROOT)):
                save = str(tmp / f"{version}.npz") if rep == 0 else None
                walls, la = run_version(tree, save)
                loads[version].append(la)
                for case, w in walls.items():
                    times[version].setdefault(case, []).append(w)
            print(
                f"  repeat {rep + 1}: "
                + ", ".join(f"{c} {times['after'][c][-1]:.3f} s" for c in times["after"])
            )
        diffs = differences(str(tmp / "before.npz"), str(tmp / "after.npz"))
        counts = {}
        for case in args.instructions:
            counts[case] = {"before": instructions(old, case), "after": instructions(ROOT, case)}
            c = counts[case]
            print(f"  {case}: {c['before'] / 1e6:.1f}M -> {c['after'] / 1e6:.1f}M instructions per run")
    finally:
        subprocess.run(
            ["git", "worktree", "remove", "--force", str(old)], cwd=ROOT, check=False, capture_output=True
        )
        shutil.rmtree(tmp, ignore_errors=True)
    rows = {}
    print(
        f"\n{'case':16s} {'before min/median [s]':>24s} {'after min/median [s]':>24s} {'after/before (min)':>19s}  largest difference"
    )
    for case in times["after"]:
        b, a = times["before"][case], times["after"][case]
        row = {
            "before_min_s": min(b), "before_median_s": statistics.median(b), "before_s": b,
            "after_min_s": min(a), "after_median_s": statistics.median(a), "after_s": a,
            "ratio_min": min(a) / min(b), "ratio_median": statistics.median(a) / statistics.median(b),
            **{f"difference_{k}": v for k, v in diffs.get(case, {}).items()},
        }  # fmt: skip
        if case in counts:
            row["instructions_before"] = counts[case]["before"]
            row["instructions_after"] = counts[case]["after"]
            row["instructions_ratio"] = counts[case]["after"] / counts[case]["before"]
        rows[case] = row
        d = diffs.get(case, {})
        dtext = "identical" if d.get("identical") else f"{d.get('max_rel', math.nan):.2g} relative"
        print(f"{case:16s} {min(b):11.3f} / {statistics.median(b):8.3f} {min(a):11.3f} / {statistics.median(a):8.3f}"
              f" {row['ratio_min']:12.3f} ({row['ratio_median']:.3f})  {dtext}")  # fmt: skip
    result = {
        "benchmark": "bench_time_core",
        "date_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "before": args.before,
        "machine": {
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "platform": platform.platform(),
        },
        "load_average_start": load0,
        "load_average_before_each_run": loads,
        "repeats": args.repeats,
        "note": "wall time of each call in a fresh interpreter after a warm-up, single-threaded BLAS; "
        "before and after alternate; min and median over the repeats; difference = largest "
        "|after - before| over each case's histories (relative: to max |before|); instructions: "
        "callgrind's count of one run (two runs minus one), independent of the machine's load",
        "cases": rows,
    }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    print(f"\nwritten {args.out}")


if __name__ == "__main__":
    main()
