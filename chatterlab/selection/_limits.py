"""What a width of cut removes and costs at a speed, and every limit on it
besides stability: the machine's speed range, power and torque curves, the
tool's depth and radial width (:class:`~chatterlab.model.Machine`, the
``[machine]`` table), and any limit plugged in (:class:`WidthLimit`, e.g. a
surface-location-error limit).

Removal (one formula for the three processes).  A pass of the tool removes
a chip of width b (the lobes' width: milling's axial depth a_p), thickness h
(the feed: per tooth, per revolution, per stroke) and length L along the
cut (milling: the radial width a_e; turning: the workpiece circumference
pi D_w; shaping: the cut length), once per delay T (tooth period,
revolution, stroke cycle), so

    MRR = b h L / T,

which is a_p a_e f_z N n / 60 for milling and b f pi D_w n / 60 for
turning.  The ranking needs only b / T (the width rate): h and L are the
same at every speed, so the recommended speeds do not depend on them.

Power.  Milling (Altintas, *Manufacturing Automation*, 2nd ed., 2012,
ch. 2): the tangential force of a tooth is K_t a_p h + K_te a_p with
h = f_z sin phi; averaged over a revolution, N teeth each sweeping
[phi_st, phi_ex], the torque is

    M = a_p (D / 2) (N / 2 pi) [K_t f_z (cos phi_st - cos phi_ex) + K_te (phi_ex - phi_st)],

the power P = M Omega (Omega = 2 pi n / 60) -- K_t MRR plus the edge
term.  Turning and shaping: P = F_c' b V with F_c' the cutting force per
unit width along the cutting velocity V (turning pi D_w n / 60, shaping
the work speed v_w, during the stroke) and the spindle torque
F_c' b D_w / 2.  F_c' is, in this order: ``specific_energy`` x feed (the
``[machine]`` field); the main cutting force of a ``grasso`` coupling,
forces[0] / width_ref (its CE axis 1 is the cutting direction by
definition, Wittbrodt & Kalinski); K_f x feed of a ``regenerative``
coupling (K_f b h is the resultant force, so this is an upper bound of the
power: its component along the cutting velocity is at most that).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from ..errors import InputError
from ..model import Machine, machine_problem

__all__ = ["Removal", "WidthLimit", "width_limit", "check_machine", "curve_at", "removal_of"]


# ------------------------------------------------------------------------------ plug-in limits
@runtime_checkable
class WidthLimit(Protocol):
    """A limit on the width of cut at each speed, besides stability and
    the machine (a surface-location-error limit, a form tolerance, a
    cutting-force limit of a thin wall ...): what :func:`recommend` takes in
    ``limits=``.

    ``name`` says what it is (it is named as the reason wherever it sets
    the width); ``max_width(speeds, upper)`` returns, for each speed (the
    process's unit), the largest width (m) in ``[0, upper]`` that satisfies
    it (``upper``: the largest width every other limit allows there; return
    ``upper`` where this limit does not bind).  :func:`width_limit` builds
    one from a quantity that grows with the width."""

    @property
    def name(self) -> str: ...

    def max_width(self, speeds: np.ndarray, upper: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True, eq=False)
class _Bisected:
    """:func:`width_limit`'s limit: the largest width with |value| <= limit, by bisection."""

    name: str
    value: Callable[[np.ndarray, np.ndarray], Any]
    limit: float
    rtol: float

    def max_width(self, speeds: np.ndarray, upper: np.ndarray) -> np.ndarray:
        v = np.asarray(speeds, float)
        hi = np.asarray(upper, float).copy()
        fin = np.isfinite(hi) & (hi > 0)
        ok = np.zeros(v.size, bool)
        ok[fin] = self._within(v[fin], hi[fin])
        out = np.where(ok | ~fin, hi, np.nan)
        todo = np.nonzero(fin & ~ok)[0]
        lo = np.zeros(todo.size)
        up = hi[todo]
        # bisection on [0, upper]: the value grows with the width, so the set that satisfies
        # the limit is [0, w*]; after k halvings the bracket is upper / 2^k
        steps = max(1, math.ceil(math.log2(1.0 / self.rtol)))
        for _ in range(steps):
            mid = 0.5 * (lo + up)
            inside = self._within(v[todo], mid)
            lo = np.where(inside, mid, lo)
            up = np.where(inside, up, mid)
        out[todo] = lo
        return out

    def _within(self, v: np.ndarray, b: np.ndarray) -> np.ndarray:
        y = np.abs(np.asarray(self.value(v, b), float))
        if y.shape != v.shape:
            raise InputError(
                f"limit '{self.name}': value(speeds, widths) must return one number per speed (shape {v.shape},"
                f" got {y.shape})"
            )
        return np.asarray(y <= self.limit)


def width_limit(
    name: str, value: Callable[[np.ndarray, np.ndarray], Any], limit: float, *, rtol: float = 1e-4
) -> WidthLimit:
    """A :class:`WidthLimit` from a quantity that grows with the width:
    ``value(speeds, widths)`` (elementwise on two arrays of equal shape,
    speeds in the process's unit, widths in m) must not exceed ``limit`` in
    magnitude.  The largest width is found by bisection on ``[0, upper]`` to
    ``rtol`` of ``upper`` (the quantity must be nondecreasing in the width,
    as a forced vibration amplitude is below the stability limit).

    Example: a surface-location-error limit of 20 um, ``sle(speed, width)``
    an SLE engine's value in m::

        recommend(model, limits=[width_limit("surface location error", sle, 20e-6)])
    """
    if not isinstance(name, str) or not name:
        raise InputError("width_limit: name must be a non-empty string (what the limit is)")
    if not callable(value):
        raise InputError(f"width_limit '{name}': value must be a function value(speeds, widths)")
    if not (isinstance(limit, int | float) and math.isfinite(limit) and limit >= 0):
        raise InputError(f"width_limit '{name}': limit must be a finite number >= 0 (got {limit!r})")
    if not (isinstance(rtol, int | float) and 0 < rtol < 1):
        raise InputError(f"width_limit '{name}': rtol must be in (0, 1) (got {rtol!r})")
    return _Bisected(name, value, float(limit), float(rtol))


# ------------------------------------------------------------------------------ the machine
def check_machine(machine: Any, kind: str) -> Machine:
    """``machine`` (a :class:`Machine`, None for no limits) checked for a
    process of ``kind``: an :class:`InputError` naming the field and the fix."""
    if machine is None:
        return Machine()
    if not isinstance(machine, Machine):
        raise InputError(
            f"machine must be a chatterlab.model.Machine (the [machine] table), got {type(machine).__name__}"
        )
    bad = machine_problem(machine, kind)
    if bad is not None:
        raise InputError(f"machine {bad[0]}: {bad[1]}")
    return machine


def curve_at(curve: tuple[tuple[float, float], ...], speeds: np.ndarray) -> np.ndarray:
    """A power or torque curve at ``speeds``: linear between its points, the
    one value of a one-point curve everywhere, 0 (nothing available) outside
    the speeds it covers; inf without a curve."""
    v = np.asarray(speeds, float)
    if not curve:
        return np.full(v.shape, np.inf)
    x = np.array([p[0] for p in curve])
    y = np.array([p[1] for p in curve])
    if x.size == 1:
        return np.full(v.shape, y[0])
    inside = (v >= x[0]) & (v <= x[-1])
    return np.where(inside, np.interp(v, x, y), 0.0)


# ------------------------------------------------------------------------------ removal and power
@dataclass(frozen=True)
class Removal:
    """What a width of cut removes and costs at a speed (module docstring).

    ``length`` L (m) and ``feed`` h (m) make the MRR; ``force`` F_c' (N/m,
    turning and shaping: the cutting force per unit width) with
    ``force_source`` saying where it comes from; for milling the cutter
    (``teeth``, ``diameter``, ``Kt``, ``Kte``, ``entry``, ``exit``).
    A quantity that cannot be known is nan (and the summary says what to
    give)."""

    kind: str
    process: Any
    length: float
    feed: float
    force: float = math.nan
    force_source: str = ""
    teeth: int = 1
    diameter: float = math.nan  #: milling: the cutter's D; turning: the workpiece's D_w
    Kt: float = math.nan
    Kte: float = 0.0
    entry: float = math.nan
    exit: float = math.nan

    def delay(self, speeds: Any) -> np.ndarray:
        """The delay T (s) at ``speeds`` (the process's kinematics)."""
        return np.asarray(self.process.delay(np.asarray(speeds, float)), float)

    def width_rate(self, widths: Any, speeds: Any) -> np.ndarray:
        """b / T, m/s: the MRR per unit feed and unit cut length (the ranking)."""
        return np.asarray(widths, float) / self.delay(speeds)

    def mrr(self, widths: Any, speeds: Any) -> np.ndarray:
        """Material removal rate b h L / T, m^3/s (nan where h or L is unknown)."""
        return self.width_rate(widths, speeds) * self.feed * self.length

    def _omega(self, speeds: Any) -> np.ndarray:
        return 2 * np.pi * np.asarray(speeds, float) / 60.0

    def power_per_width(self, speeds: Any) -> np.ndarray:
        """Cutting power per unit width, W/m (the mean for milling; during the
        stroke for shaping); nan where unknown."""
        v = np.asarray(speeds, float)
        if self.kind == "milling":
            return self.torque_per_width(v) * self._omega(v)
        if self.kind == "turning":
            return self.force * np.pi * self.diameter * v / 60.0
        if self.kind == "shaping":
            return np.full(v.shape, self.force) * v
        return np.full(v.shape, np.nan)

    def torque_per_width(self, speeds: Any) -> np.ndarray:
        """Spindle torque per unit width, N m/m (turning, milling); nan otherwise."""
        v = np.asarray(speeds, float)
        if self.kind == "milling":
            arc = self.Kt * self.feed * (math.cos(self.entry) - math.cos(self.exit)) + self.Kte * (
                self.exit - self.entry
            )
            return np.full(v.shape, 0.5 * self.diameter * self.teeth / (2 * np.pi) * arc)
        if self.kind == "turning":
            return np.full(v.shape, self.force * 0.5 * self.diameter)
        return np.full(v.shape, np.nan)

    @property
    def radial_width(self) -> float:
        """Milling: the radial width of cut a_e = (D / 2)(cos phi_st - cos phi_ex), m."""
        return 0.5 * self.diameter * (math.cos(self.entry) - math.cos(self.exit))

    def needs(self) -> list[str]:
        """What is missing for the MRR in m^3/s (the fields to give)."""
        out = []
        if math.isnan(self.feed):
            out.append("feed" if self.kind != "milling" else "feed (or [process] feed_per_tooth)")
        if self.kind == "turning" and math.isnan(self.diameter):
            out.append("workpiece_diameter")
        return out

    def power_needs(self) -> list[str]:
        """What is missing for the power and torque."""
        out = [n for n in self.needs() if self.kind != "shaping" or n != "feed"]
        if self.kind != "milling" and math.isnan(self.force):
            out.append("specific_energy and feed")
        return out


def _milling_cut(process: Any) -> Any:
    """The cutter of a milling process: a model's ``Process.milling`` or a
    :class:`chatterlab.process.Milling` itself."""
    cut = getattr(process, "milling", None)
    return cut if cut is not None else process


def removal_of(process: Any, couplings: tuple[Any, ...], machine: Machine) -> Removal:
    """The :class:`Removal` of a cut: the process's kinematics and cutter,
    the model's couplings (for the cutting force of turning and shaping),
    the machine's feed, workpiece diameter and specific energy."""
    kind = str(process.kind)
    if kind == "milling":
        cut = _milling_cut(process)
        feed = machine.feed
        if math.isnan(feed) and getattr(cut, "feed_per_tooth", 0.0) > 0:
            feed = float(cut.feed_per_tooth)
        r = Removal(
            kind, process, math.nan, feed, teeth=int(cut.teeth), diameter=float(cut.diameter),
            Kt=float(cut.Kt), Kte=float(getattr(cut, "Kte", 0.0)), entry=float(cut.entry), exit=float(cut.exit),
            force_source="[process] Kt and Kte (the mean torque of the teeth in the cut)",
        )  # fmt: skip
        from dataclasses import replace

        return replace(r, length=r.radial_width)
    force, source = math.nan, ""
    if not math.isnan(machine.specific_energy) and not math.isnan(machine.feed):
        force, source = machine.specific_energy * machine.feed, "specific_energy x feed"
    elif math.isnan(machine.specific_energy):
        for c in couplings:
            if c.kind == "grasso" and c.forces[0] != 0:
                force = abs(c.forces[0]) / c.width_ref
                source = f"the main cutting force of [[coupling]] '{c.id}' (forces[0] / width_ref)"
                break
            if c.kind == "regenerative" and not math.isnan(machine.feed):
                kf = dict(c.params).get("Kf", math.nan)
                force = kf * machine.feed
                source = (
                    f"K_f x feed of [[coupling]] '{c.id}' (the resultant force: an upper bound of the power"
                    " along the cutting speed)"
                )
                break
    if kind == "turning":
        length = math.pi * machine.workpiece_diameter
        return Removal(
            kind, process, length, machine.feed, force, source, diameter=machine.workpiece_diameter
        )
    if kind == "shaping":
        return Removal(kind, process, float(process.cut), machine.feed, force, source)
    raise InputError(
        f"speed selection needs a turning, milling or shaping process (got kind {kind!r}): a delay process"
        " has no speed to choose"
    )
