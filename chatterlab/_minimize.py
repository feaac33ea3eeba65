"""The minimum of a function of one variable on an interval, without derivatives.

Brent's method (R. P. Brent, *Algorithms for Minimization without
Derivatives*, Prentice-Hall 1973, ch. 5): golden-section steps that shrink a
bracket [a, b] by 0.382 at least every other step, and parabolic steps through
the three best points where they land well inside it, which converge with
order about 1.32 near a smooth minimum.  It stops when the best point x is
within ``2 tol`` of the bracket's ends around it, ``tol = sqrt(eps) |x| +
xatol / 3``: the minimiser is then known to ``xatol + 3 sqrt(eps) |x|``.

Written here, not taken from ``scipy.optimize.minimize_scalar``, because the
README main job needs one bounded minimisation (the absolute minimum of a lobe
diagram, :mod:`chatterlab.lobes._envelope`) and importing scipy.optimize costs
0.16-0.25 s, a tenth of the whole command (issue 26, start-up row).
"""

from __future__ import annotations

import math
from collections.abc import Callable

__all__ = ["bounded_minimum"]

_GOLD = 0.5 * (3.0 - math.sqrt(5.0))  #: the golden-section fraction 0.381966...
_SQRT_EPS = math.sqrt(2.220446049250313e-16)


def bounded_minimum(
    f: Callable[[float], float], a: float, b: float, xatol: float, maxiter: int = 500
) -> tuple[float, float, int]:
    """``(x, f(x), evaluations)``: a local minimum of ``f`` on ``[a, b]``
    (``a < b``), located to ``xatol + 3 sqrt(eps) |x|``.

    ``f`` may return ``inf`` (no value there); such a point is never the
    best, and a parabola through it is not used.  With a unimodal ``f`` the
    minimum found is the minimum on [a, b]; otherwise it is one local minimum
    (Brent 1973, ch. 5).  Never evaluates ``f`` at ``a`` or ``b``."""
    if not (a < b) or not math.isfinite(a) or not math.isfinite(b):
        raise ValueError(f"bounded_minimum needs a finite interval a < b, got [{a!r}, {b!r}]")
    x = w = v = a + _GOLD * (b - a)
    fx = fw = fv = f(x)
    count = 1
    d = e = 0.0  # the last step and the one before it
    for _ in range(maxiter):
        mid = 0.5 * (a + b)
        tol = _SQRT_EPS * abs(x) + xatol / 3.0
        tol2 = 2.0 * tol
        if abs(x - mid) <= tol2 - 0.5 * (b - a):
            break
        parabolic = False
        if abs(e) > tol:
            # the parabola through (x, fx), (w, fw), (v, fv); its vertex is x + p / q
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            e_before, e = e, d
            # accepted only if finite, inside the bracket and shorter than half the step before last
            if abs(p) < abs(0.5 * q * e_before) and q * (a - x) < p < q * (b - x):
                d = p / q
                parabolic = True
                if (x + d) - a < tol2 or b - (x + d) < tol2:
                    d = tol if x < mid else -tol
        if not parabolic:
            e = (b - x) if x < mid else (a - x)
            d = _GOLD * e
        u = x + (d if abs(d) >= tol else math.copysign(tol, d))
        fu = f(u)
        count += 1
        if fu <= fx:
            if u < x:
                b = x
            else:
                a = x
            v, fv, w, fw, x, fx = w, fw, x, fx, u, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
    return x, fx, count
