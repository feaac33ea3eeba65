"""The speeds to choose: :func:`recommend`, the cuts that maximise the
material removal rate while stable with a margin and within every limit.

At a speed v the largest width of cut allowed is

    b*(v) = min[(1 - m) b_lim(v), max depth, P(v) / p(v), M(v) / q(v), plug-in limits]

with m the safety margin, b_lim the stability limit of the lobes
(:func:`chatterlab.lobes`, the one entry), P and M the spindle's power and
torque curves and p, q the power and torque per unit width
(:mod:`._limits`).  The removal rate of that cut is b* h L / T(v)
(:class:`~chatterlab.selection._limits.Removal`), and since h and L do not
depend on the speed the ranking is that of b*(v) / T(v).  Its local maxima
over the speeds are the candidates: on the lobes they are the peaks where
two lobes cross (Tlusty's "stability pockets"; Smith & Tlusty 1990), the
fastest speed at which a depth limit is still stable, or the top of the
speed range.  Each is refined by evaluating the lobes inside its bracket
(the neighbouring speeds), ``refine`` times with ``REFINE_POINTS`` speeds,
each time narrowing the bracket by a factor 2/(REFINE_POINTS + 1); the
resolution returned is the last bracket.  Every recommended cut is then
checked on its own (the rightmost roots and the argument principle,
:func:`chatterlab.stability`; milling: the Floquet multipliers), so the
ranking never claims a stable cut that was not checked; a speed where the
lobes are undetermined (no boundary found in a band not proven complete,
or a failed argument-principle check) allows no cut.

References
----------
J. Tlusty, *Manufacturing Processes and Equipment*, Prentice Hall, 2000,
ch. 9 (the stability pockets and the choice of speed).
S. Smith, J. Tlusty, Stabilizing chatter by automatic spindle speed
regulation, CIRP Annals 41(1) (1992) 433-436.
T. L. Schmitz, K. S. Smith, *Machining Dynamics*, 2nd ed., Springer, 2019,
ch. 4 (best speeds, the MRR of a stable cut).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError, check_count
from ._limits import Removal, WidthLimit, check_machine, curve_at, removal_of
from ._reasons import PLATEAU_RTOL
from ._result import Recommendation

__all__ = ["recommend", "check_margin", "Source", "source_of", "stable_width"]

#: speeds added inside each candidate's bracket per refinement round
REFINE_POINTS = 8
#: speeds of the dense line through the lobe curves: 10 per lobe crossing the range, within these
#: bounds (the line adds each cusp where the active lobe changes between two of its speeds; its cost
#: grows with speeds x lobe segments)
LINE_POINTS = 2000
LINE_POINTS_MAX = 6000
#: rounds of seeds from the lobe curves (a seed at a peak the curves have but the lobes do not --
#: a lobe missing from a dense diagram's curves -- removes that stretch of the curves, and the next
#: round seeds the next peak)
SEED_ROUNDS = 3
#: claims of a lobe diagram (LobeDiagram.CLAIMS) that establish nothing at a speed: no boundary in a band
#: not proven, contradicted by a check, the zeroth-order approximation (its flip lobes are missing)
UNTRUSTED_CLAIMS = (2, 3, 6)


def check_margin(margin: Any) -> float:
    """The safety margin: a fraction in [0, 1) (0.2: 20 % below the limit)."""
    if isinstance(margin, bool) or not isinstance(margin, int | float | np.floating) or not 0 <= margin < 1:
        raise InputError(
            f"margin must be a fraction in [0, 1), the share of the stability limit kept free (got {margin!r});"
            " e.g. 0.2 cuts at 80 % of the limit"
        )
    return float(margin)


# ------------------------------------------------------------------------------ the source
@dataclass(frozen=True, eq=False)
class Source:
    """What :func:`recommend` and :func:`chatter_rule` read from their source:
    the lobes' source and options, the process, the couplings (for the cutting
    force), the model's ``[machine]``, its name, and how a cut is checked
    (``frozen`` for the roots, ``loop`` for the Floquet multipliers)."""

    lobes_source: Any
    process: Any
    couplings: tuple[Any, ...]
    machine: Any
    name: str
    frozen: Any = None
    loop: Any = None
    takes_verify: bool = False
    position: float | None = None

    @property
    def kind(self) -> str:
        return str(self.process.kind)


def source_of(source: Any, position: float | None = None, method: Any = None) -> Source:
    """The :class:`Source` of a Model, a FrozenSystem or a milling ClosedLoop
    (the sources whose cuts can be checked); anything else the lobes take
    (an FRF, a plant, a python-control system) is passed on unchecked."""
    from ..model import Model
    from ..process import ClosedLoop
    from ..structure import FrozenSystem

    if isinstance(source, Model):
        if source.process is None:
            raise InputError(f"{source.source} has no [process] table: add one so that speeds map to delays")
        name = source.name or str(source.source)
        if source.frf is not None:
            return Source(source, source.process, source.couplings, source.machine, name, position=position)
        from ..structure import assemble

        frozen = assemble(source).at(position)
        if source.process.kind == "milling" and method != "zoa":
            from ..lobes._milling_model import model_milling_loop

            loop = model_milling_loop(frozen)[0]
            return Source(source, source.process, source.couplings, source.machine, name, loop=loop,
                          position=position)  # fmt: skip
        return Source(source, source.process, source.couplings, source.machine, name, frozen=frozen,
                      takes_verify=True, position=position)  # fmt: skip
    if isinstance(source, FrozenSystem):
        m = source.model
        if m.process is None:
            raise InputError(f"{m.source} has no [process] table: add one so that speeds map to delays")
        return Source(source, m.process, m.couplings, m.machine, m.name or str(m.source), frozen=source,
                      takes_verify=True)  # fmt: skip
    if isinstance(source, ClosedLoop) and source.process is not None:
        return Source(source, source.process, (), None, "", loop=source)
    return Source(source, None, (), None, type(source).__name__)


def stable_width(d: Any) -> tuple[np.ndarray, np.ndarray]:
    """The width (m) up to which each speed of the diagram ``d`` is stable on
    its own claim, and whether that is only the ceiling searched: its limit
    where finite; ``width_max`` where no boundary lies below it on a proven
    basis; nan where the diagram establishes nothing (no boundary found in a
    band not proven complete, or contradicted by a check)."""
    b = np.asarray(d.b_lim, float)
    claim = np.asarray(d.claim)
    trust = ~np.isin(claim, UNTRUSTED_CLAIMS)
    ceiling = ~np.isfinite(b) & trust
    out = np.where(np.isfinite(b), b, float(d.width_max))
    return np.where(trust, out, np.nan), ceiling


# ------------------------------------------------------------------------------ evaluation
class _Table:
    """Every speed evaluated so far (sorted) with its limit and the largest
    width each limit allows."""

    def __init__(self, src: Source, removal: Removal, machine: Any, margin: float, limits: tuple[WidthLimit, ...],
                 width_max: float | None, options: dict[str, Any]) -> None:  # fmt: skip
        self.src, self.removal, self.machine, self.margin = src, removal, machine, margin
        self.limits, self.width_max, self.options = limits, width_max, options
        #: rates equal to this relative accuracy are a plateau (a plug-in limit's bisection tolerance)
        self.rtol = max([PLATEAU_RTOL] + [float(getattr(lim, "rtol", 0.0)) for lim in limits])
        self.v = np.zeros(0)
        self.cols: dict[str, np.ndarray] = {}
        self.first: Any = None
        self.evaluations = 0

    def lobes(self, speeds: np.ndarray, refine: bool) -> Any:
        from ..lobes import lobes

        opts = dict(self.options)
        if refine and self.src.takes_verify:
            opts["verify"] = 0  # the recommended cuts are checked one by one at the end
        return lobes(
            self.src.lobes_source, speeds, width_max=self.width_max, position=self.src.position, **opts
        )

    def add(self, speeds: np.ndarray) -> None:
        speeds = np.unique(np.asarray(speeds, float))
        speeds = speeds[~np.isin(speeds, self.v)]
        if not speeds.size:
            return
        d = self.lobes(speeds, refine=self.first is not None)
        if self.first is None:
            self.first = d
            if self.width_max is None:
                self.width_max = float(d.width_max)
        self.evaluations += speeds.size
        stable, ceiling = stable_width(d)
        new = {
            "limit": np.asarray(d.b_lim, float),
            "stable": stable,
            "ceiling": ceiling,
            "chatter": np.asarray(d.chatter_hz, float),
            "lobe": np.asarray(d.lobe, int),
            "kind": np.asarray(d.kind).astype(str),
        }
        v = np.concatenate([self.v, np.asarray(d.speed, float)])
        o = np.argsort(v, kind="stable")
        self.v = v[o]
        self.cols = {
            k: np.concatenate([self.cols.get(k, np.zeros(0, x.dtype)), x])[o] for k, x in new.items()
        }
        self._limit()

    def _limit(self) -> None:
        c = self.cols
        self.allowed, self.binding, self.caps, self.rate, self.room = self.limited(
            self.v, c["stable"], c["ceiling"]
        )

    def limited(
        self, v: np.ndarray, stable: np.ndarray, ceiling: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray], np.ndarray, np.ndarray]:
        """At speeds ``v`` with stable widths ``stable`` (nan: undetermined; ``ceiling``: only up to
        the width searched): the largest width every limit allows, what sets it, each limit's
        width, the rate b/T and the room (stable width over the width allowed)."""
        m = self.machine
        one = 1.0 - self.margin
        caps: dict[str, np.ndarray] = {
            "stability": np.where(ceiling | np.isnan(stable), np.inf, one * stable),
            "ceiling": np.where(ceiling, one * float(self.width_max or np.inf), np.inf),
            "max depth": np.full(v.size, m.max_depth),
        }
        if m.power:
            caps["power"] = curve_at(m.power, v) / self.removal.power_per_width(v)
        if m.torque:
            caps["torque"] = curve_at(m.torque, v) / self.removal.torque_per_width(v)
        upper = np.min(np.vstack(list(caps.values())), axis=0)
        upper = np.where(np.isnan(stable), 0.0, upper)
        for lim in self.limits:
            w = np.asarray(lim.max_width(v, upper.copy()), float)
            if w.shape != v.shape:
                raise InputError(f"limit '{lim.name}': max_width must return one width per speed")
            caps[lim.name] = np.where(np.isnan(w), 0.0, w)
            upper = np.minimum(upper, caps[lim.name])
        names = list(caps)
        stack = np.vstack([caps[k] for k in names])
        allowed = np.min(stack, axis=0)
        binding = np.array([names[i] for i in np.argmin(stack, axis=0)], dtype=object)
        und = np.isnan(stable)
        allowed = np.where(und, 0.0, np.maximum(allowed, 0.0))
        binding = np.where(und, "undetermined", binding).astype(str)
        rate = np.where(np.isfinite(allowed), self.removal.width_rate(allowed, v), 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            room = np.where(allowed > 0, stable / allowed, 0.0)
        return allowed, binding, caps, rate, room

    def raw_line(self) -> tuple[Any, np.ndarray, np.ndarray] | None:
        """The lobes' envelope interpolated between their samples on a dense
        grid (:meth:`LobeDiagram.geometry`, with its cusps): the geometry, the
        speeds and the widths; None without lobe curves (Floquet methods)."""
        d = self.first
        geo = d.geometry() if getattr(d, "lobes", None) else None
        if geo is None or not geo.curves:
            return None
        n = int(min(max(LINE_POINTS, 10 * int(getattr(d, "n_lobes", 0))), LINE_POINTS_MAX))
        vv, env, _ = geo.envelope_line(np.linspace(float(self.v.min()), float(self.v.max()), n))
        return geo, np.asarray(vv, float), np.asarray(env, float)

    def line(self, raw: tuple[Any, np.ndarray, np.ndarray] | None, count: int) -> tuple[np.ndarray, ...]:
        """The envelope where it agrees with the speeds evaluated (:func:`_trusted`),
        the width allowed there, and the speeds of its best local maxima not yet
        evaluated, with their neighbours: seeds for the exact search where the
        lobes are denser than the speeds evaluated.  Without lobe curves: the
        speeds evaluated, and no seeds."""
        if raw is None:
            return self.v, self.cols["limit"], self.allowed, np.zeros(0)
        vv, env = _trusted(raw[0], self.v, self.cols["limit"], raw[1], raw[2])
        ceiling = ~np.isfinite(env)
        stable = np.where(ceiling, float(self.width_max or np.inf), env)
        allowed, _, _, rate, room = self.limited(vv, stable, ceiling)
        idx = _maxima(rate, room, self.rtol)
        idx = idx[~np.isin(vv[idx], self.v)][: 3 * count]
        seeds = (
            np.concatenate([vv[np.clip(idx + k, 0, vv.size - 1)] for k in (-1, 0, 1)]) if idx.size else idx
        )
        return vv, env, allowed, seeds


#: the lobe curves' envelope and the exact limit at a speed evaluated agree to this (the curves
#: are cubic Hermite between the engine's frequency samples)
LINE_RTOL = 1e-3


def _trusted(
    geo: Any, v: np.ndarray, exact: np.ndarray, vv: np.ndarray, env: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The dense envelope kept only between speeds evaluated where it agrees
    with the exact limits there (a dense diagram keeps only the lobes that
    form its envelope at the speeds requested, so between them a lower lobe
    may be missing from the curves), joined with the exact values."""
    gv, ge, _ = geo.envelope_line(v)
    at = np.isin(gv, v)
    curve = np.asarray(ge, float)[at]
    both = np.isfinite(curve) & np.isfinite(exact)
    ok = np.where(both, np.abs(curve / np.where(both, exact, 1.0) - 1) <= LINE_RTOL, curve == exact)
    # an interval [v_i, v_i+1] is trusted when both its ends are
    good = ok[:-1] & ok[1:]
    i = np.clip(np.searchsorted(v, vv, side="right") - 1, 0, v.size - 2)
    keep = good[i] & (vv > v[0]) & (vv < v[-1]) & ~np.isin(vv, v)
    allv = np.r_[vv[keep], v]
    o = np.argsort(allv, kind="stable")
    return allv[o], np.r_[env[keep], exact][o]


