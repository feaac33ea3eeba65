"""What round-off alone can change in a result: the tolerance of tests that
compare two evaluations differing only in the order of floating-point
operations (another BLAS or CPU, another batch size, speeds in another order).

LAPACK's and BLAS's results are backward stable: each is the exact result for
data perturbed by c(N) u relative (u = eps / 2 the unit round-off), with c(N)
growing like the matrix order N in practice (Higham, *Accuracy and Stability
of Numerical Algorithms*, 2nd ed., SIAM 2002, ch. 1 and 9).  Two evaluations
that differ in their order of operations are then exact for two perturbed
copies of the data, and differ by at most about 2 c(N) times the change that
a perturbation of size u causes.  That change is the result's conditioning,
which this module *measures* on the machine running the test (the speeds are
moved by up to one ulp too: see :func:`roundoff_tolerance`): every entry m of
the structure's A*, B*, C* becomes m + (eps r) m, r uniform in [-1, 1], which
rounds to m or a neighbouring float (symmetric matrices kept symmetric; a
factor 1 + u r would round to 1 and change nothing), for three seeds; the
largest relative change over all outputs is the computation's round-off level
(an output that one perturbation happens to leave alone is computed by the
same code as the others).  The tolerance is ``2 N`` times that level, at least
``2 N eps`` (N = 2 n, the order of the first-order state), plus ``4 eps`` for
the final roundings, relative to each value.
Nothing is tuned: a result that is ill-conditioned at some speed gets a wider
tolerance there and only there, on any BLAS.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

EPS = float(np.finfo(float).eps)
SEEDS = (11, 12, 13)


def perturbed(fz: Any, seed: int) -> Any:
    """The frozen system with each entry of A*, B*, C* moved by at most one
    ulp (relative at most eps), at random."""
    rng = np.random.default_rng(seed)

    def one(M: np.ndarray) -> np.ndarray:
        R = rng.uniform(-1.0, 1.0, M.shape)
        if np.array_equal(M, M.T):
            R = 0.5 * (R + R.T)
        return M + (EPS * R) * M

    return dataclasses.replace(fz, A=one(fz.A), B=one(fz.B), C=one(fz.C))


def roundoff_tolerance(
    compute: Callable[[Any, np.ndarray], Any], fz: Any, speeds: Any, base: Any = None
) -> np.ndarray:
    """Elementwise tolerance on ``compute(fz, speeds)`` (an array of floats,
    inf allowed) for a comparison that differs only by round-off (module
    docstring).  The speeds are moved by up to one ulp as well: the phase
    omega T of a lobe passes through the elementary functions, whose
    vectorised implementations differ between CPUs by an ulp or a few.
    Where an output is infinite it is compared exactly (tolerance 0)."""
    sp = np.asarray(speeds, float)
    x0 = np.asarray(compute(fz, sp) if base is None else base, float)
    spread = np.zeros_like(x0)
    for s in SEEDS:
        r = np.random.default_rng(100 + s).uniform(-1.0, 1.0, sp.shape)
        x = np.asarray(compute(perturbed(fz, s), sp + (EPS * r) * sp), float)
        with np.errstate(invalid="ignore"):
            d = np.abs(x - x0)
        d[~np.isfinite(d)] = (
            0.0  # inf on both; a flip to inf is what the caller's exact finite-mask test sees
        )
        spread = np.maximum(spread, d)
    # the round-off level of the computation: the largest relative change over its outputs (one
    # output can be insensitive to a particular perturbation that another, computed alike, feels)
    fin = np.isfinite(x0) & (x0 != 0)
    level = float(np.max(spread[fin] / np.abs(x0[fin]), initial=0.0))
    tol = (2.0 * (2 * fz.n) * max(level, EPS) + 4.0 * EPS) * np.abs(x0)
    tol[~np.isfinite(x0)] = 0.0
    return tol
