"""The result of :func:`chatterlab.selection.recommend`: :class:`Recommendation`,
the ranked cuts with the reason for each, every speed evaluated (for the
plot and the files), and what the ranking rests on."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..io import Result
from ..lobes import ProcessNames

__all__ = ["Recommendation", "BINDINGS", "VERDICTS"]

#: what can set the recommended width at a speed, in the order of the files' codes
BINDINGS = ("stability", "ceiling", "max depth", "power", "torque", "undetermined", "limit")
#: what the independent check of a recommended cut can say
VERDICTS = ("stable", "unstable", "marginal", "undetermined", "not checked")


def _binding_code(names: Any) -> np.ndarray:
    """Codes of :data:`BINDINGS` (a plug-in limit's own name is ``limit``)."""
    return np.array(
        [BINDINGS.index(str(b)) if str(b) in BINDINGS else BINDINGS.index("limit") for b in names]
    )


@dataclass(frozen=True, eq=False)
class Recommendation(Result, ProcessNames):
    """The cuts that maximise the material removal rate while stable with a
    margin and within every limit, ranked (:func:`chatterlab.selection.recommend`).

    Attributes (the ranked cuts, best first; shape (n,))
    ----------
    speed : ndarray
        Speed in the process's unit (rpm; a shaper's work speed m/s).
    width : ndarray
        The recommended width of cut, m (milling: the axial depth a_p).
    limit : ndarray
        The stability limit at that speed, m (``inf``: none below the
        largest width searched).
    mrr : ndarray
        Material removal rate b h L / T, m^3/s (nan without the feed, or
        for turning the workpiece diameter).
    width_rate : ndarray
        b / T, m/s: the MRR per unit feed and cut length (what is ranked).
    power, torque : ndarray
        Cutting power, W, and spindle torque, N m (nan where not known).
    binding : ndarray of str
        What sets the width (:data:`BINDINGS`, or a plug-in limit's name).
    lobe, chatter_hz : ndarray
        The lobe number (-1 where not known) and chatter frequency (Hz) at
        the limit.
    resolution : ndarray
        How far the speed is known, +- in the process's unit (the bracket of
        the last refinement).
    verdict : ndarray of str
        The independent check of the recommended cut (:data:`VERDICTS`):
        the argument principle and the rightmost roots (turning, shaping)
        or the Floquet multipliers (milling) at (speed, width).
    check, reason : tuple of str
        What the check found, and why each cut is chosen, in words.

    The speeds evaluated (sorted; the grid plus the refinements):
    ``grid_speed``, ``grid_limit`` (m), ``grid_allowed`` (the largest
    width every limit allows, m), ``grid_rate`` (b / T, m/s),
    ``grid_binding`` and ``caps`` (each limit's largest width there, m).
    ``line_speed``, ``line_limit``, ``line_allowed``: the lobes' envelope
    interpolated between the samples of their curves on a dense grid (with
    the cusps) and the width allowed there -- what the plot draws, and where
    the search looked for peaks between the speeds evaluated (the speeds
    evaluated themselves without lobe curves).  ``diagram`` is the lobe
    diagram on the requested speeds.
    """

    speed: np.ndarray
    width: np.ndarray
    limit: np.ndarray
    mrr: np.ndarray
    width_rate: np.ndarray
    power: np.ndarray
    torque: np.ndarray
    binding: np.ndarray
    lobe: np.ndarray
    chatter_hz: np.ndarray
    resolution: np.ndarray
    verdict: np.ndarray
    check: tuple[str, ...]
    reason: tuple[str, ...]
    grid_speed: np.ndarray
    grid_limit: np.ndarray
    grid_allowed: np.ndarray
    grid_rate: np.ndarray
    grid_binding: np.ndarray
    caps: dict[str, np.ndarray]
    line_speed: np.ndarray
    line_limit: np.ndarray
    line_allowed: np.ndarray
    diagram: Any
    removal: Any
    machine: Any
    margin: float
    model: str
    width_max: float
    notes: tuple[str, ...] = ()
    evaluations: int = 0
    elapsed: float = 0.0
    meta: dict[str, Any] = field(default_factory=dict)

    # ------------------------------------------------------------------ names
    @property
    def process(self) -> Any:
        return self.removal.process

    @property
    def best(self) -> dict[str, float]:
        """The first-ranked cut: ``speed`` (process unit), ``width`` (m),
        ``mrr`` (m^3/s), ``limit`` (m); nan when nothing is feasible."""
        if not self.speed.size:
            return {k: math.nan for k in ("speed", "width", "mrr", "limit")}
        return {k: float(getattr(self, k)[0]) for k in ("speed", "width", "mrr", "limit")}

    # ------------------------------------------------------------------ words
    def table(self) -> str:
        """The ranked cuts as a text table (mm, the process's speed unit,
        cm^3/min, kW, N m)."""
        u = self.speed_unit
        sp = "{:>12.1f}" if u == "rpm" else "{:>12.4g}"
        head = (
            f"  {'rank':>4} {'speed [' + u + ']':>12} {'depth [mm]':>10} {'limit [mm]':>10}"
            f" {'MRR [cm3/min]':>13} {'power [kW]':>10} {'torque [N m]':>12}  {'set by':<12} check"
        )
        rows = [head]
        for i in range(self.speed.size):
            lim = "inf" if not np.isfinite(self.limit[i]) else f"{self.limit[i] * 1e3:.4g}"
            rows.append(
                f"  {i + 1:>4} " + sp.format(self.speed[i]) + f" {self.width[i] * 1e3:>10.4g} {lim:>10}"
                f" {_num(self.mrr[i] * 6e7, '13.4g')} {_num(self.power[i] / 1e3, '10.4g')}"
                f" {_num(self.torque[i], '12.4g')}  {str(self.binding[i]):<12} {self.verdict[i]}"
            )
        return "\n".join(rows)

    def summary(self) -> str:
        """What is recommended and why, in words."""
        d = self.diagram
        v = self.grid_speed
        lines = [
            f"recommended cuts for {self.model} ({self.process.kind}; lobes by {d.method},"
            f" {d.speed.size} speeds {_speed(self, float(np.min(d.speed)))} .. {_speed(self, float(np.max(d.speed)))}"
            f" refined to {v.size}; margin {self.margin * 100:g} % below the limit)"
        ]
        if not self.speed.size:
            lines.append("  no speed allows a cut within every limit")
        else:
            lines.append(self.table())
            lines.append("  why:")
            for i, r in enumerate(self.reason):
                lines.append(f"   {i + 1}. {r}")
                lines.append(f"      check: {self.check[i]}")
        lines += [f"  note: {n}" for n in self.notes]
        lines.append(f"  {self.evaluations} speeds evaluated, {self.elapsed:.2f} s")
        return "\n".join(lines)

    # ------------------------------------------------------------------ files
    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        """``(coords, data, attrs)``: the rank as coordinate and the ranked
        cuts as data; the speeds evaluated on a dimension ``grid``; the
        machine, the margin, the reasons and the checks as attributes."""
        n = self.speed.size
        u = self.speed_unit
        vcode = np.array([VERDICTS.index(str(x)) for x in self.verdict], float)
        g = ("grid",)
        data: dict[str, Any] = {
            "speed": (self.speed, u, self.speed_name),
            "width": (self.width, "m", f"recommended {self.width_name}"),
            self.limit_name: (self.limit, "m", "stability limit at the speed"),
            "mrr": (self.mrr, "m^3/s", "material removal rate"),
            "width_rate": (self.width_rate, "m/s", "width of cut per delay, b/T (the ranking)"),
            "power": (self.power, "W", "cutting power"),
            "torque": (self.torque, "N m", "spindle torque"),
            "binding": (_binding_code(self.binding).astype(float), "1",
                        "what sets the width: " + ", ".join(f"{i} {b}" for i, b in enumerate(BINDINGS))),
            "lobe": (np.asarray(self.lobe, np.int64), "1", "lobe number at the limit (-1: not known)"),
            "chatter_frequency": (self.chatter_hz, "Hz", "chatter frequency at the limit"),
            "speed_resolution": (self.resolution, u, "+- of the speed (last refinement's bracket)"),
            "verdict": (vcode, "1", "check of the cut: " + ", ".join(f"{i} {b}" for i, b in enumerate(VERDICTS))),
            "grid_speed": (self.grid_speed, u, "speeds evaluated", g),
            "grid_limit": (self.grid_limit, "m", "stability limit at the speeds evaluated", g),
            "grid_allowed": (self.grid_allowed, "m", "largest width within every limit", g),
            "grid_width_rate": (self.grid_rate, "m/s", "b/T at the largest width", g),
            "grid_binding": (_binding_code(self.grid_binding).astype(float), "1", "what sets the width", g),
        }  # fmt: skip
        for name, cap in self.caps.items():
            key = "cap_" + "".join(c if c.isalnum() else "_" for c in name)
            data[key] = (np.asarray(cap, float), "m", f"largest width allowed by {name}", g)
        m = self.machine
        attrs = {
            "title": "chatterlab speed selection",
            "model": self.model,
            "process": str(self.process.kind),
            "method": str(self.diagram.method),
            "margin": self.margin,
            "width_max_m": self.width_max,
            "machine": json.dumps({k: _plain(getattr(m, k)) for k in m.__dataclass_fields__}),
            "feed_m": self.removal.feed,
            "cut_length_m": self.removal.length,
            "cutting_force_source": self.removal.force_source,
            "reasons": json.dumps(list(self.reason)),
            "checks": json.dumps(list(self.check)),
            "notes": json.dumps(list(self.notes)),
        }
        attrs.update({k: v for k, v in self.meta.items() if isinstance(v, int | float | str)})
        return {"rank": (np.arange(1, n + 1), "1", "rank by material removal rate")}, data, attrs

    def to_csv(self, path: Any) -> Path | None:
        """One row per ranked cut (``name [unit]`` headers, SI, exact
        floats), with ``binding``, ``verdict`` and ``reason`` in words;
        written atomically.  Returns the path."""
        from ..io import write_csv

        coords, data, _ = self.dataset_parts()
        numeric = {k: v for k, v in data.items() if len(v) == 3 and k not in ("binding", "verdict")}
        n = self.speed.size
        coded = {
            "binding": (np.arange(n), [str(b) for b in self.binding]),
            "verdict": (np.arange(n), [str(b) for b in self.verdict]),
            "reason": (np.arange(n), list(self.reason)),
        }
        return write_csv(path, coords, numeric, coded=coded)

    def plot(self, ax: Any = None, *, title: str | None = None) -> Any:
        """The allowed width and the stability limit against speed with the
        ranked cuts marked, over the width rate (MRR) against speed
        (:func:`chatterlab.plot.plot_recommendation`).  Returns
        the two Axes."""
        from ..plot import plot_recommendation

        return plot_recommendation(self, ax=ax, title=title)


def _plain(x: Any) -> Any:
    """A machine field as strict JSON: inf as the string "inf", nan (absent) as null."""
    if isinstance(x, float):
        return x if math.isfinite(x) else ("inf" if x > 0 else None)
    return [list(p) for p in x] if isinstance(x, tuple) else x


def _num(x: float, fmt: str) -> str:
    return format(x, fmt) if np.isfinite(x) else format("-", ">" + fmt.split(".")[0])


def _speed(r: Recommendation, v: float) -> str:
    return f"{v:.0f} {r.speed_unit}" if r.speed_unit == "rpm" else f"{v:.4g} {r.speed_unit}"
