"""[[actuator]]: an active damper -- a sensor at one point, a force at
another (or the same: collocated), and the seed paper's feedback between
them with the actuator's own delay.

The sensor measures the displacement y = e_s . w_S of its point S along its
unit direction e_s; the actuator pushes at its point P along e_f with the
force

    f(s) = -(g_P + s g_V + g_O e^{-s T_a}) / (1 + s / w_b) y(s),              (1)

the feedback D_P + s D_V + D_O e^{-Ts} of the paper's Eq. 2.23 (Table 1:
proportional, ideal derivative and delayed transfer functions, each with its
own time constant) on the one measured coordinate, with the delay T_a of the
controller's delayed term and, optionally, a first-order actuator bandwidth
w_b = 2 pi f_b.  The sign makes positive gains resist the measured motion:
collocated (P = S, e_f = e_s), g_V > 0 is a viscous damper of g_V N s/m,
g_P > 0 a spring.  A ``reaction`` point takes the opposite force (an
actuator between two parts of the machine); without one the reaction goes
to an inertial mass or the ground outside the model.

The actuator is part of the machine's closed loop
(:class:`chatterlab.process.ClosedLoop`), a coupling term beside the cutting
process's; ``force_limit`` is the force it can deliver, a constraint of the
co-design (:func:`chatterlab.design.design_active`).

References
----------
.. [1] E. Wittbrodt, K. J. Kalinski, "Transient vibration of unsteady linear
   closed loop systems" (the seed paper), Table 1 and Eqs. 2.22-2.25.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ._fields import _id_of, _Ids, _Item
from ._items import PointRef

__all__ = ["Actuator", "read_actuators", "ACTUATOR_FIELDS"]


@dataclass(frozen=True)
class Actuator:
    """An active damper: sensor at ``sensor`` along ``sensor_angle``, force at
    ``at`` along ``angle`` (rad from global X; reaction at ``reaction`` or
    none), the gains of (1) (N/m, N s/m, N/m), the delay T_a (s) of the
    delayed term, the bandwidth f_b (Hz; inf: none) and the force limit (N;
    inf: none)."""

    id: str
    sensor: PointRef
    sensor_angle: float
    at: PointRef
    angle: float
    reaction: PointRef | None
    proportional_gain: float
    velocity_gain: float
    delayed_gain: float
    delay: float
    bandwidth_hz: float
    force_limit: float

    @property
    def collocated(self) -> bool:
        """The force acts where and along what the sensor measures."""
        return self.sensor == self.at and self.sensor_angle == self.angle and self.reaction is None

    @property
    def lag(self) -> float:
        """The time constant 1 / (2 pi f_b) of the bandwidth, s (0: none)."""
        return 0.0 if math.isinf(self.bandwidth_hz) else 1.0 / (2 * math.pi * self.bandwidth_hz)


#: the fields of an [[actuator]] table (docs/model-format.md)
ACTUATOR_FIELDS = (
    "id",
    "sensor",
    "sensor_direction",
    "sensor_angle_deg",
    "at",
    "direction",
    "angle_deg",
    "reaction",
    "proportional_gain",
    "velocity_gain",
    "delayed_gain",
    "delay",
    "bandwidth_hz",
    "force_limit",
    "description",
)

#: the largest actuator delay read, s: beyond it the controller cannot act on chatter
MAX_DELAY = 10.0


def read_actuators(src: str, raw: dict[str, Any], ids: _Ids, ctx: Any) -> list[Actuator]:
    """[[actuator]]: the sensor's point and direction, the force's point and
    direction (default: the sensor's: collocated), the gains of (1), the
    delay, the bandwidth and the force limit.  ``ctx`` resolves the points
    (the reader's :class:`~chatterlab.model._points._RefContext`)."""
    out: list[Actuator] = []
    for k, t in enumerate(raw.get("actuator", [])):
        iid = _id_of(src, "actuator", k, t)
        it = _Item(src, f'[[actuator]] "{iid}"', t, ACTUATOR_FIELDS)
        ids.register("actuator", iid)
        sensor = ctx.ref(it, "sensor")
        if sensor.kind == "ground":
            raise it.err("sensor", "a sensor on the ground measures nothing; put it on the structure")
        s_angle = _angle(it, "sensor_direction", "sensor_angle_deg", None)
        at = ctx.ref(it, "at") if it.has("at") else sensor
        if at.kind == "ground":
            raise it.err("at", "a force on the ground does nothing; put the actuator on the structure")
        angle = _angle(it, "direction", "angle_deg", s_angle)
        reaction = None
        if it.has("reaction"):
            reaction = ctx.ref(it, "reaction")
            if reaction.kind == "ground":
                reaction = None  # the ground takes it: the same as no reaction point
            elif reaction == at:
                raise it.err("reaction", "the reaction point is the force's own point: the forces cancel")
        gp = it.num("proportional_gain", 0.0, unit="N/m")
        gv = it.num("velocity_gain", 0.0, unit="N s/m")
        if gv < 0:
            raise it.err(
                "velocity_gain",
                f"must be >= 0 (got {gv:g} N s/m): a negative velocity gain feeds energy in; if the sensor"
                " points the other way, flip sensor_direction (sensor_angle_deg + 180)",
            )
        go = it.num("delayed_gain", 0.0, unit="N/m")
        delay = it.num("delay", 0.0, unit="s", nonneg=True)
        if delay > MAX_DELAY:
            raise it.err("delay", f"must be at most {MAX_DELAY:g} s (got {delay:g} s); it is in seconds")
        fb = (
            it.num("bandwidth_hz", math.inf, unit="Hz", positive=True) if it.has("bandwidth_hz") else math.inf
        )
        fl = it.num("force_limit", math.inf, unit="N", positive=True) if it.has("force_limit") else math.inf
        if gp == gv == go == 0.0:
            raise it.err(
                "velocity_gain",
                "every gain is 0: the actuator does nothing; give velocity_gain (N s/m),"
                " proportional_gain or delayed_gain (N/m)",
            )
        out.append(Actuator(iid, sensor, s_angle, at, angle, reaction, gp, gv, go, delay, fb, fl))
    return out


def _angle(it: _Item, dkey: str, akey: str, default: float | None) -> float:
    """A direction written as ``dkey`` ("x" or "y") or ``akey`` (degrees from
    global X); ``default`` when neither is written (None: one is required)."""
    if it.has(dkey) and it.has(akey):
        raise it.err(dkey, f'give one of {dkey} ("x" or "y") and {akey} (degrees from global X), not both')
    if it.has(akey):
        return math.radians(it.num(akey))
    if not it.has(dkey):
        if default is None:
            raise it.err(dkey, f'missing: give {dkey} ("x" or "y") or {akey} (degrees from global X)')
        return default
    d = it.raw(dkey)
    if d not in ("x", "y"):
        raise it.err(dkey, f'must be "x" or "y" (or give {akey} instead), got {d!r}')
    return 0.0 if d == "x" else math.pi / 2
