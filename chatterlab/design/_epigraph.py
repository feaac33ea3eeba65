"""Maximising the minimum chatter-free width: the candidates of the min and
the epigraph form solved by SQP -- shared by the absorber tuning
(:mod:`chatterlab.design._absorber`) and the active-damper co-design
(:mod:`chatterlab.design._active`).

The minimum of b_lim over a speed range (or over all speeds) is the lowest
of a few smooth functions of the design -- the bottoms of the boundary's
branches that the lobes show and, over a range, the limits at its ends
(:func:`candidate_points`) -- so at an optimum two or more of them are equal
and the minimum has a kink.  The problem

    maximise  min_i b_i(x)   subject to  c_j(x) >= 0,  x in the unit box,     (1)

is solved in its epigraph form, maximise t subject to b_i(x) >= t and
c_j(x) >= 0, by sequential quadratic programming (SLSQP [1]) with the exact
gradients of every b_i (:meth:`chatterlab.design.CriticalPoint.derivative`)
and of the c_j.

References
----------
.. [1] D. Kraft, *A software package for sequential quadratic programming*,
   DFVLR-FB 88-28, 1988 (SLSQP, as in scipy.optimize).
.. [2] J. Nocedal, S. J. Wright, *Numerical Optimization*, 2nd ed.,
   Springer, 2006, ch. 18 (SQP) and sec. 12.8 (sensitivity of an optimum).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ._critical import CriticalPoint, at_delay
from ._limits import limits_of, lobe_bottoms

__all__ = [
    "CANDIDATES",
    "candidate_points",
    "in_range",
    "solve_epigraph",
    "check_starts",
    "check_bound",
    "start_points",
    "best_start",
    "starts_line",
]

CANDIDATES = 3  #: the lowest candidates held by the constraints b_i >= t


def candidate_points(d: Any, L: Any, objective: str) -> list[CriticalPoint]:
    """The smooth pieces whose minimum is the objective: the branch bottoms the
    lobes show (and the range ends, for the minimum over a range)."""
    lim = limits_of(d, L, speeds=False)
    cps = list(lobe_bottoms(d, L))
    extra = [lim.absolute] if objective == "absolute" else [lim.minimum]
    T = np.asarray(d.delay)
    if objective == "minimum":
        b, f = np.asarray(d.b_lim), np.asarray(d.chatter_hz)
        for j in (int(np.argmin(T)), int(np.argmax(T))):
            if np.isfinite(b[j]) and f[j] > 0:
                extra.append(at_delay(L, T[j], b[j], 2 * np.pi * f[j], j))
    for cp in extra:
        if cp is not None and not any(
            abs(c.w - cp.w) <= 1e-7 * max(cp.w, 1.0) and abs(c.b - cp.b) <= 1e-9 * cp.b for c in cps
        ):
            cps.append(cp)
    if objective == "minimum":  # a bottom outside the range is not a candidate: keep those the range holds
        cps = [c for c in cps if c.kind != "bottom" or in_range(c, T)]
    return cps


def in_range(cp: CriticalPoint, T: np.ndarray) -> bool:
    """Some lobe k of the bottom's branch has its bottom at a delay in [T.min(), T.max()]."""
    phi = -np.angle(cp.z)  # w T = phi + 2 pi k
    lo, hi = float(T.min()) * cp.w, float(T.max()) * cp.w
    k = math.ceil((lo - phi) / (2 * math.pi))
    return bool(phi + 2 * math.pi * k <= hi)


