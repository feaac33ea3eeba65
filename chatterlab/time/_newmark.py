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

import math
import threading
import time
import warnings
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chatterlab.errors import InputError

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

FloatArray = NDArray[Any]
Matrices = tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]


class NewmarkStabilityWarning(UserWarning):
    """The chosen Newmark parameters are only conditionally stable."""


# =========================================================================== problems


@runtime_checkable
class TimeVaryingProblem(Protocol):
    """What :func:`newmark` integrates: ``A q'' + B q' + C q = p(t) + G q(t - T)``.

    Attributes
    ----------
    n : int
        Number of generalised coordinates.

    Optional attributes read with ``getattr``: ``names`` (sequence of ``n``
    coordinate names), ``time_invariant`` (``True`` when ``A, B, C, G``
    do not depend on time: the effective stiffness is then factored once) and
    ``breakpoints()`` (times [s] where the matrices or the force jump, e.g.
    the tool entering the cut; the functions must be right-continuous there).
    A breakpoint on the step grid is crossed with left limits and a restart
    of the acceleration, which keeps the second order; one off the grid costs
    a first-order error at the jump (reported in the result message).
    """

    n: int

    def matrices(self, t: FloatArray) -> Matrices:
        """Coefficient matrices at the times ``t`` (s), shape ``(k,)``.

        Returns ``(A, B, C, G)``, each of shape ``(k, n, n)`` (a ``(n, n)``
        array is broadcast): inertia [kg, kg m^2], damping [N s/m...],
        stiffness [N/m...] and delayed-feedback [N/m...] matrices.  ``G`` is
        ``None`` when there is no delayed term.
        """
        ...

    def force(self, t: FloatArray) -> FloatArray:
        """External generalised force ``p(t)`` [N, N m], shape ``(k, n)``."""
        ...

    def delay(self) -> float | None:
        """The delay ``T`` [s] of the ``G q(t - T)`` term, or ``None``."""
        ...


def _as_square(name: str, value: ArrayLike, n: int | None = None) -> FloatArray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1]:
        raise InputError(f"{name} must be a square 2-D matrix (got shape {arr.shape})")
    if n is not None and arr.shape[0] != n:
        raise InputError(f"{name} must be {n}x{n} like M (got shape {arr.shape})")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains NaN or infinite entries")
    return arr


def _check_delay(delay: float | None, has_g: bool, who: str) -> float | None:
    if delay is None:
        if has_g:
            raise InputError(f"{who}: G is given but delay is None; give the delay T > 0 in s")
        return None
    d = float(delay)
    if not math.isfinite(d) or d <= 0.0:
        raise InputError(f"{who}: delay must be a finite number > 0 s (got {delay!r})")
    return d


def _as_breakpoints(b: Sequence[float] | None) -> tuple[float, ...]:
    if b is None:
        return ()
    arr = np.asarray(b, dtype=float).reshape(-1)
    if not np.all(np.isfinite(arr)):
        raise InputError("breakpoints must be finite times in s")
    return tuple(sorted(set(arr.tolist())))


def _eval_force(
    force: Callable[[FloatArray], ArrayLike] | ArrayLike | None, t: FloatArray, n: int, who: str
) -> FloatArray:
    """Evaluate a force spec (None, constant (n,), vectorised callable) at ``t``."""
    if force is None:
        return np.zeros((t.size, n))
    if callable(force):
        out = np.asarray(force(t), dtype=float)
        if out.shape == (t.size, n):
            return out
        if out.shape == (n,):
            return np.broadcast_to(out, (t.size, n))
        raise InputError(
            f"{who}: force(t) must return an array of shape (len(t), n) = ({t.size}, {n}) "
            f"for a 1-D array of times t (got shape {out.shape}); vectorise it, e.g. "
            "lambda t: np.outer(np.sin(w * t), F)"
        )
    arr = np.asarray(force, dtype=float)
    if arr.shape != (n,):
        raise InputError(f"{who}: a constant force must have shape ({n},) (got {arr.shape})")
    return np.broadcast_to(arr, (t.size, n))


class ConstantProblem:
    """Time-invariant system ``M q'' + C q' + K q = p(t) + G q(t - T)``.

    Parameters
    ----------
    M, C, K : array_like, shape (n, n)
        Inertia [kg], damping [N s/m] and stiffness [N/m] matrices (or the
        rotational equivalents).  Note the mechanical naming: here ``C`` is the
        *damping* matrix; it becomes ``B`` of :class:`TimeVaryingProblem`.
    force : callable or array_like or None, optional
        ``force(t)`` with ``t`` a 1-D array of times [s] returning ``(len(t), n)``
        [N]; a constant ``(n,)`` vector; or ``None`` (no external force).
    G : array_like, shape (n, n), optional
        Delayed-feedback matrix [N/m] of the term ``G q(t - T)``.
    delay : float, optional
        The delay ``T`` [s]; required with ``G``.
    names : sequence of str, optional
        Names of the ``n`` coordinates.
    breakpoints : sequence of float, optional
        Times [s] where ``force`` jumps (see :class:`TimeVaryingProblem`).
    """

    time_invariant = True

    def __init__(
        self,
        M: ArrayLike,
        C: ArrayLike,
        K: ArrayLike,
        force: Callable[[FloatArray], ArrayLike] | ArrayLike | None = None,
        G: ArrayLike | None = None,
        delay: float | None = None,
        *,
        names: Sequence[str] | None = None,
        breakpoints: Sequence[float] | None = None,
    ) -> None:
        self.M = _as_square("M", M)
        self._breakpoints = _as_breakpoints(breakpoints)
        self.n = int(self.M.shape[0])
        self.C = _as_square("C (damping)", C, self.n)
        self.K = _as_square("K (stiffness)", K, self.n)
        self.G = None if G is None else _as_square("G (delayed feedback)", G, self.n)
        self._delay = _check_delay(delay, self.G is not None, "ConstantProblem")
        self._force = force
        self.names = None if names is None else tuple(str(s) for s in names)
        if self.names is not None and len(self.names) != self.n:
            raise InputError(f"names must have {self.n} entries (got {len(self.names)})")

    def matrices(self, t: FloatArray) -> Matrices:
        k = np.asarray(t).size
        shape = (k, self.n, self.n)
        g = None if self.G is None else np.broadcast_to(self.G, shape)
        return (
            np.broadcast_to(self.M, shape),
            np.broadcast_to(self.C, shape),
            np.broadcast_to(self.K, shape),
            g,
        )

    def force(self, t: FloatArray) -> FloatArray:
        return _eval_force(self._force, np.asarray(t, dtype=float), self.n, "ConstantProblem")

    def delay(self) -> float | None:
        return self._delay

    def breakpoints(self) -> tuple[float, ...]:
        return self._breakpoints


