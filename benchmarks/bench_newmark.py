"""Benchmark of the time domain (chatterlab.time._simulate on chatterlab.time._newmark).

Run from the repository root::

    python benchmarks/bench_newmark.py           # everything (a few minutes on 2 cores)
    python benchmarks/bench_newmark.py --quick   # fewer repetitions and solvers

It prints, all measured in this run:

1. **throughput**: steps per second of ``simulate(shaper, feedback="pdo")`` --
   the traverse shaper (36 independent coordinates) with the slide moving
   through its stroke cycles (W(t), dW/dt, d2W/dt2), the cutting process on
   with all feedback terms and the delayed term -- at the default step, the
   paper's step and h = 1e-4 s; best and median of repeated runs, with the
   coefficient evaluation by per-segment polynomials (default) and directly,
   and with the integrator's worker threads on and off (target >= 20 000
   steps/s);
2. **accuracy against cost**, on the second pass (t = T .. T + 0.3 s: the
   cut entry at T + 0.1 s and the delayed term reading the first pass), the
   same equations A q'' + B q' + C q = p + G q(t - T) with the same A(t),
   B(t), C(t), G(t), p(t) and the same history: Newmark at several steps
   against ``scipy.integrate.solve_ivp`` on the first-order form (RK45,
   DOP853, LSODA, Radau with the exact Jacobian), the delayed term by the
   method of steps (the history is the dense first pass), each integrated
   piecewise between the coefficient jumps.  Errors are those of the
   contact-point displacements q1, q2 (rfe5.x, rfe5.y), max over time
   relative to their max, against DOP853 at rtol = 1e-10;
   the wall time each needs to reach 1 % and 0.1 % and the ratio (target >= 10x);
3. the **machine load** (1-minute load average, before and after) -- other
   jobs on the 2 cores slow everything down, and threads most.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

try:
    import chatterlab  # noqa: F401
except ImportError:  # run from a checkout without installing
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import chatterlab as cl
from chatterlab.process._kinematics import kinematics_for
from chatterlab.time._newmark import NewmarkOptions, newmark
from chatterlab.time._simulate import ParametricProblem, _blas_limits, _output_map, simulate

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "traverse_shaper" / "model.toml"


def load() -> str:
    a, b, c = os.getloadavg()
    return f"load average {a:.2f} {b:.2f} {c:.2f} on {os.cpu_count()} cores"


def throughput(system: cl.System, reps: int) -> None:
    print("\n1. throughput: simulate(shaper, feedback='pdo', passes=2), steps/s of the integration")
    print(
        f"   {'step h [s]':>12} {'coefficients':>12} {'workers':>7} {'steps':>7} {'best':>8} {'median':>8}  wall/run"
    )
    cases = [
        (None, "auto", 2),
        (None, "auto", 0),
        (None, "direct", 2),
        (1.4e-3, "auto", 2),
        (1e-4, "auto", 2),
    ]
    for step, method, workers in cases:
        rates, walls, n, h = [], [], 0, 0.0
        for _ in range(reps):
            t0 = time.perf_counter()
            sim = simulate(
                system,
                feedback="pdo",
                passes=2,
                step=step,
                method=method,
                options=NewmarkOptions(workers=workers),
            )
            walls.append(time.perf_counter() - t0)
            rates.append(sim.response.n_steps / sim.response.wall_time)
            n, h = sim.response.n_steps, sim.step
        print(
            f"   {h:12.4g} {method:>12} {workers:7d} {n:7d} {max(rates):8.0f} {statistics.median(rates):8.0f}"
            f"  {min(walls):.2f} s"
        )


def accuracy(system: cl.System, quick: bool) -> None:
    from scipy.integrate import solve_ivp
    from scipy.interpolate import CubicSpline

    kin = kinematics_for(system.model.process)
    T = kin.cycle
    prob = ParametricProblem(system, kin, width=0.002, terms="pdo")
    prob._t_end = 2 * T
    n = prob.n
    rows = np.vstack([_output_map(system, "rfe5.x"), _output_map(system, "rfe5.y")])
    with _blas_limits():
        first = newmark(prob, (0.0, T), kin.grid_unit / 2000)  # the first pass: the history
    hist = CubicSpline(first.t, first.q.T, axis=0)
    q0, v0 = first.q[:, -1], first.v[:, -1]
    t_a, t_b = T, T + 0.3
    pieces = [t_a, T + kin.events()[0], t_b]  # the coefficients jump at the cut entry
    print(
        f"\n2. accuracy against cost: t = {t_a:g} .. {t_b:g} s (second pass, cut entry at {pieces[1]:g} s, "
        f"the delayed term reading the first pass), {n} coordinates"
    )

    def outs(t: np.ndarray, q: np.ndarray) -> np.ndarray:
        return np.einsum("mkn,nm->km", prob.maps(t, rows), q)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        A, B, C, G = prob.matrices(np.array([t]))
        F = prob.force(np.array([t]))[0]
        q, v = y[:n], y[n:]
        r = F - B[0] @ v - C[0] @ q + G[0] @ hist(t - T)
        return np.concatenate([v, np.linalg.solve(A[0], r)])

    def jac(t: float, y: np.ndarray) -> np.ndarray:
        A, B, C, _ = prob.matrices(np.array([t]))
        Ai = np.linalg.inv(A[0])
        return np.block([[np.zeros((n, n)), np.eye(n)], [-Ai @ C[0], -Ai @ B[0]]])

    def ivp(method: str, rtol: float) -> tuple[list, float, int]:
        """solve_ivp piecewise between the coefficient jumps; the dense
        solutions, the wall time and the number of coefficient evaluations
        (right-hand sides and Jacobians)."""
        t0 = time.perf_counter()
        y = np.concatenate([q0, v0])
        sols, nfev = [], 0
        with _blas_limits():
            for a, b in zip(pieces[:-1], pieces[1:], strict=True):
                kw = {"jac": jac} if method in ("Radau", "BDF", "LSODA") else {}
                s = solve_ivp(
                    rhs, (a, b), y, method=method, rtol=rtol, atol=rtol * 1e-6, dense_output=True, **kw
                )
                if not s.success:
                    raise RuntimeError(f"{method}: {s.message}")
                nfev += s.nfev + int(getattr(s, "njev", 0) or 0)  # Jacobians evaluate the coefficients too
                y = s.y[:, -1]
                sols.append(s.sol)
        return sols, time.perf_counter() - t0, nfev

    def dense(sols: list, t: np.ndarray) -> np.ndarray:
        idx = np.clip(np.searchsorted(pieces, t, side="right") - 1, 0, len(sols) - 1)
        q = np.empty((n, t.size))
        for j, sol in enumerate(sols):
            sel = idx == j
            if sel.any():
                q[:, sel] = sol(t[sel])[:n]
        return outs(t, q)

    ref, w_ref, nf_ref = ivp("DOP853", 1e-10)
    scale = np.abs(dense(ref, np.linspace(t_a, t_b, 6001))).max(axis=1)
    print(f"   reference: DOP853, rtol 1e-10: {w_ref:.1f} s, {nf_ref} evaluations")

    def err(t: np.ndarray, y: np.ndarray) -> float:
        """max over time of |q_k - q_k,ref| / max |q_k,ref|, worst of q1, q2 (at the same times)."""
        return float(np.max(np.abs(y - dense(ref, t)).max(axis=1) / scale))

    rows_nm = []
    print(f"   {'method':>10} {'h or rtol':>10} {'error':>9} {'wall [s]':>9} {'steps/evals':>11}")
    ks = (100, 200, 493, 1000, 2000, 4000, 8000) if not quick else (493, 1000, 2000, 4000)
    for k in ks:
        h = kin.grid_unit / k
        best = np.inf
        for _ in range(2):
            t0 = time.perf_counter()
            with _blas_limits():
                r = newmark(prob, (t_a, t_b), h, q0, v0, history=lambda t: hist(t))
            best = min(best, time.perf_counter() - t0)
        e = err(r.t, outs(r.t, r.q))
        rows_nm.append((h, e, best))
        print(f"   {'Newmark':>10} {h:10.3g} {e:9.2e} {best:9.3f} {r.n_steps:11d}")
    rows_ivp = []
    methods = ("RK45", "DOP853", "LSODA", "Radau") if not quick else ("RK45", "LSODA")
    t_eval = np.linspace(t_a, t_b, 3001)
    for method in methods:
        for rtol in (1e-3, 1e-5):
            sols, wall, nfev = ivp(method, rtol)
            e = err(t_eval, dense(sols, t_eval))
            rows_ivp.append((method, rtol, e, wall, nfev))
            print(f"   {method:>10} {rtol:10.0e} {e:9.2e} {wall:9.2f} {nfev:11d}")
    # the cost of one right-hand side, and how much of it is the coefficient evaluation
    y0 = np.concatenate([q0, v0])
    tt = t_a + 1e-4 * np.arange(300) + 1e-7
    t0 = time.perf_counter()
    with _blas_limits():
        for t in tt:
            rhs(float(t), y0)
    per = (time.perf_counter() - t0) / tt.size
    t0 = time.perf_counter()
    for t in tt:
        prob.matrices(np.array([t]))
        prob.force(np.array([t]))
    coef = (time.perf_counter() - t0) / tt.size
    print(
        f"   one solve_ivp right-hand side: {per * 1e6:.0f} us, of which {coef * 1e6:.0f} us evaluate the "
        "coefficients at one t (Newmark evaluates a chunk of steps at once)"
    )
    print(
        "   cost to reach a given accuracy (Newmark: the cheapest step meeting it; solve_ivp: the fastest run):"
    )
    for target in (1e-2, 1e-3):
        nm = [w for h, e, w in rows_nm if e <= target]
        iv = [(w, m, rt, nf) for m, rt, e, w, nf in rows_ivp if e <= target]
        if not nm or not iv:
            print(f"   error <= {target:.0e}: not reached by both")
            continue
        w_nm = min(nm)
        w_iv, m_iv, rt_iv, nf_iv = min(iv)
        bare = max(w_iv - nf_iv * coef, 1e-9)
        print(
            f"   error <= {target:.0e}: Newmark {w_nm:.3f} s, solve_ivp {w_iv:.2f} s ({m_iv}, rtol {rt_iv:.0e}):"
            f" ratio {w_iv / w_nm:.1f}x; without solve_ivp's coefficient evaluations ({nf_iv} x"
            f" {coef * 1e6:.0f} us) {bare:.2f} s: ratio {bare / w_nm:.1f}x"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    print(f"before: {load()}")
    system = cl.assemble(cl.load_model(MODEL))
    simulate(system, feedback="pdo", duration=0.05)  # warm-up (imports, modes)
    throughput(system, reps=2 if args.quick else 5)
    accuracy(system, args.quick)
    print(f"\nafter: {load()}")


if __name__ == "__main__":
    main()
