"""The milling rows of issue 26, measured: the Floquet lobes against a plain
numpy semi-discretisation, and an FE-scale end mill without hand reduction.

Run from the repository root::

    python benchmarks/bench_milling.py                   # label "current", 5 interleaved repeats
    python benchmarks/bench_milling.py --label before    # e.g. with PYTHONPATH at an older checkout
    python benchmarks/bench_milling.py --table-only      # regenerate milling.md from milling.json

**Row 1, the lobes.**  The 1-DOF benchmark of Insperger & Stepan
(``studies/milling/benchmark_1dof.toml``: N = 2, K_t = 6e8, K_n = 2e8 N/m^2,
922 Hz, zeta = 0.011, m = 0.03993 kg, down-milling) at a_e/D = 0.05 and 1,
201 speeds 5000-25000 rpm, depths to 10 mm, the loop read from the model
file (``milling_loop_of(assemble(load_model(path)).at())``, the immersion
set in the file's text).  Two routes, timed interleaved (a, b, a, b, ...),
``--repeat`` times each, every route with one BLAS thread:

a. chatterlab: ``milling_lobes(loop, rpm, depth_max=0.01, **SETTINGS)``, the
   spectral elements with the complete depth search.  ``SETTINGS`` is the
   1e-6 setting: ``rtol=1e-7``, so that every limit's convergence check must
   confirm it to ``10 rtol`` = 1e-6 relative (the engine refines the mesh of
   any speed where it does not; ``target_rtol`` in the diagram's meta) and
   the root is located to 1e-7;
b. the competitor, :class:`PlainSDM` below: what a competent numpy user
   writes from Insperger & Stepan (2004): first-order semi-discretisation with
   m = 40 steps per period, the step matrices of all steps by one batched
   ``scipy.linalg.expm`` of the 6 x 6 Van Loan blocks (states scaled so that
   the exponent's norm is ~omega dt), the coefficients' exact means over each
   step in closed form, the monodromy built by updating its two top rows and
   shifting the history rows (no dense (m+2)^2 products), ``numpy.linalg.eigvals``;
   and the same depth search as chatterlab's scan route (40 depths up to the
   first one with spectral radius >= 1, then Brent's method to rtol 1e-4,
   far below its own error).

And how the SDM's accuracy buys time: its limits at m = 40, 80, 160 and 320
at three speeds, each error against the reference and each search's CPU
time, measured, with the fitted order of the error in m (nothing beyond
m = 320 is claimed: the steps 1e-6 would take are not run).

Accuracy: both against a reference computed in the same run, chatterlab's
spectral method at an explicit degree 24 on elements with omega L <= 5 and
rtol 1e-11 (its own convergence check is recorded), at **all** 201 speeds:
the largest and median relative error of a_lim.  Times: min and median of
the wall clock and of the process's CPU time (the machine is shared:
``/proc/loadavg`` before and after).  Memory: the process's peak RSS after
each row.

**Row 2, the FE tool.**  ``studies/milling/tool_cantilever.toml`` with its
carbide beam cut into 100 Timoshenko elements (302 coordinates), its loop
unreduced, at 5000/10000/15000/20000/25000 rpm and a_e/D = 0.05, 0.5 and 1:
``milling_lobes(loop, [rpm])`` per speed with its defaults (the depth ceiling
from the problem: three times the zeroth-order limit), timed once each (a
per-speed cost, goal <= 10 s), with the result's basis, error estimate and
what the engine split.  A refusal (an ``InputError``, as 0.2.0 gives) is
recorded as such.

Results go to ``benchmarks/results/milling.json`` under ``runs[<label>]``
(other labels are kept) and ``benchmarks/results/milling.md`` is generated
from it.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.linalg as sla  # noqa: E402
from scipy.optimize import brentq  # noqa: E402

try:
    import chatterlab as cl
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    import chatterlab as cl

from _common import loadavg_text as loadavg
from _common import peak_rss_mb, source_commit, stats

ROOT = Path(__file__).resolve().parents[1]
ONE_DOF = ROOT / "studies" / "milling" / "benchmark_1dof.toml"
TOOL = ROOT / "studies" / "milling" / "tool_cantilever.toml"
OUT = ROOT / "benchmarks" / "results" / "milling.json"
TABLE = ROOT / "benchmarks" / "results" / "milling.md"
IMMERSIONS = (0.05, 1.0)
DEPTH_MAX = 0.01
#: chatterlab's 1e-6 setting (see the module docstring)
SETTINGS: dict[str, Any] = {"rtol": 1e-7}
#: the reference: an explicit degree 24 on elements with omega L <= 5 (the 0.2.0 mesh, independent of
#: the automatic degrees), rtol 1e-11
REFERENCE: dict[str, Any] = {"degree": 24, "rtol": 1e-11}
SDM_STEPS = 40
SDM_RTOL = 1e-4
GOAL = 10.0  #: issue 26: chatterlab at least this many times faster than the plain SDM
FE_ELEMENTS = 100
FE_RPM = (5000.0, 10000.0, 15000.0, 20000.0, 25000.0)
FE_IMMERSIONS = (0.05, 0.5, 1.0)
FE_GOAL_S = 10.0


# ============================================================================ the machine


# ============================================================================ the problem
def one_dof_loop(immersion: float) -> Any:
    """The benchmark's loop from its model file, the immersion set in the text."""
    from chatterlab.lobes import milling_loop_of

    text = ONE_DOF.read_text()
    text, n = re.subn(
        r"^radial_immersion = [0-9.e+-]+", f"radial_immersion = {immersion!r}", text, flags=re.M
    )
    assert n == 1, "the model file's radial_immersion line moved"
    return milling_loop_of(cl.assemble(cl.loads_model(text)).at())