class CallbackProblem:
    """Adapter turning user functions of time into a :class:`TimeVaryingProblem`.

    Parameters
    ----------
    n : int
        Number of coordinates.
    A, B, C : callable or array_like
        Inertia, damping and stiffness: a constant ``(n, n)`` matrix or a
        function of time.  With ``vectorized=False`` (default) the function is
        called once per time with a float ``t`` [s] and returns ``(n, n)``; with
        ``vectorized=True`` it is called with a 1-D array of times and returns
        ``(len(t), n, n)`` (much faster).
    G : callable or array_like, optional
        Delayed-feedback matrix, same conventions; requires ``delay``.
    delay : float, optional
        Delay ``T`` [s].
    force : callable or array_like, optional
        External force: with ``vectorized=False`` ``force(t: float) -> (n,)``,
        otherwise ``force(t: (k,)) -> (k, n)``; or a constant ``(n,)`` vector.
    vectorized : bool, default False
        See above.
    names : sequence of str, optional
        Coordinate names.
    breakpoints : sequence of float, optional
        Times [s] where a coefficient or the force jumps; the functions must
        be right-continuous there (see :class:`TimeVaryingProblem`).
    """

    time_invariant = False

    def __init__(
        self,
        n: int,
        A: Callable[..., ArrayLike] | ArrayLike,
        B: Callable[..., ArrayLike] | ArrayLike,
        C: Callable[..., ArrayLike] | ArrayLike,
        *,
        G: Callable[..., ArrayLike] | ArrayLike | None = None,
        delay: float | None = None,
        force: Callable[..., ArrayLike] | ArrayLike | None = None,
        vectorized: bool = False,
        names: Sequence[str] | None = None,
        breakpoints: Sequence[float] | None = None,
    ) -> None:
        self._breakpoints = _as_breakpoints(breakpoints)
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise InputError(f"n must be a positive integer (got {n!r})")
        self.n = int(n)
        self._spec = {"A": A, "B": B, "C": C, "G": G}
        for key, val in self._spec.items():
            if val is not None and not callable(val):
                self._spec[key] = _as_square(key, val, self.n)
        self._delay = _check_delay(delay, G is not None, "CallbackProblem")
        self._force = force
        self.vectorized = bool(vectorized)
        self.names = None if names is None else tuple(str(s) for s in names)

    def _one(self, key: str, t: FloatArray) -> FloatArray | None:
        spec = self._spec[key]
        k, n = t.size, self.n
        if spec is None:
            return None
        if not callable(spec):
            return np.broadcast_to(spec, (k, n, n))
        if self.vectorized:
            out = np.asarray(spec(t), dtype=float)
        else:
            out = np.empty((k, n, n))
            for i, ti in enumerate(t):
                val = np.asarray(spec(float(ti)), dtype=float)
                if val.shape != (n, n):
                    raise InputError(
                        f"CallbackProblem: {key}(t) must return shape ({n}, {n}) per time (got {val.shape})"
                    )
                out[i] = val
        if out.shape == (n, n):
            out = np.broadcast_to(out, (k, n, n))
        if out.shape != (k, n, n):
            raise InputError(
                f"CallbackProblem: {key}(t) must return shape ({n}, {n}) per time "
                f"(or ({k}, {n}, {n}) when vectorized) (got {out.shape})"
            )
        return out

    def matrices(self, t: FloatArray) -> Matrices:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        A, B, C = (self._one(key, t) for key in "ABC")
        assert A is not None and B is not None and C is not None
        return A, B, C, self._one("G", t)

    def force(self, t: FloatArray) -> FloatArray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self._force is None or not callable(self._force) or self.vectorized:
            return _eval_force(self._force, t, self.n, "CallbackProblem")
        out = np.empty((t.size, self.n))
        for i, ti in enumerate(t):
            val = np.asarray(self._force(float(ti)), dtype=float)
            if val.shape != (self.n,):
                raise InputError(
                    f"CallbackProblem: force(t) must return shape ({self.n},) per time (got {val.shape})"
                )
            out[i] = val
        return out

    def delay(self) -> float | None:
        return self._delay

    def breakpoints(self) -> tuple[float, ...]:
        return self._breakpoints