def _maxima(rate: np.ndarray, room: np.ndarray, rtol: float = PLATEAU_RTOL) -> np.ndarray:
    """Local maxima of the rate over sorted speeds (ends included), best
    first.  A plateau of equal rates (within ``rtol`` of the largest:
    :data:`PLATEAU_RTOL`, or a plug-in limit's accuracy) counts once, at its
    speed with the most ``room`` (the stability limit over the width: the cut
    farthest from the lobes)."""
    n = rate.size
    if n == 0 or not np.any(rate > 0):
        return np.zeros(0, int)
    tol = rtol * float(np.max(rate))
    starts = np.r_[0, np.nonzero(np.abs(np.diff(rate)) > tol)[0] + 1]
    ends = np.r_[starts[1:] - 1, n - 1]
    out = []
    for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
        val = float(np.max(rate[a : b + 1]))
        left = rate[a - 1] if a > 0 else -np.inf
        right = rate[b + 1] if b < n - 1 else -np.inf
        if val > 0 and left < val - tol and right < val - tol:
            seg = np.where(np.isnan(room[a : b + 1]), -np.inf, room[a : b + 1])
            out.append(b - int(np.argmax(seg[::-1])))  # the most room; of equals, the fastest
    idx = np.array(out, int)
    return idx[np.argsort(-rate[idx], kind="stable")]


