"""Named grids of parameters: :class:`Axis` and :class:`Grid` (C order, flat task index)."""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from chatterlab.errors import InputError

#: the largest number of points of a sweep (and of one axis): a task costs milliseconds to
#: seconds, so 1e7 of them are hours to weeks of work, and the results 80 MB per output in
#: memory; a larger grid is refused before the work (a 400-digit count was an internal error)
MAX_TASKS = 10_000_000

# =========================================================================== grid


@dataclass(frozen=True, init=False, eq=False)
class Axis:
    """One named axis of a :class:`Grid`.

    Parameters
    ----------
    name : str
        A Python identifier (it is passed as a keyword argument to the swept
        function and becomes a netCDF coordinate name).
    values : array_like
        The 1-D, finite, non-empty coordinate values; stored as a read-only
        float64 copy.  A scalar gives a one-point axis.
    unit : str, optional
        The unit, e.g. ``"m"`` or ``"N/m"`` (``""`` if dimensionless).
    """

    name: str
    values: np.ndarray
    unit: str

    def __init__(self, name: str, values: ArrayLike, unit: str = "") -> None:
        if not isinstance(name, str) or not (name.isidentifier() and name.isascii()):
            raise InputError(
                f"axis name {name!r} must be an ASCII identifier (letters, digits, "
                "underscores; not starting with a digit)"
            )
        if not isinstance(unit, str):
            raise InputError(f"axis {name!r}: unit must be a string (got {unit!r})")
        try:
            arr = np.array(values, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InputError(f"axis {name!r}: values must be numbers ({exc})") from None
        if arr.ndim == 0:
            arr = arr.reshape(1)
        if arr.ndim != 1 or arr.size == 0:
            raise InputError(f"axis {name!r}: values must be a non-empty 1-D array (got shape {arr.shape})")
        if not np.all(np.isfinite(arr)):
            raise InputError(f"axis {name!r}: values must be finite (got {arr[~np.isfinite(arr)][0]})")
        arr.flags.writeable = False
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "values", arr)
        object.__setattr__(self, "unit", unit)

    def __len__(self) -> int:
        return int(self.values.size)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Axis):
            return NotImplemented
        return (
            self.name == other.name
            and self.unit == other.unit
            and self.values.tobytes() == other.values.tobytes()
        )

    def __hash__(self) -> int:
        return hash((self.name, self.unit, self.values.tobytes()))

    def __repr__(self) -> str:
        v = self.values
        span = f"{v[0]:g}" if v.size == 1 else f"{v[0]:g}..{v[-1]:g}"
        return f"Axis({self.name!r}, {v.size} values {span}, unit={self.unit!r})"


