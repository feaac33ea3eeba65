"""Benchmark of FRF routes on the traverse shaper, at equal accuracy.

Run from the repository root::

    python benchmarks/bench_frf.py            # about half a minute on 2 idle cores
    python benchmarks/bench_frf.py --quick    # 2000 frequencies

The 4 x 4 receptance at the tool/workpiece contact (rfe5.x, rfe5.y, tool.x,
tool.y) at 10 000 frequencies 1-300 Hz, open loop and closed loop (case c:
b = 2 mm, v = 0.5 m/s, T = 1.5 s), by

* chatterlab ``frf(method="direct")`` and ``frf(method="modal")`` (all
  complex modes of the balanced pencil, exact pole-residue sum; "cold"
  includes the eigen-decomposition, "warm" reuses the cached modes), and
  the modal route of chatterlab <= 0.1 (modes up to 4 x fmax + residual,
  still ``modes_above=4.0``);
* what a competent user would write instead: (a) a batched numpy solve
  (``np.linalg.solve`` over a stack of (s^2 A + s B + C - D(s))); (b) the
  eigen-decomposition of the first-order (state-space) matrix and a
  pole-residue sum, about ten lines (``state_space_pole_residue`` below;
  open loop only: a delay is not a finite state space); (c) python-control's
  own evaluation of the same 72-state ``control.ss`` at j w, taken through
  ``FRF.from_control`` (chatterlab's one route in from python-control).

Accuracy of every route against one reference: the per-frequency solve with
the matrices formed and the residual computed in extended precision
(``np.clongdouble``, 64-bit mantissa on x86) and two steps of iterative
refinement; the size of the second correction is printed, it bounds the
reference's own error.  Errors are "max over (o, i) of max_w |H - ref| /
max_w |ref|" (relative to each FRF's peak).

Each timing is repeated (``--repeat``, >= 5) and min and median wall times
are printed with the load average (``os.getloadavg``) before and after;
runs with a 1-minute load above 0.5 are flagged LOADED (the machine has 2
cores).  Everything goes to ``benchmarks/results/bench_frf.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
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

from _common import load1 as load
from _common import loadavg

from chatterlab.frequency._frf import frequencies, frf
from chatterlab.frequency._stability import stability
from chatterlab.process import ClosedLoop, closed_loop

ROOT = Path(__file__).resolve().parents[1]
POINTS = ["rfe5.x", "rfe5.y", "tool.x", "tool.y"]
LOADED = 0.5  # 1-minute load average above which a timing is flagged


def timed(
    routes: dict[str, tuple[Callable[[], Any], Callable[[], None] | None]], repeat: int
) -> dict[str, tuple[dict[str, Any], Any]]:
    """Wall times of ``repeat`` rounds; each round runs every route once, in
    turn (interleaved, so that a burst of outside load hits all routes
    alike); ``setup`` runs before each call, untimed.  Per route: min,
    median, all times, the load average before and after, and the last
    output."""
    times: dict[str, list[float]] = {k: [] for k in routes}
    out: dict[str, Any] = {}
    l0 = load()
    for _ in range(repeat):
        for label, (fn, setup) in routes.items():
            if setup is not None:
                setup()
            t = time.perf_counter()
            out[label] = fn()
            times[label].append(time.perf_counter() - t)
    l1 = load()
    return {
        k: (
            {
                "min_s": min(v),
                "median_s": float(np.median(v)),
                "times_s": v,
                "load_before": l0,
                "load_after": l1,
                "loaded": bool(max(l0, l1) > LOADED),
            },
            out[k],
        )
        for k, v in times.items()
    }


def peak_error(a: np.ndarray, ref: np.ndarray) -> float:
    """max over (o, i) of max_w |a - ref| / max_w |ref|."""
    return float((np.abs(a - ref).max(axis=-1) / np.abs(ref).max(axis=-1)).max())


# --------------------------------------------------------------------------- reference


def reference(
    fz: cl.FrozenSystem, rows: np.ndarray, s: np.ndarray, fb: ClosedLoop | None, chunk: int = 250
) -> tuple[np.ndarray, float]:
    """rows Z(s)^-1 rows^T with Z formed, and the residual computed, in
    extended precision; two steps of iterative refinement on the float64 LU.
    Returns (H, size of the last correction relative to the peak)."""
    ld = np.clongdouble
    A, B, C = (np.asarray(m, dtype=np.longdouble) for m in (fz.A, fz.B, fz.C))
    rhs = rows.T.astype(ld)
    out = np.empty((rows.shape[0], rows.shape[0], s.size), dtype=complex)
    last = np.zeros_like(out)
    for k0 in range(0, s.size, chunk):
        sk = s[k0 : k0 + chunk].astype(ld)[:, None, None]
        Z = sk * sk * A + sk * B + C
        if fb is not None:
            Z = Z - fb(s[k0 : k0 + chunk]).astype(ld)  # D(s) as the route sees it (float64)
        Z64 = Z.astype(complex)
        x = np.linalg.solve(
            Z64, np.broadcast_to(rows.T.astype(complex), (sk.shape[0],) + rows.T.shape)
        ).astype(ld)
        for _ in range(2):
            r = rhs - Z @ x
            dx = np.linalg.solve(Z64, r.astype(complex))
            x = x + dx.astype(ld)
        H = rows.astype(ld) @ x
        out[:, :, k0 : k0 + chunk] = np.transpose(H.astype(complex), (1, 2, 0))
        last[:, :, k0 : k0 + chunk] = np.transpose(rows @ dx, (1, 2, 0))
    return out, peak_error(out + last, out)


# --------------------------------------------------------------------------- competitors


def numpy_batched(fz: cl.FrozenSystem, rows: np.ndarray, s: np.ndarray, fb: ClosedLoop | None) -> np.ndarray:
    """(a) A batched numpy solve, chunked to ~20 MB stacks."""
    out = np.empty((rows.shape[0], rows.shape[0], s.size), dtype=complex)
    chunk = 1000
    for k0 in range(0, s.size, chunk):
        sk = s[k0 : k0 + chunk, None, None]
        Z = sk**2 * fz.A + sk * fz.B + fz.C
        if fb is not None:
            Z = Z - fb(s[k0 : k0 + chunk])
        X = np.linalg.solve(Z, np.broadcast_to(rows.T.astype(complex), (sk.shape[0],) + rows.T.shape))
        out[:, :, k0 : k0 + chunk] = np.transpose(rows @ X, (1, 2, 0))
    return out


def state_space(fz: cl.FrozenSystem, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x = [q, q']: x' = a x + b f, y = c x."""
    n = fz.n
    Ainv = np.linalg.inv(fz.A)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-Ainv @ fz.C, -Ainv @ fz.B]])
    b = np.vstack([np.zeros((n, rows.shape[0])), Ainv @ rows.T])
    c = np.hstack([rows, np.zeros((rows.shape[0], n))])
    return a, b, c