def fe_loop(immersion: float, elements: int = FE_ELEMENTS) -> Any:
    """The cantilever end mill with its beam cut into ``elements`` parts, unreduced."""
    from chatterlab.lobes import milling_loop_of

    text = TOOL.read_text()
    text, n = re.subn(r"^elements = \d+", f"elements = {elements}", text, flags=re.M)
    text, m = re.subn(
        r"^radial_immersion = [0-9.e+-]+", f"radial_immersion = {immersion!r}", text, flags=re.M
    )
    assert n == 1 and m == 1, "the tool file's elements/radial_immersion lines moved"
    return milling_loop_of(cl.assemble(cl.loads_model(text)).at())


# ============================================================================ the competitor
class PlainSDM:
    """First-order semi-discretisation of a 1-DOF milling tool (Insperger &
    Stepan, Int. J. Numer. Meth. Engng 61 (2004) 117-141), written as a
    competent numpy user would: m x'' + c x' + k x = -a_p h(t) (x(t) - x(t - tau)),
    tau = T the tooth period, h(t) = sum_j g_j sin phi_j (K_t cos phi_j + K_n sin phi_j).

    Per speed the exact means h_i of h over the m steps (closed form); per
    depth the m step exponentials in one batched ``expm`` (Van Loan: e^{A dt}
    and the two integrals of the linear interpolation of the delayed term),
    the monodromy by its top rows and a shift, its eigenvalues by LAPACK."""

    def __init__(self, mass: float, damping: float, stiffness: float, milling: Any, rpm: float, steps: int):
        self.mass, self.steps = mass, steps
        self.w = np.sqrt(stiffness / mass)
        self.c = damping / mass
        teeth = milling.teeth
        T = 60.0 / (rpm * teeth)
        self.dt = T / steps
        t = np.arange(steps + 1) * self.dt
        self.h = self._h_mean(t[:-1], t[1:], 2 * np.pi * rpm / 60.0, teeth, milling)

    @staticmethod
    def _h_mean(t0: np.ndarray, t1: np.ndarray, Om: float, teeth: int, milling: Any) -> np.ndarray:
        st, ex = milling.entry, milling.exit  # the cut arc (down-milling: arccos(2 a_e/D - 1) to pi)
        Kt, Kn = milling.Kt, milling.Kn

        def F(ph: np.ndarray) -> np.ndarray:  # an antiderivative of sin(ph) (Kt cos ph + Kn sin ph)
            return Kt * np.sin(ph) ** 2 / 2 + Kn * (ph / 2 - np.sin(2 * ph) / 4)

        tot = np.zeros_like(t0)
        for j in range(teeth):
            p0, p1 = Om * t0 - 2 * np.pi * j / teeth, Om * t1 - 2 * np.pi * j / teeth
            for k in (-1, 0, 1):  # the cut arc [st, ex] shifted by whole turns
                lo, hi = np.maximum(p0, st + 2 * np.pi * k), np.minimum(p1, ex + 2 * np.pi * k)
                ok = hi > lo
                tot += np.where(
                    ok,
                    F(np.where(ok, hi, 0.0) - 2 * np.pi * k) - F(np.where(ok, lo, 0.0) - 2 * np.pi * k),
                    0.0,
                )
        return tot / (Om * (t1 - t0))

    def monodromy(self, a: float) -> np.ndarray:
        m, dt, w = self.steps, self.dt, self.w
        kc = a * self.h / self.mass  # (m,) cutting stiffness per unit mass on each step
        # states (x, v / w): the exponent's norm is ~ w dt instead of w^2 dt
        Z = np.zeros((m, 6, 6))
        Z[:, 0, 1] = w
        Z[:, 1, 0] = -(w * w + kc) / w
        Z[:, 1, 1] = -self.c
        Z[:, 0, 2] = Z[:, 1, 3] = Z[:, 2, 4] = Z[:, 3, 5] = 1.0
        E = sla.expm(Z * dt)
        P, F1, F2 = E[:, :2, :2], E[:, :2, 2:4], E[:, :2, 4:]
        b = kc / w  # the delayed term's input, in the scaled velocity row
        c0 = (F1[:, :, 1] - F2[:, :, 1] / dt) * b[:, None]  # weight of x_{i-m}
        c1 = (F2[:, :, 1] / dt) * b[:, None]  # weight of x_{i-m+1}
        D = m + 2
        Phi = np.eye(D)  # rows: x_i, v_i / w, x_{i-1}, ..., x_{i-m}
        for i in range(m):
            top = P[i] @ Phi[:2] + np.outer(c0[i], Phi[D - 1]) + np.outer(c1[i], Phi[D - 2])
            Phi = np.vstack([top, Phi[:1], Phi[2 : D - 1]])
        return Phi

    def radius(self, a: float) -> float:
        return float(np.max(np.abs(np.linalg.eigvals(self.monodromy(a)))))


