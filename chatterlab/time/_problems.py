"""What the Newmark integrator integrates: the :class:`TimeVaryingProblem`
protocol and the ready-made problems (constant, callbacks, piecewise)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from chatterlab.errors import InputError

FloatArray = NDArray[Any]
Matrices = tuple[FloatArray, FloatArray, FloatArray, FloatArray | None]


# =========================================================================== problems


class Sealed:
    """A problem is a value: its attributes are set in ``__init__``, which
    ends with :meth:`_seal`; setting or deleting one afterwards is an
    AttributeError (build a new problem instead).  A cache the object owns
    is updated through ``object.__setattr__``."""

    _sealed = False

    def _seal(self) -> None:
        object.__setattr__(self, "_sealed", True)

    def __setattr__(self, name: str, value: Any) -> None:
        if self._sealed:
            raise AttributeError(
                f"{type(self).__name__} is immutable: build a new one instead of setting {name!r}"
            )
        object.__setattr__(self, name, value)

    def __delattr__(self, name: str) -> None:
        if self._sealed:
            raise AttributeError(f"{type(self).__name__} is immutable: {name!r} cannot be deleted")
        object.__delattr__(self, name)


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


class ConstantProblem(Sealed):
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
        self._seal()

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


class CallbackProblem(Sealed):
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
        self._seal()

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


class PiecewiseProblem(Sealed):
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
        self._seal()

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
