"""Newmark time integration of linear time-varying systems with a delayed term.

This module integrates the parametric equation of motion of Wittbrodt &
Kaliński, eq. (2.28),

.. math::

    \\hat A(t)\\,\\ddot q + \\hat B(t)\\,\\dot q + \\hat C(t)\\,q
    = \\hat p(t, t-T),

written at matrix level as

.. math::

    A(t)\\,\\ddot q(t) + B(t)\\,\\dot q(t) + C(t)\\,q(t) = p(t) + G(t)\\,q(t-T),

with ``n`` generalised coordinates, ``q(t) = history(t)`` for ``t <= t0``
and a constant delay ``T > 0`` (the regenerative, "outer modulation" term of
the paper; no delay term when ``G`` is ``None``).  ``A(t)`` must be
nonsingular (symmetric positive definite for a mechanical model).

Method
------
The Newmark family (Newmark 1959) with parameters ``gamma``, ``beta``::

    q[k+1] = q[k] + h v[k] + h^2 ((1/2 - beta) a[k] + beta a[k+1])
    v[k+1] = v[k] + h ((1 - gamma) a[k] + gamma a[k+1])
    A[k+1] a[k+1] + B[k+1] v[k+1] + C[k+1] q[k+1] = p[k+1] + G[k+1] q(t[k+1] - T)

is solved for the increment ``dq = q[k+1] - q[k]`` with the effective
stiffness ``K_eff = A/(beta h^2) + gamma B/(beta h) + C`` evaluated at
``t[k+1]``.  The default ``gamma = 1/2, beta = 1/4`` (average acceleration,
the trapezoidal rule) is unconditionally stable, second-order accurate and
free of numerical damping: an undamped mode of circular frequency ``w`` keeps
its amplitude exactly and oscillates at ``(2/h) atan(w h / 2)`` (period
elongation ``w h / (2 atan(w h / 2)) - 1 ~ (w h)^2 / 12``).

The delayed displacement ``q(t[k+1] - T)`` is an explicit, already known
force because ``T >= h``: it is interpolated between the two stored steps
around ``t[k+1] - T`` with cubic Hermite interpolation on ``q`` and ``q'``
(error ``O(h^4)``, so it does not spoil the second order of the scheme), or
taken from ``history`` while ``t[k+1] - T < t0``.  Only the last
``T/h + 2`` steps are stored.

Because the coefficients are known in advance (the slide motion is
prescribed), the matrices for a chunk of steps are requested in one
vectorised call, and the effective stiffness matrices of the chunk are
inverted in one batched LAPACK call -- in a background thread, overlapped
with the step loop of the previous chunk -- so the per-step Python loop does
only a few small matrix-vector products.  A time-invariant problem
(:class:`ConstantProblem`) is factored once.

References
----------
.. [1] N. M. Newmark, "A method of computation for structural dynamics",
   J. Eng. Mech. Div. ASCE 85(EM3), 67-94, 1959.
.. [2] K.-J. Bathe and E. L. Wilson, *Numerical methods in finite element
   analysis*, Prentice Hall, Englewood Cliffs 1976 (sec. 8.2.4, stability
   and accuracy of the Newmark operator).
.. [3] E. Wittbrodt and K. J. Kaliński, "Transient vibration of unsteady linear
   closed loop systems" (the seed paper of chatterlab), eq. (2.28) and sec. 2.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from chatterlab.errors import InputError

from ._options import NewmarkOptions, NewmarkStabilityWarning, TimeResponse
from ._plan import _check_problem, _force_at, _hermite_weights, _inverse, _Plan, _plan, _stack
from ._problems import CallbackProblem, ConstantProblem, FloatArray, PiecewiseProblem, TimeVaryingProblem

__all__ = [
    "TimeVaryingProblem",
    "ConstantProblem",
    "CallbackProblem",
    "PiecewiseProblem",
    "NewmarkOptions",
    "NewmarkStabilityWarning",
    "TimeResponse",
    "newmark",
]


# =========================================================================== integrator


def newmark(
    problem: TimeVaryingProblem,
    t_span: tuple[float, float],
    h: float,
    q0: ArrayLike | None = None,
    v0: ArrayLike | None = None,
    *,
    options: NewmarkOptions | None = None,
    outputs: Any = None,
    record_every: int = 1,
    history: Any = None,
    progress: Callable[[float], Any] | None = None,
    callback: Callable[[float, FloatArray, FloatArray, FloatArray], Any] | None = None,
) -> TimeResponse:
    """Integrate ``A q'' + B q' + C q = p(t) + G q(t - T)`` with the Newmark method.

    Parameters
    ----------
    problem : TimeVaryingProblem
        The system (:class:`ConstantProblem`, :class:`CallbackProblem`,
        :class:`PiecewiseProblem` or any object with ``n``, ``matrices(t)``,
        ``force(t)``, ``delay()``).
    t_span : (float, float)
        Start and end time ``(t0, t1)`` [s].  The steps are ``t0 + k h`` for
        ``k = 0 .. floor((t1 - t0)/h)`` (the last step is <= ``t1``; it is
        ``t1`` when ``h`` divides the span).
    h : float
        Time step [s]; with a delay, ``h <= T`` is required.
    q0, v0 : array_like, shape (n,), optional
        Initial displacement [m, rad] and velocity [m/s, rad/s]; zero by
        default.  The initial acceleration follows from the equation of motion
        at ``t0``.
    options : NewmarkOptions, optional
        Scheme parameters, chunk size, limits.
    outputs : optional
        Recorded coordinates: ``None`` (all), a sequence of indices, a selector
        matrix ``(n_out, n)`` (e.g. a relative tool-workpiece displacement) or
        a mapping ``name -> index or (n,) row``.
    record_every : int, default 1
        Record every ``record_every``-th step (the state is still integrated at
        every step).
    history : optional
        ``q(t)`` for ``t < t0`` (only read with a delay): ``None`` (zero, the
        default), a constant ``(n,)`` vector, a vectorised callable
        ``history(t: (k,)) -> (k, n)`` or sampled ``(t_hist, q_hist)`` with
        ``q_hist`` of shape ``(len(t_hist), n)`` (cubic spline).
    progress : callable, optional
        ``progress(fraction)`` called after each chunk, fraction in ``(0, 1]``.
    callback : callable, optional
        ``callback(t, q, v, a)`` called after each chunk with the current full
        state (``(n,)`` arrays, copies); returning ``True`` stops the run with
        ``status="stopped"``.

    Returns
    -------
    TimeResponse
        Recorded ``t`` (n_t,), ``q, v, a`` (n_out, n_t), ``status`` and
        ``message``.  A numerical failure (non-finite state, ``|q|`` above
        ``options.divergence_limit``) gives ``status="diverged"`` with the
        time; a KeyboardInterrupt gives ``status="interrupted"`` with the data
        computed so far.

    Raises
    ------
    InputError
        Bad arguments: non-positive duration or step, ``h > T``, NaN inputs,
        wrong shapes, a history or output buffer above the memory limits.

    Notes
    -----
    See the module docstring for the scheme.  With the default
    ``gamma=1/2, beta=1/4`` the global error is ``O(h^2)``; the relative
    period error of a mode of circular frequency ``w`` is about
    ``(w h)^2 / 12``, so ``h <= T_min / 20`` (``T_min`` the shortest period
    of interest) keeps it below 0.8 %.

    References
    ----------
    .. [1] N. M. Newmark, J. Eng. Mech. Div. ASCE 85(EM3), 67-94, 1959.
    .. [2] K.-J. Bathe and E. L. Wilson, *Numerical methods in finite element
       analysis*, Prentice Hall 1976.
    """
    wall0 = time.perf_counter()
    opts = NewmarkOptions() if options is None else options
    if not isinstance(opts, NewmarkOptions):
        raise InputError(f"options must be a NewmarkOptions (got {type(opts).__name__})")
    n = _check_problem(problem)
    plan = _plan(problem, n, opts, t_span, h, q0, v0, outputs, record_every, history)
    run = _Stepper(plan)
    status, reason, i_done = run.run(progress, callback)
    return run.response(status, reason, i_done, time.perf_counter() - wall0)


class _Stepper:
    """One integration in progress: the state buffer, the recorded outputs,
    the preparation of each chunk of steps (matrices and batched inverses,
    in worker threads) and the step loop.

    ``S[r] = [dq slot, q, v, a]`` of global step ``off + r`` (dq slot =
    q[r+1] - q[r]); only the last ``keep`` rows survive a wrap.
    """

    def __init__(self, p: _Plan) -> None:
        self.p = p
        n = p.n
        c0, c1, c2, c3, dv1, dv2 = p.coef
        self.S = np.zeros((p.cap, 4, n))
        self.S[0, 1], self.S[0, 2], self.S[0, 3] = p.q0, p.v0, p.a0
        self.off = 0
        nb = 4 if p.has_delay else 3
        self.xfull = np.zeros(nb * n)
        self.X3 = self.xfull[: 3 * n].reshape(3, n)
        self.qd = self.xfull[3 * n :]  # empty without a delay
        self.rhs = np.zeros(n)
        # multiply C: -q;  A;  B
        self.coefX = np.array([[0.0, -1.0, 0.0, 0.0], [0.0, 0.0, c2, c3], [0.0, 0.0, -dv1, -dv2]])
        # q_new = q + dq; v_new; a_new
        self.Mupd = np.array([[1.0, 1.0, 0.0, 0.0], [c1, 0.0, dv1, dv2], [c0, 0.0, -c2, -c3]])
        self.w8 = np.zeros(8)
        if p.has_delay and not p.exact:
            self.w8[[1, 2, 5, 6]] = _hermite_weights(p.s_frac, p.h)
        n_out = p.out_idx.size if p.out_idx is not None else p.out_sel.shape[0]  # type: ignore[union-attr]
        self.t_rec = p.t0 + p.h * p.rec * np.arange(p.n_rec)
        self.out = [np.empty((n_out, p.n_rec)) for _ in range(3)]  # q, v, a
        self.record(self.S[0:1, 1:4], 0)
        self.n_recorded = 1
        self.tinv = bool(getattr(p.problem, "time_invariant", False))
        self.P = np.empty((0, 0))
        self.Kinv0 = np.empty((0, 0))
        if self.tinv:
            self.Kinv0 = _inverse((c0 * p.A0 + c1 * p.B0 + p.C0)[None], np.array([p.t0]))[0]
            blocks = [p.C0, p.A0, p.B0] + ([p.G0] if p.G0 is not None else [])
            self.P = np.ascontiguousarray(self.Kinv0 @ np.concatenate(blocks, axis=1))
        self.lock = threading.Lock()

    def record(self, rows: FloatArray, j_first: int) -> None:
        """Store states ``rows`` (k, 3, n) = [q, v, a] into outputs from record index j_first."""
        k = rows.shape[0]
        if k == 0:
            return
        p = self.p
        for slot, dst in enumerate(self.out):
            blk = rows[:, slot, :]
            if p.out_idx is not None:
                dst[:, j_first : j_first + k] = blk[:, p.out_idx].T
            else:
                dst[:, j_first : j_first + k] = p.out_sel @ blk.T

    def prepare(self, i0: int, c: int) -> tuple[FloatArray, FloatArray, FloatArray | None]:
        """Matrices for steps i0+1 .. i0+c: (Kinv or None, F or Kinv F, blocks)."""
        p, n = self.p, self.p.n
        c0, c1 = p.coef[0], p.coef[1]
        tt = p.t0 + p.h * np.arange(i0 + 1, i0 + c + 1)
        if i0 + c in p.bp_steps:  # left limit at the breakpoint
            tt[-1] -= max(1e-9 * p.h, 8 * np.spacing(abs(tt[-1])))
        with self.lock:  # the problem's own code is never called concurrently
            F = _force_at(p.problem, tt, n)
            if self.tinv:
                return np.empty(0), np.ascontiguousarray(F @ self.Kinv0.T), None
            A, B, C, G = p.problem.matrices(tt)
        A, B, C = (_stack(nm, m, c, n, tt, False) for nm, m in zip("ABC", (A, B, C), strict=True))
        mats = [C, A, B]
        if p.has_delay:
            if G is None:
                G = np.zeros((c, n, n))
            mats.append(_stack("G", G, c, n, tt))
        K = np.multiply(A, c0)
        K += c1 * B
        K += C
        if not np.all(np.isfinite(K)):  # a NaN/inf in A, B or C shows in K: name it
            for nm, m in zip("ABC", (A, B, C), strict=True):
                _stack(nm, m, c, n, tt)
        Kinv = _inverse(K, tt)
        return Kinv, np.ascontiguousarray(F), np.concatenate(mats, axis=2)

    def restart(self, ib: int) -> None:
        """Acceleration at breakpoint step ib from the equation of motion, right limits."""
        p, n, S, off = self.p, self.p.n, self.S, self.off
        tb = np.array([p.t0 + ib * p.h])
        with self.lock:
            Ab, Bb, Cb, Gb = p.problem.matrices(tb)
            fb = _force_at(p.problem, tb, n)[0]
        Ab, Bb, Cb = (_stack(nm, m, 1, n, tb)[0] for nm, m in zip("ABC", (Ab, Bb, Cb), strict=True))
        r = ib - off
        q, v = S[r, 1], S[r, 2]
        rhs_b = fb - Bb @ v - Cb @ q
        if p.has_delay and Gb is not None:
            j = ib - p.shift
            if j < 0:
                qd_b = p.hist_vals[ib]
            elif p.exact:
                qd_b = S[j - off, 1]
            else:
                qd_b = self.w8 @ S[j - off : j - off + 2].reshape(8, n)
            rhs_b = rhs_b + _stack("G", Gb, 1, n, tb)[0] @ qd_b
        S[r, 3] = np.linalg.solve(Ab, rhs_b)

    def steps(self, i0: int, c: int, data: tuple[Any, ...]) -> tuple[int, bool]:
        """The hot loop: steps i0+1 .. i0+c with the prepared ``data``; returns
        the steps done and whether a KeyboardInterrupt stopped them.  Only
        small in-place products per step (local names for speed)."""
        p = self.p
        Kinv, F, Blk = data
        S, keep, n = self.S, p.keep, p.n
        # make room: keep the last `keep` rows when the chunk would overflow
        r0 = i0 - self.off
        if r0 + c + 1 > p.cap:
            S[0:keep] = S[r0 - keep + 1 : r0 + 1].copy()
            self.off = i0 - keep + 1
            r0 = i0 - self.off
        off, shift, n_hist, hist_vals, exact = self.off, p.shift, p.n_hist, p.hist_vals, p.exact
        has_delay, tinv, P = p.has_delay, self.tinv, self.P
        coefX, Mupd, w8, X3, qd, xfull, rhs = (
            self.coefX, self.Mupd, self.w8, self.X3, self.qd, self.xfull, self.rhs
        )  # fmt: skip
        matmul, dot, add, copyto = np.matmul, np.dot, np.add, np.copyto
        k = -1
        try:
            for k in range(c):
                Sk = S[r0 + k]
                matmul(coefX, Sk, out=X3)
                if has_delay:
                    j = i0 + k + 1 - shift
                    if i0 + k + 1 < n_hist:
                        copyto(qd, hist_vals[i0 + k + 1])
                    elif exact:
                        copyto(qd, S[j - off, 1])
                    else:
                        matmul(w8, S[j - off : j - off + 2].reshape(8, n), out=qd)
                if tinv:
                    dot(P, xfull, out=rhs)
                    add(rhs, F[k], out=Sk[0])
                else:
                    dot(Blk[k], xfull, out=rhs)
                    rhs += F[k]
                    dot(Kinv[k], rhs, out=Sk[0])
                matmul(Mupd, Sk, out=S[r0 + k + 1, 1:])
            k = c
            if i0 + c in p.bp_steps:
                self.restart(i0 + c)
        except KeyboardInterrupt:
            return max(k, 0), True
        return max(k, 0), False

    def finish_chunk(self, i0: int, done: int) -> tuple[int, str]:
        """Check the ``done`` new steps after i0 for divergence (returns the
        steps to keep and a reason when it diverged) and record those on
        the record grid."""
        p = self.p
        r0 = i0 - self.off
        with np.errstate(all="ignore"):
            rows = self.S[r0 + 1 : r0 + done + 1, 1:]
            bad = ~np.all(np.isfinite(rows), axis=(1, 2))
            bad |= np.max(np.abs(rows[:, 0, :]), axis=1) > p.opts.divergence_limit
        reason = ""
        if bad.any():
            first = int(np.argmax(bad))
            done = first
            ib = i0 + first + 1
            reason = (
                f"diverged at t = {p.t0 + ib * p.h:.9g} s (step {ib}): "
                f"non-finite state or |q| > divergence_limit = {float(p.opts.divergence_limit):.3g}"
            )
        # record the steps of this chunk that fall on the record grid
        g_first, g_last = i0 + 1, i0 + done
        if g_last >= g_first:
            j_a = -(-g_first // p.rec)
            j_b = g_last // p.rec
            if j_b >= j_a:
                gl = np.arange(j_a, j_b + 1) * p.rec
                self.record(self.S[gl - self.off, 1:4], j_a)
                self.n_recorded = j_b + 1
        return done, reason

    def run(
        self,
        progress: Callable[[float], Any] | None,
        callback: Callable[[float, FloatArray, FloatArray, FloatArray], Any] | None,
    ) -> tuple[str, str, int]:
        """Step through all chunks (prepared ahead by the workers); returns
        ``(status, reason, steps done)``."""
        p = self.p
        status, reason = "ok", ""
        i_done = 0  # global index of the last completed step
        n_workers = int(p.opts.workers) if (not self.tinv and p.n_total > p.chunk) else 0
        pool = ThreadPoolExecutor(max_workers=n_workers) if n_workers else None
        bounds = sorted(set(range(0, p.n_total, p.chunk)) | {b for b in p.bp_steps if b < p.n_total})
        bounds.append(p.n_total)
        chunks = [(a, b - a) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        futures: deque[Any] = deque()
        try:
            if pool is not None:
                for ch in chunks[:n_workers]:
                    futures.append(pool.submit(self.prepare, *ch))
            for ci, (i0, c) in enumerate(chunks):
                if pool is not None:
                    data = futures.popleft().result()
                    if ci + n_workers < len(chunks):
                        futures.append(pool.submit(self.prepare, *chunks[ci + n_workers]))
                else:
                    data = self.prepare(i0, c)
                with np.errstate(all="ignore"):
                    done, interrupted = self.steps(i0, c, data)
                if interrupted:
                    status = "interrupted"
                done, diverged = self.finish_chunk(i0, done)
                if diverged:
                    status, reason = "diverged", diverged
                i_done = i0 + done
                if status != "ok":
                    break
                if progress is not None:
                    progress(i_done / p.n_total)
                if callback is not None:
                    r = i_done - self.off
                    S = self.S
                    stop = callback(p.t0 + i_done * p.h, S[r, 1].copy(), S[r, 2].copy(), S[r, 3].copy())
                    if stop is True:
                        status = "stopped"
                        reason = f"stopped by callback at t = {p.t0 + i_done * p.h:.9g} s"
                        break
        except KeyboardInterrupt:
            status = "interrupted"
        finally:
            if pool is not None:
                pool.shutdown(wait=False, cancel_futures=True)
        return status, reason, i_done

    def response(self, status: str, reason: str, i_done: int, wall: float) -> TimeResponse:
        """The :class:`TimeResponse` of the run, with its message."""
        p = self.p
        t0, h = p.t0, p.h
        t_end = t0 + i_done * h
        if status == "ok":
            msg = (
                f"{i_done} steps of h = {h:.6g} s from t = {t0:.6g} to {t_end:.6g} s in "
                f"{wall:.3g} s ({i_done / max(wall, 1e-12):.0f} steps/s)"
            )
        elif status == "interrupted":
            msg = f"interrupted after {i_done} of {p.n_total} steps (t = {t_end:.9g} s)"
        else:
            msg = reason
        if p.notes:
            msg += "; " + "; ".join(p.notes)
        nr = self.n_recorded
        q_out, v_out, a_out = self.out
        return TimeResponse(
            t=self.t_rec[:nr].copy(),
            q=q_out[:, :nr].copy(),
            v=v_out[:, :nr].copy(),
            a=a_out[:, :nr].copy(),
            names=p.out_names,
            status=status,
            message=msg,
            n_steps=i_done,
            wall_time=wall,
            h=h,
            attrs={
                "gamma": p.gam,
                "beta": p.bet,
                "delay": p.T,
                "t_span": (t0, p.t1),
                "breakpoints": tuple(t0 + b * h for b in sorted(p.bp_steps)),
            },
        )