class PiecewiseProblem:
    """A sequence of problems, each valid between two breakpoints.

    Piece ``i`` applies on ``[breakpoints[i-1], breakpoints[i])`` (the first
    from ``-inf``, the last up to ``+inf``): right-continuous, and the
    switching times are reported by :meth:`breakpoints` so that a switch on
    the step grid keeps second-order accuracy.  Useful for a slide that stops at
    a few positions, or for switching a feedback on and off.  Consecutive
    identical effective stiffness matrices are inverted only once, so
    piecewise-constant pieces cost about as little as a :class:`ConstantProblem`.

    Parameters
    ----------
    breakpoints : sequence of float
        Increasing switching times [s], ``len(pieces) - 1`` of them.
    pieces : sequence of TimeVaryingProblem
        The problems, all with the same ``n`` and, where they have a delayed
        term, the same delay.
    """

    time_invariant = False

    def __init__(self, breakpoints: Sequence[float], pieces: Sequence[TimeVaryingProblem]) -> None:
        self.breakpoints_switch = np.asarray(breakpoints, dtype=float).reshape(-1)
        self.pieces = list(pieces)
        if not self.pieces:
            raise InputError("PiecewiseProblem needs at least one piece")
        if self.breakpoints_switch.size != len(self.pieces) - 1:
            raise InputError(
                f"PiecewiseProblem: {len(self.pieces)} pieces need {len(self.pieces) - 1} "
                f"breakpoints (got {self.breakpoints_switch.size})"
            )
        if np.any(np.diff(self.breakpoints_switch) <= 0) or not np.all(np.isfinite(self.breakpoints_switch)):
            raise InputError("PiecewiseProblem: breakpoints must be finite and increasing")
        self.n = int(self.pieces[0].n)
        if any(int(p.n) != self.n for p in self.pieces):
            raise InputError("PiecewiseProblem: all pieces must have the same n")
        delays = {p.delay() for p in self.pieces} - {None}
        if len(delays) > 1:
            raise InputError(
                f"PiecewiseProblem: pieces have different delays {sorted(float(d) for d in delays if d is not None)}"
            )
        self._delay = delays.pop() if delays else None
        self.names = getattr(self.pieces[0], "names", None)

    def _index(self, t: FloatArray) -> np.ndarray:
        return np.searchsorted(self.breakpoints_switch, t, side="right")

    def matrices(self, t: FloatArray) -> Matrices:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        idx = self._index(t)
        n = self.n
        out = [np.zeros((t.size, n, n)) for _ in range(4)]
        any_g = False
        for i in np.unique(idx):
            sel = idx == i
            mats = self.pieces[i].matrices(t[sel])
            for j, m in enumerate(mats):
                if m is not None:
                    out[j][sel] = m
                    any_g |= j == 3
        return out[0], out[1], out[2], (out[3] if any_g else None)

    def force(self, t: FloatArray) -> FloatArray:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        idx = self._index(t)
        out = np.zeros((t.size, self.n))
        for i in np.unique(idx):
            sel = idx == i
            out[sel] = self.pieces[i].force(t[sel])
        return out

    def delay(self) -> float | None:
        return self._delay

    def breakpoints(self) -> tuple[float, ...]:
        """The switching times and the breakpoints of the pieces."""
        out = set(self.breakpoints_switch)
        for p in self.pieces:
            fn = getattr(p, "breakpoints", None)
            if callable(fn):
                out.update(float(b) for b in fn())
        return tuple(sorted(out))


# =========================================================================== options & result


