"""Process kinematics for the time domain: where the slide is, how fast it
moves, and when the tool is in the cut.

* :class:`ShapingKinematics` -- the seed paper's traverse shaper: a work
  stroke over run-in s_r, cutting distance s and coasting s_c at the work speed
  v_w, then the return at v_l; the coupling element is active only while the
  tool is within the cutting distance; the delay T is one stroke cycle, so the
  same point of the workpiece is cut again after T.
* :class:`SteadyKinematics` -- the slide held at one position and the tool
  always in the cut with a given delay (turning: T = 60/n, or T given).

All times in s, positions in m, speeds in m/s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError, check_delay, check_position, check_speed
from ..model._items import Process, stroke_cycle

__all__ = ["ShapingKinematics", "SteadyKinematics", "kinematics_for"]


@dataclass(frozen=True)
class ShapingKinematics:
    """Stroke cycle of a shaper (one work stroke + one return per cycle)."""

    start: float  #: slide position at the start of the work stroke, m
    direction: float  #: +1 / -1: sign of ds/dt during the work stroke
    run_in: float  #: m
    cut: float  #: m
    coast: float  #: m
    speed: float  #: work speed v_w, m/s
    return_speed: float  #: v_l, m/s

    @classmethod
    def from_process(cls, p: Process, speed: float | None = None) -> ShapingKinematics:
        v = p.speed if speed is None else check_speed(speed, unit="m/s")
        return cls(p.start, p.direction, p.run_in, p.cut, p.coast, v, p.return_speed)

    @property
    def stroke(self) -> float:
        return self.run_in + self.cut + self.coast

    @property
    def work_time(self) -> float:
        return self.stroke / self.speed

    @property
    def cycle(self) -> float:
        """One stroke cycle = the delay T between passes, s."""
        return float(stroke_cycle(self.stroke, self.speed, self.return_speed))

    @property
    def delay(self) -> float:
        return self.cycle

    def state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Slide position s (m), velocity ds/dt (m/s), in-cut mask and the
        distance travelled in the cut (m; NaN outside it), at times t.

        Right-continuous at the events (cut entry and exit, reversal, end of
        the cycle): a time within a few units in the last place of an event
        -- a step ``k h`` meant to land on it -- is taken as the event itself,
        so that the switch happens on that step and not one step late.
        """
        t = np.asarray(t, dtype=float)
        T = self.cycle
        tol = 4.0 * np.spacing(np.maximum(np.abs(t), T))
        k = np.floor((t + tol) / T)
        tau = np.maximum(t - k * T, 0.0)
        t_in, t_out, t_work, _ = self.events()
        work = tau < t_work - tol
        d_work = self.speed * tau
        d_ret = self.stroke - self.return_speed * (tau - self.work_time)
        d = np.where(work, d_work, np.clip(d_ret, 0.0, self.stroke))
        s = self.start + self.direction * d
        v = np.where(work, self.direction * self.speed, -self.direction * self.return_speed)
        in_cut = work & (tau >= t_in - tol) & (tau < t_out - tol)
        cut_d = np.where(in_cut, np.clip(d_work - self.run_in, 0.0, self.cut), np.nan)
        return s, v, in_cut, cut_d

    def events(self) -> tuple[float, float, float, float]:
        """Times within a cycle where something jumps: cut entry, cut exit,
        end of the work stroke, end of the cycle (s)."""
        v = self.speed
        return (self.run_in / v, (self.run_in + self.cut) / v, self.work_time, self.cycle)

    def breakpoints(self, t_end: float) -> tuple[float, ...]:
        """All event times in (0, t_end]."""
        ev = np.array(self.events())
        n = int(np.ceil(t_end / self.cycle)) + 1
        allt = (np.arange(n)[:, None] * self.cycle + ev[None, :]).ravel()
        allt = np.unique(allt[(allt > 0) & (allt <= t_end)])
        return tuple(float(x) for x in allt)

    @property
    def grid_unit(self) -> float:
        """The largest time step that puts every event on the step grid (to
        1e-9 relative), or the cycle if the events are incommensurate (then
        only the cycle, i.e. the delay, is on the grid; cut entry and exit
        fall between steps)."""
        from fractions import Fraction
        from math import gcd, lcm

        ev = [e for e in self.events() if e > 0]
        fr = [Fraction(e).limit_denominator(10**6) for e in ev]
        den = 1
        for f in fr:
            den = lcm(den, f.denominator)
        num = 0
        for f in fr:
            num = gcd(num, f.numerator * (den // f.denominator))
        unit = num / den if num else 0.0
        ok = unit > 1e-6 * self.cycle and all(
            abs(e / unit - round(e / unit)) < 1e-9 * max(1.0, e / unit) for e in ev
        )
        return unit if ok else self.cycle

    @property
    def range(self) -> tuple[float, float]:
        a, b = self.start, self.start + self.direction * self.stroke
        return (min(a, b), max(a, b))


@dataclass(frozen=True)
class SteadyKinematics:
    """The slide held still at ``position`` (None for models without a
    movable subsystem), the tool always cutting, delay T."""

    position: float | None
    delay: float

    def state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        s = np.full(t.shape, np.nan if self.position is None else self.position)
        return s, np.zeros(t.shape), np.ones(t.shape, bool), np.full(t.shape, np.nan)


def kinematics_for(
    process: Process | None,
    *,
    speed: float | None = None,
    delay: float | None = None,
    position: float | None = None,
) -> ShapingKinematics | SteadyKinematics:
    """The kinematics implied by the model's process and the options: a
    shaping process moves the slide through stroke cycles; turning, a given
    delay, or an explicit ``position`` hold it still."""
    if speed is not None:
        speed = check_speed(speed, unit=process.speed_unit if process is not None else "")
    if speed is not None and delay is not None:
        raise InputError("give either the speed or the delay, not both")
    if position is not None:
        position = check_position(position)
    if process is not None and process.kind == "shaping" and delay is None and position is None:
        return ShapingKinematics.from_process(process, speed)
    if delay is None:
        if process is None:
            raise InputError("the model has no [process] table: give the delay T")
        delay = float(process.delay(speed)) if speed is not None else float(process.delay())
    return SteadyKinematics(position, check_delay(delay))
