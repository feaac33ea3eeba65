"""Numbers with their units at the command line (issue 20, item 4).

A bare number keeps each option's documented unit (``--width 2`` is 2 mm,
``--speed 12000`` is in the model's process unit); a number may also carry
its unit where people write it -- ``--width 2mm``, ``--width 0.002m``,
``--kf 2000N/mm^2``, ``--speed 12000rpm``, ``--speed 30m/min``,
``--fmax 2kHz`` -- and is converted to the option's unit here, at the edge,
by pint (imported only when a unit is written: a bare number, and
``--help``, cost nothing).  A unit of the wrong kind (``--width 2kg``) is one
line naming the option, the value and what it takes.

A spindle speed in Hz is refused: pint (like SI) treats the radian as
dimensionless, so "200 Hz" would read as 200 rad/s, not 200 rev/s; write
``rev/s`` or ``rpm``.
"""

from __future__ import annotations

import argparse
import re
from functools import lru_cache
from typing import Any

from ..errors import InputError

__all__ = ["OPTION_UNITS", "quantity", "resolve_units", "resolve_speed", "speed_in"]

#: the unit of a bare number for each option that takes a quantity (dest -> unit)
OPTION_UNITS = {
    "width": "mm",
    "width_max": "mm",
    "delay": "s",
    "fmin": "Hz",
    "fmax": "Hz",
    "position": "m",
    "kf": "N/m^2",
    "kt": "N/m^2",
    "kn": "N/m^2",
    "force_angle": "deg",
    "normal_angle": "deg",
}

_NUMBER = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?\s*$")


@lru_cache(maxsize=1)
def _registry() -> Any:
    import pint

    ureg: Any = pint.UnitRegistry()
    ureg.define("rev = revolution")  # rev/s, rev/min as machinists write them
    return ureg


def _parse(text: str, option: str) -> Any:
    """A pint quantity from ``text`` (an InputError naming the option otherwise)."""
    ureg = _registry()
    try:
        q = ureg.Quantity(text.strip())
    except Exception as exc:  # pint raises several unrelated types for a bad expression
        raise InputError(
            f"{option} {text!r}: not a number with a unit ({type(exc).__name__}); write e.g. 2, 2mm or 0.002m"
        ) from None
    if not hasattr(q, "magnitude") or not isinstance(q.magnitude, int | float):
        raise InputError(f"{option} {text!r}: not a number with a unit")
    return q


def quantity(text: Any, option: str, unit: str) -> float:
    """``text`` in ``unit``: a bare number as it is, a number with a unit
    converted (pint), a unit of another kind refused in one line."""
    if not isinstance(text, str):
        return float(text)
    if _NUMBER.match(text):
        return float(text)
    q = _parse(text, option)
    ureg = _registry()
    target = ureg.Unit(unit.replace("^", "**"))
    if q.dimensionality != target.dimensionality:
        raise InputError(
            f"{option} {text!r}: a {_kind(q)} where {option} takes {unit} (or a bare number in {unit})"
        )
    return float(q.to(target).magnitude)


def speed_in(text: Any, unit: str, option: str = "--speed") -> float:
    """A speed in the process's ``unit`` (rpm, m/s or a delay in s)."""
    if not isinstance(text, str) or _NUMBER.match(text):
        return float(text)
    q = _parse(text, option)
    if unit == "rpm" and "hertz" in str(q.units):
        raise InputError(
            f"{option} {text!r}: a spindle speed in Hz is ambiguous (rev/s or rad/s?): write rev/s or rpm"
        )
    return quantity(text, option, "revolution/minute" if unit == "rpm" else unit)


def _kind(q: Any) -> str:
    d = str(q.dimensionality)
    return {"[length]": "length", "[mass]": "mass", "[time]": "time", "1 / [time]": "frequency or angular speed",
            "[length] / [time]": "speed", "dimensionless": "plain number"}.get(d, f"quantity of {d}")  # fmt: skip


def resolve_units(args: argparse.Namespace) -> None:
    """Every option of :data:`OPTION_UNITS` given as text, in its unit (in
    place, before the numbers are checked); ``--speed`` is converted when the
    model's process is known (:func:`speed_in`)."""
    for dest, unit in OPTION_UNITS.items():
        value = getattr(args, dest, None)
        option = "--" + dest.replace("_", "-")
        if isinstance(value, str):
            setattr(args, dest, quantity(value, option, unit))
        elif isinstance(value, list) and any(isinstance(v, str) for v in value):
            setattr(args, dest, [quantity(v, option, unit) for v in value])
    speed = getattr(args, "speed", None)  # bare numbers now; with a unit once the process is known
    if isinstance(speed, str) and _NUMBER.match(speed):
        args.speed = float(speed)
    elif isinstance(speed, list):
        args.speed = [float(v) if isinstance(v, str) and _NUMBER.match(v) else v for v in speed]


def resolve_speed(args: argparse.Namespace, unit: str) -> None:
    """``--speed`` (one value or MIN MAX) in the process's ``unit``, in place."""
    speed = getattr(args, "speed", None)
    if isinstance(speed, list):
        args.speed = [speed_in(v, unit) for v in speed]
    elif speed is not None:
        args.speed = speed_in(speed, unit)
