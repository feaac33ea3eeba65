"""Argument checks shared by the root search and the argument principle.

One function per kind of argument, so that a mistake gets the same one-line
:class:`~chatterlab.errors.InputError` (naming the argument and what it must
be) from every entry point.  The matrices themselves are checked where the
:class:`~chatterlab.frequency.DelaySystem` is built
(:func:`~chatterlab.frequency.make_system`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from chatterlab.errors import InputError

__all__ = ["check_count", "check_omega_max", "check_integer"]


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
