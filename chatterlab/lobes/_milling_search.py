"""The search for the limit depth a_lim at one spindle speed by Floquet
multipliers (see :mod:`chatterlab.lobes._milling`).

Spectral elements without helix (U, V affine in a_p): the complete search
:func:`certified_crossing` -- every flip and fold depth exactly, from two
real eigenproblems, and the complex pairs tracked with their exact
derivatives between the scan depths, bisected wherever a multiplier comes
within its own rate of change of the unit circle -- then the convergence
check and its finer meshes.  With a helix or by SDM: the scan of rho(a_p)
for its first crossing of 1 and Brent's refinement (:func:`_first_crossing`),
which can miss a band narrower than the scan step."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..frequency import (
    CHECK_DEGREE,
    ELEMENT_SPAN,
    SpectralMonodromy,
    chatter_frequency,
    sdm_monodromy,
)
from ..frequency._floquet import QuasiStatic, spectral_mesh
from ..process import ClosedLoop

__all__ = ["Certified", "certified_crossing", "floquet_limit"]


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


#: an interval is refined until it is this short (relative to its end) before a crossing is
#: bracketed or a near-touch is declared undetermined
MIN_WIDTH = 1e-7
#: evaluations of the multipliers and their derivatives allowed per speed (beyond the scan)
MAX_TANGENTS = 400
#: the automatic degrees aim at the check's target divided by this (the rest is the margin the
#: check confirms: a speed whose check misses the target is searched again, finer)
TOL_SHARE = 30.0
#: a step of the complete search takes every multiplier's first-order path at most this share of
#: the way to the unit circle, leaving the rest for the second-order term the test adds
SAFE = 0.5
#: ... except the multiplier heading out first (the least (1 - |mu|) / (d|mu|/da)): the step goes
#: this far past its Newton prediction of the crossing, so that one step brackets it
OVERSHOOT = 1.25
#: a step is at most this many scan steps (depth_max / scan) long: the first-order test over it
#: must still see a multiplier that bends out and back (its miss term is second order in h)
STEP_CAP = 4.0
#: the automatic mesh's depth stages are merged while the deeper one has at most this many
#: times the nodes of the shallower one (a set-up and its flip/fold eigenproblems cost more)
MERGE = 1.2


@dataclass(frozen=True)
class Certified:
    """What the complete search found at one speed (see :func:`certified_crossing`).

    ``status``: ``"crossing"`` (a_lim = ``depth``, the first depth with a
    multiplier on the unit circle), ``"stable"`` (no multiplier on the unit
    circle in (0, depth_max]: ``depth`` is inf) or ``"undetermined"``
    (stability holds on (0, ``certified``] and is not decided beyond).
    ``kind``: flip, fold or hopf for a crossing; ``certified`` the depth up
    to which every interval passed the test; ``flip``/``fold`` the exact
    depths of multipliers -1 and +1 found in (0, depth_max]."""

    status: str
    depth: float
    kind: str
    certified: float
    evaluations: int
    slope: float
    flip: tuple[float, ...]
    fold: tuple[float, ...]


def _end_safe(
    mu: np.ndarray, dmu: np.ndarray, h: float, skip: float | None, miss: np.ndarray | float = 0.0
) -> bool:
    """One end of an interval, the other end at a distance h (signed: -h from the
    right end): see :func:`_interval_safe`."""
    with np.errstate(invalid="ignore", over="ignore"):
        reach = np.maximum(np.abs(mu), np.abs(mu + dmu * h)) + miss
    ok = reach < 1.0  # nan: not ok
    if skip is not None:
        ok |= np.abs(mu - skip) <= 1e-6
    if ok.all():
        return True
    with np.errstate(invalid="ignore", over="ignore"):
        move = np.abs(dmu) * abs(h) + miss
    move = np.where(np.isnan(move), np.inf, move)
    real = np.nonzero(mu.imag == 0.0)[0]
    for i in np.nonzero(~ok)[0]:
        if mu[i].imag != 0.0 or abs(mu[i]) >= 1.0 or not np.isfinite(move[i]):
            return False
        others = real[real != i]
        if np.any(np.abs(mu[others] - mu[i]) <= move[others] + move[i]):
            return False
    return True


def _simple_bracket(lo: tuple[np.ndarray, np.ndarray], hi: tuple[np.ndarray, np.ndarray], h: float) -> bool:
    """rho < 1 at the left end, >= 1 at the right, and one multiplier (a
    complex pair) crossing once: the others pass :func:`_end_safe` at both
    ends, and the crossing one's |mu| rises at both ends with slopes s that
    differ by less than the smaller (d|mu|/da, linear between the ends,
    keeps its sign: |mu| is monotone on the interval to second order)."""
    s = []
    for (mu, dmu), miss, hs in ((lo, _miss(lo, hi, h), h), (hi, _miss(hi, lo, -h), -h)):
        top = np.abs(mu) >= np.abs(mu).max() * (1.0 - 1e-9)
        if np.sum(top) > 2 or (np.sum(top) == 2 and mu[top][0].imag == 0.0):
            return False
        m0 = mu[top][0]
        s.append(float(np.real(np.conj(m0) * dmu[top][0]) / abs(m0)))
        if not _end_safe(mu[~top], dmu[~top], hs, None, miss[~top]):
            return False
    return bool(np.isfinite(s).all() and min(s) > 0.0 and abs(s[1] - s[0]) < min(s))


def _interval_safe(
    lo: tuple[np.ndarray, np.ndarray], hi: tuple[np.ndarray, np.ndarray], h: float, skip_hi: float | None
) -> bool:
    """No multiplier reaches the unit circle on an interval of length h, to
    first order, judged from each end with its own derivatives.

    To first order a multiplier follows the segment mu + (d mu/da) t, t in
    [0, h], whose modulus is convex in t: its largest value is at one of the
    segment's ends, max(|mu|, |mu + (d mu/da) h|); the multiplier stays inside
    if that, widened by the second-order term (below), is < 1 from both ends
    (from the right end the segment runs back, -h).  A real multiplier can
    leave the unit disc only through +-1 (those depths are known exactly,
    :meth:`SpectralMonodromy.unit_depths`) or by meeting another real
    multiplier and leaving the axis as a pair; so it is also safe if it
    stays further from every other real multiplier than both move,
    |mu_k - mu_j| > (|d mu_k| + |d mu_j|) h (each widened by its miss).  ``skip_hi``: the known
    multiplier (+-1) at a right end that is a flip/fold depth, left out
    there.

    The first-order move is widened by how far the linear prediction from
    one end misses the nearest multiplier at the other (an estimate of the
    remainder |mu''| h^2 / 2, which bounds it at every t in [0, h] while mu''
    varies little over the interval): a multiplier that bends out and back
    within the interval shows there.  (Until this change the test was the
    triangle inequality's |mu| + |d mu/da| h + miss < 1, larger by up to
    |d mu/da| h where the multiplier moves along the circle: the same
    second-order claim, far shorter intervals where the multipliers turn.)"""
    return _end_safe(*lo, h, None, _miss(lo, hi, h)) and _end_safe(*hi, -h, skip_hi, _miss(hi, lo, -h))


def _miss(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], h: float) -> np.ndarray:
    """|mu + d mu h - nearest multiplier at the other end| for every multiplier of end ``a``."""
    mu, dmu = a
    with np.errstate(invalid="ignore", over="ignore"):
        pred = mu + dmu * h
        d = np.abs(pred[:, None] - b[0][None, :]).min(axis=1)
    return np.where(np.isfinite(d), d, np.inf)


def _step(mu: np.ndarray, dmu: np.ndarray, room: float) -> float:
    """The next step of the complete search from a depth with multipliers ``mu``
    and rates ``dmu``, sized so that the interval passes :func:`_interval_safe`:
    every multiplier's first-order path stays within |mu + (d mu/da) h| <=
    |mu| + SAFE (1 - |mu|) (the rest of the gap left to the second-order
    term), or, for a real one, within SAFE of its distance to the other real
    ones (it leaves the axis only by meeting one; its passage through +-1 is
    known exactly).  But if the complex multiplier heading out first (radial
    rate s > 0, least Newton distance (1 - |mu|) / s) is bracketed by a step
    OVERSHOOT times that distance while the others stay within their
    limits, that step (the bracket :func:`_simple_bracket` then confirms).
    ``room``: what is left of the interval searched (returned when nothing
    limits the step)."""
    r = np.abs(mu)
    rate = np.abs(dmu)
    if r.max(initial=0.0) >= 1.0 or not np.isfinite(rate).all():
        return 0.0
    real = mu.imag == 0.0
    s = (mu.conj() * dmu).real / np.where(r > 0.0, r, 1.0)
    c = r + SAFE * (1.0 - r)
    with np.errstate(divide="ignore", invalid="ignore"):
        # the positive root of |mu + dmu t|^2 = c^2: rate^2 t^2 + 2 r s t + r^2 - c^2 = 0
        limit = (np.sqrt((r * s) ** 2 + rate**2 * (c**2 - r**2)) - r * s) / rate**2
        limit = np.where(rate > 0.0, limit, np.inf)
        # a real multiplier's distance to the others matters only where its modulus limit binds
        bound = float(limit[~real].min(initial=room))
        near = np.nonzero(real & (limit < bound))[0]
        if near.size:
            ri = np.nonzero(real)[0]
            apart = np.abs(mu.real[near][:, None] - mu.real[ri][None, :]) / (
                rate[near][:, None] + rate[ri][None, :]
            )
            apart[near[:, None] == ri[None, :]] = np.inf
            apart = SAFE * np.min(np.where(np.isnan(apart), 0.0, apart), axis=1)
            limit[near] = np.maximum(limit[near], apart)
        newton = np.where((s > 0.0) & ~real, (1.0 - r) / s, np.inf)
    limit = np.where(np.isnan(limit), 0.0, limit)
    j = int(np.argmin(newton))
    h_out = OVERSHOOT * float(newton[j])
    if np.isfinite(h_out):
        pair = np.abs(mu - mu[j]) <= 1e-12 * r[j]
        pair |= np.abs(mu - np.conj(mu[j])) <= 1e-12 * r[j]
        if h_out <= float(limit[~pair].min(initial=np.inf)):
            return min(h_out, room)
    return min(float(limit.min()), room)


def _slope(mu: np.ndarray, dmu: np.ndarray, i: int) -> float:
    """d|mu_i|/da from a multiplier and its rate."""
    return float(np.real(np.conj(mu[i]) * dmu[i]) / abs(mu[i]))


def certified_crossing(
    sm: SpectralMonodromy,
    depth_max: float,
    scan: int,
    rtol: float,
    max_tangents: int | None = None,
    *,
    start: float = 0.0,
    stop: float | None = None,
) -> Certified:
    """The first depth in (start, stop] (default (0, depth_max]) at which a
    multiplier of ``sm`` (spectral elements, no helix: affine in a_p) reaches
    the unit circle, with stability established on (0, start] before.

    1. Flip and fold: every depth with a multiplier at -1 or +1 in
       (start, stop], exactly, from two real eigenproblems
       (:meth:`SpectralMonodromy.unit_depths`); no sampling.
    2. Complex pairs (secondary Hopf): the multipliers and their exact
       derivatives (:meth:`SpectralMonodromy.tangent`; at 0, where multipliers
       repeat, the rates of those leaving them) at depths stepped
       from ``start`` to the first flip/fold depth, each step as long as
       :func:`_step` predicts the interval passes :func:`_interval_safe`
       (every multiplier's first-order path within half its gap to the unit
       circle) or long enough to bracket the multiplier heading out first,
       and never more than STEP_CAP scan steps (depth_max / scan); an
       interval that fails is bisected until :func:`_interval_safe` passes (no
       multiplier comes within its own rate of change of the unit circle,
       nor a real one within its rate of change of another real one), or
       until it is ``MIN_WIDTH`` short: then a radius >= 1 at its right end
       brackets the crossing, and otherwise the multiplier touches the
       circle within the resolution: undetermined.  A bracket is refined to
       ``rtol`` by Newton's method on |mu| with its exact derivative,
       safeguarded by bisection (every iterate stays in the bracket).

    The limit is the first depth either finds; stability below it rests on
    step 1 (exact) and the test of step 2 on every interval (the steps only
    choose the intervals: before, they were the scan depths, with the
    same test)."""
    budget = MAX_TANGENTS if max_tangents is None else max_tangents
    stop = depth_max if stop is None else stop
    flips = sm.unit_depths(-1.0, stop)
    folds = sm.unit_depths(1.0, stop)
    flips, folds = flips[flips > start], folds[folds > start]
    reals = [(float(a), "flip", -1.0) for a in flips] + [(float(a), "fold", 1.0) for a in folds]
    a_real, kind_real, z_real = min(reals) if reals else (np.inf, "", 0.0)
    end = min(a_real, stop)
    cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}
    count = [0]

    def fetch(points: list[float]) -> None:
        todo = [a for a in dict.fromkeys(points) if a not in cache]
        if todo:
            count[0] += len(todo)
            for a, v in zip(todo, sm.tangents(np.array(todo)), strict=True):
                cache[a] = v

    def data(a: float) -> tuple[np.ndarray, np.ndarray]:
        if a not in cache:
            fetch([a])
        return cache[a]

    def radius(a: float) -> float:
        return float(np.max(np.abs(data(a)[0])))

    certified = [start]

    class _Stop(Exception):
        pass

    def refine(lo: float, hi: float) -> tuple[str, float] | None:
        if count[0] > budget + scan:
            raise _Stop
        skip = z_real if hi == a_real else None
        if radius(hi) < 1.0 or skip is not None:
            if _interval_safe(data(lo), data(hi), hi - lo, skip):
                certified[0] = hi
                return None
        if skip is None and radius(hi) >= 1.0 and _simple_bracket(data(lo), data(hi), hi - lo):
            return "hopf", hi
        if hi - lo <= MIN_WIDTH * hi:
            if skip is not None:  # the flip/fold depth itself, certified to within MIN_WIDTH
                return "real", hi
            if radius(hi) >= 1.0:
                return "hopf", hi
            return "undetermined", lo
        mid = 0.5 * (lo + hi)
        return refine(lo, mid) or refine(mid, hi)

    found: tuple[str, float] | None = None
    cap = (depth_max / scan) * STEP_CAP
    try:
        lo = start
        while lo < end and found is None:
            if count[0] > budget + scan:
                raise _Stop
            hi = min(end, lo + max(min(cap, _step(*data(lo), end - lo)), MIN_WIDTH * end))
            if end - hi <= MIN_WIDTH * end:
                hi = end
            found = refine(lo, hi)
            lo = hi
    except _Stop:
        found = ("undetermined", certified[0])
    fl, fo = tuple(float(a) for a in flips), tuple(float(a) for a in folds)
    if found is None:
        if np.isfinite(a_real) and a_real <= stop:
            mu, dmu = data(a_real)
            i = int(np.argmin(np.abs(mu - z_real)))
            return Certified("crossing", a_real, kind_real, a_real, count[0], _slope(mu, dmu, i), fl, fo)
        return Certified("stable", np.inf, "", stop, count[0], np.nan, fl, fo)
    status, a = found
    if status == "real":
        mu, dmu = data(a_real)
        i = int(np.argmin(np.abs(mu - z_real)))
        return Certified("crossing", a_real, kind_real, certified[0], count[0], _slope(mu, dmu, i), fl, fo)
    if status == "undetermined":
        return Certified("undetermined", a, "undetermined", certified[0], count[0], np.nan, fl, fo)
    # a bracket [lo, a] with rho < 1 at the left end, >= 1 at the right
    lo = max(k for k in cache if k < a)
    root = _newton(data, lo, a, rtol) if radius(lo) < 1.0 <= radius(a) else a
    mu, dmu = data(min(cache, key=lambda x: abs(x - root)))  # within rtol a of the root
    i = int(np.argmax(np.abs(mu)))
    # the bracket passed _simple_bracket (one crossing in it) or is MIN_WIDTH short: stable to the root
    return Certified("crossing", float(root), "hopf", float(root), count[0], _slope(mu, dmu, i), fl, fo)


def _newton(
    data: Callable[[float], tuple[np.ndarray, np.ndarray]], lo: float, hi: float, rtol: float
) -> float:
    """The depth in [lo, hi] where the spectral radius is 1 (rho(lo) < 1 <= rho(hi)), to
    ``rtol`` relative: Newton's method on rho - 1 with d|mu|/da of the top multiplier, a
    bisection wherever a step would leave the bracket or not halve it (rtsafe, Press et al.,
    Numerical Recipes, sec. 9.4); it converges quadratically at a simple crossing, so a Newton
    step shorter than rtol a ends within ~(rtol a)^2 |rho''| / rho' of the root: that end is
    returned without evaluating it (the caller takes the slope and the eigenvector at the
    last evaluated depth, within rtol a)."""

    def g(a: float) -> tuple[float, float]:
        mu, dmu = data(a)
        i = int(np.argmax(np.abs(mu)))
        return float(abs(mu[i])) - 1.0, _slope(mu, dmu, i)

    f_lo, s_lo = g(lo)
    f_hi, s_hi = g(hi)
    x, fx, sx = (hi, f_hi, s_hi) if abs(f_hi) < abs(f_lo) else (lo, f_lo, s_lo)
    step_old = hi - lo
    for _ in range(100):
        if fx == 0.0:
            return x
        newton_ok = np.isfinite(sx) and sx > 0.0
        nx = x - fx / sx if newton_ok else np.nan
        if not (newton_ok and lo < nx < hi and abs(nx - x) < 0.5 * abs(step_old)):
            nx = 0.5 * (lo + hi)  # bisection
            newton_ok = False
        step = nx - x
        if newton_ok and abs(step) <= rtol * abs(nx):
            return nx  # within C step^2 << rtol a of the root: no need to evaluate it
        step_old, x = step, nx
        fx, sx = g(x)
        if fx < 0.0:
            lo = x
        else:
            hi = x
        if abs(step_old) <= rtol * x or hi - lo <= rtol * x:
            break
    return x


def _helix_rho(
    loop: ClosedLoop,
    rpm: float,
    degree: int | None,
    elements: int | None,
    span: float,
    qs: QuasiStatic | None,
) -> Callable[[float], float]:
    def rho(a: float) -> float:
        sm = SpectralMonodromy(
            loop, rpm, degree, elements, depth=a, depth_hint=0.0, span=span, quasi_static=qs
        )
        return sm.radius(a)

    return rho


def _sdm_top(loop: ClosedLoop, rpm: float, steps: int) -> Callable[[float], complex]:
    def mu_at(a: float) -> complex:
        ev = np.linalg.eigvals(sdm_monodromy(loop, rpm, a, steps))
        return complex(ev[np.argmax(np.abs(ev))])

    return mu_at


def _abs_of(f: Callable[[float], complex]) -> Callable[[float], float]:
    return lambda a: abs(f(a))


def floquet_limit(
    loop: ClosedLoop,
    r: float,
    method: str,
    depth_max: float,
    scan: int,
    rtol: float,
    degree: int | None,
    elements: int | None,
    steps: int,
    check: bool,
    target: float,
    split: tuple[QuasiStatic, QuasiStatic | None] | None = None,
) -> tuple[float, float, complex, float, int, int, str, float, float]:
    """a_lim at speed ``r`` (rpm), its error estimate, the critical multiplier
    and chatter frequency there, the evaluations and the mesh refinements,
    the basis of the claim, the depth to which stability is established and
    the part of the error estimate that is the split's:
    (a, error, mu, frequency_hz, evaluations, refined, basis, certified, split_error).

    ``split``: the structure's quasi-static split (:func:`split_structure`)
    and the finer one that checks it (its modes up to twice the frequency),
    for a structure whose own discretisation is too large
    (:func:`needs_split`); the check's change of rho at the limit, through
    the slope, is added to the error.

    ``basis`` is ``"complete"`` (spectral without helix:
    :func:`certified_crossing`), ``"undetermined"`` (that search could not
    decide beyond ``certified``; a is then ``certified``, a lower bound) or
    ``"scan"`` (helix or SDM: the first crossing seen on the scan, a band
    narrower than the scan step between stable scan depths can be missed).
    a is inf (mu and the frequency nan) when no crossing is found."""
    milling = loop.milling
    helix = milling.helix > 0
    qs = split[0] if split is not None else None
    if method == "spectral" and not helix:
        return _complete_limit(loop, r, depth_max, scan, rtol, degree, elements, check, target, split)
    T = milling.period(float(r))
    rho: Callable[[float], float]
    mu_at: Callable[[float], complex]
    span = ELEMENT_SPAN
    evals = refined = 0
    err = np.nan
    for attempt in range(4):
        if method == "spectral":
            rho = _helix_rho(loop, float(r), degree, elements, span, qs)
        else:
            mu_at = _sdm_top(loop, float(r), steps)
            rho = _abs_of(mu_at)
        a, cnt, slope = _first_crossing(rho, depth_max, scan, rtol)
        evals += cnt
        if method != "spectral" or not check or not np.isfinite(a):
            break
        sm = SpectralMonodromy(
            loop, float(r), degree, elements, depth=a, depth_hint=0.0, span=span, quasi_static=qs
        )
        sm2 = SpectralMonodromy(
            loop, float(r), mesh=sm.mesh.raised(CHECK_DEGREE), depth=a, depth_hint=0.0, quasi_static=qs
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
        return a, err, complex(np.nan, 0.0), np.nan, evals, refined, "scan", np.nan, np.nan
    if method == "spectral":
        if not check:
            sm = SpectralMonodromy(
                loop, float(r), degree, elements, depth=a, depth_hint=0.0, span=span, quasi_static=qs
            )
        mu, freq = sm.critical(a)
    else:
        mu = mu_at(a)
        freq = chatter_frequency(mu, T, loop)
    return a, err, mu, freq, evals, refined, "scan", np.nan, np.nan


def _complete_limit(
    loop: ClosedLoop,
    r: float,
    depth_max: float,
    scan: int,
    rtol: float,
    degree: int | None,
    elements: int | None,
    check: bool,
    target: float,
    split: tuple[QuasiStatic, QuasiStatic | None] | None = None,
) -> tuple[float, float, complex, float, int, int, str, float, float]:
    """:func:`floquet_limit` for the spectral method without helix: the
    complete search (:func:`certified_crossing`) and the convergence check
    of its limit, on a finer discretisation where the check asks for one.

    The automatic mesh (``degree`` and ``elements`` None) is sized for the
    depths it searches: the cut stiffens the structure (at a_p it adds
    ~a_p |H| to its stiffness), so the search runs in stages (0, D/16],
    (D/16, D/4], (D/4, D] (D = depth_max), each on the mesh whose degrees
    resolve the solution at the stage's deepest cut (:func:`auto_degree`
    aiming at target / TOL_SHARE); a stage whose mesh is that of the one before
    continues on it.  Stability established on a stage rests on that stage's
    mesh.  Where the check misses ``target`` the stage of the limit is
    searched again on a finer mesh (degrees for a tolerance 100 times
    smaller at the limit's depth; an explicit degree: elements half as
    long), up to three times."""
    auto = degree is None and elements is None
    tol = target / TOL_SHARE
    qs, qs2 = split if split is not None else (None, None)
    base = qs.loop if qs is not None else loop  # the modes integrated in time set the mesh
    stages = [depth_max / 16.0, depth_max / 4.0, depth_max] if auto else [depth_max]
    span = ELEMENT_SPAN
    evals = refined = 0
    err = np.nan
    lo = 0.0

    sm: SpectralMonodromy | None = None

    def mesh_for(hint: float, tol_: float, span_: float) -> Any:
        if auto:
            return spectral_mesh(base, float(r), None, depth_hint=hint, tol=tol_)
        return spectral_mesh(base, float(r), degree, elements, span=span_)

    def build(mesh: Any) -> SpectralMonodromy:
        """The discretisation on ``mesh``; the current one if its mesh is that."""
        if sm is not None and _same_mesh(sm.mesh, mesh):
            return sm
        return SpectralMonodromy(loop, float(r), mesh=mesh, quasi_static=qs)

    # a stage whose mesh has at most MERGE times the nodes of the next one's is searched on the next
    # one's (finer) mesh: a new set-up costs more than the few extra nodes
    meshes = [mesh_for(h, tol, span) for h in stages]
    plan: list[tuple[float, Any]] = []
    for h, m in zip(stages, meshes, strict=True):
        while plan and int(m.deg.sum()) <= MERGE * int(plan[-1][1].deg.sum()):
            plan.pop()
        plan.append((h, m))
    # each planned stage covers the depths down to the previous planned stage's end
    for hi, mesh in plan:
        sm = build(mesh)
        c = certified_crossing(sm, depth_max, scan, rtol, start=lo, stop=hi)
        evals += c.evaluations
        if c.status != "stable":
            break
        lo = hi
    assert sm is not None
    for attempt in range(4):
        if not check or c.status != "crossing":
            break
        sm2 = SpectralMonodromy(loop, float(r), mesh=sm.mesh.raised(CHECK_DEGREE), quasi_static=qs)
        err = abs(sm2.radius(c.depth) - 1.0) / abs(c.slope) if c.slope else np.inf
        evals += 1
        if err <= target * c.depth or (elements is not None and not auto) or attempt == 3:
            break
        # the stage of the limit again, finer (stability below it rests on the stages before)
        tol /= 100.0
        span /= 2.0
        sm = build(mesh_for(c.depth, tol, span))
        c = certified_crossing(sm, depth_max, scan, rtol, start=lo, stop=hi)
        evals += c.evaluations
        refined += 1
    e_split = np.nan
    if c.status == "stable":
        return np.inf, err, complex(np.nan, 0.0), np.nan, evals, refined, "complete", depth_max, e_split
    if c.status == "undetermined":
        return (
            c.depth,
            np.nan,
            complex(np.nan, 0.0),
            np.nan,
            evals,
            refined,
            "undetermined",
            c.certified,
            e_split,
        )
    if (
        check and qs2 is not None
    ):  # the split: the same limit with the modes up to twice its frequency in time
        mesh2 = spectral_mesh(qs2.loop, float(r), None, depth_hint=c.depth, tol=tol)
        sm3 = SpectralMonodromy(loop, float(r), mesh=mesh2, quasi_static=qs2)
        e_split = abs(sm3.radius(c.depth) - 1.0) / abs(c.slope) if c.slope else np.inf
        err = err + e_split
        evals += 1
    mu, freq = sm.critical(c.depth, near=max(rtol, 1e-12) * c.depth)
    return c.depth, err, mu, freq, evals, refined, "complete", c.certified, e_split


def _same_mesh(ma: Any, mb: Any) -> bool:
    """Two meshes with the same elements and degrees."""
    return bool(ma.a.size == mb.a.size and np.array_equal(ma.deg, mb.deg) and np.array_equal(ma.a, mb.a))
