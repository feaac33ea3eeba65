"""The lobe engine against the FRF it is built on (issue 26, rows 3 and 4), measured.

Run from the repository root::

    python benchmarks/bench_lobes.py                  # label "current", 7 interleaved repeats
    python benchmarks/bench_lobes.py --label before   # e.g. with PYTHONPATH at an older checkout

What is timed, in one run, interleaved (route a, b, c, a, b, c, ...), every
route with one BLAS thread (threadpoolctl) and cold (the structure's complex
modes are dropped before each ``lobes()`` call, so the engine pays for its
own eigendecomposition, as the competitor does):

a. ``chatterlab.lobes.lobes(frozen, speeds, width_max=1e-3, verify=0)`` on the
   traverse shaper (``studies/traverse_shaper/model.toml`` at s = 0.85 m), 300
   work speeds 0.1 .. 1 m/s, as in the README;
b. the same with ``verify=16`` (the argument-principle checks);
c. the competitor, what a competent numpy user writes to get the structure's
   FRF between the coupling coordinates, H(jw) = J (K - w^2 M + jw C)^-1 J^T,
   at the very frequency grid the engine searches (its size is recorded): one
   eigendecomposition of the 2n x 2n first-order matrix and a vectorised
   pole-residue sum (one matrix product over the poles).  Its H agrees with the
   engine's (from the complex modes) to the recorded relative difference.

Row 3 of issue 26 is a / c (goal <= 10), row 4 is (b - a) / a (goal <= 1),
both from the min and from the median of the wall-clock times of the repeats
of this run; the process's CPU time is recorded beside them (on a machine
shared with other work the wall clock also counts the waiting for a core).  The load
(``/proc/loadavg``) is read before and after the timed loop, the peak RSS
(``resource.getrusage``) at the end.  The run is stored in
``benchmarks/results/lobes.json`` under ``runs[<label>]`` (other labels are
kept), with the diagram's results (b_lim, chatter frequency, lobe numbers at
every speed, minima, folds, checks), so that two runs (``before`` on an older
checkout, ``after``) can be compared number for number; the Markdown table
``benchmarks/results/lobes.md`` is generated from that JSON (``--table-only``
regenerates it without timing).
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

from _common import loadavg_text as loadavg
from _common import peak_rss_mb, source_commit, stats, timed

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "traverse_shaper" / "model.toml"
OUT = ROOT / "benchmarks" / "results" / "lobes.json"
GOAL_LOBES = 10.0  #: issue 26 row 3: lobes(verify=0) / FRF, at most
GOAL_VERIFY = 1.0  #: issue 26 row 4: extra time of verify=16 / lobes(verify=0), at most


def competitor(M: np.ndarray, C: np.ndarray, K: np.ndarray, J: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """H(jw) = J (K - w^2 M + jw C)^-1 J^T, shape (N, m, m), by one
    eigendecomposition of the first-order matrix and a pole-residue sum.

    x = (q, qdot): xdot = A x + B f with A = [[0, I], [-M^-1 K, -M^-1 C]],
    B = [0; M^-1 J^T]; A = S diag(lam) S^-1 gives
    H(s) = (J S_q) diag(1/(s - lam)) (S^-1 B), one GEMM over the 2n poles."""
    n = M.shape[0]
    m = J.shape[0]
    Minv_K = np.linalg.solve(M, K)
    Minv_C = np.linalg.solve(M, C)
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -Minv_K
    A[n:, n:] = -Minv_C
    lam, S = np.linalg.eig(A)
    B = np.zeros((2 * n, m))
    B[n:] = np.linalg.solve(M, J.T)
    L = J @ S[:n]  # (m, 2n)
    R = np.linalg.solve(S, B)  # (2n, m)
    LR = (L.T[:, :, None] * R[:, None, :]).reshape(2 * n, m * m)  # residue of each pole
    g = 1.0 / (1j * omega[:, None] - lam[None, :])  # (N, 2n)
    return (g @ LR).reshape(omega.size, m, m)


def summary(d: Any) -> dict[str, Any]:
    """The diagram's results that must not change between versions."""
    return {
        "b_lim_m": [float(x) for x in d.b_lim],
        "chatter_hz": [float(x) for x in d.chatter_hz],
        "lobe": [int(x) for x in d.lobe],
        "minimum": {k: float(v) for k, v in d.minimum.items()},
        "absolute_minimum": {k: float(v) for k, v in d.absolute_minimum.items()},
        "folds": int(d.folds),
        "n_frequencies": int(d.n_frequencies),
        "n_lobes_listed": len(d.lobes),
        "band_hz": [float(x) for x in d.band_hz],
        "checks": [
            {k: c[k] for k in ("speed", "width", "kind", "verdict", "rhp_roots", "proven", "agrees")}
            for c in d.checks
        ],
    }