@dataclass(frozen=True, init=False, eq=False)
class Grid:
    """An ordered set of named axes; its points are enumerated in C order.

    Parameters
    ----------
    axes : mapping or iterable of Axis
        Either ``{"width": (values, "m"), "speed": (values, "m/s")}`` (a bare
        array means a dimensionless axis) or ``[Axis("width", values, "m"),
        ...]``.  At least one axis; names must be unique.

    Examples
    --------
    >>> g = Grid({"width": ([1e-3, 2e-3], "m"), "speed": ([1.0, 2.0, 3.0], "m/s")})
    >>> g.shape, g.size
    ((2, 3), 6)
    >>> g.point(4)
    {'width': 0.002, 'speed': 2.0}
    >>> Grid.from_spec("k=1e6:1e7:10", "c=5").shape
    (10, 1)
    """

    axes: tuple[Axis, ...]

    def __init__(self, axes: Mapping[str, Any] | Iterable[Axis]) -> None:
        items: list[Axis] = []
        if isinstance(axes, Mapping):
            for name, spec in axes.items():
                if isinstance(spec, Axis):
                    if spec.name != name:
                        raise InputError(f"axis {spec.name!r} given under the key {name!r}")
                    items.append(spec)
                elif isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[1], str):
                    items.append(Axis(name, spec[0], spec[1]))
                else:
                    items.append(Axis(name, spec))
        else:
            for ax in axes:
                if not isinstance(ax, Axis):
                    raise InputError(
                        f"Grid expects a mapping name -> (values, unit) or Axis objects, "
                        f"got {type(ax).__name__}"
                    )
                items.append(ax)
        if not items:
            raise InputError("a grid needs at least one axis")
        seen: set[str] = set()
        for ax in items:
            if ax.name in seen:
                raise InputError(f"duplicate axis name {ax.name!r} in the grid")
            seen.add(ax.name)
        object.__setattr__(self, "axes", tuple(items))

    # ------------------------------------------------------------- construction

    @classmethod
    def from_spec(cls, *specs: str, units: Mapping[str, str] | None = None) -> Grid:
        """Build a grid from ``NAME=MIN:MAX:N`` specifications.

        Parameters
        ----------
        *specs : str
            One axis each, or several separated by spaces, commas or
            semicolons.  Forms: ``NAME=MIN:MAX:N`` (``N`` linearly spaced
            values, ``MIN < MAX`` when ``N > 1``), ``NAME=VALUE`` (one point).
            A unit may follow the name in brackets: ``k[N/m]=1e6:1e7:10``.
        units : mapping, optional
            Units by axis name (for axes whose spec has no ``[unit]``).

        Returns
        -------
        Grid

        Raises
        ------
        chatterlab.errors.InputError
            Naming the offending spec: bad syntax, a non-number, a non-finite
            bound, ``N < 1`` or not an integer, an empty or reversed range, a
            duplicate name.
        """
        units = dict(units or {})
        tokens = [t for s in specs for t in re.split(r"[\s,;]+", str(s).strip()) if t]
        if not tokens:
            raise InputError("empty grid specification: expected NAME=MIN:MAX:N, e.g. k=1e6:1e7:10")
        axes: list[Axis] = []
        seen: set[str] = set()
        for tok in tokens:
            ax = _parse_axis_spec(tok, units)
            if ax.name in seen:
                raise InputError(f"grid spec {shown_spec(tok)!r}: axis {ax.name!r} is given twice")
            seen.add(ax.name)
            axes.append(ax)
        unknown = set(units) - seen
        if unknown:
            raise InputError(f"units given for unknown axes {sorted(unknown)}; axes are {sorted(seen)}")
        return cls(axes)

    @classmethod
    def from_json(cls, obj: Mapping[str, Any]) -> Grid:
        """Inverse of :meth:`to_json`."""
        try:
            return cls([Axis(a["name"], a["values"], a.get("unit", "")) for a in obj["axes"]])
        except (KeyError, TypeError) as exc:
            raise InputError(f"not a grid description: {exc}") from None

    def to_json(self) -> dict[str, Any]:
        """A JSON-serialisable description (floats round-trip exactly)."""
        return {"axes": [{"name": a.name, "unit": a.unit, "values": a.values.tolist()} for a in self.axes]}

    # ------------------------------------------------------------- shape & points

    @property
    def names(self) -> tuple[str, ...]:
        """Axis names, in order."""
        return tuple(a.name for a in self.axes)

    @property
    def units(self) -> dict[str, str]:
        """Axis units by name."""
        return {a.name: a.unit for a in self.axes}

    @property
    def shape(self) -> tuple[int, ...]:
        """Number of values along each axis."""
        return tuple(len(a) for a in self.axes)

    @property
    def size(self) -> int:
        """Number of grid points (tasks)."""
        return math.prod(self.shape)

    @property
    def ndim(self) -> int:
        """Number of axes."""
        return len(self.axes)

    @property
    def coords(self) -> dict[str, tuple[np.ndarray, str]]:
        """``name -> (values, unit)``, as :func:`chatterlab.io._netcdf.write_netcdf` takes."""
        return {a.name: (a.values, a.unit) for a in self.axes}

    def __getitem__(self, name: str) -> Axis:
        for a in self.axes:
            if a.name == name:
                return a
        raise KeyError(f"no axis {name!r}; axes are {list(self.names)}")

    def unravel(self, index: int) -> tuple[int, ...]:
        """Per-axis indices of flat task index ``index`` (C order)."""
        if not 0 <= int(index) < self.size:
            raise IndexError(f"task index {index} out of range for a grid of {self.size} points")
        return tuple(int(i) for i in np.unravel_index(int(index), self.shape))

    def point(self, index: int) -> dict[str, float]:
        """The grid point of flat task index ``index``: ``{name: value}``."""
        sub = self.unravel(index)
        return {a.name: float(a.values[i]) for a, i in zip(self.axes, sub, strict=True)}

    def format_point(self, point: Mapping[str, float]) -> str:
        """``"width=0.003 m, speed=2 m/s"`` for messages."""
        units = self.units
        return ", ".join(f"{k}={v:.10g}" + (f" {units[k]}" if units.get(k) else "") for k, v in point.items())

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Grid):
            return NotImplemented
        return self.axes == other.axes

    def __hash__(self) -> int:
        return hash(self.axes)

    def __repr__(self) -> str:
        dims = " x ".join(f"{a.name}[{len(a)}]" for a in self.axes)
        return f"Grid({dims} = {self.size} points)"


