"""Why a recommended cut is chosen, in words: where its speed lies (a lobe
peak, the fastest speed at which a depth limit is stable, an end of the
speed range) and what sets its width (stability with the margin, the
tool's depth, the spindle's power or torque, a plug-in limit)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

#: rates within this relative tolerance of each other are equal (a plateau: a power-limited MRR is
#: the same at every speed, b* = P / p(v), up to the round-off of the formulas)
PLATEAU_RTOL = 1e-9

__all__ = ["reason"]


def _mm(x: float) -> str:
    return f"{x * 1e3:.4g} mm"


def _v(unit: str, x: float) -> str:
    return f"{x:.0f} {unit}" if unit == "rpm" else f"{x:.4g} {unit}"


def _plateau(rate: np.ndarray, i: int, rtol: float) -> tuple[int, int]:
    """The run of speeds around ``i`` with the same rate (the search's plateau tolerance)."""
    tol = rtol * float(np.max(rate))
    lo = hi = i
    while lo > 0 and abs(rate[lo - 1] - rate[i]) <= tol:
        lo -= 1
    while hi < rate.size - 1 and abs(rate[hi + 1] - rate[i]) <= tol:
        hi += 1
    return lo, hi


def _where(tab: Any, i: int, mach: Any, unit: str) -> str:
    """Where the speed lies."""
    v, c = tab.v, tab.cols
    n = v.size
    if i == n - 1:
        top = math.isfinite(mach.max_speed) and v[i] >= mach.max_speed * (1 - 1e-12)
        return "the machine's highest speed" if top else "the top of the speeds searched"
    if i == 0:
        low = v[i] <= mach.min_speed * (1 + 1e-12)
        return "the machine's lowest speed" if low else "the bottom of the speeds searched"
    b = str(tab.binding[i])
    right = str(tab.binding[i + 1])
    lo, hi = _plateau(tab.rate, i, PLATEAU_RTOL)
    if hi > lo:
        what = {"max depth": "the tool's largest depth"}.get(
            b, f"the spindle's {b}" if b in ("power", "torque") else b
        )
        return (
            f"the removal rate is the same from {_v(unit, float(v[lo]))} to {_v(unit, float(v[hi]))}"
            f" ({what} sets it), and here the cut is farthest from the lobes (limit / width ="
            f" {float(c['stable'][i] / tab.allowed[i]):.3g})"
        )
    if b != "stability" and right == "stability":
        return "the fastest speed at which this width is stable with the margin (just above it the lobe falls below)"
    if b == "stability":
        kl, kr = int(c["lobe"][i - 1]), int(c["lobe"][i + 1])
        if kl >= 0 and kr >= 0 and kl != kr:
            return f"the peak where lobes k = {min(kl, kr)} and k = {max(kl, kr)} cross"
        fl, fr = c["chatter"][i - 1], c["chatter"][i + 1]
        kinds = (str(c["kind"][i - 1]), str(c["kind"][i + 1]))
        if kinds[0] != kinds[1] and all(kinds):
            return f"the peak where a {kinds[0]} and a {kinds[1]} lobe cross"
        if np.isfinite(fl) and np.isfinite(fr) and abs(fl - fr) > 0.02 * max(abs(fl), abs(fr)):
            return (
                f"the peak where two lobes cross (chatter {fl:.0f} Hz on one side, {fr:.0f} Hz on the other)"
            )
        k = int(c["lobe"][i])
        return f"the top of lobe k = {k}" if k >= 0 else "a local maximum of the stable width over the speed"
    what = {"max depth": "the tool's largest depth"}.get(
        b, f"the spindle's {b}" if b in ("power", "torque") else b
    )
    return f"where the removal rate that {what} allows peaks"


def _what(tab: Any, i: int, mach: Any, margin: float, removal: Any, unit: str) -> str:
    """What sets the width there."""
    c = tab.cols
    b = str(tab.binding[i])
    w = float(tab.allowed[i])
    lim = float(c["limit"][i])
    limit = _mm(lim) if math.isfinite(lim) else "none below the largest width searched"
    if b == "stability":
        return f"width {_mm(w)} = {(1 - margin) * 100:g} % of the stability limit {_mm(lim)} (margin {margin * 100:g} %)"
    if b == "ceiling":
        return (
            f"no limit found up to {_mm(tab.width_max)} (the largest width searched): width {_mm(w)} is"
            f" {(1 - margin) * 100:g} % of that; give the tool's max_depth or raise width_max"
        )
    if b == "max depth":
        return f"width {_mm(w)} = the tool's largest depth (stability limit there: {limit})"
    if b == "power":
        from ._limits import curve_at

        p = float(curve_at(mach.power, np.array([tab.v[i]]))[0])
        return (
            f"width {_mm(w)}: the spindle's power, {p / 1e3:.4g} kW at this speed, is all used"
            f" (stability limit there: {limit})"
        )
    if b == "torque":
        from ._limits import curve_at

        q = float(curve_at(mach.torque, np.array([tab.v[i]]))[0])
        return f"width {_mm(w)}: the spindle's torque, {q:.4g} N m at this speed, is all used (stability limit {limit})"
    return f"width {_mm(w)} set by the limit '{b}' (stability limit there: {limit})"


def reason(tab: Any, i: int, mach: Any, margin: float, removal: Any, src: Any) -> str:
    """Why the cut at the ``i``-th speed of ``tab`` is chosen."""
    unit = str(src.process.speed_unit)
    where = _where(tab, i, mach, unit)
    what = _what(tab, i, mach, margin, removal, unit)
    best = float(np.max(tab.rate)) if tab.rate.size else math.nan
    share = tab.rate[i] / best * 100 if best > 0 else math.nan
    return f"{_v(unit, float(tab.v[i]))}: {where}; {what}; removal rate {share:.0f} % of the best"
