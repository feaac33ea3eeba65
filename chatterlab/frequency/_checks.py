"""Argument checks shared by the root search and the argument principle.

One function per kind of argument, so that a mistake gets the same one-line
:class:`~chatterlab.errors.InputError` (naming the argument and what it must
be) from every entry point: the options of the searches, and the matrices
and delay from which :func:`~chatterlab.frequency.make_system` builds a
:class:`~chatterlab.frequency.DelaySystem`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from chatterlab.errors import InputError

__all__ = ["check_count", "check_omega_max", "check_integer", "as_real_matrix", "factor_delayed", "check_tau"]


def check_count(count: Any) -> int:
    """``count`` (roots wanted) as an int >= 1."""
    if isinstance(count, bool) or not isinstance(count, int | np.integer):
        raise InputError(f"count must be an integer >= 1 (got {count!r})")
    if count < 1:
        raise InputError(f"count must be >= 1 (got {count})")
    return int(count)


def check_omega_max(omega_max: Any) -> float | None:
    """``omega_max`` (rad/s) as a finite float > 0, or None."""
    if omega_max is None:
        return None
    try:
        om = float(omega_max)
    except (TypeError, ValueError) as exc:
        raise InputError(f"omega_max must be a positive number in rad/s (got {omega_max!r})") from exc
    if not math.isfinite(om) or om <= 0:
        raise InputError(f"omega_max must be finite and > 0 rad/s (got {omega_max!r})")
    return om


def check_integer(value: Any, name: str, minimum: int) -> None:
    """``value`` is None or an integer >= ``minimum`` (``n_nodes``, ``n_points``)."""
    if value is not None and (
        isinstance(value, bool) or not isinstance(value, int | np.integer) or value < minimum
    ):
        raise InputError(f"{name} must be an integer >= {minimum} (got {value!r})")


def as_real_matrix(x: Any, name: str, n: int | None = None) -> NDArray[np.float64]:
    try:
        a = np.asarray(x)
    except Exception as exc:  # pragma: no cover - exotic inputs
        raise InputError(f"{name} must be a real matrix ({exc})") from exc
    if a.dtype.kind == "c":
        raise InputError(f"{name} must be real (got complex entries)")
    if a.dtype.kind not in "biuf":
        raise InputError(f"{name} must be a real numeric matrix (got dtype {a.dtype})")
    a = np.atleast_2d(a.astype(float))
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise InputError(f"{name} must be a square matrix (got shape {np.shape(x)})")
    if n is not None and a.shape[0] != n:
        raise InputError(f"{name} must have shape ({n}, {n}) like M (got {a.shape})")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name} has non-finite entries (NaN or inf)")
    return a


def factor_delayed(DO: Any, n: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return ``(U, V)`` with ``DO = U V^T`` (r may be 0)."""
    if DO is None:
        return np.zeros((n, 0)), np.zeros((n, 0))
    if isinstance(DO, tuple | list) and len(DO) == 2:
        U = np.asarray(DO[0])
        V = np.asarray(DO[1])
        for nm, a in (("DO[0] (U)", U), ("DO[1] (V)", V)):
            if a.dtype.kind == "c":
                raise InputError(f"{nm} must be real (got complex entries)")
            if a.dtype.kind not in "biuf":
                raise InputError(f"{nm} must be numeric (got dtype {a.dtype})")
        U = U.astype(float)
        V = V.astype(float)
        if U.ndim == 1:
            U = U[:, None]
        if V.ndim == 1:
            V = V[:, None]
        if U.ndim != 2 or V.ndim != 2 or U.shape != V.shape or U.shape[0] != n:
            raise InputError(
                f"DO=(U, V) factors must both have shape (n, r) with n={n} (got U {U.shape}, V {V.shape})"
            )
        if not (np.all(np.isfinite(U)) and np.all(np.isfinite(V))):
            raise InputError("DO=(U, V) factors have non-finite entries")
        if U.shape[1] > 0 and (np.abs(U).max() == 0.0 or np.abs(V).max() == 0.0):
            return np.zeros((n, 0)), np.zeros((n, 0))
        return U, V
    D = as_real_matrix(DO, "DO", n)
    if not np.any(D):
        return np.zeros((n, 0)), np.zeros((n, 0))
    W, s, Zt = np.linalg.svd(D)
    keep = s > 1e-12 * s[0]
    return W[:, keep] * s[keep], Zt[keep].T.copy()


def check_tau(tau: Any, needed: bool) -> float:
    if not needed:
        return 0.0
    if tau is None:
        raise InputError("tau must be given (> 0, in s) when a delayed term DO is present")
    try:
        t = float(tau)
    except (TypeError, ValueError) as exc:
        raise InputError(f"tau must be a positive number in s (got {tau!r})") from exc
    if not math.isfinite(t) or t <= 0.0:
        raise InputError(f"tau must be finite and > 0 s when DO is given (got {tau!r})")
    return t
