"""The Newmark core of :mod:`chatterlab.time`: one scheme, one step loop.

Every time integration of chatterlab runs here -- :func:`~chatterlab.time.newmark`
on a linear problem (the seed paper's Eq. 2.28, turning, any
:class:`~chatterlab.time.TimeVaryingProblem`) and
:func:`~chatterlab.time.simulate_milling` on a structure cut by a milling
cutter.  What they share exists once, here:

* **the scheme** -- the constants of the Newmark family for a step
  (:func:`scheme_constants`) and, for coefficients constant over a
  (sub)step, the step written as one linear map of the state and of the
  force at its end (:func:`step_map`, :class:`StepMap`);
* **the delayed history** -- where a delay falls on the step grid
  (:func:`delay_on_grid`) and the cubic Hermite interpolation between two
  stored steps (:func:`hermite_weights`, the one place of its weights);
* **the run** (:class:`_Stepper`) -- the state buffer, the chunks of steps
  (prepared ahead in worker threads where nothing in them depends on the
  steps before), the one step loop, restarts where the coefficients jump,
  divergence and interruption, the record.

The step loop advances the state ``[q, v, a]`` point by point.  For a
linear problem the points are the steps and the force at the end of a step
is known before it (the external force and ``G q(t - T)``, ``h <= T``):
the step is the increment form with the effective stiffness of that step.
Its features beyond that, which the milling cut uses:

* **a unilateral coupling** (:mod:`._contact`): a force ``F`` on the
  structure through a map ``P`` (the tool point, ``r = P q``), made of
  contacts ``j`` whose gap ``h_j = n_j . r + s_j`` is affine in ``r`` and
  which push only while ``h_j > 0`` (a tooth cuts only while its chip is
  positive).  ``F`` is implicit (it depends on ``r`` at the end of the
  step): ``r = r* + Z F`` with ``Z`` the compliance of the step, and the
  set of active contacts is found implicitly at each step (an active-set
  iteration); an instant inside a step where a gap crosses zero is located
  and stepped to, with a restart there;
* **several delays**: the gaps read the coupling's own history
  (``r``, ``r'`` at every step) at any number of delays, through the same
  Hermite interpolation (the milling cut's passes: variable pitch, multiple
  regeneration);
* **substeps on a periodic pattern**: the coupling's coefficients are
  periodic (a tooth enters and leaves the arc once per revolution); the
  points of one period -- the steps, split where a coefficient jumps -- are
  a pattern repeated over the run, each substep length with its own step
  map, a restart of the acceleration after each jump (second order kept).

References
----------
.. [1] N. M. Newmark, "A method of computation for structural dynamics",
   J. Eng. Mech. Div. ASCE 85(EM3), 67-94, 1959.
.. [2] K.-J. Bathe and E. L. Wilson, *Numerical methods in finite element
   analysis*, Prentice Hall, Englewood Cliffs 1976 (sec. 8.2.4).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from chatterlab.errors import InputError

__all__: list[str] = []

FloatArray = NDArray[Any]


# =========================================================================== the scheme


def scheme_constants(gamma: float, beta: float, h: float) -> tuple[float, float, float, float, float, float]:
    """Newmark constants ``(c0, c1, c2, c3, dv1, dv2)`` of a step ``h``: the
    effective stiffness is ``c0 A + c1 B + C``, the acceleration at the end
    ``a' = c0 dq - c2 v - c3 a`` and the velocity ``v' = c1 dq + dv1 v + dv2 a``."""
    return (
        1.0 / (beta * h * h),
        gamma / (beta * h),
        1.0 / (beta * h),
        1.0 / (2.0 * beta) - 1.0,
        1.0 - gamma / beta,
        h * (1.0 - gamma / (2.0 * beta)),
    )


@dataclass(frozen=True)
class StepMap:
    """One Newmark (sub)step of a structure with constant ``M, C, K`` as a
    linear map: with ``z = (q, v, a)`` at its start and ``F`` the coupling
    force at its end, ``r* = PL z`` is where the coupling's output would be
    without ``F``, ``r = r* + Z F`` where it is, and
    ``z' = [Phi Psi] (z, F)`` the state at the end."""

    PL: FloatArray  # (p, 3n)
    Z: tuple[float, float, float, float]  # the 2 x 2 compliance of the step, row by row
    PhiPsi: FloatArray  # (3n, 3n + p)