def _bracket(v: np.ndarray, i: int) -> tuple[float, float]:
    return float(v[max(i - 1, 0)]), float(v[min(i + 1, v.size - 1)])


# ------------------------------------------------------------------------------ the entry
def recommend(
    source: Any,
    speeds: Any = None,
    *,
    machine: Any = None,
    margin: float = 0.2,
    count: int = 5,
    limits: Any = (),
    width_max: float | None = None,
    position: float | None = None,
    points: int = 300,
    refine: int = 3,
    check: bool = True,
    **options: Any,
) -> Recommendation:
    """The speeds and widths of cut that maximise the material removal rate
    while stable with a margin and within the machine's and tool's limits,
    ranked, with the reason for each.

    Parameters
    ----------
    source : Model, FrozenSystem, milling ClosedLoop, or anything :func:`chatterlab.lobes` takes
        The structure and its process (a model's ``[machine]`` is its
        default ``machine``).
    speeds : array, optional
        The speeds searched, in the process's unit (rpm; a shaper's work
        speed m/s); default: ``points`` speeds from the machine's
        ``min_speed`` to ``max_speed``.  Speeds outside the machine's range
        are dropped.
    machine : Machine, optional
        The limits (:class:`chatterlab.model.Machine`): speed range, power
        and torque curves, largest depth and radial width, feed (default:
        the model's ``[machine]``, else none).
    margin : float
        Safety margin in [0, 1): the width is at most (1 - margin) b_lim.
    count : int
        How many cuts to rank (the best local maxima of the MRR).
    limits : sequence of WidthLimit
        Further limits on the width (:func:`width_limit`; e.g. a surface
        location error).
    width_max : float, optional
        Largest width searched by the lobes, m (default: the limits' largest
        width divided by 1 - margin, else the lobes' default).
    position : float, optional
        A model's slide position, m.
    points : int
        Speeds of the default grid.
    refine : int
        Refinement rounds around each candidate (0: the grid's best).
    check : bool
        Check each recommended cut on its own (roots and argument
        principle, or Floquet multipliers).
    **options
        Options of the lobes' route (``method="zoa"``, ``fmax``, ``verify``...).

    Returns
    -------
    Recommendation
    """
    t0 = time.perf_counter()
    src = source_of(source, position, options.get("method"))
    margin = check_margin(margin)
    count = check_count(count, "count")
    refine = check_count(refine, "refine", 0)
    points = check_count(points, "points", 3)
    lims = tuple(limits or ())
    for lim in lims:
        if not isinstance(lim, WidthLimit):
            raise InputError(
                f"limits: {lim!r} is not a WidthLimit (an object with a name and max_width(speeds, upper));"
                " build one with chatterlab.selection.width_limit(name, value, limit)"
            )
    if src.process is None:  # an FRF, a plant, an LTI system: the process comes with the diagram
        return _recommend_unchecked(
            src, speeds, machine, margin, count, lims, width_max, points, refine, options, t0
        )
    return _run(src, speeds, machine, margin, count, lims, width_max, points, refine, check, options, t0)


