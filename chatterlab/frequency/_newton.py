"""Newton's method on :math:`\\det\\Delta(\\lambda)` and the bookkeeping of roots.

Every root the search reports is refined here:
:math:`\\lambda \\leftarrow \\lambda - 1/\\operatorname{tr}(\\Delta^{-1}\\Delta')`
(Lancaster), vectorised over the starts, optionally with known roots deflated.
Roots are compared in canonical form (upper half plane, nearly-real snapped to
the real axis) relative to the system's scale (:func:`root_scale`).

References
----------
.. [1] P. Lancaster, *Lambda-matrices and Vibrating Systems*, Pergamon 1966
   (Newton's method :math:`\\lambda \\leftarrow \\lambda -
   1/\\operatorname{tr}(\\Delta^{-1}\\Delta')`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._delay_system import DelaySystem, as_delay_system, batched_solve

__all__ = [
    "newton_refine",
    "newton",
    "newton_distinct",
    "root_scale",
    "canonical",
    "dedupe",
    "match",
    "EXP_LIMIT",
]

ComplexArray = NDArray[np.complex128]
FloatArray = NDArray[np.float64]

# exp(-lambda tau) overflows for Re(lambda) tau < -709; candidates that far
# left are discarded (they are never among the rightmost roots).
EXP_LIMIT = 600.0


def newton(
    sys: DelaySystem,
    lam0: ArrayLike,
    *,
    tol: float = 1e-13,
    maxiter: int = 40,
    deflate: ComplexArray | None = None,
    factored: bool = False,
) -> tuple[ComplexArray, NDArray[np.bool_]]:
    """Vectorised Newton iteration on det Delta; returns (roots, converged).

    ``deflate``: known roots ``zeta_i``; Newton is then applied to
    ``det Delta(lam) / prod (lam - zeta_i)`` so that it cannot return them.
    ``factored``: the step from the low-rank factorisation of det Delta
    (:meth:`DelaySystem.factored_log_derivative`, O(m r^2) per step) instead
    of a solve with Delta (O(n^3)); the same iteration in exact arithmetic,
    used for the many candidates of a large system's search, whose reported
    roots are then refined with Delta itself.  Ignored without a
    pole-residue form.
    """
    lam = np.array(lam0, dtype=complex).ravel()
    conv = np.zeros(lam.shape, dtype=bool)
    alive = np.isfinite(lam)
    if sys.has_delay:
        alive &= lam.real * sys.tau > -EXP_LIMIT
    scale = root_scale(sys)
    last = np.full(lam.shape, np.inf)
    factored = factored and sys.partial_fractions() is not None
    for _ in range(maxiter):
        idx = np.flatnonzero(alive & ~conv)
        if idx.size == 0:
            break
        L = lam[idx]
        with np.errstate(all="ignore"):
            fac = sys.factored_log_derivative(L) if factored else None
            if fac is not None:
                tr = fac
            else:
                D = sys.delta(L)
                Dp = sys.ddelta(L)
                # an exactly singular Delta means lam is a root to machine precision
                X = batched_solve(D, Dp, singular=np.inf)
                tr = np.trace(X, axis1=-2, axis2=-1)
            exact = np.isinf(tr.real) | np.isinf(tr.imag)
            if deflate is not None and deflate.size:
                tr = tr - (1.0 / (L[:, None] - deflate[None, :])).sum(axis=1)
            step = 1.0 / tr
            step[~np.isfinite(tr)] = np.nan
        step[exact] = 0.0
        bad = ~np.isfinite(step)
        new = L - np.where(bad, 0.0, step)
        if sys.has_delay:
            bad |= new.real * sys.tau < -EXP_LIMIT
        lam[idx] = new
        a = np.abs(step)
        done = ~bad & (a <= tol * np.maximum(np.abs(new), scale))
        # a stalled iteration at roundoff level also counts as converged
        done |= ~bad & (a <= 1e-9 * np.maximum(np.abs(new), scale)) & (a >= 0.5 * last[idx])
        conv[idx[done]] = True
        alive[idx[bad]] = False
        last[idx] = np.where(bad, np.inf, a)
    # accept iterations that ended within a loose tolerance of a root
    idx = np.flatnonzero(alive & ~conv & (last <= 1e-8 * np.maximum(np.abs(lam), scale)))
    conv[idx] = True
    return lam, conv


def root_scale(sys: DelaySystem) -> float:
    """Size (rad/s) below which |lambda| counts as zero when roots are
    compared: 1e-3 of the largest delay-free pole or of 1/tau."""

    def compute() -> float:
        p = sys.delay_free_poles()
        s = float(np.max(np.abs(p))) if p.size else 1.0
        if sys.has_delay:
            s = max(s, 1.0 / sys.tau)
        return max(s, 1e-300) * 1e-3

    return sys.cached("scale", compute)


def newton_refine(
    lam0: ArrayLike,
    system: Any,
    *,
    tol: float = 1e-13,
    maxiter: int = 40,
) -> tuple[ComplexArray, NDArray[np.bool_]]:
    """Refine approximate characteristic roots by Newton's method on det Delta.

    Iterates :math:`\\lambda \\leftarrow \\lambda - 1/\\operatorname{tr}(
    \\Delta(\\lambda)^{-1}\\Delta'(\\lambda))`, quadratically convergent to a
    simple root.

    Parameters
    ----------
    lam0 : complex or array_like of complex, shape (k,)
        Starting values in rad/s.
    system : DelaySystem or ClosedLoop
        The delay equation (:func:`make_system`,
        :func:`make_first_order_system`, or a
        :class:`chatterlab.process.ClosedLoop`).
    tol : float
        Relative step size at which an iterate counts as converged.
    maxiter : int
        Maximum number of Newton steps.

    Returns
    -------
    roots : ndarray of complex, shape (k,)
        Final iterates (rad/s).
    converged : ndarray of bool, shape (k,)
        Whether each iterate converged.

    References
    ----------
    .. [1] P. Lancaster, *Lambda-matrices and Vibrating Systems*, 1966.
    """
    return newton(as_delay_system(system), lam0, tol=tol, maxiter=maxiter)


def canonical(lam: ComplexArray, scale: float) -> ComplexArray:
    """Map roots to the closed upper half plane; snap nearly-real roots to real."""
    lam = np.where(lam.imag < 0, lam.conj(), lam)
    near_real = np.abs(lam.imag) <= 1e-9 * np.maximum(np.abs(lam), scale)
    return np.where(near_real, lam.real + 0j, lam)


def dedupe(lam: ComplexArray, tol_rel: float, scale: float) -> ComplexArray:
    if lam.size == 0:
        return lam
    lam = lam[np.lexsort((lam.imag, lam.real))]
    keep: list[complex] = []
    for z in lam:
        t = tol_rel * max(abs(z), scale)
        if not any(abs(z - w) <= t for w in keep[-8:]):
            # roots are sorted by real part; compare with the recent ones and
            # a vectorised pass over all kept ones for safety
            if keep and np.min(np.abs(np.asarray(keep) - z)) <= t:
                continue
            keep.append(complex(z))
    return np.asarray(keep, dtype=complex)


def match(a: ComplexArray, b: ComplexArray, tol_rel: float, scale: float) -> NDArray[np.bool_]:
    """For each element of ``a``, whether ``b`` holds a root within tolerance."""
    if a.size == 0:
        return np.zeros(0, dtype=bool)
    if b.size == 0:
        return np.zeros(a.shape, dtype=bool)
    d = np.abs(a[:, None] - b[None, :]).min(axis=1)
    return d <= tol_rel * np.maximum(np.abs(a), scale)


def newton_distinct(sys: DelaySystem, starts: ComplexArray, known: ComplexArray) -> tuple[ComplexArray, int]:
    """Newton from each start; a start that lands on a root already claimed by
    another start is restarted with the claimed roots deflated, so that one
    start yields one distinct root.  Returns (all distinct roots, failures)."""
    scale = root_scale(sys)
    lam, conv = newton(sys, starts)
    roots = dedupe(np.concatenate([known, canonical(lam[conv], scale)]), 1e-8, scale)
    rejected = int(np.sum(~conv))
    ndup = int(np.sum(conv)) + known.size - roots.size
    if ndup <= 0:
        return roots, rejected
    # which starts collided: those whose root is closer to another start
    good = canonical(lam, scale)
    d_own = np.abs(good - canonical(starts, scale))
    dup_idx = []
    for z in roots:
        hit = np.flatnonzero(conv & (np.abs(good - z) <= 1e-8 * max(abs(z), scale)))
        if hit.size > 1:
            dup_idx.extend(hit[np.argsort(d_own[hit])][1:].tolist())
    if not dup_idx:
        return roots, rejected
    defl = np.concatenate([roots, roots[roots.imag != 0].conj()])
    lam2, conv2 = newton(sys, starts[dup_idx], deflate=defl, maxiter=60)
    if np.any(conv2):
        # polish without deflation (deflation only steers the iteration)
        lam3, conv3 = newton(sys, lam2[conv2])
        roots = dedupe(np.concatenate([roots, canonical(lam3[conv3], scale)]), 1e-8, scale)
    return roots, rejected