def step_map(
    M: FloatArray, C: FloatArray, K: FloatArray, P: FloatArray, hs: float, gamma: float, beta: float
) -> StepMap:
    """The :class:`StepMap` of a (sub)step of length ``hs`` for ``M q'' + C q'
    + K q = P^T F`` (``P``: 2 x n).  The displacement at the end is written
    from the predictor ``Qt z = q + hs v + hs^2 (1/2 - beta) a`` as
    ``L z = Qt z + K_eff^-1 (-C Vt z - K Qt z)`` (``Vt z = v + hs (1 -
    gamma) a``), which avoids the cancellation of ``c0 M Qt``."""
    n = M.shape[0]
    c0, c1 = scheme_constants(gamma, beta, hs)[:2]
    Kinv = np.linalg.inv(c0 * M + c1 * C + K)
    eye = np.eye(n)
    zero = np.zeros((n, n))
    Qt = np.hstack([eye, hs * eye, hs * hs * (0.5 - beta) * eye])
    Vt = np.hstack([zero, eye, hs * (1.0 - gamma) * eye])
    dL = Kinv @ (-C @ Vt - K @ Qt)  # L - Qt, without the cancellation of c0 M Qt
    L = Qt + dL
    U = Kinv @ P.T
    Aa = c0 * dL
    Phi = np.vstack([L, Vt + gamma * hs * Aa, Aa])
    Psi = np.vstack([U, gamma * hs * c0 * U, c0 * U])
    Z = P @ U
    return StepMap(
        PL=np.ascontiguousarray(P @ L),
        Z=(float(Z[0, 0]), float(Z[0, 1]), float(Z[1, 0]), float(Z[1, 1])),
        PhiPsi=np.ascontiguousarray(np.hstack([Phi, Psi])),
    )


# =========================================================================== the delayed history


def hermite_weights(s: Any, h: float) -> tuple[Any, Any, Any, Any]:
    """Weights of ``y_j, y'_j, y_j+1, y'_j+1`` for ``y(t_j + s h)``, ``0 <= s <= 1``
    (cubic Hermite interpolation: error ``O(h^4)``, below the scheme's);
    ``s`` a number or an array (then four arrays)."""
    s2 = s * s
    s3 = s2 * s
    return 2 * s3 - 3 * s2 + 1, h * (s3 - 2 * s2 + s), -2 * s3 + 3 * s2, h * (s3 - s2)


#: a delay within this many steps of a whole number of steps is taken as one
#: (relative to the number of steps when larger than 1)
DELAY_ON_GRID = 1e-9


def delay_on_grid(d: Any) -> tuple[np.ndarray, np.ndarray]:
    """Where delays of ``d`` steps (array) fall on the step grid: ``(whole,
    rem)`` with ``d = whole + rem``, ``0 <= rem < 1``, and ``rem = 0`` (the
    delayed value is a stored step) when ``d`` is within :data:`DELAY_ON_GRID`
    of a whole number.  Otherwise ``y(t_i - d h) = y(t_j + (1 - rem) h)``,
    ``j = i - whole - 1``: :func:`hermite_weights` at ``s = 1 - rem``."""
    d = np.asarray(d, dtype=float)
    near = np.round(d)
    exact = np.abs(d - near) <= DELAY_ON_GRID * np.maximum(1.0, d)
    below = np.floor(d)
    whole = np.where(exact, near, below).astype(int)
    rem = np.where(exact, 0.0, d - below)
    return whole, rem


# =========================================================================== the run


