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

import time
from collections.abc import Callable
from typing import Any

from numpy.typing import ArrayLike

from ._core import _Stepper, check_options
from ._options import NewmarkOptions, NewmarkStabilityWarning, TimeResponse
from ._plan import _check_problem, _plan
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
    opts = check_options(options)
    n = _check_problem(problem)
    plan = _plan(problem, n, opts, t_span, h, q0, v0, outputs, record_every, history)
    run = _Stepper(plan)
    status, reason, i_done = run.run(progress, callback)
    return _response(run, status, reason, i_done, time.perf_counter() - wall0)


def _response(run: _Stepper, status: str, reason: str, i_done: int, wall: float) -> TimeResponse:
    """The :class:`TimeResponse` of a linear problem's run, with its message."""
    p = run.p
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
    nr = run.n_recorded
    q_out, v_out, a_out = run.out
    return TimeResponse(
        t=run.t_rec[:nr].copy(),
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
