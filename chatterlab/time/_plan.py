"""Everything the Newmark integrator fixes before the first step (:class:`_Plan`):
the arguments checked, the scheme constants, the delay on the step grid, the
history, the breakpoints and the initial acceleration."""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from chatterlab.errors import InputError

from ._core import _force_at, _stack, count_text, delay_on_grid, scheme_constants, stability_notes
from ._options import NewmarkOptions, NewmarkStabilityWarning
from ._problems import FloatArray

# =========================================================================== helpers


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


@dataclass(frozen=True)
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
    coupling: Any = None  # a unilateral coupling's run (:class:`._contact._Contacts`)

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
    stability_notes(opts, notes)
    return scheme_constants(float(opts.gamma), float(opts.beta), h)


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
    whole_a, rem_a = delay_on_grid(d)
    whole, rem = int(whole_a), float(rem_a)
    exact = rem == 0.0
    # exact: j = i - m is a stored node; else q(t_j + s h), j = i - m - 1, s = 1 - rem
    s_frac = 0.0 if exact else 1.0 - rem
    shift = whole if exact else whole + 1
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
            f"recording {n_out} outputs at {count_text(n_rec)} times needs {out_bytes / 2**30:.2f} GiB > "
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
            f"the delay T = {T:.6g} s at step h = {h:.6g} s needs {count_text(keep)} stored steps of {n} "
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


def coupled_plan(
    structure: tuple[FloatArray, FloatArray, FloatArray],
    coupling: Any,
    opts: NewmarkOptions,
    grid: tuple[float, int, int],
    start: tuple[FloatArray, FloatArray, FloatArray],
) -> _Plan:
    """The plan of a structure ``(M, C, K)``, ``M q'' + C q' + K q = P^T F``,
    with a unilateral coupling (:class:`._contact._Contacts`): ``grid`` =
    (step h, steps, the coupling's chunk: its shortest delay in steps),
    ``start`` = (q0, v0, a0), a0 from the coupling's force at t = 0.  No
    linear delayed term and no breakpoints of a problem (the coupling's
    pattern restarts), and the coupling records its own outputs."""
    M, C, K = structure
    h, n_total, chunk = grid
    q0, v0, a0 = start
    n = M.shape[0]
    notes: list[str] = []
    coef = _scheme(opts, h, notes)
    chunk = int(min(chunk, n_total))
    return _Plan(
        None, n, opts, 0.0, n_total * h, h, n_total, 1, n_total + 1, np.zeros(0, dtype=int), None, (),
        float(opts.gamma), float(opts.beta), coef, M, C, K, None, None, True, 0.0, 0, 1,
        chunk, chunk + 2, 0, np.zeros((0, n)), set(), q0, v0, a0, notes, coupling,
    )  # fmt: skip
