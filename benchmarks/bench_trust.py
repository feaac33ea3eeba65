"""Issue 8's speed, memory and correctness targets, measured in one run.

Run from the repository root::

    python benchmarks/bench_trust.py                      # this checkout only
    python benchmarks/bench_trust.py --baseline fe522ca   # and a baseline commit, same run

What is measured (each command in a fresh process, so that wall time
includes start-up and the peak resident set size is the process's own,
read from ``os.wait4``; repeated ``--repeat`` times, min and median printed):

1. **main job**: the README's quick-start command (shaper, 300 speeds,
   verification on, netCDF + PNG).  Targets: <= 2.5 s wall, <= 250 MB.
2. **refined stability**: ``stability()`` on the shaper with every beam in 8
   elements (288 coordinates), b = 0.2 mm at 0.1 m/s (T = 6.3 s).
   Targets: <= 10 s, <= 1 GB.
3. **correctness**: b_lim at the 20 speeds of the issue's table (0.1-1 m/s,
   slide at 0.85 m, width ceiling 5 mm).  Each claim is checked against the
   sign of the rightmost characteristic root at (1 -+ 1e-6) b_lim, computed
   with *this* checkout's root solver (whose roots are unchanged since
   0.1.0); a claim "within 1e-6" has a stable root set just below and an
   unstable one just above.

The baseline runs from a ``git worktree`` of the given commit, with its own
code on PYTHONPATH.  Numbers go to ``benchmarks/results/bench_trust.json``.
The machine's load average is printed and stored: timings on a loaded
machine are not comparable.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import loadavg

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "traverse_shaper" / "model.toml"

#: the code under test comes from PYTHONPATH, not from an editable install of this
#: checkout nor from the working directory (the children run in /tmp)
PRELUDE = (
    "import sys; sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in repr(f).lower()];"
    " sys.path[:] = [p for p in sys.path if p not in ('', '.')]\n"
)
CWD = tempfile.gettempdir()

MAIN_JOB = PRELUDE + (
    "import sys; from chatterlab.cli import main; sys.argv = ['chatterlab', 'lobes', {model!r}, '--speed', '0.1',"
    " '1.0', '--width-max', '1', '--out', {out!r}, '--plot', {png!r}{extra}]; sys.exit(main())"
)
REFINED = (
    PRELUDE
    + """
import chatterlab as cl

m = cl.load_model({model!r})
m = m.with_parameters({{f"beam.{{b.id}}.elements": 8 for b in m.beams}})
fz = cl.assemble(m).at(0.85)
st = cl.stability(fz, width=2e-4, speed=0.1)
print(st.verdict, st.abscissa, fz.A.shape[0])
"""
)
CLAIMS = (
    PRELUDE
    + """
