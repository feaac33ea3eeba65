"""The search for the limit depth a_lim at one spindle speed by Floquet
multipliers (spectral or SDM): the scan of rho(a_p) for its first crossing of
1, Brent's refinement, the spectral method's convergence check and its finer
meshes (see :mod:`chatterlab.lobes._milling`)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..frequency import (
    CHECK_DEGREE,
    ELEMENT_SPAN,
    SpectralMonodromy,
    ToolStructure,
    chatter_frequency,
    sdm_monodromy,
)
from ..process import Milling

__all__ = ["floquet_limit"]


def _first_crossing(
    rho: Callable[[float], float], depth_max: float, scan: int, rtol: float
) -> tuple[float, int, float]:
    """Smallest a in (0, depth_max] with rho(a) = 1 found on the scan, refined
    by Brent's method; inf if rho < 1 at every scan depth.  Also the slope
    d rho / d a at the root from the closest evaluations on either side (nan
    when they are further apart than 1e-4 a)."""
    grid = depth_max * np.arange(1, scan + 1) / scan
    count = 0
    prev_a, prev_f = 0.0, -1.0  # rho(0) < 1: the structure is stable (checked by the caller)
    for a in grid:
        f = rho(float(a)) - 1.0
        count += 1
        if f >= 0.0:
            from scipy.optimize import brentq  # here: import chatterlab stays light

            seen: list[tuple[float, float]] = [(prev_a, prev_f), (float(a), f)]

            def g(x: float, seen: list[tuple[float, float]] = seen) -> float:
                v = rho(x) - 1.0
                seen.append((x, v))
                return v

            if prev_a == 0.0:
                seen.clear()
                prev_f = g(1e-12 * depth_max)
                prev_a = 1e-12 * depth_max
                if prev_f >= 0:
                    return prev_a, count + len(seen), float("nan")
                seen.append((float(a), f))
            root = brentq(g, prev_a, float(a), xtol=rtol * prev_a, rtol=4 * np.finfo(float).eps, maxiter=200)
            below = [p for p in seen if p[1] < 0]
            above = [p for p in seen if p[1] >= 0]
            lo = max(below, key=lambda p: p[0])
            hi = min(above, key=lambda p: p[0])
            slope = (hi[1] - lo[1]) / (hi[0] - lo[0]) if hi[0] - lo[0] <= 1e-4 * root else float("nan")
            return float(root), count + len(seen) - 2, slope
        prev_a, prev_f = float(a), f
    return float("inf"), count, float("nan")


def _spectral_rho(sm: SpectralMonodromy) -> Callable[[float], float]:
    return sm.radius


def _helix_rho(
    structure: ToolStructure, milling: Milling, rpm: float, degree: int, elements: int | None, span: float
) -> Callable[[float], float]:
    def rho(a: float) -> float:
        sm = SpectralMonodromy(structure, milling, rpm, degree, elements, depth=a, depth_hint=0.0, span=span)
        return sm.radius(a)

    return rho


def _sdm_top(
    structure: ToolStructure, milling: Milling, rpm: float, steps: int
) -> Callable[[float], complex]:
    def mu_at(a: float) -> complex:
        ev = np.linalg.eigvals(sdm_monodromy(structure, milling, rpm, a, steps))
        return complex(ev[np.argmax(np.abs(ev))])

    return mu_at


def _abs_of(f: Callable[[float], complex]) -> Callable[[float], float]:
    return lambda a: abs(f(a))


def floquet_limit(
    structure: ToolStructure,
    milling: Milling,
    r: float,
    method: str,
    depth_max: float,
    scan: int,
    rtol: float,
    degree: int,
    elements: int | None,
    steps: int,
    check: bool,
    target: float,
) -> tuple[float, float, complex, float, int, int]:
    """a_lim at speed ``r`` (rpm), its error estimate, the critical multiplier
    and chatter frequency there, the evaluations of rho and the mesh
    refinements: (a, error, mu, frequency_hz, evaluations, refined).  a is
    inf (mu and the frequency nan) when rho < 1 at every scanned depth."""
    helix = milling.helix > 0
    T = milling.period(float(r))
    rho: Callable[[float], float]
    mu_at: Callable[[float], complex]
    span = ELEMENT_SPAN
    evals = refined = 0
    err = np.nan
    for attempt in range(4):
        if method == "spectral":
            # the mesh resolves the structure's own frequencies (span); where the limit lies
            # deeper than the cut's stiffening allows, the check below asks for a finer one
            if helix:  # the coefficients depend on a_p: a discretisation per depth
                rho = _helix_rho(structure, milling, float(r), degree, elements, span)
            else:
                sm = SpectralMonodromy(structure, milling, float(r), degree, elements, span=span)
                rho = _spectral_rho(sm)
        else:
            mu_at = _sdm_top(structure, milling, float(r), steps)
            rho = _abs_of(mu_at)
        a, cnt, slope = _first_crossing(rho, depth_max, scan, rtol)
        evals += cnt
        if method != "spectral" or not check or not np.isfinite(a):
            break
        if helix:
            sm = SpectralMonodromy(
                structure, milling, float(r), degree, elements, depth=a, depth_hint=0.0, span=span
            )
        sm2 = SpectralMonodromy(
            structure,
            milling,
            float(r),
            degree + CHECK_DEGREE,
            mesh=sm.mesh,
            depth=a if helix else None,
            depth_hint=0.0,
        )
        if not np.isfinite(slope):  # Brent's last points too far apart: a central difference
            da = max(1e-6 * a, 10 * rtol * a)
            slope = (rho(a + da) - rho(a - da)) / (2 * da)
            evals += 2
        err = abs(sm2.radius(a) - 1.0) / abs(slope) if slope else np.inf
        evals += 1
        if err <= target * a or elements is not None or attempt == 3:
            break
        span /= 2.0
        refined += 1
    if not np.isfinite(a):
        return a, err, complex(np.nan, 0.0), np.nan, evals, refined
    if method == "spectral":
        if helix and not check:
            sm = SpectralMonodromy(
                structure, milling, float(r), degree, elements, depth=a, depth_hint=0.0, span=span
            )
        mu, freq = sm.critical(a)
    else:
        mu = mu_at(a)
        freq = chatter_frequency(mu, T, structure)
    return a, err, mu, freq, evals, refined
