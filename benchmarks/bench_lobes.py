"""Benchmark of the stability lobe diagram of the traverse shaper.

Run from the repository root::

    python benchmarks/bench_lobes.py           # about a minute on 2 cores
    python benchmarks/bench_lobes.py --quick   # no real bisection, fewer samples

It compares, in the same run:

1. ``lobes()`` (D-subdivision in the CE coordinates): 300 work speeds
   0.1-1 m/s, width_max 5 mm, paper's CE with all terms (case c); best of
   ``--repeat`` wall times, without and with the default root spot checks
   (target: < 1 s);
2. the brute force at equal resolution: for each of the 300 speeds, bisection
   on the width with a characteristic-root verdict
   (the sign of ``stability(..., winding=False).abscissa``) at every step,
   from [0, width_max]
   until the bracket is below ``--tol`` x b_lim (1e-6 by default: far looser
   than lobes()' round-off refinement, i.e. in the brute force's favour).
   That is 300 x (1 + ceil(log2(width_max / (tol b_lim)))) root computations.
   Their cost is **extrapolated** from a sample of root computations at
   widths and speeds spread over the diagram (the cost depends on the delay:
   T = 0.9 s at 1 m/s ... 6.3 s at 0.1 m/s); with ``--bisect`` (default
   1.0 m/s) one full bisection is also run for real, to check the count and
   that it converges to lobes()' b_lim.

Prints the ratio brute force / lobes() (target >= 100x).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

try:
    import chatterlab as cl
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import chatterlab as cl

from chatterlab.frequency._stability import stability
from chatterlab.lobes._diagram import lobes

ROOT = Path(__file__).resolve().parents[1]


def verdict_time(fz: cl.FrozenSystem, width: float, delay: float) -> tuple[float, str]:
    t = time.perf_counter()
    s = stability(fz, width=width, delay=delay, terms="pdo", winding=False)
    return time.perf_counter() - t, s.verdict


def bisect(fz: cl.FrozenSystem, delay: float, width_max: float, tol: float, b_guess: float) -> tuple[float, int, float]:
    """Brute-force b_lim at one delay: (b_lim, root computations, seconds).

    Decides on the sign of the rightmost real part, not on the verdict:
    stability() calls |Re lambda| <= MARGINAL_TOL |lambda| "marginal", a
    band of about +-5e-5 relative in width around the shaper's b_lim (the
    critical root is lightly damped: dRe/d(ln b) ~ 1 1/s), too wide for a
    1e-6 bisection."""
    t0 = time.perf_counter()
    n = 1
    if stability(fz, width=width_max, delay=delay, winding=False).abscissa < 0:
        return math.inf, n, time.perf_counter() - t0
    lo, hi = 0.0, width_max
    while hi - lo > tol * b_guess:
        mid = 0.5 * (lo + hi)
        n += 1
        if stability(fz, width=mid, delay=delay, winding=False).abscissa < 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi), n, time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer samples, no real bisection")
    ap.add_argument("--repeat", type=int, default=None, help="lobes() timing repeats (best of)")
    ap.add_argument("--speeds", type=int, default=300)
    ap.add_argument("--tol", type=float, default=1e-6, help="relative b_lim tolerance of the brute force")
    ap.add_argument("--bisect", type=float, nargs="*", default=None,
                    help="speeds (m/s) at which to run a real bisection (default 1.0; none with --quick)")
    args = ap.parse_args()
    rep = args.repeat or (2 if args.quick else 5)
    bisect_speeds = args.bisect if args.bisect is not None else ([] if args.quick else [1.0])

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"chatterlab {cl.__version__}, {os.cpu_count()} CPUs, load average {load:.2f}")
    fz = cl.assemble(cl.load_model(ROOT / "studies" / "traverse_shaper" / "model.toml")).at()
    speeds = np.linspace(0.1, 1.0, args.speeds)
    width_max = 0.005

    # ------------------------------------------------------------------ lobes()
    best, best_cpu, d = np.inf, np.nan, None
    for _ in range(rep):
        fz.__dict__.pop("complex_modes", None)  # cold: complex modes recomputed every time
        t, c = time.perf_counter(), time.process_time()
        d = lobes(fz, speeds, width_max=width_max, terms="pdo", verify=0)
        dt, dc = time.perf_counter() - t, time.process_time() - c
        if dt < best:
            best, best_cpu = dt, dc
    assert d is not None
    t = time.perf_counter()
    dv = lobes(fz, speeds, width_max=width_max, terms="pdo")
    t_verify = time.perf_counter() - t
    print(f"\n1. lobes(): {speeds.size} speeds {speeds[0]:g}-{speeds[-1]:g} m/s, width_max {width_max * 1e3:g} mm,"
          f" {d.n_frequencies} grid frequencies, {len(d.lobes)} lobes")
    print(f"   {best:.3f} s (best of {rep}; CPU {best_cpu:.3f} s)  [target < 1 s: {'met' if best < 1 else 'NOT met'}]")
    print(f"   with the default root spot checks (verify=2, {len(dv.checks)} root computations): {t_verify:.2f} s,"
          f" {sum(c['agrees'] for c in dv.checks)}/{len(dv.checks)} agree")
    print(f"   min b_lim {d.minimum['width'] * 1e3:.4f} mm at {d.minimum['speed']:.4f} m/s,"
          f" {d.minimum['chatter_hz']:.2f} Hz; b_lim range {d.b_lim.min() * 1e3:.4f}-{d.b_lim.max() * 1e3:.4f} mm")

    # ------------------------------------------------------------------ brute force
    steps = 1 + np.ceil(np.log2(width_max / (args.tol * d.b_lim)))
    n_roots = int(steps.sum())
    print(f"\n2. brute force: bisection on the sign of the rightmost root to {args.tol:g} x b_lim from [0, {width_max * 1e3:g} mm]:"
          f" {int(steps.min())}-{int(steps.max())} root computations per speed, {n_roots} in all")
    picks = np.linspace(0, speeds.size - 1, 4 if args.quick else 7).astype(int)
    factors = [0.6, 1.4, 0.95, 1.05, 0.3, 2.0, 1.2]
    samples = []
    for i, j in enumerate(picks):
        b = factors[i % len(factors)] * d.b_lim[j]
        dt, v = verdict_time(fz, b, d.delay[j])
        samples.append((speeds[j], d.delay[j], b, dt, v))
        print(f"   sample: v = {speeds[j]:.3f} m/s (T = {d.delay[j]:.2f} s), b = {b * 1e3:.4f} mm -> {v:8s} {dt:6.2f} s")
    sv = np.array([s[0] for s in samples])
    st = np.array([s[3] for s in samples])
    # the cost grows with the delay: interpolate the per-verdict time over the
    # speeds (piecewise linear in T) rather than taking one mean
    T_s = np.array([s[1] for s in samples])
    order = np.argsort(T_s)
    per_speed = np.interp(d.delay, T_s[order], st[order])
    t_brute = float((per_speed * steps).sum())
    print(f"   mean {st.mean():.2f} s per root computation (range {st.min():.2f}-{st.max():.2f} s over speeds"
          f" {sv.min():.2f}-{sv.max():.2f} m/s)")
    print(f"   EXTRAPOLATED brute force: {t_brute:.0f} s = {t_brute / 3600:.2f} h"
          f" ({n_roots} root computations, per-verdict time interpolated in T)")

    for v in bisect_speeds:
        j = int(np.argmin(np.abs(speeds - v)))
        b, n, dt = bisect(fz, float(d.delay[j]), width_max, args.tol, float(d.b_lim[j]))
        print(f"   real bisection at v = {speeds[j]:.3f} m/s: {n} root computations, {dt:.1f} s"
              f" ({dt / n:.2f} s each; extrapolation used {per_speed[j]:.2f} s);"
              f" b_lim {b * 1e3:.6f} mm vs lobes() {d.b_lim[j] * 1e3:.6f} mm"
              f" (relative difference {abs(b / d.b_lim[j] - 1):.1e}, tolerance {args.tol:g})")

    ratio = t_brute / best
    print(f"\n3. brute force (extrapolated) / lobes(): {ratio:,.0f}x  [target >= 100x: {'met' if ratio >= 100 else 'NOT met'}];"
          f" lobes() {best:.3f} s  [target < 1 s: {'met' if best < 1 else 'NOT met'}]")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average at the end {load:.2f}")


if __name__ == "__main__":
    main()