def _recommend_unchecked(src: Source, speeds: Any, machine: Any, margin: float, count: int, lims: tuple,
                         width_max: Any, points: int, refine: int, options: dict, t0: float) -> Recommendation:  # fmt: skip
    """A source without a model: the process is the diagram's (its ``process=``)."""
    if speeds is None:
        raise InputError("give speeds= (the source has no [machine] speed range)")
    from ..lobes import lobes

    v = np.asarray(speeds, float)
    d = lobes(src.lobes_source, v[:2] if v.size >= 2 else v, width_max=width_max, **options)
    src = Source(src.lobes_source, d.process, (), None, str(d.model))
    return _run(src, speeds, machine, margin, count, lims, width_max, points, refine, False, options, t0)


def _speeds(speeds: Any, machine: Any, proc: Any, points: int) -> tuple[np.ndarray, list[str]]:
    """The speeds searched: given, or the machine's range; within the machine's range."""
    from ..errors import check_speed

    u = proc.speed_unit
    lo_name, hi_name = (
        ("min_rpm", "max_rpm") if proc.kind in ("turning", "milling") else ("min_speed", "max_speed")
    )
    notes = []
    if speeds is None:
        if not (machine.min_speed > 0 and math.isfinite(machine.max_speed)):
            raise InputError(
                f"give the speeds to search (speeds=, --speed MIN MAX) or the machine's {lo_name} > 0 and"
                f" {hi_name} ([machine], --{lo_name.replace('_', '-')} --{hi_name.replace('_', '-')})"
            )
        v = np.linspace(machine.min_speed, machine.max_speed, points)
    else:
        v = np.asarray(speeds, float)
        if v.ndim != 1 or v.size < 3:
            raise InputError("speeds must be a 1-D array of at least 3 speeds")
        for x in (np.min(v), np.max(v)) if np.all(np.isfinite(v)) else v[~np.isfinite(v)][:1]:
            check_speed(float(x), "speeds", u)
        speeds_min, speeds_max = float(np.min(v)), float(np.max(v))
        inside = (v >= machine.min_speed) & (v <= machine.max_speed)
        if not np.any(inside):
            raise InputError(
                f"no speed searched lies within the machine's {lo_name}..{hi_name}"
                f" ({machine.min_speed:g}..{machine.max_speed:g} {u}): search speeds the machine runs"
            )
        if not np.all(inside):
            notes.append(
                f"{int(np.sum(~inside))} of {v.size} speeds lie outside the machine's range"
                f" {machine.min_speed:g}..{machine.max_speed:g} {u} and were dropped"
            )
            v = v[inside]
            # the machine's own limits, where the range searched reaches past them, are speeds to consider
            ends = [x for x in (machine.min_speed, machine.max_speed) if speeds_min < x < speeds_max]
            v = np.r_[v, ends]
        if v.size < 3:
            raise InputError(
                f"only {v.size} speed(s) lie within the machine's range: search at least 3 speeds inside"
                f" {machine.min_speed:g}..{machine.max_speed:g} {u}"
            )
    return np.unique(v), notes


