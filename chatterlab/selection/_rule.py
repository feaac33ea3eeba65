"""The shop floor's route to a stable speed: the chatter-frequency rule.

A cut chatters at f_c.  The stability pockets lie where the delay between
passes holds a whole number of chatter waves (the tooth-passing frequency
1/T an integer fraction of the chatter frequency): at such a speed the
surface left by the previous tooth is in phase with the vibration, the chip
thickness does not modulate and the regeneration stops (Tlusty;
Smith & Tlusty, "Stabilizing chatter by automatic spindle speed
regulation", CIRP Annals 41 (1992) 433-436; Schmitz & Smith, *Machining
Dynamics*, ch. 4).  So the speeds to try are

    T_j = j / f_c,  v_j = the speed whose delay is T_j  (j = 1, 2, ...),

for turning and milling n_j = 60 f_c / (N j) rpm; the ones nearest the
running speed come first.  The chatter frequency is known to its
resolution df (1/duration of a recording), so each speed to dv = v df / f_c
(turning, milling).  The rule puts the speed near a pocket; whether the cut
is stable there at the depth being cut only the lobes can say: with a
model each speed is checked against them (:func:`chatterlab.lobes`), and
without one the verdict is "undetermined".
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError, check_count
from ..io import Result
from ..model._items import spindle_speed_for, tooth_period
from ._recommend import check_margin, source_of, stable_width
from ._spectrum import ChatterFrequency

__all__ = ["SpeedRule", "chatter_rule", "RULE_VERDICTS"]

#: what the lobes say of a speed of the rule: stable at the depth with the margin, within the
#: margin, chatter at the depth, undetermined (no model, or the lobes establish nothing there),
#: the limit only (no depth given to compare)
RULE_VERDICTS = ("stable", "within margin", "unstable", "undetermined", "limit")


@dataclass(frozen=True)
class _Spindle:
    """Turning or milling kinematics without a model: T = 60 / (N n)."""

    teeth: int
    kind: str = "milling"
    speed_unit: str = "rpm"
    speed_name: str = "spindle speed"
    min_delay: float = 0.0

    def delay(self, speed: Any) -> Any:
        return tooth_period(np.asarray(speed, float), self.teeth)

    def speed_for_delay(self, T: Any) -> Any:
        return spindle_speed_for(np.asarray(T, float), self.teeth)


@dataclass(frozen=True, eq=False)
class SpeedRule(Result):
    """The speeds of the chatter-frequency rule (:func:`chatter_rule`), the
    nearest to the running speed first.

    Attributes
    ----------
    waves : ndarray of int
        j: chatter waves per delay (the tooth-passing frequency f_c / j).
    speed, speed_error : ndarray
        The speed (process unit) and its +- from the chatter frequency's
        resolution.
    delay : ndarray
        T_j = j / f_c, s.
    limit, width : ndarray
        The stability limit (m) at the speed and the width allowed with the
        margin (nan without a model).
    verdict : ndarray of str
        :data:`RULE_VERDICTS`.
    reason : tuple of str
        Each speed's verdict in words.
    """

    chatter_hz: float
    resolution_hz: float
    current_speed: float
    teeth: int
    process: Any
    waves: np.ndarray
    speed: np.ndarray
    speed_error: np.ndarray
    delay: np.ndarray
    limit: np.ndarray
    width: np.ndarray
    verdict: np.ndarray
    reason: tuple[str, ...]
    current_limit: float
    current_chatter_hz: float
    depth: float | None
    margin: float
    model: str
    spectrum: ChatterFrequency | None = None
    diagram: Any = None
    notes: tuple[str, ...] = ()
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def speed_unit(self) -> str:
        return str(self.process.speed_unit)

    def table(self) -> str:
        u = self.speed_unit
        fmt = "{:>12.1f}" if u == "rpm" else "{:>12.4g}"
        rows = [
            f"  {'j':>3} {'speed [' + u + ']':>12} {'+-':>8} {'limit [mm]':>10} {'allowed [mm]':>12}  verdict"
        ]
        for i in range(self.speed.size):
            lim = self.limit[i]
            ls = "-" if np.isnan(lim) else ("inf" if np.isinf(lim) else f"{lim * 1e3:.4g}")
            ws = "-" if not np.isfinite(self.width[i]) else f"{self.width[i] * 1e3:.4g}"
            rows.append(
                f"  {int(self.waves[i]):>3} " + fmt.format(self.speed[i]) + f" {self.speed_error[i]:>8.2g}"
                f" {ls:>10} {ws:>12}  {self.verdict[i]}"
            )
        return "\n".join(rows)

    def summary(self) -> str:
        u = self.speed_unit
        cur = f"{self.current_speed:.0f} {u}" if u == "rpm" else f"{self.current_speed:.4g} {u}"
        lines = []
        if self.spectrum is not None:
            lines.append(self.spectrum.summary())
        lines.append(
            f"chatter-frequency rule for {self.model}: chatter at {self.chatter_hz:.2f} Hz"
            f" (+- {self.resolution_hz:.2g} Hz), running at {cur}"
            + (f", depth {self.depth * 1e3:.4g} mm" if self.depth is not None else "")
            + (f", margin {self.margin * 100:g} %" if self.diagram is not None else "")
        )
        if np.isfinite(self.current_limit) or np.isinf(self.current_limit):
            lines.append(
                "  at the running speed the lobes give the limit "
                + (f"{self.current_limit * 1e3:.4g} mm" if np.isfinite(self.current_limit) else "inf")
                + (
                    f", chatter at {self.current_chatter_hz:.2f} Hz"
                    if np.isfinite(self.current_chatter_hz)
                    else ""
                )
            )
        lines.append("  the speeds that put the tooth-passing frequency on f_c / j, nearest first:")
        lines.append(self.table())
        lines.append("  why:")
        lines += [f"   j = {int(j)}: {r}" for j, r in zip(self.waves, self.reason, strict=True)]
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)

    def dataset_parts(self) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
        u = self.speed_unit
        code = np.array([RULE_VERDICTS.index(str(v)) for v in self.verdict], float)
        data = {
            "speed": (self.speed, u, str(self.process.speed_name)),
            "speed_error": (self.speed_error, u, "+- from the chatter frequency's resolution"),
            "delay": (self.delay, "s", "delay j / f_c"),
            "limit": (self.limit, "m", "stability limit at the speed (nan: no model)"),
            "width": (self.width, "m", "width allowed with the margin"),
            "verdict": (code, "1", "verdict: " + ", ".join(f"{i} {v}" for i, v in enumerate(RULE_VERDICTS))),
        }
        attrs = {
            "title": "chatterlab chatter-frequency rule",
            "model": self.model,
            "chatter_frequency_hz": self.chatter_hz,
            "resolution_hz": self.resolution_hz,
            "current_speed": self.current_speed,
            "teeth": self.teeth,
            "depth_m": float("nan") if self.depth is None else self.depth,
            "margin": self.margin,
            "current_limit_m": self.current_limit,
            "reasons": json.dumps(list(self.reason)),
            "notes": json.dumps(list(self.notes)),
        }
        return {"waves": (np.asarray(self.waves, np.int64), "1", "chatter waves per delay j")}, data, attrs

    def to_csv(self, path: Any) -> Path | None:
        """One row per speed, with the verdict and its reason in words."""
        from ..io import write_csv

        coords, data, _ = self.dataset_parts()
        numeric = {k: v for k, v in data.items() if k != "verdict"}
        n = self.speed.size
        coded = {
            "verdict": (np.arange(n), [str(v) for v in self.verdict]),
            "reason": (np.arange(n), list(self.reason)),
        }
        return write_csv(path, coords, numeric, coded=coded)

    def plot(self, ax: Any = None, *, title: str | None = None) -> Any:
        """The rule's speeds on the lobes (with a model) and the spectrum
        (from a recording) (:func:`chatterlab.plot.plot_speed_rule`).
        Returns the Axes (a tuple when there are two panels)."""
        from ..plot import plot_speed_rule

        return plot_speed_rule(self, ax=ax, title=title)


def _speed_value(v: Any, name: str) -> float:
    if (
        isinstance(v, bool)
        or not isinstance(v, int | float | np.floating)
        or not (math.isfinite(v) and v > 0)
    ):
        raise InputError(f"{name} must be a finite speed > 0 (got {v!r})")
    return float(v)


def chatter_rule(
    chatter: Any,
    speed: float,
    *,
    source: Any = None,
    teeth: int | None = None,
    depth: float | None = None,
    margin: float = 0.2,
    count: int = 4,
    machine: Any = None,
    resolution_hz: float | None = None,
    position: float | None = None,
    width_max: float | None = None,
    **options: Any,
) -> SpeedRule:
    """The speeds that put the tooth-passing frequency (or an integer
    fraction of it) on the chatter frequency, nearest to the running speed
    first, each checked against the lobes when ``source`` is a model.

    Parameters
    ----------
    chatter : float or ChatterFrequency
        The chatter frequency, Hz (a number measured, or what
        :func:`chatter_frequency` found in a recording).
    speed : float
        The running speed, in the process's unit (rpm without a model).
    source : Model, FrozenSystem, milling ClosedLoop, optional
        The model whose lobes check each speed (without one every verdict
        is "undetermined").
    teeth : int, optional
        N, without a model (default 1: turning).
    depth : float, optional
        The width of cut being cut, m: each speed says whether it is stable
        there.
    margin : float
        Safety margin in [0, 1) below the limit.
    count : int
        How many speeds (the nearest j).
    machine : Machine, optional
        Speeds outside its range are dropped (default: the model's).
    resolution_hz : float, optional
        The chatter frequency's resolution, Hz (default: the recording's,
        else 0).
    position, width_max, **options
        The lobes' (a model's slide position, the largest width searched,
        the route's options).

    Returns
    -------
    SpeedRule
    """
    from ._limits import check_machine

    spectrum = chatter if isinstance(chatter, ChatterFrequency) else None
    if spectrum is not None:
        if not spectrum.found:
            raise InputError(
                f"{spectrum.source}: no chatter frequency found (no peak apart from the spindle harmonics):"
                " the rule needs one"
            )
        f_c, res = spectrum.frequency_hz, spectrum.resolution_hz
    else:
        f_c, res = _speed_value(chatter, "the chatter frequency (Hz)"), 0.0
    if resolution_hz is not None:
        if not (
            isinstance(resolution_hz, int | float) and math.isfinite(resolution_hz) and resolution_hz >= 0
        ):
            raise InputError(f"resolution_hz must be a finite number >= 0 Hz (got {resolution_hz!r})")
        res = float(resolution_hz)
    v0 = _speed_value(speed, "the running speed")
    margin = check_margin(margin)
    count = check_count(count, "count")
    if depth is not None and not (isinstance(depth, int | float) and math.isfinite(depth) and depth > 0):
        raise InputError(f"depth must be a width of cut > 0 m (got {depth!r})")
    src = source_of(source, position, options.get("method")) if source is not None else None
    if src is not None and src.process is None:
        raise InputError("the rule's source must be a model, a frozen configuration or a milling loop")
    if src is None:
        n_teeth = 1 if teeth is None else check_count(teeth, "teeth")
        proc: Any = _Spindle(n_teeth, "turning" if n_teeth == 1 and teeth is None else "milling")
        mach = check_machine(machine, "milling")
    else:
        proc = src.process
        n_teeth = int(getattr(getattr(proc, "milling", None), "teeth", 1) or 1)
        if teeth is not None and int(teeth) != n_teeth:
            raise InputError(f"teeth {teeth}: the model's cutter has {n_teeth}; drop the option")
        mach = check_machine(machine if machine is not None else src.machine, str(proc.kind))
    if proc.kind == "delay":
        raise InputError("a delay process has no speed to change: the rule needs turning, milling or shaping")
    T0 = float(proc.delay(v0))
    j0 = f_c * T0
    js = np.arange(max(1, math.floor(j0) - count - 1), math.ceil(j0) + count + 2)
    js = js[np.argsort(np.abs(js - j0), kind="stable")]
    T = js / f_c
    ok = T > proc.min_delay * (1 + 1e-12)
    js, T = js[ok], T[ok]
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.asarray(proc.speed_for_delay(T), float)
    inside = np.isfinite(v) & (v > 0) & (v >= mach.min_speed) & (v <= mach.max_speed)
    notes = []
    if np.any(~inside[:count]):
        notes.append(
            f"speeds outside the machine's range {mach.min_speed:g}..{mach.max_speed:g} {proc.speed_unit} dropped"
        )
    js, T, v = js[inside][:count], T[inside][:count], v[inside][:count]
    if not v.size:
        raise InputError(
            f"no speed of the rule (f_c / j = tooth-passing frequency) lies within the machine's range"
            f" {mach.min_speed:g}..{mach.max_speed:g} {proc.speed_unit}"
        )
    with np.errstate(divide="ignore", invalid="ignore"):
        dv = (
            np.abs(np.asarray(proc.speed_for_delay(js / max(f_c - res, 1e-300)), float) - v)
            if res
            else np.zeros(v.size)
        )
    return _checked(src, proc, f_c, res, v0, n_teeth, js, v, dv, T, depth, margin, spectrum, notes,
                    width_max, options)  # fmt: skip


def _checked(src: Any, proc: Any, f_c: float, res: float, v0: float, n_teeth: int, js: np.ndarray, v: np.ndarray,
             dv: np.ndarray, T: np.ndarray, depth: float | None, margin: float, spectrum: Any, notes: list[str],
             width_max: float | None, options: dict[str, Any]) -> SpeedRule:  # fmt: skip
    n = v.size
    limit = np.full(n, np.nan)
    width = np.full(n, np.nan)
    cur_lim, cur_f = math.nan, math.nan
    d = None
    if src is None:
        verdict = ["undetermined"] * n
        reasons = [
            "no model to check it on: the rule places the speed near a stability pocket, it does not prove the"
            " cut stable (give the model, or try the speed and listen)"
        ] * n
    else:
        from ..lobes import lobes

        speeds = np.r_[v, v0]
        o = np.argsort(speeds)
        d = lobes(src.lobes_source, speeds[o], width_max=width_max, position=src.position, **options)
        back = np.empty_like(o)
        back[o] = np.arange(o.size)
        stable, ceiling = stable_width(d)
        stable = stable[back]
        b = np.asarray(d.b_lim, float)[back]
        f = np.asarray(d.chatter_hz, float)[back]
        limit, cur_lim, cur_f = b[:n], float(b[n]), float(f[n])
        width = (1 - margin) * stable[:n]
        verdict, reasons = [], []
        for i in range(n):
            vd, why = _verdict(float(stable[i]), bool(ceiling[back][i]), depth, margin, float(d.width_max))
            verdict.append(vd)
            reasons.append(why)
        if depth is not None and np.isfinite(stable[n]) and depth < stable[n] and not ceiling[back][n]:
            notes.append(
                f"the lobes say the running cut ({depth * 1e3:.4g} mm) is stable (limit {stable[n] * 1e3:.4g} mm),"
                " yet chatter was measured: the model may not describe the machine here; check it"
            )
        if np.isfinite(cur_f) and abs(cur_f - f_c) > 0.1 * f_c:
            notes.append(
                f"the lobes' chatter frequency at the running speed is {cur_f:.1f} Hz, the measured {f_c:.1f} Hz:"
                " more than 10 % apart (in milling the measured peak may be f_c + k x tooth-passing frequency)"
            )
    return SpeedRule(
        chatter_hz=f_c, resolution_hz=res, current_speed=v0, teeth=n_teeth, process=proc, waves=js.astype(int),
        speed=v, speed_error=dv, delay=T, limit=limit, width=width, verdict=np.array(verdict, dtype=str),
        reason=tuple(reasons), current_limit=cur_lim, current_chatter_hz=cur_f, depth=depth, margin=margin,
        model=src.name if src is not None else "no model", spectrum=spectrum, diagram=d, notes=tuple(notes),
    )  # fmt: skip


def _verdict(
    stable: float, ceiling: bool, depth: float | None, margin: float, wmax: float
) -> tuple[str, str]:
    if not np.isfinite(stable):
        return (
            "undetermined",
            "the lobes establish nothing at this speed (no boundary found in a band not proven complete, a failed"
            " check, or the zeroth-order approximation's limit, which misses the flip lobes)",
        )
    lim = f"no limit up to {wmax * 1e3:.4g} mm" if ceiling else f"limit {stable * 1e3:.4g} mm"
    allowed = (1 - margin) * stable
    if depth is None:
        return "limit", f"{lim}: stable up to {allowed * 1e3:.4g} mm with the margin"
    if depth <= allowed:
        return "stable", f"stable at the depth {depth * 1e3:.4g} mm with the margin ({lim})"
    if depth < stable or ceiling:
        return "within margin", (
            f"stable at the depth {depth * 1e3:.4g} mm but within the margin ({lim}; {allowed * 1e3:.4g} mm with it)"
        )
    return (
        "unstable",
        f"chatters at the depth {depth * 1e3:.4g} mm ({lim}): cut at most {allowed * 1e3:.4g} mm here",
    )