@dataclass(frozen=True)
class NewmarkOptions:
    """Parameters of the Newmark integrator.

    Attributes
    ----------
    gamma, beta : float
        Newmark parameters.  Default ``1/2, 1/4``: average acceleration
        (trapezoidal rule), unconditionally stable, second order, no numerical
        damping.  Following Bathe & Wilson (1976) the scheme is called
        unconditionally stable when ``gamma >= 1/2`` and
        ``beta >= (gamma + 1/2)^2 / 4``; ``gamma > 1/2`` adds numerical damping
        and lowers the order to one.  ``beta < gamma/2`` is only conditionally
        stable (``w_max h < (gamma/2 - beta)^(-1/2)``) and gives a
        :class:`NewmarkStabilityWarning`.  ``beta <= 0`` (explicit) and
        ``gamma < 1/2`` (negative numerical damping: spurious growth, the worst
        possible error for a chatter prediction) are refused.
    chunk : int or None
        Steps whose matrices are prepared together.  ``None`` picks about
        ``2**18 / n**2`` (2 MB per stack of matrices), within [16, 4096].
    workers : int, default 2
        Background threads preparing the next chunks (matrices, batched
        inverse) while the current one is stepped; 0 prepares them in the
        calling thread.  The batched LAPACK calls release the GIL, so two
        workers keep two cores busy.  The problem's ``matrices``/``force``
        are called under a lock (one call at a time), so a
        problem object need not be thread-safe.
    divergence_limit : float, default 1e12
        ``max |q|`` (units of ``q``: m, rad) beyond which the run stops with
        ``status="diverged"``.
    max_history_bytes : int, default 2 GiB
        Memory allowed for the stored state history (needed for the delay).
    max_output_bytes : int, default 4 GiB
        Memory allowed for the recorded ``q, v, a``.
    """

    gamma: float = 0.5
    beta: float = 0.25
    chunk: int | None = None
    workers: int = 2
    divergence_limit: float = 1e12
    max_history_bytes: int = 2 * 1024**3
    max_output_bytes: int = 4 * 1024**3

    def __post_init__(self) -> None:
        g, b = self.gamma, self.beta
        if not (isinstance(g, (int, float)) and math.isfinite(g)):
            raise InputError(f"NewmarkOptions.gamma must be a finite number (got {g!r})")
        if not (isinstance(b, (int, float)) and math.isfinite(b)):
            raise InputError(f"NewmarkOptions.beta must be a finite number (got {b!r})")
        if b <= 0.0:
            raise InputError(
                f"NewmarkOptions.beta must be > 0 (got {b}); beta = 0 is the explicit central "
                "difference scheme, which this implicit solver does not implement; use the "
                "default beta = 1/4"
            )
        if g < 0.5:
            raise InputError(
                f"NewmarkOptions.gamma must be >= 1/2 (got {g}); gamma < 1/2 adds negative "
                "numerical damping, i.e. spurious growth that would be mistaken for chatter"
            )
        if self.chunk is not None and (
            isinstance(self.chunk, bool) or not isinstance(self.chunk, (int, np.integer)) or self.chunk < 1
        ):
            raise InputError(f"NewmarkOptions.chunk must be a positive integer or None ({self.chunk!r})")
        if (
            isinstance(self.workers, bool)
            or not isinstance(self.workers, (int, np.integer))
            or self.workers < 0
        ):
            raise InputError(f"NewmarkOptions.workers must be an integer >= 0 ({self.workers!r})")
        if not (self.divergence_limit > 0):
            raise InputError(f"NewmarkOptions.divergence_limit must be > 0 (got {self.divergence_limit!r})")
        for name in ("max_history_bytes", "max_output_bytes"):
            if not getattr(self, name) > 0:
                raise InputError(f"NewmarkOptions.{name} must be > 0")

    @property
    def unconditionally_stable(self) -> bool:
        """``gamma >= 1/2`` and ``beta >= (gamma + 1/2)^2 / 4`` (Bathe & Wilson)."""
        return self.gamma >= 0.5 and self.beta >= (self.gamma + 0.5) ** 2 / 4.0 - 1e-15

    @property
    def critical_omega_h(self) -> float:
        """Stability limit of ``w h`` for an undamped mode (``inf`` when ``beta >= gamma/2``)."""
        if self.beta >= self.gamma / 2.0:
            return math.inf
        return 1.0 / math.sqrt(self.gamma / 2.0 - self.beta)


