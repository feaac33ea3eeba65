"""The chatterlab exception family.

Every error chatterlab raises on purpose derives from :class:`ChatterlabError`
and from the built-in exception a caller would expect (``ValueError`` for bad
input), so ``except ValueError`` keeps working.  Errors are raised at the
boundary where input enters and say what to do about it.

Numerical outcomes (a diverging simulation, a root search that did not
converge) are *not* exceptions: they are reported as a ``status`` and
``message`` on the result object.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "ChatterlabError",
    "ModelError",
    "InputError",
    "SweepError",
    "UnitWarning",
    "check_count",
    "check_delay",
    "check_finite",
    "check_nonneg",
    "check_position",
    "check_positive",
    "check_speed",
    "check_width",
    "warn_width",
]


class ChatterlabError(Exception):
    """Base class of every exception raised on purpose by chatterlab."""


class ModelError(ChatterlabError, ValueError):
    """A model file or model description is invalid.

    The message names the file, the item (``[[beam]] "bed"``), the field and
    the fix, e.g.::

        model.toml, [[beam]] "bed-1": I must be > 0 (got -0.0004 m^4)
    """

    def __init__(
        self,
        message: str,
        *,
        source: str | None = None,
        item: str | None = None,
        field: str | None = None,
    ) -> None:
        self.source = source
        self.item = item
        self.field = field
        self.detail = message
        prefix = ", ".join(p for p in (source, item) if p)
        super().__init__(f"{prefix}: {message}" if prefix else message)


class InputError(ChatterlabError, ValueError):
    """An argument to an analysis is invalid (a non-positive width, an empty
    frequency range, an unknown point name...).  The message names the
    argument and the accepted values."""


class SweepError(ChatterlabError, RuntimeError):
    """A sweep task failed; the message names the grid point.  Results of the
    tasks that finished are kept in the checkpoint."""


# ----------------------------------------------------------------------------- argument checks
#
# One set of checks for the quantities every entry point takes (the command
# line, the sweep tasks, the analysis functions): a width, a speed, a delay,
# a slide position, a duration.  Each returns the value as a float or raises
# InputError naming the argument, its unit and what was given.


def _show(value: object) -> str:
    import numbers
    import operator

    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        n = operator.index(value)
        return f"an integer of {len(str(abs(n)))} digits" if abs(n) >= 2**1023 else f"{float(n):g}"
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return f"{float(value):g}"
    return repr(value)


def _as_float(value: object, name: str, unit: str) -> float:
    import math
    import numbers

    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{name} must be a number{' in ' + unit if unit else ''} (got {_show(value)})")
    try:
        x = float(value)
    except (OverflowError, ValueError):
        raise InputError(
            f"{name} must be a finite number{' in ' + unit if unit else ''} (got {_show(value)})"
        ) from None
    if not math.isfinite(x):
        raise InputError(
            f"{name} must be a finite number{' in ' + unit if unit else ''} (got {_show(value)})"
        )
    return x


def check_finite(value: object, name: str, unit: str = "") -> float:
    """``value`` as a finite float, else :class:`InputError` naming ``name``."""
    return _as_float(value, name, unit)


def check_positive(value: object, name: str, unit: str = "") -> float:
    """``value`` as a finite float > 0, else :class:`InputError` naming ``name``::

    width must be > 0 m (got -0.001)
    """
    import math
    import numbers

    u = f" {unit}" if unit else ""
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        try:
            x = float(value)
        except OverflowError:
            x = math.inf
        if not math.isfinite(x):
            raise InputError(f"{name} must be > 0{u} and finite (got {_show(value)})")
    x = _as_float(value, name, unit)
    if not x > 0:
        raise InputError(f"{name} must be > 0{u} (got {_show(value)})")
    return x


def check_nonneg(value: object, name: str, unit: str = "") -> float:
    """``value`` as a finite float >= 0, else :class:`InputError`."""
    x = _as_float(value, name, unit)
    if not x >= 0:
        raise InputError(f"{name} must be >= 0{' ' + unit if unit else ''} (got {_show(value)})")
    return x


class UnitWarning(UserWarning):
    """A value in the Python API that machines do not have, most likely typed
    in another unit (a width in mm where m is wanted).  The command line says
    the same in its own warnings, so it silences these."""


#: a width of cut (m) above this is a warning in the Python API: 100 mm
WIDTH_WARN_ABOVE = 0.1


def check_width(value: object, name: str = "width", unit: str = "m") -> float:
    """A width of cut (or a largest width): finite and > 0."""
    return check_positive(value, name, unit)


def warn_width(width: float, width_refs: Any) -> None:
    """A :class:`UnitWarning` for a width of cut (m) above 0.1 m and 20 times
    the model's largest reference width: 2 (mm) passed as 2 m gives a
    confident verdict on a cut 1000 times too wide.  A model whose widths are
    gains (``width_ref = 1``) is not warned at 1."""
    refs = [float(r) for r in width_refs] or [0.0]
    if width > WIDTH_WARN_ABOVE and width > 20.0 * max(refs):
        import warnings

        warnings.warn(
            UnitWarning(
                f"width = {width:g} m is above {WIDTH_WARN_ABOVE:g} m and {width / max(refs):.0f} times the"
                f" model's width_ref: widths are in m (did you mean {width * 1e-3:g}?)"
                if max(refs) > 0
                else f"width = {width:g} m is above {WIDTH_WARN_ABOVE:g} m: widths are in m"
            ),
            stacklevel=3,
        )


def check_speed(value: object, name: str = "speed", unit: str = "") -> float:
    """A cutting speed in the process's unit (m/s, rpm; s for a delay process): finite and > 0."""
    return check_positive(value, name, unit)