def _run(src: Source, speeds: Any, machine: Any, margin: float, count: int, lims: tuple, width_max: Any,
         points: int, refine: int, check: bool, options: dict, t0: float) -> Recommendation:  # fmt: skip
    proc = src.process
    mach = check_machine(machine if machine is not None else src.machine, str(proc.kind))
    removal = removal_of(proc, src.couplings, mach)
    if (
        proc.kind == "milling"
        and math.isfinite(mach.max_width)
        and removal.radial_width > mach.max_width * (1 + 1e-12)
    ):
        raise InputError(
            f"machine max_width: the cut's radial width a_e = {removal.radial_width * 1e3:.4g} mm ([process]"
            f" radial_immersion or entry/exit) exceeds the tool's largest, {mach.max_width * 1e3:.4g} mm:"
            " narrow the cut or correct max_width"
        )  # fmt: skip
    for name, curve, per in (("power", mach.power, removal.power_per_width), ("torque", mach.torque,
                                                                          removal.torque_per_width)):  # fmt: skip
        if curve and not np.all(np.isfinite(per(np.array([1.0])))):
            raise InputError(
                f"machine {name}: the {name} of a cut needs {' and '.join(removal.power_needs())}"
                " ([machine] fields, or the command's options) to compare it with the curve"
            )
    v, notes = _speeds(speeds, mach, proc, points)
    if width_max is None:
        # the lobes need no deeper search than the machine's own limit allows (divided by 1 - margin)
        tab0 = _Table(src, removal, mach, margin, (), math.inf, options)
        tab0.v = v
        tab0.cols = {"stable": np.full(v.size, np.inf), "ceiling": np.zeros(v.size, bool)}
        tab0._limit()
        top = float(np.max(tab0.allowed)) if v.size else math.inf
        if math.isfinite(top) and top > 0:
            width_max = top / (1.0 - margin) * (1 + 1e-9)
    tab = _Table(src, removal, mach, margin, lims, width_max, options)
    tab.add(v)
    raw = tab.raw_line()
    for _ in range(SEED_ROUNDS):  # lobes denser than the grid: their curves say where the peaks are
        seeds = tab.line(raw, count)[3]
        if not seeds.size:
            break
        tab.add(seeds)
    for _ in range(refine):
        new = []
        for i in _maxima(tab.rate, tab.room, tab.rtol)[: max(2 * count, count + 3)]:
            lo, hi = _bracket(tab.v, int(i))
            if hi > lo:
                new.append(np.linspace(lo, hi, REFINE_POINTS + 2)[1:-1])
        if not new:
            break
        tab.add(np.concatenate(new))
    best = _maxima(tab.rate, tab.room, tab.rtol)[:count]
    return _result(src, tab, best, mach, margin, removal, notes, check, t0, tab.line(raw, count))


