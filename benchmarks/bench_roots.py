"""The roots row of issue 26: ``stability()`` on the traverse shaper refined to
306 coordinates (16 elements per beam), against its budget of 10 s CPU and
1 GB peak RSS (0.2.0: 19.3 s CPU, 2.7 GB, as the issue measured it).

Each repeat is a fresh interpreter (``python -c``) under one BLAS thread, so
its peak RSS is its own and nothing is cached between repeats; the child
reports its CPU time for the call (``time.process_time``), the wall time,
the verdict, whether the root search and the argument principle agree, the
right-half-plane count and the rightmost root; the driver records min and
median over the repeats, the 1-minute load before and after (LOADED above 1
on 2 cores), the commit, and writes ``benchmarks/results/roots.json`` with
an ``"issue26"`` entry that ``benchmarks/report.py`` puts on the
performance page.

    python benchmarks/bench_roots.py [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

from _common import load1 as _load
from _common import source_commit as _commit

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "roots.json"
SHAPER = ROOT / "studies" / "traverse_shaper" / "model.toml"

CHILD = """
import json, resource, sys, time
def hwm():  # this process's peak RSS, MB: VmHWM restarts at exec (ru_maxrss keeps the forking parent's)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
import chatterlab as cl
m = cl.load_model(sys.argv[1])
m = m.with_parameters({f"beam.{b.id}.elements": 16 for b in m.beams})
fz = cl.assemble(m).at(0.85)
w, t = time.perf_counter(), time.process_time()
st = cl.stability(fz, width=2e-4, speed=0.1)
cpu, wall = time.process_time() - t, time.perf_counter() - w
r = st.roots.roots[0]
print(json.dumps({"n": int(fz.structure.M.shape[0]), "cpu": cpu, "wall": wall, "verdict": st.verdict,
                  "agree": bool(st.agree), "count": st.winding.count, "re": r.real, "im": r.imag,
                  "rss_mb": hwm()}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    load0 = _load()
    runs = []
    for k in range(args.repeat):
        out = subprocess.run(
            [sys.executable, "-c", CHILD, str(SHAPER)], capture_output=True, text=True, env=env, check=True
        )
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
        r = runs[-1]
        print(f"repeat {k + 1}: {r['n']} coordinates, {r['cpu']:.2f} s CPU, {r['wall']:.2f} s wall, "
              f"{r['rss_mb']:.0f} MB, {r['verdict']} ({r['count']} roots right, agree {r['agree']})")  # fmt: skip
    load1 = _load()
    cpu = sorted(r["cpu"] for r in runs)
    wall = sorted(r["wall"] for r in runs)
    rss = max(r["rss_mb"] for r in runs)
    same = all(r["verdict"] == runs[0]["verdict"] and r["count"] == runs[0]["count"] for r in runs)
    loaded = max(load0, load1) > 1.0
    date = datetime.now(UTC).isoformat(timespec="seconds")
    doc = {
        "benchmark": "bench_roots",
        "date_utc": date,
        "commit": _commit(),
        "problem": "stability() on the traverse shaper, 16 elements per beam, width 0.2 mm, 0.1 m/s, s = 0.85 m",
        "repeats": runs,
        "cpu_s": {"min": cpu[0], "median": statistics.median(cpu)},
        "wall_s": {"min": wall[0], "median": statistics.median(wall)},
        "peak_rss_mb": rss,
        "load_1min": [load0, load1],
        "loaded": loaded,
        "issue26": [
            {
                "row": "roots",
                "label": "after",
                "case": f"{runs[0]['n']} coordinates, CPU",
                "chatterlab_s": [cpu[0], statistics.median(cpu)],
                "ratio": [cpu[0] / 10.0, statistics.median(cpu) / 10.0],
                "accuracy": f"verdict {runs[0]['verdict']}, {runs[0]['count']} roots right of the axis, "
                f"roots and argument principle agree: {all(r['agree'] for r in runs)}"
                + ("" if same else "; the repeats differ"),
                "load": load0,
                "peak_rss_mb": rss,
                "date": date,
                "commit": _commit(),
            }
        ],
    }
    OUT.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"CPU min {cpu[0]:.2f} s, median {statistics.median(cpu):.2f} s; peak RSS {rss:.0f} MB; "
          f"load {load0:.2f} -> {load1:.2f}{' LOADED' if loaded else ''}; wrote {OUT.relative_to(ROOT)}")  # fmt: skip


if __name__ == "__main__":
    main()
