"""Between the measured frequencies of an FRF: the cubic spline through the
samples and the estimate of its error (the method is described in
:meth:`chatterlab.structure.FRF.interpolate` and
:meth:`chatterlab.structure.FRF.interpolation_error`).

The functions work on the stack of matrices ``H`` (n_freq, n_out, n_in),
the layout of the spline (one curve per entry along the first axis); the
FRF hands them ``FRF.matrices`` and returns its own axis order.

References
----------
.. [1] C. A. Hall, W. W. Meyer, "Optimal error bounds for cubic spline
   interpolation", J. Approx. Theory 16, 105-122, 1976.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InputError

#: relative tolerance on the band ends (a frequency that prints equal is inside)
BAND_TOL = 1e-12


def check_frequency(w: np.ndarray, source: str) -> None:
    """Finite, >= 0 and strictly increasing angular frequencies, else one
    line naming the first offending point (in Hz)."""
    if not np.all(np.isfinite(w)):
        raise InputError(f"{source}: frequencies must be finite")
    if np.any(w < 0):
        raise InputError(f"{source}: frequencies must be >= 0 (got {w.min() / (2 * np.pi):g} Hz)")
    d = np.diff(w)
    if np.any(d <= 0):
        k = int(np.nonzero(d <= 0)[0][0])
        what = "repeated" if d[k] == 0 else "decreasing"
        raise InputError(
            f"{source}: frequencies must increase strictly; {w[k + 1] / (2 * np.pi):g} Hz after"
            f" {w[k] / (2 * np.pi):g} Hz is {what} (point {k + 2}); sort the data and drop duplicates"
        )


def spline(x: np.ndarray, H: np.ndarray) -> Any:
    """The cubic splines (not-a-knot) of Re H and Im H of every entry, in w."""
    from scipy.interpolate import CubicSpline

    n = x.size
    flat = H.reshape(n, -1)
    y = np.concatenate([flat.real, flat.imag], axis=1)
    return CubicSpline(x, y, axis=0, bc_type="not-a-knot", extrapolate=False)


def spline_values(sp: Any, x: np.ndarray, H: np.ndarray, w: np.ndarray, inside: np.ndarray) -> np.ndarray:
    """The spline at ``w`` (n_w, n_out, n_in), the samples exactly where ``w``
    is one, NaN outside the band (``inside`` False)."""
    n, no, ni = H.shape
    wc = np.clip(w, x[0], x[-1])
    y = sp(wc)
    out = (y[:, : no * ni] + 1j * y[:, no * ni :]).reshape(w.size, no, ni)
    # exact at the samples (the spline passes through them to round-off; make it exact)
    k = np.searchsorted(x, wc)
    k = np.minimum(k, n - 1)
    hit = x[k] == wc
    out[hit] = H[k[hit]]
    out[~inside] = np.nan
    return out


def spline_error(
    x: np.ndarray, H: np.ndarray, slope: np.ndarray, w: np.ndarray, inside: np.ndarray
) -> np.ndarray:
    """The leading-order spline error over the interval holding each w
    (n_w, n_out, n_in); ``slope``: :func:`slope_errors`."""
    n = x.size
    if n < 5:
        return np.full((w.size,) + H.shape[1:], np.inf)
    j = np.clip(np.searchsorted(x, w) - 1, 0, n - 2)  # interval [x_j, x_j+1]
    h = x[j + 1] - x[j]
    # the fourth derivative (complex, per entry) at mid-interval: the mean of the fourth
    # divided differences of the five samples from x_j-2 and from x_j-1
    s0, s1 = np.clip(j - 2, 0, n - 5), np.clip(j - 1, 0, n - 5)
    d4 = 12.0 * (_newton(x, H, s0, 5)[4] + _newton(x, H, s1, 5)[4])
    t = np.linspace(0.0, 1.0, 17)[1:-1, None, None, None]
    hh = h[None, :, None, None]
    e = -(d4[None] / 24.0) * hh**4 * t**2 * (1 - t) ** 2 + hh * (
        t * (1 - t) ** 2 * slope[j][None] - t**2 * (1 - t) * slope[j + 1][None]
    )
    err = np.max(np.abs(e), axis=0)
    err[~inside] = np.nan
    return err


def slope_errors(sp: Any, x: np.ndarray, H: np.ndarray) -> np.ndarray:
    """d_j = s'(x_j) - H'(x_j) at every sample, (n, n_out, n_in): the
    spline's slope less that of the polynomial through the seven samples
    around x_j (whose slope error, O(h^6), is below the spline's)."""
    n, no, ni = H.shape
    ds = sp.derivative()(x)
    spline_slope = (ds[:, : no * ni] + 1j * ds[:, no * ni :]).reshape(n, no, ni)
    k = min(7, n)  # the polynomial through the k (7) samples around x_j
    s = np.clip(np.arange(n) - k // 2, 0, n - k)
    c = _newton(x, H, s, k)
    P = np.ones(n)
    dP = np.zeros(n)
    poly_slope = np.zeros_like(spline_slope)
    for i in range(k):  # d/dx of the Newton form sum_i c_i prod_{l<i} (x - x_l)
        poly_slope += c[i] * dP[:, None, None]
        xk = x[s + i]
        dP = dP * (x - xk) + P
        P = P * (x - xk)
    return spline_slope - poly_slope


def _newton(x: np.ndarray, H: np.ndarray, s: np.ndarray, k: int) -> list[np.ndarray]:
    """Newton divided differences H[x_s], H[x_s, x_s+1], ..., H[x_s .. x_s+k-1]
    of the k samples from index s (one start per entry of ``s``), each
    (len(s), n_out, n_in), complex."""
    idx = s[:, None] + np.arange(k)[None, :]
    xs = x[idx]
    dd = H[idx]
    out = [dd[:, 0]]
    for level in range(1, k):
        den = (xs[:, level:] - xs[:, : k - level])[:, :, None, None]
        dd = (dd[:, 1:] - dd[:, :-1]) / den
        out.append(dd[:, 0])
    return out