_NUM = r"[^:=\[\]]+"
_SPEC_RE = re.compile(r"^(?P<name>[^=\[\]]+)(?:\[(?P<unit>[^\]]*)\])?=(?P<rhs>.*)$")


def shown_spec(tok: str) -> str:
    """A grid spec as messages show it (a 5000-digit one shortened)."""
    return tok if len(tok) <= 60 else f"{tok[:48]}... ({len(tok)} characters)"


def _parse_axis_spec(tok: str, units: Mapping[str, str]) -> Axis:
    shown = shown_spec(tok)
    hint = "expected NAME=MIN:MAX:N (e.g. k=1e6:1e7:10) or NAME=VALUE"
    m = _SPEC_RE.match(tok)
    if not m:
        raise InputError(f"grid spec {shown!r}: {hint}")
    name = m["name"].strip()
    if not (name.isidentifier() and name.isascii()):
        raise InputError(f"grid spec {shown!r}: {name!r} is not a valid axis name (an identifier)")
    unit = m["unit"] if m["unit"] is not None else units.get(name, "")
    parts = m["rhs"].split(":")
    if len(parts) not in (1, 3):
        raise InputError(f"grid spec {shown!r}: {hint}")

    def number(text: str, what: str) -> float:
        try:
            x = float(text)
        except ValueError:
            raise InputError(f"grid spec {shown!r}: {what} {text!r} is not a number; {hint}") from None
        if not math.isfinite(x):
            raise InputError(f"grid spec {shown!r}: {what} must be finite (got {text!r})")
        return x

    if len(parts) == 1:
        return Axis(name, np.array([number(parts[0], "VALUE")]), unit)
    lo, hi = number(parts[0], "MIN"), number(parts[1], "MAX")
    if not re.fullmatch(r"\s*[+]?\d+\s*", parts[2]):
        raise InputError(f"grid spec {shown!r}: N {parts[2]!r} must be a whole number of points >= 1; {hint}")
    digits = parts[2].strip().lstrip("+").lstrip("0") or "0"
    if len(digits) > len(str(MAX_TASKS)) or int(digits) > MAX_TASKS:
        count = digits if len(digits) <= 12 else f"a {len(digits)}-digit number"
        raise InputError(
            f"grid spec {shown!r}: N = {count} points is more than the largest accepted, {MAX_TASKS} points"
            " (a sweep's tasks cost milliseconds to seconds each)"
        )
    n = int(digits)
    if n < 1:
        raise InputError(f"grid spec {shown!r}: N must be >= 1 (got {n}): the axis would be empty")
    if n > 1 and lo >= hi:
        what = "empty" if lo == hi else "reversed"
        raise InputError(f"grid spec {shown!r}: {what} range: MIN ({lo:g}) must be < MAX ({hi:g}) when N > 1")
    if n == 1 and lo != hi:
        raise InputError(
            f"grid spec {shown!r}: N=1 with MIN != MAX is ambiguous; write {name}={lo:g} for a single point"
        )
    return Axis(name, np.linspace(lo, hi, n), unit)
