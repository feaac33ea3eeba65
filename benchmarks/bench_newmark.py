"""Benchmark of the time domain (chatterlab.time.simulate on chatterlab.time.newmark).

Run from the repository root::

    python benchmarks/bench_newmark.py           # everything (10-20 min on 2 loaded cores)
    python benchmarks/bench_newmark.py --quick   # fewer repetitions, two solve_ivp methods

It prints, all measured in this run, and writes to
``benchmarks/results/bench_newmark.json``:

1. **throughput**: steps per second of ``simulate(shaper, feedback="pdo")`` --
   the traverse shaper (36 independent coordinates) with the slide moving
   through its stroke cycles (W(t), dW/dt, d2W/dt2), the cutting process on
   with all feedback terms and the delayed term -- at the default step, the
   paper's step and h = 1e-4 s; min and median of repeated runs, with the
   coefficients by per-segment polynomials (default) and directly, and with
   the integrator's worker threads on and off;
2. **equal-accuracy cost against solve_ivp**, on the second pass
   (t = T .. T + 0.3 s: the cut entry at T + 0.1 s and the delayed term
   reading the first pass): the same equations A q'' + B q' + C q = p + G q(t - T)
   with the same A(t), B(t), C(t), G(t), p(t) and the same history, solved by
   Newmark at the default step of ``simulate`` (and a 4x finer one) and by
   ``scipy.integrate.solve_ivp`` on the first-order form -- what a competent
   user would otherwise write: the method of steps (the history is the
   dense first pass), integrated piecewise between the coefficient jumps,
   the exact Jacobian for the implicit methods, ``atol`` scaled to the
   state (rtol times the largest |q| and |v| of the first pass).  For each
   Newmark step and each method the tolerance is **chosen in this run** so
   that solve_ivp's error equals Newmark's: bisection on log10(rtol) for the
   largest rtol whose error is at most Newmark's (bracketed to a factor
   10^0.125), so solve_ivp is never asked for more accuracy than Newmark
   delivers.  Error: max over time of |y - y_ref| / max |y_ref| of the
   contact-point displacements rfe5.x, rfe5.y, worst of the two, against
   DOP853 at rtol 1e-10, whose own error is estimated by a second reference
   (Radau at rtol 1e-10) and must be below 1 % of the smallest error
   compared.  Then both are timed, interleaved, ``--repeats`` times: min and
   median wall times and their ratios.  Newmark runs with its default two
   worker threads and with none (one core, like solve_ivp).  Nothing is
   extrapolated: every ratio is two measured wall times of runs reaching
   the same error.
3. the **machine load** (1-minute load average) before and after each part
   -- other jobs on the 2 cores slow everything, threads most; the JSON
   flags a run that started at a load above 0.5 per core as ``loaded``
   (the later loads include the benchmark's own threads).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import math
import os
import platform
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

try:
    import chatterlab  # noqa: F401
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import chatterlab as cl
from chatterlab.process._kinematics import kinematics_for
from chatterlab.time import Integration, NewmarkOptions, newmark, simulate
from chatterlab.time._simulate import ParametricProblem, _blas_limits, _output_map

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "traverse_shaper" / "model.toml"
OUT = ROOT / "benchmarks" / "results" / "bench_newmark.json"
#: 1-minute load average per core above which a timing is flagged as taken on a loaded machine
LOADED = 0.5


def load() -> list[float]:
    return [float(x) for x in os.getloadavg()] if hasattr(os, "getloadavg") else [math.nan] * 3


def stats(walls: list[float]) -> dict[str, Any]:
    return {"min_s": min(walls), "median_s": statistics.median(walls), "runs_s": walls}


# =========================================================================== 1. throughput


def throughput(system: cl.System, reps: int) -> list[dict[str, Any]]:
    print("\n1. throughput: simulate(shaper, feedback='pdo', passes=2), steps/s of the integration")
    print(
        f"   {'step h [s]':>12} {'coefficients':>12} {'workers':>7} {'steps':>7} {'best':>8} {'median':>8}  (steps/s from the min and median wall)"
    )
    cases = [
        (None, "auto", 2),
        (None, "auto", 0),
        (None, "direct", 2),
        (1.4e-3, "auto", 2),
        (1e-4, "auto", 2),
    ]
    rows = []
    for step, method, workers in cases:
        walls, n, h = [], 0, 0.0
        la = load()
        for _ in range(reps):
            sim = simulate(
                system,
                feedback="pdo",
                integration=Integration(
                    periods=2, step=step, method=method, scheme=NewmarkOptions(workers=workers)
                ),
            )
            walls.append(sim.response.wall_time)
            n, h = sim.response.n_steps, sim.step
        s = stats(walls)
        print(f"   {h:12.4g} {method:>12} {workers:7d} {n:7d} {n / s['min_s']:8.0f} {n / s['median_s']:8.0f}")
        rows.append({"step_s": h, "coefficients": method, "workers": workers, "steps": n,
                     "steps_per_s_best": n / s["min_s"], "steps_per_s_median": n / s["median_s"],
                     "integration_wall": s, "load_average_before": la})  # fmt: skip
    return rows


# =========================================================================== 2. equal accuracy


class SecondPass:
    """The second pass of the shaper (t = T .. T + 0.3 s) with the first pass as its history."""

    def __init__(self, system: cl.System) -> None:
        from scipy.interpolate import CubicSpline

        kin = kinematics_for(system.model.process)
        self.kin, self.T = kin, kin.cycle
        self.prob = ParametricProblem(system, kin, width=0.002, terms="pdo", t_end=2 * self.T)
        self.n = self.prob.n
        self.rows = np.vstack([_output_map(system, "rfe5.x"), _output_map(system, "rfe5.y")])
        with _blas_limits():
            first = newmark(self.prob, (0.0, self.T), kin.grid_unit / 2000)  # the history: fine and dense
        self.hist = CubicSpline(first.t, first.q.T, axis=0)
        self.q0, self.v0 = first.q[:, -1], first.v[:, -1]
        self.t_a, self.t_b = self.T, self.T + 0.3
        self.pieces = [self.t_a, self.T + kin.events()[0], self.t_b]  # the coefficients jump at the cut entry
        # atol scaled to the state, as a user would: rtol x the largest |q| and |v| (of the first pass)
        self.atol_scale = np.r_[
            np.full(self.n, np.abs(first.q).max()), np.full(self.n, np.abs(first.v).max())
        ]

    def outs(self, t: np.ndarray, q: np.ndarray) -> np.ndarray:
        return np.einsum("mkn,nm->km", self.prob.maps(t, self.rows), q)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        A, B, C, G = self.prob.matrices(np.array([t]))
        F = self.prob.force(np.array([t]))[0]
        n = self.n
        r = F - B[0] @ y[n:] - C[0] @ y[:n] + G[0] @ self.hist(t - self.T)
        return np.concatenate([y[n:], np.linalg.solve(A[0], r)])

    def jac(self, t: float, y: np.ndarray) -> np.ndarray:
        A, B, C, _ = self.prob.matrices(np.array([t]))
        Ai = np.linalg.inv(A[0])
        n = self.n
        return np.block([[np.zeros((n, n)), np.eye(n)], [-Ai @ C[0], -Ai @ B[0]]])

    def ivp(self, method: str, rtol: float) -> tuple[list[Any], float, int]:
        """solve_ivp piecewise between the coefficient jumps: the dense
        solutions, the wall time and the right-hand side + Jacobian evaluations."""
        from scipy.integrate import solve_ivp

        t0 = time.perf_counter()
        y = np.concatenate([self.q0, self.v0])
        sols, nfev = [], 0
        with _blas_limits():
            for a, b in zip(self.pieces[:-1], self.pieces[1:], strict=True):
                kw = {"jac": self.jac} if method in ("Radau", "BDF", "LSODA") else {}
                s = solve_ivp(
                    self.rhs, (a, b), y, method=method, rtol=rtol, atol=rtol * self.atol_scale,
                    dense_output=True, **kw,
                )  # fmt: skip
                if not s.success:
                    raise RuntimeError(f"{method}: {s.message}")
                nfev += s.nfev + int(getattr(s, "njev", 0) or 0)
                y = s.y[:, -1]
                sols.append(s.sol)
        return sols, time.perf_counter() - t0, nfev

    def dense(self, sols: list[Any], t: np.ndarray) -> np.ndarray:
        idx = np.clip(np.searchsorted(self.pieces, t, side="right") - 1, 0, len(sols) - 1)
        q = np.empty((self.n, t.size))
        for j, sol in enumerate(sols):
            sel = idx == j
            if sel.any():
                q[:, sel] = sol(t[sel])[: self.n]
        return self.outs(t, q)

    def newmark(self, h: float, workers: int) -> tuple[Any, float]:
        t0 = time.perf_counter()
        with _blas_limits():
            r = newmark(
                self.prob, (self.t_a, self.t_b), h, self.q0, self.v0, history=self.hist,
                options=NewmarkOptions(workers=workers),
            )  # fmt: skip
        return r, time.perf_counter() - t0


def equal_accuracy(system: cl.System, quick: bool, reps: int) -> dict[str, Any]:
    sp = SecondPass(system)
    kin = sp.kin
    print(
        f"\n2. equal accuracy: t = {sp.t_a:g} .. {sp.t_b:g} s (second pass, cut entry at {sp.pieces[1]:g} s, "
        f"the delayed term reading the first pass), {sp.n} coordinates"
    )
    ref_sols, w_ref, nf_ref = sp.ivp("DOP853", 1e-10)
    t_ref = np.linspace(sp.t_a, sp.t_b, 6001)
    scale = np.abs(sp.dense(ref_sols, t_ref)).max(axis=1)

    def err_at(y: np.ndarray, t: np.ndarray) -> float:
        """max over the times t of |y - y_ref| / max |y_ref|, worst of rfe5.x, rfe5.y."""
        return float(np.max(np.abs(y - sp.dense(ref_sols, t)).max(axis=1) / scale))

    check_sols, _, _ = sp.ivp("Radau", 1e-10)
    ref_err = err_at(sp.dense(check_sols, t_ref), t_ref)
    print(f"   reference: DOP853 rtol 1e-10 ({w_ref:.1f} s, {nf_ref} evaluations); Radau rtol 1e-10 differs by "
          f"{ref_err:.1e} (the reference's error is at most about this)")  # fmt: skip

    # the default step of simulate() for the shaper (grid unit / 493), and the steps at which
    # Newmark's error is about 1 % and 0.1 % (error ~ h^2)
    steps = {"default step of simulate()": kin.grid_unit / 493, "about 1 %": kin.grid_unit / 2000,
             "about 0.1 %": kin.grid_unit / 6325}  # fmt: skip
    methods = ("RK45", "DOP853", "LSODA", "Radau", "BDF") if not quick else ("LSODA", "Radau")
    out: dict[str, Any] = {
        "window_s": [sp.t_a, sp.t_b], "coordinates": sp.n, "error_measure":
        "max over t of |y - y_ref| / max|y_ref|, worst of rfe5.x and rfe5.y",
        "reference": {"method": "DOP853", "rtol": 1e-10, "wall_s": w_ref, "evaluations": nf_ref,
                      "difference_to_Radau_rtol_1e-10": ref_err},
        "atol": "rtol x max|q| for q, rtol x max|v| for v (over all coordinates of the first pass)",
        "cases": [],
    }  # fmt: skip
    for label, h in steps.items():
        r, _ = sp.newmark(h, 2)
        e_nm = err_at(sp.outs(r.t, r.q), r.t)
        if not ref_err < 0.01 * e_nm:
            print(f"   WARNING: the reference's error {ref_err:.1e} is not below 1 % of Newmark's {e_nm:.1e}")
        print(f"\n   Newmark h = {h:.4g} s ({label}, {r.n_steps} steps): error {e_nm:.3e}")
        print(f"   {'solve_ivp':>9} {'rtol':>9} {'error':>9} {'evals':>7} {'tries':>5}")
        for method in methods:
            # solve_ivp's error at Newmark's own step times (its dense output), so both are
            # measured on the same instants
            rtol, e, nfev, tries = match(sp, method, e_nm, lambda sols, t=r.t: err_at(sp.dense(sols, t), t))
            print(f"   {method:>9} {rtol:9.2e} {e:9.3e} {nfev:7d} {tries:5d}")
            la = load()
            w_nm2, w_nm0, w_iv = [], [], []
            for _ in range(reps):  # interleaved, so a change of load hits all three alike
                w_nm2.append(sp.newmark(h, 2)[1])
                w_nm0.append(sp.newmark(h, 0)[1])
                w_iv.append(sp.ivp(method, rtol)[1])
            case = {
                "newmark_step_s": h, "step_label": label, "newmark_steps": r.n_steps, "newmark_error": e_nm,
                "method": method, "rtol": rtol, "solve_ivp_error": e, "solve_ivp_evaluations": nfev,
                "rtol_tries": tries, "load_average_before": la, "load_average_after": load(),
                "newmark_2_workers": stats(w_nm2), "newmark_0_workers": stats(w_nm0), "solve_ivp": stats(w_iv),
            }  # fmt: skip
            for key in ("newmark_2_workers", "newmark_0_workers"):
                case[f"ratio_min_vs_{key}"] = min(w_iv) / min(case[key]["runs_s"])
                case[f"ratio_median_vs_{key}"] = statistics.median(w_iv) / statistics.median(
                    case[key]["runs_s"]
                )
            out["cases"].append(case)
            print(
                f"      wall min/median: Newmark {min(w_nm2):.3f}/{statistics.median(w_nm2):.3f} s (2 workers), "
                f"{min(w_nm0):.3f}/{statistics.median(w_nm0):.3f} s (0 workers); solve_ivp "
                f"{min(w_iv):.3f}/{statistics.median(w_iv):.3f} s -> ratio (min) "
                f"{case['ratio_min_vs_newmark_2_workers']:.1f}x / {case['ratio_min_vs_newmark_0_workers']:.1f}x, "
                f"(median) {case['ratio_median_vs_newmark_2_workers']:.1f}x / "
                f"{case['ratio_median_vs_newmark_0_workers']:.1f}x; load {la[0]:.2f}"
            )
    print("\n   summary: the fastest solve_ivp method at Newmark's error, against Newmark (min wall times)")
    out["summary"] = []
    for label, h in steps.items():
        cs = [c for c in out["cases"] if c["step_label"] == label]
        best = min(cs, key=lambda c: c["solve_ivp"]["min_s"])
        row = {"step_label": label, "newmark_step_s": h, "error": best["newmark_error"], "fastest": best["method"],
               "rtol": best["rtol"], "ratio_min_2_workers": best["ratio_min_vs_newmark_2_workers"],
               "ratio_min_0_workers": best["ratio_min_vs_newmark_0_workers"],
               "ratio_median_2_workers": best["ratio_median_vs_newmark_2_workers"],
               "ratio_median_0_workers": best["ratio_median_vs_newmark_0_workers"]}  # fmt: skip
        out["summary"].append(row)
        print(
            f"   error {row['error']:.2e} (h = {h:.4g} s, {label}): {best['method']} at rtol {best['rtol']:.2e} "
            f"takes {row['ratio_min_2_workers']:.1f}x Newmark's time ({row['ratio_min_0_workers']:.1f}x Newmark "
            f"on one thread); medians {row['ratio_median_2_workers']:.1f}x / {row['ratio_median_0_workers']:.1f}x"
        )
    return out


def match(sp: SecondPass, method: str, target: float, err: Any) -> tuple[float, float, int, int]:
    """An rtol whose solve_ivp error is at most ``target``, as loose as found:
    ``(rtol, error, evaluations, runs tried)``.  A decade scan brackets the
    crossing, bisection on log10(rtol) narrows it to a factor 10^0.125; of
    all rtols tried that meet the target, the one with the fewest
    evaluations is taken (the error is not monotone in rtol)."""
    tries = 0
    cache: dict[float, tuple[float, int]] = {}

    def e_at(lg: float) -> float:
        nonlocal tries
        if lg not in cache:
            tries += 1
            sols, _, nfev = sp.ivp(method, 10.0**lg)
            cache[lg] = (err(sols), nfev)
        return cache[lg][0]

    hi = -2.0  # a loose tolerance, error usually above the target
    while e_at(hi) <= target and hi < 0:
        hi += 1.0
    lo = hi - 1.0
    while e_at(lo) > target:
        hi, lo = lo, lo - 1.0
        if lo < -12:
            raise RuntimeError(f"{method}: no rtol >= 1e-12 reaches the error {target:.2e}")
    # e(lo) <= target < e(hi) (or hi is as loose as allowed): bisect
    while hi - lo > 0.125:
        mid = 0.5 * (lo + hi)
        if e_at(mid) <= target:
            lo = mid
        else:
            hi = mid
    # the error is not monotone in rtol (step-size control): of every rtol tried that meets
    # the target, the one needing the fewest evaluations
    ok = [lg for lg, (e, _) in cache.items() if e <= target]
    best = min(ok, key=lambda lg: (cache[lg][1], -lg))
    return 10.0**best, cache[best][0], cache[best][1], tries


# =========================================================================== main


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeats", type=int, default=None, help="timed runs of each case (default 5, quick 3)")
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args()
    reps = args.repeats or (3 if args.quick else 5)
    load0 = load()
    print(f"before: load average {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f} on {os.cpu_count()} cores")
    system = cl.assemble(cl.load_model(MODEL))
    simulate(system, feedback="pdo", integration=Integration(duration=0.05))  # warm-up (imports, modes)
    result: dict[str, Any] = {
        "benchmark": "bench_newmark",
        "date_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "chatterlab": chatterlab.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
        "quick": args.quick,
        "repeats": reps,
        "model": str(MODEL.relative_to(ROOT)),
        "load_average_start": load0,
        "loaded_threshold_per_core": LOADED,
    }
    result["throughput"] = throughput(system, reps)
    result["equal_accuracy"] = equal_accuracy(system, args.quick, reps)
    result["load_average_end"] = load()
    # the load before the benchmark starts: the later ones include its own one or two busy threads
    result["loaded"] = bool(load0[0] > LOADED * (os.cpu_count() or 1))
    result["note_on_loads"] = "loads after the start include this benchmark's own 1-2 busy threads"
    print(
        f"\nafter: load average {result['load_average_end'][0]:.2f}"
        + (" (LOADED machine)" if result["loaded"] else "")
    )
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