def measure(label: str, repeat: int, n_speeds: int, width_max: float, verify: int) -> dict[str, Any]:
    from threadpoolctl import threadpool_info, threadpool_limits

    from chatterlab.lobes import Boundary, lobes
    from chatterlab.process._loop import closed_loop_unwarned

    fz = cl.assemble(cl.load_model(MODEL)).at(0.85)
    speeds = np.linspace(0.1, 1.0, n_speeds)
    J = closed_loop_unwarned(fz, width=1.0, delay=1.0, terms="pdo").J
    M, C, K = fz.A, fz.B, fz.C
    with threadpool_limits(limits=1, user_api="blas"):
        import scipy.linalg  # noqa: F401  (its OpenBLAS loaded before the limit is read back)

        blas = [{k: x.get(k) for k in ("internal_api", "num_threads", "version")} for x in threadpool_info()]
        omega = Boundary(fz, width_max=width_max).ops.omega  # the engine's grid (6169 for 0.2.0)

        def cold() -> None:
            fz.__dict__.pop("complex_modes", None)

        def run_a() -> Any:
            cold()
            return lobes(fz, speeds, width_max=width_max, verify=0)

        def run_b() -> Any:
            cold()
            return lobes(fz, speeds, width_max=width_max, verify=verify)

        def run_c() -> Any:
            return competitor(M, C, K, J, omega)

        routes: dict[str, Callable[[], Any]] = {"lobes_verify0": run_a, "lobes_verify": run_b, "frf": run_c}
        out = {k: f() for k, f in routes.items()}  # warm-up: imports, caches of numpy/scipy
        times: dict[str, list[float]] = {k: [] for k in routes}
        cpu: dict[str, list[float]] = {k: [] for k in routes}
        load_before = loadavg()
        for _ in range(repeat):
            for k, f in routes.items():
                out[k], t, c = timed(f)
                times[k].append(t)
                cpu[k].append(c)
        load_after = loadavg()
    rss_mb = peak_rss_mb()
    Href = Boundary(fz, width_max=width_max).plant.H(omega)
    Hc = out["frf"]
    rel = float(np.max(np.abs(Hc - Href)) / np.max(np.abs(Href)))
    a, b, c = (stats(times[k], cpu[k]) for k in ("lobes_verify0", "lobes_verify", "frf"))
    ratios = {
        "lobes_over_frf_min": a["min_s"] / c["min_s"],
        "lobes_over_frf_median": a["median_s"] / c["median_s"],
        "verify_extra_over_lobes_min": (b["min_s"] - a["min_s"]) / a["min_s"],
        "verify_extra_over_lobes_median": (b["median_s"] - a["median_s"]) / a["median_s"],
        # the same from the process's CPU time (less inflated by other processes' load)
        "cpu_lobes_over_frf_min": a["cpu_min_s"] / c["cpu_min_s"],
        "cpu_verify_extra_over_lobes_min": (b["cpu_min_s"] - a["cpu_min_s"]) / a["cpu_min_s"],
    }
    d0, dv = out["lobes_verify0"], out["lobes_verify"]
    return {
        "label": label,
        "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "chatterlab": cl.__version__,
        "commit": source_commit(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "cpu_count": os.cpu_count(),
        "blas": blas,
        "model": "studies/traverse_shaper/model.toml at 0.85 m",
        "speeds": [0.1, 1.0, n_speeds],
        "width_max_m": width_max,
        "verify": verify,
        "repeats": repeat,
        "grid_size": int(omega.size),
        "n_poles": int(2 * M.shape[0]),
        "frf_rel_diff_vs_engine": rel,
        "load_before": load_before,
        "load_after": load_after,
        "peak_rss_mb": rss_mb,
        "lobes_verify0": a,
        "lobes_verify": b,
        "frf": c,
        "ratios": ratios,
        "result_verify0": summary(d0),
        "result_verify": summary(dv),
    }


def _agreement(ref: dict[str, Any], new: dict[str, Any]) -> dict[str, Any]:
    """How far two runs' diagrams are apart (relative, finite entries)."""
    r0, r1 = ref["result_verify"], new["result_verify"]
    b0, b1 = np.array(r0["b_lim_m"]), np.array(r1["b_lim_m"])
    f0, f1 = np.array(r0["chatter_hz"]), np.array(r1["chatter_hz"])
    fin = np.isfinite(b0) & np.isfinite(b1)
    same_inf = bool(np.array_equal(np.isfinite(b0), np.isfinite(b1)))
    key = ("kind", "verdict", "rhp_roots", "proven", "agrees")
    return {
        "b_lim_max_rel": float(np.max(np.abs(b1[fin] / b0[fin] - 1))) if fin.any() else 0.0,
        "chatter_max_rel": float(np.max(np.abs(f1[fin] / f0[fin] - 1))) if fin.any() else 0.0,
        "same_inf": same_inf,
        "same_lobes": r0["lobe"] == r1["lobe"],
        "same_folds": r0["folds"] == r1["folds"],
        "same_grid": r0["n_frequencies"] == r1["n_frequencies"],
        "minimum_rel": abs(r1["minimum"]["width"] / r0["minimum"]["width"] - 1),
        "absolute_minimum_rel": abs(r1["absolute_minimum"]["width"] / r0["absolute_minimum"]["width"] - 1),
        "same_checks": [{k: c[k] for k in key} for c in r0["checks"]]
        == [{k: c[k] for k in key} for c in r1["checks"]],
    }


def table(data: dict[str, Any]) -> str:
    """benchmarks/results/lobes.md from the JSON (never typed by hand)."""
    runs = data["runs"]
    lines = [
        "# Lobe engine against the FRF it is built on (issue 26, rows 3 and 4)",
        "",
        "Generated by `python benchmarks/bench_lobes.py` from `benchmarks/results/lobes.json`; do not edit.",
        "",
        "Traverse shaper at s = 0.85 m, 300 work speeds 0.1 .. 1 m/s, width ceiling 1 mm, one BLAS thread,"
        " interleaved repeats. *FRF* is the competitor: the structure's FRF between the coupling coordinates"
        " at the engine's own frequency grid by one eigendecomposition and a vectorised pole-residue sum."
        " Row 3 is `lobes(verify=0)` / FRF (goal <= 10); row 4 is the extra time of `verify=16` over"
        " `lobes(verify=0)` (goal <= 1). Ratios are taken within one run (min / min and median / median).",
        "",
        "| run | commit | grid | repeats | FRF min / median ms | lobes verify=0 min / median ms"
        " | verify=16 min / median ms | row 3: lobes / FRF (min, median; CPU min) | row 4: verify extra / lobes"
        " (min, median; CPU min) | load before -> after | peak RSS MB |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for label, r in runs.items():
        q = r["ratios"]
        lines.append(
            f"| {label} | {r['commit']} | {r['grid_size']} | {r['repeats']}"
            f" | {r['frf']['min_s'] * 1e3:.1f} / {r['frf']['median_s'] * 1e3:.1f}"
            f" | {r['lobes_verify0']['min_s'] * 1e3:.0f} / {r['lobes_verify0']['median_s'] * 1e3:.0f}"
            f" | {r['lobes_verify']['min_s'] * 1e3:.0f} / {r['lobes_verify']['median_s'] * 1e3:.0f}"
            f" | {q['lobes_over_frf_min']:.1f}x, {q['lobes_over_frf_median']:.1f}x;"
            f" {q.get('cpu_lobes_over_frf_min', float('nan')):.1f}x"
            f" | {q['verify_extra_over_lobes_min']:.2f}x, {q['verify_extra_over_lobes_median']:.2f}x;"
            f" {q.get('cpu_verify_extra_over_lobes_min', float('nan')):.2f}x"
            f" | {r['load_before'].split()[0]} -> {r['load_after'].split()[0]}"
            f" | {r['peak_rss_mb']:.0f} |"
        )
    lines += ["", "Load: 1-minute /proc/loadavg on a 2-core machine shared with other work.", ""]
    for label, r in runs.items():
        res = r["result_verify"]
        agree = sum(c["agrees"] for c in res["checks"])
        lines.append(
            f"- {label}: minimum b_lim {res['minimum']['width'] * 1e3:.6f} mm at"
            f" {res['minimum']['speed']:.5f} m/s, {res['minimum']['chatter_hz']:.4f} Hz;"
            f" {res['folds']} folds, {res['n_frequencies']} frequencies; {agree}/{len(res['checks'])}"
            f" checks agree; FRF of the competitor vs the engine's: {r['frf_rel_diff_vs_engine']:.1e} relative"
        )
    labels = list(runs)
    if "before" in runs:
        for label in labels:
            if label == "before":
                continue
            g = _agreement(runs["before"], runs[label])
            lines.append(
                f"- {label} vs before: b_lim within {g['b_lim_max_rel']:.1e} relative, chatter frequency within"
                f" {g['chatter_max_rel']:.1e}; same inf: {g['same_inf']}, same lobe numbers: {g['same_lobes']},"
                f" same folds: {g['same_folds']}, same grid: {g['same_grid']}; minimum within"
                f" {g['minimum_rel']:.1e}, absolute minimum within {g['absolute_minimum_rel']:.1e};"
                f" same check verdicts and counts: {g['same_checks']}"
            )
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--label", default="current", help="name of this run in the JSON (e.g. before, after)")
    ap.add_argument("--repeat", type=int, default=7, help="interleaved repeats (>= 5)")
    ap.add_argument("--speeds", type=int, default=300)
    ap.add_argument("--width-max", type=float, default=1e-3, help="width ceiling, m")
    ap.add_argument("--verify", type=int, default=16)
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument("--table-only", action="store_true", help="regenerate the Markdown table from the JSON")
    args = ap.parse_args()
    out = Path(args.out)
    data: dict[str, Any] = json.loads(out.read_text()) if out.exists() else {}
    data.setdefault("benchmark", "lobes (issue 26, rows 3 and 4)")
    data.setdefault("runs", {})
    if not args.table_only:
        rec = measure(args.label, max(5, args.repeat), args.speeds, args.width_max, args.verify)
        data["runs"][args.label] = rec
        q = rec["ratios"]
        print(
            f"chatterlab {rec['chatterlab']} ({rec['commit']}), grid {rec['grid_size']} frequencies,"
            f" {rec['repeats']} interleaved repeats, load {rec['load_before']} -> {rec['load_after']}"
        )
        for k in ("frf", "lobes_verify0", "lobes_verify"):
            print(
                f"  {k:14s} min {rec[k]['min_s'] * 1e3:8.1f} ms  median {rec[k]['median_s'] * 1e3:8.1f} ms"
                f"  (CPU min {rec[k]['cpu_min_s'] * 1e3:8.1f} ms)"
            )
        print(
            f"  row 3 lobes/FRF: {q['lobes_over_frf_min']:.1f}x (min), {q['lobes_over_frf_median']:.1f}x (median)"
            f" [goal <= {GOAL_LOBES:g}]; row 4 verify extra/lobes: {q['verify_extra_over_lobes_min']:.2f}x (min),"
            f" {q['verify_extra_over_lobes_median']:.2f}x (median) [goal <= {GOAL_VERIFY:g}];"
            f" peak RSS {rec['peak_rss_mb']:.0f} MB"
        )
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(data, indent=1) + "\n")
    md = out.with_suffix(".md")
    md.write_text(table(data))
    print(f"wrote {out} and {md}")


if __name__ == "__main__":
    main()