def _result(src: Source, tab: _Table, best: np.ndarray, mach: Any, margin: float, removal: Removal,
            notes: list[str], check: bool, t0: float, line: tuple[np.ndarray, ...]) -> Recommendation:  # fmt: skip
    from ._reasons import reason

    v, c = tab.v, tab.cols
    sp = v[best]
    width = tab.allowed[best]
    res = np.array([(_bracket(v, int(i))[1] - _bracket(v, int(i))[0]) / 2 for i in best])
    checks = [_check(src, float(s), float(w)) if check else ("not checked", "not checked (check=False)")
              for s, w in zip(sp, width, strict=True)]  # fmt: skip
    reasons = tuple(reason(tab, int(i), mach, margin, removal, src) for i in best)
    notes = list(notes) + _notes(tab, removal, mach)
    with np.errstate(invalid="ignore"):
        power = width * removal.power_per_width(sp)
        torque = width * removal.torque_per_width(sp)
    return Recommendation(
        speed=sp,
        width=width,
        limit=c["limit"][best],
        mrr=removal.mrr(width, sp),
        width_rate=tab.rate[best],
        power=power,
        torque=torque,
        binding=tab.binding[best],
        lobe=c["lobe"][best],
        chatter_hz=c["chatter"][best],
        resolution=res.astype(float),
        verdict=np.array([k for k, _ in checks], dtype=str) if checks else np.zeros(0, str),
        check=tuple(t for _, t in checks),
        reason=reasons,
        grid_speed=v,
        grid_limit=c["limit"],
        grid_allowed=tab.allowed,
        grid_rate=tab.rate,
        grid_binding=tab.binding,
        caps=dict(tab.caps),
        line_speed=line[0],
        line_limit=line[1],
        line_allowed=line[2],
        diagram=tab.first,
        removal=removal,
        machine=mach,
        margin=margin,
        model=src.name or str(getattr(tab.first, "model", "")),
        width_max=float(tab.width_max or math.nan),
        notes=tuple(notes),
        evaluations=tab.evaluations,
        elapsed=time.perf_counter() - t0,
    )


