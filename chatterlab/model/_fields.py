"""Typed access to the tables of a model file: fields checked and named in
every message, ids checked for uniqueness."""

from __future__ import annotations

import builtins
import difflib
import math
from collections.abc import Iterable
from typing import Any

from ..errors import ModelError
from ._items import GROUND

#: the list tables of a model file ([[KIND]] items): the item kinds of messages and of
#: parameter paths KIND.ID.FIELD
LIST_TABLES = (
    "body",
    "node",
    "beam",
    "point",
    "spring",
    "attachment",
    "support",
    "contact",
    "constraint",
    "coupling",
    "mode",
    "absorber",
    "actuator",
)
#: the single tables of a model file
TABLES = ("model", "movable", "process", "matrices", "frf", "variant", "machine", "process_damping", "ssv")
#: the single tables whose fields a parameter path TABLE.FIELD addresses (--set, variants,
#: sweeps, [uncertainty], sensitivities)
PARAMETER_TABLES = ("movable", "process", "model", "frf", "machine", "process_damping", "ssv")

#: the magnitudes a physical field of a model file may have, by unit: a
#: nonzero value outside is refused, naming the field, before it reaches the
#: matrices (1e300 overflows the eigen-solver; 1e-300 is a part held by
#: nothing, reported as rigid-body modes).  The ranges reach about six
#: decades beyond any machine on both sides (a shear modulus G = 1e8 E
#: suppresses shear deformation); zero keeps its own meaning where allowed.
PLAUSIBLE: dict[str, tuple[float, float, str]] = {
    "N/m": (1e-3, 1e16, "a stiffness"),
    "N m/rad": (1e-3, 1e16, "a rotational stiffness"),
    "N s/m": (1e-9, 1e16, "a damping"),
    "N m s/rad": (1e-9, 1e16, "a rotational damping"),
    "Pa": (1e2, 1e24, "a modulus"),
    "N/m^2": (1e-3, 1e18, "a cutting stiffness"),
    "N s/m^2": (1e-9, 1e20, "a damping coefficient"),
    "kg": (1e-9, 1e9, "a mass"),
    "kg m^2": (1e-18, 1e9, "a rotary inertia"),
    "kg/m^3": (1e-9, 1e6, "a density"),
    "m^2": (1e-16, 1e4, "a cross-section area"),
    "m^4": (1e-30, 1e8, "a second moment of area"),
}


def plausible(v: float, unit: str) -> str | None:
    """Why the value ``v`` of a field in ``unit`` is implausible (None: it is not)."""
    rng = PLAUSIBLE.get(unit)
    if rng is None or v == 0 or rng[0] <= abs(v) <= rng[1]:
        return None
    lo, hi, what = rng
    return (
        f"{v:g} {unit} is outside the plausible range of {what}, {lo:g}..{hi:g} {unit}:"
        f" correct the value (a model file is in SI units: {unit})"
    )


class _Item:
    """Typed access to one table of the file, with messages that name it."""

    def __init__(self, src: str, label: str, table: Any, allowed: Iterable[str]):
        self.src = src
        self.label = label
        if not isinstance(table, dict):
            raise ModelError(f"must be a table, got {type(table).__name__}", source=src, item=label)
        self.t = table
        allowed = set(allowed)
        for key in table:
            if key not in allowed:
                close = difflib.get_close_matches(key, sorted(allowed), n=1)
                hint = f" Did you mean '{close[0]}'?" if close else ""
                raise ModelError(
                    f"unknown field '{key}'.{hint} Allowed: {', '.join(sorted(allowed))}",
                    source=src,
                    item=label,
                    field=key,
                )

    def err(self, field: str | None, msg: str) -> ModelError:
        return ModelError(f"{field}: {msg}" if field else msg, source=self.src, item=self.label, field=field)

    def has(self, key: str) -> bool:
        return key in self.t

    def raw(self, key: str, default: Any = ...) -> Any:
        if key not in self.t:
            if default is ...:
                raise self.err(key, "missing field; it is required (see docs/model-format.md)")
            return default
        return self.t[key]

    def str(self, key: str, default: Any = ...) -> str:
        v = self.raw(key, default)
        if v is default and default is not ...:
            return v
        if not isinstance(v, str) or not v:
            raise self.err(key, f"must be a non-empty string, got {v!r}")
        return v

    def num(
        self,
        key: builtins.str,
        default: Any = ...,
        *,
        unit: builtins.str = "",
        positive: bool = False,
        nonneg: bool = False,
    ) -> float:
        v = self.raw(key, default)
        if v is default and default is not ...:
            return v
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise self.err(key, f"must be a number{f' in {unit}' if unit else ''}, got {v!r}")
        v = float(v)
        if not math.isfinite(v):
            raise self.err(key, f"must be finite, got {v}")
        u = f" {unit}" if unit else ""
        if positive and v <= 0:
            raise self.err(key, f"must be > 0 (got {v:g}{u})")
        if nonneg and v < 0:
            raise self.err(key, f"must be >= 0 (got {v:g}{u})")
        why = plausible(v, unit)
        if why is not None:
            raise self.err(key, why)
        return v

    def vec(
        self, key: builtins.str, n: int, default: Any = ..., *, unit: builtins.str = ""
    ) -> tuple[float, ...]:
        v = self.raw(key, default)
        if v is default and default is not ...:
            return v
        if not isinstance(v, list) or len(v) != n:
            raise self.err(key, f"must be a list of {n} numbers{f' in {unit}' if unit else ''}, got {v!r}")
        out = []
        for x in v:
            if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
                raise self.err(key, f"must hold finite numbers, got {v!r}")
            out.append(float(x))
        return tuple(out)

    def matrix3(self, key: builtins.str) -> tuple[tuple[float, ...], ...]:
        v = self.raw(key, [[0.0] * 3] * 3)
        ok = (
            isinstance(v, list)
            and len(v) == 3
            and all(isinstance(r, list) and len(r) == 3 for r in v)
            and all(
                isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
                for r in v
                for x in r
            )
        )
        if not ok:
            raise self.err(key, f"must be a 3x3 matrix (a list of 3 rows of 3 numbers), got {v!r}")
        return tuple(tuple(float(x) for x in r) for r in v)


def _id_of(src: str, kind: str, k: int, table: Any, required: bool = True) -> str:
    if isinstance(table, dict) and "id" in table:
        v = table["id"]
        if not isinstance(v, str) or not v.strip():
            raise ModelError(
                f"id must be a non-empty string, got {v!r}", source=src, item=f"[[{kind}]] #{k + 1}"
            )
        return v
    if required:
        raise ModelError(
            "missing field 'id': every item needs a unique string id",
            source=src,
            item=f"[[{kind}]] #{k + 1}",
            field="id",
        )
    return f"{kind}-{k + 1}"


class _Ids:
    """The ids used so far: unique across all item kinds, never the ground's."""

    def __init__(self, src: str) -> None:
        self.src = src
        self.seen: dict[str, str] = {}

    def register(self, kind: str, iid: str) -> None:
        if iid == GROUND:
            raise ModelError(
                f"'{GROUND}' is reserved for the foundation; choose another id",
                source=self.src,
                item=f'[[{kind}]] "{iid}"',
            )
        if iid in self.seen:
            raise ModelError(
                f"duplicate id '{iid}' (already used by a [[{self.seen[iid]}]]); ids must be unique",
                source=self.src,
                item=f'[[{kind}]] "{iid}"',
                field="id",
            )
        self.seen[iid] = kind