def state_space_pole_residue(fz: cl.FrozenSystem, rows: np.ndarray, s: np.ndarray) -> np.ndarray:
    """(b) The ten-line route: eigen-decomposition of the state matrix and
    H(s) = sum_r (c v_r)(w_r b) / (s - lam_r)."""
    a, b, c = state_space(fz, rows)
    lam, V = np.linalg.eig(a)
    W = np.linalg.solve(V, b)  # rows of V^-1 b
    cV = c @ V
    R = (cV[:, None, :] * W.T[None, :, :]).reshape(-1, lam.size)
    return (R @ (1.0 / (s[None, :] - lam[:, None]))).reshape(rows.shape[0], rows.shape[0], s.size)


# --------------------------------------------------------------------------- main


def row(label: str, rec: dict[str, Any], err: float | None, base: float | None) -> str:
    ratio = f"{base / rec['min_s']:8.2f}x" if base else " " * 9
    e = f"{err:10.1e}" if err is not None else " " * 10
    flag = " LOADED" if rec["loaded"] else ""
    return (
        f"   {label:44s} {rec['min_s']:8.4f} {rec['median_s']:8.4f} {ratio} {e}"
        f"   load {rec['load_before']:.2f}->{rec['load_after']:.2f}{flag}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="2000 frequencies")
    ap.add_argument(
        "--repeat", type=int, default=15, help="timing repeats (>= 5), interleaved over the routes"
    )
    ap.add_argument("--points", type=int, default=None, help="number of frequencies (default 10 000)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "bench_frf.json"))
    args = ap.parse_args()
    rep = max(5, args.repeat)
    npts = args.points or (2000 if args.quick else 10_000)

    try:
        from threadpoolctl import threadpool_info

        blas = [{k: d.get(k) for k in ("internal_api", "num_threads", "version")} for d in threadpool_info()]
    except ImportError:
        blas = []
    load0 = loadavg()
    print(
        f"chatterlab {cl.__version__}, numpy {np.__version__}, {os.cpu_count()} CPUs,"
        f" BLAS {blas}, load average {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}"
        + ("  (LOADED: timings inflated by other processes)" if load0[0] > LOADED else "")
    )
    fz = cl.assemble(cl.load_model(ROOT / "studies" / "traverse_shaper" / "model.toml")).at()
    om = frequencies(1.0, 300.0, npts)
    s = 1j * om
    rows = np.array([fz.dof(p) for p in POINTS])
    fb = closed_loop(fz, width=0.002, speed=0.5, terms="pdo")
    print(
        f"traverse shaper: {fz.n} coordinates ({2 * fz.n} states), {len(POINTS)} x {len(POINTS)} receptance,"
        f" {om.size} frequencies 1-300 Hz; closed loop (c): b = 2 mm, v = 0.5 m/s, T = {fb.delay:.3g} s;"
        f" {rep} repeats"
    )
    drop = lambda: fz.__dict__.pop("complex_modes", None)  # noqa: E731  cold: recompute the modes
    result: dict[str, Any] = {
        "benchmark": "bench_frf",
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "chatterlab": cl.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "blas": blas,
        "load_average_start": list(load0),
        "loaded_threshold": LOADED,
        "model": "studies/traverse_shaper/model.toml",
        "points": POINTS,
        "n_frequencies": int(om.size),
        "band_hz": [1.0, 300.0],
        "repeats": rep,
        "error_measure": "max over (o,i) of max_w |H - ref| / max_w |ref|",
        "cases": {},
    }

    for case, f_b in (("open loop", None), ("closed loop (c)", fb)):
        t = time.perf_counter()
        ref, ref_err = reference(fz, rows, s, f_b)
        print(
            f"\n{case}: reference (extended-precision residual, 2 refinement steps) in {time.perf_counter() - t:.1f} s,"
            f" last correction {ref_err:.1e} of the peak"
        )
        print(f"   {'route':44s} {'min s':>8s} {'median s':>8s} {'speed-up':>9s} {'error':>10s}")
        routes: dict[str, tuple[Callable[[], np.ndarray], Callable[[], None] | None]] = {
            "chatterlab direct": (
                lambda f_b=f_b: frf(f_b, om, inputs=POINTS, outputs=POINTS).data,
                None,
            ),
            "(a) numpy batched solve": (lambda f_b=f_b: numpy_batched(fz, rows, s, f_b), None),
            "chatterlab modal, cold (eig included)": (
                lambda f_b=f_b: frf(f_b, om, inputs=POINTS, outputs=POINTS, method="modal").data,
                drop,
            ),
            "chatterlab modal, warm (cached modes)": (
                lambda f_b=f_b: frf(f_b, om, inputs=POINTS, outputs=POINTS, method="modal").data,
                None,
            ),
            "chatterlab <= 0.1 modal (4 x fmax + residual)": (
                lambda f_b=f_b: (
                    frf(f_b, om, inputs=POINTS, outputs=POINTS, method="modal", modes_above=4.0).data
                ),
                None,
            ),
        }
        if f_b is None:
            routes["(b) state-space eig + pole-residue"] = (
                lambda: state_space_pole_residue(fz, rows, s),
                None,
            )
            try:
                import control
            except ImportError:
                print("   python-control not installed: (c) skipped")
            else:
                from chatterlab.structure import FRF

                sys_c = control.ss(*state_space(fz, rows), np.zeros((len(POINTS), len(POINTS))))
                # python-control evaluates its own state space at j w; FRF.from_control is the one route in
                routes[f"(c) python-control {control.__version__} freq. response"] = (
                    lambda sys_c=sys_c: FRF.from_control(sys_c, om).data,
                    None,
                )
        for fn, setup in routes.values():
            if setup is None:
                fn()  # warm-up (imports, caches) outside the timing
        recs: dict[str, Any] = {}
        base = None
        for label, (rec, out) in timed(routes, rep).items():
            rec["error_vs_reference"] = peak_error(np.asarray(out), ref)
            if base is None:
                base = rec["min_s"]
            rec["speedup_vs_direct_min"] = base / rec["min_s"]
            recs[label] = rec
            print(row(label, rec, rec["error_vs_reference"], base))
        result["cases"][case] = {"reference_last_correction": ref_err, "routes": recs}

    # the comparisons the issue asked about, as measured ratios
    ol = result["cases"]["open loop"]["routes"]
    new, old, ssr = (
        ol["chatterlab modal, cold (eig included)"],
        ol["chatterlab <= 0.1 modal (4 x fmax + residual)"],
        ol["(b) state-space eig + pole-residue"],
    )
    warm = ol["chatterlab modal, warm (cached modes)"]
    ratios = {
        "ss_pole_residue_over_modal_cold_time": ssr["min_s"] / new["min_s"],
        "ss_pole_residue_over_modal_warm_time": ssr["min_s"] / warm["min_s"],
        "old_modal_over_modal_warm_time": old["min_s"] / warm["min_s"],
        "ss_pole_residue_error_over_modal_error": ssr["error_vs_reference"] / new["error_vs_reference"],
        "old_modal_error_over_modal_error": old["error_vs_reference"] / new["error_vs_reference"],
    }
    result["ratios_open_loop"] = ratios
    print(
        "\n   open loop, measured (min times): (b) state-space pole-residue takes"
        f" {ratios['ss_pole_residue_over_modal_cold_time']:.2f}x the time of chatterlab modal cold"
        f" ({ratios['ss_pole_residue_over_modal_warm_time']:.2f}x warm), error {ssr['error_vs_reference']:.1e}"
        f" vs {new['error_vs_reference']:.1e} ({ratios['ss_pole_residue_error_over_modal_error']:.0f}x);"
        f" the 0.1 modal route: {ratios['old_modal_over_modal_warm_time']:.2f}x the time of modal warm,"
        f" error {old['error_vs_reference']:.1e} ({ratios['old_modal_error_over_modal_error']:.0f}x)"
    )

    # ------------------------------------------------------------------ roots
    print("\none converged rightmost-root computation, case (c) (T = 1.5 s)")
    rec, st = timed(
        {"roots": (lambda: stability(fz, width=0.002, speed=0.5, terms="pdo", winding=False), None)}, 5
    )["roots"]
    r = st.roots
    rec.update(verdict=st.verdict, abscissa=float(r.roots[0].real), chatter_hz=float(r.frequency_hz[0]))
    result["rightmost_root_case_c"] = rec
    print(
        f"   stability(winding=False): min {rec['min_s']:.3f} s, median {rec['median_s']:.3f} s,"
        f" verdict {st.verdict}, rightmost root {r.roots[0].real:+.4f} 1/s at {r.frequency_hz[0]:.3f} Hz"
        f"   load {rec['load_before']:.2f}->{rec['load_after']:.2f}" + (" LOADED" if rec["loaded"] else "")
    )
    result["load_average_end"] = list(loadavg())
    result["loaded"] = bool(
        load0[0] > LOADED
        or any(r_["loaded"] for c in result["cases"].values() for r_ in c["routes"].values())
        or rec["loaded"]
    )
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    print(
        f"\nload average at the end {result['load_average_end'][0]:.2f}"
        + (" -- LOADED machine: ratios are more trustworthy than absolute times" if result["loaded"] else "")
        + f"; wrote {args.out}"
    )


if __name__ == "__main__":
    main()
