"""Time-domain confirmation of a stability boundary.

For points straddling the boundary of a :class:`~chatterlab.lobes._diagram.LobeDiagram`
(widths ``factors`` times b_lim at a few speeds), run the Newmark solver on
the frozen configuration with a continuous cut and the delay of that speed,
starting from a small disturbance without the static cutting force, and
measure the growth rate of the chip-thickness variation.  A point below the
boundary must decay, one above must grow.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ..io import Result
from ..structure._assembly import System

__all__ = ["Confirmation", "confirm"]


#: the columns of a confirmation: name -> (unit, long name); a text column is
#: stored as the index of its value in the tuple of :data:`CODES`
COLUMNS: dict[str, tuple[str, str]] = {
    "speed": ("", "speed of the diagram"),
    "delay": ("s", "delay T at that speed"),
    "width": ("m", "width of cut simulated"),
    "factor": ("1", "width / b_lim"),
    "expected": ("1", "the diagram's side"),
    "growth_rate": ("1/s", "envelope growth rate of the chip-thickness variation"),
    "classification": ("1", "simulated"),
    "agrees": ("1", "the simulation agrees with the diagram: 1, or 0"),
    "status": ("1", "the run's status"),
    "step": ("s", "time step"),
    "duration": ("s", "simulated time"),
}
#: the words of the text columns, stored as their index
CODES: dict[str, tuple[str, ...]] = {
    "expected": ("stable", "unstable"),
    "classification": ("stable", "unstable", "marginal"),
    "status": ("ok", "diverged", "interrupted", "stopped"),
}


@dataclass(frozen=True)
class Confirmation(Result):
    """Result of :func:`confirm`: one row per simulated point (the files of
    the one result protocol, :class:`chatterlab.io.Result`, with a ``point``
    coordinate); ``speed_unit`` the diagram's (m/s or rpm)."""

    rows: tuple[dict[str, Any], ...]
    speed_unit: str = ""

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``point`` (0 .. n-1) and one variable per column (:data:`COLUMNS`)."""
        n = len(self.rows)
        data: dict[str, Any] = {}
        for name, (unit, what) in COLUMNS.items():
            vals = [r[name] for r in self.rows]
            if name in CODES:
                words = CODES[name]
                vals = [words.index(v) for v in vals]
                what += ": " + ", ".join(f"{k} {w}" for k, w in enumerate(words))
            unit = self.speed_unit if name == "speed" else unit
            data[name] = (np.array(vals, dtype=float).reshape(n), unit, what)
        attrs = {
            "title": "chatterlab time-domain confirmation of a lobe diagram",
            "summary": self.summary_line(),
        }
        return {"point": (np.arange(n), "", "simulated point")}, data, attrs

    def plot(self, ax: Any = None, **style: Any) -> Any:
        """The simulated points over the diagram's speed and width
        (:func:`chatterlab.plot._time.plot_confirmation`); returns the Axes."""
        from ..plot._time import plot_confirmation

        return plot_confirmation(self, ax=ax, **style)

    @property
    def agrees(self) -> bool:
        return all(r["agrees"] for r in self.rows)

    def summary_line(self) -> str:
        ok = sum(r["agrees"] for r in self.rows)
        return f"time-domain confirmation: {ok}/{len(self.rows)} points agree with the boundary"

    def table(self) -> str:
        lines = [self.summary_line()]
        lines.append(
            f"  {'speed':>10} {'b [mm]':>9} {'b/b_lim':>7} {'expected':>9} {'growth [1/s]':>13} {'simulated':>10}"
        )
        for r in self.rows:
            lines.append(
                f"  {r['speed']:>10.5g} {r['width'] * 1e3:>9.4g} {r['factor']:>7.2f} {r['expected']:>9}"
                f" {r['growth_rate']:>+13.4g} {r['classification']:>10}"
            )
        return "\n".join(lines)


def confirm(
    system: System,
    diagram: Any,
    *,
    count: int = 2,
    factors: tuple[float, float] = (0.7, 1.4),
    periods: int = 30,
    min_duration: float = 2.0,
    phase_error: float = 0.1,
    max_steps: int = 4_000_000,
) -> Confirmation:
    """Simulate ``count`` speeds of the diagram at ``factors`` x b_lim.

    Parameters
    ----------
    system : System
    diagram : LobeDiagram
    count : int
        Number of speeds (the minimum of the envelope first, then spread).
    factors : (float, float)
        Widths relative to b_lim below and above the boundary.
    periods : int
        Simulated duration in delays T (at least ``min_duration`` s).
    phase_error : float
        Allowed error (rad) of the phase w T of the chatter wave over one
        delay caused by Newmark's period elongation (w h)^2 / 12: the step is
        h <= sqrt(12 phase_error / (w^3 T)).  With long delays (shaping:
        seconds) a frequency error of 0.1 % already moves the point to another
        lobe, so this, not stability, sets the step.
    max_steps : int
        Cap on the steps of one run (the duration is shortened to fit).
    """
    from ..process._damping import damping_term
    from ..time import Excitation, Initial, Integration, simulate
    from ..time._simulate import LAND_STEPS

    # the indentation model's flank force needs LAND_STEPS samples across the wear land
    term = damping_term(system.model) if getattr(system.model, "process_damping", None) else None
    flank = term if term is not None and term.indentation else None

    if count < 1:
        raise InputError(f"count must be >= 1 (got {count})")
    if diagram.terms != "pdo":
        raise InputError(
            "time-domain confirmation simulates all feedback terms: compute the lobes with terms='pdo'"
        )
    picks = _picks(diagram, count)
    if not picks:
        return Confirmation((), str(getattr(diagram, "speed_unit", "")))
    cid, axis, q0 = _disturbance(system, diagram.position)
    rows = []
    for j in picks:
        T = float(diagram.delay[j])
        fch = float(diagram.chatter_hz[j])
        land = float(flank.wear_land / (LAND_STEPS * flank.speed(T))) if flank is not None else math.inf
        h, dur = _step_and_duration(T, fch, periods, min_duration, phase_error, max_steps, land)
        for fac in factors:
            b = float(diagram.b_lim[j] * fac)
            sim = simulate(
                system,
                feedback="pdo",
                width=b,
                delay=T,
                position=diagram.position,
                outputs=[],
                integration=Integration(
                    duration=dur, step=h, record_every=max(1, int(round(1.0 / (8.0 * fch * h))))
                ),
                initial=Initial(q0=q0),
                excitation=Excitation(cutting_forces=False),
            )
            g = sim.growth(f"{cid}.{axis + 1}", window="all", skip=min(3 * T, 0.3 * dur))
            expected = "stable" if fac < 1 else "unstable"
            got = {"decaying": "stable", "growing": "unstable"}.get(g.classification, "marginal")
            rows.append(
                {
                    "speed": float(diagram.speed[j]),
                    "delay": T,
                    "width": b,
                    "factor": fac,
                    "expected": expected,
                    "growth_rate": float(g.rate),
                    "classification": got,
                    "agrees": got == expected,
                    "status": sim.status,
                    "step": h,
                    "duration": float(sim.t[-1]) if sim.t.size else 0.0,
                }
            )
    return Confirmation(tuple(rows), str(getattr(diagram, "speed_unit", "")))


def _picks(diagram: Any, count: int) -> list[int]:
    """Indices of the speeds simulated: the minimum of the envelope first,
    then up to ``count`` spread over the finite b_lim (none if there is none)."""
    fin = np.nonzero(np.isfinite(diagram.b_lim))[0]
    if fin.size == 0:
        return []
    picks = [int(np.nanargmin(diagram.b_lim))]
    for p in fin[np.linspace(0, fin.size - 1, count + 1).astype(int)[1:]]:
        if len(picks) >= count:
            break
        if int(p) not in picks:
            picks.append(int(p))
    return picks


def _disturbance(system: System, position: float | None) -> tuple[str, int, np.ndarray]:
    """The first coupling element's id, its regenerated axis (where the
    delayed matrix acts) and initial displacements that disturb that axis by
    1 micrometre."""
    c0 = system.model.couplings[0]
    cid = c0.id
    # the regenerated CE axis: where the delayed matrix acts
    axis = int(np.argmax(np.abs(np.array(c0.DO)).sum(axis=0)))
    fz = system.at(position)
    J = fz.couplings()[0].J
    e = np.zeros(3)
    e[axis] = 1e-6
    q0 = np.linalg.lstsq(J, e, rcond=None)[0]  # a small disturbance of that axis
    return cid, axis, q0


def _step_and_duration(
    T: float,
    fch: float,
    periods: int,
    min_duration: float,
    phase_error: float,
    max_steps: int,
    land: float = math.inf,
) -> tuple[float, float]:
    """Newmark step (a whole fraction of the delay T, fine enough for the
    chatter frequency's phase over one delay, and at most ``land``: the
    indentation model's wear-land step) and the simulated duration."""
    w = 2 * np.pi * fch
    h = min(1.0 / (25.0 * fch), T / 10.0, math.sqrt(12.0 * phase_error / (w**3 * T)), land)
    h = T / math.ceil(T / h)
    dur = max(periods * T, min_duration, 12.0 / fch)
    dur = min(dur, max_steps * h)
    return h, dur