class _Stepper:
    """One integration in progress: the state buffer, the recorded outputs,
    the preparation of each chunk of steps and the one step loop.

    ``S[r] = [dq slot, q, v, a]`` of global step ``off + r`` (dq slot =
    q[r+1] - q[r] for a linear problem); only the last ``keep`` rows survive
    a wrap.  ``p`` is the run's plan (:class:`chatterlab.time._plan._Plan`):
    the grid, the scheme's constants, the delay, the history, the
    breakpoints, the outputs and the initial state; ``p.coupling`` a
    unilateral coupling's run (:class:`._contact._Contacts`) or None.
    """

    def __init__(self, p: Any) -> None:
        self.p = p
        n = p.n
        c0, c1, c2, c3, dv1, dv2 = p.coef
        self.S = np.zeros((p.cap, 4, n))
        self.S[0, 1], self.S[0, 2], self.S[0, 3] = p.q0, p.v0, p.a0
        self.Sz = self.S.reshape(p.cap, 4 * n)[:, n:]  # rows: the state (q, v, a) as one vector
        # the rows as views made once (S is never reallocated): a point of a coupling reads and
        # writes them without making a view per step
        self.Zrows = [self.Sz[i] for i in range(p.cap)] if p.coupling is not None else []
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
            self.w8[[1, 2, 5, 6]] = hermite_weights(p.s_frac, p.h)
        n_out = p.out_idx.size if p.out_idx is not None else p.out_sel.shape[0]
        self.t_rec = p.t0 + p.h * p.rec * np.arange(p.n_rec)
        self.out = [np.empty((n_out, p.n_rec)) for _ in range(3)]  # q, v, a
        self.record(self.S[0:1, 1:4], 0)
        self.n_recorded = 1
        self.cut = p.coupling
        self.tinv = bool(getattr(p.problem, "time_invariant", False)) and self.cut is None
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

    def prepare(self, i0: int, c: int) -> tuple[Any, ...]:
        """What the steps i0+1 .. i0+c need before the first of them: a
        linear problem's matrices (Kinv or None, F or Kinv F, blocks); a
        coupling's points and the delayed part of their gaps."""
        if self.cut is not None:
            return self.cut.prepare(i0, c)
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
        """The step loop: steps i0+1 .. i0+c with the prepared ``data``;
        returns the steps done and whether a KeyboardInterrupt stopped them.

        Each point advances the state by one Newmark (sub)step.  A linear
        problem's point is a step, in the increment form with the step's
        effective stiffness (``Kinv``; ``F`` and ``G q(t - T)`` known before
        it).  A coupling's points are its pattern's substeps, each advanced
        by the step map of its length with the coupling force solved
        implicitly (:meth:`._contact._Contacts.point`: active set, the
        instant a gap crosses zero located, restarts).  Only small in-place
        products per point (local names for speed)."""
        p = self.p
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
        cut = self.cut
        Kinv: Any
        F: Any
        Blk: Any
        if cut is not None:
            points, gsteps = data
            point, Zrows, src = cut.point, self.Zrows, r0
        else:
            Kinv, F, Blk = data
            points = range(c)
        k = -1
        try:
            for k, e in enumerate(points):
                if cut is not None:  # the coupling's substep e ends in step gsteps[k]
                    row = gsteps[k] - off
                    point(k, e, Zrows[src], Zrows[row])
                    src = row
                    continue
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
            if cut is not None and 0 <= k < len(gsteps):  # the steps before the one interrupted
                k = gsteps[k] - 1 - i0
            return max(k, 0), True
        return max(k, 0), False

    def finish_chunk(self, i0: int, done: int) -> tuple[int, str]:
        """Check the ``done`` new steps after i0 for divergence (returns the
        steps to keep and a reason when it diverged) and record those on
        the record grid."""
        p = self.p
        r0 = i0 - self.off
        rows = self.S[r0 + 1 : r0 + done + 1, 1:]
        reason = ""
        limit = p.opts.divergence_limit
        # one reduction over the chunk; the row that diverged only when something did
        if rows.size and not (np.isfinite(rows).all() and np.abs(rows[:, 0, :]).max() <= limit):
            with np.errstate(all="ignore"):
                bad = ~np.all(np.isfinite(rows), axis=(1, 2))
                bad |= np.max(np.abs(rows[:, 0, :]), axis=1) > limit
            if bad.any():
                first = int(np.argmax(bad))
                done = first
                ib = i0 + first + 1
                reason = (
                    f"diverged at t = {p.t0 + ib * p.h:.9g} s (step {ib}): "
                    f"non-finite state or |q| > divergence_limit = {float(limit):.3g}"
                )
        # record the steps of this chunk that fall on the record grid (a coupling records its own)
        g_first, g_last = i0 + 1, i0 + done
        if g_last >= g_first and self.out[0].shape[0]:
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
        """Step through all chunks (prepared ahead by the workers when they
        do not depend on the steps before: a linear problem); returns
        ``(status, reason, steps done)``."""
        p = self.p
        status, reason = "ok", ""
        i_done = 0  # global index of the last completed step
        ahead = not self.tinv and self.cut is None and p.n_total > p.chunk
        n_workers = int(p.opts.workers) if ahead else 0
        pool = ThreadPoolExecutor(max_workers=n_workers) if n_workers else None
        bounds = sorted(set(range(0, p.n_total, p.chunk)) | {b for b in p.bp_steps if b < p.n_total})
        bounds.append(p.n_total)
        chunks = [(a, b - a) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
        futures: deque[Any] = deque()
        quiet = nullcontext if self.cut is not None else (lambda: np.errstate(all="ignore"))
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
                with quiet():  # a coupling's loop is in Python floats: no numpy state to set
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


# =========================================================================== helpers of the linear problem


def _stack(name: str, m: Any, k: int, n: int, t: FloatArray, check: bool = True) -> FloatArray:
    """Validate one coefficient stack; ``check=False`` skips the NaN scan (done later)."""
    arr = np.asarray(m, dtype=float)
    if arr.shape == (n, n):
        arr = np.broadcast_to(arr, (k, n, n))
    if arr.shape != (k, n, n):
        raise InputError(
            f"problem.matrices(t) returned {name} of shape {arr.shape}; expected "
            f"(len(t), n, n) = ({k}, {n}, {n})"
        )
    if check and not np.all(np.isfinite(arr)):
        bad = int(np.argmax(~np.all(np.isfinite(arr), axis=(1, 2))))
        raise InputError(f"problem.matrices(t): {name} has NaN/inf entries at t = {t[bad]:.9g} s")
    return arr


def _force_at(problem: Any, t: FloatArray, n: int) -> FloatArray:
    f = np.asarray(problem.force(t), dtype=float)
    if f.shape != (t.size, n):
        raise InputError(f"problem.force(t) returned shape {f.shape}; expected (len(t), n) = ({t.size}, {n})")
    if not np.all(np.isfinite(f)):
        bad = int(np.argmax(~np.all(np.isfinite(f), axis=1)))
        raise InputError(f"problem.force(t) has NaN/inf entries at t = {t[bad]:.9g} s")
    return f


def _inverse(K: FloatArray, t: FloatArray) -> FloatArray:
    """Batched inverse; consecutive identical matrices are inverted once."""
    k = K.shape[0]
    new = np.ones(k, dtype=bool)
    if k > 1:
        new[1:] = np.any(K[1:] != K[:-1], axis=(1, 2))
    try:
        if new.all():
            return np.linalg.inv(K)
        uniq = np.linalg.inv(K[new])
    except np.linalg.LinAlgError:
        for i in range(k):
            try:
                np.linalg.inv(K[i])
            except np.linalg.LinAlgError:
                raise InputError(
                    f"the effective stiffness A/(beta h^2) + gamma B/(beta h) + C is singular "
                    f"at t = {t[i]:.9g} s; check that A(t) is positive definite there"
                ) from None
        raise
    return uniq[np.cumsum(new) - 1]


def count_text(n: float) -> str:
    """A count for a message: whole digits up to 1e9, else 3 significant digits
    (an absurd step must not print a 300-digit integer)."""
    return f"{int(n)}" if n < 1e9 else f"{n:.3g}"


def check_options(options: Any) -> Any:
    """``options`` (None: the defaults) as a NewmarkOptions, or one line naming it."""
    from ._options import NewmarkOptions

    opts = NewmarkOptions() if options is None else options
    if not isinstance(opts, NewmarkOptions):
        raise InputError(f"options must be a NewmarkOptions (got {type(opts).__name__})")
    return opts


def stability_notes(opts: Any, notes: list[str]) -> None:
    """A note when the parameters are not unconditionally stable (Bathe & Wilson)."""
    if not opts.unconditionally_stable:
        notes.append(
            f"gamma={float(opts.gamma)}, beta={float(opts.beta)} is not unconditionally stable in the sense "
            "of Bathe & Wilson (gamma >= 1/2, beta >= (gamma + 1/2)^2/4)"
        )