#: the longest delay between passes, s (11.6 days): anything longer comes from a speed
#: that is no cut (1e-300 m/s) and would size arrays by it
MAX_DELAY = 1e6


def check_delay(value: object, name: str = "delay", unit: str = "s") -> float:
    """A delay between passes, s: finite, > 0 and at most :data:`MAX_DELAY`."""
    x = check_positive(value, name, unit)
    if x > MAX_DELAY:
        raise InputError(
            f"{name} must be at most {MAX_DELAY:g} s (got {_show(value)} s); a delay this long is no cut"
        )
    return x


def check_position(
    value: object, name: str = "position", unit: str = "m", within: tuple[float, float] | None = None
) -> float:
    """A slide position, m: finite, and inside ``within`` (the model's movable
    range, to 1e-9 relative) when given."""
    x = check_finite(value, name, unit)
    if within is not None:
        lo, hi = within
        tol = 1e-9 * max(1.0, abs(lo), abs(hi))
        if not lo - tol <= x <= hi + tol:
            raise InputError(
                f"{name} {_show(value)} {unit} is outside the movable range [{lo:g}, {hi:g}] {unit};"
                " choose a position inside it or widen [movable] range"
            )
    return x


def check_count(value: object, name: str, minimum: int = 1) -> int:
    """An integer count >= ``minimum`` (a float such as ``3.0`` is accepted, NaN is not)."""
    import math
    import numbers

    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InputError(f"{name} must be a whole number >= {minimum} (got {_show(value)})")
    if isinstance(value, numbers.Integral):
        n = int(value)
    else:
        x = float(value)
        if not math.isfinite(x) or x != int(x):
            raise InputError(f"{name} must be a whole number >= {minimum} (got {_show(value)})")
        n = int(x)
    if n < minimum:
        raise InputError(f"{name} must be >= {minimum} (got {_show(value)})")
    return n


def check_axis_values(name: str, values: object, unit: str = "") -> None:
    """Check the values of a built-in sweep/grid axis (``width``, ``speed``,
    ``delay``, ``position``) with the same check as a single value."""
    import numpy as np

    checks = {"width": check_width, "speed": check_speed, "delay": check_delay, "position": check_position}
    check = checks.get(name)
    if check is None:
        return
    for v in np.atleast_1d(np.asarray(values, dtype=float)).tolist():
        check(v, f"grid axis {name}", unit)