def solve_epigraph(
    prob: Any,
    u0: np.ndarray,
    extra: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None,
    t_min: float = 0.0,
) -> tuple[np.ndarray, float, int]:
    """SLSQP on the epigraph form of (1) in the unit box, from ``u0``.

    ``prob.candidates(u)`` gives the lowest candidate limits (m) and their
    gradients in u, ``prob.scale`` the objective's scale (m); ``extra(u)``,
    optional, the values and gradients of further constraints c_j(u) >= 0
    (each of order 1); ``t_min`` (m) a lower bound of the objective (a design
    width the result must exceed).  Returns the best design, its objective
    (m) and the iterations."""
    from scipy.optimize import minimize

    s = prob.scale
    vals0, _ = prob.candidates(u0)
    y0 = np.r_[u0, max(vals0[0], t_min) / s]
    n = u0.size

    def cons(y: np.ndarray) -> np.ndarray:
        vals, _ = prob.candidates(y[:n])
        return vals / s - y[n]

    def cons_jac(y: np.ndarray) -> np.ndarray:
        _, grads = prob.candidates(y[:n])
        return np.hstack([grads / s, -np.ones((grads.shape[0], 1))])

    constraints: list[dict[str, Any]] = [{"type": "ineq", "fun": cons, "jac": cons_jac}]
    if extra is not None:
        constraints.append(
            {
                "type": "ineq",
                "fun": lambda y: extra(y[:n])[0],
                "jac": lambda y: np.hstack([extra(y[:n])[1], np.zeros((extra(y[:n])[1].shape[0], 1))]),
            }
        )
    res = minimize(
        lambda y: -y[n],
        y0,
        jac=lambda y: np.r_[np.zeros(n), -1.0],
        method="SLSQP",
        bounds=[(0.0, 1.0)] * n + [(t_min / s, None)],
        constraints=constraints,
        options={"ftol": 1e-10, "maxiter": 100},
    )
    u = np.clip(res.x[:n], 0.0, 1.0)
    best = float(prob.candidates(u)[0][0])
    return u, best, int(res.nit)


# ------------------------------------------------------------------ the multi-start scaffolding
def check_starts(starts: Any) -> int:
    """The number of optimiser starts: a whole number >= 1, else one line."""
    if not isinstance(starts, int) or isinstance(starts, bool) or starts < 1:
        from ..errors import InputError

        raise InputError(f"starts must be a whole number >= 1 (got {starts!r})")
    return starts


def check_bound(what: str, lo: Any, hi: Any, *, positive: bool = False) -> tuple[float, float]:
    """An optimiser bound ``(lo, hi)``: finite, lo < hi (and 0 < lo when
    ``positive``), else one line naming ``what``."""
    from ..errors import InputError

    a, b = float(lo), float(hi)
    if not (math.isfinite(a) and math.isfinite(b) and a < b and (a > 0 or not positive)):
        raise InputError(
            f"{what}: the bound is empty (got {a:g} .. {b:g}); give {'0 < lo < hi' if positive else 'lo < hi'}"
        )
    return a, b


def start_points(
    named: list[tuple[str, np.ndarray]], dim: int, starts: int, seed: int
) -> list[tuple[str, np.ndarray]]:
    """The optimiser's starts in the unit box: the ``named`` ones (a
    classical design, the file's), then Latin-hypercube points (``seed``) up
    to ``starts`` in all."""
    out = list(named)
    n_rand = max(starts - len(named), 0)
    if n_rand:
        rng = np.random.default_rng(seed)
        lhs = (np.argsort(rng.random((dim, n_rand)), axis=1).T + rng.random((n_rand, dim))) / n_rand
        out += [(f"random {i + 1}", lhs[i]) for i in range(n_rand)]
    return out[:starts]


def best_start(
    u0: list[tuple[str, np.ndarray]],
    solve: Callable[[np.ndarray], tuple[np.ndarray, float, int]],
    feasible: Callable[[np.ndarray], bool] | None = None,
) -> tuple[
    list[tuple[str, np.ndarray, np.ndarray, float, int]], tuple[str, np.ndarray, np.ndarray, float, int]
]:
    """Every start solved (``solve(u) -> (u_best, width, iterations)``; an
    infeasible end counts -inf) and the best: ``(runs, best)``, each run
    ``(label, start, end, width, iterations)``."""
    runs = []
    for label, u in u0:
        ub, wb, it = solve(u)
        ok = feasible is None or feasible(ub)
        runs.append((label, u, ub, wb if ok else -math.inf, it))
    return runs, max(runs, key=lambda r: r[3])


def starts_line(starts: tuple[dict[str, Any], ...], width: float, evaluations: int, elapsed: float) -> str:
    """The summary line of a multi-start optimisation."""
    agree = sum(abs(s["width"] - width) <= 1e-6 * width for s in starts)
    return (
        f"  {len(starts)} start{'s' if len(starts) != 1 else ''} ({', '.join(s['label'] for s in starts)});"
        f" {agree} reach the optimum to 1e-6; {evaluations} evaluations, {elapsed:.1f} s"
    )
