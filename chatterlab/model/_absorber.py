"""[[absorber]]: a tuned vibration absorber (a mass on a spring and a
viscous damper) attached at a point of the structure, acting along one
direction.

The absorber is a point mass m guided rigidly across its direction and
free along it: it adds one coordinate ``ID.u`` (its displacement along the
unit direction e, m), the mass m on it, and a spring k and damper c between
it and the host point's motion along e,

    kinetic energy  m/2 (u'^2 + (e_perp . w'_P)^2),
    potential energy  k/2 (u - e . w_P)^2,   dissipation  c/2 (u' - e . w'_P)^2,

with w_P the host point's (x, y) displacement: across e the mass moves with
the host point (it loads it with m), along e it is tuned.  The assembly
(:mod:`chatterlab.structure._assembly`) adds these terms to M, L, K; the
absorber is then part of the structure for every analysis.

The tuning is written either as stiffness and damping (N/m, N s/m) or as
the absorber's own natural frequency f_a = sqrt(k/m) / 2 pi (Hz) and damping
ratio zeta_a = c / (2 sqrt(k m)), the way absorbers are specified
(Den Hartog, *Mechanical Vibrations*, 4th ed., Dover, 1985, sec. 3.3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ._fields import _id_of, _Ids, _Item
from ._items import PointRef

__all__ = ["Absorber", "read_absorbers"]


@dataclass(frozen=True)
class Absorber:
    """A tuned vibration absorber: mass (kg), stiffness (N/m) and damping
    (N s/m) acting at the point ``at`` along ``angle`` (rad from global X)."""

    id: str
    at: PointRef
    angle: float
    mass: float
    stiffness: float
    damping: float

    @property
    def omega(self) -> float:
        """Natural frequency of the absorber on a fixed base, sqrt(k/m), rad/s."""
        return math.sqrt(self.stiffness / self.mass)

    @property
    def frequency_hz(self) -> float:
        return self.omega / (2 * math.pi)

    @property
    def damping_ratio(self) -> float:
        """c / (2 sqrt(k m))."""
        return self.damping / (2 * math.sqrt(self.stiffness * self.mass))

    @property
    def direction(self) -> tuple[float, float]:
        """Unit direction e (global x, y)."""
        return (math.cos(self.angle), math.sin(self.angle))


_FIELDS = (
    "id",
    "at",
    "direction",
    "angle_deg",
    "mass",
    "stiffness",
    "frequency_hz",
    "damping",
    "damping_ratio",
    "description",
)


def read_absorbers(src: str, raw: dict[str, Any], ids: _Ids, ctx: Any) -> list[Absorber]:
    """[[absorber]]: mass, stiffness (or frequency_hz) and damping (or
    damping_ratio) at a point ``at``, along ``direction`` ("x" or "y") or
    ``angle_deg`` (from global X).  ``ctx`` resolves the point (the
    reader's :class:`~chatterlab.model._points._RefContext`)."""
    out: list[Absorber] = []
    for k, t in enumerate(raw.get("absorber", [])):
        iid = _id_of(src, "absorber", k, t)
        it = _Item(src, f'[[absorber]] "{iid}"', t, _FIELDS)
        ids.register("absorber", iid)
        at = ctx.ref(it, "at")
        if at.kind == "ground":
            raise it.err(
                "at", "an absorber on the ground does nothing; attach it to a point of the structure"
            )
        angle = _angle(it)
        m = it.num("mass", unit="kg", positive=True)
        if it.has("stiffness") == it.has("frequency_hz"):
            raise it.err(
                "stiffness",
                "give exactly one of stiffness (N/m) and frequency_hz (the absorber's natural frequency, Hz)",
            )
        if it.has("stiffness"):
            kk = it.num("stiffness", unit="N/m", positive=True)
        else:
            f = it.num("frequency_hz", unit="Hz", positive=True)
            kk = m * (2 * math.pi * f) ** 2
            _plausible(it, "frequency_hz", kk, "N/m")
        if it.has("damping") and it.has("damping_ratio"):
            raise it.err("damping", "give one of damping (N s/m) and damping_ratio, not both")
        if it.has("damping_ratio"):
            z = it.num("damping_ratio", nonneg=True)
            if z >= 10.0:
                raise it.err("damping_ratio", f"must be below 10 (got {z:g}); an absorber is lightly damped")
            c = 2 * z * math.sqrt(kk * m)
            _plausible(it, "damping_ratio", c, "N s/m")
        else:
            c = it.num("damping", 0.0, unit="N s/m", nonneg=True)
        out.append(Absorber(iid, at, angle, m, kk, c))
    return out


def _angle(it: _Item) -> float:
    if it.has("direction") == it.has("angle_deg"):
        raise it.err(
            "direction", 'give exactly one of direction ("x" or "y") and angle_deg (degrees from global X)'
        )
    if it.has("angle_deg"):
        return math.radians(it.num("angle_deg"))
    d = it.raw("direction")
    if d not in ("x", "y"):
        raise it.err("direction", f'must be "x" or "y" (or give angle_deg instead), got {d!r}')
    return 0.0 if d == "x" else math.pi / 2


def _plausible(it: _Item, key: str, value: float, unit: str) -> None:
    """The stiffness or damping a frequency or ratio gives, held to the
    same plausible range as one written directly."""
    from ._fields import plausible

    why = plausible(value, unit)
    if why is not None:
        raise it.err(key, f"gives {why}")
