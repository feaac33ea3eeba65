"""Benchmark of the stability lobe diagram of the traverse shaper, measured.

Run from the repository root::

    python benchmarks/bench_lobes.py                     # ~1.5 minutes on 2 idle cores
    python benchmarks/bench_lobes.py --compare-speeds 10 # the 10-speed comparison (~3 min)
    python benchmarks/bench_lobes.py --quick             # 3 speeds compared

Paper's CE with all terms (case c), width_max 5 mm.  Everything below is
measured in this run; nothing is extrapolated.

1. ``lobes()`` on 300 work speeds 0.1-1 m/s, cold (complex modes
   recomputed), ``verify=0`` and with its default argument-principle checks;
   ``--repeat`` interleaved repeats, min and median.
2. The comparison at equal accuracy on ``--compare-speeds`` speeds spread
   over 0.1-1 m/s (default 6):

   * ``lobes()`` on exactly those speeds (``verify=0`` and default), repeated;
   * brute-force bisection on the width at each speed, deciding on the sign
     of the rightmost characteristic root (``stability(..., winding=False)
     .abscissa``) at every step, from [0, width_max] until the bracket is
     below ``--tol`` (1e-6) of its upper end -- run for real, once per speed
     (one run of the whole set takes most of the minute);
   * what a competent user would do instead of bisection: Brent's method
     (``scipy.optimize.brentq``) on the abscissa as a continuous function of
     the width, same bracket and relative tolerance -- also run for real.

   Each reports its root computations, wall time, and b_lim relative to
   ``lobes()`` (equal accuracy: both agree to the tolerance).  The ratio
   printed is (brute-force time on those speeds) / (``lobes()`` time on
   those speeds): no extrapolation to 300 speeds.

Load averages (``os.getloadavg``) are recorded with every timing; a 1-minute
load above 0.5 is flagged LOADED (2 cores).  Numbers go to
``benchmarks/results/bench_lobes.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import brentq

try:
    import chatterlab as cl
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import chatterlab as cl

from chatterlab.frequency._stability import stability
from chatterlab.lobes._diagram import lobes

ROOT = Path(__file__).resolve().parents[1]
LOADED = 0.5


def load() -> float:
    return float(os.getloadavg()[0]) if hasattr(os, "getloadavg") else float("nan")


def stats(times: list[float], l0: float, l1: float) -> dict[str, Any]:
    return {
        "min_s": min(times),
        "median_s": float(np.median(times)),
        "times_s": times,
        "load_before": l0,
        "load_after": l1,
        "loaded": bool(max(l0, l1) > LOADED),
    }


def timed(routes: dict[str, Callable[[], Any]], repeat: int) -> dict[str, tuple[dict[str, Any], Any]]:
    """Interleaved repeats (a burst of outside load hits every route alike)."""
    times: dict[str, list[float]] = {k: [] for k in routes}
    out: dict[str, Any] = {}
    l0 = load()
    for _ in range(repeat):
        for k, fn in routes.items():
            t = time.perf_counter()
            out[k] = fn()
            times[k].append(time.perf_counter() - t)
    l1 = load()
    return {k: (stats(v, l0, l1), out[k]) for k, v in times.items()}


def fmt(rec: dict[str, Any]) -> str:
    return (
        f"min {rec['min_s']:7.3f} s, median {rec['median_s']:7.3f} s"
        f"  (load {rec['load_before']:.2f}->{rec['load_after']:.2f}{' LOADED' if rec['loaded'] else ''})"
    )


class Counted:
    """abscissa(width) at one delay, counting root computations."""

    def __init__(self, fz: cl.FrozenSystem, delay: float) -> None:
        self.fz, self.delay, self.n = fz, delay, 0

    def __call__(self, width: float) -> float:
        self.n += 1
        return float(stability(self.fz, width=width, delay=self.delay, terms="pdo", winding=False).abscissa)


def bisect(f: Counted, width_max: float, tol: float) -> float:
    """Brute force: bisection on the sign of the rightmost root.  Decides on
    the sign of Re lambda, not on the verdict: stability() calls |Re lambda|
    <= MARGINAL_TOL |lambda| "marginal", a band of about +-5e-5 relative in
    width around the shaper's b_lim, too wide for a 1e-6 bisection."""
    if f(width_max) < 0:
        return math.inf
    lo, hi = 0.0, width_max
    while hi - lo > tol * hi:
        mid = 0.5 * (lo + hi)
        if f(mid) < 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def brent(f: Counted, width_max: float, tol: float, a0: float) -> float:
    """Brent's method on abscissa(width) in [0, width_max]; abscissa(0) is
    the structure's own (from its complex modes, no root computation)."""
    fb = f(width_max)
    if fb < 0:
        return math.inf
    return float(brentq(lambda b: a0 if b == 0.0 else f(b), 0.0, width_max, xtol=1e-15, rtol=tol))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="3 speeds compared")
    ap.add_argument("--repeat", type=int, default=5, help="lobes() timing repeats (>= 5)")
    ap.add_argument("--speeds", type=int, default=300, help="speeds of the full diagram")
    ap.add_argument(
        "--compare-speeds", type=int, default=None, help="speeds of the measured comparison (default 6)"
    )
    ap.add_argument("--tol", type=float, default=1e-6, help="relative b_lim tolerance of the root searches")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "bench_lobes.json"))
    args = ap.parse_args()
    rep = max(5, args.repeat)
    ncmp = args.compare_speeds or (3 if args.quick else 6)

    load0 = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(
        f"chatterlab {cl.__version__}, {os.cpu_count()} CPUs, load average {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}"
        + ("  (LOADED: timings inflated by other processes)" if load0[0] > LOADED else "")
    )
    fz = cl.assemble(cl.load_model(ROOT / "studies" / "traverse_shaper" / "model.toml")).at()
    width_max = 0.005
    cold = lambda: fz.__dict__.pop("complex_modes", None)  # noqa: E731

    def run(sp: np.ndarray, verify: int | None) -> Any:
        cold()
        kw = {} if verify is None else {"verify": verify}
        return lobes(fz, sp, width_max=width_max, terms="pdo", **kw)

    result: dict[str, Any] = {
        "benchmark": "bench_lobes",
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "chatterlab": cl.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "load_average_start": list(load0),
        "loaded_threshold": LOADED,
        "model": "studies/traverse_shaper/model.toml",
        "terms": "pdo",
        "width_max_m": width_max,
        "tol": args.tol,
        "repeats": rep,
    }

    # ------------------------------------------------------------------ 1. lobes() on 300 speeds
    speeds = np.linspace(0.1, 1.0, args.speeds)
    run(speeds[:2], 0)  # warm-up: imports
    res = timed({"verify=0": lambda: run(speeds, 0), "default verify": lambda: run(speeds, None)}, rep)
    (r0, d), (rv, dv) = res["verify=0"], res["default verify"]
    print(
        f"\n1. lobes(): {speeds.size} speeds {speeds[0]:g}-{speeds[-1]:g} m/s, width_max {width_max * 1e3:g} mm,"
        f" {d.n_frequencies} grid frequencies, {len(d.lobes)} lobes, cold, {rep} interleaved repeats"
    )
    print(f"   verify=0:          {fmt(r0)}")
    print(
        f"   default verify:    {fmt(rv)}  ({len(dv.checks)} argument-principle checks,"
        f" {sum(c['agrees'] for c in dv.checks)} agree)"
    )
    print(
        f"   min b_lim {d.minimum['width'] * 1e3:.4f} mm at {d.minimum['speed']:.4f} m/s,"
        f" {d.minimum['chatter_hz']:.2f} Hz"
    )
    result["lobes_300"] = {
        "n_speeds": int(speeds.size),
        "n_frequencies": int(d.n_frequencies),
        "n_lobes": len(d.lobes),
        "verify0": r0,
        "default_verify": {**rv, "checks": len(dv.checks), "agree": int(sum(c["agrees"] for c in dv.checks))},
        "min_b_lim_m": float(d.minimum["width"]),
    }

    # ------------------------------------------------------------------ 2. measured comparison
    sp = np.linspace(0.1, 1.0, ncmp)
    res = timed({"verify=0": lambda: run(sp, 0), "default verify": lambda: run(sp, None)}, rep)
    (c0, dc), (cv, dcv) = res["verify=0"], res["default verify"]
    print(
        f"\n2. the same computation on {ncmp} speeds {', '.join(f'{v:.2f}' for v in sp)} m/s, tolerance {args.tol:g}"
    )
    print(f"   lobes() verify=0:        {fmt(c0)}")
    print(f"   lobes() default verify:  {fmt(cv)}  ({len(dcv.checks)} checks)")
    a0 = float(fz.complex_modes.lam.real.max())  # abscissa of the structure alone (< 0)
    rows = []
    tot = {"bisection": [0.0, 0], "brent": [0.0, 0]}
    l0 = load()
    print(
        f"   {'v m/s':>6s} {'T s':>5s} {'lobes() b_lim mm':>16s}"
        f" {'bisection: roots':>16s} {'s':>6s} {'rel. diff':>9s} {'Brent: roots':>12s} {'s':>6s} {'rel. diff':>9s}"
    )
    for j, v in enumerate(sp):
        T, ref = float(dc.delay[j]), float(dc.b_lim[j])
        row: dict[str, Any] = {"speed": float(v), "delay_s": T, "lobes_b_lim_m": ref}
        line = f"   {v:6.3f} {T:5.2f} {ref * 1e3:16.7f}"
        for name, search in (
            ("bisection", lambda f: bisect(f, width_max, args.tol)),
            ("brent", lambda f: brent(f, width_max, args.tol, a0)),
        ):
            f = Counted(fz, T)
            t = time.perf_counter()
            b = search(f)
            dt = time.perf_counter() - t
            rel = (
                abs(b / ref - 1)
                if math.isfinite(b) and math.isfinite(ref)
                else (0.0 if b == ref else math.inf)
            )
            row[name] = {"b_lim_m": b, "root_computations": f.n, "wall_s": dt, "rel_diff_vs_lobes": rel}
            tot[name][0] += dt
            tot[name][1] += f.n
            line += (
                f" {f.n:16d} {dt:6.1f} {rel:9.1e}"
                if name == "bisection"
                else f" {f.n:12d} {dt:6.1f} {rel:9.1e}"
            )
        rows.append(row)
        print(line, flush=True)
    l1 = load()
    t_bis, t_br = tot["bisection"][0], tot["brent"][0]
    ratios = {
        "bisection_over_lobes_verify0": t_bis / c0["min_s"],
        "bisection_over_lobes_default": t_bis / cv["min_s"],
        "brent_over_lobes_verify0": t_br / c0["min_s"],
        "brent_over_lobes_default": t_br / cv["min_s"],
    }
    flag = " LOADED" if max(l0, l1) > LOADED else ""
    print(
        f"   total: bisection {t_bis:.1f} s ({tot['bisection'][1]} root computations),"
        f" Brent {t_br:.1f} s ({tot['brent'][1]}), measured once each (load {l0:.2f}->{l1:.2f}{flag})"
    )
    print(
        f"\n   measured on these {ncmp} speeds (lobes() min time):"
        f" bisection / lobes() = {ratios['bisection_over_lobes_verify0']:.0f}x (verify=0),"
        f" {ratios['bisection_over_lobes_default']:.0f}x (default verify);"
        f" Brent / lobes() = {ratios['brent_over_lobes_verify0']:.0f}x, {ratios['brent_over_lobes_default']:.0f}x"
    )
    worst = max(
        (r[k]["rel_diff_vs_lobes"] for r in rows for k in ("bisection", "brent")),
        default=0.0,
    )
    print(
        f"   equal accuracy: the root searches agree with lobes() to {worst:.1e} relative (tolerance {args.tol:g})"
    )
    result["comparison"] = {
        "n_speeds": ncmp,
        "speeds": sp.tolist(),
        "lobes_verify0": c0,
        "lobes_default_verify": {**cv, "checks": len(dcv.checks)},
        "per_speed": rows,
        "bisection_total_s": t_bis,
        "bisection_root_computations": tot["bisection"][1],
        "brent_total_s": t_br,
        "brent_root_computations": tot["brent"][1],
        "root_searches_load": [l0, l1],
        "root_searches_loaded": bool(max(l0, l1) > LOADED),
        "worst_rel_diff_vs_lobes": worst,
        "ratios": ratios,
    }
    result["load_average_end"] = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    result["loaded"] = bool(
        load0[0] > LOADED or r0["loaded"] or rv["loaded"] or c0["loaded"] or max(l0, l1) > LOADED
    )
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    print(
        f"\nload average at the end {result['load_average_end'][0]:.2f}"
        + (" -- LOADED machine" if result["loaded"] else "")
        + f"; wrote {args.out}"
    )


if __name__ == "__main__":
    main()
