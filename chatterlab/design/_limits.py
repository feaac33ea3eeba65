"""The critical points of a lobe diagram, polished on the loop's matrices:
b_lim at each speed, the minimum over the speed range, the absolute
minimum over all speeds, and every lobe bottom in the range
(:class:`Limits`).  The lobe engine (:func:`chatterlab.lobes.lobes`) finds
them; here each is solved again to round-off on the equation of
:mod:`chatterlab.design._critical`, which is the one its derivatives come
from.

The minimum over a speed range [v1, v2] is either a lobe bottom inside the
range -- a local minimum of its branch b(w), the same for every lobe k of
the branch, at the delay T = (2 pi k - arg z) / w -- or the limit at an end
of the range (a lobe that falls towards the end): the grid minimum of the
diagram is polished to the bottom of its lobe, and if that bottom's delay is
outside the range, to the nearer end.  A cusp (two lobes crossing) is a
local maximum of the envelope, never its minimum.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError
from ._critical import CriticalPoint, at_delay, branch_minimum, static_point
from ._matrices import LoopMatrices
from ._receptance import receptance

__all__ = ["Limits", "limits_of", "lobe_bottoms", "branch_bottoms"]


@dataclass(frozen=True)
class Limits:
    """Critical points of one diagram (None where the limit is inf)."""

    speeds: tuple[CriticalPoint | None, ...]
    minimum: CriticalPoint | None
    minimum_speed: float  #: speed (process unit) of the minimum over the range
    #: "bottom" (a lobe bottom inside the range), "end" (a range end), "static", "grid" (the
    #: diagram's lowest speed: no bottom of its branch found), "" (inf)
    minimum_at: str
    absolute: CriticalPoint | None


def _z_of(H: np.ndarray, L: LoopMatrices, b: float, w: float) -> complex:
    """The z on (nearest to) the unit circle with det(I + b H (A + z O)) = 0,
    from the pencil (I + b H A) v = -z (b H O) v."""
    from scipy.linalg import eigvals

    A = L.P + 1j * w * L.V
    lhs = np.eye(H.shape[0]) + b * H @ A
    rhs = -b * H @ L.O
    z = eigvals(lhs, rhs)
    z = z[np.isfinite(z) & (z != 0)]
    if z.size == 0:
        raise InputError("the boundary point has no delayed root: the coupling elements have no delayed term")
    return complex(z[np.argmin(np.abs(np.log(np.abs(z))))])


def limits_of(diagram: Any, L: LoopMatrices, *, speeds: bool = True) -> Limits:
    """The polished critical points of ``diagram`` (a
    :class:`chatterlab.lobes.LobeDiagram` computed by D-subdivision) on the
    loop's matrices ``L`` (whose ``T`` are the diagram's delays).
    ``speeds=False`` skips the per-speed points (only the minima)."""
    T = np.asarray(diagram.delay, dtype=float)
    b = np.asarray(diagram.b_lim, dtype=float)
    f = np.asarray(diagram.chatter_hz, dtype=float)
    pts: list[CriticalPoint | None] = [None] * T.size

    def at(j: int) -> CriticalPoint | None:
        if pts[j] is None and np.isfinite(b[j]):
            try:
                pts[j] = static_point(L, b[j]) if f[j] == 0 else at_delay(L, T[j], b[j], 2 * np.pi * f[j], j)
            except ArithmeticError:  # the engine's point is not solved again here: no derivative
                pts[j] = None
        return pts[j]

    if speeds:
        for j in range(T.size):
            at(j)
    # the minimum over the range
    minimum, where, vmin = None, "", float("nan")
    if np.any(np.isfinite(b)):
        j = int(np.nanargmin(b))
        cp = at(j)
        if cp is None:
            pass
        elif cp.kind == "static":
            minimum, where, vmin = cp, "static", float(diagram.speed[j])
        else:
            bottom = branch_minimum(L, cp.b, cp.w, cp.z)
            if not bottom.converged:  # no minimum of the branch found: the grid's point stands
                return Limits(tuple(pts), cp, float(diagram.speed[j]), "grid", _absolute(diagram, L))
            k = np.round((bottom.w * T[j] + np.angle(bottom.z)) / (2 * np.pi))
            Tb = (2 * np.pi * k - np.angle(bottom.z)) / bottom.w
            lo, hi = int(np.argmin(T)), int(np.argmax(T))
            if T[lo] <= Tb <= T[hi]:
                minimum, where = bottom, "bottom"
                vmin = float(diagram.speed_of(Tb))
            else:
                end = at(lo if Tb < T[lo] else hi)
                minimum, where = end, "end"
                vmin = float(diagram.speed[lo if Tb < T[lo] else hi])
    absolute = _absolute(diagram, L)
    return Limits(tuple(pts), minimum, vmin, where, absolute)


def _absolute(diagram: Any, L: LoopMatrices) -> CriticalPoint | None:
    """The absolute minimum: the lowest of the engine's, polished, and of
    every branch's low samples, each polished (:func:`branch_bottoms`: the
    engine refines only the branch with the lowest *sampled* width; where two
    branch minima are within the sampling error of each other, about 1e-6,
    that can be the higher one)."""
    a = diagram.absolute_minimum
    width, fa = float(a["width"]), float(a["chatter_hz"])
    if not np.isfinite(width):
        return None
    if fa == 0:
        try:
            return static_point(L, width)
        except ArithmeticError:
            return None
    w = 2 * np.pi * fa
    z = _z_of(receptance(L, w)[0], L, width, w)
    try:
        cp: CriticalPoint | None = branch_minimum(L, width, w, z)
    except ArithmeticError:
        cp = None
    if cp is not None and not cp.converged:
        cp = None
    for other in branch_bottoms(diagram, L):
        if cp is None or other.b < cp.b * (1 - 1e-12):
            cp = other
    return cp


def branch_bottoms(diagram: Any, L: LoopMatrices, rel: float = 1e-7) -> list[CriticalPoint]:
    """Every local minimum of every branch of the boundary that the diagram
    samples, polished (:func:`~chatterlab.design._critical.branch_minimum`),
    lowest first.  A branch's lobes are one curve b(w) over different ranges
    of the delay: their samples, merged and sorted by frequency, sample the
    branch, and each of its local minima -- an end of the samples too, when
    it is lower than its neighbour -- is refined; minima closer than ``rel``
    in frequency are one."""
    found: list[CriticalPoint] = []
    branches: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    for lobe in diagram.lobes:
        branches.setdefault(int(lobe.branch), []).append(
            (np.asarray(lobe.frequency_hz, dtype=float), np.asarray(lobe.width, dtype=float))
        )
    for parts in branches.values():
        f = np.concatenate([p[0] for p in parts])
        wd = np.concatenate([p[1] for p in parts])
        f, idx = np.unique(f, return_index=True)
        wd = wd[idx]
        ok = np.isfinite(wd) & (f > 0)
        f, wd = f[ok], wd[ok]
        if f.size == 0:
            continue
        left = np.r_[np.inf, wd[:-1]]
        right = np.r_[wd[1:], np.inf]
        for i in np.nonzero((wd <= left) & (wd <= right))[0]:
            w = 2 * np.pi * f[i]
            if any(abs(cp.w - w) <= 1e-3 * w for cp in found):
                continue
            try:
                z = _z_of(receptance(L, w)[0], L, wd[i], w)
                cp = branch_minimum(L, wd[i], w, z)
            except (ArithmeticError, InputError):
                continue
            if cp.converged and not any(abs(c.w - cp.w) <= rel * cp.w for c in found):
                found.append(cp)
    return sorted(found, key=lambda c: c.b)


def lobe_bottoms(diagram: Any, L: LoopMatrices, rel: float = 1e-7) -> list[CriticalPoint]:
    """Every distinct local minimum of the boundary's branches that a lobe
    of ``diagram`` shows as an interior minimum (each polished by
    :func:`~chatterlab.design._critical.branch_minimum`), lowest first;
    minima closer than ``rel`` in frequency are one."""
    found: list[CriticalPoint] = []
    for lobe in diagram.lobes:
        wd = np.asarray(lobe.width, dtype=float)
        fr = np.asarray(lobe.frequency_hz, dtype=float)
        if wd.size < 3:
            continue
        inner = np.nonzero((wd[1:-1] <= wd[:-2]) & (wd[1:-1] <= wd[2:]))[0] + 1
        for i in inner:
            w = 2 * np.pi * fr[i]
            if w <= 0 or any(abs(cp.w - w) <= 1e-3 * w for cp in found):
                continue
            z = _z_of(receptance(L, w)[0], L, wd[i], w)
            try:
                cp = branch_minimum(L, wd[i], w, z)
            except ArithmeticError:
                continue
            if cp.converged and not any(abs(c.w - cp.w) <= rel * cp.w for c in found):
                found.append(cp)
    return sorted(found, key=lambda c: c.b)