@dataclass(frozen=True, eq=False)
class TimeResponse:
    """Result of :func:`newmark`.

    Attributes
    ----------
    t : ndarray, shape (n_t,)
        Recorded times [s].
    q, v, a : ndarray, shape (n_out, n_t)
        Displacement [m, rad], velocity [m/s, rad/s] and acceleration
        [m/s^2, rad/s^2] at the recorded output coordinates.
    names : tuple of str or None
        Names of the ``n_out`` outputs.
    status : str
        ``"ok"``, ``"diverged"`` (non-finite state or ``|q|`` beyond
        ``divergence_limit``; the data stop before it), ``"interrupted"``
        (KeyboardInterrupt: the data computed so far) or ``"stopped"``
        (the ``callback`` asked to stop).
    message : str
        Human-readable account of the run (and of any stability caveat).
    n_steps : int
        Number of steps integrated.
    wall_time : float
        Wall-clock time of the integration [s].
    h : float
        Step [s].
    """

    t: FloatArray
    q: FloatArray
    v: FloatArray
    a: FloatArray
    names: tuple[str, ...] | None
    status: str
    message: str
    n_steps: int
    wall_time: float
    h: float = math.nan
    attrs: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def _row(self, coord: int | str) -> int:
        if isinstance(coord, str):
            if self.names is None or coord not in self.names:
                raise InputError(f"coord {coord!r} is not one of the output names {self.names}")
            return self.names.index(coord)
        i = int(coord)
        if not -self.q.shape[0] <= i < self.q.shape[0]:
            raise InputError(f"coord {coord} out of range for {self.q.shape[0]} outputs")
        return i

    def _field(self, name: str) -> FloatArray:
        if name not in ("q", "v", "a"):
            raise InputError(f"field must be 'q', 'v' or 'a' (got {name!r})")
        return getattr(self, name)

    def _series(self, coord: int | str, field_: str, t_min: float | None) -> tuple[FloatArray, FloatArray]:
        x = self._field(field_)[self._row(coord)]
        if t_min is None:
            return self.t, x
        sel = self.t >= t_min
        return self.t[sel], x[sel]

    def spectrum(
        self, coord: int | str = 0, *, field: str = "q", t_min: float | None = None, **kwargs: Any
    ) -> tuple[FloatArray, FloatArray]:
        """Amplitude spectrum of one output (see :func:`chatterlab.time._signals.amplitude_spectrum`).

        Returns ``(freq [Hz], amplitude [units of the field])``; ``t_min``
        [s] drops the start (e.g. the transient).
        """
        from chatterlab.time._signals import amplitude_spectrum

        t, x = self._series(coord, field, t_min)
        return amplitude_spectrum(t, x, **kwargs)

    def growth_rate(self, coord: int | str = 0, *, field: str = "q", **kwargs: Any) -> Any:
        """Envelope growth rate of one output (see :func:`chatterlab.time._signals.growth_rate`)."""
        from chatterlab.time._signals import growth_rate

        t, x = self._series(coord, field, None)
        return growth_rate(t, x, **kwargs)

    def _labels(self) -> list[str]:
        if self.names is not None:
            return list(self.names)
        return [f"out{i}" for i in range(self.q.shape[0])]

    def to_csv(self, path: str | Path, *, fields: Sequence[str] = ("q",)) -> Path:
        """Write ``t`` and the chosen fields as a wide CSV file (one row per time).

        Columns: ``t [s]`` then ``<field>:<name>`` for each output; SI units.
        """
        path = Path(path)
        cols = [self.t]
        header = ["t [s]"]
        for f in fields:
            arr = self._field(f)
            cols.extend(arr)
            header.extend(f"{f}:{name}" for name in self._labels())
        np.savetxt(
            path, np.column_stack(cols), delimiter=",", header=",".join(header), comments="", fmt="%.17g"
        )
        return path

    def to_netcdf(self, path: str | Path) -> Path:
        """Write the response with :func:`chatterlab.io._netcdf.write_netcdf` (dims output, time)."""
        try:
            from chatterlab.io._netcdf import write_netcdf
        except ImportError as exc:  # pragma: no cover - depends on the install
            raise ImportError(
                "TimeResponse.to_netcdf needs chatterlab.io._netcdf; use to_csv instead"
            ) from exc
        coords = {
            "output": (np.arange(self.q.shape[0]), "", "recorded output index"),
            "time": (self.t, "s", "time"),
        }
        data = {
            "q": (self.q, "SI", "displacement"),
            "v": (self.v, "SI", "velocity"),
            "a": (self.a, "SI", "acceleration"),
        }
        attrs = {
            "output_names": ",".join(self._labels()),
            "status": self.status,
            "message": self.message,
            "step_s": float(self.h),
            "n_steps": int(self.n_steps),
        }
        return write_netcdf(path, coords, data, attrs)

    def plot(
        self,
        coords: Sequence[int | str] | int | str | None = None,
        *,
        field: str = "q",
        ax: Any = None,
        **kwargs: Any,
    ) -> Any:
        """Plot outputs against time with matplotlib; returns the Axes."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots()
        rows = (
            range(self.q.shape[0])
            if coords is None
            else ([coords] if isinstance(coords, (int, str)) else list(coords))
        )
        arr = self._field(field)
        labels = self._labels()
        for c in rows:
            i = self._row(c)
            ax.plot(self.t, arr[i], label=labels[i], **kwargs)
        ax.set_xlabel("t [s]")
        ax.set_ylabel(field)
        ax.legend()
        return ax


# =========================================================================== helpers


def _hermite_weights(s: float, h: float) -> FloatArray:
    """Weights of ``[q_j, v_j, q_j+1, v_j+1]`` for ``q(t_j + s h)``, cubic Hermite."""
    s2, s3 = s * s, s * s * s
    return np.array([2 * s3 - 3 * s2 + 1, h * (s3 - 2 * s2 + s), -2 * s3 + 3 * s2, h * (s3 - s2)])


def _history_function(history: Any, n: int, t0: float) -> Callable[[FloatArray], FloatArray]:
    """Normalise ``history`` to a vectorised ``f(t: (k,)) -> (k, n)``."""
    if history is None:
        return lambda t: np.zeros((np.size(t), n))
    if callable(history):

        def f(t: FloatArray) -> FloatArray:
            out = np.asarray(history(t), dtype=float)
            if out.shape == (n,) and t.size != n:
                out = np.broadcast_to(out, (t.size, n))
            if out.shape != (t.size, n):
                raise InputError(
                    f"history(t) must return shape (len(t), n) = ({t.size}, {n}) for a 1-D "
                    f"array of times t <= t0 (got {out.shape})"
                )
            return out

        return f
    if isinstance(history, tuple) and len(history) == 2:
        th = np.asarray(history[0], dtype=float).reshape(-1)
        qh = np.asarray(history[1], dtype=float)
        if qh.ndim != 2 or qh.shape != (th.size, n):
            raise InputError(
                f"history=(t, q): q must have shape (len(t), n) = ({th.size}, {n}) (got {qh.shape})"
            )
        if th.size < 2 or np.any(np.diff(th) <= 0):
            raise InputError("history=(t, q): t needs >= 2 increasing times")
        if not (np.all(np.isfinite(th)) and np.all(np.isfinite(qh))):
            raise InputError("history=(t, q) contains NaN or infinite values")
        from scipy.interpolate import CubicSpline, interp1d

        interp = CubicSpline(th, qh, axis=0) if th.size >= 4 else interp1d(th, qh, axis=0)

        def g(t: FloatArray) -> FloatArray:
            if t.size and (
                t.min() < th[0] - 1e-12 * max(1.0, abs(th[0]))
                or t.max() > th[-1] + 1e-12 * max(1.0, abs(th[-1]))
            ):
                raise InputError(
                    f"history=(t, q) covers [{th[0]:.6g}, {th[-1]:.6g}] s but times "
                    f"[{t.min():.6g}, {t.max():.6g}] s are needed (t0 - T .. t0)"
                )
            return np.asarray(interp(t), dtype=float)

        return g
    arr = np.asarray(history, dtype=float)
    if arr.shape != (n,):
        raise InputError(
            "history must be None (zero), a constant (n,) vector, a vectorised callable "
            f"history(t) -> (len(t), n) or a tuple (t, q) with q of shape (len(t), n); n={n} "
            f"(got an array of shape {arr.shape})"
        )
    if not np.all(np.isfinite(arr)):
        raise InputError("history contains NaN or infinite values")
    return lambda t: np.broadcast_to(arr, (np.size(t), n))


def _outputs(
    outputs: Any, n: int, names: Sequence[str] | None
) -> tuple[np.ndarray | None, FloatArray | None, tuple[str, ...] | None]:
    """Return ``(indices, selector matrix, names)``; exactly one of the first two is set."""
    if outputs is None:
        return np.arange(n), None, (tuple(names) if names is not None else None)
    if isinstance(outputs, Mapping):
        out_names = tuple(str(k) for k in outputs)
        rows = []
        for key, val in outputs.items():
            arr = np.asarray(val)
            if arr.ndim == 0:
                row = np.zeros(n)
                idx = int(arr)
                if not 0 <= idx < n:
                    raise InputError(f"outputs[{key!r}] = {idx} is not a coordinate index 0..{n - 1}")
                row[idx] = 1.0
            elif arr.shape == (n,):
                row = arr.astype(float)
            else:
                raise InputError(f"outputs[{key!r}] must be a coordinate index or a row of {n} weights")
            rows.append(row)
        sel = np.array(rows)
        return None, sel, out_names
    arr = np.asarray(outputs)
    if arr.ndim == 1 and arr.dtype.kind in "iu":
        if arr.size == 0 or arr.min() < -n or arr.max() >= n:
            raise InputError(f"outputs: indices must be in 0..{n - 1} (got {arr.tolist()})")
        out_i = arr % n
        return out_i, None, (tuple(names[i] for i in out_i) if names is not None else None)
    if arr.ndim == 2 and arr.shape[1] == n and arr.shape[0] >= 1:
        sel = arr.astype(float)
        if not np.all(np.isfinite(sel)):
            raise InputError("outputs selector matrix contains NaN or infinite values")
        return None, sel, None
    raise InputError(
        "outputs must be None (all coordinates), a sequence of coordinate indices, a selector "
        f"matrix of shape (n_out, {n}) or a mapping name -> index/row (got {arr.shape})"
    )


def _vector(name: str, value: ArrayLike | None, n: int) -> FloatArray:
    if value is None:
        return np.zeros(n)
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0 and n == 1:
        arr = arr.reshape(1)
    if arr.shape != (n,):
        raise InputError(f"{name} must have shape ({n},) (got {arr.shape})")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains NaN or infinite values")
    return arr.copy()


def _check_problem(problem: Any) -> int:
    for attr in ("n", "matrices", "force", "delay"):
        if not hasattr(problem, attr):
            raise InputError(
                f"problem must provide n, matrices(t), force(t) and delay() (missing {attr!r}); "
                "wrap plain matrices in ConstantProblem or functions in CallbackProblem"
            )
    n = problem.n
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise InputError(f"problem.n must be a positive integer (got {n!r})")
    return int(n)


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


@dataclass
class _Plan:
    """Everything :func:`newmark` fixes before the first step: the grid, the
    scheme constants, the delay's place on the grid, the history samples,
    the breakpoints, the output selection and the initial state."""

    problem: Any
    n: int
    opts: NewmarkOptions
    t0: float
    t1: float
    h: float
    n_total: int  # steps
    rec: int  # record every rec-th step
    n_rec: int  # recorded times
    out_idx: np.ndarray | None
    out_sel: FloatArray | None
    out_names: tuple[str, ...] | None
    gam: float
    bet: float
    coef: tuple[float, float, float, float, float, float]  # c0, c1, c2, c3, dv1, dv2
    A0: FloatArray
    B0: FloatArray
    C0: FloatArray
    G0: FloatArray | None
    T: float | None
    exact: bool  # the delay is a whole number of steps
    s_frac: float  # else: q(t - T) = q(t_j + s_frac h), j = i - shift
    shift: int
    keep: int  # stored steps the delayed term needs
    chunk: int
    cap: int  # rows of the state buffer
    n_hist: int  # steps whose delayed time lies before t0
    hist_vals: FloatArray  # (n_hist, n) history at those delayed times
    bp_steps: set[int]
    q0: FloatArray
    v0: FloatArray
    a0: FloatArray
    notes: list[str]

    @property
    def has_delay(self) -> bool:
        return self.G0 is not None


def _time_grid(t_span: Any, h: Any, record_every: Any) -> tuple[float, float, float, int, int]:
    """``(t0, t1, h, n_total, rec)`` from the arguments, checked."""
    try:
        t0, t1 = (float(x) for x in t_span)
    except (TypeError, ValueError):
        raise InputError(f"t_span must be a pair (t0, t1) of numbers in s (got {t_span!r})") from None
    if not (math.isfinite(t0) and math.isfinite(t1)):
        raise InputError(f"t_span must be finite (got {t_span!r})")
    if t1 <= t0:
        raise InputError(f"t_span: the duration t1 - t0 must be > 0 s (got t0={t0}, t1={t1})")
    try:
        h = float(h)
    except (TypeError, ValueError):
        raise InputError(f"h must be a number in s (got {h!r})") from None
    if not math.isfinite(h) or h <= 0.0:
        raise InputError(f"h (time step) must be a finite number > 0 s (got {h})")
    n_total = int(math.floor((t1 - t0) / h + 1e-9))
    if n_total < 1:
        raise InputError(f"h = {h:.6g} s is longer than the duration t1 - t0 = {t1 - t0:.6g} s")
    if isinstance(record_every, bool) or not isinstance(record_every, (int, np.integer)) or record_every < 1:
        raise InputError(f"record_every must be a positive integer (got {record_every!r})")
    return t0, t1, h, n_total, int(record_every)


def _scheme(
    opts: NewmarkOptions, h: float, notes: list[str]
) -> tuple[float, float, float, float, float, float]:
    """Newmark constants ``(c0, c1, c2, c3, dv1, dv2)`` for step h (a note when
    the parameters are not unconditionally stable)."""
    gam, bet = float(opts.gamma), float(opts.beta)
    if not opts.unconditionally_stable:
        notes.append(
            f"gamma={gam}, beta={bet} is not unconditionally stable in the sense of Bathe & "
            "Wilson (gamma >= 1/2, beta >= (gamma + 1/2)^2/4)"
        )
    return (
        1.0 / (bet * h * h),
        gam / (bet * h),
        1.0 / (bet * h),
        1.0 / (2.0 * bet) - 1.0,
        1.0 - gam / bet,
        h * (1.0 - gam / (2.0 * bet)),
    )


def _delay_on_grid(T: Any, h: float) -> tuple[float, bool, float, int, int]:
    """``(T, exact, s_frac, shift, keep)``: where q(t - T) lies on the step grid."""
    if T is None:
        raise InputError("problem.matrices returned G but problem.delay() is None")
    T = float(T)
    if not math.isfinite(T) or T <= 0:
        raise InputError(f"problem.delay() must be a finite number > 0 s (got {T})")
    d = T / h
    if d < 1.0 - 1e-9:
        raise InputError(
            f"h = {h:.6g} s is larger than the delay T = {T:.6g} s: the delayed term "
            f"G q(t - T) must be known before each step; use h <= T (e.g. h = T/"
            f"{max(2, math.ceil(h / T))})"
        )
    m_round = round(d)
    if abs(d - m_round) <= 1e-9 * max(1.0, d):
        exact, m_del, s_frac = True, int(m_round), 0.0
        shift = m_del  # j = i - m is a stored node
    else:
        exact, m_del = False, int(math.floor(d))
        s_frac = 1.0 - (d - m_del)  # q(t_j + s h), j = i - m - 1
        shift = m_del + 1
    return T, exact, s_frac, shift, shift + 2


def _plan(
    problem: Any,
    n: int,
    opts: NewmarkOptions,
    t_span: Any,
    h: Any,
    q0: Any,
    v0: Any,
    outputs: Any,
    record_every: Any,
    history: Any,
) -> _Plan:
    """Check the arguments and fix everything before the first step."""
    t0, t1, h, n_total, rec = _time_grid(t_span, h, record_every)
    q0v = _vector("q0", q0, n)
    v0v = _vector("v0", v0, n)
    out_idx, out_sel, out_names = _outputs(outputs, n, getattr(problem, "names", None))
    n_out = out_idx.size if out_idx is not None else out_sel.shape[0]  # type: ignore[union-attr]
    n_rec = n_total // rec + 1
    out_bytes = 3 * n_out * n_rec * 8
    if out_bytes > opts.max_output_bytes:
        raise InputError(
            f"recording {n_out} outputs at {_count(n_rec)} times needs {out_bytes / 2**30:.2f} GiB > "
            f"max_output_bytes = {opts.max_output_bytes / 2**30:.2f} GiB; record fewer "
            "coordinates (outputs=...), thin the record (record_every=...) or raise "
            "NewmarkOptions.max_output_bytes"
        )
    notes: list[str] = []
    coef = _scheme(opts, h, notes)

    # ---- initial state and delay -------------------------------------------------------
    t0a = np.array([t0])
    A0, B0, C0, G0 = problem.matrices(t0a)
    A0, B0, C0 = (_stack(nm, m, 1, n, t0a)[0] for nm, m in zip("ABC", (A0, B0, C0), strict=True))
    T = problem.delay()
    has_delay = G0 is not None
    if has_delay:
        G0 = _stack("G", G0, 1, n, t0a)[0]
        T, exact, s_frac, shift, keep = _delay_on_grid(T, h)
    else:
        T = None
        exact, s_frac, shift, keep = True, 0.0, 0, 1

    chunk = opts.chunk if opts.chunk is not None else int(np.clip(2**18 // (n * n), 16, 4096))
    chunk = int(min(chunk, n_total))
    cap = keep + max(chunk, keep) + 1
    hist_bytes = (cap * 4 + (shift + 1 if has_delay else 0)) * n * 8  # buffer + history samples
    if hist_bytes > opts.max_history_bytes:
        raise InputError(
            f"the delay T = {T:.6g} s at step h = {h:.6g} s needs {_count(keep)} stored steps of {n} "
            f"coordinates ({hist_bytes / 2**30:.2f} GiB) > max_history_bytes = "
            f"{opts.max_history_bytes / 2**30:.2f} GiB; use a larger step h, or raise "
            "NewmarkOptions(max_history_bytes=...) if the memory is available"
        )
    hist_f = _history_function(history, n, t0) if has_delay else None
    n_hist, hist_vals = _history_samples(hist_f, n, t0, h, T, exact, shift, n_total)
    a0 = _initial_acceleration(problem, n, t0, A0, B0, C0, G0, hist_vals, q0v, v0v)
    bp_steps = _breakpoint_steps(problem, hist_f, q0v, t0, T, h, n_total, notes)
    _stability_note(opts, A0, C0, h, notes)
    return _Plan(
        problem, n, opts, t0, t1, h, n_total, rec, n_rec, out_idx, out_sel, out_names,
        float(opts.gamma), float(opts.beta), coef, A0, B0, C0, G0, T, exact, s_frac, shift, keep,
        chunk, cap, n_hist, hist_vals, bp_steps, q0v, v0v, a0, notes,
    )  # fmt: skip


def _history_samples(
    hist_f: Callable[[FloatArray], FloatArray] | None,
    n: int,
    t0: float,
    h: float,
    T: float | None,
    exact: bool,
    shift: int,
    n_total: int,
) -> tuple[int, FloatArray]:
    """The history at the delayed times of the first steps: ``(n_hist, (n_hist, n))``."""
    if hist_f is None or T is None:
        return 0, np.zeros((0, n))
    # steps i whose delayed time t_i - T lies before t0 (i = 0 included); with a whole
    # number m of steps per delay, step m (delayed time exactly t0) also reads the
    # history: the left limit, the step that lands on the breakpoint t0 + T
    n_hist = min(shift + 1 if exact else shift, n_total + 1)
    th = t0 + h * np.arange(n_hist) - T
    hist_vals = np.ascontiguousarray(hist_f(th), dtype=float)
    if not np.all(np.isfinite(hist_vals)):
        raise InputError("history(t) returned NaN or infinite values")
    return n_hist, hist_vals


def _initial_acceleration(
    problem: Any,
    n: int,
    t0: float,
    A0: FloatArray,
    B0: FloatArray,
    C0: FloatArray,
    G0: FloatArray | None,
    hist_vals: FloatArray,
    q0v: FloatArray,
    v0v: FloatArray,
) -> FloatArray:
    """a(t0) from the equation of motion."""
    f0 = _force_at(problem, np.array([t0]), n)[0]
    rhs0 = f0 - B0 @ v0v - C0 @ q0v
    if G0 is not None:
        rhs0 = rhs0 + G0 @ hist_vals[0]
    try:
        return np.linalg.solve(A0, rhs0)
    except np.linalg.LinAlgError:
        raise InputError(
            f"A(t0) is singular at t0 = {t0} s: the initial acceleration cannot be computed; "
            "A must be positive definite (no massless coordinates: condense them first)"
        ) from None


def _breakpoint_steps(
    problem: Any,
    hist_f: Callable[[FloatArray], FloatArray] | None,
    q0v: FloatArray,
    t0: float,
    T: float | None,
    h: float,
    n_total: int,
    notes: list[str],
) -> set[int]:
    """Steps that land on a time where the coefficients or the force jump.

    The step landing on a breakpoint uses the left limits (data at t_b - delta), then the
    acceleration is recomputed from the equation of motion with the right limits: a
    restart, which keeps second order across the jump.  Breakpoints off the grid are
    reported in ``notes``.
    """
    bp_times: list[float] = []
    bp_fn = getattr(problem, "breakpoints", None)
    if callable(bp_fn):
        bp_times.extend(float(b) for b in np.asarray(bp_fn(), dtype=float).reshape(-1))
    if hist_f is not None and T is not None:
        # an inconsistent history (history(t0) != q0) makes G q(t - T) jump at t0 + T
        h_t0 = hist_f(np.array([t0]))[0]
        if np.any(np.abs(h_t0 - q0v) > 1e-12 * (np.abs(q0v) + np.abs(h_t0)) + 1e-300):
            bp_times.append(t0 + T)
    bp_steps: set[int] = set()
    off_grid: list[float] = []
    for tb in sorted(set(bp_times)):
        x = (tb - t0) / h
        if not (0.0 < x <= n_total + 1e-9):
            continue
        if abs(x - round(x)) <= 1e-6:
            bp_steps.add(int(round(x)))
        else:
            off_grid.append(tb)
    if off_grid:
        notes.append(
            "breakpoint(s) at t = "
            + ", ".join(f"{b:.9g}" for b in off_grid[:3])
            + (" ..." if len(off_grid) > 3 else "")
            + " s not on the step grid: first-order error at the jump; choose h dividing t_b - t0"
        )
    return bp_steps


def _stability_note(opts: NewmarkOptions, A0: FloatArray, C0: FloatArray, h: float, notes: list[str]) -> None:
    """Note and warn when the scheme is only conditionally stable (with the
    critical step estimated at t0)."""
    if opts.critical_omega_h == math.inf:
        return
    bet = float(opts.beta)
    try:
        import scipy.linalg as sla

        w2 = sla.eigvals(C0, A0)
        wmax = float(np.sqrt(np.max(np.abs(w2[np.isfinite(w2)]))))
        hcr = opts.critical_omega_h / wmax if wmax > 0 else math.inf
        msg = (
            f"beta={bet} < gamma/2 is only conditionally stable: h must be < "
            f"{opts.critical_omega_h:.4g}/w_max = {hcr:.4g} s at t0 (h = {h:.4g} s)"
        )
    except Exception:  # noqa: BLE001 - the estimate is only informative
        msg = f"beta={bet} < gamma/2 is only conditionally stable"
    notes.append(msg)
    warnings.warn(msg, NewmarkStabilityWarning, stacklevel=4)


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


def _count(n: float) -> str:
    """A count for a message: whole digits up to 1e9, else 3 significant digits
    (an absurd step must not print a 300-digit integer)."""
    return f"{int(n)}" if n < 1e9 else f"{n:.3g}"