def _notes(tab: _Table, removal: Removal, mach: Any) -> list[str]:
    out = []
    und = int(np.count_nonzero(tab.binding == "undetermined"))
    if und:
        out.append(
            f"{und} of {tab.v.size} speeds allow no cut: the lobes establish nothing there (no boundary found"
            " in a band not proven complete, a failed check, or the zeroth-order approximation, which misses the"
            " flip lobes: use the default Floquet method)"
        )
    if np.any(tab.binding == "ceiling"):
        out.append(
            f"where the width is set by the ceiling, the lobes found no limit up to {(tab.width_max or 0) * 1e3:.4g} mm"
            " (the largest width searched): give the tool's max_depth, or raise width_max"
        )
    need = removal.needs()
    if need:
        out.append(f"the MRR in m^3/s needs {' and '.join(need)} ([machine]): ranked by b/T meanwhile")
    if tab.first is not None and getattr(tab.first, "basis", None) is not None:
        basis = set(np.asarray(tab.first.basis).astype(str))
        if "zoa" in basis:
            out.append("the limits are the zeroth-order approximation's (flip lobes are not modelled)")
        if "scan" in basis:
            out.append("the limits are first crossings on a depth scan (a narrower band can be missed)")
        if "measured" in basis:
            out.append("the limits hold within the measured FRF's band; outside it nothing is known")
    return out


def _check(src: Source, speed: float, width: float) -> tuple[str, str]:
    """The recommended cut checked on its own: (verdict, what was found)."""
    if width <= 0:
        return "not checked", "no cut"
    if src.loop is not None:
        from ..frequency import multipliers

        mu = multipliers(src.loop, speed, width)
        verdict = "stable" if mu.stable else "unstable"
        if abs(mu.spectral_radius - 1) <= max(mu.error, 1e-9) * 10:
            verdict = "marginal"
        return verdict, (
            f"{verdict}: Floquet multipliers ({mu.method}), |mu|max = {mu.spectral_radius:.6g}"
            f" ({mu.kind}, estimated error {mu.error:.1e})"
        )
    if src.frozen is not None:
        from ..frequency import stability

        s = stability(src.frozen, width=width, speed=speed)
        verdict = s.verdict if s.verdict in ("stable", "unstable", "marginal") else "undetermined"
        how = "roots and the argument principle agree" if s.agree else "roots only"
        return verdict, f"{verdict}: rightmost root at {s.abscissa:.5g} 1/s ({how})"
    return "not checked", "not checked: the source has no model to check the cut on (a measured FRF, a plant)"
