"""The spectral root search: frequency windows placed on predicted root locations.

Windows (:mod:`chatterlab.frequency._collocation`) are placed on the
predictions of :func:`chatterlab.frequency._branches.predict` and added until
every prediction right of the ``count``-th root found (minus a margin and the
prediction's own uncertainty) lies in a window.  The predictions only steer
where to look; every reported root is an eigenvalue of a discretised
generator, refined by Newton and reproduced by a finer discretisation.
A short delay or a small band needs one window through the origin.

References
----------
.. [1] D. Breda, S. Maset, R. Vermiglio, SIAM J. Sci. Comput. 27(2),
   482-495, 2005.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ._band import band_top
from ._branches import predict
from ._collocation import N2_FACTOR, Window, make_window, solve_window, window_size
from ._delay_system import DelaySystem
from ._newton import canonical, dedupe, newton, root_scale
from ._roots_result import RootsResult, make_result

__all__ = ["spectral_roots"]

ComplexArray = NDArray[np.complex128]
FloatArray = NDArray[np.float64]

# Largest discretised-generator size solved by one dense eigenvalue problem
# (about 0.15 s for a complex 400x400 matrix); beyond that, frequency windows.
_DENSE_MAX = 420

#: a system with more first-order states than this is searched on its band
#: model (:meth:`DelaySystem.band_model`: the modes of the band and above it
#: the ones whose static part is not accurate enough, plus the static
#: response), its roots refined on the full system; smaller ones (the bundled
#: models) on the full system, the reference
REDUCE_ABOVE = 120
#: bound on the error of the band model's loop transfer H in the band (H is
#: dimensionless): a root with Re >= -SIGMA_TAU / tau, the certified region,
#: has |e^{-lambda tau} mu(H)| = 1, so |mu(H)| >= e^{-2} = 0.135 there, and an
#: error of 1e-3 moves the loop gain by < 0.75 %: the model's roots are close
#: starts for Newton on the full system, not the roots themselves
REDUCE_TOL = 1e-3


def spectral_roots(
    sys: DelaySystem,
    count: int,
    omega_max: float | None,
    n_nodes: int | None,
    match_tol: float,
    max_windows: int,
    t0: float,
) -> RootsResult:
    tau = sys.tau
    scale = root_scale(sys)
    if n_nodes is not None:
        N = int(n_nodes)
        win = Window(0.0, N / tau, N, int(math.ceil(N2_FACTOR * N)))
        solve_window(sys, win, match_tol)
        return finish(sys, [win], count, "spectral", t0, extra="(N fixed by caller)")
    top = band_top(sys, count, omega_max)
    model = band_model(sys, top)
    est, unc = predict(model or sys, top)
    p = (model or sys).delay_free_poles()
    pmax = float(np.max(np.abs(p))) if p.size else 0.0
    re_sorted = np.sort(est.real)[::-1]
    a_c = float(re_sorted[min(2 * count + 1, re_sorted.size - 1)]) if est.size else 0.0

    windows: list[Window] = []
    single = True
    method = "spectral"
    note = ""
    for _round in range(20):
        delta = 0.25 / tau + 0.05 * abs(a_c)
        lo = a_c - delta
        sel = est.real + np.minimum(unc, 1e6) >= lo
        # only roots right of lo matter: cover the prediction clipped to lo
        need = np.maximum(est.real[sel], lo) + 1j * est.imag[sel]
        # a prediction whose fixed-point iteration did not settle is only
        # known to lie near the axis: cover the band from its estimate to lo
        cov = np.zeros(need.shape, dtype=bool)
        for win in windows:
            cov |= np.abs(need - 1j * win.centre) <= win.radius
        if windows and np.all(cov):
            roots = collect(windows, scale)
            if roots.size >= count:
                a_new = float(np.sort(roots.real)[::-1][count - 1])
                if a_new >= a_c - 1e-12 * scale:
                    break
                a_c = a_new
                continue
            # everything predicted is covered but too few roots: lower the bar
            a_c = lo - delta
            continue
        todo = need[~cov]
        if single:
            R = max(1.1 * float(np.max(np.abs(need))) if need.size else 0.0, 8.0 / tau)
            if pmax * tau < 60.0:
                # short delay: the structural roots are cheap to include
                R = max(R, 1.2 * pmax + 4.0 / tau)
            if windows:
                R = max(R, 1.3 * windows[0].radius)
            if window_size(model or sys, R) <= _DENSE_MAX:
                windows = [make_window(0.0, R, tau)]
                solve_window(sys, windows[0], match_tol, model)
                roots = collect(windows, scale)
                if roots.size >= count:
                    a_c = min(a_c, float(np.sort(roots.real)[::-1][count - 1]))
                continue
            single = False
            method = "spectral-windowed"
        new = _cover(todo, tau, sys)
        for win in new:
            solve_window(sys, win, match_tol, model)
        windows.extend(new)
        if len(windows) > max_windows:
            return finish(
                sys,
                windows,
                count,
                method,
                t0,
                fail=f"more than {max_windows} frequency windows needed; "
                "pass omega_max to narrow the band or use method='branch'",
                model=model,
                match_tol=match_tol,
            )
        roots = collect(windows, scale)
        if roots.size >= count:
            a_c = min(a_c, float(np.sort(roots.real)[::-1][count - 1]))
    else:
        note = "window placement did not settle after 20 rounds"
    return finish(sys, windows, count, method, t0, fail=note, model=model, match_tol=match_tol)


def band_model(sys: DelaySystem, top: float) -> DelaySystem | None:
    """The reduced model the search runs on (:meth:`DelaySystem.band_model`
    for the band up to ``top`` with the error bound ``REDUCE_TOL``), or None:
    the system is small (at most ``REDUCE_ABOVE`` first-order states) or has
    no such model."""
    if sys.A.shape[0] <= REDUCE_ABOVE:
        return None
    return sys.band_model(top, REDUCE_TOL)


def _cover(pts: ComplexArray, tau: float, sys: DelaySystem) -> list[Window]:
    """Greedy cover of predicted root locations by discs centred on the imaginary axis."""
    out: list[Window] = []
    pts = pts[np.argsort(pts.imag)]
    base = 36.0 / tau  # radius giving N of about 48
    todo = np.ones(pts.shape, dtype=bool)
    while np.any(todo):
        i = int(np.flatnonzero(todo)[0])
        near = pts[todo][:16]
        amag = float(np.max(np.abs(near.real)))
        R = max(base, 1.25 * amag)
        half = math.sqrt(max(R * R - amag * amag, 0.0))
        c = float(pts[i].imag) + 0.9 * half
        if pts[i].imag <= half:  # near the origin: real arithmetic, real roots too
            c = 0.0
            R = max(R, 1.05 * abs(pts[i]))
        win = make_window(c, R, tau)
        hit = np.abs(pts - 1j * c) <= R
        hit[i] = True  # guarantees progress
        todo &= ~hit
        out.append(win)
    return out


def collect(windows: list[Window], scale: float) -> ComplexArray:
    allr = [w.roots for w in windows if w.roots.size]
    if not allr:
        return np.zeros(0, complex)
    return dedupe(np.concatenate(allr), 1e-8, scale)


def finish(
    sys: DelaySystem,
    windows: list[Window],
    count: int,
    method: str,
    t0: float,
    *,
    fail: str = "",
    extra: str = "",
    model: DelaySystem | None = None,
    match_tol: float = 1e-6,
) -> RootsResult:
    """The result: the ``count`` rightmost roots the windows confirmed.  When
    they were found on a reduced ``model`` and refined from the low-rank
    factorisation, each reported root is refined once more by Newton on
    Delta itself (the reference iteration) and must stay within
    ``match_tol``."""
    scale = root_scale(sys)
    roots = collect(windows, scale)
    roots = roots[np.lexsort((roots.imag, -roots.real))][:count]
    rejected = sum(w.rejected for w in windows)
    if model is not None and roots.size:
        lam, ok = newton(sys, roots)
        lam = canonical(lam, scale)
        ok &= np.abs(lam - roots) <= match_tol * np.maximum(np.abs(roots), scale)
        if not np.all(ok):
            fail = "; ".join(
                x
                for x in (
                    fail,
                    f"{int(np.sum(~ok))} root(s) of the band model's search not reproduced by Newton on"
                    " the full characteristic matrix",
                )
                if x
            )
        roots = np.where(ok, lam, roots)
        roots = roots[np.lexsort((roots.imag, -roots.real))]
    N = max((w.N for w in windows), default=0)
    N2 = max((w.N2 for w in windows), default=0)
    fails = "; ".join(w.failed for w in windows if w.failed)
    if fail or fails:
        status = "not_converged"
        msg = "; ".join(x for x in (fail, fails) if x)
    elif roots.size < count:
        status = "not_converged"
        msg = f"only {roots.size} of {count} roots confirmed by both discretisations"
    else:
        status = "converged"
        msg = (
            f"{roots.size} roots confirmed by N={N} and N2={N2} after Newton "
            f"({len(windows)} window(s), {rejected} candidate(s) rejected)"
        )
    if extra:
        msg = f"{msg} {extra}"
    if model is not None:
        msg += (
            f"; searched on the band model ({model.n} of {sys.n} coordinates: the modes of the band and"
            f" the static response, loop transfer within {REDUCE_TOL:g}), roots refined on the full system"
        )
    return make_result(
        roots,
        method=method,
        n_nodes=(N, N2),
        rejected=rejected,
        status=status,
        message=msg,
        n_windows=len(windows),
        t0=t0,
    )