import json, numpy as np
import chatterlab as cl
from chatterlab.lobes import lobes
fz = cl.assemble(cl.load_model({model!r})).at(0.85)
d = lobes(fz, np.linspace(0.1, 1.0, 20), width_max=5e-3, verify=0)
print(json.dumps([d.b_lim.tolist(), d.delay.tolist()]))
"""
)


def timed(code: str, pythonpath: str, repeat: int) -> dict[str, object]:
    walls, rsss, status, out = [], [], 0, ""
    for _ in range(repeat):
        # ru_maxrss of RUSAGE_CHILDREN is the largest child so far: run each
        # measurement in a fresh helper process so the maximum is this command's
        helper = (
            "import resource, subprocess, sys, time, json; t = time.perf_counter();"
            f"p = subprocess.run([sys.executable, '-c', {code!r}], capture_output=True, text=True);"
            "w = time.perf_counter() - t;"
            "r = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0;"
            "print(json.dumps([w, r, p.returncode, p.stdout[-2000:] + (p.stderr[-400:] if p.returncode else '')]))"
        )
        env = dict(os.environ, PYTHONPATH=pythonpath, MPLBACKEND="Agg")
        res = subprocess.run(
            [sys.executable, "-c", helper], env=env, capture_output=True, text=True, check=True
        )
        w, r, status, out = json.loads(res.stdout)
        walls.append(w)
        rsss.append(r)
    return {
        "wall_min_s": min(walls),
        "wall_median_s": statistics.median(walls),
        "rss_max_mb": max(rsss),
        "exit_status": status,
        "output_tail": out.strip().splitlines()[-1] if out.strip() else "",
    }


def check_claims(b_lim: list[float], delay: list[float]) -> dict[str, object]:
    """How many claims lie within 1e-6 of the rightmost-root boundary, and the
    largest relative distance (found by bisection where a claim is outside)."""
    sys.path.insert(0, str(ROOT))
    import numpy as np

    import chatterlab as cl
    from chatterlab.frequency import stability

    fz = cl.assemble(cl.load_model(MODEL)).at(0.85)

    def absc(b: float, T: float) -> float:
        return stability(fz, width=b, delay=T, winding=False, count=2).abscissa

    within, worst = 0, 0.0
    for b, T in zip(b_lim, delay, strict=True):
        if not np.isfinite(b):
            continue
        if absc(b * (1 - 1e-6), T) < 0 < absc(b * (1 + 1e-6), T):
            within += 1
            continue
        lo, hi = 0.0, 5e-3
        for _ in range(40):
            m = 0.5 * (lo + hi)
            lo, hi = (m, hi) if absc(m, T) < 0 else (lo, m)
            if hi - lo < 1e-7 * hi:
                break
        worst = max(worst, abs(b / hi - 1))
    return {"claims": len(b_lim), "within_1e-6": within, "worst_relative_error": worst}


def measure(pythonpath: str, repeat: int, label: str) -> dict[str, object]:
    out: dict[str, object] = {"label": label}
    where = PRELUDE + "import chatterlab; print(chatterlab.__file__)"
    out["code"] = subprocess.run(
        [sys.executable, "-c", where],
        env=dict(os.environ, PYTHONPATH=pythonpath),
        capture_output=True,
        text=True,
        cwd=CWD,
    ).stdout.strip()
    with tempfile.TemporaryDirectory() as tmp:
        # old versions refused to overwrite without --force (not --force-angle, a milling option)
        extra = ", '--force'" if re.search(r"--force(?![-\w])", _cli_help(pythonpath)) else ""
        code = MAIN_JOB.format(model=str(MODEL), out=f"{tmp}/l.nc", png=f"{tmp}/l.png", extra=extra)
        out["main_job"] = timed(code, pythonpath, repeat)
    out["refined_stability"] = timed(REFINED.format(model=str(MODEL)), pythonpath, max(1, repeat // 2))
    res = subprocess.run(
        [sys.executable, "-c", CLAIMS.format(model=str(MODEL))],
        env=dict(os.environ, PYTHONPATH=pythonpath),
        capture_output=True,
        text=True,
        cwd=CWD,
    )
    if res.returncode == 0:
        b, T = json.loads(res.stdout.strip().splitlines()[-1])
        out["correctness"] = check_claims(b, T)
    else:
        out["correctness"] = {"error": res.stderr.strip().splitlines()[-1]}
    return out


def _cli_help(pythonpath: str) -> str:
    res = subprocess.run(
        [
            sys.executable,
            "-c",
            PRELUDE + "from chatterlab.cli import main; sys.argv=['x','lobes','-h']; main()",
        ],
        env=dict(os.environ, PYTHONPATH=pythonpath),
        capture_output=True,
        text=True,
        cwd=CWD,
    )
    return res.stdout


def report(r: dict[str, object]) -> None:
    print(f"== {r['label']} ({r['code']})")
    for key, (tw, tm) in {"main_job": (2.5, 250.0), "refined_stability": (10.0, 1000.0)}.items():
        m = r[key]
        assert isinstance(m, dict)
        if m["exit_status"]:
            print(
                f"  {key:18s} FAILED (exit {m['exit_status']}): no timing reported\n      {m['output_tail']}"
            )
            continue
        print(
            f"  {key:18s} wall min {m['wall_min_s']:.2f} s, median {m['wall_median_s']:.2f} s"
            f" (target {tw} s: {m['wall_min_s'] / tw:.2f}x), peak RSS {m['rss_max_mb']:.0f} MB"
            f" (target {tm:.0f} MB: {m['rss_max_mb'] / tm:.2f}x), exit {m['exit_status']}"
        )
    print(f"  correctness        {r['correctness']}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", help="git revision to measure in the same run (e.g. fe522ca)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "bench_trust.json"))
    args = ap.parse_args()
    load = loadavg()
    print(f"load average at start: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} (2 cores)")
    results = [measure(str(ROOT), args.repeat, "this checkout")]
    if args.baseline:
        with tempfile.TemporaryDirectory() as tmp:
            wt = Path(tmp) / "baseline"
            subprocess.run(
                ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(wt), args.baseline],
                check=True,
                capture_output=True,
            )
            try:
                results.append(measure(str(wt), args.repeat, f"baseline {args.baseline}"))
            finally:
                subprocess.run(
                    ["git", "-C", str(ROOT), "worktree", "remove", "--force", str(wt)], capture_output=True
                )
    for r in results:
        report(r)
    if len(results) == 2:
        a, b = results[0], results[1]
        for key in ("main_job", "refined_stability"):
            ma, mb = a[key], b[key]
            assert isinstance(ma, dict) and isinstance(mb, dict)
            if ma["exit_status"]:
                print(f"  {key}: this checkout failed (exit {ma['exit_status']}): no comparison")
            elif not mb["exit_status"]:
                print(
                    f"  {key}: baseline / this = {mb['wall_min_s'] / ma['wall_min_s']:.2f}x wall,"
                    f" {mb['rss_max_mb'] / ma['rss_max_mb']:.2f}x memory"
                )
            else:
                print(f"  {key}: the baseline failed (exit {mb['exit_status']})")
    path = Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"load_average": load, "results": results}, indent=2))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
