"""Benchmark of FRFs and characteristic roots on the traverse shaper.

Run from the repository root::

    python benchmarks/bench_frf.py            # about half a minute on 2 cores
    python benchmarks/bench_frf.py --quick    # fewer repeats

It prints, all measured in the same run (best of ``--repeat`` wall times, with
the CPU time of that run and the load average, so outside load is visible):

1. the 4 x 4 FRF at the tool/workpiece contact (rfe5.x, rfe5.y, tool.x,
   tool.y) at 10 000 frequencies 1-300 Hz, ``method="modal"`` (complex
   modes up to 4 x 300 Hz + residual; cold = eigen-decomposition included,
   warm = cached modes) against ``method="direct"``, open loop and closed
   loop (case c: b = 2 mm, v = 0.5 m/s, T = 1.5 s): time ratio and maximum
   difference (relative to each FRF's peak, and pointwise relative to the
   largest entry at the same frequency);
2. python-control's ``frequency_response`` of the equivalent 72-state
   ``control.ss`` model (open loop, same frequencies) as a reference timing;
3. the time of one converged rightmost-root computation at b = 2 mm,
   v = 0.5 m/s: ``stability(..., winding=False)`` and
   ``roots.characteristic_roots`` on the same matrices.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

try:
    import chatterlab as cl
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import chatterlab as cl

from chatterlab.frequency._frf import frequencies, frf
from chatterlab.frequency._roots import characteristic_roots
from chatterlab.frequency._stability import stability
from chatterlab.process._cutting import feedback

ROOT = Path(__file__).resolve().parents[1]
POINTS = ["rfe5.x", "rfe5.y", "tool.x", "tool.y"]


def timed(fn: Callable[[], Any], repeat: int, setup: Callable[[], None] | None = None) -> tuple[float, float, Any]:
    """Best wall time over ``repeat`` runs, the CPU time of that run, and
    the last result."""
    best, cpu, out = np.inf, np.nan, None
    for _ in range(repeat):
        if setup is not None:
            setup()
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        dt, dc = time.perf_counter() - t, time.process_time() - c
        if dt < best:
            best, cpu = dt, dc
    return best, cpu, out


def errors(a: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    """(max over pairs of max|a - ref| / max|ref|, max over w of
    max|a - ref| / max|ref| at that w)."""
    d = np.abs(a - ref)
    per_pair = float((d.max(axis=-1) / np.abs(ref).max(axis=-1)).max())
    per_freq = float((d.max(axis=(0, 1)) / np.abs(ref).max(axis=(0, 1))).max())
    return per_pair, per_freq


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    ap.add_argument("--repeat", type=int, default=None, help="timing repeats (best of)")
    ap.add_argument("--points", type=int, default=10_000, help="number of frequencies")
    args = ap.parse_args()
    rep = args.repeat or (2 if args.quick else 5)
    rep_roots = 1 if args.quick else 3

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"chatterlab {cl.__version__}, numpy {np.__version__}, {os.cpu_count()} CPUs, load average {load:.2f}")
    fz = cl.assemble(cl.load_model(ROOT / "studies" / "traverse_shaper" / "model.toml")).at()
    om = frequencies(1.0, 300.0, args.points)
    fb = feedback(fz, width=0.002, speed=0.5, terms="pdo")
    print(f"traverse shaper: {fz.n} independent coordinates, {len(POINTS)} x {len(POINTS)} FRF,"
          f" {om.size} frequencies 1-300 Hz; closed loop: b = 2 mm, v = 0.5 m/s, T = {fb.delay:.3g} s")

    # ------------------------------------------------------------------ FRF
    print("\n1. FRF, modal (modes up to 4 x fmax + residual) vs direct")
    print(f"   {'':12s} {'direct s':>9s} {'modal cold s':>13s} {'modal warm s':>13s}"
          f" {'direct/cold':>11s} {'direct/warm':>11s} {'max diff/peak':>13s} {'max diff/|H(w)|':>15s}")
    rows = {}
    for label, f_b in (("open loop", None), ("closed (c)", fb)):
        t_d, c_d, direct = timed(lambda f_b=f_b: frf(fz, om, inputs=POINTS, outputs=POINTS, feedback=f_b), rep)
        t_c, _, _ = timed(
            lambda f_b=f_b: frf(fz, om, inputs=POINTS, outputs=POINTS, feedback=f_b, method="modal"),
            rep,
            setup=lambda: fz.__dict__.pop("complex_modes", None),  # cold: drop the cached modes
        )
        t_w, _, modal = timed(
            lambda f_b=f_b: frf(fz, om, inputs=POINTS, outputs=POINTS, feedback=f_b, method="modal"), rep
        )
        e_pair, e_freq = errors(modal.data, direct.data)
        rows[label] = (t_d, t_w)
        print(f"   {label:12s} {t_d:9.4f} {t_c:13.4f} {t_w:13.4f} {t_d / t_c:10.1f}x {t_d / t_w:10.1f}x"
              f" {e_pair:13.2e} {e_freq:15.2e}")
        print(f"   {'':12s} (direct: CPU {c_d:.3f} s for {t_d:.3f} s wall)")

    # ------------------------------------------------------------------ python-control
    print("\n2. python-control frequency_response of the equivalent state space (open loop)")
    try:
        import control
    except ImportError:
        print("   python-control not installed: skipped")
    else:
        n = fz.n
        Bi = np.array([fz.dof(p) for p in POINTS])
        Ainv = np.linalg.inv(fz.A)
        ss = control.ss(
            np.block([[np.zeros((n, n)), np.eye(n)], [-Ainv @ fz.C, -Ainv @ fz.B]]),
            np.vstack([np.zeros((n, len(POINTS))), Ainv @ Bi.T]),
            np.hstack([Bi, np.zeros((len(POINTS), n))]),
            np.zeros((len(POINTS), len(POINTS))),
        )
        t_pc, _, resp = timed(lambda: ss.frequency_response(om), max(1, rep // 2))
        direct = frf(fz, om, inputs=POINTS, outputs=POINTS)
        e_pair, _ = errors(resp.complex, direct.data)
        t_d, t_w = rows["open loop"]
        print(f"   control {control.__version__}, {2 * n} states: {t_pc:.4f} s"
              f"  = {t_pc / t_d:.1f}x chatterlab direct, {t_pc / t_w:.1f}x chatterlab modal (warm);"
              f" max diff/peak vs direct {e_pair:.1e}")

    # ------------------------------------------------------------------ roots
    print("\n3. one converged rightmost-root computation, b = 2 mm, v = 0.5 m/s (T = 1.5 s), case c")
    t_s, c_s, st = timed(lambda: stability(fz, width=0.002, speed=0.5, terms="pdo", winding=False), rep_roots)
    r = st.roots
    print(f"   stability(winding=False): {t_s:.3f} s (CPU {c_s:.3f} s)  verdict {st.verdict},"
          f" rightmost root {r.roots[0].real:+.4f} 1/s at {r.frequency_hz[0]:.3f} Hz"
          f" ({r.method}, {r.n_windows} windows, N = {r.n_nodes[0]}/{r.n_nodes[1]}, {r.status})")
    t_r, c_r, rr = timed(
        lambda: characteristic_roots(
            fz.A, fz.B, fz.C, DP=fb.DP, DV=fb.DV, DO=(fb.U, fb.V), tau=fb.delay, count=6
        ),
        rep_roots,
    )
    print(f"   characteristic_roots:     {t_r:.3f} s (CPU {c_r:.3f} s)  abscissa {rr.abscissa:+.4f} 1/s,"
          f" {rr.status}; same roots as stability(): {np.allclose(rr.roots, r.roots, rtol=1e-10)}")
    t_d, t_w = rows["closed (c)"]
    print(f"   = {t_r / t_w:.0f}x a warm modal 10 000-point closed-loop FRF, {t_r / t_d:.1f}x a direct one")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\nload average at the end {load:.2f}")


if __name__ == "__main__":
    main()
