"""The time domain at equal accuracy: chatterlab's exponential step map and
Newmark against every scipy ``solve_ivp`` method (issue 26, time rows).

Run from the repository root::

    python benchmarks/bench_time.py              # both rows, 5 interleaved repeats
    python benchmarks/bench_time.py --repeats 7
    python benchmarks/bench_time.py --markdown   # only regenerate time.md and the docs table from time.json

Two problems, each ``A q'' + B q' + C q = f + G q(t - T)`` with constant
coefficients, zero history:

* ``turning_1dof``: the 1-DOF turning tool of the tests (1 kg, 10 MN/m, 3 %
  damping, K_f b = 2e9 N/m^2 x 0.6 mm), T = 0.02 s (3000 rpm), 0.4 s from
  q0 = 1 um (chatter growing at 20.8 1/s);
* ``shaper_36dof``: the traverse shaper held at its default position,
  cutting continuously with T = 0.1 s, b = 2 mm, 36 coordinates, 0.3 s from
  rest under the cutting force (``chatterlab.time._simulate.constant_loop``:
  the matrices ``simulate`` integrates).

Error: max over time of ``|y - y_ref| / max |y_ref|`` of the tool
displacement (the 1-DOF's q; the shaper's rfe5.x and rfe5.y, worst of the
two), against DOP853 at rtol 1e-12 by the method of steps.  Each contender is
evaluated at its own output instants (solve_ivp: its dense output at 4001
instants).

Contenders, all single BLAS thread, in one process:

* ``solve_ivp`` RK45, RK23, DOP853, Radau, BDF, LSODA -- what a competent
  user writes: the first-order form ``x' = L x + N q(t - T) + c`` with the
  matrices precomputed (a vectorised numpy right-hand side, two small
  matrix-vector products), the method of steps (one call per delay interval,
  the history the previous interval's dense output), the exact Jacobian
  ``L`` for the implicit methods, ``atol = rtol x`` the largest |q| and |v|
  of the reference;  its ``rtol`` chosen **in this run** as the loosest
  (decade scan then bisection to a factor 10^0.125) whose error is at most
  the target, and of those the one with the fewest evaluations;
* ``exponential (rtol)``: ``chatterlab.time.exponential`` with ``rtol`` =
  the target -- its own error control, what a user runs;
* ``exponential (fixed h)``: the same scheme at the largest step (fewest
  steps per delay, bisection) whose error is at most the target -- tuned in
  this run exactly as solve_ivp's rtol;
* ``newmark``: ``chatterlab.time.newmark`` (average acceleration), no worker
  threads, at the largest step h = T/m whose error is at most the target.

Then every contender is timed ``--repeats`` times, interleaved (one run of
each in turn, so a change of load hits all alike): CPU time
(``time.process_time``) and wall time, min and median.  Ratios are of
measured times only: the fastest solve_ivp method (min CPU) over each
chatterlab contender (min CPU), and the same with medians.  The 1-minute
load (/proc/loadavg) is recorded before each row and at the end, ``LOADED``
when above 1; the peak RSS of the process after each row.  Results:
``benchmarks/results/time.json`` and the table ``benchmarks/results/time.md``
generated from it.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from _common import load1, peak_rss_mb

ROOT = Path(__file__).resolve().parents[1]
try:
    import chatterlab
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(ROOT))
    import chatterlab

from chatterlab._threads import one_blas_thread  # noqa: E402
from chatterlab.time import ConstantProblem, NewmarkOptions, exponential, newmark  # noqa: E402

OUT = ROOT / "benchmarks" / "results" / "time.json"
MD = ROOT / "benchmarks" / "results" / "time.md"
METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")
TARGETS = (1e-2, 1e-3)
#: a solve_ivp run longer than this (s) stops the search towards tighter rtol for that method
RUN_CAP_S = 60.0


# =========================================================================== the problems


class Problem:
    """One delayed loop: matrices, outputs, the reference and the contenders."""

    def __init__(self, name: str, A, B, C, G, T: float, f0, q0, t_end: float, rows) -> None:
        self.name, self.T, self.t_end = name, float(T), float(t_end)
        self.A, self.B, self.C, self.G = A, B, C, G
        self.n = n = A.shape[0]
        self.f0, self.q0, self.rows = np.asarray(f0, float), np.asarray(q0, float), np.asarray(rows, float)
        Ai = np.linalg.inv(A)
        self.L = np.block([[np.zeros((n, n)), np.eye(n)], [-Ai @ C, -Ai @ B]])
        self.N = np.vstack([np.zeros((n, n)), Ai @ G])
        self.c = np.r_[np.zeros(n), Ai @ self.f0]
        self.problem = ConstantProblem(A, B, C, force=self.f0, G=G, delay=self.T)
        self.atol_scale = np.ones(2 * n)
        self.ref: Any = None
        self.t_ref = np.linspace(0.0, self.t_end, 4001)

    # ---- solve_ivp by the method of steps
    def ivp(self, method: str, rtol: float, atol_scale: np.ndarray | None = None) -> tuple[Callable, int]:
        from scipy.integrate import solve_ivp

        L, N, c, n, T = self.L, self.N, self.c, self.n, self.T
        y = np.r_[self.q0, np.zeros(n)]
        sols, a, nfev = [], 0.0, 0
        atol = rtol * (self.atol_scale if atol_scale is None else atol_scale)
        jac: dict[str, Any] = {}
        if method in ("Radau", "BDF"):
            jac = {"jac": L}
        elif method == "LSODA":  # LSODA takes the Jacobian as a function only
            jac = {"jac": lambda t, y: L}
        while a < self.t_end - 1e-12 * T:
            b = min(a + T, self.t_end)
            prev = sols[-1] if sols else None
            if prev is None:

                def f(t: float, y: np.ndarray) -> np.ndarray:
                    return L @ y + c
            else:

                def f(t: float, y: np.ndarray, prev: Any = prev) -> np.ndarray:
                    return L @ y + N @ prev(t - T)[:n] + c

            s = solve_ivp(f, (a, b), y, method=method, rtol=rtol, atol=atol, dense_output=True, **jac)
            if not s.success:
                raise RuntimeError(f"{method}: {s.message}")
            nfev += int(s.nfev)
            sols.append(s.sol)
            y, a = s.y[:, -1], b

        def q(t: np.ndarray) -> np.ndarray:
            k = np.minimum((t / T).astype(int), len(sols) - 1)
            out = np.empty((n, t.size))
            for i, sol in enumerate(sols):
                sel = k == i
                if sel.any():
                    out[:, sel] = sol(t[sel])[:n]
            return out

        return q, nfev

    def error(self, t: np.ndarray, y: np.ndarray) -> float:
        """``y``: the outputs (rows) at the instants ``t``."""
        y_ref = self.rows @ self.ref(t)
        return float((np.abs(y - y_ref).max(axis=1) / np.abs(y_ref).max(axis=1)).max())

    # ---- chatterlab
    def expo(self, rtol: float | None = None, m: int | None = None) -> Any:
        h = None if m is None else self.T / m
        return exponential(
            self.problem, (0.0, self.t_end), self.q0, rtol=rtol or 1e-3, h=h, outputs=self.rows
        )

    def newmark(self, m: int) -> Any:
        return newmark(
            self.problem,
            (0.0, self.t_end),
            self.T / m,
            self.q0,
            options=NewmarkOptions(workers=0),
            outputs=self.rows,
        )


def turning() -> Problem:
    kb = 2.0e9 * 6e-4
    A, B, C, G = (np.array([[x]]) for x in (1.0, 189.7, 1.0e7 + kb, kb))
    return Problem("turning_1dof", A, B, C, G, 0.02, [0.0], [1e-6], 0.4, [[1.0]])


def shaper() -> Problem:
    import chatterlab as cl
    from chatterlab.process._kinematics import kinematics_for
    from chatterlab.time._simulate import ParametricProblem, _constant_matrices, _output_map

    system = cl.assemble(cl.load_model(ROOT / "studies" / "traverse_shaper" / "model.toml"))
    prob = ParametricProblem(
        system, kinematics_for(system.model.process, delay=0.1), width=0.002, terms="pdo"
    )
    A, B, C, G, T = _constant_matrices(prob)
    assert G is not None
    f0 = np.array(prob.force(np.array([0.0]))[0])
    rows = prob.maps(
        np.array([0.0]), np.vstack([_output_map(system, "rfe5.x"), _output_map(system, "rfe5.y")])
    )[0]
    return Problem("shaper_36dof", A, B, C, G, T, f0, np.zeros(A.shape[0]), 0.3, rows)


# =========================================================================== matching the error


def match_rtol(pb: Problem, method: str, target: float) -> dict[str, Any]:
    """The loosest rtol of ``method`` whose error is at most ``target`` (see the module notes)."""
    cache: dict[float, tuple[float, int, float]] = {}

    def e_at(lg: float) -> float:
        if lg not in cache:
            t0 = time.perf_counter()
            q, nfev = pb.ivp(method, 10.0**lg)
            wall = time.perf_counter() - t0
            t = pb.t_ref
            cache[lg] = (pb.error(t, pb.rows @ q(t)), nfev, wall)
        return cache[lg][0]

    hi = 0.0 if target >= 1e-2 else -1.0
    while e_at(hi) <= target and hi < 0:
        hi += 1.0
    lo = hi - 1.0
    capped = False
    while e_at(lo) > target:
        if cache[lo][2] > RUN_CAP_S or lo <= -12:
            capped = True
            break
        hi, lo = lo, lo - 1.0
    if not capped:
        while hi - lo > 0.125:
            mid = 0.5 * (lo + hi)
            if e_at(mid) <= target:
                lo = mid
            else:
                hi = mid
    ok = [lg for lg, v in cache.items() if v[0] <= target]
    if not ok:
        return {"method": method, "matched": False, "tries": len(cache),
                "note": f"no rtol tried reaches the error (last run {cache[lo][2]:.1f} s > {RUN_CAP_S:g} s cap)"}  # fmt: skip
    best = min(ok, key=lambda lg: (cache[lg][1], -lg))
    return {"method": method, "matched": True, "rtol": 10.0**best, "error": cache[best][0],
            "evaluations": cache[best][1], "tries": len(cache)}  # fmt: skip


def match_steps(err_of: Callable[[int], float], target: float, m0: int, m_min: int) -> tuple[int, float]:
    """The fewest steps per delay m >= m_min whose error is at most ``target``
    (doubling from m0, then bisection on the integer m; the error is assumed
    to fall with m near the crossing)."""
    cache: dict[int, float] = {}

    def e(m: int) -> float:
        if m not in cache:
            cache[m] = err_of(m)
        return cache[m]

    lo, hi = m_min, max(m0, m_min)
    while e(hi) > target:
        lo, hi = hi, 2 * hi
    if lo < hi and e(lo) <= target:
        hi = lo
    while hi - lo > max(1, hi // 64):
        mid = (lo + hi) // 2
        if e(mid) <= target:
            hi = mid
        else:
            lo = mid
    return hi, cache[hi]


# =========================================================================== timing


def timed(fn: Callable[[], Any]) -> tuple[float, float]:
    c0, w0 = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c0, time.perf_counter() - w0


def summary(runs: list[tuple[float, float]]) -> dict[str, Any]:
    cpu, wall = [r[0] for r in runs], [r[1] for r in runs]
    return {"cpu_min_s": min(cpu), "cpu_median_s": statistics.median(cpu), "wall_min_s": min(wall),
            "wall_median_s": statistics.median(wall), "cpu_runs_s": cpu, "wall_runs_s": wall}  # fmt: skip


def row(pb: Problem, reps: int) -> dict[str, Any]:
    load_before = load1()
    print(f"\n== {pb.name}: {pb.n} coordinates, T = {pb.T:g} s, {pb.t_end:g} s   (load {load_before:.2f})")
    t0 = time.perf_counter()
    # atol far below anything compared: 1e-6 of the largest of |q0| and the static deflection
    static = np.linalg.solve(pb.C - pb.G, pb.f0)
    q_scale = max(float(np.abs(pb.q0).max()), float(np.abs(static).max()))
    pb.ref, nf = pb.ivp("DOP853", 1e-12, atol_scale=np.full(2 * pb.n, 1e-6 * q_scale))
    w_ref = time.perf_counter() - t0
    qr = pb.ref(pb.t_ref)
    vr_scale = np.abs(np.gradient(qr, pb.t_ref, axis=1)).max()
    pb.atol_scale = np.r_[np.full(pb.n, np.abs(qr).max()), np.full(pb.n, vr_scale)]
    # the reference's own error: against DOP853 at rtol 1e-11 (must be far below the targets)
    q11, _ = pb.ivp("DOP853", 1e-11)
    ref_err = pb.error(pb.t_ref, pb.rows @ q11(pb.t_ref))
    print(
        f"   reference DOP853 rtol 1e-12: {w_ref:.1f} s, {nf} evaluations; differs from rtol 1e-11 by {ref_err:.1e}"
    )
    out: dict[str, Any] = {"problem": pb.name, "coordinates": pb.n, "delay_s": pb.T, "window_s": pb.t_end,
                           "reference": {"method": "DOP853", "rtol": 1e-12, "wall_s": w_ref, "evaluations": nf,
                                         "difference_to_rtol_1e-11": ref_err},
                           "load_1min_before": load_before, "targets": []}  # fmt: skip
    p = 5
    for target in TARGETS:
        print(f"\n   target error {target:g}")
        contenders: dict[str, Callable[[], Any]] = {}
        info: dict[str, Any] = {}
        r = pb.expo(rtol=target)
        e = pb.error(r.t, r.q)
        info["exponential (rtol)"] = {"rtol": target, "error": e, "steps_per_delay": r.attrs["steps_per_delay"],
                                      "step_s": r.h, "error_estimate": r.attrs["error_estimate"],
                                      "tries": r.attrs["tries"], "met": e <= target}  # fmt: skip
        contenders["exponential (rtol)"] = lambda target=target: pb.expo(rtol=target)
        print(f"   exponential rtol={target:g}: error {e:.2e} (estimate {r.attrs['error_estimate']:.2e}), "
              f"{r.attrs['steps_per_delay']} steps/delay, {r.attrs['tries']} tries")  # fmt: skip

        def e_exp(m: int) -> float:
            rr = pb.expo(m=m)
            return pb.error(rr.t, rr.q)

        m_e, err_e = match_steps(e_exp, target, p + 1, p + 1)
        info["exponential (fixed h)"] = {"steps_per_delay": m_e, "step_s": pb.T / m_e, "error": err_e}
        contenders["exponential (fixed h)"] = lambda m=m_e: pb.expo(m=m)
        print(f"   exponential fixed h = T/{m_e}: error {err_e:.2e}")

        def e_nm(m: int) -> float:
            rr = pb.newmark(m)
            return pb.error(rr.t, rr.q)

        m_n, err_n = match_steps(e_nm, target, 64, 2)
        info["newmark"] = {"steps_per_delay": m_n, "step_s": pb.T / m_n, "error": err_n}
        contenders["newmark"] = lambda m=m_n: pb.newmark(m)
        print(f"   newmark h = T/{m_n}: error {err_n:.2e}")
        for method in METHODS:
            mt = match_rtol(pb, method, target)
            info[f"solve_ivp {method}"] = mt
            if mt["matched"]:
                contenders[f"solve_ivp {method}"] = lambda method=method, rt=mt["rtol"]: pb.ivp(method, rt)
                print(f"   solve_ivp {method:6s} rtol {mt['rtol']:.2e}: error {mt['error']:.2e}, "
                      f"{mt['evaluations']} evaluations")  # fmt: skip
            else:
                print(f"   solve_ivp {method:6s}: {mt['note']}")
        runs: dict[str, list[tuple[float, float]]] = {k: [] for k in contenders}
        la = load1()
        for _ in range(reps):  # interleaved
            for k, fn in contenders.items():
                runs[k].append(timed(fn))
        times = {k: summary(v) for k, v in runs.items()}
        for k in times:
            info[k]["time"] = times[k]
        ivps = [k for k in times if k.startswith("solve_ivp")]
        fastest = min(ivps, key=lambda k: times[k]["cpu_min_s"])
        ratios = {}
        for k in ("exponential (rtol)", "exponential (fixed h)", "newmark"):
            ratios[k] = {
                "cpu_min": times[fastest]["cpu_min_s"] / times[k]["cpu_min_s"],
                "cpu_median": times[fastest]["cpu_median_s"] / times[k]["cpu_median_s"],
                "wall_min": times[fastest]["wall_min_s"] / times[k]["wall_min_s"],
                "wall_median": times[fastest]["wall_median_s"] / times[k]["wall_median_s"],
            }
        for k, v in times.items():
            print(f"   {k:24s} cpu min {v['cpu_min_s'] * 1e3:9.2f} ms  median {v['cpu_median_s'] * 1e3:9.2f} ms   "
                  f"wall min {v['wall_min_s'] * 1e3:9.2f} ms")  # fmt: skip
        print(
            f"   fastest solve_ivp: {fastest}; its CPU (min) over exponential (rtol) "
            f"{ratios['exponential (rtol)']['cpu_min']:.1f}x, exponential (fixed h) "
            f"{ratios['exponential (fixed h)']['cpu_min']:.1f}x, newmark {ratios['newmark']['cpu_min']:.2f}x"
        )
        out["targets"].append({"target": target, "contenders": info, "fastest_solve_ivp": fastest,
                               "ratios_fastest_solve_ivp_over": ratios, "load_1min_before_timing": la,
                               "load_1min_after_timing": load1()})  # fmt: skip
    out["peak_rss_mb_after"] = peak_rss_mb()
    return out


# =========================================================================== the table


def markdown(res: dict[str, Any]) -> str:
    """The table of time.md, from the JSON only."""
    lines = [
        "# Time domain at equal accuracy (generated by benchmarks/bench_time.py from time.json)",
        "",
        f"{res['date_utc']}, chatterlab {res['chatterlab']}, numpy {res['numpy']}, scipy {res['scipy']}, "
        f"{res['cpu_count']} cores, one BLAS thread, {res['repeats']} interleaved repeats; 1-min load at start "
        f"{res['load_1min_start']:.2f}, end {res['load_1min_end']:.2f}"
        + (" -- **LOADED** (> 1)" if res["loaded"] else ""),
        "",
        "Error: max over t of |y - y_ref| / max|y_ref| of the tool displacement against DOP853 rtol 1e-12 "
        "(method of steps). Ratio: the fastest solve_ivp method's CPU time over chatterlab's (min of the "
        "repeats; median in brackets).",
        "",
        "| problem | target | contender | setting | error | CPU min [ms] | CPU median [ms] | wall min [ms] "
        "| fastest solve_ivp / this (CPU min, median) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for rw in res["rows"]:
        for tg in rw["targets"]:
            fast = tg["fastest_solve_ivp"]
            for name, c in tg["contenders"].items():
                if "time" not in c:
                    lines.append(f"| {rw['problem']} | {tg['target']:g} | {name} | -- | -- | -- | -- | -- | "
                                 f"{c.get('note', '')} |")  # fmt: skip
                    continue
                if name.startswith("solve_ivp"):
                    setting = f"rtol {c['rtol']:.2e}" + (" (fastest)" if name == fast else "")
                elif "steps_per_delay" in c:
                    setting = f"h = T/{c['steps_per_delay']}" + (
                        f", rtol {c['rtol']:g}" if "rtol" in c else ""
                    )
                else:
                    setting = ""
                t = c["time"]
                ratio = ""
                if name in tg["ratios_fastest_solve_ivp_over"]:
                    rr = tg["ratios_fastest_solve_ivp_over"][name]
                    ratio = f"**{rr['cpu_min']:.1f}x** ({rr['cpu_median']:.1f}x)"
                lines.append(
                    f"| {rw['problem']} | {tg['target']:g} | {name} | {setting} | {c['error']:.2e} | "
                    f"{t['cpu_min_s'] * 1e3:.2f} | {t['cpu_median_s'] * 1e3:.2f} | {t['wall_min_s'] * 1e3:.2f} | {ratio} |"
                )
        lines.append("")
    lines += [
        f"Peak RSS of the benchmark process: {max(r['peak_rss_mb_after'] for r in res['rows']):.0f} MB.",
        "",
    ]
    return "\n".join(lines)


DOC = ROOT / "docs" / "time-domain.md"
BEGIN, END = (
    "<!-- bench_time: begin (generated from benchmarks/results/time.json) -->",
    "<!-- bench_time: end -->",
)


def docs_table(res: dict[str, Any]) -> str:
    """The summary of docs/time-domain.md section 9, from the JSON only."""
    lines = [
        f"Measured {res['date_utc'][:10]} by `benchmarks/bench_time.py` ({res['repeats']} interleaved repeats, one "
        f"BLAS thread, {res['cpu_count']} cores, 1-min load {res['load_1min_start']:.1f} at the start and "
        f"{res['load_1min_end']:.1f} at the end"
        + (": **loaded**, other jobs sharing the cores" if res["loaded"] else "")
        + f"; peak RSS {res['peak_rss_mb']:.0f} MB). CPU time, min (median) of the repeats; the ratio is the "
        "fastest `solve_ivp` method's CPU time over the contender's.",
        "",
        "| problem | error target | contender (setting) | its error | CPU, ms | fastest solve_ivp / it |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for rw in res["rows"]:
        for tg in rw["targets"]:
            fast = tg["fastest_solve_ivp"]
            for name in ("exponential (rtol)", "exponential (fixed h)", "newmark", fast):
                c = tg["contenders"][name]
                t = c["time"]
                if name.startswith("solve_ivp"):
                    setting, ratio = f"{name} (rtol {c['rtol']:.1e})", "1"
                else:
                    setting = f"{name} (h = T/{c['steps_per_delay']})"
                    rr = tg["ratios_fastest_solve_ivp_over"][name]
                    ratio = f"**{rr['cpu_min']:.1f}×** ({rr['cpu_median']:.1f}×)"
                lines.append(
                    f"| {rw['problem']} ({rw['coordinates']} DOF, T = {rw['delay_s']:g} s, {rw['window_s']:g} s) | "
                    f"{tg['target']:g} | {setting} | {c['error']:.1e} | {t['cpu_min_s'] * 1e3:.1f} "
                    f"({t['cpu_median_s'] * 1e3:.1f}) | {ratio} |"
                )
    return "\n".join(lines)


def update_docs(res: dict[str, Any]) -> None:
    text = DOC.read_text()
    if BEGIN not in text or END not in text:
        print(f"{DOC} has no {BEGIN} ... {END} region: not updated")
        return
    a, b = text.index(BEGIN) + len(BEGIN), text.index(END)
    DOC.write_text(text[:a] + "\n" + docs_table(res) + "\n" + text[b:])
    print(f"updated {DOC}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--rows", nargs="*", default=["turning_1dof", "shaper_36dof"])
    ap.add_argument("--markdown", action="store_true", help="only regenerate time.md from time.json")
    args = ap.parse_args()
    if args.markdown:
        res0 = json.loads(OUT.read_text())
        MD.write_text(markdown(res0))
        print(f"wrote {MD}")
        update_docs(res0)
        return
    import scipy

    l0 = load1()
    print(f"1-min load {l0:.2f} on {os.cpu_count()} cores" + (" LOADED" if l0 > 1 else ""))
    res: dict[str, Any] = {
        "benchmark": "bench_time", "date_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "chatterlab": chatterlab.__version__, "numpy": np.__version__, "scipy": scipy.__version__,
        "python": platform.python_version(), "cpu_count": os.cpu_count(), "repeats": args.repeats,
        "blas_threads": 1, "load_1min_start": l0, "rows": [],
    }  # fmt: skip
    makers = {"turning_1dof": turning, "shaper_36dof": shaper}
    with one_blas_thread():
        for name in args.rows:
            res["rows"].append(row(makers[name](), args.repeats))
    res["load_1min_end"] = load1()
    res["loaded"] = bool(l0 > 1 or res["load_1min_end"] > 1)
    res["peak_rss_mb"] = peak_rss_mb()
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(res, indent=2) + "\n")
    MD.write_text(markdown(res))
    update_docs(res)
    print(f"\n1-min load at the end {res['load_1min_end']:.2f}" + (" LOADED" if res["loaded"] else ""))
    print(f"peak RSS {res['peak_rss_mb']:.0f} MB; wrote {OUT} and {MD}")


if __name__ == "__main__":
    main()
