"""Initial conditions of a simulated cut: the start q0, v0 (vectors over
the independent coordinates or values at named points, which take the
least-energy state) and the delay history before t = 0 (zero, constant,
callable or table), checked one argument at a time with one-line messages.
Used by :func:`chatterlab.time.simulate`."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ..errors import InputError
from ._parametric import ParametricProblem, _output_map

__all__ = ["AT_REST", "initial_state"]

#: what a run from rest says (the command line prints it for a run that has nothing to show)
AT_REST = "at rest (q = 0, v = 0, zero delay history before t = 0)"


def initial_state(
    prob: ParametricProblem, kin: Any, q0: Any, v0: Any, history: Any
) -> tuple[np.ndarray, np.ndarray, Any, str]:
    """``(q0, v0, history for newmark, description)`` from :func:`simulate`'s
    arguments, each checked with an InputError naming it."""
    n = prob.n
    names = [prob.system.names[k] for k in prob.system.i]
    q0v, q0_txt = _initial_vector(prob, "q0", q0, "m")
    v0v, v0_txt = _initial_vector(prob, "v0", v0, "m/s")
    T = float(kin.delay)
    hist: Any = None
    if history is None or (isinstance(history, str) and history == "zero"):
        h_txt = "zero"
    elif isinstance(history, str):
        if history != "constant":
            raise InputError(
                f"history must be None, 'zero', 'constant', a vector, a callable or a table (t, q) (got {history!r})"
            )
        hist, h_txt = q0v.copy(), "constant (q0 held)"
    elif callable(history):
        hist, h_txt = (
            _history_callable(history, n),
            f"the callable {getattr(history, '__name__', 'history')}(t)",
        )
    elif isinstance(history, tuple):
        hist, h_txt = _history_table(history, n, T)
    else:
        hist = _vector("history", history, n)
        h_txt = "constant " + _fmt(hist, names, "m")
    if prob.delay() is None and hist is not None:
        h_txt += f" (not read: feedback {prob.terms!r} has no delayed term)"
    if q0_txt == v0_txt == "0" and h_txt == "zero":
        return q0v, v0v, hist, AT_REST
    return q0v, v0v, hist, f"q0 = {q0_txt}, v0 = {v0_txt}, delay history before t = 0: {h_txt}"


def _initial_vector(prob: ParametricProblem, name: str, value: Any, unit: str) -> tuple[np.ndarray, str]:
    """q0 or v0 as a vector over the independent coordinates, and its description."""
    n = prob.n
    if value is None:
        return np.zeros(n), "0"
    if not isinstance(value, Mapping):
        vec = _vector(name, value, n)
        names = [prob.system.names[k] for k in prob.system.i]
        return vec, ("0" if not vec.any() else _fmt(vec, names, unit))
    if not value:
        raise InputError(f"{name}: the mapping names no output")
    keys = list(value)
    vals = np.empty(len(keys))
    for j, key in enumerate(keys):
        try:
            vals[j] = float(value[key])
        except (TypeError, ValueError):
            raise InputError(f"{name}[{key!r}] must be a number (got {value[key]!r})") from None
        if not math.isfinite(vals[j]):
            raise InputError(f"{name}[{key!r}] must be finite (got {vals[j]})")
    rows = np.array([_output_map(prob.system, str(k)) for k in keys])  # unknown names refused here
    R = prob.maps(np.array([0.0]), rows)[0]  # (k, n_i) at t = 0
    A, _, C, _ = prob.matrices(np.array([0.0]))
    M = (C if name == "q0" else A)[0]
    # min x^T M x subject to R x = vals: [[M, R^T], [R, 0]] [x; lam] = [0; vals]
    k = len(keys)
    K = np.block([[M, R.T], [R, np.zeros((k, k))]])
    try:
        sol = np.linalg.solve(K, np.concatenate([np.zeros(n), vals]))
    except np.linalg.LinAlgError:
        sol = np.full(n + k, np.nan)
    x = sol[:n]
    scale = max(float(np.abs(vals).max()), 1e-300)
    if not np.all(np.isfinite(x)) or np.abs(R @ x - vals).max() > 1e-9 * scale:
        what = "stiffness" if name == "q0" else "mass matrix"
        raise InputError(
            f"{name}: {', '.join(keys)} cannot be set together (dependent outputs, or a {what} "
            f"singular on them); give {name} as a vector over the {n} independent coordinates"
        )
    u = "rad" + unit[1:]
    txt = ", ".join(
        f"{key} = {v:.6g} {u if key.endswith('.rz') else unit}" for key, v in zip(keys, vals, strict=True)
    )
    how = "the static shape under forces there" if name == "q0" else "the state after impulses there"
    return x, f"{txt} ({how})"


def _fmt(vec: np.ndarray, names: list[str], unit: str) -> str:
    body = ", ".join(f"{nm} {v:.6g}" for nm, v in zip(names, vec, strict=True) if v != 0.0)
    return f"[{body}] ({unit}, {'rad' + unit[1:]})" if len(names) > 1 else f"{names[0]} {vec[0]:.6g} {unit}"


def _vector(name: str, value: Any, n: int) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(
            f"{name} must be a vector of {n} numbers or a mapping {{'POINT.DIR': value}}"
        ) from None
    if arr.ndim == 0 and n == 1:
        arr = arr.reshape(1)
    if arr.shape != (n,):
        raise InputError(
            f"{name} must have shape ({n},), one value per independent coordinate (got {arr.shape})"
        )
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} contains NaN or infinite values")
    return arr.copy()


def _history_callable(history: Callable[..., Any], n: int) -> Callable[[np.ndarray], np.ndarray]:
    """The callable history, a (len(t),) result accepted for one coordinate
    (its shape and values are checked by the integrator, naming history)."""

    def f(t: np.ndarray) -> np.ndarray:
        out = np.asarray(history(t), dtype=float)
        return out.reshape(-1, 1) if (n == 1 and out.shape == (np.size(t),)) else out

    return f


def _history_table(history: tuple[Any, ...], n: int, T: float) -> tuple[tuple[np.ndarray, np.ndarray], str]:
    """A table (t_k, q_k) checked: shapes, finite, increasing, covering [-T, 0]."""
    if len(history) != 2:
        raise InputError(f"history=(t, q) must be a pair (got a tuple of {len(history)})")
    try:
        th = np.asarray(history[0], dtype=float)
        qh = np.asarray(history[1], dtype=float)
    except (TypeError, ValueError):
        raise InputError("history=(t, q) must hold numbers") from None
    if th.ndim != 1 or th.size < 2:
        raise InputError(f"history=(t, q): t must be 1-D with >= 2 times (got shape {th.shape})")
    if n == 1 and qh.shape == th.shape:
        qh = qh.reshape(-1, 1)
    if qh.shape != (th.size, n):
        raise InputError(
            f"history=(t, q): q must have shape (len(t), n_i) = ({th.size}, {n}) (got {qh.shape})"
        )
    if not (np.all(np.isfinite(th)) and np.all(np.isfinite(qh))):
        raise InputError("history=(t, q) contains NaN or infinite values")
    if np.any(np.diff(th) <= 0):
        raise InputError("history=(t, q): the times t must be strictly increasing")
    tol = 1e-12 * max(1.0, T)
    if th[0] > -T + tol or th[-1] < -tol:
        raise InputError(
            f"history=(t, q) covers [{th[0]:.6g}, {th[-1]:.6g}] s but must cover [-T, 0] = [{-T:.6g}, 0] s"
        )
    kind = "not-a-knot cubic spline" if th.size >= 4 else "linear interpolation"
    return (th, qh), f"a table of {th.size} nodes on [{th[0]:.6g}, {th[-1]:.6g}] s ({kind})"
