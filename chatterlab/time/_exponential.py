"""The exponential integrator of a time-invariant delayed loop: an exact step
map with the delayed term integrated against an interpolant of the history.

Between events the closed loop of a continuous cut is linear with constant
coefficients, ``A q'' + B q' + C q = f(t) + G q(t - T)``.  In first-order
form, ``x = [q, q']``,

.. math::

    x' = L x + N\\,z(t - T) + F f(t), \\quad
    L = \\begin{bmatrix} 0 & I \\\\ -A^{-1}C & -A^{-1}B \\end{bmatrix}, \\;
    N = \\begin{bmatrix} 0 \\\\ A^{-1} U \\end{bmatrix}, \\;
    F = \\begin{bmatrix} 0 \\\\ A^{-1} \\end{bmatrix}                       (1)

with ``G = U V^T`` of rank ``r`` (the cut's few directions) and ``z = V^T q``.
The variation-of-constants formula over one step ``t_n -> t_n + h`` is exact
(Hochbruck & Ostermann 2010, Eq. 1.4):

.. math::

    x_{n+1} = e^{hL} x_n + \\int_0^1 e^{hL(1-\\tau)} h
              \\left[N z(t_n + \\tau h - T) + F f(t_n + \\tau h)\\right] d\\tau.  (2)

The step is ``h = T/m`` (a whole number ``m`` of steps per delay), so the
delayed argument runs over the stored interval ``[t_{n-m}, t_{n-m+1}]``;
``z`` is replaced there by its Lagrange interpolant of degree ``p`` through
the ``p + 1`` stored nodes ``t_{n-m+i}``, ``i = i_0 .. i_0 + p``,

.. math::

    z(t_{n-m} + \\tau h) \\approx \\sum_i \\ell_i(\\tau)\\, z_{n-m+i},
    \\qquad \\ell_i(\\tau) = \\sum_{k=0}^p c_{ik}\\, \\tau^k/k!,             (3)

and the force by its interpolant through ``p + 1`` equispaced points of the
step.  The step map is then exact for the interpolants:

.. math::

    x_{n+1} = E x_n + \\sum_i W_i z_{n-m+i} + \\sum_j W^f_j f(t_n + jh/p),
    \\quad E = e^{hL},\\; W_i = \\sum_k c_{ik} \\Phi_k,                       (4)

.. math::

    \\Phi_k = \\int_0^1 e^{hL(1-\\tau)} h N \\frac{\\tau^k}{k!} d\\tau
    = \\left[\\exp \\begin{bmatrix} hL & hN & & \\\\ & 0 & I & \\\\
      & & \\ddots & I \\\\ & & & 0 \\end{bmatrix}\\right]_{1,k+2}          (5)

(Van Loan 1978: one matrix exponential of the block matrix with a chain of
``p + 1`` identity blocks gives ``E`` and every ``\\Phi_k``; the same chain on
``F`` gives the force weights).  The interpolation error of ``z`` is
``O(h^{p+1})`` on the interval, its integral over a step ``O(h^{p+2})``: the
global error of Eq. (4) is ``O(h^{p+1})`` (order ``p + 1``; default ``p = 5``,
the stencil ``i = -2 .. 3`` centred on the interval).  The homogeneous part
is exact for every mode, however stiff.  A stencil never straddles the
instants ``t_0 + kT`` (``k = 0 .. p + 1``) where the solution of a DDE is
less smooth (a history inconsistent with the initial state makes ``q''``
jump at ``T``, ``q'''`` at ``2T``, ...): there it is shifted to one side.

**Error control.**  With a tolerance ``rtol`` the run is made at ``h``, ``2h``
and ``4h`` (a whole number of steps per delay, a multiple of 4).  For a
scheme of order ``q = p + 1`` the error of the ``h`` run is ``e_h ~ c h^q``
and ``d1 = |y_h - y_{2h}| = e_h (2^q - 1)``; the ratio ``rho = d2/d1``
(``d2 = |y_{2h} - y_{4h}|``) is ``2^q`` once the error is asymptotic.  Before
that (a mode of the delayed loop still under-resolved) it is smaller, so the
estimate

.. math::

    \\hat e_h = \\frac{d_1}{\\min(\\rho, 2^q) - 1} \\; (\\rho > 2), \\qquad
    \\hat e_h = d_1 \\; (\\rho \\le 2)                                        (6)

(each output relative to its largest value) is Richardson's when the order
is observed and more cautious otherwise.  Above ``rtol`` the steps per delay
are doubled once to three times, as ``(\\hat e_h / (rtol/2))^{1/q}`` asks, and
the estimate repeated (the runs at ``2h`` and ``4h`` are then runs already
made: a doubling costs one new run).  The first try resolves the dominant mode of the delayed loop
(``(w h)^q = 10 rtol``).  The step chosen, the estimate and the tries are in
the result's ``attrs``.

References
----------
.. [1] M. Hochbruck and A. Ostermann, "Exponential integrators", Acta
   Numerica 19, 209-286, 2010 (Eqs. 1.4, 2.1; the phi-functions).
.. [2] C. F. Van Loan, "Computing integrals involving the matrix exponential",
   IEEE Trans. Automatic Control 23(3), 395-404, 1978.
.. [3] A. Bellen and M. Zennaro, *Numerical methods for delay differential
   equations*, Oxford University Press 2003 (ch. 3: the method of steps,
   breaking points and the order of continuous extensions).
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from chatterlab.errors import InputError

from ._options import TimeResponse, check_rtol
from ._plan import _check_problem, _history_function, _outputs, _vector
from ._problems import FloatArray

__all__ = ["exponential", "DEFAULT_DEGREE", "DEFAULT_RTOL"]

#: the interpolation degree p of the delayed term: order p + 1
DEFAULT_DEGREE = 5
#: the relative error of the recorded outputs the step is chosen for
DEFAULT_RTOL = 1e-3
#: the step reductions tried before the best run is returned with a note
MAX_TRIES = 5
#: the states stored for the whole run (the delayed nodes and the record), bytes
MAX_STATE_BYTES = 1024**3


@dataclass(frozen=True)
class _Loop:
    """Eq. (1) of one time-invariant problem: ``L``, the rank-``r`` delayed
    input (``N``, ``Vt``), the force (constant ``f0`` or callable) and its
    input ``F``; the matrices for the accelerations."""

    n: int
    A: FloatArray
    B: FloatArray
    C: FloatArray
    G: FloatArray | None
    T: float | None
    L: FloatArray
    N: FloatArray  # (2n, r)
    Vt: FloatArray  # (r, n)
    F: FloatArray  # (2n, n)
    f0: FloatArray | None  # constant force, else None
    problem: Any


def _loop(problem: Any, t0: float) -> _Loop:
    """The first-order form of a time-invariant problem, or one line saying why not."""
    n = _check_problem(problem)
    if not getattr(problem, "time_invariant", False):
        raise InputError(
            "the exponential integrator needs constant coefficients (a ConstantProblem); integrate "
            "a time-varying problem with newmark()"
        )
    bp = getattr(problem, "breakpoints", None)
    if callable(bp) and len(tuple(bp())):
        raise InputError(
            "the exponential integrator interpolates the force across a step: a force with breakpoints "
            "needs newmark() (or split the run at them)"
        )
    A, B, C, G = (
        None if x is None else np.array(x[0], dtype=float) for x in problem.matrices(np.array([t0]))
    )
    assert A is not None and B is not None and C is not None
    try:
        Ai = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        raise InputError("A (the mass matrix) is singular: condense the massless coordinates first") from None
    L = np.zeros((2 * n, 2 * n))
    L[:n, n:] = np.eye(n)
    L[n:, :n] = -Ai @ C
    L[n:, n:] = -Ai @ B
    F = np.vstack([np.zeros((n, n)), Ai])
    T = problem.delay()
    if G is not None and np.any(G != 0.0):
        U, s, Vt = np.linalg.svd(G)
        r = int(np.count_nonzero(s > 1e-13 * s[0]))
        N = F @ (U[:, :r] * s[:r])
        Vt = np.ascontiguousarray(Vt[:r])
        T = float(T)
    else:
        G, T = None, None
        N, Vt = np.zeros((2 * n, 0)), np.zeros((0, n))
    raw = getattr(problem, "_force", "callable")
    f0 = None
    if raw is None or not callable(raw):
        f0 = np.array(problem.force(np.array([t0]))[0], dtype=float)
    return _Loop(n, A, B, C, G, T, L, N, Vt, F, f0, problem)


# =========================================================================== the step map


@functools.lru_cache(maxsize=64)
def _lagrange(first: float, p: int, scale: float) -> FloatArray:
    """``c`` with ``l_i(tau) = sum_k c[k, i] tau^k / k!`` the Lagrange basis on
    the nodes ``(first + i) / scale``, ``i = 0 .. p`` (Eq. 3)."""
    nodes = (first + np.arange(p + 1, dtype=float)) / scale
    V = np.vander(nodes, p + 1, increasing=True)  # V[i, k] = tau_i^k
    fact = np.array([math.factorial(k) for k in range(p + 1)], dtype=float)
    c = np.linalg.inv(V) * fact[:, None]
    c.setflags(write=False)
    return c


def _chain_exp(hL: FloatArray, inputs: list[tuple[FloatArray, int]]) -> tuple[FloatArray, list[FloatArray]]:
    """Eq. (5): ``E = e^{hL}`` and, for each ``(hN, p)``, the stack
    ``[Phi_0 .. Phi_p]`` (each ``(2n, r)``), from one exponential."""
    from scipy.linalg import expm

    s = hL.shape[0]
    size = s + sum(N.shape[1] * (p + 1) for N, p in inputs)
    M = np.zeros((size, size))
    M[:s, :s] = hL
    off, where = s, []
    for N, p in inputs:
        r = N.shape[1]
        M[:s, off : off + r] = N
        for k in range(p):
            a = off + k * r
            M[a : a + r, a + r : a + 2 * r] = np.eye(r)
        where.append((off, r, p))
        off += r * (p + 1)
    Z = expm(M)
    E = Z[:s, :s].copy()
    phis = [Z[:s, a : a + r * (p + 1)].reshape(s, p + 1, r) for a, r, p in where]
    return E, phis


@dataclass(frozen=True)
class _Maps:
    """The step map (4) at one step: ``E``, the delay weights for each
    stencil start ``i0`` (``(2n, (p+1) r)``), the force term (constant
    ``cf`` or weights ``Wf`` on ``p + 1`` points of the step)."""

    h: float
    m: int
    p: int
    E: FloatArray
    Wd: dict[int, FloatArray]
    cf: FloatArray | None
    Wf: FloatArray | None
    P: FloatArray | None = None
    Tm: FloatArray | None = None


def _maps(lp: _Loop, h: float, m: int, p: int) -> _Maps:
    inputs: list[tuple[FloatArray, int]] = []
    if lp.G is not None:
        inputs.append((h * lp.N, p))
    pf = 0 if lp.f0 is not None else p
    inputs.append((h * lp.F, pf))
    E, phis = _chain_exp(h * lp.L, inputs)
    Wd: dict[int, FloatArray] = {}
    if lp.G is not None:
        phi = phis[0]  # (2n, p+1, r)
        for i0 in range(1 - p, 1):
            c = _lagrange(float(i0), p, 1.0)  # (k, i)
            Wd[i0] = np.einsum("ski,kj->sji", phi, c).reshape(phi.shape[0], -1)  # (2n, (p+1) r) by node
    P, Tm = _powers(E) if E.shape[0] <= 16 else (None, None)
    phf = phis[-1]
    if lp.f0 is not None:
        return _Maps(h, m, p, E, Wd, phf[:, 0, :] @ lp.f0, None, P, Tm)
    c = _lagrange(0.0, pf, float(pf))
    Wf = np.einsum("ski,kj->sji", phf, c).reshape(phf.shape[0], -1)
    return _Maps(h, m, p, E, Wd, None, Wf, P, Tm)


def _stencil_starts(j: FloatArray, m: int, p: int) -> FloatArray:
    """``i0`` of the delayed interval ``[j, j + 1]`` (node indices): centred
    (``i0 = -(p - 1)//2``) but not across a breaking point ``0, m, .., (p+1) m``."""
    pref = -((p - 1) // 2)
    bps = np.arange(0, (p + 2) * m, m)
    k = np.searchsorted(bps, j, side="right")  # bps[k-1] <= j < bps[k]
    lo = np.where(k > 0, bps[np.maximum(k - 1, 0)], -(10**12))
    hi = np.where(k < bps.size, bps[np.minimum(k, bps.size - 1)], 10**12)
    lo_i0, hi_i0 = lo - j, hi - j - p
    i0 = np.clip(np.minimum(np.maximum(pref, lo_i0), hi_i0), 1 - p, 0)
    return i0.astype(int)


def _run(
    lp: _Loop,
    mp: _Maps,
    t0: float,
    n_total: int,
    q0: FloatArray,
    v0: FloatArray,
    hist: Any,
    limit: float,
) -> tuple[FloatArray, int, str]:
    """States ``x_0 .. x_N`` (rows ``[q, v]``) of Eq. (4); the steps done and a
    divergence reason (empty when none)."""
    n, p, m, h = lp.n, mp.p, mp.m, mp.h
    X = np.empty((n_total + 1, 2 * n))
    X[0, :n], X[0, n:] = q0, v0
    D = np.zeros((n_total, 2 * n))
    if mp.cf is not None:
        D += mp.cf
    else:
        assert mp.Wf is not None
        tf = t0 + h * np.arange(n_total * p + 1) / p
        Fg = np.asarray(lp.problem.force(tf), dtype=float)
        win = np.lib.stride_tricks.sliding_window_view(Fg, (p + 1, n))[::p, 0].reshape(n_total, -1)
        D += win @ mp.Wf.T
    if lp.G is None:
        return _recur(X, D, mp, 0, n_total, limit, n)
    Vt = lp.Vt
    # the steps whose delayed interval lies in the history (t <= t0): their inputs are known
    n_h = min(m, n_total)
    j_all = np.arange(n_total) - m  # the delayed interval of every step
    i0_all = _stencil_starts(j_all, m, p)
    j, i0 = j_all[:n_h], i0_all[:n_h]
    kh = np.arange(-m - p, 1)
    Zh = hist(t0 + h * kh) @ Vt.T  # history nodes -m-p .. 0 (node 0: the history's value at t0)
    _delayed(D, 0, j, i0, Zh, -m - p, mp)
    done, reason = _recur_part(X, D, mp, 0, n_h, limit, n)
    if reason or n_h == n_total:
        return X[: done + 1], done, reason
    Z = np.empty((n_total + 1, Vt.shape[0]))
    Z[: n_h + 1] = X[: n_h + 1, :n] @ Vt.T
    a = n_h
    block = m - p + 1  # the delayed nodes of steps a .. a + block - 1 are all <= a
    while a < n_total:
        b = min(a + block, n_total)
        _delayed(D, a, j_all[a:b], i0_all[a:b], Z, 0, mp)
        done, reason = _recur_part(X, D, mp, a, b, limit, n)
        if reason:
            return X[: done + 1], done, reason
        Z[a + 1 : b + 1] = X[a + 1 : b + 1, :n] @ Vt.T
        a = b
    return X, n_total, ""


def _delayed(
    D: FloatArray, a: int, j: FloatArray, i0: FloatArray, Z: FloatArray, z_first: int, mp: _Maps
) -> None:
    """Add ``sum_i W_i z_{j+i}`` (Eq. 4) to the rows ``a ..`` of D; ``Z[k]``
    is node ``z_first + k``."""
    p = mp.p
    if i0[0] == i0[-1] and (i0 == i0[0]).all():  # one stencil, consecutive intervals: a window view
        f0 = int(j[0] + i0[0] - z_first)
        win = np.lib.stride_tricks.sliding_window_view(Z[f0 : f0 + j.size + p], p + 1, axis=0)
        D[a : a + j.size] += win.transpose(0, 2, 1).reshape(j.size, -1) @ mp.Wd[int(i0[0])].T
        return
    for s in np.unique(i0):
        sel = np.nonzero(i0 == s)[0]
        first = j[sel] + s - z_first
        W = Z[first[:, None] + np.arange(p + 1)].reshape(sel.size, -1)
        D[a + sel] += W @ mp.Wd[int(s)].T


def _recur_part(
    X: FloatArray, D: FloatArray, mp: _Maps, a: int, b: int, limit: float, n: int
) -> tuple[int, str]:
    """``x_{k+1} = E x_k + d_k`` for ``k = a .. b - 1``, then the divergence check.

    A small state (``2n <= 16``) advances ``S`` steps per product,
    ``x_{k+i+1} = E^{i+1} x_k + sum_{j<=i} E^{i-j} d_{k+j}``, ``S 2n <= 256``
    (one matrix product instead of ``S`` Python steps); a larger one step by step."""
    E, P, Tm = mp.E, mp.P, mp.Tm
    s = E.shape[0]
    if P is not None and Tm is not None:
        S = P.shape[0] // s
        k = a
        while k < b:
            c = min(S, b - k)
            blk = P[: c * s] @ X[k] + Tm[: c * s, : c * s] @ D[k : k + c].reshape(-1)
            X[k + 1 : k + 1 + c] = blk.reshape(c, s)
            k += c
    else:
        dot = np.dot
        for k in range(a, b):
            row = X[k + 1]
            dot(E, X[k], out=row)
            row += D[k]
    blk = X[a + 1 : b + 1, :n]
    if np.isfinite(blk).all() and (blk.size == 0 or np.abs(blk).max() <= limit):
        return b, ""
    with np.errstate(all="ignore"):
        bad = ~np.isfinite(X[a + 1 : b + 1]).all(axis=1) | (np.abs(blk).max(axis=1) > limit)
    first = a + int(np.argmax(bad))
    return first, f"non-finite state or |q| > divergence_limit = {limit:.3g}"


def _powers(E: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``P`` (rows ``E^1 .. E^S`` stacked) and the block lower-triangular
    Toeplitz ``Tm`` (block ``(i, j)`` = ``E^{i-j}``, ``i >= j``) of a small
    ``E``, ``S 2n <= 256``."""
    s = E.shape[0]
    S = max(1, 256 // s)
    pw = [np.eye(s)]
    for _ in range(S):
        pw.append(E @ pw[-1])
    stack = np.array(pw)  # (S + 1, s, s)
    P = stack[1:].reshape(S * s, s)
    d = np.arange(S)[:, None] - np.arange(S)[None, :]
    T4 = stack[np.maximum(d, 0)] * (d >= 0)[:, :, None, None]  # (i, j, s, s)
    return P, np.ascontiguousarray(T4.transpose(0, 2, 1, 3).reshape(S * s, S * s))


def _recur(
    X: FloatArray, D: FloatArray, mp: _Maps, a: int, b: int, limit: float, n: int
) -> tuple[FloatArray, int, str]:
    done, reason = _recur_part(X, D, mp, a, b, limit, n)
    return X[: done + 1], done, reason


# =========================================================================== the entry


def exponential(
    problem: Any,
    t_span: tuple[float, float],
    q0: ArrayLike | None = None,
    v0: ArrayLike | None = None,
    *,
    rtol: float = DEFAULT_RTOL,
    h: float | None = None,
    degree: int = DEFAULT_DEGREE,
    outputs: Any = None,
    record_every: int = 1,
    history: Any = None,
    control: ArrayLike | None = None,
    divergence_limit: float = 1e12,
) -> TimeResponse:
    """Integrate ``A q'' + B q' + C q = f(t) + G q(t - T)`` (constant
    ``A, B, C, G``) with the exponential step map of order ``degree + 1``.

    Parameters
    ----------
    problem : ConstantProblem
        The time-invariant system (no force breakpoints).
    t_span : (float, float)
        Start and end time ``(t0, t1)``, s.
    q0, v0 : array_like, shape (n,), optional
        Initial displacement and velocity (zero by default).
    rtol : float, default 1e-3
        The relative error of the recorded outputs (each relative to its
        largest value) the step is chosen for, by Richardson's estimate of a
        run at ``h`` against one at ``2h`` (see the module notes).
    h : float, optional
        A fixed step, s, instead of the error control (rounded down to a
        whole number of steps per delay).
    degree : int, default 5
        Degree ``p`` of the history's interpolant (1 .. 7): order ``p + 1``.
    outputs, record_every, history
        As :func:`~chatterlab.time.newmark`.
    control : array_like, shape (k, n), optional
        The rows ``y = control @ q`` whose relative error ``rtol`` bounds
        (default: the recorded outputs).
    divergence_limit : float, default 1e12
        ``max |q|`` beyond which the run stops with ``status="diverged"``.

    Returns
    -------
    TimeResponse
        ``attrs``: ``method`` ("exponential"), ``order``, ``rtol``,
        ``error_estimate`` (Richardson's, None for a fixed step),
        ``steps_per_delay``, ``tries`` (steps tried before the one kept).

    Raises
    ------
    InputError
        A time-varying problem, force breakpoints, bad ``rtol``, ``h``,
        ``degree``, shapes, or a run whose states exceed 1 GiB.
    """
    wall0 = time.perf_counter()
    try:
        t0, t1 = (float(x) for x in t_span)
    except (TypeError, ValueError):
        raise InputError(f"t_span must be a pair (t0, t1) of numbers in s (got {t_span!r})") from None
    if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
        raise InputError(f"t_span: t1 must be > t0, both finite (got {t_span!r})")
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or not 1 <= degree <= 7:
        raise InputError(f"degree must be an integer 1..7 (got {degree!r})")
    p = int(degree)
    check_rtol(rtol)
    if h is not None and not (isinstance(h, (int, float)) and math.isfinite(h) and h > 0):
        raise InputError(f"h (the step) must be a number > 0 s (got {h!r})")
    if isinstance(record_every, bool) or not isinstance(record_every, (int, np.integer)) or record_every < 1:
        raise InputError(f"record_every must be a positive integer (got {record_every!r})")
    lp = _loop(problem, t0)
    n = lp.n
    q0v, v0v = _vector("q0", q0, n), _vector("v0", v0, n)
    out_idx, out_sel, out_names = _outputs(outputs, n, getattr(problem, "names", None))
    sel = np.eye(n)[out_idx] if out_idx is not None else np.asarray(out_sel)
    ctl = sel if control is None else np.asarray(control, dtype=float)
    if ctl.ndim != 2 or ctl.shape[1] != n or not np.all(np.isfinite(ctl)):
        raise InputError(f"control must be a finite (k, {n}) matrix of output rows (got shape {ctl.shape})")
    hist = _history_function(history, n, t0) if lp.G is not None else None
    span = t1 - t0

    def grid(c: int) -> tuple[float, int, int]:
        """(h, steps per delay m, steps) of ``c`` steps per delay (without a delay: in the run)."""
        if lp.T is None:
            return span / c, 0, c
        hh = lp.T / c
        return hh, c, int(math.floor(span / hh + 1e-9))

    def run(c: int) -> tuple[FloatArray, int, str, float, int]:
        hh, m, k = grid(c)
        if k < 1:
            raise InputError(f"the step {hh:.6g} s is longer than the duration {span:.6g} s")
        if (k + 1) * 2 * n * 8 > MAX_STATE_BYTES:
            raise InputError(
                f"{k} steps of {n} coordinates exceed {MAX_STATE_BYTES / 2**30:.0f} GiB of states: shorten "
                "the run, loosen rtol, or integrate with newmark()"
            )
        X, done, reason = _run(lp, _maps(lp, hh, m, p), t0, k, q0v, v0v, hist, float(divergence_limit))
        return X, done, reason, hh, m

    notes: list[str] = []
    est: float | None = None
    tries = 0
    if h is not None:
        c = (
            math.ceil(span / float(h) - 1e-9)
            if lp.T is None
            else max(p + 1, math.ceil(lp.T / float(h) - 1e-9))
        )
        X, done, reason, hh, m = run(c)
    elif lp.T is None and lp.f0 is not None:
        # no delay and a constant force: Eq. (4) is exact at every step; the step only spaces the record
        X, done, reason, hh, m = run(_first_step(lp, float(rtol), p, span))
        est = 0.0
    else:
        c = _first_step(lp, float(rtol), p, span)
        made: dict[int, tuple[FloatArray, int, str, float, int]] = {}

        def level(k: int) -> tuple[FloatArray, int, str, float, int]:
            if k not in made:
                made[k] = run(k)
            return made[k]

        while True:
            tries += 1
            X, done, reason, hh, m = level(c)
            half, quarter = level(c // 2), level(c // 4)
            if reason or half[2] or quarter[2]:
                est = math.nan
                break
            est = _richardson(X, half[0], quarter[0], ctl, n, p)
            if est <= rtol or tries >= MAX_TRIES:
                if est > rtol:
                    notes.append(f"the error estimate {est:.3g} is above rtol = {rtol:g} after {tries} tries")
                break
            # double the steps per delay 1-3 times: the runs at 2h and 4h are then runs already made
            grow = (est / (0.5 * float(rtol))) ** (1.0 / (p + 1))
            c *= 2 ** min(3, max(1, math.ceil(math.log2(max(grow, 1.0)))))
            for k in [k for k in made if k < c // 4]:
                del made[k]
    status = "diverged" if reason else "ok"
    rec = int(record_every)
    Xr = X[: done + 1 : rec]
    t = t0 + hh * np.arange(0, done + 1, rec)
    acc = _accelerations(lp, Xr, t, np.arange(0, done + 1, rec), m, hh, X, hist, t0)
    wall = time.perf_counter() - wall0
    msg = (
        f"diverged at t = {t0 + (done + 1) * hh:.9g} s (step {done + 1}): {reason}"
        if reason
        else f"{done} steps of h = {hh:.6g} s (exponential step map, order {p + 1}) from t = {t0:.6g} to "
        f"{t0 + done * hh:.6g} s in {wall:.3g} s"
    )
    if est is not None and math.isfinite(est):
        msg += f"; estimated relative error {est:.2g} (rtol {float(rtol):g})"
    if notes:
        msg += "; " + "; ".join(notes)
    return TimeResponse(
        t=t,
        q=sel @ Xr[:, :n].T,
        v=sel @ Xr[:, n:].T,
        a=sel @ acc.T,
        names=out_names,
        status=status,
        message=msg,
        n_steps=done,
        wall_time=wall,
        h=hh,
        attrs={
            "method": "exponential",
            "order": p + 1,
            "degree": p,
            "rtol": None if h is not None else float(rtol),
            "error_estimate": est,
            "steps_per_delay": m if lp.T is not None else None,
            "tries": tries,
            "delay": lp.T,
            "t_span": (t0, t1),
        },
    )


def _first_step(lp: _Loop, rtol: float, p: int, span: float) -> int:
    """The first try, in steps per delay (without a delay: in the run), a
    multiple of 4 (the error control halves it twice): the dominant mode of
    the delayed loop's input-output weights (the mode's coupling from ``G``'s
    output directions to its input directions over its damping rate) resolved
    with ``(w h)^(p+1) = 10 rtol``; at least ``4 (p + 1)`` steps per delay,
    and at least 16 steps in a run shorter than the delay."""
    mu, V = np.linalg.eig(lp.L)
    n = lp.n
    if lp.G is not None:
        try:
            Vi = np.linalg.inv(V)
        except np.linalg.LinAlgError:
            Vi = np.linalg.pinv(V)
        gin = np.linalg.norm(Vi @ lp.N, axis=1)
        gout = np.linalg.norm(lp.Vt @ V[:n], axis=0)
        w = gin * gout / np.maximum(np.abs(mu.real), 1e-9 * np.abs(mu) + 1e-300)
        om = float(np.abs(mu[int(np.argmax(w))]))
    else:
        om = float(np.max(np.abs(mu)))
    x = (10.0 * rtol) ** (1.0 / (p + 1))
    h = x / om if om > 0 else span / 100
    c = math.ceil((lp.T if lp.T is not None else span) / h)
    # a run shorter than a few delays: its coarsest level (4h) still holds 4 steps
    short = math.ceil(16.0 * lp.T / span) if lp.T is not None else 0
    return 4 * math.ceil(max(c, 4 * (p + 1), short) / 4)


def _richardson(X: FloatArray, X2: FloatArray, X4: FloatArray, sel: FloatArray, n: int, p: int) -> float:
    """The error of the ``h`` run from the runs at ``h``, ``2h``, ``4h``
    (Eq. 6): ``d1 = |y_h - y_2h|``, ``d2 = |y_2h - y_4h|`` at the common
    instants, each output relative to its largest value; with the observed
    ratio ``rho = d2/d1 > 2`` (the error falling) Richardson's
    ``d1 / (min(rho, 2^q) - 1)``, ``q = p + 1`` (never more optimistic than
    the scheme's order allows), else ``d1`` itself."""
    k = min((X.shape[0] - 1) // 4, (X2.shape[0] - 1) // 2, X4.shape[0] - 1)
    y1 = X[: 4 * k + 1 : 4, :n] @ sel.T
    y2 = X2[: 2 * k + 1 : 2, :n] @ sel.T
    y4 = X4[: k + 1, :n] @ sel.T
    k2 = min((X.shape[0] - 1) // 2, X2.shape[0] - 1)
    scale = np.abs(X[:, :n] @ sel.T).max(axis=0)
    ok = scale > 0
    if not ok.any():
        return 0.0
    d1 = float(
        (np.abs(X[: 2 * k2 + 1 : 2, :n] @ sel.T - X2[: k2 + 1, :n] @ sel.T).max(axis=0)[ok] / scale[ok]).max()
    )
    d1c = float((np.abs(y1 - y2).max(axis=0)[ok] / scale[ok]).max())
    d2 = float((np.abs(y2 - y4).max(axis=0)[ok] / scale[ok]).max())
    q = 2.0 ** (p + 1)
    rho = d2 / d1c if d1c > 0 else math.inf
    if rho > 2.0:
        return d1 / (min(rho, q) - 1.0)
    return d1


def _accelerations(
    lp: _Loop,
    Xr: FloatArray,
    t: FloatArray,
    idx: FloatArray,
    m: int,
    h: float,
    X: FloatArray,
    hist: Any,
    t0: float,
) -> FloatArray:
    """``q'' = A^{-1} (f + G q(t - T) - B v - C q)`` at the recorded steps
    (the delayed value on the grid; the history's at and before t0)."""
    n = lp.n
    rhs = -(Xr[:, n:] @ lp.B.T) - Xr[:, :n] @ lp.C.T
    rhs += lp.f0 if lp.f0 is not None else np.asarray(lp.problem.force(t), dtype=float)
    if lp.G is not None:
        jd = idx - m
        qd = np.empty((idx.size, n))
        past = jd <= 0
        if past.any():
            qd[past] = hist(t0 + h * jd[past])
        qd[~past] = X[jd[~past], :n]
        rhs += qd @ lp.G.T
    return np.linalg.solve(lp.A, rhs.T).T