def sdm_limit(sdm: PlainSDM, depth_max: float, scan: int, rtol: float) -> float:
    """chatterlab's scan route with the SDM's spectral radius: the first of
    ``scan`` depths where rho >= 1, refined by Brent's method; inf if none."""
    prev = 1e-12 * depth_max
    for a in depth_max * np.arange(1, scan + 1) / scan:
        if sdm.radius(float(a)) >= 1.0:
            return float(
                brentq(lambda x: sdm.radius(x) - 1.0, prev, a, xtol=rtol * prev, rtol=4 * np.finfo(float).eps)
            )
        prev = float(a)
    return float("inf")


def sdm_lobes(loop: Any, rpm: np.ndarray) -> np.ndarray:
    M, C, K = (float(np.asarray(X)[0, 0]) for X in (loop.M, loop.C, loop.K))
    assert loop.n == 1, "the plain SDM is written for the 1-DOF benchmark"
    return np.array(
        [
            sdm_limit(PlainSDM(M, C, K, loop.milling, float(r), SDM_STEPS), DEPTH_MAX, 40, SDM_RTOL)
            for r in rpm
        ]
    )


# ============================================================================ row 1
def relerr(x: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """|x - ref| / ref, 0 where both are inf (stable to the ceiling), inf where one is."""
    both = ~np.isfinite(x) & ~np.isfinite(ref)
    with np.errstate(invalid="ignore"):
        e = np.abs(x - ref) / ref
    e[both] = 0.0
    e[np.isfinite(x) != np.isfinite(ref)] = np.inf
    return e


def reference(loop: Any, rpm: np.ndarray) -> Any:
    from chatterlab.lobes import milling_lobes

    return milling_lobes(loop, rpm, depth_max=DEPTH_MAX, **REFERENCE)


def row_lobes(repeat: int, n_speeds: int) -> dict[str, Any]:
    from threadpoolctl import threadpool_limits

    from chatterlab.lobes import milling_lobes

    rpm = np.linspace(5000.0, 25000.0, n_speeds)
    out: dict[str, Any] = {}
    with threadpool_limits(limits=1, user_api="blas"):
        for imm in IMMERSIONS:
            loop = one_dof_loop(imm)
            routes: dict[str, Callable[[], Any]] = {
                "chatterlab": lambda loop=loop: milling_lobes(loop, rpm, depth_max=DEPTH_MAX, **SETTINGS),
                "sdm": lambda loop=loop: sdm_lobes(loop, rpm),
            }
            res = {k: f() for k, f in routes.items()}  # warm-up
            wall: dict[str, list[float]] = {k: [] for k in routes}
            cpu: dict[str, list[float]] = {k: [] for k in routes}
            load_before = loadavg()
            for _ in range(repeat):
                for k, f in routes.items():
                    c, t = time.process_time(), time.perf_counter()
                    res[k] = f()
                    wall[k].append(time.perf_counter() - t)
                    cpu[k].append(time.process_time() - c)
            load_after = loadavg()
            t = time.perf_counter()
            ref = reference(loop, rpm)
            t_ref = time.perf_counter() - t
            equal = sdm_at_equal_accuracy(loop, ref, rpm, np.asarray(res["chatterlab"].a_lim))
            d = res["chatterlab"]
            e_cl, e_sd = relerr(np.asarray(d.a_lim), ref.a_lim), relerr(res["sdm"], ref.a_lim)
            with np.errstate(invalid="ignore", divide="ignore"):
                est = np.asarray(d.error) / np.asarray(d.a_lim)
                ref_est = np.asarray(ref.error) / np.asarray(ref.a_lim)
            s_cl, s_sd = (
                stats(wall["chatterlab"], cpu["chatterlab"], wall_key="wall_s"),
                stats(wall["sdm"], cpu["sdm"], wall_key="wall_s"),
            )
            out[f"{imm:g}"] = {
                "immersion": imm,
                "speeds": n_speeds,
                "chatterlab": {
                    **s_cl,
                    "settings": SETTINGS,
                    "resolution": d.resolution,
                    "evaluations": int(d.evaluations),
                    "meta": {k: v for k, v in d.meta.items() if isinstance(v, (int, float, str))},
                    "basis": {
                        b: int(np.sum(np.asarray(d.basis) == b)) for b in sorted(set(map(str, d.basis)))
                    },
                    "kinds": {b: int(np.sum(np.asarray(d.kind) == b)) for b in sorted(set(map(str, d.kind)))},
                    "error_max_rel": float(np.max(e_cl)),
                    "error_median_rel": float(np.median(e_cl)),
                    "own_estimate_max_rel": float(np.nanmax(np.where(np.isfinite(est), est, np.nan))),
                    "a_lim_m": [float(x) for x in d.a_lim],
                },
                "sdm": {
                    **s_sd,
                    "steps": SDM_STEPS,
                    "rtol": SDM_RTOL,
                    "error_max_rel": float(np.max(e_sd)),
                    "error_median_rel": float(np.median(e_sd)),
                    "a_lim_m": [float(x) for x in res["sdm"]],
                },
                "reference": {
                    **REFERENCE,
                    "time_s": t_ref,
                    "own_estimate_max_rel": float(np.nanmax(np.where(np.isfinite(ref_est), ref_est, np.nan))),
                    "a_lim_m": [float(x) for x in ref.a_lim],
                    "kind": [str(x) for x in ref.kind],
                },
                "sdm_at_equal_accuracy": equal,
                "ratio_sdm_over_chatterlab": {
                    "min": s_sd["min_s"] / s_cl["min_s"],
                    "median": s_sd["median_s"] / s_cl["median_s"],
                    "cpu_min": s_sd["cpu_min_s"] / s_cl["cpu_min_s"],
                },
                "load_before": load_before,
                "load_after": load_after,
                "peak_rss_mb": peak_rss_mb(),
            }
            r = out[f"{imm:g}"]
            print(
                f"a_e/D = {imm:g}: chatterlab {s_cl['min_s']:.2f} / {s_cl['median_s']:.2f} s (CPU {s_cl['cpu_min_s']:.2f}),"
                f" SDM {s_sd['min_s']:.2f} / {s_sd['median_s']:.2f} s (CPU {s_sd['cpu_min_s']:.2f}):"
                f" {r['ratio_sdm_over_chatterlab']['min']:.2f}x min, {r['ratio_sdm_over_chatterlab']['median']:.2f}x median;"
                f" errors max {r['chatterlab']['error_max_rel']:.1e} vs {r['sdm']['error_max_rel']:.1e}"
                f" (reference {t_ref:.0f} s, own estimate {r['reference']['own_estimate_max_rel']:.1e});"
                f" load {load_before.split()[0]} -> {load_after.split()[0]}, RSS {r['peak_rss_mb']:.0f} MB",
                flush=True,
            )
    return out


def sdm_at_equal_accuracy(loop: Any, ref: Any, rpm_all: np.ndarray, a_cl: np.ndarray) -> dict[str, Any]:
    """The plain SDM's accuracy against its cost: at three speeds, its limits with m = 40, 80,
    160, 320 steps (Brent to rtol 1e-9, below its error), their error against the reference,
    each search's CPU time (all measured), and the fitted order of the error in m."""
    out: dict[str, Any] = {"speeds": []}
    M, C, K = (float(np.asarray(X)[0, 0]) for X in (loop.M, loop.C, loop.K))
    steps = np.array([40, 80, 160, 320])
    for r in (5000.0, 12000.0, 20000.0):
        i = int(np.argmin(np.abs(rpm_all - r)))
        a_ref = float(ref.a_lim[i])
        if not np.isfinite(a_ref):
            continue
        errs, cpus = [], []
        for m in steps:
            c = time.process_time()
            a = sdm_limit(PlainSDM(M, C, K, loop.milling, float(rpm_all[i]), int(m)), DEPTH_MAX, 40, 1e-9)
            cpus.append(time.process_time() - c)
            errs.append(abs(a - a_ref) / a_ref)
        q = -np.polyfit(np.log(steps[1:]), np.log(errs[1:]), 1)[0]  # error ~ m^-q (the asymptotic pairs)
        out["speeds"].append(
            {
                "rpm": float(rpm_all[i]),
                "steps": steps.tolist(),
                "error_rel": errs,
                "cpu_s": cpus,
                "order": float(q),
                "chatterlab_error_rel": float(abs(a_cl[i] - a_ref) / a_ref),
            }
        )
    return out


# ============================================================================ row 2
def row_fe(depth_max: float | None) -> dict[str, Any]:
    from threadpoolctl import threadpool_limits

    from chatterlab.errors import InputError
    from chatterlab.lobes import milling_lobes

    out: dict[str, Any] = {"elements": FE_ELEMENTS, "depth_max": depth_max, "cases": []}
    with threadpool_limits(limits=1, user_api="blas"):
        for imm in FE_IMMERSIONS:
            loop = fe_loop(imm)
            out["n"] = int(loop.n)
            for rpm in FE_RPM:
                load = loadavg()
                c, t = time.process_time(), time.perf_counter()
                case: dict[str, Any] = {"immersion": imm, "rpm": rpm, "load": load}
                try:
                    d = milling_lobes(loop, np.array([rpm]), depth_max=depth_max)
                except InputError as exc:
                    case.update(status="refused", message=str(exc))
                else:
                    case.update(
                        status="ok",
                        a_lim_m=float(d.a_lim[0]),
                        kind=str(d.kind[0]),
                        basis=str(d.basis[0]),
                        error_m=float(d.error[0]),
                        resolution=d.resolution,
                        meta={k: v for k, v in d.meta.items() if isinstance(v, (int, float, str))},
                    )
                case.update(
                    wall_s=time.perf_counter() - t, cpu_s=time.process_time() - c, peak_rss_mb=peak_rss_mb()
                )
                out["cases"].append(case)
                shown = (
                    f"a_lim {case['a_lim_m'] * 1e3:.6g} mm {case['kind']} ({case['basis']}, error {case['error_m']:.1e} m)"
                    if case["status"] == "ok"
                    else "refused: " + case["message"][:90]
                )
                print(
                    f"FE tool {loop.n} DOF, a_e/D {imm:g}, {rpm:g} rpm: {case['wall_s']:.2f} s, {shown}",
                    flush=True,
                )
    return out


# ============================================================================ the table
def table(data: dict[str, Any]) -> str:
    lines = [
        "# Milling rows of issue 26: Floquet lobes against a plain numpy SDM, and an FE-scale tool",
        "",
        "Generated by `python benchmarks/bench_milling.py` from `benchmarks/results/milling.json`; do not edit.",
        "",
        "Row 1: the 1-DOF benchmark (`studies/milling/benchmark_1dof.toml`), 201 speeds 5000-25000 rpm, depths"
        " to 10 mm, one BLAS thread, interleaved repeats. *chatterlab* is `milling_lobes(..., rtol=1e-7)` (every"
        " limit's convergence check must confirm 1e-6 relative); *SDM* is the plain numpy first-order"
        " semi-discretisation written in the benchmark (m = 40, the same scan and Brent search, rtol 1e-4). Errors"
        " are against the spectral reference (degree 24, omega L <= 5, rtol 1e-11) at all 201 speeds. The ratio"
        " is SDM time / chatterlab time within one run (goal >= 10).",
        "",
        "| run | commit | a_e/D | repeats | chatterlab min / median s (CPU min) | SDM min / median s (CPU min)"
        " | ratio min, median (CPU min) | chatterlab error max / median | SDM error max / median | chatterlab"
        " evaluations | load before -> after | peak RSS MB |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for label, run in data.get("runs", {}).items():
        for key, r in run.get("lobes", {}).items():
            c, s, q = r["chatterlab"], r["sdm"], r["ratio_sdm_over_chatterlab"]
            lines.append(
                f"| {label} | {run['commit']} | {key} | {run['repeat']} | {c['min_s']:.2f} / {c['median_s']:.2f}"
                f" ({c['cpu_min_s']:.2f}) | {s['min_s']:.2f} / {s['median_s']:.2f} ({s['cpu_min_s']:.2f})"
                f" | {q['min']:.2f}x, {q['median']:.2f}x ({q['cpu_min']:.2f}x)"
                f" | {c['error_max_rel']:.1e} / {c['error_median_rel']:.1e} | {s['error_max_rel']:.1e} /"
                f" {s['error_median_rel']:.1e} | {c['evaluations']} | {r['load_before'].split()[0]} ->"
                f" {r['load_after'].split()[0]} | {r['peak_rss_mb']:.0f} |"
            )
    lines += [
        "",
        "The plain SDM's accuracy against its cost at three speeds (its limits at m = 40..320 steps against the"
        " reference, each search's CPU time, all measured; the fitted order of its error in m; chatterlab's error"
        " at the same speed and its CPU per speed, the min run's time over the 201 speeds):",
        "",
        "| run | a_e/D | rpm | SDM error at m = 40, 80, 160, 320 | order | SDM CPU s at m = 40, 80, 160, 320"
        " | chatterlab error | chatterlab CPU s per speed (mean) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for label, run in data.get("runs", {}).items():
        for key, r in run.get("lobes", {}).items():
            eq = r.get("sdm_at_equal_accuracy")
            if not eq:
                continue
            per = r["chatterlab"]["cpu_min_s"] / r["speeds"]
            for e in eq["speeds"]:
                errs = ", ".join(f"{x:.1e}" for x in e["error_rel"])
                lines.append(
                    f"| {label} | {key} | {e['rpm']:g} | {errs} | {e['order']:.2f}"
                    f" | {', '.join(f'{c:.3g}' for c in e['cpu_s'])} | {e.get('chatterlab_error_rel', float('nan')):.1e}"
                    f" | {per:.3g} |"
                )
    lines += [
        "",
        "Load: 1-minute /proc/loadavg on a 2-core machine shared with other work; CPU is the process's CPU time.",
        "",
        "Row 2: the cantilever end mill (`studies/milling/tool_cantilever.toml`, its beam in"
        f" {FE_ELEMENTS} Timoshenko elements), unreduced, one `milling_lobes` call per speed with its defaults"
        " (goal <= 10 s; the ceiling is the problem's own, three times the zeroth-order limit).",
        "",
        "| run | commit | DOF | a_e/D | rpm | status | wall s (CPU) | a_lim mm | kind | basis | error estimate"
        " (relative) | peak RSS MB |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for label, run in data.get("runs", {}).items():
        fe = run.get("fe")
        if not fe:
            continue
        for c in fe["cases"]:
            if c["status"] == "ok":
                a = c["a_lim_m"]
                rel = c["error_m"] / a if np.isfinite(a) and a else float("nan")
                res = f"{a * 1e3:.6g} | {c['kind']} | {c['basis']} | {rel:.1e}"
            else:
                res = "— | — | — | —"
            lines.append(
                f"| {label} | {run['commit']} | {fe.get('n', '')} | {c['immersion']:g} | {c['rpm']:g} | {c['status']}"
                f" | {c['wall_s']:.2f} ({c['cpu_s']:.2f}) | {res} | {c['peak_rss_mb']:.0f} |"
            )
    notes = [f"- {label}: {run['note']}" for label, run in data.get("runs", {}).items() if run.get("note")]
    return "\n".join(lines + ([""] + notes if notes else [])) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--label", default="current", help="the run's name in milling.json (before, after, ...)")
    ap.add_argument("--repeat", type=int, default=5, help="interleaved repeats of row 1 (default 5)")
    ap.add_argument("--speeds", type=int, default=201, help="speeds of row 1 (default 201)")
    ap.add_argument("--rows", default="lobes,fe", help="rows to run: lobes, fe (comma-separated)")
    ap.add_argument(
        "--fe-depth-max",
        type=float,
        default=None,
        help="depth ceiling of row 2, m (default: the problem's own)",
    )
    ap.add_argument("--note", default="", help="a note stored with the run")
    ap.add_argument("--table-only", action="store_true", help="regenerate milling.md from milling.json")
    args = ap.parse_args()
    data = json.loads(OUT.read_text()) if OUT.exists() else {"runs": {}}
    if not args.table_only:
        rows = set(args.rows.split(","))
        run: dict[str, Any] = {
            "commit": source_commit(),
            "chatterlab": cl.__version__,
            "machine": platform.platform(),
            "cpus": os.cpu_count(),
            "repeat": args.repeat,
            "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
            "note": args.note,
        }
        print(f"chatterlab {run['commit']} ({cl.__file__}); load {loadavg()}", flush=True)
        if "lobes" in rows:
            run["lobes"] = row_lobes(args.repeat, args.speeds)
        if "fe" in rows:
            run["fe"] = row_fe(args.fe_depth_max)
        run["peak_rss_mb"] = peak_rss_mb()
        data.setdefault("runs", {})[args.label] = run
        OUT.parent.mkdir(parents=True, exist_ok=True)
        OUT.write_text(json.dumps(data, indent=1) + "\n")
        print(f"wrote {OUT.relative_to(ROOT)}")
    TABLE.write_text(table(data))
    print(f"wrote {TABLE.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
