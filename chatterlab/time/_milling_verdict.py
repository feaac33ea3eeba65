"""The verdict of a milling run (:mod:`chatterlab.time._milling`): the dominant
multiplier fitted to the Poincare samples, the growth per period and its
error, the chatter frequency, and the rule that reads stable, Hopf or flip
chatter from them (stated in the docstring of :mod:`chatterlab.time._milling`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__: list[str] = []

FloatArray = NDArray[Any]
_MIN_WINDOW = 20


def _dmd(d: FloatArray, rtol: float = 1e-7) -> complex:
    """Dominant multiplier of the linear map fitted to the delay-embedded
    deviations z_p = (d_p, d_{p+1}) -> z_{p+1} (Hankel dynamic mode
    decomposition): several pairs of multipliers, e.g. the x and y modes of a
    2-DOF tool, are resolved (a scalar order-2 Prony fit assumes one pair).
    Each snapshot pair is scaled by |z_p| (the samples span decades);
    singular values below ``rtol`` x the largest are dropped (round-off,
    modes decayed away)."""
    if d.shape[0] < 4:
        return complex("nan")
    Z = np.hstack([d[:-1], d[1:]])  # (n_p - 1, 2k)
    X, Y = Z[:-1].T, Z[1:].T
    scale = np.linalg.norm(X, axis=0)
    ok = scale > 0
    if np.sum(ok) < 3:
        return complex("nan")
    X, Y = X[:, ok] / scale[ok], Y[:, ok] / scale[ok]
    U, S, Vt = np.linalg.svd(X, full_matrices=False)
    r = int(np.sum(S > rtol * S[0]))
    A = U[:, :r].T @ Y @ Vt[:r].T / S[:r]
    ev = np.linalg.eigvals(A)
    return complex(ev[np.argmax(np.abs(ev))])


def _analyse(
    pt: FloatArray, w1: float, nonlinear: bool, fc: float, T: float, res: float, diverged: bool = False
) -> tuple[float, float, float, complex, str, str]:
    """Growth per period, its fit error, slope, multiplier, verdict and reason from the samples
    pt (n_p, 4), the chatter frequency fc (Hz), the sampled period T (s) and the
    spectral resolution res (Hz).  A run that diverged is judged on the
    samples it has (at least 8 periods in the window), and only growth is
    concluded from it."""
    s = pt.copy()
    s[:, 2:] /= w1
    n_p = s.shape[0]
    first = n_p // 2
    win = s[first:]
    d = np.diff(win, axis=0)
    P_w = d.shape[0]
    need = 8 if diverged else _MIN_WINDOW
    if P_w < need:
        return (
            math.nan, math.nan, math.nan, complex("nan"), "undetermined",
            f"run too short: {P_w} periods in the analysed last half (need >= {need}: "
            f"run >= {2 * need + 2} periods)" + (" before it diverged" if diverged else ""),
        )  # fmt: skip
    e = np.linalg.norm(d, axis=1)
    scale = float(np.max(np.linalg.norm(win, axis=1)))
    tiny = 1e-300
    slope = float(np.polyfit(np.arange(P_w), np.log(np.maximum(e, tiny)), 1)[0])
    mu = _dmd(d)
    growth = math.log(abs(mu)) if np.isfinite(abs(mu)) and abs(mu) > 0 else math.nan
    mu_q = _dmd(d[P_w // 2 :])  # the last quarter of the run: the fit's own uncertainty
    g_q = math.log(abs(mu_q)) if np.isfinite(abs(mu_q)) and abs(mu_q) > 0 else math.nan
    g_err = abs(growth - g_q)
    D = slope * P_w
    base = f"over the last {P_w} periods the deviations changed by exp({D:.3g})"
    converged = float(np.max(e[-5:])) <= 1e-8 * max(scale, tiny)
    verdict, reason = _verdict(D, converged, mu, P_w, win, nonlinear, fc, T, res)
    if diverged:
        reason += " (the run diverged)"
        if D < math.log(10.0):
            verdict = "undetermined"
    return growth, g_err, slope, mu, verdict, base + reason


def _verdict(
    D: float,
    converged: bool,
    mu: complex,
    P_w: int,
    win: FloatArray,
    nonlinear: bool,
    fc: float,
    T: float,
    res: float,
) -> tuple[str, str]:
    """The rule of the module docstring: (verdict, the end of the reason)."""
    if D <= -math.log(10.0):
        return "stable", " <= 1/10: the samples converge to a fixed point (periodic motion)"
    if converged:
        return "stable", ": the samples are converged to 1e-8"
    if D >= math.log(10.0):
        tol_angle = math.pi / P_w
        ang = abs(math.atan2(mu.imag, mu.real)) if np.isfinite(abs(mu)) else math.nan
        what = f" >= 10; dominant multiplier {mu:.4g} (|arg| = {ang:.3g} rad)"
        if abs(mu.imag) <= 1e-12 * abs(mu) and mu.real < 0 or ang >= math.pi - tol_angle:
            return "flip chatter", what
        if tol_angle < ang < math.pi - tol_angle:
            return "Hopf chatter", what
        return "undetermined", what + ": real and positive"
    if abs(D) > math.log(2.0):
        return "undetermined", ": neither converged nor steady; run longer"
    if not nonlinear:
        return "undetermined", ": a linear run at the stability limit (|mu| ~ 1)"
    d1 = float(np.mean(np.linalg.norm(win[1:] - win[:-1], axis=1)))
    d2 = float(np.mean(np.linalg.norm(win[2:] - win[:-2], axis=1)))
    bounded = f" (bounded); |s_p+2 - s_p| / |s_p+1 - s_p| = {d2 / d1:.3g}"
    if not math.isfinite(fc):
        return "undetermined", bounded + "; no chatter peak off the harmonics of 1/T"
    if abs(fc * T - math.floor(fc * T) - 0.5) / T <= res:
        return "flip chatter", bounded + f"; chatter at {fc:.6g} Hz, a half harmonic of 1/T"
    return "Hopf chatter", bounded + f"; chatter at {fc:.6g} Hz, not a (half) harmonic of 1/T"


def _chatter_frequency(t: FloatArray, x: FloatArray, y: FloatArray, f_rev: float) -> tuple[float, float]:
    """Largest spectral peak of the last half of x or y (the larger) farther
    than two resolutions from every multiple of ``f_rev`` (the frequency of
    the sampled period: harmonics of the forced periodic motion), Hz, and
    that tolerance (two resolutions), Hz."""
    from ._signals import amplitude_spectrum, peaks

    half = t.size // 2
    if t.size - half < 16:
        return math.nan, math.nan
    tt = t[half:]
    res = 2.0 / (tt[-1] - tt[0])
    sig = x[half:] if np.ptp(x[half:]) >= np.ptp(y[half:]) else y[half:]
    if not np.ptp(sig) > 0:
        return math.nan, res
    f, a = amplitude_spectrum(tt, sig, detrend="constant")
    fp, ap = peaks(f, a, n=30, fmin=0.5 * f_rev)
    for fk, _ in zip(fp, ap, strict=True):
        k = round(fk / f_rev)
        if abs(fk - k * f_rev) > res:
            return float(fk), res
    return math.nan, res


def natural_frequencies(M: FloatArray, K: FloatArray) -> FloatArray:
    """Undamped natural circular frequencies of ``M q'' + K q = 0``, rad/s."""
    from scipy.linalg import eigh, eigvals

    try:
        lam = eigh(K, M, eigvals_only=True) if np.allclose(K, K.T) and np.allclose(M, M.T) else None
    except np.linalg.LinAlgError:
        lam = None
    if lam is None:
        lam = np.real(eigvals(np.linalg.solve(M, K)))
    return np.sqrt(np.clip(lam, 0.0, None))
